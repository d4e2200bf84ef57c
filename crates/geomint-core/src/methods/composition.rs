//! Symmetric compositions that raise the order of a symmetric second-order method Φ:
//! Ψ_h = Φ_{γ_s h} ∘ … ∘ Φ_{γ_1 h} with palindromic weights γ (γ_i = γ_{s+1−i}) summing to one.
//!
//! | scheme | order | stages | source |
//! |---|---|---|---|
//! | `triple_jump` | 4 | 3 | Creutz & Gocksch 1989, Yoshida 1990; Hairer–Lubich–Wanner (HLW), *Geometric Numerical Integration*, II.4 eq. (4.4) |
//! | `suzuki_4` | 4 | 5 | Suzuki 1990 (fractal); HLW Sec. II.4 |
//! | `mclachlan_4` | 4 | 5 | McLachlan 1995 (SIAM J. Sci. Comput. 16, 151–168), the five-stage scheme with γ₁ = 0.28 |
//! | `suzuki_6` | 6 | 25 | Suzuki 1990 (fractal, one level up: Phys. Lett. A 146, 319–323); HLW Sec. II.4 |
//! | `yoshida_6` | 6 | 7 | Yoshida 1990, solution A; HLW Sec. V.3.2 |
//! | `kahan_li_6` | 6 | 9 | Kahan & Li 1997 (s9odr6a); HLW Sec. V.3.2 |
//! | `kahan_li_8` | 8 | 17 | Kahan & Li 1997 (s17odr8a); HLW Sec. V.3.2 |
//! | `blanes_casas_murua_8` | 8 (processed) | 13 + 20 per output | Blanes, Casas & Murua 2006 (SIAM J. Sci. Comput. 27), tabulated in Blanes, Casas & Murua 2024 (Acta Numerica 33, Table 8.1) |
//!
//! **Processing.** `blanes_casas_murua_8` is a processed method Ψ̂_h = π⁻¹ ∘ K_h ∘ π (Blanes,
//! Casas & Ros): the kernel K_h is a 13-stage symmetric composition that is of order 4 on its own
//! (its weights meet Σγ³ = Σγ⁵ = Σγ⁷ = 0, not the other conditions of order 6 and 8), but
//! conjugate to an eighth-order map, and the processor π is a 20-stage composition whose weights
//! sum to zero. The driver applies π once before the first step and π⁻¹ only at
//! the outputs (`Stepper::pre_process`, `post_process`), so over n steps π⁻¹ ∘ K_hⁿ ∘ π costs the
//! kernel's 13 stages per step, against kahan_li_8's 17, with a smaller error constant. π⁻¹ is π
//! backwards with negated weights, since a symmetric base has Φ_{−τ} = Φ_τ⁻¹; with damping both
//! run its flows backwards in time exactly, as negative weights do here anyway, so the outputs
//! keep what the base keeps exactly.
//!
//! Some weights are negative; the damping sub-flows then run backwards in time exactly, so a
//! composition of a conformal symplectic base stays conformal symplectic (det ∂Ψ/∂z = e^{−2γh}
//! per degree of freedom) and keeps what the base keeps exactly (the elastic pendulum's J₃).
//!
//! Splitting bases are composed as data (`splitting::Composition`, which also fuses adjacent
//! exact flows of one kind, so that s stages cost s force evaluations per step, and runs the
//! stages with the base's flows written out); other bases (cimp, csv2, implicit_midpoint) are
//! wrapped by [`Composed`].
//!
//! The order conditions the tables must meet are tested: Σγ = 1 to round-off, Σγ³ = 0 for order
//! ≥ 4, Σγ⁵ = 0 for order ≥ 6, Σγ⁷ = 0 for order 8, and the observed order on the damped
//! oscillator (`tests/core/compositions.rs`); every condition up to the order, as words in the
//! flows' Lie operators, with and without damping (`tests/core/order_conditions.rs`).

use std::time::Instant;

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::sources::*;
use super::{Citation, Group, Kind, MethodId, MethodInfo, MethodOption, Steps};
use crate::error::StepError;
use crate::run::{Advanced, Stepper};
use crate::system::{MechanicalSystem, State};
use crate::tangent::Tangent;

/// A composition's weights as its catalogue entry gives them ([`super::Steps::Composition`]).
#[derive(Clone, Copy, Debug)]
pub struct Weights {
    /// The order of the composition of a symmetric second-order method (of the processed
    /// method, for a scheme with a processor).
    pub order: u32,
    /// The weights γ_1 … γ_s of the step (the kernel's, for a processed scheme), in the order
    /// the stages act (made by a function: some are computed, e.g. with cube roots).
    pub step: fn() -> Vec<f64>,
    /// The processor π of a processed scheme, as the weights of its stages in the order they
    /// act (they sum to zero); `None` for a plain composition. The output map π⁻¹ is the same
    /// list reversed with each weight negated ([`inverse`]).
    pub processor: Option<fn() -> Vec<f64>>,
}

impl Weights {
    /// Whether the two give the same composition.
    pub fn same_as(&self, other: &Weights) -> bool {
        self.order == other.order
            && (self.step)() == (other.step)()
            && self.processor.map(|p| p()) == other.processor.map(|p| p())
    }
}

/// A symmetric composition scheme: a method whose catalogue entry gives its [`Weights`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Scheme(MethodId);

/// Yoshida's order-6 weights γ_1 … γ_4 (γ_4 the middle one), HLW Sec. V.3.2.
#[allow(clippy::excessive_precision)] // as published (26 digits); the compiler rounds to f64
const YOSHIDA_6: [f64; 4] = [
    0.784_513_610_477_557_263_819_497_63,
    0.235_573_213_359_358_133_684_793_18,
    -1.177_679_984_178_871_006_946_415_68,
    1.315_186_320_683_911_218_884_249_73,
];

/// McLachlan's order-4 weights γ₁, γ₂ (SIAM J. Sci. Comput. 16 (1995) 151–168): γ₁ = 0.28 is
/// his choice of the one free weight, γ₂ as published (20 digits). Order 4 leaves γ₂ no choice:
/// it is the root near 0.625 of 2γ₁³ + 2γ₂³ + (1 − 2γ₁ − 2γ₂)³ = 0, and a 40-digit Newton
/// solve of that cubic agrees with the published digits to 2·10⁻²¹, so the table was checked
/// against its derivation before it was coded.
#[allow(clippy::excessive_precision)] // as published; the compiler rounds to f64
const MCLACHLAN_4: [f64; 2] = [0.28, 0.625_466_428_467_670_045_01];

/// Kahan and Li's order-6 weights γ_1 … γ_5 (γ_5 the middle one), HLW Sec. V.3.2.
#[allow(clippy::excessive_precision)] // as published (26 digits); the compiler rounds to f64
const KAHAN_LI_6: [f64; 5] = [
    0.392_161_444_007_314_139_279_250_56,
    0.332_599_136_789_359_438_599_748_64,
    -0.706_246_172_557_639_359_809_964_82,
    0.082_213_596_293_550_800_231_490_45,
    0.798_543_990_934_829_963_398_950_35,
];

/// Kahan and Li's order-8 weights γ_1 … γ_9 (γ_9 the middle one), HLW Sec. V.3.2.
#[allow(clippy::excessive_precision)] // as published (26 digits); the compiler rounds to f64
const KAHAN_LI_8: [f64; 9] = [
    0.130_202_483_088_890_080_878_817_63,
    0.561_162_981_775_108_384_561_964_41,
    -0.389_474_962_644_847_286_408_078_60,
    0.158_841_906_555_155_600_896_210_75,
    -0.395_903_894_133_237_577_336_231_54,
    0.184_539_640_978_315_707_091_832_54,
    0.258_374_387_686_322_047_293_979_11,
    0.295_011_723_609_310_298_870_966_24,
    -0.605_508_533_830_034_511_698_921_08,
];

/// Blanes, Casas and Murua's kernel of effective order 8 (2006; Acta Numerica 2024, Table 8.1):
/// a₁, a₁, a₃, a₄, a₅, a₆ and the middle weight 1 − 2(2a₁ + a₃ + a₄ + a₅ + a₆), as published
/// (a₁ = 0.168 is their free choice).
const BLANES_CASAS_MURUA_8: [f64; 6] = [
    0.168,
    0.168,
    0.585_550_530_805_562,
    -0.460_090_457_516_872,
    0.172_863_148_729_731,
    0.179_664_539_695_039,
];

/// Their processor's g₂ … g₁₀ (g₁ = −(g₂ + … + g₁₀)); see [`blanes_casas_murua_8_processor`].
#[allow(clippy::excessive_precision)] // as published
const BLANES_CASAS_MURUA_8_PROCESSOR: [f64; 9] = [
    -0.008_488_123_494_574_411,
    -0.337_188_967_354_338,
    0.333_987_768_164_597,
    0.588_351_189_003_849,
    0.162_324_207_599_241,
    -0.511_744_926_116_413,
    0.236_885_952_363_384,
    0.598_212_975_943_381,
    -0.543_415_765_371_656,
];

/// The palindrome γ_1 … γ_m … γ_1 of a half table ending with its middle weight.
fn palindrome(half: &[f64]) -> Vec<f64> {
    let (middle, outer) = half.split_last().expect("a table has a middle weight");
    outer
        .iter()
        .chain(std::iter::once(middle))
        .chain(outer.iter().rev())
        .copied()
        .collect()
}

impl Scheme {
    /// The triple jump: the composition a base method takes when none is named.
    pub const TRIPLE_JUMP: Scheme = Scheme(MethodId::TripleJump);

    /// The scheme of a composition method, if `id` is one.
    pub fn of(id: MethodId) -> Option<Scheme> {
        matches!(id.info().steps, Steps::Composition(_)).then_some(Scheme(id))
    }

    /// Every scheme, in catalogue order.
    pub fn all() -> impl Iterator<Item = Scheme> {
        MethodId::ALL.iter().copied().filter_map(Scheme::of)
    }

    /// The method id of the scheme.
    pub fn id(self) -> MethodId {
        self.0
    }

    /// Its weights, from its catalogue entry.
    fn weights_of(self) -> Weights {
        match self.0.info().steps {
            Steps::Composition(weights) => weights,
            _ => unreachable!("a Scheme is made only of a composition's id"),
        }
    }

    /// The order of the composition of a symmetric second-order method (of the processed method,
    /// for a scheme with a processor).
    pub fn order(self) -> u32 {
        self.weights_of().order
    }

    /// The weights γ_1 … γ_s of the step (the kernel's, for a processed scheme), in the order the
    /// stages act.
    pub fn weights(self) -> Vec<f64> {
        (self.weights_of().step)()
    }

    /// The processor π of a processed scheme ([`Weights::processor`]); `None` for a plain
    /// composition.
    pub fn processor(self) -> Option<Vec<f64>> {
        self.weights_of().processor.map(|p| p())
    }
}

/// Suzuki's fractal: four equal outer steps around one negative middle step.
fn suzuki_4_weights() -> Vec<f64> {
    let w = 1.0 / (4.0 - 4f64.cbrt());
    vec![w, w, 1.0 - 4.0 * w, w, w]
}

/// Suzuki's fractal one level up (Suzuki 1990, eq. (3.9) with k = 3; HLW Sec. II.4): his
/// fourth-order composition taken at the steps p h, p h, (1 − 4p) h, p h, p h with
/// p = 1/(4 − 4^{1/5}), so that 4p⁵ + (1 − 4p)⁵ = 0 cancels the fifth-order term. The 25 weights
/// are the products of the outer and the inner ones, palindromic bit for bit since both
/// factors are.
fn suzuki_6_weights() -> Vec<f64> {
    let p = 1.0 / (4.0 - 4f64.powf(0.2));
    let inner = suzuki_4_weights();
    [p, p, 1.0 - 4.0 * p, p, p]
        .iter()
        .flat_map(|outer| inner.iter().map(move |w| outer * w))
        .collect()
}

/// Blanes, Casas and Murua's kernel: the published outer weights and the middle one that makes
/// them sum to one.
fn blanes_casas_murua_8_weights() -> Vec<f64> {
    let outer: f64 = BLANES_CASAS_MURUA_8.iter().sum();
    let mut half = BLANES_CASAS_MURUA_8.to_vec();
    half.push(1.0 - 2.0 * outer);
    palindrome(&half)
}

/// Their processor. Blanes, Casas and Murua publish g₁ … g₁₀ (Σg = 0) and the processor
/// −(g₁, …, g₁₀, −g₁, …, −g₁₀); read first element first, that is
/// π = Φ_{g₁₀h} ∘ … ∘ Φ_{g₁h} ∘ Φ_{−g₁₀h} ∘ … ∘ Φ_{−g₁h}. The reading is checked by the
/// observed order (8.0, `tests/core/compositions.rs`); with π and π⁻¹ swapped (π⁻¹ before
/// the first step, π at the outputs) the method is of order 4, as the kernel alone is.
fn blanes_casas_murua_8_processor() -> Vec<f64> {
    let rest = &BLANES_CASAS_MURUA_8_PROCESSOR;
    let g1 = -rest.iter().sum::<f64>();
    let g: Vec<f64> = std::iter::once(g1).chain(rest.iter().copied()).collect();
    g.iter().map(|x| -x).chain(g.iter().copied()).collect()
}

/// The weights of the inverse of a composition of a symmetric base (Φ_{−τ} = Φ_τ⁻¹): the stages
/// backwards, each with its weight negated.
pub fn inverse(weights: &[f64]) -> Vec<f64> {
    weights.iter().rev().map(|w| -w).collect()
}

/// The triple-jump weights (w₁, w₀, w₁): w₁ = 1/(2 − 2^{1/3}), w₀ = 1 − 2w₁.
pub fn triple_jump_weights() -> [f64; 3] {
    let w1 = 1.0 / (2.0 - 2f64.cbrt());
    [w1, 1.0 - 2.0 * w1, w1]
}

/// The palindromes of the published half tables, as weights functions.
fn yoshida_6_weights() -> Vec<f64> {
    palindrome(&YOSHIDA_6)
}

/// The middle weight makes them sum to one.
fn mclachlan_4_weights() -> Vec<f64> {
    let [g1, g2] = MCLACHLAN_4;
    palindrome(&[g1, g2, 1.0 - 2.0 * (g1 + g2)])
}

fn kahan_li_6_weights() -> Vec<f64> {
    palindrome(&KAHAN_LI_6)
}

fn kahan_li_8_weights() -> Vec<f64> {
    palindrome(&KAHAN_LI_8)
}

/// A base stepper applied with sub-steps w_k h.
pub struct Composed<M> {
    base: M,
    weights: Vec<f64>,
}

impl<M> Composed<M> {
    /// Composes `base` with `weights` (summing to one for a method, to zero for a processor).
    pub fn new(base: M, weights: Vec<f64>) -> Self {
        Self { base, weights }
    }
}

impl<S: MechanicalSystem, M: Stepper<S>> Stepper<S> for Composed<M>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        for &w in &self.weights {
            self.base.step(sys, z, w * h)?;
        }
        Ok(())
    }

    fn force_evaluations(&self) -> u64 {
        self.base.force_evaluations()
    }

    fn check_interval(&self) -> u64 {
        self.base.check_interval()
    }

    fn restart(&mut self) {
        self.base.restart()
    }

    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        for &w in &self.weights {
            self.base.step_tangent(sys, z, w * h, tangent)?;
        }
        Ok(())
    }
}

/// A processed method π⁻¹ ∘ K ∘ π: three compositions of one base, the kernel K that `step`
/// runs, the processor π and the output map π⁻¹ (module docs). π and π⁻¹ act on copies or once,
/// so the kernel's force cache is never disturbed; each is restarted before it runs, since the
/// state it starts from is not where it left off.
pub struct Processed<M> {
    kernel: M,
    processor: M,
    output: M,
}

impl<M> Processed<M> {
    /// The kernel, the processor and the output map, each a stepper whose one step of h is the
    /// whole composition.
    pub fn new(kernel: M, processor: M, output: M) -> Self {
        Self {
            kernel,
            processor,
            output,
        }
    }
}

impl<S: MechanicalSystem, M: Stepper<S>> Stepper<S> for Processed<M>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        self.kernel.step(sys, z, h)
    }

    #[inline]
    fn advance(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, n: u64) -> Advanced {
        self.kernel.advance(sys, z, h, n)
    }

    fn force_evaluations(&self) -> u64 {
        self.kernel.force_evaluations()
            + self.processor.force_evaluations()
            + self.output.force_evaluations()
    }

    fn check_interval(&self) -> u64 {
        self.kernel.check_interval()
    }

    fn set_deadline(&mut self, deadline: Option<Instant>) {
        self.kernel.set_deadline(deadline);
        self.processor.set_deadline(deadline);
        self.output.set_deadline(deadline);
    }

    fn restart(&mut self) {
        self.kernel.restart()
    }

    fn pre_process(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        let before = z.clone();
        self.processor.restart();
        if let Err(e) = self.processor.step(sys, z, h) {
            z.clone_from(&before);
            return Err(e);
        }
        self.kernel.restart();
        Ok(())
    }

    fn post_process(
        &mut self,
        sys: &S,
        z: &State<S::Dim>,
        h: f64,
        out: &mut State<S::Dim>,
    ) -> Result<bool, StepError> {
        out.clone_from(z);
        self.output.restart();
        // `advance` rather than `step`: the same numbers, through the compiled stretch where
        // the system has one (a watched run forms an output state near every crossing).
        self.output.advance(sys, out, h, 1).1?;
        Ok(true)
    }

    /// The output map restarts before it runs, so any kernel state may be given to it.
    fn processes_any_state(&self) -> bool {
        true
    }

    /// The kernel's step Jacobian. Over n steps the method's map is π⁻¹ ∘ Kⁿ ∘ π, so a step's
    /// Jacobian is the kernel's conjugated by ∂π/∂z: the same determinant (what the Jacobian
    /// defect reads) and eigenvalues, not the same matrix. (The stability analysis propagates
    /// `step`, the kernel, and so reports the kernel's matrix, with the method's spectrum.)
    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        self.kernel.step_tangent(sys, z, h, tangent)
    }
}

/// The catalogue entry of a composition: what tells it apart (its id, name, source and weights),
/// and what every composition shares: explicit, symplectic and conformally symplectic as its base
/// is, with one option, the base. A plain composition of a symmetric base is symmetric; a
/// processed one, π⁻¹ ∘ K ∘ π, only to O(h¹⁰), since π does not change with the sign of h.
const fn entry(
    id: &'static str,
    name: &'static str,
    reference: Citation,
    weights: Weights,
) -> MethodInfo {
    MethodInfo {
        id,
        name,
        order: weights.order,
        kind: Kind::Explicit,
        symplectic: true,
        conformal_symplectic: true,
        symmetric: weights.processor.is_none(),
        requirements: &[],
        reference,
        group: Group::Geometric,
        options: &[MethodOption::Base],
        no_step_jacobian: None,
        steps: Steps::Composition(weights),
    }
}

/// Catalogue entry of `triple_jump`.
pub const TRIPLE_JUMP_INFO: MethodInfo = entry(
    "triple_jump",
    "Triple-jump composition (order 4)",
    Citation {
        paper: GNI,
        equation: "Sec. II.4, eq. (4.4)",
    },
    Weights {
        order: 4,
        step: || triple_jump_weights().to_vec(),
        processor: None,
    },
);

/// Catalogue entry of `suzuki_4`.
pub const SUZUKI_4_INFO: MethodInfo = entry(
    "suzuki_4",
    "Suzuki fractal composition (order 4, 5 stages)",
    Citation {
        paper: "Suzuki 1990; HLW",
        equation: "Sec. II.4",
    },
    Weights {
        order: 4,
        step: suzuki_4_weights,
        processor: None,
    },
);

/// Catalogue entry of `mclachlan_4`.
pub const MCLACHLAN_4_INFO: MethodInfo = entry(
    "mclachlan_4",
    "McLachlan composition (order 4, 5 stages)",
    Citation {
        paper: "McLachlan, SIAM J. Sci. Comput. 16 (1995) 151–168",
        equation: "symmetric composition, 5 stages, γ₁ = 0.28",
    },
    Weights {
        order: 4,
        step: mclachlan_4_weights,
        processor: None,
    },
);

/// Catalogue entry of `suzuki_6`.
pub const SUZUKI_6_INFO: MethodInfo = entry(
    "suzuki_6",
    "Suzuki fractal composition (order 6, 25 stages)",
    Citation {
        paper: "Suzuki, Phys. Lett. A 146 (1990) 319–323; HLW",
        equation: "eq. (3.9), k = 3; Sec. II.4",
    },
    Weights {
        order: 6,
        step: suzuki_6_weights,
        processor: None,
    },
);

/// Catalogue entry of `yoshida_6`.
pub const YOSHIDA_6_INFO: MethodInfo = entry(
    "yoshida_6",
    "Yoshida composition (order 6, 7 stages)",
    Citation {
        paper: "Yoshida 1990, solution A; HLW",
        equation: "Sec. V.3.2",
    },
    Weights {
        order: 6,
        step: yoshida_6_weights,
        processor: None,
    },
);

/// Catalogue entry of `kahan_li_6`.
pub const KAHAN_LI_6_INFO: MethodInfo = entry(
    "kahan_li_6",
    "Kahan–Li composition (order 6, 9 stages)",
    Citation {
        paper: "Kahan & Li 1997; HLW",
        equation: "Sec. V.3.2",
    },
    Weights {
        order: 6,
        step: kahan_li_6_weights,
        processor: None,
    },
);

/// Catalogue entry of `kahan_li_8`.
pub const KAHAN_LI_8_INFO: MethodInfo = entry(
    "kahan_li_8",
    "Kahan–Li composition (order 8, 17 stages)",
    Citation {
        paper: "Kahan & Li 1997; HLW",
        equation: "Sec. V.3.2",
    },
    Weights {
        order: 8,
        step: kahan_li_8_weights,
        processor: None,
    },
);

/// Catalogue entry of `blanes_casas_murua_8`.
pub const BLANES_CASAS_MURUA_8_INFO: MethodInfo = entry(
    "blanes_casas_murua_8",
    "Blanes–Casas–Murua processed composition (order 8, 13 stages)",
    Citation {
        paper: "Blanes, Casas & Murua 2006 (SIAM J. Sci. Comput. 27); Acta Numerica 33 (2024)",
        equation: "Table 8.1, order 8, s = 13",
    },
    Weights {
        order: 8,
        step: blanes_casas_murua_8_weights,
        processor: Some(blanes_casas_murua_8_processor),
    },
);

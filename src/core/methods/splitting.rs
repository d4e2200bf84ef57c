//! Splitting methods as data: a method is a list of (sub-flow, fraction of h), run by one composer.
//!
//! Sequences, written in the order they act on the state (the rightmost factor of the paper's
//! composition first):
//! - `modin_3s`, paper 000 Algorithm 3.1: damp ½, drift ½, kick 1, drift ½, damp ½;
//! - `modin_2s`, Algorithm 3.2: drift ½, kick-and-damp 1, drift ½;
//! - `modin_rks`, Algorithm 3.3: drift ½, a Runge–Kutta step of p' = −∇V − εDM⁻¹p with q frozen,
//!   drift ½;
//! - `csv1`, paper 003 eq. (2.12): damp ½, kick ½, drift 1, kick ½, damp ½ (003 writes the
//!   damping half-flow as p ← e^{−γh} p, i.e. e^{−2γ·h/2});
//! - the undamped classics applied to the full damped vector field as partitioned methods
//!   (baselines, not geometric): symplectic Euler (001 eqs. 42–43: p₁ = p + h G(q, p₁), implicit in
//!   p₁, then q₁ = q + h M⁻¹p₁), its adjoint (001 footnote 3), velocity Verlet as the Lobatto IIIA–IIIB
//!   pair (backward-Euler half kick, drift, forward-Euler half kick) and position Verlet (drift,
//!   trapezoidal kick, drift), where G = −∇V − εDM⁻¹p. All reduce to the classical schemes at
//!   ε = 0; the Verlets stay symmetric and second order under damping.
//!
//! The composer keeps the last ∇V(q) and reuses it while q has not moved, so velocity Verlet,
//! csv1 and modin_3s all cost one force evaluation per step (003 Table 4.1 counts two for csv1
//! because it does not reuse; we count what we evaluate, except that a fused stretch that
//! diverges and is rerun counts only the rerun). Compositions (the triple jump) are built by
//! scaling and concatenating sequences, then fusing adjacent flows of the same kind.
//!
//! The built-in sequences are also types ([`Known`]), so their steps compile to straight-line
//! code, and a composition of one is walked stage by stage with the base's flow kinds known at
//! compile time ([`Composition`]); between two samples, the last flow of a step and the first of
//! the next are fused too when they are of one kind ([`Splitting::advance`]), which changes
//! results by round-off only.

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::runge_kutta::MomentumRk;
use crate::core::error::StepError;
use crate::core::flows::{self, Tangent};
use crate::core::run::{finite, step_by_step, Advanced, Stepper};
use crate::core::system::{MechanicalSystem, State, Vector};

/// The implicitness θ of a damped kick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Theta {
    /// θ = 0, forward Euler.
    Explicit,
    /// θ = ½, the trapezoidal rule.
    Trapezoid,
    /// θ = 1, backward Euler.
    Implicit,
}

impl Theta {
    /// θ as a number.
    pub fn value(self) -> f64 {
        match self {
            Theta::Explicit => 0.0,
            Theta::Trapezoid => 0.5,
            Theta::Implicit => 1.0,
        }
    }
}

/// One exact (or, for `DampedKick` and `MomentumRk`, approximate) sub-flow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SubFlow {
    /// q ← q + τ M⁻¹p.
    Drift,
    /// p ← p − τ ∇V(q).
    Kick,
    /// A θ-method step of the damped momentum field p' = −∇V − r P p (see `flows::kick_theta`),
    /// θ in {0, ½, 1}.
    DampedKick(Theta),
    /// Exact damping decay.
    Damp,
    /// Exact linear kick-and-damp (modin_2s's middle flow).
    KickDamp,
    /// A Runge–Kutta step of the damped momentum field with q frozen (modin_rks).
    MomentumRk,
}

impl SubFlow {
    /// Whether this flow followed by `next` is one flow over the summed time: both of one kind,
    /// and that kind exact and autonomous with the other half of the state frozen.
    const fn fuses_with(self, next: SubFlow) -> bool {
        matches!(
            (self, next),
            (SubFlow::Drift, SubFlow::Drift)
                | (SubFlow::Kick, SubFlow::Kick)
                | (SubFlow::Damp, SubFlow::Damp)
                | (SubFlow::KickDamp, SubFlow::KickDamp)
        )
    }
}

/// A splitting method: sub-flows with their fractions of the step h.
pub type Sequence = &'static [(SubFlow, f64)];

use super::sources::*;
use super::{unroll, Citation, Group, Kind, Known, MethodInfo, MethodOption, Requirement};
use SubFlow::*;

/// Paper 000, Algorithm 3.1.
pub const MODIN_3S: Sequence = &[
    (Damp, 0.5),
    (Drift, 0.5),
    (Kick, 1.0),
    (Drift, 0.5),
    (Damp, 0.5),
];
/// Paper 000, Algorithm 3.2.
pub const MODIN_2S: Sequence = &[(Drift, 0.5), (KickDamp, 1.0), (Drift, 0.5)];
/// Paper 000, Algorithm 3.3.
pub const MODIN_RKS: Sequence = &[(Drift, 0.5), (MomentumRk, 1.0), (Drift, 0.5)];
/// Paper 003, eq. (2.12).
pub const CSV1: Sequence = &[
    (Damp, 0.5),
    (Kick, 0.5),
    (Drift, 1.0),
    (Kick, 0.5),
    (Damp, 0.5),
];
/// Paper 001, eqs. (42)–(43): p⁺ = p − h∇V(q), q⁺ = q + h M⁻¹p⁺.
pub const SYMPLECTIC_EULER: Sequence = &[(DampedKick(Theta::Implicit), 1.0), (Drift, 1.0)];
/// The adjoint of symplectic Euler (001 footnote 3): q⁺ = q + h M⁻¹p, p⁺ = p − h∇V(q⁺).
pub const SYMPLECTIC_EULER_ADJOINT: Sequence = &[(Drift, 1.0), (DampedKick(Theta::Explicit), 1.0)];
/// Störmer–Verlet, drift–kick–drift.
pub const POSITION_VERLET: Sequence = &[
    (Drift, 0.5),
    (DampedKick(Theta::Trapezoid), 1.0),
    (Drift, 0.5),
];
/// Störmer–Verlet, kick–drift–kick.
pub const VELOCITY_VERLET: Sequence = &[
    (DampedKick(Theta::Implicit), 0.5),
    (Drift, 1.0),
    (DampedKick(Theta::Explicit), 0.5),
];

/// Concatenates `base` scaled by each weight, fusing adjacent flows of one kind: the sequence of
/// the composition Φ_{w_k h} ∘ … ∘ Φ_{w_1 h}.
pub fn compose(base: &[(SubFlow, f64)], weights: &[f64]) -> Vec<(SubFlow, f64)> {
    let mut out: Vec<(SubFlow, f64)> = Vec::with_capacity(base.len() * weights.len());
    for &w in weights {
        for &(flow, frac) in base {
            match out.last_mut() {
                Some((last, f)) if last.fuses_with(flow) => *f += w * frac,
                _ => out.push((flow, w * frac)),
            }
        }
    }
    out
}

/// Where a splitting's sub-flows come from: a sequence built at run time (a [`Composition`]), or
/// one fixed in the program ([`Known`]), for which the compiler unrolls the step and resolves
/// each flow's kind, so a built-in method runs as the straight-line code one would write by hand.
/// Sealed: the composer trusts what [`Flows::stages`] says about the layout of the flows.
pub trait Flows: sealed::Sealed {
    /// Whether the sequence is known at compile time: the composer then writes its step out
    /// flow by flow; a sequence built at run time is looped over.
    const KNOWN: bool;
    /// The sub-flows with their fractions of h, in the order they act.
    fn flows(&self) -> &[(SubFlow, f64)];
    /// The built-in sequence this one composes, if it is a [`Composition`] of one.
    #[inline(always)]
    fn stages(&self) -> Option<ComposedBase> {
        None
    }
}

/// A splitting sequence known when the program is compiled.
pub trait KnownSequence {
    /// The sequence.
    const FLOWS: Sequence;
}

impl<K: KnownSequence> Flows for Known<K> {
    const KNOWN: bool = true;
    #[inline(always)]
    fn flows(&self) -> &[(SubFlow, f64)] {
        K::FLOWS
    }
}

mod sealed {
    /// Implemented by the two sources of flows only.
    pub trait Sealed {}
    impl<K: super::KnownSequence> Sealed for super::Known<K> {}
    impl Sealed for super::Composition {}
}

/// The built-in splittings a composition accepts as its base (the symmetric second-order ones).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ComposedBase {
    /// [`MODIN_3S`].
    Modin3s,
    /// [`MODIN_2S`].
    Modin2s,
    /// [`CSV1`].
    Csv1,
    /// [`POSITION_VERLET`].
    PositionVerlet,
    /// [`VELOCITY_VERLET`].
    VelocityVerlet,
}

impl ComposedBase {
    /// The built-in whose sequence is `sequence`, if one is.
    fn of(sequence: &[(SubFlow, f64)]) -> Option<ComposedBase> {
        [
            (ComposedBase::Modin3s, MODIN_3S),
            (ComposedBase::Modin2s, MODIN_2S),
            (ComposedBase::Csv1, CSV1),
            (ComposedBase::PositionVerlet, POSITION_VERLET),
            (ComposedBase::VelocityVerlet, VELOCITY_VERLET),
        ]
        .into_iter()
        .find(|(_, known)| *known == sequence)
        .map(|(base, _)| base)
    }
}

/// A composition of a splitting as one sequence ([`compose`]). When the base is a built-in, the
/// composer walks it stage by stage with the base's flow kinds known at compile time, which
/// spares a dispatch on the kind at every flow: kahan_li_8(modin_3s) on the elastic pendulum went
/// from 3110 to 2070 instructions per step (callgrind).
pub struct Composition {
    flows: Vec<(SubFlow, f64)>,
    base: Option<ComposedBase>,
}

impl Composition {
    /// Φ_{w_k h} ∘ … ∘ Φ_{w_1 h} for the splitting `base`.
    pub fn new(base: Sequence, weights: &[f64]) -> Self {
        let flows = compose(base, weights);
        // The stages are laid out as the walk expects (a shared first flow when the base's ends
        // fuse, then `weights.len()` stages of the rest), which holds for every built-in base
        // and checks that no flows fused inside a stage; else walk flow by flow.
        let shared = usize::from(base.len() > 1 && base[base.len() - 1].0.fuses_with(base[0].0));
        let laid_out =
            !weights.is_empty() && flows.len() == shared + weights.len() * (base.len() - shared);
        Self {
            base: ComposedBase::of(base).filter(|_| laid_out),
            flows,
        }
    }

    /// The same composition walked flow by flow, as a sequence of unknown origin is: the general
    /// path, which the stage-by-stage walk must reproduce bit for bit.
    pub fn without_stages(self) -> Self {
        Self { base: None, ..self }
    }
}

impl Flows for Composition {
    const KNOWN: bool = false;
    #[inline(always)]
    fn flows(&self) -> &[(SubFlow, f64)] {
        &self.flows
    }
    #[inline(always)]
    fn stages(&self) -> Option<ComposedBase> {
        self.base
    }
}

/// How the composer names the kinds of a sequence's flows: read from the sequence at run time,
/// or known at compile time. A sequence is walked as a first flow (`START` = 1: shared by the
/// stages of a composition whose stages fuse end to start) and then stages of `period` flows.
trait Walk {
    /// 1 when the first flow stands apart from the stages, else 0.
    const START: usize;
    /// Flows per stage.
    fn period(flows: &[(SubFlow, f64)]) -> usize;
    /// The kind of flow `i` of the sequence; `j` is its index in the base's sequence, for a walk
    /// that knows the base.
    fn kind(flows: &[(SubFlow, f64)], i: usize, j: usize) -> SubFlow;
}

/// A sequence of unknown origin: flow by flow, with a dispatch on each flow's kind.
struct Loop;

/// A built-in sequence ([`Known`]): one stage, written out.
struct Unrolled;

/// A composition of the built-in sequence `K`: stage after stage, each written out with `K`'s
/// kinds. [`compose`] lays the stages out as `K`'s flows, with each stage's first flow merged
/// into the previous stage's last when the two fuse: after that shared first flow, every stage
/// is `PERIOD` flows ([`Composition::new`] checks the layout).
struct Stages<K>(std::marker::PhantomData<K>);

impl<K: KnownSequence> Stages<K> {
    /// Whether `K`'s last flow and its first fuse, so that stages share one flow.
    const FUSED: bool = K::FLOWS[K::FLOWS.len() - 1].0.fuses_with(K::FLOWS[0].0);
    /// Flows per stage after the shared one.
    const PERIOD: usize = {
        assert!(K::FLOWS.len() >= 2, "a composed base has two flows or more");
        K::FLOWS.len() - Self::FUSED as usize
    };
}

impl Walk for Loop {
    const START: usize = 0;
    #[inline(always)]
    fn period(_: &[(SubFlow, f64)]) -> usize {
        1
    }
    #[inline(always)]
    fn kind(flows: &[(SubFlow, f64)], i: usize, _: usize) -> SubFlow {
        flows[i].0
    }
}

impl Walk for Unrolled {
    const START: usize = 0;
    #[inline(always)]
    fn period(flows: &[(SubFlow, f64)]) -> usize {
        flows.len()
    }
    #[inline(always)]
    fn kind(flows: &[(SubFlow, f64)], i: usize, _: usize) -> SubFlow {
        flows[i].0
    }
}

impl<K: KnownSequence> Walk for Stages<K> {
    const START: usize = Self::FUSED as usize;
    #[inline(always)]
    fn period(_: &[(SubFlow, f64)]) -> usize {
        Self::PERIOD
    }
    #[inline(always)]
    fn kind(_: &[(SubFlow, f64)], _: usize, j: usize) -> SubFlow {
        K::FLOWS[j].0
    }
}

/// Applies `flows[lo..hi]` to `z` with their h-dependent coefficients, walking with `W`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn walk<W: Walk, S: MechanicalSystem>(
    work: &mut Work<S>,
    sys: &S,
    z: &mut State<S::Dim>,
    h: f64,
    flows: &[(SubFlow, f64)],
    coefficients: &[(f64, f64)],
    lo: usize,
    hi: usize,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    let (start, period) = (W::START, W::period(flows));
    debug_assert_eq!((flows.len() - start) % period, 0, "whole stages");
    if lo < start && start <= hi {
        let kind = W::kind(flows, 0, 0);
        work.apply(sys, z, kind, flows[0].1 * h, coefficients[0]);
    }
    let stages = flows[start..].chunks_exact(period);
    let stage_coefficients = coefficients[start..].chunks_exact(period);
    let mut at = start;
    for (stage, cds) in stages.zip(stage_coefficients) {
        if at >= lo && at + period <= hi {
            unroll!(period, k => {
                let kind = W::kind(flows, at + k, start + k);
                work.apply(sys, z, kind, stage[k].1 * h, cds[k]);
            });
        } else {
            // A stage the range starts or ends inside.
            unroll!(period, k => {
                if at + k >= lo && at + k < hi {
                    let kind = W::kind(flows, at + k, start + k);
                    work.apply(sys, z, kind, stage[k].1 * h, cds[k]);
                }
            });
        }
        at += period;
    }
}

/// Runs `$call` with `$walk` the [`Walk`] that suits the sequence of the splitting `$split`:
/// unrolled for a built-in, stage by stage for a composition of one, else a loop. Used inside
/// `impl<…, Q: Flows> … for Splitting<S, Q>`, whose `Q` it reads.
macro_rules! with_walk {
    ($split:expr, $walk:ident => $call:expr) => {
        if Q::KNOWN {
            type $walk = Unrolled;
            $call
        } else {
            match $split.sequence.stages() {
                Some(ComposedBase::Modin3s) => {
                    type $walk = Stages<Modin3s>;
                    $call
                }
                Some(ComposedBase::Modin2s) => {
                    type $walk = Stages<Modin2s>;
                    $call
                }
                Some(ComposedBase::Csv1) => {
                    type $walk = Stages<Csv1>;
                    $call
                }
                Some(ComposedBase::PositionVerlet) => {
                    type $walk = Stages<PositionVerlet>;
                    $call
                }
                Some(ComposedBase::VelocityVerlet) => {
                    type $walk = Stages<VelocityVerlet>;
                    $call
                }
                None => {
                    type $walk = Loop;
                    $call
                }
            }
        }
    };
}

/// Declares a marker type for each built-in sequence.
macro_rules! known_sequences {
    ($($(#[$doc:meta])* $marker:ident = $sequence:ident;)*) => {
        $(
            $(#[$doc])*
            pub struct $marker;
            impl KnownSequence for $marker {
                const FLOWS: Sequence = $sequence;
            }
        )*
    };
}

known_sequences! {
    /// [`MODIN_3S`] as a type.
    Modin3s = MODIN_3S;
    /// [`MODIN_2S`] as a type.
    Modin2s = MODIN_2S;
    /// [`MODIN_RKS`] as a type.
    ModinRks = MODIN_RKS;
    /// [`CSV1`] as a type.
    Csv1 = CSV1;
    /// [`SYMPLECTIC_EULER`] as a type.
    SymplecticEuler = SYMPLECTIC_EULER;
    /// [`SYMPLECTIC_EULER_ADJOINT`] as a type.
    SymplecticEulerAdjoint = SYMPLECTIC_EULER_ADJOINT;
    /// [`POSITION_VERLET`] as a type.
    PositionVerlet = POSITION_VERLET;
    /// [`VELOCITY_VERLET`] as a type.
    VelocityVerlet = VELOCITY_VERLET;
}

/// Runs a splitting sequence; one instance per run, so its buffers are allocated once.
pub struct Splitting<S: MechanicalSystem, Q: Flows = Composition>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sequence: Q,
    /// Per-flow coefficients that depend on h only (the damping exponentials), for `coeff_h`.
    coefficients: Vec<(f64, f64)>,
    /// The flow that ends one step and begins the next, fused (see [`Splitting::advance`]): its
    /// time τ and coefficients for `coeff_h`, if the sequence ends and begins with one kind of
    /// flow that fuses.
    seam: Option<(f64, (f64, f64))>,
    coeff_h: f64,
    work: Work<S>,
}

/// What the sub-flows change besides the state: the force cache and the work vectors.
struct Work<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    inner: Option<MomentumRk<S::Dim>>,
    grad: Vector<S::Dim>,
    grad_valid: bool,
    w1: Vector<S::Dim>,
    w2: Vector<S::Dim>,
    force_evaluations: u64,
    /// The state at the start of a fused stretch, to run it again step by step if it diverges.
    start: State<S::Dim>,
    /// The force cache at the start of a fused stretch, restored with `start` so that a rerun
    /// counts exactly the evaluations of the step-by-step run.
    start_grad: Vector<S::Dim>,
}

impl<S: MechanicalSystem, Q: Flows> Splitting<S, Q>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A composer for `sequence`; `inner` is the Runge–Kutta method for `MomentumRk` flows.
    pub fn new(sys: &S, sequence: Q, inner: Option<MomentumRk<S::Dim>>) -> Self {
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), nalgebra::U1);
        Self {
            coefficients: vec![(0.0, 0.0); sequence.flows().len()],
            seam: None,
            coeff_h: f64::NAN,
            sequence,
            work: Work {
                inner,
                grad: zero.clone(),
                grad_valid: false,
                w1: zero.clone(),
                w2: zero.clone(),
                force_evaluations: 0,
                start: State {
                    q: zero.clone(),
                    p: zero.clone(),
                },
                start_grad: zero,
            },
        }
    }

    /// Recomputes the h-dependent coefficients when the step size changes (once per fixed-step
    /// run; compositions of splittings are flattened into one sequence, so they too).
    #[inline]
    fn prepare(&mut self, sys: &S, h: f64) {
        if h == self.coeff_h {
            return;
        }
        let r = sys.damping_rate();
        let coefficients = |flow: SubFlow, tau: f64| match flow {
            Damp => (flows::damp_coefficient(r, tau), 0.0),
            KickDamp => flows::kick_damp_coefficients(r, tau),
            _ => (0.0, 0.0),
        };
        let sequence = self.sequence.flows();
        for (k, &(flow, frac)) in sequence.iter().enumerate() {
            self.coefficients[k] = coefficients(flow, frac * h);
        }
        self.seam = match (sequence.first(), sequence.last()) {
            (Some(&(first, a)), Some(&(last, b)))
                if sequence.len() > 2 && last.fuses_with(first) =>
            {
                let tau = (b + a) * h;
                Some((tau, coefficients(first, tau)))
            }
            _ => None,
        };
        self.coeff_h = h;
    }

    /// `n ≥ 2` steps with the last flow of each step and the first of the next applied as one
    /// flow over their summed time (exact in exact arithmetic: with q frozen, or p for a drift,
    /// two flows of one autonomous field compose to the flow over the sum). The state between
    /// them is never observed, and the stretch ends with the whole last step, so the result
    /// differs from `n` separate steps only by round-off; modin_3s saves one of its two damping
    /// flows per step this way, modin_2s and position_verlet one drift. A stretch that diverges
    /// is run again step by step, so a run stops at the same step as it would unfused.
    #[inline(always)]
    fn advance_fused<W: Walk>(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        n: u64,
        (seam_tau, seam_coefficients): (f64, (f64, f64)),
    ) -> Advanced {
        let sequence = self.sequence.flows();
        let m = sequence.len();
        let coefficients = &self.coefficients[..m];
        let work = &mut self.work;
        work.start.q.copy_from(&z.q);
        work.start.p.copy_from(&z.p);
        work.start_grad.copy_from(&work.grad);
        let (start_grad_valid, start_count) = (work.grad_valid, work.force_evaluations);
        let first = sequence[0];
        let last = W::kind(sequence, m - 1, W::START + W::period(sequence) - 1);
        let last_frac = sequence[m - 1].1;
        work.apply(sys, z, first.0, first.1 * h, coefficients[0]);
        for done in 1..=n {
            // The flows between the first and the last.
            walk::<W, S>(work, sys, z, h, sequence, coefficients, 1, m - 1);
            // The seam, or at the end of the stretch the last flow alone.
            let (tau, cd) = if done < n {
                (seam_tau, seam_coefficients)
            } else {
                (last_frac * h, coefficients[m - 1])
            };
            work.apply(sys, z, last, tau, cd);
            if !finite(z) {
                break;
            }
            if done == n {
                return (n, Ok(()));
            }
        }
        // Diverged: run the stretch again step by step from where it started, with the force
        // cache and the count as they were, so that the stop step, the state and the count are
        // those of single steps.
        z.q.copy_from(&work.start.q);
        z.p.copy_from(&work.start.p);
        work.grad.copy_from(&work.start_grad);
        work.grad_valid = start_grad_valid;
        work.force_evaluations = start_count;
        step_by_step(self, sys, z, h, n)
    }

    /// One step, walking the sequence with `W`.
    #[inline(always)]
    fn step_with<W: Walk>(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) {
        let flows = self.sequence.flows();
        // One bounds check here instead of one per flow.
        let coefficients = &self.coefficients[..flows.len()];
        walk::<W, S>(
            &mut self.work,
            sys,
            z,
            h,
            flows,
            coefficients,
            0,
            flows.len(),
        );
    }
}

impl<S: MechanicalSystem> Work<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// Applies `flow` for time τ, with its h-dependent coefficients (c, d).
    #[inline(always)]
    fn apply(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        flow: SubFlow,
        tau: f64,
        (c, d): (f64, f64),
    ) {
        match flow {
            Drift => {
                flows::drift(sys, z, tau, &mut self.w1);
                self.grad_valid = false;
            }
            Kick => {
                self.ensure_grad(sys, &z.q);
                flows::kick(z, tau, &self.grad);
            }
            DampedKick(theta) => {
                self.ensure_grad(sys, &z.q);
                flows::kick_theta(sys, z, tau, theta.value(), &self.grad, &mut self.w1);
            }
            Damp => flows::damp_with(sys, z, tau, c, &mut self.w1),
            KickDamp => {
                self.ensure_grad(sys, &z.q);
                flows::kick_damp_with(sys, z, tau, c, d, &self.grad, &mut self.w1, &mut self.w2);
            }
            MomentumRk => {
                self.ensure_grad(sys, &z.q);
                if let Some(inner) = self.inner.as_mut() {
                    inner.step(sys, z, tau, &self.grad);
                }
            }
        }
    }

    #[inline]
    fn ensure_grad(&mut self, sys: &S, q: &Vector<S::Dim>) {
        if !self.grad_valid {
            sys.grad_potential(q, &mut self.grad);
            self.force_evaluations += 1;
            self.grad_valid = true;
        }
    }
}

impl<S: MechanicalSystem, Q: Flows> Stepper<S> for Splitting<S, Q>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline(always)]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        self.prepare(sys, h);
        with_walk!(self, W => self.step_with::<W>(sys, z, h));
        Ok(())
    }

    #[inline]
    fn advance(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, n: u64) -> Advanced {
        self.prepare(sys, h);
        match self.seam {
            Some(seam) if n >= 2 => {
                with_walk!(self, W => self.advance_fused::<W>(sys, z, h, n, seam))
            }
            _ => step_by_step(self, sys, z, h, n),
        }
    }

    fn force_evaluations(&self) -> u64 {
        self.work.force_evaluations
    }

    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent,
    ) -> Result<(), StepError> {
        let r = sys.damping_rate();
        self.prepare(sys, h);
        let flows = self.sequence.flows();
        for (&(flow, frac), &cd) in flows.iter().zip(&self.coefficients) {
            let tau = frac * h;
            // Each flow's Jacobian is taken at the state it acts on, before it moves it.
            match flow {
                Drift => tangent.drift(tau),
                Damp => tangent.kick_scaled((-r * tau).exp(), 0.0),
                Kick | DampedKick(_) | KickDamp | MomentumRk => {
                    self.work.force_evaluations += tangent.load_hessian(sys, &z.q);
                    let (a, b) = match flow {
                        Kick => (1.0, tau),
                        DampedKick(theta) => flows::kick_theta_tangent(r, tau, theta.value()),
                        KickDamp => ((-r * tau).exp(), one_minus_exp_neg_over(r, tau)),
                        _ => match self.work.inner.as_ref() {
                            Some(inner) => inner.tangent_coefficients(r, tau),
                            None => (1.0, tau),
                        },
                    };
                    tangent.kick_scaled(a, b);
                }
            }
            self.work.apply(sys, z, flow, tau, cd);
        }
        Ok(())
    }
}

/// (1 − e^{−rτ})/r, which tends to τ as r → 0.
fn one_minus_exp_neg_over(r: f64, tau: f64) -> f64 {
    if r == 0.0 {
        tau
    } else {
        flows::one_minus_exp_neg(r * tau) / r
    }
}

/// Catalogue entry of `modin_3s`.
pub const MODIN_3S_INFO: MethodInfo = MethodInfo {
    id: "modin_3s",
    name: "Three-term splitting (3S)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: true,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: MODIN,
        equation: "Algorithm 3.1",
    },
    group: Group::Geometric,
    options: &[],
    no_step_jacobian: None,
};

/// Catalogue entry of `modin_2s`.
pub const MODIN_2S_INFO: MethodInfo = MethodInfo {
    id: "modin_2s",
    name: "Two-term splitting (2S)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: true,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: MODIN,
        equation: "Algorithm 3.2",
    },
    group: Group::Geometric,
    options: &[],
    no_step_jacobian: None,
};

/// Catalogue entry of `modin_rks`.
pub const MODIN_RKS_INFO: MethodInfo = MethodInfo {
    id: "modin_rks",
    name: "Runge–Kutta splitting (RKS)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: MODIN,
        equation: "Algorithm 3.3",
    },
    group: Group::Geometric,
    options: &[MethodOption::Inner],
    no_step_jacobian: None,
};

/// Catalogue entry of `csv1`.
pub const CSV1_INFO: MethodInfo = MethodInfo {
    id: "csv1",
    name: "Conformal Störmer–Verlet 1 (CSV1)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: true,
    symmetric: true,
    requirements: &[
        Requirement::SeparableConstantMass,
        Requirement::ConformalDamping,
    ],
    reference: Citation {
        paper: FLOYD,
        equation: "eq. (2.12)",
    },
    group: Group::Conformal,
    options: &[],
    no_step_jacobian: None,
};

/// Catalogue entry of `symplectic_euler`.
pub const SYMPLECTIC_EULER_INFO: MethodInfo = MethodInfo {
    id: "symplectic_euler",
    name: "Symplectic Euler",
    order: 1,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: TAKACS,
        equation: "eq. (42)",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
};

/// Catalogue entry of `symplectic_euler_adjoint`.
pub const SYMPLECTIC_EULER_ADJOINT_INFO: MethodInfo = MethodInfo {
    id: "symplectic_euler_adjoint",
    name: "Symplectic Euler (adjoint)",
    order: 1,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: TAKACS,
        equation: "footnote 3 (the adjoint of eqs. 42–43)",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
};

/// Catalogue entry of `position_verlet`.
pub const POSITION_VERLET_INFO: MethodInfo = MethodInfo {
    id: "position_verlet",
    name: "Störmer–Verlet (drift–kick–drift)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: GNI,
        equation: "Sec. I.1.4",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
};

/// Catalogue entry of `velocity_verlet`.
pub const VELOCITY_VERLET_INFO: MethodInfo = MethodInfo {
    id: "velocity_verlet",
    name: "Störmer–Verlet (kick–drift–kick)",
    order: 2,
    kind: Kind::Explicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: true,
    requirements: &[Requirement::SeparableConstantMass],
    reference: Citation {
        paper: GNI,
        equation: "Sec. I.1.4",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
};

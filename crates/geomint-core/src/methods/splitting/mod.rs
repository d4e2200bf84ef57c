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
//! - `blanes_moan_s6` and `blanes_moan_srkn11`, Blanes & Moan's optimized splittings of orders 4
//!   and 6 (see [`BLANES_MOAN_S6`], [`BLANES_MOAN_SRKN11`]);
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
//! The built-in sequences are also types ([`Known`](super::Known)), so their steps compile to straight-line
//! code, and a composition of one is walked stage by stage with the base's flow kinds known at
//! compile time ([`Composition`]); between two samples, the last flow of a step and the first of
//! the next are fused too when they are of one kind ([`Splitting::advance`](crate::run::Stepper::advance)), which changes
//! results by round-off only.
//! A system may compile those fused stretches whole ([`compiled`]: a typed-in system does), with
//! the composer's bits.

mod catalogue;
pub use crate::flows::compiled;
mod composer;
mod walk;

pub use catalogue::*;
pub use composer::Splitting;
pub use walk::{ComposedBase, Composition, Flows, KnownSequence};

pub use crate::flows::{seam, SubFlow, Theta};

/// A splitting method: sub-flows with their fractions of the step h.
pub type Sequence = &'static [(SubFlow, f64)];

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
/// Velocity Verlet on an undamped system, the base its compositions take there
/// (`methods::build`): its θ-kicks are exact kicks then (`flows::kick_theta` with r = 0, to the
/// bit), so one stage's last kick and the next stage's first fuse into one kick over the summed
/// time. The same method in exact arithmetic, with one sum fewer per stage on the chain from
/// one force to the next; results change by round-off only. (Writing each drift from the
/// momentum before its kick, q + τM⁻¹p₀ − (τ·τₖ)M⁻¹∇V, would take off two operations more, but
/// the rounded product τ·τₖ makes the kick–drift pair's area 1 + O(ε)·∇²V per stage, not 1:
/// the energy error of 10⁶ Hénon–Heiles section points came out 1.6–1.8 times larger.)
pub const UNDAMPED_VELOCITY_VERLET: Sequence = &[(Kick, 0.5), (Drift, 1.0), (Kick, 0.5)];

// Blanes & Moan, J. Comput. Appl. Math. 142 (2002) 313–330: optimized splittings whose
// coefficients are theirs to 15 digits, the remaining ones fixed by consistency. Checked before
// coding against a fine reference on the pendulum: S₆ observed order 3.9996, SRKN₁₁ᵇ 6.13 (and an
// error of 5.8e-10 at h = 0.5 over t = 1); `tests/core/blanes_moan.rs` measures both.
const S6_A: [f64; 3] = [0.0792036964311957, 0.353172906049774, -0.0420650803577195];
const S6_A4: f64 = 1.0 - 2.0 * (S6_A[0] + S6_A[1] + S6_A[2]);
const S6_B: [f64; 2] = [0.209515106613362, -0.143851773179818];
const S6_B3: f64 = 0.5 - (S6_B[0] + S6_B[1]);

/// Blanes & Moan's S₆: order 4 for any splitting A + B in six B-stages, here A the drift and B
/// the exact kick-and-damp flow, so that it is order 4 and conformally symplectic under damping
/// too.
pub const BLANES_MOAN_S6: Sequence = &[
    (Drift, S6_A[0]),
    (KickDamp, S6_B[0]),
    (Drift, S6_A[1]),
    (KickDamp, S6_B[1]),
    (Drift, S6_A[2]),
    (KickDamp, S6_B3),
    (Drift, S6_A4),
    (KickDamp, S6_B3),
    (Drift, S6_A[2]),
    (KickDamp, S6_B[1]),
    (Drift, S6_A[1]),
    (KickDamp, S6_B[0]),
    (Drift, S6_A[0]),
];

const SRKN11_B: [f64; 5] = [
    0.0414649985182624,
    0.198128671918067,
    -0.0400061921041533,
    0.0752539843015807,
    -0.0115113874206879,
];
const SRKN11_A: [f64; 5] = [
    0.123229775946271,
    0.290553797799558,
    -0.127049212625417,
    -0.246331761062075,
    0.357208872795928,
];
const SRKN11_B6: f64 = 0.5 - (SRKN11_B[0] + SRKN11_B[1] + SRKN11_B[2] + SRKN11_B[3] + SRKN11_B[4]);
const SRKN11_A6: f64 = 0.5 - (SRKN11_A[0] + SRKN11_A[1] + SRKN11_A[2] + SRKN11_A[3] + SRKN11_A[4]);

/// Blanes & Moan's SRKN₁₁ᵇ: order 6 for H = T(p) + V(q) with T quadratic (a
/// Runge–Kutta–Nyström splitting: kicks commute with [kick, [kick, drift]]), kick first; eleven
/// force evaluations per step, the last kick shared with the next step's first. The two middle
/// drifts of its table (a₆ each) are one flow here.
pub const BLANES_MOAN_SRKN11: Sequence = &[
    (Kick, SRKN11_B[0]),
    (Drift, SRKN11_A[0]),
    (Kick, SRKN11_B[1]),
    (Drift, SRKN11_A[1]),
    (Kick, SRKN11_B[2]),
    (Drift, SRKN11_A[2]),
    (Kick, SRKN11_B[3]),
    (Drift, SRKN11_A[3]),
    (Kick, SRKN11_B[4]),
    (Drift, SRKN11_A[4]),
    (Kick, SRKN11_B6),
    (Drift, 2.0 * SRKN11_A6),
    (Kick, SRKN11_B6),
    (Drift, SRKN11_A[4]),
    (Kick, SRKN11_B[4]),
    (Drift, SRKN11_A[3]),
    (Kick, SRKN11_B[3]),
    (Drift, SRKN11_A[2]),
    (Kick, SRKN11_B[2]),
    (Drift, SRKN11_A[1]),
    (Kick, SRKN11_B[1]),
    (Drift, SRKN11_A[0]),
    (Kick, SRKN11_B[0]),
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
    /// [`UNDAMPED_VELOCITY_VERLET`] as a type.
    UndampedVelocityVerlet = UNDAMPED_VELOCITY_VERLET;
}

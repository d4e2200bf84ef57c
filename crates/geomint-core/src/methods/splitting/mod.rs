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
//! The built-in sequences are also types ([`Known`](super::Known)), so their steps compile to straight-line
//! code, and a composition of one is walked stage by stage with the base's flow kinds known at
//! compile time ([`Composition`]); between two samples, the last flow of a step and the first of
//! the next are fused too when they are of one kind ([`Splitting::advance`](crate::run::Stepper::advance)), which changes
//! results by round-off only.

mod catalogue;
mod composer;
mod walk;

pub use catalogue::*;
pub use composer::Splitting;
pub use walk::{ComposedBase, Composition, Flows, KnownSequence};

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

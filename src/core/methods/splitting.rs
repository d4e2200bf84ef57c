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
//! because it does not reuse; we count what we evaluate). Compositions (the triple jump) are
//! built by scaling and concatenating sequences, then fusing adjacent flows of the same kind.

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::runge_kutta::MomentumRk;
use crate::core::error::StepError;
use crate::core::flows::{self, Tangent};
use crate::core::run::Stepper;
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
    /// Whether two adjacent flows of this kind merge into one with the summed fraction.
    fn fuses(self) -> bool {
        matches!(
            self,
            SubFlow::Drift | SubFlow::Kick | SubFlow::Damp | SubFlow::KickDamp
        )
    }
}

/// A splitting method: sub-flows with their fractions of the step h.
pub type Sequence = &'static [(SubFlow, f64)];

use super::sources::*;
use super::{Citation, Group, Kind, MethodInfo, MethodOption, Requirement};
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
                Some((last, f)) if *last == flow && flow.fuses() => *f += w * frac,
                _ => out.push((flow, w * frac)),
            }
        }
    }
    out
}

/// Runs a splitting sequence; one instance per run, so its buffers are allocated once.
pub struct Splitting<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sequence: Vec<(SubFlow, f64)>,
    /// Per-flow coefficients that depend on h only (the damping exponentials), for `coeff_h`.
    coefficients: Vec<(f64, f64)>,
    coeff_h: f64,
    inner: Option<MomentumRk<S::Dim>>,
    grad: Vector<S::Dim>,
    grad_valid: bool,
    w1: Vector<S::Dim>,
    w2: Vector<S::Dim>,
    force_evaluations: u64,
}

impl<S: MechanicalSystem> Splitting<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A composer for `sequence`; `inner` is the Runge–Kutta method for `MomentumRk` flows.
    pub fn new(sys: &S, sequence: Vec<(SubFlow, f64)>, inner: Option<MomentumRk<S::Dim>>) -> Self {
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), nalgebra::U1);
        Self {
            coefficients: vec![(0.0, 0.0); sequence.len()],
            coeff_h: f64::NAN,
            sequence,
            inner,
            grad: zero.clone(),
            grad_valid: false,
            w1: zero.clone(),
            w2: zero,
            force_evaluations: 0,
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
        for (k, &(flow, frac)) in self.sequence.iter().enumerate() {
            let tau = frac * h;
            self.coefficients[k] = match flow {
                Damp => (flows::damp_coefficient(r, tau), 0.0),
                KickDamp => flows::kick_damp_coefficients(r, tau),
                _ => (0.0, 0.0),
            };
        }
        self.coeff_h = h;
    }

    /// Applies sub-flow `k` of the sequence for time τ.
    #[inline(always)]
    fn apply(&mut self, sys: &S, z: &mut State<S::Dim>, k: usize, tau: f64) {
        let flow = self.sequence[k].0;
        let (c, d) = self.coefficients[k];
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

impl<S: MechanicalSystem> Stepper<S> for Splitting<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        self.prepare(sys, h);
        for k in 0..self.sequence.len() {
            let frac = self.sequence[k].1;
            self.apply(sys, z, k, frac * h);
        }
        Ok(())
    }

    fn force_evaluations(&self) -> u64 {
        self.force_evaluations
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
        for k in 0..self.sequence.len() {
            let (flow, frac) = self.sequence[k];
            let tau = frac * h;
            // Each flow's Jacobian is taken at the state it acts on, before it moves it.
            match flow {
                Drift => tangent.drift(tau),
                Damp => tangent.kick_scaled((-r * tau).exp(), 0.0),
                Kick | DampedKick(_) | KickDamp | MomentumRk => {
                    self.force_evaluations += tangent.load_hessian(sys, &z.q);
                    let (a, b) = match flow {
                        Kick => (1.0, tau),
                        DampedKick(theta) => flows::kick_theta_tangent(r, tau, theta.value()),
                        KickDamp => ((-r * tau).exp(), one_minus_exp_neg_over(r, tau)),
                        _ => match self.inner.as_ref() {
                            Some(inner) => inner.tangent_coefficients(r, tau),
                            None => (1.0, tau),
                        },
                    };
                    tangent.kick_scaled(a, b);
                }
            }
            self.apply(sys, z, k, tau);
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

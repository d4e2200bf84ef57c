//! `csv2`, the second conformal Störmer–Verlet method of paper 003, eq. (2.16):
//!
//! ```text
//! (1 + γh/2) p½  = e^{−γh/2} pⁿ − h/2 ∇V(qⁿ)
//! (1 − γh/2) qⁿ⁺¹ = e^{−γh/2} [ (1 + γh/2) e^{−γh/2} qⁿ + h M⁻¹ p½ ]
//! pⁿ⁺¹           = e^{−γh/2} [ (1 − γh/2) p½ − h/2 ∇V(qⁿ⁺¹) ]
//! ```
//!
//! It is the generalized leapfrog for H_γ = T + V + γ qᵀp between two exact decays z ← e^{−γh/2} z,
//! except that the printed scheme (and its pendulum form, eq. 4.7) evaluates the force at qⁿ and
//! qⁿ⁺¹ rather than at the decayed e^{−γh/2}qⁿ and e^{+γh/2}qⁿ⁺¹ that the literal composition gives.
//! We implement the printed scheme, which the thesis's stability analysis (Ch. 3) is about. It is
//! still conformal symplectic: each line is a shear times a scaling, and the scalings multiply to
//! e^{−2γh} (tested); it is second order and symmetric, Φ₋ₕ ∘ Φₕ = id (both tested), so it can be
//! a triple-jump base. It is undefined at γh = 2.

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::sources::*;
use super::{Citation, Group, Kind, MethodInfo, Requirement, Steps};
use crate::error::StepError;
use crate::run::Stepper;
use crate::system::{MechanicalSystem, State, Vector};
use crate::tangent::Tangent;

/// The csv2 stepper; keeps ∇V(qⁿ⁺¹) for the next step.
pub struct Csv2<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    grad: Vector<S::Dim>,
    grad_valid: bool,
    v: Vector<S::Dim>,
    force_evaluations: u64,
}

impl<S: MechanicalSystem> Csv2<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A stepper for `sys`.
    pub fn new(sys: &S) -> Self {
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), nalgebra::U1);
        Self {
            grad: zero.clone(),
            grad_valid: false,
            v: zero,
            force_evaluations: 0,
        }
    }
}

impl<S: MechanicalSystem> Stepper<S> for Csv2<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        let a = 0.25 * sys.damping_rate() * h; // γh/2 with γ = r/2
        let e = (-a).exp();
        if !self.grad_valid {
            sys.grad_potential(&z.q, &mut self.grad);
            self.force_evaluations += 1;
        }
        // p½
        z.p *= e / (1.0 + a);
        z.p.axpy(-0.5 * h / (1.0 + a), &self.grad, 1.0);
        // qⁿ⁺¹
        sys.velocity(&z.q, &z.p, &mut self.v);
        z.q *= e * e * (1.0 + a) / (1.0 - a);
        z.q.axpy(e * h / (1.0 - a), &self.v, 1.0);
        // pⁿ⁺¹
        sys.grad_potential(&z.q, &mut self.grad);
        self.force_evaluations += 1;
        self.grad_valid = true;
        z.p *= e * (1.0 - a);
        z.p.axpy(-0.5 * e * h, &self.grad, 1.0);
        Ok(())
    }

    fn force_evaluations(&self) -> u64 {
        self.force_evaluations
    }

    fn restart(&mut self) {
        self.grad_valid = false;
    }

    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        let a = 0.25 * sys.damping_rate() * h;
        let e = (-a).exp();
        self.force_evaluations += tangent.load_hessian(sys, &z.q);
        tangent.kick_scaled(e / (1.0 + a), 0.5 * h / (1.0 + a));
        tangent.scale_q(e * e * (1.0 + a) / (1.0 - a));
        tangent.drift(e * h / (1.0 - a));
        self.step(sys, z, h)?;
        self.force_evaluations += tangent.load_hessian(sys, &z.q);
        tangent.kick_scaled(e * (1.0 - a), 0.5 * e * h);
        Ok(())
    }
}

/// Catalogue entry of `csv2`.
pub const CSV2_INFO: MethodInfo = MethodInfo {
    id: "csv2",
    name: "Conformal Störmer–Verlet 2 (CSV2)",
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
        equation: "eq. (2.16)",
    },
    group: Group::Conformal,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Own,
};

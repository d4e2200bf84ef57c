//! Implicit midpoint rules solved by Newton's method:
//! - `implicit_midpoint` on the full damped vector field (a non-geometric baseline under damping);
//! - `cimp`, the conformal implicit midpoint rule of paper 003 eq. (2.3). Multiplying (2.3) by
//!   e^{−γh/2} shows that it is Φ_{h/2} ∘ IMP_h ∘ Φ_{h/2}, where IMP_h is the implicit midpoint rule
//!   for the Hamiltonian H_γ = T + V + γ qᵀp of eq. (1.4) (q' = M⁻¹p + γq, p' = −∇V − γp) and
//!   Φ_τ(z) = e^{−γτ} z is the exact flow of the remaining linear part of eq. (1.5). The thesis's
//!   eq. (4.8) for the pendulum is exactly this; eq. (2.4) writes "h/2 ∇V(a + b)" where
//!   h ∇V((a + b)/2) is meant (the two agree only for a linear force).
//!
//! Newton solves for the midpoint m = (z₀ + z₁)/2 of m = z₀ + h/2 f(m), with the analytic
//! Jacobian where the system is separable with constant mass and conformal damping, and central
//! differences of the vector field otherwise. It stops when the correction is below 4 ulps of the
//! state, and reports a typed error if that takes more than 50 iterations.

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DVector, DefaultAllocator};

use super::sources::*;
use super::{Citation, Group, Kind, MethodInfo, Requirement, Steps};
use crate::error::StepError;
use crate::run::Stepper;
use crate::system::{MechanicalSystem, State, Vector};
use crate::tangent::Tangent;

/// Which vector field the midpoint rule discretizes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MidpointField {
    /// The damped field (q', p') = (∂H/∂p, −∂H/∂q − εDM⁻¹p).
    Full,
    /// The conformal Hamiltonian part of paper 003 eq. (1.5): (M⁻¹p + γq, −∇V − γp); the step is
    /// wrapped in the exact decay e^{−γh/2} on both sides.
    Conformal,
}

const MAX_NEWTON: usize = 50;

/// Newton-based implicit midpoint stepper.
pub struct ImplicitMidpoint<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    field: MidpointField,
    analytic_jacobian: bool,
    n: usize,
    z0: DVector<f64>,
    mid: DVector<f64>,
    f: DVector<f64>,
    jac: DMatrix<f64>,
    hess: DMatrix<f64>,
    minv: DMatrix<f64>,
    work: State<S::Dim>,
    dq: Vector<S::Dim>,
    dp: Vector<S::Dim>,
    scratch: Vector<S::Dim>,
    force_evaluations: u64,
}

impl<S: MechanicalSystem> ImplicitMidpoint<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A stepper for `field` on `sys`.
    pub fn new(sys: &S, field: MidpointField) -> Self {
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), nalgebra::U1);
        let n = zero.len();
        let structure = sys.structure();
        let probe = State {
            q: zero.clone(),
            p: zero.clone(),
        };
        let minv = Tangent::new(sys, &probe).minv;
        Self {
            field,
            analytic_jacobian: structure.separable_constant_mass && structure.conformal_damping,
            n,
            z0: DVector::zeros(2 * n),
            mid: DVector::zeros(2 * n),
            f: DVector::zeros(2 * n),
            jac: DMatrix::zeros(2 * n, 2 * n),
            hess: DMatrix::zeros(n, n),
            minv,
            work: probe,
            dq: zero.clone(),
            dp: zero.clone(),
            scratch: zero,
            force_evaluations: 0,
        }
    }

    fn gamma(sys: &S) -> f64 {
        0.5 * sys.damping_rate()
    }

    /// Loads `x` (length 2n) into the work state.
    fn load(&mut self, x: &DVector<f64>) {
        let n = self.n;
        for i in 0..n {
            self.work.q[i] = x[i];
            self.work.p[i] = x[n + i];
        }
    }

    /// f(x) into `self.f`.
    fn eval(&mut self, sys: &S, x: &DVector<f64>) {
        self.load(x);
        let n = self.n;
        match self.field {
            MidpointField::Full => {
                sys.vector_field(
                    &self.work.q,
                    &self.work.p,
                    &mut self.dq,
                    &mut self.dp,
                    &mut self.scratch,
                );
            }
            MidpointField::Conformal => {
                let g = Self::gamma(sys);
                sys.velocity(&self.work.q, &self.work.p, &mut self.dq);
                self.dq.axpy(g, &self.work.q, 1.0);
                sys.grad_potential(&self.work.q, &mut self.dp);
                self.dp.axpy(g, &self.work.p, 1.0);
                self.dp.neg_mut();
            }
        }
        self.force_evaluations += 1;
        for i in 0..n {
            self.f[i] = self.dq[i];
            self.f[n + i] = self.dp[i];
        }
    }

    /// ∂f/∂z at x into `self.jac`.
    fn jacobian(&mut self, sys: &S, x: &DVector<f64>) {
        let n = self.n;
        if self.analytic_jacobian {
            self.load(x);
            self.force_evaluations += sys.hess_potential(&self.work.q, &mut self.hess);
            let g = Self::gamma(sys);
            let (diag_q, diag_p) = match self.field {
                MidpointField::Full => (0.0, -2.0 * g),
                MidpointField::Conformal => (g, -g),
            };
            self.jac.fill(0.0);
            self.jac.view_mut((0, n), (n, n)).copy_from(&self.minv);
            self.jac.view_mut((n, 0), (n, n)).copy_from(&(-&self.hess));
            for i in 0..n {
                self.jac[(i, i)] = diag_q;
                self.jac[(n + i, n + i)] = diag_p;
            }
        } else {
            let mut xx = x.clone();
            for j in 0..2 * n {
                let delta = 1e-6 * (1.0 + x[j].abs());
                xx[j] = x[j] + delta;
                self.eval(sys, &xx);
                let fp = self.f.clone();
                xx[j] = x[j] - delta;
                self.eval(sys, &xx);
                xx[j] = x[j];
                for i in 0..2 * n {
                    self.jac[(i, j)] = (fp[i] - self.f[i]) / (2.0 * delta);
                }
            }
        }
    }

    /// Solves m = z0 + h/2 f(m) for `self.mid`, leaving the Jacobian at the last iterate in `self.jac`.
    fn solve_midpoint(&mut self, sys: &S, h: f64) -> Result<(), StepError> {
        let n2 = 2 * self.n;
        let z0 = self.z0.clone();
        self.eval(sys, &z0);
        self.mid.copy_from(&z0);
        self.mid.axpy(0.5 * h, &self.f, 1.0);
        let mut last = f64::INFINITY;
        for iteration in 1..=MAX_NEWTON {
            let mid = self.mid.clone();
            self.jacobian(sys, &mid);
            self.eval(sys, &mid);
            // G(m) = m − z0 − h/2 f(m); G'(m) = I − h/2 J(m).
            let mut residual: DVector<f64> = &mid - &z0;
            residual.axpy(-0.5 * h, &self.f, 1.0);
            let g_prime = DMatrix::<f64>::identity(n2, n2) - (0.5 * h) * &self.jac;
            let Some(correction) = solve(g_prime, &residual) else {
                return Err(StepError::NewtonFailed {
                    iterations: iteration,
                    residual: f64::NAN,
                });
            };
            self.mid -= &correction;
            let size = correction.amax();
            let scale = self.mid.amax().max(1e-300);
            // Converged at round-off, or stalled there: a correction below 1e-12 of the state that
            // no longer halves is round-off noise, not progress.
            if size <= 4.0 * f64::EPSILON * scale || (size <= 1e-12 * scale && size > 0.5 * last) {
                // The Jacobian stays the one at the previous iterate: the tangent map only needs
                // it to O(correction), and re-evaluating would cost a force evaluation per step.
                return Ok(());
            }
            if !size.is_finite() {
                return Err(StepError::NewtonFailed {
                    iterations: iteration,
                    residual: size,
                });
            }
            last = size;
        }
        Err(StepError::NewtonFailed {
            iterations: MAX_NEWTON,
            residual: last,
        })
    }

    fn advance(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        let n = self.n;
        let decay = match self.field {
            MidpointField::Full => 1.0,
            MidpointField::Conformal => (-0.5 * Self::gamma(sys) * h).exp(),
        };
        for i in 0..n {
            self.z0[i] = decay * z.q[i];
            self.z0[n + i] = decay * z.p[i];
        }
        self.solve_midpoint(sys, h)?;
        for i in 0..n {
            z.q[i] = decay * (2.0 * self.mid[i] - self.z0[i]);
            z.p[i] = decay * (2.0 * self.mid[n + i] - self.z0[n + i]);
        }
        Ok(())
    }
}

impl<S: MechanicalSystem> Stepper<S> for ImplicitMidpoint<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        self.advance(sys, z, h)
    }

    fn force_evaluations(&self) -> u64 {
        self.force_evaluations
    }

    fn check_interval(&self) -> u64 {
        1
    }

    /// (I − h/2 J(m)) δz₁ = (I + h/2 J(m)) δz₀, times e^{−γh} for cimp. J is the Jacobian Newton
    /// used last where it is analytic (separable H, conformal damping: it differs from J at the
    /// converged midpoint by the last correction); otherwise J at the midpoint from the system's
    /// second derivatives (and its damping projector's derivative), which Newton's finite
    /// differences only approximate. The linear solve allocates, as Newton's does.
    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        self.advance(sys, z, h)?;
        if !self.analytic_jacobian {
            let mid = self.mid.clone();
            self.load(&mid);
            self.force_evaluations +=
                tangent.load_second_derivatives(sys, &self.work.q, &self.work.p);
            tangent.load_damping(sys, &self.work.q, &self.work.p)?;
            tangent.field_jacobian(sys.damping_rate(), &mut self.jac);
        }
        let n2 = 2 * self.n;
        let lhs = DMatrix::<f64>::identity(n2, n2) - (0.5 * h) * &self.jac;
        let rhs = DMatrix::<f64>::identity(n2, n2) + (0.5 * h) * &self.jac;
        let step_jac = solve_matrix(lhs, &rhs).ok_or(StepError::NewtonFailed {
            iterations: 0,
            residual: f64::NAN,
        })?;
        let decay2 = match self.field {
            MidpointField::Full => 1.0,
            MidpointField::Conformal => (-Self::gamma(sys) * h).exp(),
        };
        tangent.jac = compose_scaled(decay2, &step_jac, &tangent.jac);
        Ok(())
    }
}

// Dense linear algebra lives outside the generic impls: with `Allocator<S::Dim>` bounds in scope,
// type inference for nalgebra's dynamic-size operations goes astray.

/// Solves a x = b by LU with partial pivoting.
fn solve(a: DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    a.lu().solve(b)
}

/// Solves a X = b by LU with partial pivoting.
fn solve_matrix(a: DMatrix<f64>, b: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    a.lu().solve(b)
}

/// c · a · b.
fn compose_scaled(c: f64, a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    (a * b) * c
}

/// Catalogue entry of `implicit_midpoint`.
pub const IMPLICIT_MIDPOINT_INFO: MethodInfo = MethodInfo {
    id: "implicit_midpoint",
    name: "Implicit midpoint",
    order: 2,
    kind: Kind::Implicit,
    symplectic: true,
    conformal_symplectic: false,
    symmetric: true,
    requirements: &[],
    reference: Citation {
        paper: GNI,
        equation: "Sec. II.1.1",
    },
    group: Group::Baseline,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Own,
};

/// Catalogue entry of `cimp`.
pub const CIMP_INFO: MethodInfo = MethodInfo {
    id: "cimp",
    name: "Conformal implicit midpoint (CIMP)",
    order: 2,
    kind: Kind::Implicit,
    symplectic: true,
    conformal_symplectic: true,
    symmetric: true,
    requirements: &[
        Requirement::SeparableConstantMass,
        Requirement::ConformalDamping,
    ],
    reference: Citation {
        paper: FLOYD,
        equation: "eq. (2.3)",
    },
    group: Group::Conformal,
    options: &[],
    no_step_jacobian: None,
    steps: Steps::Own,
};

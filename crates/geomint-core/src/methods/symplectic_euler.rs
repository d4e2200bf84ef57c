//! Symplectic Euler for a general, non-separable H(q, p) (paper 001 eqs. 42–43) and its adjoint
//! (001 footnote 3). Separable systems never get here: for them both are explicit splittings
//! (see `splitting`).
//!
//! - `symplectic_euler`: p₁ = p − h (∂H/∂q(q, p₁) + r P(q) p₁), then q₁ = q + h ∂H/∂p(q, p₁);
//! - `symplectic_euler_adjoint`: q₁ = q + h ∂H/∂p(q₁, p), then p₁ = p − h (∂H/∂q(q₁, p) + r P(q₁) p).
//!
//! The damping r P(q) p (zero in the paper's conservative setting) is taken with the new momentum
//! in the first and the old one in the second, as in the separable splittings, so that the two
//! stay adjoint to each other. The implicit stage is solved in closed form where the chart makes
//! it explicit (the system's `solve_momentum_stage` / `solve_position_stage`: a cyclic coordinate
//! makes it triangular), and by Newton's method with the analytic second derivatives of H
//! otherwise (`hessian_h`; central differences of ∂H/∂q, ∂H/∂p for systems without them).
//! Newton works in preallocated buffers with an in-place LU, so a step allocates nothing.

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator};

use crate::error::StepError;
use crate::run::Stepper;
use crate::system::{MechanicalSystem, State, Vector};
use crate::tangent::Tangent;

const MAX_NEWTON: usize = 50;

/// Which of the two variants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// 001 eqs. (42)–(43): implicit in the new momentum.
    Original,
    /// The adjoint: implicit in the new position.
    Adjoint,
}

/// Symplectic Euler on a non-separable Hamiltonian.
pub struct GeneralSymplecticEuler<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    variant: Variant,
    /// Newton matrix, and the three blocks of ∇²H.
    jac: DMatrix<f64>,
    hqq: DMatrix<f64>,
    hqp: DMatrix<f64>,
    hpp: DMatrix<f64>,
    /// The damping projector P(q) as a matrix (columns P e_j).
    proj: DMatrix<f64>,
    x: Vector<S::Dim>,
    fx: Vector<S::Dim>,
    work: Vector<S::Dim>,
    work2: Vector<S::Dim>,
    pivots: Vec<usize>,
    force_evaluations: u64,
    /// The state before a tangent step, and a column of the tangent map's linear solve.
    start: State<S::Dim>,
    column: Vec<f64>,
}

impl<S: MechanicalSystem> GeneralSymplecticEuler<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A stepper for `sys`.
    pub fn new(sys: &S, variant: Variant) -> Self {
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), nalgebra::U1);
        let n = zero.len();
        Self {
            variant,
            jac: DMatrix::zeros(n, n),
            hqq: DMatrix::zeros(n, n),
            hqp: DMatrix::zeros(n, n),
            hpp: DMatrix::zeros(n, n),
            proj: DMatrix::zeros(n, n),
            x: zero.clone(),
            fx: zero.clone(),
            work: zero.clone(),
            work2: zero.clone(),
            pivots: vec![0; n],
            force_evaluations: 0,
            start: State {
                q: zero.clone(),
                p: zero.clone(),
            },
            column: vec![0.0; n],
        }
    }

    /// The damping force r P(q) v into `out` (zero without damping).
    fn damping(sys: &S, q: &Vector<S::Dim>, v: &Vector<S::Dim>, out: &mut Vector<S::Dim>) {
        if sys.damping_rate() == 0.0 {
            out.fill(0.0);
        } else {
            sys.damping_force(q, v, out);
        }
    }

    /// Fills `self.proj` with r P(q).
    fn load_damping_matrix(&mut self, sys: &S, q: &Vector<S::Dim>) {
        let n = self.x.len();
        let r = sys.damping_rate();
        if r == 0.0 {
            self.proj.fill(0.0);
            return;
        }
        for j in 0..n {
            self.work.fill(0.0);
            self.work[j] = 1.0;
            sys.project_damped(q, &self.work, &mut self.work2);
            for i in 0..n {
                self.proj[(i, j)] = r * self.work2[i];
            }
        }
    }

    /// Solves p₁ = p − h (∂H/∂q(q, p₁) + r P(q) p₁) for p₁ (into `p1`).
    fn momentum_stage(
        &mut self,
        sys: &S,
        q: &Vector<S::Dim>,
        p: &Vector<S::Dim>,
        h: f64,
        p1: &mut Vector<S::Dim>,
    ) -> Result<(), StepError> {
        if sys.solve_momentum_stage(q, p, h, p1) {
            self.force_evaluations += 1;
            return Ok(());
        }
        let n = self.x.len();
        self.load_damping_matrix(sys, q);
        // Start from the explicit Euler guess p − h G(q, p).
        sys.dh_dq(q, p, &mut self.fx);
        Self::damping(sys, q, p, &mut self.work);
        self.x.copy_from(p);
        self.x.axpy(-h, &self.fx, 1.0);
        self.x.axpy(-h, &self.work, 1.0);
        self.force_evaluations += 1;
        let mut last = f64::INFINITY;
        for iteration in 1..=MAX_NEWTON {
            // Residual F = x − p + h (∂H/∂q(q, x) + r P x), Jacobian I + h (H_qp + r P).
            sys.dh_dq(q, &self.x, &mut self.fx);
            self.force_evaluations += 1;
            Self::damping(sys, q, &self.x, &mut self.work);
            for i in 0..n {
                self.fx[i] = self.x[i] - p[i] + h * (self.fx[i] + self.work[i]);
            }
            self.mixed_derivative(sys, q);
            for i in 0..n {
                for j in 0..n {
                    let identity = if i == j { 1.0 } else { 0.0 };
                    self.jac[(i, j)] = identity + h * (self.hqp[(i, j)] + self.proj[(i, j)]);
                }
            }
            let step = self.newton_update(iteration, &mut last)?;
            if step {
                p1.copy_from(&self.x);
                return Ok(());
            }
        }
        Err(StepError::NewtonFailed {
            iterations: MAX_NEWTON,
            residual: last,
        })
    }

    /// Solves q₁ = q + h ∂H/∂p(q₁, p) for q₁ (into `q1`).
    fn position_stage(
        &mut self,
        sys: &S,
        q: &Vector<S::Dim>,
        p: &Vector<S::Dim>,
        h: f64,
        q1: &mut Vector<S::Dim>,
    ) -> Result<(), StepError> {
        if sys.solve_position_stage(q, p, h, q1) {
            return Ok(());
        }
        let n = self.x.len();
        sys.dh_dp(q, p, &mut self.fx);
        self.x.copy_from(q);
        self.x.axpy(h, &self.fx, 1.0);
        let mut last = f64::INFINITY;
        for iteration in 1..=MAX_NEWTON {
            // Residual G = x − q − h ∂H/∂p(x, p), Jacobian I − h H_pq = I − h H_qpᵀ.
            sys.dh_dp(&self.x, p, &mut self.fx);
            for i in 0..n {
                self.fx[i] = self.x[i] - q[i] - h * self.fx[i];
            }
            self.position_derivative(sys, p);
            for i in 0..n {
                for j in 0..n {
                    let identity = if i == j { 1.0 } else { 0.0 };
                    self.jac[(i, j)] = identity - h * self.hqp[(j, i)];
                }
            }
            if self.newton_update(iteration, &mut last)? {
                q1.copy_from(&self.x);
                return Ok(());
            }
        }
        Err(StepError::NewtonFailed {
            iterations: MAX_NEWTON,
            residual: last,
        })
    }

    /// H_qp at (q, self.x) into `self.hqp`: analytic where the system has it, else central
    /// differences of ∂H/∂q in p.
    fn mixed_derivative(&mut self, sys: &S, q: &Vector<S::Dim>) {
        if sys.hessian_h(q, &self.x, &mut self.hqq, &mut self.hqp, &mut self.hpp) {
            return;
        }
        let n = self.x.len();
        self.work.copy_from(&self.x);
        for j in 0..n {
            let pj = self.x[j];
            let delta = 1e-6 * (1.0 + pj.abs());
            self.work[j] = pj + delta;
            sys.dh_dq(q, &self.work, &mut self.work2);
            for i in 0..n {
                self.hqp[(i, j)] = self.work2[i];
            }
            self.work[j] = pj - delta;
            sys.dh_dq(q, &self.work, &mut self.work2);
            for i in 0..n {
                self.hqp[(i, j)] = (self.hqp[(i, j)] - self.work2[i]) / (2.0 * delta);
            }
            self.work[j] = pj;
            self.force_evaluations += 2;
        }
    }

    /// H_qp at (self.x, p) into `self.hqp` (the position stage needs ∂(∂H/∂p)/∂q = H_qpᵀ).
    fn position_derivative(&mut self, sys: &S, p: &Vector<S::Dim>) {
        if sys.hessian_h(&self.x, p, &mut self.hqq, &mut self.hqp, &mut self.hpp) {
            return;
        }
        // Central differences of ∂H/∂p in q give H_pq = H_qpᵀ column by column.
        let n = self.x.len();
        self.work.copy_from(&self.x);
        for j in 0..n {
            let qj = self.x[j];
            let delta = 1e-6 * (1.0 + qj.abs());
            self.work[j] = qj + delta;
            sys.dh_dp(&self.work, p, &mut self.work2);
            for i in 0..n {
                self.hqp[(j, i)] = self.work2[i];
            }
            self.work[j] = qj - delta;
            sys.dh_dp(&self.work, p, &mut self.work2);
            for i in 0..n {
                self.hqp[(j, i)] = (self.hqp[(j, i)] - self.work2[i]) / (2.0 * delta);
            }
            self.work[j] = qj;
        }
    }

    /// x ← x − J⁻¹ F with J in `self.jac` and F in `self.fx`; true once converged.
    fn newton_update(&mut self, iteration: usize, last: &mut f64) -> Result<bool, StepError> {
        if !lu_solve_in_place(&mut self.jac, self.fx.as_mut_slice(), &mut self.pivots) {
            return Err(StepError::NewtonFailed {
                iterations: iteration,
                residual: f64::NAN,
            });
        }
        self.x -= &self.fx;
        let size = self.fx.amax();
        let scale = self.x.amax().max(1e-300);
        if !size.is_finite() {
            return Err(StepError::NewtonFailed {
                iterations: iteration,
                residual: size,
            });
        }
        // Converged at round-off, or stalled there (a correction that no longer halves).
        let done =
            size <= 4.0 * f64::EPSILON * scale || (size <= 1e-12 * scale && size > 0.5 * *last);
        *last = size;
        Ok(done)
    }
}

/// Solves A x = b in place by LU with partial pivoting (A is overwritten, b becomes x). Returns
/// false for a singular A. No allocation.
pub fn lu_solve_in_place(a: &mut DMatrix<f64>, b: &mut [f64], pivots: &mut [usize]) -> bool {
    if !lu_factor_in_place(a, pivots) {
        return false;
    }
    lu_solve_factored(a, pivots, b);
    true
}

/// Factors A = P⁻¹LU in place (L's multipliers below the diagonal, U on and above it, the row
/// swaps in `pivots`); false for a singular A.
pub fn lu_factor_in_place(a: &mut DMatrix<f64>, pivots: &mut [usize]) -> bool {
    let n = a.nrows();
    for k in 0..n {
        let (mut pivot, mut best) = (k, a[(k, k)].abs());
        for i in k + 1..n {
            if a[(i, k)].abs() > best {
                pivot = i;
                best = a[(i, k)].abs();
            }
        }
        if best == 0.0 || !best.is_finite() {
            return false;
        }
        pivots[k] = pivot;
        if pivot != k {
            a.swap_rows(pivot, k);
        }
        for i in k + 1..n {
            let factor = a[(i, k)] / a[(k, k)];
            a[(i, k)] = factor;
            for j in k + 1..n {
                a[(i, j)] -= factor * a[(k, j)];
            }
        }
    }
    true
}

/// Solves with the factors of [`lu_factor_in_place`]: b becomes x.
pub fn lu_solve_factored(a: &DMatrix<f64>, pivots: &[usize], b: &mut [f64]) {
    let n = b.len();
    for k in 0..n {
        if pivots[k] != k {
            b.swap(pivots[k], k);
        }
        for i in k + 1..n {
            b[i] -= a[(i, k)] * b[k];
        }
    }
    for k in (0..n).rev() {
        let mut s = b[k];
        for j in k + 1..n {
            s -= a[(k, j)] * b[j];
        }
        b[k] = s / a[(k, k)];
    }
}

impl<S: MechanicalSystem> Stepper<S> for GeneralSymplecticEuler<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        let mut next = z.clone();
        match self.variant {
            Variant::Original => {
                self.momentum_stage(sys, &z.q, &z.p, h, &mut next.p)?;
                sys.dh_dp(&z.q, &next.p, &mut self.work);
                next.q.copy_from(&z.q);
                next.q.axpy(h, &self.work, 1.0);
            }
            Variant::Adjoint => {
                self.position_stage(sys, &z.q, &z.p, h, &mut next.q)?;
                sys.dh_dq(&next.q, &z.p, &mut self.work);
                Self::damping(sys, &next.q, &z.p, &mut self.work2);
                self.force_evaluations += 1;
                next.p.copy_from(&z.p);
                next.p.axpy(-h, &self.work, 1.0);
                next.p.axpy(-h, &self.work2, 1.0);
            }
        }
        *z = next;
        Ok(())
    }

    fn force_evaluations(&self) -> u64 {
        self.force_evaluations
    }

    /// The stage equations differentiated (module docs for the stages), with the second
    /// derivatives of H at the implicit stage's point and P = I unless the damping is a
    /// projector:
    /// - original, at (q, p₁): (I + h(H_qp + rP))δp₁ = δp − h(H_qq + rD_{p₁})δq, then
    ///   δq₁ = δq + h(H_pq δq + H_pp δp₁);
    /// - adjoint, at (q₁, p): (I − hH_pq)δq₁ = δq + hH_pp δp, then
    ///   δp₁ = δp − h((H_qq + rD_p)δq₁ + (H_qp + rP)δp).
    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        self.start.q.copy_from(&z.q);
        self.start.p.copy_from(&z.p);
        self.step(sys, z, h)?;
        let n = z.q.len();
        let r = sys.damping_rate();
        let projector = tangent.projector_damping();
        // The implicit stage's point: (q, p₁), or (q₁, p).
        let (q, p) = match self.variant {
            Variant::Original => (&self.start.q, &z.p),
            Variant::Adjoint => (&z.q, &self.start.p),
        };
        self.force_evaluations += tangent.load_second_derivatives(sys, q, p);
        tangent.load_damping(sys, q, p)?;
        let pr = |i: usize, j: usize| {
            if projector {
                tangent.proj[(i, j)]
            } else if i == j {
                1.0
            } else {
                0.0
            }
        };
        let dp = |i: usize, j: usize| {
            if projector {
                tangent.dproj[(i, j)]
            } else {
                0.0
            }
        };
        for i in 0..n {
            for j in 0..n {
                let identity = if i == j { 1.0 } else { 0.0 };
                self.jac[(i, j)] = match self.variant {
                    Variant::Original => identity + h * (tangent.hqp[(i, j)] + r * pr(i, j)),
                    Variant::Adjoint => identity - h * tangent.hqp[(j, i)],
                };
            }
        }
        if !lu_factor_in_place(&mut self.jac, &mut self.pivots) {
            return Err(StepError::NewtonFailed {
                iterations: 0,
                residual: f64::NAN,
            });
        }
        let w = &mut tangent.jac;
        for c in 0..w.ncols() {
            match self.variant {
                Variant::Original => {
                    for i in 0..n {
                        let mut acc = w[(n + i, c)];
                        for j in 0..n {
                            acc -= h * (tangent.hess[(i, j)] + r * dp(i, j)) * w[(j, c)];
                        }
                        self.column[i] = acc;
                    }
                    lu_solve_factored(&self.jac, &self.pivots, &mut self.column);
                    for i in 0..n {
                        let mut acc = w[(i, c)];
                        for j in 0..n {
                            acc += h
                                * (tangent.hqp[(j, i)] * w[(j, c)]
                                    + tangent.hpp[(i, j)] * self.column[j]);
                        }
                        self.x[i] = acc;
                    }
                    for i in 0..n {
                        w[(i, c)] = self.x[i];
                        w[(n + i, c)] = self.column[i];
                    }
                }
                Variant::Adjoint => {
                    for i in 0..n {
                        let mut acc = w[(i, c)];
                        for j in 0..n {
                            acc += h * tangent.hpp[(i, j)] * w[(n + j, c)];
                        }
                        self.column[i] = acc;
                    }
                    lu_solve_factored(&self.jac, &self.pivots, &mut self.column);
                    for i in 0..n {
                        let mut acc = w[(n + i, c)];
                        for j in 0..n {
                            acc -= h
                                * ((tangent.hess[(i, j)] + r * dp(i, j)) * self.column[j]
                                    + (tangent.hqp[(i, j)] + r * pr(i, j)) * w[(n + j, c)]);
                        }
                        self.x[i] = acc;
                    }
                    for i in 0..n {
                        w[(i, c)] = self.column[i];
                        w[(n + i, c)] = self.x[i];
                    }
                }
            }
        }
        Ok(())
    }
}

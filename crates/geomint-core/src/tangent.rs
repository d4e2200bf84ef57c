//! Tangent dynamics: a step's tangent map ∂Φ/∂z applied to k deviation vectors, built from the
//! tangent maps of the step's own pieces — each exact sub-flow's (drift, kick, the exact damping
//! decay and kick-and-damp of paper 000), a Runge–Kutta stage's linearisation, an implicit
//! stage's by implicit differentiation. For a splitting the product of the sub-flows' maps is
//! the step's Jacobian exactly (not a finite-difference approximation of it), so a symplectic
//! method's tangent map is symplectic and a conformal symplectic one's conformal (Skokos &
//! Gerlach, Phys. Rev. E 82 (2010) 036704, "the tangent map method").
//!
//! [`Tangent`] holds the propagated matrix (2n × k, δq rows first) and the derivatives the maps
//! need, in buffers allocated once: ∇²V or the blocks of ∇²H, M⁻¹, and for damping r P(q) with P
//! an orthogonal projector that depends on q (the spring direction of the elastic pendulum)
//! P(q) itself and ∂(P(q)v)/∂q. With k = 2n and the identity as the start it is the step's
//! Jacobian (the determinant diagnostics); with k < 2n it carries deviation vectors (chaos
//! indicators, see `chaos`).
//!
//! Tangent maps of the sub-flows, with H = ∇²V(q) and D_v = ∂(P(q)v)/∂q:
//! - drift q ← q + τM⁻¹p:                δq ← δq + τM⁻¹δp;
//! - kick p ← p − τ∇V(q):                δp ← δp − τHδq;
//! - decay p ← p − cPp:                   δp ← δp − c(Pδp + D_p δq)  (e^{−rτ}δp for P = I);
//! - kick-and-damp p ← p − τg + P(−cp + dg): δp ← δp − τHδq + P(−cδp + dHδq) + D_u δq,
//!   u = −cp + dg;
//! - θ-kick (I + aP)p₁ = p − (1−θ)rτPp − τg, a = θrτ:
//!   (I + aP)δp₁ = δp − (1−θ)rτ(Pδp + D_p δq) − τHδq − a D_{p₁} δq, with (I + aP)⁻¹ = I −
//!   a/(1+a) P;
//! - a Runge–Kutta step of p' = −g − rPp (q frozen): p₁ = p + (A−1)Pp − τg − (B−τ)Pg, where
//!   p ↦ Ap − Bg is the step for P = I (A = R(−rτ), B = τS(−rτ), polynomials or rational
//!   functions f with f(−rτP) = I + (f(−rτ) − 1)P for a projector), so
//!   δp₁ = δp + (A−1)Pδp − τHδq − (B−τ)PHδq + D_u δq, u = (A−1)p − (B−τ)g.
//!
//! The products are written as loops with a fixed order of operations (the order nalgebra's
//! small-matrix products use, which the Jacobian diagnostics were pinned with), so the same
//! input gives the same bits, and a specialised kernel can repeat them exactly.

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator, Dim};

use crate::error::StepError;
use crate::flows;
use crate::system::{MechanicalSystem, State, Vector};

/// The propagated matrix of a step's tangent map and the work space of its sub-flows.
#[derive(Clone, Debug)]
pub struct Tangent<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// The propagated matrix (2n × k): rows 0..n are δq, n..2n are δp; column j is the image of
    /// the j-th starting column (the identity for the Jacobian, deviation vectors otherwise).
    pub jac: DMatrix<f64>,
    /// ∇²V, or ∂²H/∂q² for a general H, at the current point.
    pub hess: DMatrix<f64>,
    /// ∂²H/∂q∂p (entry (i, j) = ∂²H/∂q_i∂p_j) for a general H.
    pub hqp: DMatrix<f64>,
    /// ∂²H/∂p² for a general H.
    pub hpp: DMatrix<f64>,
    /// M⁻¹ as a matrix (constant mass).
    pub minv: DMatrix<f64>,
    /// P(q) as a matrix, for a state-dependent projector damping.
    pub proj: DMatrix<f64>,
    /// ∂(P(q)v)/∂q for the v of the last [`Tangent::load_projector`].
    pub dproj: DMatrix<f64>,
    /// Work matrix (n × k).
    pub work: DMatrix<f64>,
    /// Work vectors of the system's dimension.
    e: Vector<D>,
    pe: Vector<D>,
    /// Whether the damping is r P(q) with P a projector that depends on q (else P = I, or no
    /// damping).
    projector: bool,
}

impl<D: Dim> Tangent<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// The identity Jacobian (k = 2n) for `sys` at `z`, with M⁻¹ read off `sys`.
    pub fn new<S: MechanicalSystem<Dim = D>>(sys: &S, z: &State<D>) -> Self {
        let n = z.q.len();
        Self::with_columns(sys, z, DMatrix::identity(2 * n, 2 * n))
    }

    /// A tangent map acting on the columns of `start` (2n × k).
    pub fn with_columns<S: MechanicalSystem<Dim = D>>(
        sys: &S,
        z: &State<D>,
        start: DMatrix<f64>,
    ) -> Self {
        let n = z.q.len();
        let k = start.ncols();
        assert_eq!(start.nrows(), 2 * n, "deviation vectors have 2n rows");
        let mut minv = DMatrix::zeros(n, n);
        let mut e = z.p.clone();
        let mut v = z.p.clone();
        for j in 0..n {
            e.fill(0.0);
            e[j] = 1.0;
            sys.velocity(&z.q, &e, &mut v);
            for i in 0..n {
                minv[(i, j)] = v[i];
            }
        }
        let st = sys.structure();
        Self {
            jac: start,
            hess: DMatrix::zeros(n, n),
            hqp: DMatrix::zeros(n, n),
            hpp: DMatrix::zeros(n, n),
            minv,
            proj: DMatrix::identity(n, n),
            dproj: DMatrix::zeros(n, n),
            work: DMatrix::zeros(n, k),
            e,
            pe: v,
            projector: sys.damping_rate() != 0.0 && !st.conformal_damping,
        }
    }

    fn n(&self) -> usize {
        self.minv.nrows()
    }

    /// Deviation vectors carried (columns).
    pub fn columns(&self) -> usize {
        self.jac.ncols()
    }

    /// Whether the damping is a state-dependent projector r P(q) (else P = I or undamped).
    pub fn projector_damping(&self) -> bool {
        self.projector
    }

    /// Resets the propagated matrix to the identity (k = 2n).
    pub fn reset(&mut self) {
        self.jac.fill_with_identity();
    }

    /// δq ← δq + τ M⁻¹ δp.
    pub fn drift(&mut self, tau: f64) {
        let n = self.n();
        if n == 0 {
            return;
        }
        let minv = &self.minv;
        for column in self.jac.as_mut_slice().chunks_exact_mut(2 * n) {
            let (dq, dp) = column.split_at_mut(n);
            flows::drift_tangent(dq, dp, |i, j| tau * minv[(i, j)]);
        }
    }

    /// δp ← a δp − b ∇²V δq, with ∇²V evaluated at q into `hess` beforehand.
    pub fn kick_scaled(&mut self, a: f64, b: f64) {
        let n = self.n();
        if n == 0 {
            return;
        }
        let nb = -b;
        let hess = &self.hess;
        for column in self.jac.as_mut_slice().chunks_exact_mut(2 * n) {
            let (dq, dp) = column.split_at_mut(n);
            flows::kick_tangent(dp, dq, a, |i, j| nb * hess[(i, j)]);
        }
    }

    /// δq ← c δq.
    pub fn scale_q(&mut self, c: f64) {
        let n = self.n();
        for col in 0..self.columns() {
            for i in 0..n {
                self.jac[(i, col)] *= c;
            }
        }
    }

    /// Evaluates ∇²V at q into `hess`; returns the gradient evaluations it took.
    pub fn load_hessian<S: MechanicalSystem<Dim = D>>(&mut self, sys: &S, q: &Vector<D>) -> u64 {
        sys.hess_potential(q, &mut self.hess)
    }

    /// Loads P(q) into `proj` and ∂(P(q)v)/∂q into `dproj`, for a state-dependent projector
    /// damping. Returns false when the system cannot give the derivative.
    pub fn load_projector<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        q: &Vector<D>,
        v: &Vector<D>,
    ) -> bool {
        let n = self.n();
        for j in 0..n {
            self.e.fill(0.0);
            self.e[j] = 1.0;
            sys.project_damped(q, &self.e, &mut self.pe);
            for i in 0..n {
                self.proj[(i, j)] = self.pe[i];
            }
        }
        sys.projector_derivative(q, v, &mut self.dproj)
    }

    /// For a state-dependent projector damping, loads P(q) and ∂(P(q)p)/∂q at (q, p) (nothing
    /// otherwise); an error when the system cannot give the derivative.
    pub fn load_damping<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        q: &Vector<D>,
        p: &Vector<D>,
    ) -> Result<(), StepError> {
        if self.projector && !self.load_projector(sys, q, p) {
            return Err(no_projector_derivative());
        }
        Ok(())
    }

    /// Loads ∂(P(q)v)/∂q only (P(q) as loaded before, at the same q).
    pub fn load_projector_derivative<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        q: &Vector<D>,
        v: &Vector<D>,
    ) -> bool {
        sys.projector_derivative(q, v, &mut self.dproj)
    }

    /// The second derivatives of H at (q, p) into `hess`, `hqp`, `hpp`: the system's own where it
    /// has them, else those of a separable H with constant mass (∇²V, 0, M⁻¹). Returns the
    /// gradient evaluations used.
    pub fn load_second_derivatives<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        q: &Vector<D>,
        p: &Vector<D>,
    ) -> u64 {
        if sys.hessian_h(q, p, &mut self.hess, &mut self.hqp, &mut self.hpp) {
            return 0;
        }
        self.hqp.fill(0.0);
        self.hpp.copy_from(&self.minv);
        sys.hess_potential(q, &mut self.hess)
    }

    /// δp ← δp − c (P δp + D_p δq): the exact decay p ← p − cP(q)p with `proj` and `dproj`
    /// (v = p) loaded at the state before it.
    pub fn decay_projector(&mut self, c: f64) {
        let n = self.n();
        for col in 0..self.columns() {
            self.apply_block(Block::ProjP, col);
            self.apply_block_add(Block::DprojQ, col);
            for i in 0..n {
                self.jac[(n + i, col)] -= c * self.work[(i, col)];
            }
        }
    }

    /// The kick-and-damp p ← p − τg + P(−cp + dg), with `hess` at q and `proj`, `dproj`
    /// (v = −cp + dg) loaded: δp ← δp − τHδq + P(−cδp + dHδq) + D_u δq.
    pub fn kick_damp_projector(&mut self, tau: f64, c: f64, d: f64) {
        let n = self.n();
        let k = self.columns();
        for col in 0..k {
            // work = H δq
            self.apply_block(Block::HessQ, col);
            // u = −c δp + d H δq (into e), then P u (into pe)
            for i in 0..n {
                self.e[i] = -c * self.jac[(n + i, col)] + d * self.work[(i, col)];
            }
            for i in 0..n {
                let mut acc = self.proj[(i, 0)] * self.e[0];
                for j in 1..n {
                    acc += self.proj[(i, j)] * self.e[j];
                }
                self.pe[i] = acc;
            }
            for i in 0..n {
                let mut du = self.dproj[(i, 0)] * self.jac[(0, col)];
                for j in 1..n {
                    du += self.dproj[(i, j)] * self.jac[(j, col)];
                }
                self.jac[(n + i, col)] += -tau * self.work[(i, col)] + self.pe[i] + du;
            }
        }
    }

    /// The first half of a θ-kick's tangent map, before the state moves: with `hess`, `proj`
    /// and `dproj` (v = p) loaded at the old state, δp ← δp − (1−θ)rτ(Pδp + D_p δq) − τHδq.
    pub fn theta_kick_projector_before(&mut self, tau: f64, explicit_rate: f64) {
        let n = self.n();
        for col in 0..self.columns() {
            self.apply_block(Block::ProjP, col);
            self.apply_block_add(Block::DprojQ, col);
            for i in 0..n {
                self.e[i] = self.work[(i, col)];
            }
            self.apply_block(Block::HessQ, col);
            for i in 0..n {
                self.jac[(n + i, col)] -= explicit_rate * self.e[i] + tau * self.work[(i, col)];
            }
        }
    }

    /// The second half, after the state moved: with `dproj` (v = p₁) loaded,
    /// δp₁ = (I − a/(1+a) P)(δp − a D_{p₁} δq).
    pub fn theta_kick_projector_after(&mut self, a: f64) {
        let n = self.n();
        let f = a / (1.0 + a);
        for col in 0..self.columns() {
            self.apply_block(Block::DprojQ, col);
            for i in 0..n {
                self.e[i] = self.jac[(n + i, col)] - a * self.work[(i, col)];
            }
            for i in 0..n {
                let mut acc = self.proj[(i, 0)] * self.e[0];
                for j in 1..n {
                    acc += self.proj[(i, j)] * self.e[j];
                }
                self.jac[(n + i, col)] = self.e[i] - f * acc;
            }
        }
    }

    /// The tangent map of a Runge–Kutta step of the damped momentum with a projector (module
    /// docs), `hess`, `proj` and `dproj` (v = u) loaded:
    /// δp ← δp + (A−1)Pδp − τHδq − (B−τ)PHδq + D_u δq.
    pub fn momentum_rk_projector(&mut self, tau: f64, (a, b): (f64, f64)) {
        let n = self.n();
        for col in 0..self.columns() {
            self.apply_block(Block::HessQ, col);
            for i in 0..n {
                self.e[i] = self.work[(i, col)];
            }
            for i in 0..n {
                let (mut ph, mut pp) = (0.0, 0.0);
                let mut du = 0.0;
                for j in 0..n {
                    ph += self.proj[(i, j)] * self.e[j];
                    pp += self.proj[(i, j)] * self.jac[(n + j, col)];
                    du += self.dproj[(i, j)] * self.jac[(j, col)];
                }
                self.pe[i] = (a - 1.0) * pp - tau * self.e[i] - (b - tau) * ph + du;
            }
            for i in 0..n {
                self.jac[(n + i, col)] += self.pe[i];
            }
        }
    }

    /// work[:, col] = block · (δq or δp of column `col`).
    fn apply_block(&mut self, block: Block, col: usize) {
        self.block_product(block, col, false);
    }

    /// work[:, col] += block · (δq or δp of column `col`).
    fn apply_block_add(&mut self, block: Block, col: usize) {
        self.block_product(block, col, true);
    }

    fn block_product(&mut self, block: Block, col: usize, add: bool) {
        let n = self.n();
        let (m, offset) = match block {
            Block::HessQ => (&self.hess, 0),
            Block::ProjP => (&self.proj, n),
            Block::DprojQ => (&self.dproj, 0),
        };
        for i in 0..n {
            let mut acc = m[(i, 0)] * self.jac[(offset, col)];
            for j in 1..n {
                acc += m[(i, j)] * self.jac[(offset + j, col)];
            }
            if add {
                self.work[(i, col)] += acc;
            } else {
                self.work[(i, col)] = acc;
            }
        }
    }

    /// Writes the Jacobian of the vector field (q', p') = (∂H/∂p, −∂H/∂q − rP(q)p) at the
    /// loaded derivatives into `out` (2n × 2n): [[H_pq, H_pp], [−H_qq − rD_p, −H_qp − rP]], with
    /// P = I unless the damping is a projector (then `proj` and `dproj` with v = p are loaded).
    pub fn field_jacobian(&self, r: f64, out: &mut DMatrix<f64>) {
        let n = self.n();
        for i in 0..n {
            for j in 0..n {
                out[(i, j)] = self.hqp[(j, i)];
                out[(i, n + j)] = self.hpp[(i, j)];
                let (p_ij, d_ij) = if self.projector {
                    (self.proj[(i, j)], self.dproj[(i, j)])
                } else {
                    (if i == j { 1.0 } else { 0.0 }, 0.0)
                };
                out[(n + i, j)] = -self.hess[(i, j)] - r * d_ij;
                out[(n + i, n + j)] = -self.hqp[(i, j)] - r * p_ij;
            }
        }
    }
}

/// The error of a tangent map that needs the derivative of a damping projector the system does
/// not give.
pub fn no_projector_derivative() -> StepError {
    StepError::TangentUnsupported {
        reason: "the system gives no derivative of its damping projector",
    }
}

/// Which block of derivatives multiplies which half of a deviation vector.
#[derive(Clone, Copy)]
enum Block {
    /// ∇²V δq.
    HessQ,
    /// P δp.
    ProjP,
    /// D_v δq.
    DprojQ,
}

/// out = m · x for a 2n × 2n matrix `m` and 2n × k `x`, column by column, each entry summed
/// from its first term in column order.
pub fn mul_into(m: &DMatrix<f64>, x: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    let rows = m.nrows();
    for c in 0..x.ncols() {
        for i in 0..rows {
            let mut acc = m[(i, 0)] * x[(0, c)];
            for j in 1..m.ncols() {
                acc += m[(i, j)] * x[(j, c)];
            }
            out[(i, c)] = acc;
        }
    }
}

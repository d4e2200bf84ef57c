//! A user-defined system compiled for one run: its functions are native code with the run's
//! parameters folded in, and [`CustomSystem`] implements [`MechanicalSystem`] on them like a
//! hand-written system, generic over the dimension so that one, two and three degrees of
//! freedom run on stack vectors. A step allocates nothing: outputs go straight into the
//! caller's vectors, and the few intermediate buffers are on the stack (or, past 8 numbers,
//! in a buffer kept per thread).

use std::sync::Arc;

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator, Dim};

use super::buffers::{eval_on_phase, with_buffer, with_phase};
use super::damping::{DampingFlows, MassFactor};
pub use super::lanes::LaneCode;
pub use super::mass::InverseMass;
use super::DampingKind;
use crate::expr::CompiledFunction;
use crate::flows::compiled::CompiledForces;
pub use crate::flows::compiled::CompiledSteps;
use crate::system::{projector, MechanicalSystem, Structure, Vector};

/// The energy's compiled functions.
#[derive(Debug)]
pub enum EnergyModel {
    /// H = ½ pᵀM⁻¹p + V(q): V, ∇V and ∇²V of q.
    Separable {
        /// V(q), one output.
        potential: CompiledFunction,
        /// ∇V(q), n outputs.
        gradient: CompiledFunction,
        /// ∇²V(q), n² outputs (symmetric, so row- and column-major alike).
        hessian: CompiledFunction,
        /// M⁻¹.
        inverse_mass: InverseMass,
    },
    /// A general H(q, p): functions of (q, p).
    General {
        /// H, one output.
        hamiltonian: CompiledFunction,
        /// ∂H/∂q, n outputs.
        dq: CompiledFunction,
        /// ∂H/∂p, n outputs.
        dp: CompiledFunction,
        /// ∂²H/∂q², ∂²H/∂q∂p (entry (i, j) = ∂²H/∂q_i∂p_j) and ∂²H/∂p², each row-major.
        second: CompiledFunction,
    },
}

impl EnergyModel {
    /// A separable energy with constant mass `m` (row-major n×n, factor `factor`).
    pub fn separable(
        potential: CompiledFunction,
        gradient: CompiledFunction,
        hessian: CompiledFunction,
        m: &[f64],
        factor: &MassFactor,
        n: usize,
    ) -> Self {
        EnergyModel::Separable {
            potential,
            gradient,
            hessian,
            inverse_mass: InverseMass::new(m, factor, n),
        }
    }
}

/// The damping in the form the flows use.
#[derive(Clone, Debug, PartialEq)]
pub enum DampingModel {
    /// Undamped.
    None,
    /// p' = … − r p (r = 2γ).
    Conformal {
        /// r.
        rate: f64,
    },
    /// p' = … − r D(q) p with D(q) an orthogonal projector (M = mI, r = ε/m).
    Projector {
        /// r.
        rate: f64,
    },
    /// p' = … − ε D(q) M⁻¹ p with a general D(q).
    General {
        /// ε.
        epsilon: f64,
        /// The Cholesky factor of M.
        factor: MassFactor,
    },
}

impl DampingModel {
    /// The rate the methods see: r P(q) is the damping operator, with P(q) = D(q) M⁻¹ and r = ε
    /// for a general D.
    pub fn rate(&self) -> f64 {
        match self {
            DampingModel::None => 0.0,
            DampingModel::Conformal { rate } | DampingModel::Projector { rate } => *rate,
            DampingModel::General { epsilon, .. } => *epsilon,
        }
    }

    /// The damping's form.
    pub fn kind(&self) -> DampingKind {
        match self {
            DampingModel::None => DampingKind::None,
            DampingModel::Conformal { .. } => DampingKind::Conformal,
            DampingModel::Projector { .. } => DampingKind::RayleighProjector,
            DampingModel::General { .. } => DampingKind::Rayleigh,
        }
    }
}

/// A user-defined system's functions, compiled for one run's parameters.
#[derive(Debug)]
pub struct Compiled {
    /// The state's dimension: the degrees of freedom, and the clock of a driven system.
    pub n: usize,
    /// For a driven system, the index of the clock coordinate t (= the degrees of freedom);
    /// the functions then read the extended state (q, t) and (q, t, p, p_t).
    pub clock: Option<usize>,
    /// What the methods may rely on.
    pub structure: Structure,
    /// The energy.
    pub energy: EnergyModel,
    /// The damping.
    pub damping: DampingModel,
    /// D(q), n² outputs row-major, for Rayleigh damping.
    pub damping_matrix: Option<CompiledFunction>,
    /// ∂D_ab/∂q_c, n³ outputs at (a n + b) n + c, for the tangent maps (absent when it grew
    /// past the compiler's limits).
    pub damping_derivative: Option<CompiledFunction>,
    /// The invariants, functions of (q, p).
    pub invariants: Option<CompiledFunction>,
    /// ∇V and ∇²V compiled over the SIMD lanes, once the lanes ask for them.
    pub lane_forces: LaneCode,
    /// The compiled steps built for it so far (a sweep's full groups run the lanes' stretch;
    /// its last cells may run alone, on the one-run stretch).
    pub compiled_steps: CompiledSteps,
}

/// A user-defined system of dimension `D` (`U1`–`U3` on the stack, `Dyn` beyond).
pub struct CustomSystem<D: Dim> {
    dim: D,
    model: Arc<Compiled>,
    /// Whether splittings and Runge–Kutta methods run compiled steps on it (see
    /// [`Self::without_compiled_stretches`]).
    stretches: bool,
}

impl<D: Dim> CustomSystem<D> {
    /// The system of `model`, whose dimension is `dim`.
    pub fn new(dim: D, model: Arc<Compiled>) -> Self {
        debug_assert_eq!(dim.value(), model.n);
        CustomSystem {
            dim,
            model,
            stretches: true,
        }
    }

    /// The same system, on which splittings and Runge–Kutta methods take the generic path instead
    /// of compiled steps (the same bits, which tests compare).
    pub fn without_compiled_stretches(mut self) -> Self {
        self.stretches = false;
        self
    }

    /// The compiled model.
    pub fn model(&self) -> &Compiled {
        &self.model
    }

    /// The degrees of freedom: the state's dimension without a driven system's clock.
    #[inline]
    pub(super) fn dof(&self, len: usize) -> usize {
        self.model.clock.unwrap_or(len)
    }

    /// ∂H/∂p of a driven separable system or of a general H.
    #[inline(never)]
    fn dh_dp_otherwise(&self, q: &Vector<D>, p: &Vector<D>, out: &mut Vector<D>)
    where
        DefaultAllocator: Allocator<D>,
    {
        match &self.model.energy {
            EnergyModel::Separable { inverse_mass, .. } => {
                let n = self.dof(p.len());
                inverse_mass.apply(&p.as_slice()[..n], &mut out.as_mut_slice()[..n]);
                // ∂H̃/∂p_t = 1: the drift advances the clock.
                if n < p.len() {
                    out[n] = 1.0;
                }
            }
            EnergyModel::General { dp, .. } => {
                eval_on_phase(dp, q.as_slice(), p.as_slice(), out.as_mut_slice())
            }
        }
    }

    /// out = D(q) v (no mass factor); a driven system's clock momentum is not damped.
    #[inline]
    fn damping_times(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        let n = self.dof(q.len());
        let Some(matrix) = &self.model.damping_matrix else {
            out.fill(0.0);
            return;
        };
        with_buffer(n * n, |d| {
            matrix.eval(q, d);
            for (i, o) in out[..n].iter_mut().enumerate() {
                *o = d[i * n..(i + 1) * n]
                    .iter()
                    .zip(v)
                    .map(|(a, x)| a * x)
                    .sum();
            }
            out[n..].fill(0.0);
        })
    }

    /// P(q) v for a damping that depends on q: D(q) v for a projector, D(q) M⁻¹ v in general (so
    /// that r P = ε D M⁻¹ with r = ε). Out of line, so that the conformal case inlines to a copy.
    #[inline(never)]
    fn project_state_dependent(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        match &self.model.damping {
            DampingModel::General { factor, .. } => with_buffer(self.dof(q.len()), |u| {
                u.copy_from_slice(&v[..u.len()]);
                factor.solve(u);
                self.damping_times(q, u, out);
            }),
            _ => self.damping_times(q, v, out),
        }
    }

    /// Applies a flow of the general damping: `f(flows, ε, D(q), n)` on the first n = degrees
    /// of freedom momenta.
    #[inline]
    fn general_flow(&self, q: &[f64], f: impl FnOnce(&DampingFlows, f64, &[f64], usize)) -> bool {
        let (DampingModel::General { epsilon, factor }, Some(matrix)) =
            (&self.model.damping, &self.model.damping_matrix)
        else {
            return false;
        };
        let n = self.dof(q.len());
        with_buffer(n * n, |d| {
            matrix.eval(q, d);
            f(&DampingFlows::new(factor), *epsilon, d, n);
        });
        true
    }
}

impl<D: Dim> Clone for CustomSystem<D> {
    fn clone(&self) -> Self {
        CustomSystem {
            dim: self.dim,
            model: Arc::clone(&self.model),
            stretches: self.stretches,
        }
    }
}

impl<D: Dim> PartialEq for CustomSystem<D> {
    /// The same compiled model.
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.model, &other.model)
    }
}

impl<D: Dim> std::fmt::Debug for CustomSystem<D> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CustomSystem")
            .field("n", &self.model.n)
            .field("clock", &self.model.clock)
            .field("structure", &self.model.structure)
            .field("damping", &self.model.damping)
            .finish_non_exhaustive()
    }
}

impl<D: Dim> MechanicalSystem for CustomSystem<D>
where
    DefaultAllocator: Allocator<D>,
{
    type Dim = D;

    fn dim(&self) -> D {
        self.dim
    }

    fn structure(&self) -> Structure {
        self.model.structure
    }

    fn kinetic(&self, q: &Vector<D>, p: &Vector<D>) -> f64 {
        match &self.model.energy {
            EnergyModel::Separable { inverse_mass, .. } => {
                inverse_mass.half_quadratic(&p.as_slice()[..self.dof(p.len())])
            }
            EnergyModel::General { .. } => self.energy(q, p) - self.potential(q),
        }
    }

    fn potential(&self, q: &Vector<D>) -> f64 {
        let mut v = [0.0];
        match &self.model.energy {
            EnergyModel::Separable { potential, .. } => potential.eval(q.as_slice(), &mut v),
            // The energy at rest: H(q, 0).
            EnergyModel::General { hamiltonian, .. } => with_buffer(2 * q.len(), |x| {
                x[..q.len()].copy_from_slice(q.as_slice());
                hamiltonian.eval(x, &mut v)
            }),
        }
        v[0]
    }

    fn energy(&self, q: &Vector<D>, p: &Vector<D>) -> f64 {
        match &self.model.energy {
            EnergyModel::Separable { .. } => self.kinetic(q, p) + self.potential(q),
            EnergyModel::General { hamiltonian, .. } => {
                let mut v = [0.0];
                with_phase(q.as_slice(), p.as_slice(), |x| hamiltonian.eval(x, &mut v));
                v[0]
            }
        }
    }

    #[inline]
    fn grad_potential(&self, q: &Vector<D>, out: &mut Vector<D>) {
        match &self.model.energy {
            EnergyModel::Separable { gradient, .. } => {
                gradient.eval(q.as_slice(), out.as_mut_slice())
            }
            // Methods that use ∇V require a separable H; a general H answers ∂H/∂q at p = 0.
            EnergyModel::General { dq, .. } => with_buffer(2 * q.len(), |x| {
                x[..q.len()].copy_from_slice(q.as_slice());
                dq.eval(x, out.as_mut_slice())
            }),
        }
    }

    #[inline]
    fn velocity(&self, q: &Vector<D>, p: &Vector<D>, out: &mut Vector<D>) {
        self.dh_dp(q, p, out)
    }

    #[inline]
    fn dh_dp(&self, q: &Vector<D>, p: &Vector<D>, out: &mut Vector<D>) {
        // The autonomous separable case inline in the drift; the others out of line.
        match (&self.model.energy, self.model.clock) {
            (EnergyModel::Separable { inverse_mass, .. }, None) => {
                inverse_mass.apply(p.as_slice(), out.as_mut_slice())
            }
            _ => self.dh_dp_otherwise(q, p, out),
        }
    }

    #[inline]
    fn dh_dq(&self, q: &Vector<D>, p: &Vector<D>, out: &mut Vector<D>) {
        match &self.model.energy {
            EnergyModel::Separable { gradient, .. } => {
                gradient.eval(q.as_slice(), out.as_mut_slice())
            }
            EnergyModel::General { dq, .. } => {
                eval_on_phase(dq, q.as_slice(), p.as_slice(), out.as_mut_slice())
            }
        }
    }

    #[inline]
    fn damping_rate(&self) -> f64 {
        self.model.damping.rate()
    }

    #[inline]
    fn project_damped(&self, q: &Vector<D>, v: &Vector<D>, out: &mut Vector<D>) {
        match &self.model.damping {
            DampingModel::None | DampingModel::Conformal { .. } => out.copy_from(v),
            _ => self.project_state_dependent(q.as_slice(), v.as_slice(), out.as_mut_slice()),
        }
    }

    fn hess_potential(&self, q: &Vector<D>, out: &mut DMatrix<f64>) -> u64 {
        match &self.model.energy {
            EnergyModel::Separable { hessian, .. } => {
                hessian.eval(q.as_slice(), out.as_mut_slice())
            }
            EnergyModel::General { second, .. } => {
                let n = q.len();
                with_buffer(3 * n * n + 2 * n, |buffer| {
                    let (x, values) = buffer.split_at_mut(2 * n);
                    x[..n].copy_from_slice(q.as_slice());
                    second.eval(x, values);
                    out.as_mut_slice().copy_from_slice(&values[..n * n]);
                })
            }
        }
        0
    }

    fn hessian_h(
        &self,
        q: &Vector<D>,
        p: &Vector<D>,
        hqq: &mut DMatrix<f64>,
        hqp: &mut DMatrix<f64>,
        hpp: &mut DMatrix<f64>,
    ) -> bool {
        let n = q.len();
        match &self.model.energy {
            EnergyModel::Separable {
                hessian,
                inverse_mass,
                ..
            } => {
                hessian.eval(q.as_slice(), hqq.as_mut_slice());
                hqp.fill(0.0);
                hpp.fill(0.0);
                // H̃ is linear in a driven system's p_t: its row and column stay zero.
                let n = self.dof(n);
                for i in 0..n {
                    match inverse_mass {
                        InverseMass::Unit => hpp[(i, i)] = 1.0,
                        InverseMass::Scalar(m) => hpp[(i, i)] = 1.0 / m,
                        InverseMass::Diagonal(d) => hpp[(i, i)] = 1.0 / d[i],
                        InverseMass::Full(inverse) => {
                            for j in 0..n {
                                hpp[(i, j)] = inverse[i * n + j];
                            }
                        }
                    }
                }
            }
            EnergyModel::General { second, .. } => {
                with_buffer(3 * n * n + 2 * n, |buffer| {
                    let (x, values) = buffer.split_at_mut(2 * n);
                    x[..n].copy_from_slice(q.as_slice());
                    x[n..].copy_from_slice(p.as_slice());
                    second.eval(x, values);
                    // ∂²H/∂q² and ∂²H/∂p² are symmetric; ∂²H/∂q∂p is stored row-major.
                    hqq.as_mut_slice().copy_from_slice(&values[..n * n]);
                    hpp.as_mut_slice()
                        .copy_from_slice(&values[2 * n * n..3 * n * n]);
                    for i in 0..n {
                        for j in 0..n {
                            hqp[(i, j)] = values[n * n + i * n + j];
                        }
                    }
                })
            }
        }
        true
    }

    fn clock(&self) -> Option<usize> {
        self.model.clock
    }

    fn compiled_forces(&self) -> Option<CompiledForces<'_>> {
        self.stretches
            .then(|| self.model.compiled_forces())
            .flatten()
    }

    fn invariant_count(&self) -> usize {
        self.model
            .invariants
            .as_ref()
            .map_or(0, CompiledFunction::output_count)
    }

    fn invariants(&self, _t: f64, q: &Vector<D>, p: &Vector<D>, out: &mut [f64]) {
        if let Some(invariants) = &self.model.invariants {
            with_phase(q.as_slice(), p.as_slice(), |x| invariants.eval(x, out));
        }
    }

    /// ∂(P(q)v)/∂q = Σ_b ∂D_ab/∂q_c u_b with u = v (a projector) or u = M⁻¹v (general D).
    fn projector_derivative(&self, q: &Vector<D>, v: &Vector<D>, out: &mut DMatrix<f64>) -> bool {
        let n = q.len();
        match (&self.model.damping, &self.model.damping_derivative) {
            (DampingModel::None | DampingModel::Conformal { .. }, _) => {
                out.fill(0.0);
                true
            }
            (_, None) => false,
            (damping, Some(derivative)) => with_buffer(n * n * n + n, |buffer| {
                let (d, u) = buffer.split_at_mut(n * n * n);
                derivative.eval(q.as_slice(), d);
                u.copy_from_slice(v.as_slice());
                if let DampingModel::General { factor, .. } = damping {
                    factor.solve(u);
                }
                for a in 0..n {
                    for c in 0..n {
                        out[(a, c)] = (0..n).map(|b| d[(a * n + b) * n + c] * u[b]).sum();
                    }
                }
                true
            }),
        }
    }

    fn damping_is_projector(&self) -> bool {
        !matches!(self.model.damping, DampingModel::General { .. })
    }

    #[inline]
    fn damp_flow(&self, q: &Vector<D>, p: &mut Vector<D>, tau: f64, c: f64, w: &mut Vector<D>) {
        let general = matches!(self.model.damping, DampingModel::General { .. })
            && self.general_flow(q.as_slice(), |flows, epsilon, d, n| {
                flows.decay(epsilon, d, &mut p.as_mut_slice()[..n], tau)
            });
        if !general {
            projector::damp_flow(self, q, p, c, w);
        }
    }

    #[inline]
    fn kick_damp_flow(
        &self,
        q: &Vector<D>,
        p: &mut Vector<D>,
        g: &Vector<D>,
        tau: f64,
        (c, d): (f64, f64),
        w: &mut Vector<D>,
        pw: &mut Vector<D>,
    ) {
        let general = self.general_flow(q.as_slice(), |flows, epsilon, matrix, n| {
            let (p, g) = (p.as_mut_slice(), g.as_slice());
            flows.kick_decay(epsilon, matrix, &mut p[..n], &g[..n], tau);
            // A driven system's clock momentum is kicked, not damped.
            for (p, g) in p[n..].iter_mut().zip(&g[n..]) {
                *p -= tau * g;
            }
        });
        if !general {
            projector::kick_damp_flow(self, q, p, g, tau, (c, d), w, pw);
        }
    }

    #[inline]
    fn damped_solve(
        &self,
        q: &Vector<D>,
        p: &mut Vector<D>,
        theta: f64,
        tau: f64,
        w: &mut Vector<D>,
    ) {
        let general = self.general_flow(q.as_slice(), |flows, epsilon, d, n| {
            flows.solve(epsilon, d, &mut p.as_mut_slice()[..n], theta * tau)
        });
        if !general {
            projector::damped_solve(self, q, p, theta, tau, w);
        }
    }
}

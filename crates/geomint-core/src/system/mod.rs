//! What a mechanical system is: a Hamiltonian H(q, p) = T(q, p) + V(q) on a configuration space
//! of dimension n, perturbed by Rayleigh damping (paper 000, eqs. 4–5):
//!
//! ```text
//! q' = ∂H/∂p,    p' = −∂H/∂q − ε D(q) M(q)⁻¹ p
//! ```
//!
//! The trait is written for the general case — the required methods `dh_dq` and `dh_dp` are the
//! partial derivatives of a possibly non-separable H in generalized coordinates — while the
//! splitting methods only use the separable pieces (`velocity`, `grad_potential`) and say so
//! through [`Structure`]. Every output goes into a caller-owned buffer, so a step allocates nothing.
//!
//! Damping is described as "the momentum component in the damped subspace P(q) decays at the rate
//! r": ε D(q) M⁻¹ p = r P(q) p with P an orthogonal projector. That covers the conformal case
//! (D = M, P = I, r = ε = 2γ) and damping along a spring (P = q qᵀ/|q|², r = ε/m, paper 000
//! eq. 16), and gives the exact sub-flows in closed form (see `flows`).

use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator, Dim, OVector};
use serde::Serialize;

/// A vector of the configuration (or momentum) space.
pub type Vector<D> = OVector<f64, D>;

/// A phase-space point (q, p).
#[derive(Clone, Debug, PartialEq)]
pub struct State<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// Generalized coordinates.
    pub q: Vector<D>,
    /// Conjugate momenta.
    pub p: Vector<D>,
}

impl<D: Dim> State<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// A state from slices, which must have the system's dimension.
    pub fn from_slices(dim: D, q: &[f64], p: &[f64]) -> Self {
        Self {
            q: Vector::<D>::from_column_slice_generic(dim, nalgebra::U1, q),
            p: Vector::<D>::from_column_slice_generic(dim, nalgebra::U1, p),
        }
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.q.iter().chain(self.p.iter()).all(|x| x.is_finite())
    }

    /// The state of `sys` at time `t` with positions `q` and momenta `p` (the system's degrees of
    /// freedom): for a system in extended phase space (see [`MechanicalSystem::clock`]) the clock
    /// coordinate is `t` and its momentum 0, else the state is `q`, `p` as they are.
    pub fn at_time<S>(sys: &S, t: f64, q: &[f64], p: &[f64]) -> Self
    where
        S: MechanicalSystem<Dim = D> + ?Sized,
    {
        match sys.clock() {
            None => Self::from_slices(sys.dim(), q, p),
            Some(k) => {
                let mut z = Self::from_slices(
                    sys.dim(),
                    &[q, &[t][..]].concat(),
                    &[p, &[0.0][..]].concat(),
                );
                z.q[k] = t;
                z
            }
        }
    }

    /// The positions and momenta of the system's degrees of freedom, without the clock
    /// coordinate of an extended phase space.
    pub fn physical<S>(&self, sys: &S) -> (&[f64], &[f64])
    where
        S: MechanicalSystem<Dim = D> + ?Sized,
    {
        let n = sys.clock().unwrap_or(self.q.len());
        (&self.q.as_slice()[..n], &self.p.as_slice()[..n])
    }
}

/// Structural facts about a system that methods may require.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Structure {
    /// H = ½ pᵀM⁻¹p + V(q) with a constant mass matrix M: the drift and kick flows are exact
    /// and explicit.
    pub separable_constant_mass: bool,
    /// The damping is conformal (D ∝ M), so p' = −∇V − 2γp.
    pub conformal_damping: bool,
}

/// A structural requirement a method may place on the system (see each method's catalogue
/// entry); the error that names an unmet one says it in words.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
#[cfg_attr(feature = "openapi", schema(as = MethodRequirement))]
pub enum Requirement {
    /// H = ½pᵀM⁻¹p + V(q) with constant M.
    SeparableConstantMass,
    /// D ∝ M (linear damping p' = … − 2γp).
    ConformalDamping,
    /// No damping: the system's damping rate is zero.
    Conservative,
}

impl Requirement {
    /// The requirement in words, for error messages.
    pub fn describe(self) -> &'static str {
        match self {
            Requirement::SeparableConstantMass => {
                "a separable Hamiltonian with a constant mass matrix (its drift and kick flows must be exact)"
            }
            Requirement::ConformalDamping => "conformal damping D ∝ M (p' = −∇V − 2γp)",
            Requirement::Conservative => {
                "no damping (its modified potential and processors are derived for a conservative Hamiltonian; set the damping to 0)"
            }
        }
    }

    /// Whether a system with this structure and damping rate meets the requirement.
    pub fn met_by(self, s: Structure, damping_rate: f64) -> bool {
        match self {
            Requirement::SeparableConstantMass => s.separable_constant_mass,
            Requirement::ConformalDamping => s.conformal_damping,
            Requirement::Conservative => damping_rate == 0.0,
        }
    }
}

pub mod lanes;

pub use crate::flows::{Lane, LANES};
pub use lanes::LaneForces;

/// A Hamiltonian system with Rayleigh damping. See the module docs for the model.
pub trait MechanicalSystem: Sync
where
    DefaultAllocator: Allocator<Self::Dim>,
{
    /// The configuration-space dimension type: `Const<N>` when fixed, `Dyn` when known only at
    /// run time (N bodies).
    type Dim: Dim;

    /// The configuration-space dimension.
    fn dim(&self) -> Self::Dim;

    /// What the system's Hamiltonian and damping look like.
    fn structure(&self) -> Structure;

    /// Kinetic energy T(q, p).
    fn kinetic(&self, q: &Vector<Self::Dim>, p: &Vector<Self::Dim>) -> f64;

    /// Potential energy V(q).
    fn potential(&self, q: &Vector<Self::Dim>) -> f64;

    /// ∇V(q), written into `out`. This is the "force evaluation" the statistics count.
    fn grad_potential(&self, q: &Vector<Self::Dim>, out: &mut Vector<Self::Dim>);

    /// M⁻¹p for a separable system with constant mass (the drift velocity).
    fn velocity(&self, q: &Vector<Self::Dim>, p: &Vector<Self::Dim>, out: &mut Vector<Self::Dim>);

    /// ∂H/∂p. Defaults to the separable case, M⁻¹p.
    fn dh_dp(&self, q: &Vector<Self::Dim>, p: &Vector<Self::Dim>, out: &mut Vector<Self::Dim>) {
        self.velocity(q, p, out)
    }

    /// ∂H/∂q. Defaults to the separable case, ∇V(q).
    fn dh_dq(&self, q: &Vector<Self::Dim>, _p: &Vector<Self::Dim>, out: &mut Vector<Self::Dim>) {
        self.grad_potential(q, out)
    }

    /// Total energy H = T + V (the damping makes it decay).
    fn energy(&self, q: &Vector<Self::Dim>, p: &Vector<Self::Dim>) -> f64 {
        self.kinetic(q, p) + self.potential(q)
    }

    /// The rate r at which momentum in the damped subspace decays (ε D M⁻¹ p = r P(q) p);
    /// zero for an undamped system.
    fn damping_rate(&self) -> f64;

    /// `out = P(q) v`, the projection onto the damped subspace. The default is the conformal
    /// case P = I.
    fn project_damped(
        &self,
        _q: &Vector<Self::Dim>,
        v: &Vector<Self::Dim>,
        out: &mut Vector<Self::Dim>,
    ) {
        out.copy_from(v);
    }

    /// The Hessian ∇²V(q) (n×n). The default differentiates `grad_potential` by central
    /// differences; systems with a cheap analytic Hessian override it. Returns the number of
    /// gradient evaluations it used (2n here, none for an analytic override), which is what
    /// callers add to their force-evaluation counts.
    fn hess_potential(&self, q: &Vector<Self::Dim>, out: &mut DMatrix<f64>) -> u64 {
        let n = q.len();
        let mut qq = q.clone();
        let mut gp = q.clone();
        let mut gm = q.clone();
        for j in 0..n {
            let delta = 1e-5 * (1.0 + q[j].abs());
            qq[j] = q[j] + delta;
            self.grad_potential(&qq, &mut gp);
            qq[j] = q[j] - delta;
            self.grad_potential(&qq, &mut gm);
            qq[j] = q[j];
            for i in 0..n {
                out[(i, j)] = (gp[i] - gm[i]) / (2.0 * delta);
            }
        }
        // Symmetrise: the exact Hessian is symmetric, the differences only nearly so.
        for i in 0..n {
            for j in 0..i {
                let s = 0.5 * (out[(i, j)] + out[(j, i)]);
                out[(i, j)] = s;
                out[(j, i)] = s;
            }
        }
        2 * n as u64
    }

    /// ∂(P(q)v)/∂q (n×n, entry (i, j) = ∂(P(q)v)_i/∂q_j) for a damping r P(q), which the
    /// tangent maps of the damping flows need; returns false when the system cannot give it.
    /// The default answers for P = I (conformal damping) and for no damping, where it is zero,
    /// and refuses a state-dependent damping: a system with one overrides this.
    fn projector_derivative(
        &self,
        _q: &Vector<Self::Dim>,
        _v: &Vector<Self::Dim>,
        out: &mut DMatrix<f64>,
    ) -> bool {
        if self.damping_rate() == 0.0 || self.structure().conformal_damping {
            out.fill(0.0);
            true
        } else {
            false
        }
    }

    /// Whether P(q) of the damping r P(q) is an orthogonal projector, which the closed-form
    /// damping flows and their tangent maps rely on (a user's general D(q)M⁻¹ is not one: its
    /// flows go through an eigendecomposition).
    fn damping_is_projector(&self) -> bool {
        true
    }

    /// The second derivatives of H at (q, p): `hqq` = ∂²H/∂q², `hqp` with entries ∂²H/∂q_i∂p_j,
    /// `hpp` = ∂²H/∂p² (all n×n). Newton's method in a non-separable chart uses them. Returns
    /// false when the system does not provide them; methods then difference ∂H/∂q and ∂H/∂p.
    fn hessian_h(
        &self,
        _q: &Vector<Self::Dim>,
        _p: &Vector<Self::Dim>,
        _hqq: &mut DMatrix<f64>,
        _hqp: &mut DMatrix<f64>,
        _hpp: &mut DMatrix<f64>,
    ) -> bool {
        false
    }

    /// Solves the momentum stage of symplectic Euler (001 eq. 42, damping taken implicitly),
    /// p₁ = p − h (∂H/∂q(q, p₁) + r P(q) p₁), in closed form where the chart makes it explicit
    /// (a cyclic coordinate makes it triangular). Returns false when it cannot; Newton then
    /// solves it.
    fn solve_momentum_stage(
        &self,
        _q: &Vector<Self::Dim>,
        _p: &Vector<Self::Dim>,
        _h: f64,
        _p1: &mut Vector<Self::Dim>,
    ) -> bool {
        false
    }

    /// Solves the position stage of the adjoint symplectic Euler, q₁ = q + h ∂H/∂p(q₁, p), in
    /// closed form where the chart allows; false otherwise (Newton solves it).
    fn solve_position_stage(
        &self,
        _q: &Vector<Self::Dim>,
        _p: &Vector<Self::Dim>,
        _h: f64,
        _q1: &mut Vector<Self::Dim>,
    ) -> bool {
        false
    }

    /// The state in Cartesian coordinates (for a first-order ODE: in its original variable):
    /// the chart's point transformation x = X(q) and its cotangent lift p_x = (∂X/∂q)⁻ᵀ p
    /// (001 eqs. 40–41). The identity for systems written in Cartesian coordinates. `x` and
    /// `px` have the system's dimension.
    fn to_cartesian(
        &self,
        q: &Vector<Self::Dim>,
        p: &Vector<Self::Dim>,
        x: &mut [f64],
        px: &mut [f64],
    ) {
        x.copy_from_slice(q.as_slice());
        px.copy_from_slice(p.as_slice());
    }

    /// The inverse of [`to_cartesian`](Self::to_cartesian): the chart state of a Cartesian
    /// one, or why the chart does not cover it (a singular point, outside its range).
    fn from_cartesian(
        &self,
        x: &[f64],
        px: &[f64],
        q: &mut Vector<Self::Dim>,
        p: &mut Vector<Self::Dim>,
    ) -> Result<(), String> {
        q.as_mut_slice().copy_from_slice(x);
        p.as_mut_slice().copy_from_slice(px);
        Ok(())
    }

    /// Whether this is the identity chart (the state is already Cartesian).
    fn is_cartesian(&self) -> bool {
        true
    }

    /// For a system whose H or damping depends on the time t: the index of the coordinate that
    /// is t. Such a system lives in extended phase space, H̃(q, t, p, p_t) = H(q, p, t) + p_t
    /// (Hairer–Lubich–Wanner, *Geometric Numerical Integration*, Sec. VI.10; Arnold, *Mathematical
    /// Methods of Classical Mechanics*, Sec. 45): the clock is the last coordinate, its
    /// velocity ∂H̃/∂p_t = 1, its momentum p_t' = −∂H/∂t does not act back on the motion, and
    /// every method that treats coordinates alike integrates t exactly with the rest (a drift
    /// advances it, a kick holds it). `None` (the default) for autonomous systems, whose state
    /// is (q, p) alone.
    fn clock(&self) -> Option<usize> {
        None
    }

    /// The system's forces as programs, from which the splittings' and Runge–Kutta methods'
    /// compiled steps are built (`flows::compiled`), and the cache the system keeps their code
    /// in: a typed-in system's programs, or a built-in one's force traced into a program.
    /// `None` (the default) leaves every step to the generic path. The programs must give the
    /// bits of the system's own functions.
    fn compiled_forces(&self) -> Option<crate::flows::compiled::CompiledForces<'_>> {
        None
    }

    /// How many invariants (or conformal invariants) [`invariants`](Self::invariants) writes;
    /// their names are in the system's catalogue entry.
    fn invariant_count(&self) -> usize {
        0
    }

    /// The invariants at time t, written into `out` (length `invariant_count()`).
    fn invariants(
        &self,
        _t: f64,
        _q: &Vector<Self::Dim>,
        _p: &Vector<Self::Dim>,
        _out: &mut [f64],
    ) {
    }

    /// The exact state at time t from (q0, p0), where a closed form is known.
    fn exact(&self, _t: f64, _start: &State<Self::Dim>) -> Option<State<Self::Dim>> {
        None
    }

    /// The exact damping decay with q frozen, p ← e^{−τ εD(q)M⁻¹} p, given c = 1 − e^{−rτ}
    /// (computed once per step size). The default is the projector form p ← p − c P(q) p; a
    /// system whose damping is not rate × projector overrides this and the two methods below.
    #[inline]
    fn damp_flow(
        &self,
        q: &Vector<Self::Dim>,
        p: &mut Vector<Self::Dim>,
        _tau: f64,
        c: f64,
        w: &mut Vector<Self::Dim>,
    ) {
        projector::damp_flow(self, q, p, c, w)
    }

    /// The exact flow of p' = −g − εD(q)M⁻¹p for time τ with q and g frozen, given
    /// c = 1 − e^{−rτ} and d = τ(1 − φ₁(−rτ)). The default is the projector form
    /// p ← p − τ g + P(−c p + d g) (the damped part decays, the force enters through τφ₁).
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn kick_damp_flow(
        &self,
        q: &Vector<Self::Dim>,
        p: &mut Vector<Self::Dim>,
        g: &Vector<Self::Dim>,
        tau: f64,
        (c, d): (f64, f64),
        w: &mut Vector<Self::Dim>,
        pw: &mut Vector<Self::Dim>,
    ) {
        projector::kick_damp_flow(self, q, p, g, tau, (c, d), w, pw)
    }

    /// Solves (I + θτ εD(q)M⁻¹) x = p for x, in place (the implicit part of a θ-method kick).
    /// The default uses (I + aP)⁻¹ = I − a/(1 + a) P with a = θ r τ.
    #[inline]
    fn damped_solve(
        &self,
        q: &Vector<Self::Dim>,
        p: &mut Vector<Self::Dim>,
        theta: f64,
        tau: f64,
        w: &mut Vector<Self::Dim>,
    ) {
        projector::damped_solve(self, q, p, theta, tau, w)
    }

    /// The damping force ε D(q) M⁻¹ p = r P(q) p, written into `out`.
    fn damping_force(
        &self,
        q: &Vector<Self::Dim>,
        p: &Vector<Self::Dim>,
        out: &mut Vector<Self::Dim>,
    ) {
        self.project_damped(q, p, out);
        *out *= self.damping_rate();
    }

    /// The full vector field (q', p') = (∂H/∂p, −∂H/∂q − ε D M⁻¹ p). `scratch` is a work
    /// vector of the system's dimension.
    fn vector_field(
        &self,
        q: &Vector<Self::Dim>,
        p: &Vector<Self::Dim>,
        dq: &mut Vector<Self::Dim>,
        dp: &mut Vector<Self::Dim>,
        scratch: &mut Vector<Self::Dim>,
    ) {
        self.dh_dp(q, p, dq);
        self.dh_dq(q, p, dp);
        self.damping_force(q, p, scratch);
        *dp += &*scratch;
        dp.neg_mut();
    }
}

/// The damping flows for a damping r P(q) with P(q) an orthogonal projector, in closed form: the
/// defaults of [`MechanicalSystem`]'s damping flows, callable by a system that overrides them for
/// some other form of damping and keeps these for the projector form.
pub mod projector {
    use super::{MechanicalSystem, Vector};
    use nalgebra::allocator::Allocator;
    use nalgebra::DefaultAllocator;

    /// p ← p − c P(q) p with c = 1 − e^{−rτ}.
    #[inline]
    pub fn damp_flow<S: MechanicalSystem + ?Sized>(
        sys: &S,
        q: &Vector<S::Dim>,
        p: &mut Vector<S::Dim>,
        c: f64,
        w: &mut Vector<S::Dim>,
    ) where
        DefaultAllocator: Allocator<S::Dim>,
    {
        if c == 0.0 {
            return;
        }
        sys.project_damped(q, p, w);
        crate::flows::decay(p.as_mut_slice(), w.as_slice(), c);
    }

    /// p ← p − τ g + P(q)(−c p + d g), with c = 1 − e^{−rτ} and d = τ(1 − φ₁(−rτ)).
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn kick_damp_flow<S: MechanicalSystem + ?Sized>(
        sys: &S,
        q: &Vector<S::Dim>,
        p: &mut Vector<S::Dim>,
        g: &Vector<S::Dim>,
        tau: f64,
        (c, d): (f64, f64),
        w: &mut Vector<S::Dim>,
        pw: &mut Vector<S::Dim>,
    ) where
        DefaultAllocator: Allocator<S::Dim>,
    {
        crate::flows::kick_damp_increment(p.as_slice(), g.as_slice(), (c, d), w.as_mut_slice());
        sys.project_damped(q, w, pw);
        crate::flows::kick_damp(p.as_mut_slice(), g.as_slice(), tau, pw.as_slice());
    }

    /// p ← (I + aP)⁻¹ p = p − a/(1 + a) P p with a = θ r τ.
    #[inline]
    pub fn damped_solve<S: MechanicalSystem + ?Sized>(
        sys: &S,
        q: &Vector<S::Dim>,
        p: &mut Vector<S::Dim>,
        theta: f64,
        tau: f64,
        w: &mut Vector<S::Dim>,
    ) where
        DefaultAllocator: Allocator<S::Dim>,
    {
        let a = theta * sys.damping_rate() * tau;
        sys.project_damped(q, p, w);
        p.axpy(-a / (1.0 + a), w, 1.0);
    }
}

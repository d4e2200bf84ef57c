//! A system in SIMD lanes: [`LaneForces`], the velocity, force, Hessian and damping of
//! [`LANES`] points at once, which the lanes of `methods::lanes` step with.
//!
//! Lanes whose runs differ in more than their initial states: one system per lane, so that a
//! sweep over a parameter (or over the step, a group of cells at a time sharing it) runs side by
//! side. Each lane evaluates its own system one point at a time ([`PointForces`]), with the
//! arithmetic of that system's one-run path; what the lanes gain is the independent work of
//! sixteen runs in flight along each step's chain, not one vector operation per formula.
//!
//! The exact damping flow is evaluated here too (for lanes of one system as well): the system's
//! own `damp_flow` on one lane's state, with the coefficient c = 1 − e^{−rτ} its composer uses.

// Lanes and components are indexed side by side.
#![allow(clippy::needless_range_loop)]

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, U1};

use super::{Lane, MechanicalSystem, Vector, LANES};
use crate::flows::compiled::CompiledForces;

/// A separable system with constant mass whose velocity, force and Hessian the lanes evaluate,
/// each lane with exactly the arithmetic of the system's own `velocity`, `grad_potential` and
/// `hess_potential` (an exact Hessian, which costs no gradient evaluations).
pub trait LaneForces<const N: usize> {
    /// Whether this instance evaluates in lanes (a system type may do so only for some of its
    /// instances).
    fn in_lanes(&self) -> bool {
        true
    }
    /// v = M⁻¹p.
    fn velocity_lanes(&self, p: &[Lane; N], v: &mut [Lane; N]);
    /// ∇V(q).
    fn grad_lanes(&self, q: &[Lane; N], g: &mut [Lane; N]);
    /// ∇²V(q), row i and column j in `hess[i][j]`.
    fn hessian_lanes(&self, q: &[Lane; N], hess: &mut [[Lane; N]; N]);
    /// The exact damping flow over τ, lane l's with the coefficient c[l] = 1 − e^{−r τ} of its
    /// rate r, as the system's `damp_flow` ([`damp_each_lane`]).
    fn damp_lanes(&self, q: &[Lane; N], p: &mut [Lane; N], tau: f64, c: &Lane);
    /// The forces as programs from which the lanes' compiled stretches are built: the system's
    /// own ([`MechanicalSystem::compiled_forces`]) when the lanes run one system that has them;
    /// `None` (the default) leaves the lanes to the generic path.
    fn compiled_forces_in_lanes(&self) -> Option<CompiledForces<'_>> {
        None
    }
    /// Whether single steps (a basin map's, a sweep's sampled every step) take the compiled
    /// lanes too. They do where the generic lanes call the force through a pointer (a typed-in
    /// system); where they inline it (a built-in system), one step of compiled code, copied in
    /// and out, is no faster: the built-in Hénon–Heiles escapes map took 4.5–5.6 s that way
    /// against 3.6–5.2 s on the generic lanes (300 × 300 cells, runs alternated).
    fn single_steps_compiled(&self) -> bool {
        true
    }
}

/// A separable system with constant mass, one point at a time: what [`LaneForces`] evaluates for
/// sixteen points of one system, for one point of one lane's system.
pub trait PointForces<const N: usize> {
    /// v = M⁻¹p, as the system's `velocity`.
    fn velocity_at(&self, p: [f64; N]) -> [f64; N];
    /// ∇V(q), as the system's `grad_potential`.
    fn grad_at(&self, q: [f64; N]) -> [f64; N];
    /// The exact damping flow over τ with c = 1 − e^{−rτ}, as the system's `damp_flow`.
    fn damp_at(&self, q: [f64; N], p: [f64; N], tau: f64, c: f64) -> [f64; N];
}

/// [`PointForces::damp_at`] through the system's own `damp_flow` (no allocation for the
/// dimensions the lanes take, which live on the stack).
#[inline(always)]
pub fn damp_point<S: MechanicalSystem, const N: usize>(
    sys: &S,
    q: [f64; N],
    p: [f64; N],
    tau: f64,
    c: f64,
) -> [f64; N]
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let vector = |x: &[f64; N]| Vector::<S::Dim>::from_column_slice_generic(sys.dim(), U1, x);
    let q = vector(&q);
    let mut p = vector(&p);
    let mut w = Vector::<S::Dim>::zeros_generic(sys.dim(), U1);
    sys.damp_flow(&q, &mut p, tau, c, &mut w);
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = p[i];
    }
    out
}

/// Lane `l`'s components (a plain loop: `array::from_fn` may be left out of line).
#[inline(always)]
fn lane<const N: usize>(x: &[Lane; N], l: usize) -> [f64; N] {
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = x[i][l];
    }
    out
}

/// The damping flow of every lane, lane `l` through `system(l)`: the [`LaneForces::damp_lanes`]
/// of lanes of one system and of lanes of one system each.
#[inline(always)]
pub fn damp_each_lane<'s, S: PointForces<N> + 's, const N: usize>(
    system: impl Fn(usize) -> &'s S,
    q: &[Lane; N],
    p: &mut [Lane; N],
    tau: f64,
    c: &Lane,
) {
    for l in 0..LANES {
        let damped = system(l).damp_at(lane(q, l), lane(p, l), tau, c[l]);
        for i in 0..N {
            p[i][l] = damped[i];
        }
    }
}

/// Sixteen lanes, one system each (a lane without a run repeats another's system). The systems
/// are copies side by side, so that lane l's parameters sit at a fixed stride from lane 0's
/// rather than behind sixteen pointers.
pub struct EachLane<S> {
    systems: [S; LANES],
}

impl<S: Clone> EachLane<S> {
    /// Lane `l` runs `systems[l]`; lanes past the last system run the first. `None` without
    /// systems or with more than [`LANES`].
    pub fn new(systems: &[&S]) -> Option<Self> {
        let first = *systems.first()?;
        (systems.len() <= LANES).then(|| EachLane {
            systems: std::array::from_fn(|l| (*systems.get(l).unwrap_or(&first)).clone()),
        })
    }
}

impl<S: PointForces<N>, const N: usize> LaneForces<N> for EachLane<S> {
    #[inline(always)]
    fn velocity_lanes(&self, p: &[Lane; N], v: &mut [Lane; N]) {
        for l in 0..LANES {
            let out = self.systems[l].velocity_at(lane(p, l));
            for i in 0..N {
                v[i][l] = out[i];
            }
        }
    }

    #[inline(always)]
    fn grad_lanes(&self, q: &[Lane; N], g: &mut [Lane; N]) {
        for l in 0..LANES {
            let out = self.systems[l].grad_at(lane(q, l));
            for i in 0..N {
                g[i][l] = out[i];
            }
        }
    }

    /// Lanes of several systems carry no deviation vectors (their inverse masses, which the
    /// tangent maps read, may differ), so nothing asks them for a Hessian.
    fn hessian_lanes(&self, _q: &[Lane; N], _hess: &mut [[Lane; N]; N]) {
        unreachable!("lanes of several systems run without deviation vectors")
    }

    #[inline(always)]
    fn damp_lanes(&self, q: &[Lane; N], p: &mut [Lane; N], tau: f64, c: &Lane) {
        damp_each_lane(|l| &self.systems[l], q, p, tau, c);
    }
}

//! The kernel's sub-flows ([`crate::flows`]) on a system's state: each with the system's part
//! evaluated first (its velocity M⁻¹p, its damping flows, which a system may override for a
//! damping that is not a rate times a projector), for the one-run steppers. The θ-method kick
//! of the non-geometric baselines lives here too: only the one-run path takes it on a damped
//! system (elsewhere r = 0 makes it the plain kick).

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use crate::flows;
use crate::system::{MechanicalSystem, State, Vector};

/// Drift q ← q + τ M⁻¹p; `v` is a work vector.
#[inline(always)]
pub fn drift<S: MechanicalSystem>(sys: &S, z: &mut State<S::Dim>, tau: f64, v: &mut Vector<S::Dim>)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys.velocity(&z.q, &z.p, v);
    flows::drift(z.q.as_mut_slice(), v.as_slice(), tau);
}

/// Kick p ← p − τ g with g = ∇V(q) already evaluated.
#[inline(always)]
pub fn kick<D: nalgebra::Dim>(z: &mut State<D>, tau: f64, grad: &Vector<D>)
where
    DefaultAllocator: Allocator<D>,
{
    flows::kick(z.p.as_mut_slice(), grad.as_slice(), tau);
}

/// A θ-method kick on the full momentum field p' = −g − r P p with q frozen (g = ∇V(q) given):
/// p₁ = p − τ g − rτ P((1 − θ) p + θ p₁). θ = 0 is forward Euler, θ = 1 backward Euler and θ = ½
/// the trapezoidal rule; the implicit part is linear and solved in closed form, since
/// (I + aP)⁻¹ = I − a/(1 + a) P for a projector P. This is how the non-geometric partitioned
/// baselines (symplectic Euler, the Verlets) treat the damping; with r = 0 it is the exact kick.
#[inline]
pub fn kick_theta<S: MechanicalSystem>(
    sys: &S,
    z: &mut State<S::Dim>,
    tau: f64,
    theta: f64,
    grad: &Vector<S::Dim>,
    w: &mut Vector<S::Dim>,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    let r = sys.damping_rate();
    if r != 0.0 && theta != 1.0 {
        sys.project_damped(&z.q, &z.p, w);
        z.p.axpy(-(1.0 - theta) * r * tau, w, 1.0);
    }
    kick(z, tau, grad);
    if r != 0.0 && theta != 0.0 {
        sys.damped_solve(&z.q, &mut z.p, theta, tau, w);
    }
}

/// Damping decay over τ with a precomputed c = 1 − e^{−rτ} (see
/// [`MechanicalSystem::damp_flow`]). A run with a fixed step computes c once instead of an
/// exponential per step.
#[inline(always)]
pub fn damp_with<S: MechanicalSystem>(
    sys: &S,
    z: &mut State<S::Dim>,
    tau: f64,
    c: f64,
    w: &mut Vector<S::Dim>,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys.damp_flow(&z.q, &mut z.p, tau, c, w);
}

/// The exact kick-and-damp with precomputed coefficients (see
/// [`MechanicalSystem::kick_damp_flow`]; for a projector p ← p − τ g + P(−c p + d g)).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn kick_damp_with<S: MechanicalSystem>(
    sys: &S,
    z: &mut State<S::Dim>,
    tau: f64,
    c: f64,
    d: f64,
    grad: &Vector<S::Dim>,
    w: &mut Vector<S::Dim>,
    pw: &mut Vector<S::Dim>,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    if c == 0.0 {
        kick(z, tau, grad);
        return;
    }
    sys.kick_damp_flow(&z.q, &mut z.p, grad, tau, (c, d), w, pw);
}

/// Exact damping decay p ← p − (1 − e^{−rτ}) P p.
#[inline]
pub fn damp<S: MechanicalSystem>(sys: &S, z: &mut State<S::Dim>, tau: f64, w: &mut Vector<S::Dim>)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    damp_with(
        sys,
        z,
        tau,
        flows::damp_coefficient(sys.damping_rate(), tau),
        w,
    );
}

/// Exact flow of p' = −g − r P p for time τ with q (and so g = ∇V(q)) frozen.
#[inline]
pub fn kick_damp<S: MechanicalSystem>(
    sys: &S,
    z: &mut State<S::Dim>,
    tau: f64,
    grad: &Vector<S::Dim>,
    w: &mut Vector<S::Dim>,
    pw: &mut Vector<S::Dim>,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    let (c, d) = flows::kick_damp_coefficients(sys.damping_rate(), tau);
    kick_damp_with(sys, z, tau, c, d, grad, w, pw);
}

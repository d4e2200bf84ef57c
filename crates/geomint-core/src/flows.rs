//! Exact sub-flows that splitting methods compose (paper 000 Sec. 3, paper 003 Sec. 2.2); their
//! tangent maps are in [`crate::tangent`].
//!
//! With q frozen, the momentum equation p' = −∇V(q) − r P(q) p is linear with a constant
//! projector P, so every flow here is exact and explicit:
//! - drift, exp(τ X_T): q ← q + τ M⁻¹p (constant M);
//! - kick, exp(τ X_V): p ← p − τ ∇V(q);
//! - damping decay, exp(τ εY): p ← p − (1 − e^{−rτ}) P p;
//! - linear kick-and-damp, exp(τ (X_V + εY)): the exponential-Euler solution
//!   p ← p − τ g + P(−c p + (τ − c/r) g), with g = ∇V(q) and c = 1 − e^{−rτ}
//!   (on the damped subspace p decays with e^{−rτ} and the force enters through τφ₁(−rτ) = c/r;
//!   on its complement the kick is plain). This handles a singular D such as the elastic
//!   pendulum's q qᵀ/|q|², where a matrix inverse would fail.
//!
//! Negative τ is allowed everywhere: it is the exact backward flow, which high-order
//! compositions with negative coefficients rely on.

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::system::{MechanicalSystem, State, Vector};
pub use super::tangent::Tangent;

/// 1 − e^{−x}, accurate for small |x|.
#[inline]
pub fn one_minus_exp_neg(x: f64) -> f64 {
    -(-x).exp_m1()
}

/// 1 − φ₁(−x) = 1 − (1 − e^{−x})/x, by its series where the closed form cancels.
#[inline]
pub fn one_minus_phi1_neg(x: f64) -> f64 {
    if x.abs() < 1e-2 {
        // x/2 − x²/6 + x³/24 − x⁴/120 + x⁵/720: the first omitted term, x⁶/5040, is about 4e-14
        // of the sum at |x| = 1e-2, comparable with the closed form's cancellation just above.
        x * (0.5 - x * (1.0 / 6.0 - x * (1.0 / 24.0 - x * (1.0 / 120.0 - x / 720.0))))
    } else {
        1.0 - one_minus_exp_neg(x) / x
    }
}

/// Drift q ← q + τ M⁻¹p; `v` is a work vector.
#[inline]
pub fn drift<S: MechanicalSystem>(sys: &S, z: &mut State<S::Dim>, tau: f64, v: &mut Vector<S::Dim>)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys.velocity(&z.q, &z.p, v);
    z.q.axpy(tau, v, 1.0);
}

/// Kick p ← p − τ g with g = ∇V(q) already evaluated.
#[inline]
pub fn kick<D: nalgebra::Dim>(z: &mut State<D>, tau: f64, grad: &Vector<D>)
where
    DefaultAllocator: Allocator<D>,
{
    z.p.axpy(-tau, grad, 1.0);
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
    z.p.axpy(-tau, grad, 1.0);
    if r != 0.0 && theta != 0.0 {
        sys.damped_solve(&z.q, &mut z.p, theta, tau, w);
    }
}

/// The tangent coefficients (A, B) of [`kick_theta`] for P = I: δp ← A δp − B ∇²V δq.
pub fn kick_theta_tangent(r: f64, tau: f64, theta: f64) -> (f64, f64) {
    let denominator = 1.0 + theta * r * tau;
    (
        (1.0 - (1.0 - theta) * r * tau) / denominator,
        tau / denominator,
    )
}

/// Exact damping decay p ← p − (1 − e^{−rτ}) P p.
#[inline]
pub fn damp<S: MechanicalSystem>(sys: &S, z: &mut State<S::Dim>, tau: f64, w: &mut Vector<S::Dim>)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    damp_with(sys, z, tau, damp_coefficient(sys.damping_rate(), tau), w);
}

/// The coefficient c = 1 − e^{−rτ} of [`damp_with`].
#[inline]
pub fn damp_coefficient(r: f64, tau: f64) -> f64 {
    one_minus_exp_neg(r * tau)
}

/// Damping decay over τ with a precomputed c = 1 − e^{−rτ} (see
/// [`MechanicalSystem::damp_flow`]). A run with a fixed step computes c once instead of an
/// exponential per step.
#[inline]
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
    let (c, d) = kick_damp_coefficients(sys.damping_rate(), tau);
    kick_damp_with(sys, z, tau, c, d, grad, w, pw);
}

/// The coefficients (c, d) = (1 − e^{−rτ}, τ − c/r) of [`kick_damp_with`]; d = τ(1 − φ₁(−rτ)).
#[inline]
pub fn kick_damp_coefficients(r: f64, tau: f64) -> (f64, f64) {
    let x = r * tau;
    (one_minus_exp_neg(x), tau * one_minus_phi1_neg(x))
}

/// The exact kick-and-damp with precomputed coefficients (see
/// [`MechanicalSystem::kick_damp_flow`]; for a projector p ← p − τ g + P(−c p + d g)).
#[inline]
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

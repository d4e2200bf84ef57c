//! The kernel: what a step is made of, written once. The exact sub-flows that splitting
//! methods compose (paper 000 Sec. 3, paper 003 Sec. 2.2) are written here over any [`Real`]
//! — one `f64` for a single run, a [`Pack`] of lanes for runs side by side, or a value of the
//! code being compiled (`emit`) — so the one-run composer, the SIMD lanes and the compiled
//! stretches all do the same operations in the same order and give the same bits. The
//! system's part of a flow (its velocity M⁻¹p, its force ∇V, its damping projection P(q)p) is
//! the caller's; a flow here is the update of the state once those are known. The tangent maps
//! of the drift and the kick on a deviation vector are here too ([`drift_tangent`],
//! [`kick_tangent`]), for the one-run tangent ([`crate::tangent`]) and the chaos maps' lanes; the
//! damped flows' tangent maps, which only the one-run path has, are in [`crate::tangent`].
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
//!
//! Also here, since every back end reads them: the names of the flows ([`SubFlow`]), their
//! h-dependent coefficients, the plan of a compiled stretch ([`compiled`]) and the Butcher
//! tableau of an explicit Runge–Kutta method ([`tableau`]).

/// Runs `$body` with `$k` bound to 0, 1, …, `$n` − 1, the block written out once per index for
/// `$n` ≤ 6 (the stages of the built-in tableaux, the flows of the built-in splittings): with the
/// table known at compile time `$n` is a constant, each copy sees a constant index, and the
/// coefficients and the kind of each flow fold. The compiler does not reliably unroll such loops
/// by itself once their bodies are large, nor inline a closure that is called several times.
macro_rules! unroll {
    ($n:expr, $k:ident => $body:block) => {{
        let n: usize = $n;
        match n {
            0 => {}
            1 => unroll!(@at $k $body 0),
            2 => unroll!(@at $k $body 0 1),
            3 => unroll!(@at $k $body 0 1 2),
            4 => unroll!(@at $k $body 0 1 2 3),
            5 => unroll!(@at $k $body 0 1 2 3 4),
            6 => unroll!(@at $k $body 0 1 2 3 4 5),
            _ => {
                for $k in 0..n {
                    $body
                }
            }
        }
    }};
    (@at $k:ident $body:block $($i:literal)*) => {{
        $({
            let $k: usize = $i;
            $body
        })*
    }};
}
pub(crate) use unroll;

pub mod compiled;
pub(crate) mod emit;
mod mass;
mod number;
pub mod tableau;

pub use mass::InverseMass;
pub use number::{Lane, Pack, Real, LANES};
pub use tableau::Tableau;

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

/// The coefficient c = 1 − e^{−rτ} of the damping decay over τ at rate r.
#[inline]
pub fn damp_coefficient(r: f64, tau: f64) -> f64 {
    one_minus_exp_neg(r * tau)
}

/// The coefficients (c, d) = (1 − e^{−rτ}, τ − c/r) of the kick-and-damp over τ at rate r;
/// d = τ(1 − φ₁(−rτ)).
#[inline]
pub fn kick_damp_coefficients(r: f64, tau: f64) -> (f64, f64) {
    let x = r * tau;
    (one_minus_exp_neg(x), tau * one_minus_phi1_neg(x))
}

/// The tangent coefficients (A, B) of a θ-method kick for P = I: δp ← A δp − B ∇²V δq.
pub fn kick_theta_tangent(r: f64, tau: f64, theta: f64) -> (f64, f64) {
    let denominator = 1.0 + theta * r * tau;
    (
        (1.0 - (1.0 - theta) * r * tau) / denominator,
        tau / denominator,
    )
}

/// Drift q ← q + τ v, with v = M⁻¹p already evaluated.
#[inline(always)]
pub fn drift<T: Real>(q: &mut [T], v: &[T], tau: T) {
    for (q, &v) in q.iter_mut().zip(v) {
        *q = tau * v + *q;
    }
}

/// Kick p ← p − τ g, with g = ∇V(q) already evaluated.
#[inline(always)]
pub fn kick<T: Real>(p: &mut [T], g: &[T], tau: T) {
    let minus_tau = -tau;
    for (p, &g) in p.iter_mut().zip(g) {
        *p = minus_tau * g + *p;
    }
}

/// The damping decay's update p ← p − c w, with w = P(q)p already evaluated and
/// c = 1 − e^{−rτ} ([`damp_coefficient`]).
#[inline(always)]
pub fn decay<T: Real>(p: &mut [T], w: &[T], c: T) {
    let minus_c = -c;
    for (p, &w) in p.iter_mut().zip(w) {
        *p = minus_c * w + *p;
    }
}

/// The kick-and-damp for a damping r P(q) with P an orthogonal projector,
/// p ← p − τ g + P(−c p + d g) with (c, d) from [`kick_damp_coefficients`], in two halves around
/// the system's projection: this one writes the damped subspace's increment u = −c p + d g.
#[inline(always)]
pub fn kick_damp_increment<T: Real>(p: &[T], g: &[T], (c, d): (T, T), u: &mut [T]) {
    let minus_c = -c;
    for ((u, &p), &g) in u.iter_mut().zip(p).zip(g) {
        *u = d * g + p * minus_c;
    }
}

/// The second half of the kick-and-damp: p ← p − τ g + P u, given P u
/// ([`kick_damp_increment`] wrote u).
#[inline(always)]
pub fn kick_damp<T: Real>(p: &mut [T], g: &[T], tau: T, projected_increment: &[T]) {
    kick(p, g, tau);
    for (p, &pu) in p.iter_mut().zip(projected_increment) {
        *p = *p + pu;
    }
}

/// A drift's tangent map on one deviation vector, δq ← δq + (τM⁻¹) δp, with `scaled(i, j)` the
/// entry (τM⁻¹)ᵢⱼ. Each row is summed from its first term in column order, the order nalgebra's
/// small-matrix products use and the Jacobian diagnostics were pinned with; the products by
/// zero entries are kept, so a run and its lanes do the same operations.
// Index loops: with the length known after inlining the compiler unrolls them whole, which it
// did not for the iterator form (the chaos map's lanes ran 20 % slower).
#[allow(clippy::needless_range_loop)]
#[inline(always)]
pub fn drift_tangent<T: Real>(dq: &mut [T], dp: &[T], scaled: impl Fn(usize, usize) -> T) {
    let n = dq.len();
    for i in 0..n {
        let mut acc = scaled(i, 0) * dp[0];
        for j in 1..n {
            acc = acc + scaled(i, j) * dp[j];
        }
        dq[i] = dq[i] + acc;
    }
}

/// A kick's tangent map on one deviation vector, δp ← a δp + (−b∇²V) δq, with
/// `scaled(i, j)` the entry (−b∇²V)ᵢⱼ at the kick's q: a = 1 and b = τ for the plain kick, other
/// (a, b) for the damped kicks with P = I (see [`kick_theta_tangent`]). Rows are summed as in
/// [`drift_tangent`]; with a = 1, a δp is δp exactly.
// Index loops: with the length known after inlining the compiler unrolls them whole, which it
// did not for the iterator form (the chaos map's lanes ran 20 % slower).
#[allow(clippy::needless_range_loop)]
#[inline(always)]
pub fn kick_tangent<T: Real>(dp: &mut [T], dq: &[T], a: T, scaled: impl Fn(usize, usize) -> T) {
    let n = dp.len();
    for i in 0..n {
        let mut acc = scaled(i, 0) * dq[0];
        for j in 1..n {
            acc = acc + scaled(i, j) * dq[j];
        }
        dp[i] = a * dp[i] + acc;
    }
}

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
    /// A θ-method step of the damped momentum field p' = −∇V − r P p (see `methods::state_flows::kick_theta`),
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
    /// Whether this flow followed by `next` is one flow over the summed time: both of one kind,
    /// and that kind exact and autonomous with the other half of the state frozen.
    pub const fn fuses_with(self, next: SubFlow) -> bool {
        matches!(
            (self, next),
            (SubFlow::Drift, SubFlow::Drift)
                | (SubFlow::Kick, SubFlow::Kick)
                | (SubFlow::Damp, SubFlow::Damp)
                | (SubFlow::KickDamp, SubFlow::KickDamp)
        )
    }

    /// This flow's coefficients over τ at damping rate r, which depend on h only: the damping's
    /// c = 1 − e^{−rτ}, the kick-and-damp's (c, d) ([`kick_damp_coefficients`]); none for
    /// the others.
    #[inline]
    pub fn coefficients(self, r: f64, tau: f64) -> (f64, f64) {
        match self {
            SubFlow::Damp => (damp_coefficient(r, tau), 0.0),
            SubFlow::KickDamp => kick_damp_coefficients(r, tau),
            _ => (0.0, 0.0),
        }
    }
}

/// The seam of `flows` at step h and damping rate r: the last flow of a step and the first of
/// the next applied as one over their summed time (b + a)·h, with its coefficients, when the
/// sequence ends and begins with one kind of flow that fuses (see the splitting composer's `advance`).
pub fn seam(flows: &[(SubFlow, f64)], r: f64, h: f64) -> Option<(f64, (f64, f64))> {
    match (flows.first(), flows.last()) {
        (Some(&(first, a)), Some(&(last, b))) if flows.len() > 2 && last.fuses_with(first) => {
            let tau = (b + a) * h;
            Some((tau, first.coefficients(r, tau)))
        }
        _ => None,
    }
}

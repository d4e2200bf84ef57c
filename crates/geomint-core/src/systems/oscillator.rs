//! The damped harmonic oscillator q'' + 2γq' + ω²q = 0 (paper 003 eq. 2.5): T = p²/2,
//! V = ω²q²/2, p' = −ω²q − 2γp, with its exact solution in all three damping regimes.

use nalgebra::{DMatrix, U1};

use std::borrow::Cow;

use super::{AnySystem, Builder, ChartInfo, ParamSpec, ParamValues, SystemInfo, World};
use crate::system::lanes::{damp_each_lane, damp_point, PointForces};
use crate::system::{Lane, LaneForces, MechanicalSystem, State, Structure, Vector, LANES};

/// The damped harmonic oscillator.
#[derive(Clone, Debug, PartialEq)]
pub struct HarmonicOscillator {
    /// Angular frequency ω.
    pub omega: f64,
    /// Damping coefficient γ (ε = 2γ).
    pub gamma: f64,
}

impl HarmonicOscillator {
    /// The exact (q, p) at time t from (q0, p0). With a = q0, b = (p0 + γq0) the solution is
    /// e^{−γt}(a C(t) + b S(t)) where C, S are cos βt and sin(βt)/β (under-damped, β² = ω² − γ²),
    /// 1 and t (critical), cosh κt and sinh(κt)/κ (over-damped, κ² = γ² − ω²).
    pub fn solution(&self, t: f64, q0: f64, p0: f64) -> (f64, f64) {
        let g = self.gamma;
        let d = self.omega * self.omega - g * g;
        // e^{−γt}·(C, S, C', S'); in the over-damped case from the two real exponents
        // λ± = γ ± κ (λ₋ = ω²/(γ + κ) without cancellation), so that e^{−γt} cosh κt does not
        // overflow for large κt.
        let (c, s, c_dot, s_dot) = if d > 0.0 {
            let beta = d.sqrt();
            let decay = (-g * t).exp();
            let (sn, cs) = (beta * t).sin_cos();
            (
                decay * cs,
                decay * sn / beta,
                -decay * beta * sn,
                decay * cs,
            )
        } else if d < 0.0 {
            let kappa = (-d).sqrt();
            let slow = (-(self.omega * self.omega / (g + kappa)) * t).exp();
            let fast = (-(g + kappa) * t).exp();
            let ch = 0.5 * (slow + fast);
            let sh = 0.5 * (slow - fast);
            (ch, sh / kappa, kappa * sh, ch)
        } else {
            let decay = (-g * t).exp();
            (decay, decay * t, 0.0, decay)
        };
        let (a, b) = (q0, p0 + g * q0);
        let q = a * c + b * s;
        let p = a * c_dot + b * s_dot - g * q;
        (q, p)
    }
}

impl MechanicalSystem for HarmonicOscillator {
    type Dim = U1;
    fn dim(&self) -> U1 {
        U1
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: true,
            conformal_damping: true,
        }
    }
    fn kinetic(&self, _q: &Vector<U1>, p: &Vector<U1>) -> f64 {
        0.5 * p[0] * p[0]
    }
    fn potential(&self, q: &Vector<U1>) -> f64 {
        0.5 * self.omega * self.omega * q[0] * q[0]
    }
    #[inline]
    fn grad_potential(&self, q: &Vector<U1>, out: &mut Vector<U1>) {
        out[0] = self.omega * self.omega * q[0];
    }
    #[inline]
    fn velocity(&self, _q: &Vector<U1>, p: &Vector<U1>, out: &mut Vector<U1>) {
        out[0] = p[0];
    }
    fn damping_rate(&self) -> f64 {
        2.0 * self.gamma
    }
    fn hess_potential(&self, _q: &Vector<U1>, out: &mut DMatrix<f64>) -> u64 {
        out[(0, 0)] = self.omega * self.omega;
        0
    }
    fn exact(&self, t: f64, start: &State<U1>) -> Option<State<U1>> {
        let (q, p) = self.solution(t, start.q[0], start.p[0]);
        Some(State::from_slices(U1, &[q], &[p]))
    }
}

/// The velocity and force in lanes, with the arithmetic of `velocity` and `grad_potential`.
impl LaneForces<1> for HarmonicOscillator {
    #[inline(always)]
    fn velocity_lanes(&self, p: &[Lane; 1], v: &mut [Lane; 1]) {
        *v = *p;
    }

    #[inline(always)]
    fn grad_lanes(&self, q: &[Lane; 1], g: &mut [Lane; 1]) {
        for l in 0..LANES {
            [g[0][l]] = self.grad_at([q[0][l]]);
        }
    }

    #[inline(always)]
    fn hessian_lanes(&self, _q: &[Lane; 1], hess: &mut [[Lane; 1]; 1]) {
        hess[0][0] = [self.omega * self.omega; LANES];
    }

    #[inline(always)]
    fn damp_lanes(&self, q: &[Lane; 1], p: &mut [Lane; 1], tau: f64, c: &Lane) {
        damp_each_lane(|_| self, q, p, tau, c);
    }
}

impl PointForces<1> for HarmonicOscillator {
    #[inline(always)]
    fn velocity_at(&self, p: [f64; 1]) -> [f64; 1] {
        p
    }

    #[inline(always)]
    fn grad_at(&self, [q]: [f64; 1]) -> [f64; 1] {
        [self.omega * self.omega * q]
    }

    #[inline(always)]
    fn damp_at(&self, q: [f64; 1], p: [f64; 1], tau: f64, c: f64) -> [f64; 1] {
        damp_point(self, q, p, tau, c)
    }
}

/// The oscillator in the order-compensating coordinate of paper 001 Appendix B, eq. (82):
/// Q̄ = Q(q) = (2/π)(q̂ √(1 − q̂²) + arcsin q̂) with q̂ = q/c, c = 1 + k h², and p̄ = p/Q'(q)
/// (the cotangent lift, eq. 41). With q̂ = sin σ this is Q = (sin 2σ + 2σ)/π,
/// Q'(q) = (4/π) cos σ / c and Q''(q) = −(4/(π c²)) tan σ. In this chart
/// H̄ = ½ p̄² Q'(q)² + ½ ω² q² (not separable), ∂H̄/∂p̄ = p̄ Q'², ∂H̄/∂Q̄ = p̄² Q'' + ω² q/Q'.
/// Conformal damping keeps its form: the generalized force −2γp becomes −2γp̄.
///
/// Eq. (81) (k = 0) solves eq. (80), (1 − q²) Q''/Q' + q = 0, which makes symplectic Euler's
/// first-order error term H̄_p̄ H̄_Q̄ vanish along the unit-amplitude motion (ω = 1, q(0) = 1,
/// p(0) = 0); the k h² margin keeps |q̂| < 1 for the numerical solution. The chart depends on the
/// run's step h. The inverse Q̄ ↦ q solves sin 2σ + 2σ = πQ̄ by safeguarded Newton; |Q̄| > 1 lies
/// outside the chart, and a state that gets there reads as non-finite (a divergence).
#[derive(Clone, Debug, PartialEq)]
pub struct CompensatedOscillator {
    /// The oscillator.
    pub oscillator: HarmonicOscillator,
    /// c = 1 + k h².
    pub c: f64,
}

/// Q(q), Q'(q), Q''(q), Q'''(q) at q̂ = sin σ.
#[derive(Clone, Copy, Debug)]
struct Compensation {
    q: f64,
    d1: f64,
    d2: f64,
    d3: f64,
}

impl CompensatedOscillator {
    /// The chart for parameter k and step h.
    pub fn new(oscillator: HarmonicOscillator, k: f64, h: f64) -> Self {
        Self {
            oscillator,
            c: 1.0 + k * h * h,
        }
    }

    /// σ with sin 2σ + 2σ = πQ̄, or NaN outside [−1, 1].
    fn sigma(qbar: f64) -> f64 {
        use std::f64::consts::{FRAC_PI_2, PI};
        if !(-1.0..=1.0).contains(&qbar) {
            return f64::NAN;
        }
        let target = PI * qbar;
        let (mut lo, mut hi) = (-FRAC_PI_2, FRAC_PI_2);
        // The inverse of the odd, increasing g(σ) = sin 2σ + 2σ; a good start is σ = πQ̄/4
        // (g'(0) = 4).
        let mut s = 0.25 * target;
        for _ in 0..100 {
            let g = (2.0 * s).sin() + 2.0 * s - target;
            if g > 0.0 {
                hi = s;
            } else {
                lo = s;
            }
            let slope = 4.0 * s.cos().powi(2);
            let mut next = s - g / slope;
            // Keep Newton inside the bracket; bisect where it would leave it (near ±π/2 the
            // slope vanishes).
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            if (next - s).abs() <= 2.0 * f64::EPSILON * s.abs().max(1e-300) {
                return next;
            }
            s = next;
        }
        s
    }

    /// q and the derivatives of Q at q for a chart coordinate Q̄.
    fn at(&self, qbar: f64) -> Compensation {
        use std::f64::consts::PI;
        let s = Self::sigma(qbar);
        let (sin, cos) = s.sin_cos();
        let c = self.c;
        Compensation {
            q: c * sin,
            d1: 4.0 / PI * cos / c,
            d2: -4.0 / (PI * c * c) * sin / cos,
            d3: -4.0 / (PI * c * c * c) / (cos * cos * cos),
        }
    }

    /// Q(q), or None where |q| ≥ c (outside the chart, or where Q' = 0).
    fn chart_of(&self, q: f64) -> Option<(f64, f64)> {
        use std::f64::consts::PI;
        let qhat = q / self.c;
        if qhat.abs() >= 1.0 || !qhat.is_finite() {
            return None;
        }
        let root = (1.0 - qhat * qhat).sqrt();
        let qbar = 2.0 / PI * (qhat * root + qhat.asin());
        Some((qbar, 4.0 / PI * root / self.c))
    }
}

impl MechanicalSystem for CompensatedOscillator {
    type Dim = U1;
    fn dim(&self) -> U1 {
        U1
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: false,
            conformal_damping: true,
        }
    }
    fn kinetic(&self, q: &Vector<U1>, p: &Vector<U1>) -> f64 {
        let x = self.at(q[0]);
        0.5 * (p[0] * x.d1).powi(2)
    }
    fn potential(&self, q: &Vector<U1>) -> f64 {
        let x = self.at(q[0]);
        0.5 * self.oscillator.omega.powi(2) * x.q * x.q
    }
    fn grad_potential(&self, q: &Vector<U1>, out: &mut Vector<U1>) {
        let x = self.at(q[0]);
        out[0] = self.oscillator.omega.powi(2) * x.q / x.d1;
    }
    fn velocity(&self, q: &Vector<U1>, p: &Vector<U1>, out: &mut Vector<U1>) {
        self.dh_dp(q, p, out)
    }
    fn dh_dp(&self, q: &Vector<U1>, p: &Vector<U1>, out: &mut Vector<U1>) {
        let x = self.at(q[0]);
        out[0] = p[0] * x.d1 * x.d1;
    }
    fn dh_dq(&self, q: &Vector<U1>, p: &Vector<U1>, out: &mut Vector<U1>) {
        let x = self.at(q[0]);
        out[0] = p[0] * p[0] * x.d2 + self.oscillator.omega.powi(2) * x.q / x.d1;
    }
    fn damping_rate(&self) -> f64 {
        2.0 * self.oscillator.gamma
    }
    fn hessian_h(
        &self,
        q: &Vector<U1>,
        p: &Vector<U1>,
        hqq: &mut DMatrix<f64>,
        hqp: &mut DMatrix<f64>,
        hpp: &mut DMatrix<f64>,
    ) -> bool {
        // d/dQ̄ = (1/Q') d/dq.
        let x = self.at(q[0]);
        let w2 = self.oscillator.omega.powi(2);
        let pb = p[0];
        hqq[(0, 0)] = (pb * pb * x.d3 + w2 * (x.d1 - x.q * x.d2) / (x.d1 * x.d1)) / x.d1;
        hqp[(0, 0)] = 2.0 * pb * x.d2;
        hpp[(0, 0)] = x.d1 * x.d1;
        true
    }
    fn solve_momentum_stage(
        &self,
        q: &Vector<U1>,
        p: &Vector<U1>,
        h: f64,
        p1: &mut Vector<U1>,
    ) -> bool {
        // p₁ = p − h (p₁² Q'' + ω² q/Q' + 2γ p₁) is the quadratic a p₁² + b p₁ − d = 0 with
        // a = h Q'', b = 1 + 2γh, d = p − h ω² q/Q'; the root that tends to d/b as h → 0,
        // written without cancellation.
        let x = self.at(q[0]);
        let a = h * x.d2;
        let b = 1.0 + h * self.damping_rate();
        let d = p[0] - h * self.oscillator.omega.powi(2) * x.q / x.d1;
        let disc = b * b + 4.0 * a * d;
        p1[0] = if disc >= 0.0 {
            2.0 * d / (b + disc.sqrt())
        } else {
            f64::NAN
        };
        true
    }
    fn is_cartesian(&self) -> bool {
        false
    }
    fn to_cartesian(&self, q: &Vector<U1>, p: &Vector<U1>, x: &mut [f64], px: &mut [f64]) {
        let c = self.at(q[0]);
        x[0] = c.q;
        px[0] = p[0] * c.d1;
    }
    fn from_cartesian(
        &self,
        x: &[f64],
        px: &[f64],
        q: &mut Vector<U1>,
        p: &mut Vector<U1>,
    ) -> Result<(), String> {
        let (qbar, d1) = self.chart_of(x[0]).ok_or_else(|| {
            format!(
                "the compensating chart covers |q| < 1 + k h² = {}, not q = {}",
                self.c, x[0]
            )
        })?;
        q[0] = qbar;
        p[0] = px[0] / d1;
        Ok(())
    }
    fn exact(&self, t: f64, start: &State<U1>) -> Option<State<U1>> {
        let (mut x, mut px) = ([0.0], [0.0]);
        self.to_cartesian(&start.q, &start.p, &mut x, &mut px);
        let (q, p) = self.oscillator.solution(t, x[0], px[0]);
        let mut end = start.clone();
        self.from_cartesian(&[q], &[p], &mut end.q, &mut end.p)
            .ok()?;
        Some(end)
    }
}

/// The angular frequency.
const OMEGA: ParamSpec = ParamSpec::number("omega", "Angular frequency ω.", 1.0, 0.0, true, 1e6);
/// The damping coefficient.
const GAMMA: ParamSpec = ParamSpec::gamma(0.05);
/// The margin of the compensating chart.
const MARGIN: ParamSpec = ParamSpec::number(
    "k",
    "Margin k of the compensating chart, q̂ = q/(1 + k h²) (paper 001 eq. 82; chart `compensating` only).",
    2.0,
    0.0,
    true,
    1e6,
);
/// Cartesian coordinates.
const CARTESIAN: ChartInfo = ChartInfo::new("cartesian", &["q"], true, "H = p²/2 + ω²q²/2.");
/// The compensating coordinate of 001 eq. (82).
const COMPENSATING: ChartInfo = ChartInfo::new(
    "compensating",
    &["Q"],
    false,
    "Q = (2/π)(q̂√(1 − q̂²) + arcsin q̂), q̂ = q/(1 + k h²), p̄ = p/Q'(q) (paper 001 eq. 82); H̄ = ½ p̄² Q'(q)² + ½ ω² q² is not separable. Symplectic Euler's first-order energy error vanishes along the unit-amplitude motion (ω = 1, q0 = 1, p0 = 0).",
);

/// The catalogue entry of `harmonic_oscillator`.
pub(super) fn entry() -> SystemInfo {
    SystemInfo {
        id: Cow::Borrowed("harmonic_oscillator"),
        name: Cow::Borrowed("Damped harmonic oscillator"),
        description: Cow::Borrowed("q'' + 2γq' + ω²q = 0 with T = p²/2, V = ω²q²/2 (paper 003 eq. 2.5); exact solution in the under-, critically and over-damped regimes."),
        degrees_of_freedom: 1,
        charts: vec![CARTESIAN, COMPENSATING],
        params: vec![OMEGA, GAMMA, MARGIN],
        q0: vec![1.0],
        p0: vec![0.0],
        invariants: Vec::new(),
        exact_solution: true,
        conformal_damping: true,
        world: World::Line,
        build: Builder::Catalog(|p: &ParamValues, chart: &ChartInfo, h: f64| {
            let oscillator = HarmonicOscillator {
                omega: p.number(&OMEGA),
                gamma: p.number(&GAMMA),
            };
            if chart.id == COMPENSATING.id {
                AnySystem::CompensatedOscillator(CompensatedOscillator::new(
                    oscillator,
                    p.number(&MARGIN),
                    h,
                ))
            } else {
                AnySystem::HarmonicOscillator(oscillator)
            }
        }),
    }
}

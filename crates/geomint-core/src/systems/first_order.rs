//! First-order ODEs y' = f(y) of paper 001 Sec. 2.3, and their variable transformations.
//!
//! An ODE enters the mechanical framework through its cotangent lift: H(y, p) = p f(y) gives
//! y' = ∂H/∂p = f(y) and the adjoint equation p' = −p f'(y). With p(0) = 0 the momentum stays 0
//! and H = 0, and every method's y-part is that method applied to the ODE itself (explicit Euler
//! on the lift is explicit Euler on y). A variable transformation ȳ = Ψ(y) is then a point
//! transformation with the cotangent lift p̄ = p/Ψ'(y) (001 eqs. 40–41), so it is a chart like
//! any other: H̄(ȳ, p̄) = p̄ Ψ'(y) f(y), and "Cartesian" coordinates are the original variable y.
//!
//! Both systems offer the chart `transformed` with the compensating Ψ of eq. (13), Ψ' = 1/f, in
//! which ȳ' = ∓1 and explicit Euler is exact:
//! - `exponential_decay`, y' = −αy, Ψ(y) = ln(y)/α (eq. 15), ȳ' = −1;
//! - `gompertz`, y' = y (a − b ln y), Ψ(y) = −(1/b) ln(1 − (b/a) ln y), ȳ' = 1. Eq. (18) adds the
//!   constant (1/b) ln(1 − (b/a) ln y₀) so that ȳ(0) = 0; any constant gives the same ȳ' = 1
//!   (it is eq. 13's C₂), and leaving it out keeps the chart independent of the initial state.

use nalgebra::{DMatrix, U1};

use std::borrow::Cow;

use super::{AnySystem, Builder, ChartInfo, ParamSpec, ParamValues, SystemInfo, World};
use crate::system::{MechanicalSystem, State, Structure, Vector};

/// y' = −αy.
#[derive(Clone, Debug, PartialEq)]
pub struct ExponentialDecay {
    /// Rate α > 0.
    pub alpha: f64,
    /// Whether the state is ȳ = ln(y)/α rather than y.
    pub transformed: bool,
}

/// y' = y (a − b ln y), the Gompertz growth law (001 eq. 17).
#[derive(Clone, Debug, PartialEq)]
pub struct Gompertz {
    /// Growth parameter a > 0.
    pub a: f64,
    /// Growth parameter b > 0 (the carrying capacity is e^{a/b}).
    pub b: f64,
    /// Whether the state is ȳ = Ψ(y) of eq. (18) rather than y.
    pub transformed: bool,
}

/// What distinguishes the two ODEs: f, f', and the transformation Ψ with its inverse.
trait Ode {
    fn f(&self, y: f64) -> f64;
    fn df(&self, y: f64) -> f64;
    /// Ψ(y), or why y lies outside the transformation's domain.
    fn psi(&self, y: f64) -> Result<f64, String>;
    fn psi_inverse(&self, ybar: f64) -> f64;
    /// The constant ȳ' = Ψ'(y) f(y) in the transformed chart.
    fn transformed_rate(&self) -> f64;
    /// The exact y(t) from y₀.
    fn solution(&self, t: f64, y0: f64) -> f64;
}

impl Ode for ExponentialDecay {
    fn f(&self, y: f64) -> f64 {
        -self.alpha * y
    }
    fn df(&self, _y: f64) -> f64 {
        -self.alpha
    }
    fn psi(&self, y: f64) -> Result<f64, String> {
        if y > 0.0 {
            Ok(y.ln() / self.alpha)
        } else {
            Err(format!("Ψ(y) = ln(y)/α needs y > 0, got {y}"))
        }
    }
    fn psi_inverse(&self, ybar: f64) -> f64 {
        (self.alpha * ybar).exp()
    }
    fn transformed_rate(&self) -> f64 {
        -1.0
    }
    fn solution(&self, t: f64, y0: f64) -> f64 {
        y0 * (-self.alpha * t).exp()
    }
}

impl Ode for Gompertz {
    fn f(&self, y: f64) -> f64 {
        y * (self.a - self.b * y.ln())
    }
    fn df(&self, y: f64) -> f64 {
        self.a - self.b * y.ln() - self.b
    }
    fn psi(&self, y: f64) -> Result<f64, String> {
        let inner = 1.0 - self.b / self.a * y.ln();
        if y > 0.0 && inner > 0.0 {
            Ok(-inner.ln() / self.b)
        } else {
            Err(format!(
                "Ψ of eq. (18) needs 0 < y < e^(a/b) = {}, got {y}",
                (self.a / self.b).exp()
            ))
        }
    }
    fn psi_inverse(&self, ybar: f64) -> f64 {
        // ln y = (a/b)(1 − e^{−b ȳ}).
        (self.a / self.b * -(-self.b * ybar).exp_m1()).exp()
    }
    fn transformed_rate(&self) -> f64 {
        1.0
    }
    fn solution(&self, t: f64, y0: f64) -> f64 {
        // ln y(t) = a/b + (ln y₀ − a/b) e^{−bt}.
        let k = self.a / self.b;
        (k + (y0.ln() - k) * (-self.b * t).exp()).exp()
    }
}

/// The chart machinery shared by both ODEs.
macro_rules! first_order_system {
    ($ty:ty) => {
        impl MechanicalSystem for $ty {
            type Dim = U1;
            fn dim(&self) -> U1 {
                U1
            }
            fn structure(&self) -> Structure {
                Structure {
                    separable_constant_mass: false,
                    conformal_damping: false,
                }
            }
            fn kinetic(&self, q: &Vector<U1>, p: &Vector<U1>) -> f64 {
                let mut v = Vector::<U1>::zeros();
                self.dh_dp(q, p, &mut v);
                p[0] * v[0]
            }
            fn potential(&self, _q: &Vector<U1>) -> f64 {
                0.0
            }
            fn grad_potential(&self, _q: &Vector<U1>, out: &mut Vector<U1>) {
                out[0] = 0.0;
            }
            fn velocity(&self, q: &Vector<U1>, p: &Vector<U1>, out: &mut Vector<U1>) {
                self.dh_dp(q, p, out)
            }
            #[inline]
            fn dh_dp(&self, q: &Vector<U1>, _p: &Vector<U1>, out: &mut Vector<U1>) {
                out[0] = if self.transformed {
                    self.transformed_rate()
                } else {
                    self.f(q[0])
                };
            }
            #[inline]
            fn dh_dq(&self, q: &Vector<U1>, p: &Vector<U1>, out: &mut Vector<U1>) {
                out[0] = if self.transformed {
                    0.0
                } else {
                    p[0] * self.df(q[0])
                };
            }
            fn damping_rate(&self) -> f64 {
                0.0
            }
            fn hessian_h(
                &self,
                q: &Vector<U1>,
                p: &Vector<U1>,
                hqq: &mut DMatrix<f64>,
                hqp: &mut DMatrix<f64>,
                hpp: &mut DMatrix<f64>,
            ) -> bool {
                hpp[(0, 0)] = 0.0;
                if self.transformed {
                    hqq[(0, 0)] = 0.0;
                    hqp[(0, 0)] = 0.0;
                } else {
                    // f'' is b/y for Gompertz' f' = a − b ln y − b and 0 for the decay; take it
                    // by differencing f', which is cheap and smooth here.
                    let y = q[0];
                    let d = 1e-6 * y.abs().max(1e-6);
                    hqq[(0, 0)] = p[0] * (self.df(y + d) - self.df(y - d)) / (2.0 * d);
                    hqp[(0, 0)] = self.df(y);
                }
                true
            }
            fn solve_momentum_stage(
                &self,
                q: &Vector<U1>,
                p: &Vector<U1>,
                h: f64,
                p1: &mut Vector<U1>,
            ) -> bool {
                // p₁ = p − h p₁ f'(y): linear.
                p1[0] = if self.transformed {
                    p[0]
                } else {
                    p[0] / (1.0 + h * self.df(q[0]))
                };
                true
            }
            fn is_cartesian(&self) -> bool {
                !self.transformed
            }
            fn to_cartesian(&self, q: &Vector<U1>, p: &Vector<U1>, x: &mut [f64], px: &mut [f64]) {
                if self.transformed {
                    // p = p̄ Ψ'(y) = p̄ / f(y) · ȳ', since Ψ' f is the constant ȳ'.
                    let y = self.psi_inverse(q[0]);
                    x[0] = y;
                    px[0] = p[0] * self.transformed_rate() / self.f(y);
                } else {
                    x[0] = q[0];
                    px[0] = p[0];
                }
            }
            fn from_cartesian(
                &self,
                x: &[f64],
                px: &[f64],
                q: &mut Vector<U1>,
                p: &mut Vector<U1>,
            ) -> Result<(), String> {
                if self.transformed {
                    q[0] = self.psi(x[0])?;
                    p[0] = px[0] * self.f(x[0]) / self.transformed_rate();
                } else {
                    q[0] = x[0];
                    p[0] = px[0];
                }
                Ok(())
            }
            fn exact(&self, t: f64, start: &State<U1>) -> Option<State<U1>> {
                let (mut y0, mut p0) = ([0.0], [0.0]);
                self.to_cartesian(&start.q, &start.p, &mut y0, &mut p0);
                let y = self.solution(t, y0[0]);
                // H = p f(y) is conserved: p(t) = p₀ f(y₀)/f(y(t)).
                let p = if p0[0] == 0.0 {
                    0.0
                } else {
                    p0[0] * self.f(y0[0]) / self.f(y)
                };
                let mut end = start.clone();
                if self.transformed {
                    // The exact transformed flow is ȳ₀ + t ȳ' (the inverse map would lose
                    // digits near the carrying capacity).
                    end.q[0] = start.q[0] + t * self.transformed_rate();
                    end.p[0] = start.p[0];
                } else {
                    end.q[0] = y;
                    end.p[0] = p;
                }
                Some(end)
            }
        }
    };
}

first_order_system!(ExponentialDecay);
first_order_system!(Gompertz);

const ALPHA: ParamSpec = ParamSpec::number("alpha", "Decay rate α.", 1.0, 0.0, true, 1e6);
const GROWTH_A: ParamSpec = ParamSpec::number("a", "Growth parameter a.", 2.0, 0.0, true, 1e6);
const GROWTH_B: ParamSpec = ParamSpec::number(
    "b",
    "Growth parameter b (carrying capacity e^(a/b)).",
    0.5,
    0.0,
    true,
    1e6,
);
/// The id of the chart in which explicit Euler is exact.
const TRANSFORMED: &str = "transformed";

/// The catalogue entry of `exponential_decay`.
pub(super) fn exponential_decay_entry() -> SystemInfo {
    SystemInfo {
        id: Cow::Borrowed("exponential_decay"),
        name: Cow::Borrowed("Exponential decay (first-order ODE)"),
        description: Cow::Borrowed("y' = −αy (paper 001 eq. 14), run as the cotangent lift H = p f(y) (p stays 0 from p0 = 0, H = 0). In the chart `transformed`, ȳ = ln(y)/α (eq. 15) obeys ȳ' = −1 and explicit Euler is exact."),
        degrees_of_freedom: 1,
        charts: vec![
            ChartInfo::new("original", &["y"], false, "y' = −αy; H = −α p y."),
            ChartInfo::new(
                TRANSFORMED,
                &["ȳ"],
                false,
                "ȳ = ln(y)/α, p̄ = p α y (001 eq. 15): ȳ' = −1, H̄ = −p̄.",
            ),
        ],
        params: vec![ALPHA],
        q0: vec![1.0],
        p0: vec![0.0],
        invariants: Vec::new(),
        exact_solution: true,
        conformal_damping: false,
        world: World::Line,
        build: Builder::Catalog(|p: &ParamValues, chart: &ChartInfo, _: f64| {
            AnySystem::ExponentialDecay(ExponentialDecay {
                alpha: p.number(&ALPHA),
                transformed: chart.id == TRANSFORMED,
            })
        }),
    }
}

/// The catalogue entry of `gompertz`.
pub(super) fn gompertz_entry() -> SystemInfo {
    SystemInfo {
        id: Cow::Borrowed("gompertz"),
        name: Cow::Borrowed("Gompertz growth (first-order ODE)"),
        description: Cow::Borrowed("y' = y (a − b ln y) (paper 001 eq. 17), run as the cotangent lift H = p f(y). In the chart `transformed`, ȳ = −(1/b) ln(1 − (b/a) ln y) (eq. 18 up to its additive constant) obeys ȳ' = 1 and explicit Euler is exact; it covers 0 < y < e^(a/b)."),
        degrees_of_freedom: 1,
        charts: vec![
            ChartInfo::new("original", &["y"], false, "y' = y (a − b ln y); H = p y (a − b ln y)."),
            ChartInfo::new(
                TRANSFORMED,
                &["ȳ"],
                false,
                "ȳ = −(1/b) ln(1 − (b/a) ln y), p̄ = p y (a − b ln y) (001 eq. 18): ȳ' = 1, H̄ = p̄.",
            ),
        ],
        params: vec![GROWTH_A, GROWTH_B],
        q0: vec![3.0],
        p0: vec![0.0],
        invariants: Vec::new(),
        exact_solution: true,
        conformal_damping: false,
        world: World::Line,
        build: Builder::Catalog(|p: &ParamValues, chart: &ChartInfo, _: f64| {
            AnySystem::Gompertz(Gompertz {
                a: p.number(&GROWTH_A),
                b: p.number(&GROWTH_B),
                transformed: chart.id == TRANSFORMED,
            })
        }),
    }
}

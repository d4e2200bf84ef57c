//! The damped planar pendulum (paper 000 Sec. 4.3; paper 003 eq. 4.5): T = p²/2, V = 1 − cos q,
//! p' = −sin q − 2γp (000 writes ε p with ε = 2γ).

use nalgebra::{DMatrix, U1};

use std::borrow::Cow;

use super::{AnySystem, Builder, ChartInfo, ParamSpec, ParamValues, SystemInfo, World};
use crate::system::{MechanicalSystem, Structure, Vector};

/// The damped pendulum with unit mass, length and gravity.
#[derive(Clone, Debug, PartialEq)]
pub struct Pendulum {
    /// Damping coefficient γ (ε = 2γ).
    pub gamma: f64,
}

impl MechanicalSystem for Pendulum {
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
        1.0 - q[0].cos()
    }
    #[inline]
    fn grad_potential(&self, q: &Vector<U1>, out: &mut Vector<U1>) {
        out[0] = q[0].sin();
    }
    #[inline]
    fn velocity(&self, _q: &Vector<U1>, p: &Vector<U1>, out: &mut Vector<U1>) {
        out[0] = p[0];
    }
    fn damping_rate(&self) -> f64 {
        2.0 * self.gamma
    }
    fn hess_potential(&self, q: &Vector<U1>, out: &mut DMatrix<f64>) -> u64 {
        out[(0, 0)] = q[0].cos();
        0
    }
}

/// The damping coefficient.
const GAMMA: ParamSpec = ParamSpec::gamma(0.005);
/// The one chart.
const CARTESIAN: ChartInfo = ChartInfo::new("cartesian", &["q"], true, "H = p²/2 + 1 − cos q.");

/// The catalogue entry of `pendulum`.
pub(super) fn entry() -> SystemInfo {
    SystemInfo {
        id: Cow::Borrowed("pendulum"),
        name: Cow::Borrowed("Damped pendulum"),
        description: Cow::Borrowed(
            "T = p²/2, V = 1 − cos q, p' = −sin q − 2γp (paper 000 Sec. 4.3, paper 003 eq. 4.5).",
        ),
        degrees_of_freedom: 1,
        charts: vec![CARTESIAN],
        params: vec![GAMMA],
        q0: vec![0.9 * std::f64::consts::PI],
        p0: vec![0.0],
        invariants: Vec::new(),
        exact_solution: false,
        conformal_damping: true,
        world: World::Pendulum,
        build: Builder::Catalog(|p: &ParamValues, _: &ChartInfo, _: f64| {
            AnySystem::Pendulum(Pendulum {
                gamma: p.number(&GAMMA),
            })
        }),
    }
}

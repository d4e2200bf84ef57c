//! The Hénon–Heiles system (M. Hénon & C. Heiles, Astron. J. 69 (1964) 73), the classic test of
//! regular and chaotic motion in two degrees of freedom, with optional linear damping:
//! H = (p_x² + p_y²)/2 + (x² + y²)/2 + λ(x²y − y³/3), p' = −∇V − 2γp. With λ = 1 the motion is
//! bounded for H < 1/6; at H = 1/8 regular and chaotic orbits share the (y, p_y) section, at
//! H = 1/6 most of it is chaotic. The default orbit, (x, y, p_x, p_y) = (0, −0.25, 0.42, 0) at
//! H ≈ 1/8, is a chaotic one of the SALI literature (Skokos, J. Phys. A 34 (2001) 10029).
//!
//! Its force is written once, over any number type ([`HenonHeiles::force`]): the one-run path
//! and the lanes compute it on `f64`s, and traced (`expr::trace`) it is the program that the
//! splittings' and Runge–Kutta methods' compiled steps write into their code, as for a system
//! typed in, with the same bits as the `f64` path.

use std::borrow::Cow;
use std::sync::{Arc, Mutex, PoisonError};

use nalgebra::{DMatrix, U2};

use super::custom::BuiltInSteps;
use super::{AnySystem, Builder, ChartInfo, ParamSpec, ParamValues, SystemInfo, World};
use crate::expr::trace;
use crate::flows::compiled::CompiledForces;
use crate::flows::Real;
use crate::system::lanes::{damp_each_lane, damp_point, PointForces};
use crate::system::{Lane, LaneForces, LANES};
use crate::system::{MechanicalSystem, Structure, Vector};

/// The Hénon–Heiles system with unit masses and frequencies. Its parameters are fixed when it is
/// made ([`HenonHeiles::new`]): its compiled code is built for them.
#[derive(Clone)]
pub struct HenonHeiles {
    /// The strength λ of the cubic coupling.
    lambda: f64,
    /// Damping coefficient γ (p' = … − 2γp).
    gamma: f64,
    /// Its compiled steps, shared by its clones.
    code: Arc<BuiltInSteps>,
}

impl std::fmt::Debug for HenonHeiles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HenonHeiles")
            .field("lambda", &self.lambda)
            .field("gamma", &self.gamma)
            .finish_non_exhaustive()
    }
}

/// Two systems are equal when their parameters are; the code built for them is not compared.
impl PartialEq for HenonHeiles {
    fn eq(&self, other: &Self) -> bool {
        (self.lambda, self.gamma) == (other.lambda, other.gamma)
    }
}

impl MechanicalSystem for HenonHeiles {
    type Dim = U2;
    fn dim(&self) -> U2 {
        U2
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: true,
            conformal_damping: true,
        }
    }
    fn kinetic(&self, _q: &Vector<U2>, p: &Vector<U2>) -> f64 {
        0.5 * (p[0] * p[0] + p[1] * p[1])
    }
    fn potential(&self, q: &Vector<U2>) -> f64 {
        let (x, y) = (q[0], q[1]);
        0.5 * (x * x + y * y) + self.lambda * (x * x * y - y * y * y / 3.0)
    }
    #[inline]
    fn grad_potential(&self, q: &Vector<U2>, out: &mut Vector<U2>) {
        [out[0], out[1]] = self.grad(q[0], q[1]);
    }
    #[inline]
    fn velocity(&self, _q: &Vector<U2>, p: &Vector<U2>, out: &mut Vector<U2>) {
        out[0] = p[0];
        out[1] = p[1];
    }
    fn damping_rate(&self) -> f64 {
        2.0 * self.gamma
    }
    fn hess_potential(&self, q: &Vector<U2>, out: &mut DMatrix<f64>) -> u64 {
        let [[a, b], [c, d]] = self.hessian(q[0], q[1]);
        out[(0, 0)] = a;
        out[(0, 1)] = b;
        out[(1, 0)] = c;
        out[(1, 1)] = d;
        0
    }
    fn compiled_forces(&self) -> Option<CompiledForces<'_>> {
        self.code.forces()
    }
}

/// The force and Hessian at one point: the one formula the one-run path, the lanes and the
/// compiled steps share.
impl HenonHeiles {
    /// The system of coupling `lambda` and damping `gamma`. Systems of the same parameters made
    /// one after the other (the cells of a sweep over initial states) share their compiled code.
    pub fn new(lambda: f64, gamma: f64) -> Self {
        /// The code of the parameters last asked for.
        static LAST: Mutex<Option<([u64; 2], Arc<BuiltInSteps>)>> = Mutex::new(None);
        let key = [lambda.to_bits(), gamma.to_bits()];
        let mut last = LAST.lock().unwrap_or_else(PoisonError::into_inner);
        let code = match last.as_ref().filter(|(k, _)| *k == key) {
            Some((_, code)) => Arc::clone(code),
            None => {
                // With λ = 0 the expression graph would drop the products by the constant 0
                // (see `expr::trace`), which can change the sign of a zero: such a system
                // keeps the generic steps.
                let gradient = (lambda != 0.0)
                    .then(|| {
                        trace::program(|[x, y]| Self::force(lambda, x, y, |c| x.constant(c))).ok()
                    })
                    .flatten();
                let code = Arc::new(BuiltInSteps::new(2, gradient, 2.0 * gamma));
                *last = Some((key, Arc::clone(&code)));
                code
            }
        };
        HenonHeiles {
            lambda,
            gamma,
            code,
        }
    }

    /// The system without compiled steps: every step on the generic path (to compare the two).
    pub fn without_compiled_steps(self) -> Self {
        HenonHeiles {
            code: Arc::new(BuiltInSteps::new(2, None, self.damping_rate())),
            ..self
        }
    }

    /// Whether compiled steps were built for the last plan or tableau its runs asked for.
    pub fn has_compiled_steps(&self) -> bool {
        self.code.built()
    }

    /// ∇V at (x, y) for coupling `lambda`, over any numbers, with `number` making constants.
    #[inline(always)]
    fn force<T: Real>(lambda: f64, x: T, y: T, number: impl Fn(f64) -> T) -> [T; 2] {
        [
            x + number(2.0 * lambda) * x * y,
            y + number(lambda) * (x * x - y * y),
        ]
    }

    #[inline(always)]
    fn grad(&self, x: f64, y: f64) -> [f64; 2] {
        Self::force(self.lambda, x, y, |c| c)
    }

    #[inline(always)]
    fn hessian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let (cx, cy) = (2.0 * self.lambda * x, 2.0 * self.lambda * y);
        [[1.0 + cy, cx], [cx, 1.0 - cy]]
    }
}

impl LaneForces<2> for HenonHeiles {
    #[inline(always)]
    fn velocity_lanes(&self, p: &[Lane; 2], v: &mut [Lane; 2]) {
        *v = *p;
    }

    #[inline(always)]
    fn grad_lanes(&self, q: &[Lane; 2], g: &mut [Lane; 2]) {
        for l in 0..LANES {
            [g[0][l], g[1][l]] = self.grad(q[0][l], q[1][l]);
        }
    }

    #[inline(always)]
    fn hessian_lanes(&self, q: &[Lane; 2], hess: &mut [[Lane; 2]; 2]) {
        for l in 0..LANES {
            let [[a, b], [c, d]] = self.hessian(q[0][l], q[1][l]);
            hess[0][0][l] = a;
            hess[0][1][l] = b;
            hess[1][0][l] = c;
            hess[1][1][l] = d;
        }
    }
    #[inline(always)]
    fn damp_lanes(&self, q: &[Lane; 2], p: &mut [Lane; 2], tau: f64, c: &Lane) {
        damp_each_lane(|_| self, q, p, tau, c);
    }

    fn compiled_forces_in_lanes(&self) -> Option<CompiledForces<'_>> {
        self.compiled_forces()
    }

    fn single_steps_compiled(&self) -> bool {
        false
    }
}

impl PointForces<2> for HenonHeiles {
    #[inline(always)]
    fn velocity_at(&self, p: [f64; 2]) -> [f64; 2] {
        p
    }

    #[inline(always)]
    fn grad_at(&self, [x, y]: [f64; 2]) -> [f64; 2] {
        self.grad(x, y)
    }

    #[inline(always)]
    fn damp_at(&self, q: [f64; 2], p: [f64; 2], tau: f64, c: f64) -> [f64; 2] {
        damp_point(self, q, p, tau, c)
    }
}

const LAMBDA: ParamSpec = ParamSpec::number(
    "lambda",
    "Strength λ of the cubic coupling x²y − y³/3.",
    1.0,
    -1e3,
    false,
    1e3,
);
const GAMMA: ParamSpec = ParamSpec::gamma(0.0);
const CARTESIAN: ChartInfo = ChartInfo::new(
    "cartesian",
    &["x", "y"],
    true,
    "H = (p_x² + p_y²)/2 + (x² + y²)/2 + λ(x²y − y³/3).",
);

/// The catalogue entry of `henon_heiles`.
pub(super) fn entry() -> SystemInfo {
    SystemInfo {
        id: Cow::Borrowed("henon_heiles"),
        name: Cow::Borrowed("Hénon–Heiles"),
        description: Cow::Borrowed(
            "H = (p_x² + p_y²)/2 + (x² + y²)/2 + λ(x²y − y³/3), p' = −∇V − 2γp (Hénon & Heiles 1964): \
             regular and chaotic orbits side by side at H = 1/8, mostly chaos at H = 1/6.",
        ),
        degrees_of_freedom: 2,
        charts: vec![CARTESIAN],
        params: vec![LAMBDA, GAMMA],
        q0: vec![0.0, -0.25],
        p0: vec![0.42, 0.0],
        invariants: Vec::new(),
        exact_solution: false,
        conformal_damping: true,
        world: World::Plane,
        build: Builder::Catalog(|p: &ParamValues, _: &ChartInfo, _: f64| {
            AnySystem::HenonHeiles(HenonHeiles::new(p.number(&LAMBDA), p.number(&GAMMA)))
        }),
    }
}

//! The elastic 3-D pendulum with damping along the spring (paper 000 Sec. 6.2, eq. 16): a mass m on
//! a spring of stiffness k and rest length l, gravity (0, 0, −g),
//! V = k/2 (l − |q|)² + m g q_z, M = m I, D(q) = q qᵀ/|q|².
//!
//! Only the radial momentum is damped, at the rate ε/m; D is singular (rank one). Both gravity
//! and the spring are invariant under rotations about the z axis, and so is D, so
//! J₃ = (q × p)_z is conserved for every ε.

use nalgebra::{DMatrix, U3};

use std::borrow::Cow;

use super::{AnySystem, Builder, ChartInfo, ParamSpec, ParamValues, SystemInfo, World};
use crate::system::lanes::{damp_each_lane, damp_point, PointForces};
use crate::system::{Lane, LaneForces, LANES};
use crate::system::{MechanicalSystem, Structure, Vector};

/// a·b, summed in index order.
#[inline(always)]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The damped elastic 3-D pendulum.
#[derive(Clone, Debug, PartialEq)]
pub struct ElasticPendulum3d {
    /// Mass.
    pub m: f64,
    /// Spring stiffness.
    pub k: f64,
    /// Spring rest length.
    pub l: f64,
    /// Gravitational acceleration (acting along −z).
    pub g: f64,
    /// Damping strength ε of the radial dissipation.
    pub epsilon: f64,
}

impl MechanicalSystem for ElasticPendulum3d {
    type Dim = U3;
    fn dim(&self) -> U3 {
        U3
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: true,
            conformal_damping: false,
        }
    }
    fn kinetic(&self, _q: &Vector<U3>, p: &Vector<U3>) -> f64 {
        0.5 * p.norm_squared() / self.m
    }
    fn potential(&self, q: &Vector<U3>) -> f64 {
        let stretch = self.l - q.norm();
        0.5 * self.k * stretch * stretch + self.m * self.g * q[2]
    }
    #[inline]
    fn grad_potential(&self, q: &Vector<U3>, out: &mut Vector<U3>) {
        [out[0], out[1], out[2]] = self.grad(q);
    }
    #[inline]
    fn velocity(&self, _q: &Vector<U3>, p: &Vector<U3>, out: &mut Vector<U3>) {
        [out[0], out[1], out[2]] = self.velocity_of(p);
    }
    fn damping_rate(&self) -> f64 {
        self.epsilon / self.m
    }
    #[inline]
    fn project_damped(&self, q: &Vector<U3>, v: &Vector<U3>, out: &mut Vector<U3>) {
        // Divided by |q|² last: the damping flow follows a drift, so q is the late input and
        // q·v and |q|² are computed side by side (unlike the kick below).
        let c = q.dot(v) / q.norm_squared();
        out[0] = c * q[0];
        out[1] = c * q[1];
        out[2] = c * q[2];
    }
    /// r P(q) p through [`Self::projection_row`]: in a Runge–Kutta stage q and p arrive
    /// together, and the division then runs beside the force's square root (rk4 on this system:
    /// 84 → 57 ns per step).
    #[inline]
    fn damping_force(&self, q: &Vector<U3>, p: &Vector<U3>, out: &mut Vector<U3>) {
        let c = self.damping_rate() * dot(Self::projection_row(q), [p[0], p[1], p[2]]);
        out[0] = c * q[0];
        out[1] = c * q[1];
        out[2] = c * q[2];
    }
    /// The default's p ← p − τ g + P(q)(−c p + d g), rearranged so that only two operations
    /// follow the force's latency. With g = c_r q + m g e_z (c_r = k(1 − l/r), see
    /// [`Self::radial_coefficient`]) and q·q/|q|² = 1,
    /// P(q)(d g − c p) = (d c_r + (d m g q_z − c q·p)/|q|²) q, so
    /// p ← (p − τ m g e_z) + ((d − τ) c_r + (d m g q_z − c q·p)/|q|²) q,
    /// where everything but c_r is ready before the force is. `g` is ∇V(q), as the kick's force
    /// always is, and c_r is taken from q instead: the compiler merges it with the force
    /// computed just before, and a cached force gives the same bits as a fresh one.
    #[inline]
    fn kick_damp_flow(
        &self,
        q: &Vector<U3>,
        p: &mut Vector<U3>,
        _g: &Vector<U3>,
        tau: f64,
        (c, d): (f64, f64),
        _w: &mut Vector<U3>,
        _pw: &mut Vector<U3>,
    ) {
        let q = [q[0], q[1], q[2]];
        let weight = self.m * self.g;
        let inverse = 1.0 / dot(q, q);
        let early = (d * weight * q[2] - c * dot(q, [p[0], p[1], p[2]])) * inverse;
        let along = (d - tau) * self.radial_coefficient(q) + early;
        p[0] += along * q[0];
        p[1] += along * q[1];
        p[2] = (p[2] - tau * weight) + along * q[2];
    }
    fn projector_derivative(&self, q: &Vector<U3>, v: &Vector<U3>, out: &mut DMatrix<f64>) -> bool {
        spring_projector_derivative([q[0], q[1], q[2]], v, [true, true, true], out);
        true
    }
    fn hess_potential(&self, q: &Vector<U3>, out: &mut DMatrix<f64>) -> u64 {
        let h = self.hessian(q);
        for i in 0..3 {
            for j in 0..3 {
                out[(i, j)] = h[i][j];
            }
        }
        0
    }
    fn invariant_count(&self) -> usize {
        1
    }
    fn invariants(&self, _t: f64, q: &Vector<U3>, p: &Vector<U3>, out: &mut [f64]) {
        out[0] = q[0] * p[1] - q[1] * p[0];
    }
}

/// The velocity, force and Hessian at one point: the one formula the one-run path and the lanes
/// share.
impl ElasticPendulum3d {
    #[inline(always)]
    fn velocity_of(&self, p: &Vector<U3>) -> [f64; 3] {
        let inv_m = 1.0 / self.m;
        [p[0] * inv_m, p[1] * inv_m, p[2] * inv_m]
    }

    /// q/|q|², the row of the projector P(q) = q qᵀ/|q|² = q (q/|q|²)ᵀ. It depends on q alone,
    /// so in a Runge–Kutta stage its division runs while the force is computed.
    #[inline(always)]
    fn projection_row(q: &Vector<U3>) -> [f64; 3] {
        let inverse = 1.0 / q.norm_squared();
        [q[0] * inverse, q[1] * inverse, q[2] * inverse]
    }

    /// ∇V = c_r q + m g e_z with the radial coefficient c_r of [`Self::radial_coefficient`].
    #[inline(always)]
    fn grad(&self, q: &Vector<U3>) -> [f64; 3] {
        let c = self.radial_coefficient([q[0], q[1], q[2]]);
        [c * q[0], c * q[1], c * q[2] + self.m * self.g]
    }

    /// c_r = k(1 − l/r), with l/r computed as (l/r²)·r: the division by r² runs beside the
    /// square root instead of after it. A long run's step is bound by the chain of latencies
    /// from one stage to the next (drift, force, kick), not by throughput, and this takes a
    /// division's latency off it. It rounds once more than l/r: the pinned snapshots of this
    /// system changed with it.
    #[inline(always)]
    fn radial_coefficient(&self, q: [f64; 3]) -> f64 {
        let r2 = dot(q, q);
        let l_over_r2 = self.l / r2;
        self.k * (1.0 - l_over_r2 * r2.sqrt())
    }

    /// ∇V = k(1 − l/r) q + m g e_z, so ∇²V = k(1 − l/r) I + k l q qᵀ / r³.
    #[inline(always)]
    fn hessian(&self, q: &Vector<U3>) -> [[f64; 3]; 3] {
        let r = q.norm();
        let a = self.k * (1.0 - self.l / r);
        let b = self.k * self.l / (r * r * r);
        std::array::from_fn(|i| {
            std::array::from_fn(|j| b * q[i] * q[j] + if i == j { a } else { 0.0 })
        })
    }
}

impl LaneForces<3> for ElasticPendulum3d {
    #[inline(always)]
    fn velocity_lanes(&self, p: &[Lane; 3], v: &mut [Lane; 3]) {
        for l in 0..LANES {
            [v[0][l], v[1][l], v[2][l]] =
                self.velocity_of(&Vector::<U3>::new(p[0][l], p[1][l], p[2][l]));
        }
    }

    #[inline(always)]
    fn grad_lanes(&self, q: &[Lane; 3], g: &mut [Lane; 3]) {
        for l in 0..LANES {
            [g[0][l], g[1][l], g[2][l]] = self.grad(&Vector::<U3>::new(q[0][l], q[1][l], q[2][l]));
        }
    }

    #[inline(always)]
    fn hessian_lanes(&self, q: &[Lane; 3], hess: &mut [[Lane; 3]; 3]) {
        for l in 0..LANES {
            let h = self.hessian(&Vector::<U3>::new(q[0][l], q[1][l], q[2][l]));
            for i in 0..3 {
                for j in 0..3 {
                    hess[i][j][l] = h[i][j];
                }
            }
        }
    }
    #[inline(always)]
    fn damp_lanes(&self, q: &[Lane; 3], p: &mut [Lane; 3], tau: f64, c: &Lane) {
        damp_each_lane(|_| self, q, p, tau, c);
    }
}

impl PointForces<3> for ElasticPendulum3d {
    #[inline(always)]
    fn velocity_at(&self, p: [f64; 3]) -> [f64; 3] {
        self.velocity_of(&Vector::<U3>::from(p))
    }

    #[inline(always)]
    fn grad_at(&self, q: [f64; 3]) -> [f64; 3] {
        self.grad(&Vector::<U3>::from(q))
    }

    #[inline(always)]
    fn damp_at(&self, q: [f64; 3], p: [f64; 3], tau: f64, c: f64) -> [f64; 3] {
        damp_point(self, q, p, tau, c)
    }
}

/// The same pendulum in cylindrical coordinates (ρ, φ, z), x = ρ cos φ, y = ρ sin φ:
/// H = (p_ρ² + p_φ²/ρ² + p_z²)/(2m) + k/2 (s − l)² + m g z with s = √(ρ² + z²). φ is cyclic, so
/// p_φ = J₃ is constant in every method's numbers, not only the exact flow's. The damping is the
/// same Rayleigh function ε/2 ṡ² written in these coordinates: with u = (ρ, 0, z)/s the force on
/// the momenta is −(ε/m) u (u·p), a projector onto u at the rate ε/m as in Cartesian coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct ElasticPendulum3dCylindrical(pub ElasticPendulum3d);

impl ElasticPendulum3dCylindrical {
    /// s = √(ρ² + z²) and the unit vector u = (ρ, 0, z)/s along the spring.
    #[inline]
    fn spring(q: &Vector<U3>) -> (f64, f64, f64) {
        let s = q[0].hypot(q[2]);
        (s, q[0] / s, q[2] / s)
    }
}

impl MechanicalSystem for ElasticPendulum3dCylindrical {
    type Dim = U3;
    fn dim(&self) -> U3 {
        U3
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: false,
            conformal_damping: false,
        }
    }
    fn kinetic(&self, q: &Vector<U3>, p: &Vector<U3>) -> f64 {
        let rho = q[0];
        0.5 * (p[0] * p[0] + p[1] * p[1] / (rho * rho) + p[2] * p[2]) / self.0.m
    }
    fn potential(&self, q: &Vector<U3>) -> f64 {
        let (s, _, _) = Self::spring(q);
        let stretch = s - self.0.l;
        0.5 * self.0.k * stretch * stretch + self.0.m * self.0.g * q[2]
    }
    fn grad_potential(&self, q: &Vector<U3>, out: &mut Vector<U3>) {
        let (s, ur, uz) = Self::spring(q);
        let f = self.0.k * (s - self.0.l);
        out[0] = f * ur;
        out[1] = 0.0;
        out[2] = f * uz + self.0.m * self.0.g;
    }
    fn velocity(&self, q: &Vector<U3>, p: &Vector<U3>, out: &mut Vector<U3>) {
        self.dh_dp(q, p, out)
    }
    #[inline]
    fn dh_dp(&self, q: &Vector<U3>, p: &Vector<U3>, out: &mut Vector<U3>) {
        let inv_m = 1.0 / self.0.m;
        out[0] = p[0] * inv_m;
        out[1] = p[1] * inv_m / (q[0] * q[0]);
        out[2] = p[2] * inv_m;
    }
    #[inline]
    fn dh_dq(&self, q: &Vector<U3>, p: &Vector<U3>, out: &mut Vector<U3>) {
        self.grad_potential(q, out);
        out[0] -= p[1] * p[1] / (self.0.m * q[0] * q[0] * q[0]);
    }
    fn damping_rate(&self) -> f64 {
        self.0.epsilon / self.0.m
    }
    #[inline]
    fn project_damped(&self, q: &Vector<U3>, v: &Vector<U3>, out: &mut Vector<U3>) {
        let (_, ur, uz) = Self::spring(q);
        let c = ur * v[0] + uz * v[2];
        out[0] = c * ur;
        out[1] = 0.0;
        out[2] = c * uz;
    }
    fn projector_derivative(&self, q: &Vector<U3>, v: &Vector<U3>, out: &mut DMatrix<f64>) -> bool {
        // The projector onto w = (ρ, 0, z), which depends on ρ and z only.
        spring_projector_derivative([q[0], 0.0, q[2]], v, [true, false, true], out);
        true
    }
    fn hessian_h(
        &self,
        q: &Vector<U3>,
        p: &Vector<U3>,
        hqq: &mut DMatrix<f64>,
        hqp: &mut DMatrix<f64>,
        hpp: &mut DMatrix<f64>,
    ) -> bool {
        let (m, k, l) = (self.0.m, self.0.k, self.0.l);
        let (rho, p_phi) = (q[0], p[1]);
        let (s, _, _) = Self::spring(q);
        // The spring in the (ρ, z) plane: k(1 − l/s) I + k l w wᵀ/s³ with w = (ρ, z).
        let a = k * (1.0 - l / s);
        let b = k * l / (s * s * s);
        hqq.fill(0.0);
        hqq[(0, 0)] = a + b * rho * rho + 3.0 * p_phi * p_phi / (m * rho.powi(4));
        hqq[(0, 2)] = b * rho * q[2];
        hqq[(2, 0)] = b * rho * q[2];
        hqq[(2, 2)] = a + b * q[2] * q[2];
        hqp.fill(0.0);
        hqp[(0, 1)] = -2.0 * p_phi / (m * rho * rho * rho);
        hpp.fill(0.0);
        hpp[(0, 0)] = 1.0 / m;
        hpp[(1, 1)] = 1.0 / (m * rho * rho);
        hpp[(2, 2)] = 1.0 / m;
        true
    }
    #[inline]
    fn solve_momentum_stage(
        &self,
        q: &Vector<U3>,
        p: &Vector<U3>,
        h: f64,
        p1: &mut Vector<U3>,
    ) -> bool {
        // p_φ is unchanged (φ is cyclic and undamped); then (p_ρ, p_z) solve the linear system
        // (I + c u uᵀ) x = b with c = h r and |u| = 1, whose inverse is I − c/(1 + c) u uᵀ.
        let (m, k, l) = (self.0.m, self.0.k, self.0.l);
        let (rho, p_phi) = (q[0], p[1]);
        let (s, ur, uz) = Self::spring(q);
        let f = k * (s - l);
        let b_rho = p[0] - h * (f * ur - p_phi * p_phi / (m * rho * rho * rho));
        let b_z = p[2] - h * (f * uz + m * self.0.g);
        let c = h * self.damping_rate();
        let along = c / (1.0 + c) * (ur * b_rho + uz * b_z);
        p1[0] = b_rho - along * ur;
        p1[1] = p_phi;
        p1[2] = b_z - along * uz;
        true
    }
    #[inline]
    fn solve_position_stage(
        &self,
        q: &Vector<U3>,
        p: &Vector<U3>,
        h: f64,
        q1: &mut Vector<U3>,
    ) -> bool {
        // ρ and z first (their velocities do not involve q), then φ with the new ρ.
        let inv_m = 1.0 / self.0.m;
        let rho1 = q[0] + h * p[0] * inv_m;
        q1[0] = rho1;
        q1[1] = q[1] + h * p[1] * inv_m / (rho1 * rho1);
        q1[2] = q[2] + h * p[2] * inv_m;
        true
    }
    fn invariant_count(&self) -> usize {
        1
    }
    fn invariants(&self, _t: f64, _q: &Vector<U3>, p: &Vector<U3>, out: &mut [f64]) {
        out[0] = p[1];
    }
    fn is_cartesian(&self) -> bool {
        false
    }
    fn to_cartesian(&self, q: &Vector<U3>, p: &Vector<U3>, x: &mut [f64], px: &mut [f64]) {
        let (rho, phi) = (q[0], q[1]);
        let (sin, cos) = phi.sin_cos();
        x[0] = rho * cos;
        x[1] = rho * sin;
        x[2] = q[2];
        px[0] = p[0] * cos - p[1] / rho * sin;
        px[1] = p[0] * sin + p[1] / rho * cos;
        px[2] = p[2];
    }
    fn from_cartesian(
        &self,
        x: &[f64],
        px: &[f64],
        q: &mut Vector<U3>,
        p: &mut Vector<U3>,
    ) -> Result<(), String> {
        let rho = x[0].hypot(x[1]);
        if rho == 0.0 {
            return Err("the cylindrical chart is singular on the axis ρ = 0".to_string());
        }
        let phi = x[1].atan2(x[0]);
        let (sin, cos) = phi.sin_cos();
        q[0] = rho;
        q[1] = phi;
        q[2] = x[2];
        p[0] = px[0] * cos + px[1] * sin;
        p[1] = x[0] * px[1] - x[1] * px[0];
        p[2] = px[2];
        Ok(())
    }
}

/// ∂(P v)/∂q for the projector P = w wᵀ/|w|² onto w, with ∂w/∂q the identity on the
/// components `moving` and zero elsewhere: with s = w·v, (v_j w_i + s δ_ij)/|w|² −
/// 2 s w_i w_j/|w|⁴ in the columns j that move, zero in the others.
fn spring_projector_derivative(
    w: [f64; 3],
    v: &Vector<U3>,
    moving: [bool; 3],
    out: &mut DMatrix<f64>,
) {
    let w2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    let s = w[0] * v[0] + w[1] * v[1] + w[2] * v[2];
    for i in 0..3 {
        for j in 0..3 {
            out[(i, j)] = if moving[j] {
                let diagonal = if i == j { s } else { 0.0 };
                (v[j] * w[i] + diagonal - 2.0 * s * w[i] * w[j] / w2) / w2
            } else {
                0.0
            };
        }
    }
}

const MASS: ParamSpec = ParamSpec::number("m", "Mass.", 1.0, 0.0, true, 1e6);
const STIFFNESS: ParamSpec = ParamSpec::number("k", "Spring stiffness.", 1.0, 0.0, true, 1e6);
const REST_LENGTH: ParamSpec = ParamSpec::number("l", "Spring rest length.", 1.0, 0.0, true, 1e6);
const GRAVITY: ParamSpec = ParamSpec::number(
    "g",
    "Gravitational acceleration (along −z).",
    1.0,
    0.0,
    false,
    1e6,
);
const EPSILON: ParamSpec = ParamSpec::number(
    "epsilon",
    "Damping strength ε of the radial Rayleigh dissipation.",
    0.1,
    0.0,
    false,
    1e6,
);
const CARTESIAN: ChartInfo = ChartInfo::new(
    "cartesian",
    &["x", "y", "z"],
    true,
    "H = |p|²/(2m) + k/2 (|q| − l)² + m g z.",
);
const CYLINDRICAL: ChartInfo = ChartInfo::new(
    "cylindrical",
    &["ρ", "φ", "z"],
    false,
    "x = ρ cos φ, y = ρ sin φ: H = (p_ρ² + p_φ²/ρ² + p_z²)/(2m) + k/2 (√(ρ² + z²) − l)² + m g z, with J₃ = p_φ cyclic; the damping is the same spring-direction Rayleigh function.",
);

/// The catalogue entry of `elastic_pendulum_3d`.
pub(super) fn entry() -> SystemInfo {
    SystemInfo {
        id: Cow::Borrowed("elastic_pendulum_3d"),
        name: Cow::Borrowed("Elastic 3-D pendulum, damped along the spring"),
        description: Cow::Borrowed("A mass on a spring in R³ under gravity (0, 0, −g), V = k/2 (l − |q|)² + m g q_z, Rayleigh damping along the spring only, D = q qᵀ/|q|² (paper 000 Sec. 6.2, eq. 16). J₃ = (q × p)_z is conserved for every ε."),
        degrees_of_freedom: 3,
        charts: vec![CARTESIAN, CYLINDRICAL],
        params: vec![MASS, STIFFNESS, REST_LENGTH, GRAVITY, EPSILON],
        q0: vec![0.0, 1.558_845_73, -0.6],
        p0: vec![1.341_640_79, 0.0, 0.0],
        invariants: vec![Cow::Borrowed("J3")],
        exact_solution: false,
        conformal_damping: false,
        world: World::Spring,
        build: Builder::Catalog(|p: &ParamValues, chart: &ChartInfo, _: f64| {
            let pendulum = ElasticPendulum3d {
                m: p.number(&MASS),
                k: p.number(&STIFFNESS),
                l: p.number(&REST_LENGTH),
                g: p.number(&GRAVITY),
                epsilon: p.number(&EPSILON),
            };
            if chart.id == CYLINDRICAL.id {
                AnySystem::ElasticPendulum3dCylindrical(ElasticPendulum3dCylindrical(pendulum))
            } else {
                AnySystem::ElasticPendulum3d(pendulum)
            }
        }),
    }
}

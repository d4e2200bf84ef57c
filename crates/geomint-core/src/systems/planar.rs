//! A point mass in the plane on a spring under gravity, in Cartesian and in polar coordinates:
//! the planar elastic pendulum of paper 001 Appendix A (eqs. 70–73) and, with k = g = 0, the free
//! particle of 001 Sec. 5.2 (eqs. 61–62).
//!
//! Charts. Cartesian (x, y) with y pointing down (along gravity), so
//! H = |p|²/(2m) + k/2 (|q| − l)² − m g y (eq. 73), separable with constant mass. Polar (r, θ)
//! with θ measured from the downward y axis, x = r sin θ, y = r cos θ, so
//! H = (p_r² + p_θ²/r²)/(2m) + k/2 (r − l)² − m g r cos θ (eq. 72): the mass matrix depends on r.
//! Eq. (63) writes the inverse map as x = r cos θ, y = r sin θ, but that makes eqs. (72) and (73)
//! different systems (−mgr cos θ ≠ −mgy); its own forward map θ = atan2(x, y) and the divergence
//! boundary of Sec. 4.1 (r(0) ≥ 2l + 2mg/k cos θ(0), from energy conservation along the line
//! through the pivot) both need y = r cos θ, which is what we use for both planar systems.
//!
//! In polar coordinates θ is cyclic when g = 0, and symplectic Euler's momentum stage is explicit
//! for every g: p_θ first (∂H/∂θ does not involve p), then p_r with the new p_θ; the adjoint's
//! position stage likewise (r first, then θ with the new r).

use nalgebra::{DMatrix, U2};

use std::borrow::Cow;

use super::{AnySystem, Builder, ChartInfo, ParamSpec, ParamValues, SystemInfo, World};
use crate::system::lanes::{damp_each_lane, damp_point, PointForces};
use crate::system::{Lane, LaneForces, LANES};
use crate::system::{MechanicalSystem, State, Structure, Vector};

/// Which first integrals a planar system reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanarKind {
    /// The elastic pendulum: none besides the energy.
    Pendulum,
    /// The free particle: angular momentum L = x p_y − y p_x and linear momentum (p_x, p_y),
    /// computed from the Cartesian state whatever the chart.
    FreeParticle,
}

/// The physical parameters, shared by both charts.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanarSpring {
    /// Mass.
    pub m: f64,
    /// Spring stiffness (0 for the free particle).
    pub k: f64,
    /// Spring rest length.
    pub l: f64,
    /// Gravitational acceleration along +y (0 for the free particle).
    pub g: f64,
    /// Which invariants to report.
    pub kind: PlanarKind,
}

impl PlanarSpring {
    /// The invariants: none for the pendulum; L, p_x, p_y for the free particle.
    fn invariant_count(&self) -> usize {
        match self.kind {
            PlanarKind::Pendulum => 0,
            PlanarKind::FreeParticle => 3,
        }
    }

    fn invariants(&self, x: &[f64], px: &[f64], out: &mut [f64]) {
        if self.kind == PlanarKind::FreeParticle {
            out[0] = x[0] * px[1] - x[1] * px[0];
            out[1] = px[0];
            out[2] = px[1];
        }
    }

    /// The free particle's exact Cartesian state at time t (straight line at constant momentum).
    fn exact_cartesian(&self, t: f64, x: &[f64], px: &[f64]) -> Option<([f64; 2], [f64; 2])> {
        (self.kind == PlanarKind::FreeParticle).then(|| {
            (
                [x[0] + t * px[0] / self.m, x[1] + t * px[1] / self.m],
                [px[0], px[1]],
            )
        })
    }
}

/// The planar system in Cartesian coordinates (x, y).
#[derive(Clone, Debug, PartialEq)]
pub struct PlanarCartesian(pub PlanarSpring);

/// The planar system in polar coordinates (r, θ).
#[derive(Clone, Debug, PartialEq)]
pub struct PlanarPolar(pub PlanarSpring);

impl MechanicalSystem for PlanarCartesian {
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
        self.kinetic_of([p[0], p[1]])
    }
    fn potential(&self, q: &Vector<U2>) -> f64 {
        self.potential_with_norm(q[1], q.norm())
    }
    #[inline]
    fn grad_potential(&self, q: &Vector<U2>, out: &mut Vector<U2>) {
        [out[0], out[1]] = self.grad(q);
    }
    #[inline]
    fn velocity(&self, _q: &Vector<U2>, p: &Vector<U2>, out: &mut Vector<U2>) {
        [out[0], out[1]] = self.velocity_of(p[0], p[1]);
    }
    fn damping_rate(&self) -> f64 {
        0.0
    }
    fn hess_potential(&self, q: &Vector<U2>, out: &mut DMatrix<f64>) -> u64 {
        for (i, row) in self.hessian(q).iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                out[(i, j)] = v;
            }
        }
        0
    }
    fn invariant_count(&self) -> usize {
        self.0.invariant_count()
    }
    fn invariants(&self, _t: f64, q: &Vector<U2>, p: &Vector<U2>, out: &mut [f64]) {
        self.0.invariants(q.as_slice(), p.as_slice(), out);
    }
    fn exact(&self, t: f64, start: &State<U2>) -> Option<State<U2>> {
        let (x, px) = self
            .0
            .exact_cartesian(t, start.q.as_slice(), start.p.as_slice())?;
        Some(State::from_slices(U2, &x, &px))
    }
}

/// The velocity, force and Hessian at one point: the one formula the one-run path and the
/// lanes share.
impl PlanarCartesian {
    #[inline(always)]
    pub(crate) fn velocity_of(&self, px: f64, py: f64) -> [f64; 2] {
        let inv_m = 1.0 / self.0.m;
        [px * inv_m, py * inv_m]
    }

    #[inline(always)]
    fn grad(&self, q: &Vector<U2>) -> [f64; 2] {
        self.grad_with_norm(q[0], q[1], q.norm())
    }

    /// ∇V at (x, y) whose |q| is `norm` (the energy map's lanes keep it from the energy before).
    #[inline(always)]
    pub(crate) fn grad_with_norm(&self, x: f64, y: f64, norm: f64) -> [f64; 2] {
        let s = &self.0;
        // k(1 − l/|q|) q: zero spring force for the free particle even at q = 0.
        let c = if s.k == 0.0 {
            0.0
        } else {
            s.k * (1.0 - s.l / norm)
        };
        [c * x, c * y - s.m * s.g]
    }

    /// T = |p|²/2m.
    #[inline(always)]
    fn kinetic_of(&self, [px, py]: [f64; 2]) -> f64 {
        0.5 * (px * px + py * py) / self.0.m
    }

    /// V at height y and |q| = `norm`.
    #[inline(always)]
    fn potential_with_norm(&self, y: f64, norm: f64) -> f64 {
        let s = &self.0;
        let stretch = norm - s.l;
        0.5 * s.k * stretch * stretch - s.m * s.g * y
    }

    /// H = T + V at a point whose |q| is `norm`, summed as [`MechanicalSystem::energy`] sums
    /// them.
    #[inline(always)]
    pub(crate) fn energy_with_norm(&self, y: f64, p: [f64; 2], norm: f64) -> f64 {
        self.kinetic_of(p) + self.potential_with_norm(y, norm)
    }

    /// ∇²V = k(1 − l/r) I + k l q qᵀ / r³.
    #[inline(always)]
    fn hessian(&self, q: &Vector<U2>) -> [[f64; 2]; 2] {
        let s = &self.0;
        let mut out = [[0.0; 2]; 2];
        if s.k == 0.0 {
            return out;
        }
        let r = q.norm();
        let a = s.k * (1.0 - s.l / r);
        let b = s.k * s.l / (r * r * r);
        for i in 0..2 {
            for j in 0..2 {
                out[i][j] = b * q[i] * q[j] + if i == j { a } else { 0.0 };
            }
        }
        out
    }
}

impl LaneForces<2> for PlanarCartesian {
    #[inline(always)]
    fn velocity_lanes(&self, p: &[Lane; 2], v: &mut [Lane; 2]) {
        for l in 0..LANES {
            [v[0][l], v[1][l]] = self.velocity_of(p[0][l], p[1][l]);
        }
    }

    #[inline(always)]
    fn grad_lanes(&self, q: &[Lane; 2], g: &mut [Lane; 2]) {
        for l in 0..LANES {
            [g[0][l], g[1][l]] = self.grad(&Vector::<U2>::new(q[0][l], q[1][l]));
        }
    }

    #[inline(always)]
    fn hessian_lanes(&self, q: &[Lane; 2], hess: &mut [[Lane; 2]; 2]) {
        for l in 0..LANES {
            let h = self.hessian(&Vector::<U2>::new(q[0][l], q[1][l]));
            for i in 0..2 {
                for j in 0..2 {
                    hess[i][j][l] = h[i][j];
                }
            }
        }
    }
    #[inline(always)]
    fn damp_lanes(&self, q: &[Lane; 2], p: &mut [Lane; 2], tau: f64, c: &Lane) {
        damp_each_lane(|_| self, q, p, tau, c);
    }
}

impl PointForces<2> for PlanarCartesian {
    #[inline(always)]
    fn velocity_at(&self, [px, py]: [f64; 2]) -> [f64; 2] {
        self.velocity_of(px, py)
    }

    #[inline(always)]
    fn grad_at(&self, [x, y]: [f64; 2]) -> [f64; 2] {
        self.grad(&Vector::<U2>::new(x, y))
    }

    #[inline(always)]
    fn damp_at(&self, q: [f64; 2], p: [f64; 2], tau: f64, c: f64) -> [f64; 2] {
        damp_point(self, q, p, tau, c)
    }
}

/// The polar chart's formulas at one point, given sin θ and cos θ where they need them: the
/// one place they are written, for the one-run path (the trait's methods below) and the energy
/// map's lanes, which keep sin θ and cos θ from the energy of one step for the force of the next.
impl PlanarPolar {
    /// (r, θ, p_r, p_θ) of a state.
    #[inline]
    fn unpack(q: &Vector<U2>, p: &Vector<U2>) -> (f64, f64, f64, f64) {
        (q[0], q[1], p[0], p[1])
    }

    /// ∂H/∂p = (p_r/m, p_θ/(m r²)).
    #[inline(always)]
    pub(crate) fn velocity_at(&self, r: f64, [pr, pt]: [f64; 2]) -> [f64; 2] {
        [pr / self.0.m, pt / (self.0.m * r * r)]
    }

    /// ∇V = (k(r − l) − m g cos θ, m g r sin θ).
    #[inline(always)]
    pub(crate) fn grad_at(&self, r: f64, (sin, cos): (f64, f64)) -> [f64; 2] {
        let s = &self.0;
        [s.k * (r - s.l) - s.m * s.g * cos, s.m * s.g * r * sin]
    }

    /// ∂H/∂q = ∇V − (p_θ²/(m r³), 0).
    #[inline(always)]
    pub(crate) fn dh_dq_at(&self, r: f64, pt: f64, turn: (f64, f64)) -> [f64; 2] {
        let [mut dr, dth] = self.grad_at(r, turn);
        dr -= pt * pt / (self.0.m * r * r * r);
        [dr, dth]
    }

    /// Symplectic Euler's momentum stage p₁ = p − h ∂H/∂q(q, p₁) in closed form: ∂H/∂θ =
    /// m g r sin θ does not involve p, so p_θ first, then p_r with the new p_θ.
    #[inline(always)]
    pub(crate) fn momentum_stage_at(
        &self,
        h: f64,
        r: f64,
        [pr, pt]: [f64; 2],
        (sin, cos): (f64, f64),
    ) -> [f64; 2] {
        let s = &self.0;
        let pt1 = pt - h * s.m * s.g * r * sin;
        let dh_dr = -pt1 * pt1 / (s.m * r * r * r) + s.k * (r - s.l) - s.m * s.g * cos;
        [pr - h * dh_dr, pt1]
    }

    /// The adjoint's position stage q₁ = q + h ∂H/∂p(q₁, p) in closed form: ṙ = p_r/m does not
    /// involve q, so r first, then θ with the new r.
    #[inline(always)]
    pub(crate) fn position_stage_at(
        &self,
        h: f64,
        [r, th]: [f64; 2],
        [pr, pt]: [f64; 2],
    ) -> [f64; 2] {
        let r1 = r + h * pr / self.0.m;
        [r1, th + h * pt / (self.0.m * r1 * r1)]
    }

    /// T = (p_r² + p_θ²/r²)/2m.
    #[inline(always)]
    fn kinetic_at(&self, r: f64, [pr, pt]: [f64; 2]) -> f64 {
        0.5 * (pr * pr + pt * pt / (r * r)) / self.0.m
    }

    /// V = ½k(r − l)² − m g r cos θ.
    #[inline(always)]
    fn potential_at(&self, r: f64, cos: f64) -> f64 {
        let s = &self.0;
        let stretch = r - s.l;
        0.5 * s.k * stretch * stretch - s.m * s.g * r * cos
    }

    /// H = T + V, summed as [`MechanicalSystem::energy`] sums them.
    #[inline(always)]
    pub(crate) fn energy_at(&self, r: f64, p: [f64; 2], cos: f64) -> f64 {
        self.kinetic_at(r, p) + self.potential_at(r, cos)
    }
}

impl MechanicalSystem for PlanarPolar {
    type Dim = U2;
    fn dim(&self) -> U2 {
        U2
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: false,
            conformal_damping: true,
        }
    }
    fn kinetic(&self, q: &Vector<U2>, p: &Vector<U2>) -> f64 {
        self.kinetic_at(q[0], [p[0], p[1]])
    }
    fn potential(&self, q: &Vector<U2>) -> f64 {
        self.potential_at(q[0], q[1].cos())
    }
    fn grad_potential(&self, q: &Vector<U2>, out: &mut Vector<U2>) {
        [out[0], out[1]] = self.grad_at(q[0], q[1].sin_cos());
    }
    fn velocity(&self, q: &Vector<U2>, p: &Vector<U2>, out: &mut Vector<U2>) {
        self.dh_dp(q, p, out)
    }
    #[inline]
    fn dh_dp(&self, q: &Vector<U2>, p: &Vector<U2>, out: &mut Vector<U2>) {
        [out[0], out[1]] = self.velocity_at(q[0], [p[0], p[1]]);
    }
    #[inline]
    fn dh_dq(&self, q: &Vector<U2>, p: &Vector<U2>, out: &mut Vector<U2>) {
        [out[0], out[1]] = self.dh_dq_at(q[0], p[1], q[1].sin_cos());
    }
    fn damping_rate(&self) -> f64 {
        0.0
    }
    fn hessian_h(
        &self,
        q: &Vector<U2>,
        p: &Vector<U2>,
        hqq: &mut DMatrix<f64>,
        hqp: &mut DMatrix<f64>,
        hpp: &mut DMatrix<f64>,
    ) -> bool {
        let s = &self.0;
        let (r, th, _, pt) = Self::unpack(q, p);
        let (sin, cos) = th.sin_cos();
        let m = s.m;
        hqq[(0, 0)] = 3.0 * pt * pt / (m * r.powi(4)) + s.k;
        hqq[(0, 1)] = m * s.g * sin;
        hqq[(1, 0)] = m * s.g * sin;
        hqq[(1, 1)] = m * s.g * r * cos;
        hqp.fill(0.0);
        hqp[(0, 1)] = -2.0 * pt / (m * r * r * r);
        hpp.fill(0.0);
        hpp[(0, 0)] = 1.0 / m;
        hpp[(1, 1)] = 1.0 / (m * r * r);
        true
    }
    #[inline]
    fn solve_momentum_stage(
        &self,
        q: &Vector<U2>,
        p: &Vector<U2>,
        h: f64,
        p1: &mut Vector<U2>,
    ) -> bool {
        [p1[0], p1[1]] = self.momentum_stage_at(h, q[0], [p[0], p[1]], q[1].sin_cos());
        true
    }
    #[inline]
    fn solve_position_stage(
        &self,
        q: &Vector<U2>,
        p: &Vector<U2>,
        h: f64,
        q1: &mut Vector<U2>,
    ) -> bool {
        [q1[0], q1[1]] = self.position_stage_at(h, [q[0], q[1]], [p[0], p[1]]);
        true
    }
    fn invariant_count(&self) -> usize {
        self.0.invariant_count()
    }
    fn invariants(&self, _t: f64, q: &Vector<U2>, p: &Vector<U2>, out: &mut [f64]) {
        let (mut x, mut px) = ([0.0; 2], [0.0; 2]);
        self.to_cartesian(q, p, &mut x, &mut px);
        self.0.invariants(&x, &px, out);
    }
    fn exact(&self, t: f64, start: &State<U2>) -> Option<State<U2>> {
        let (mut x, mut px) = ([0.0; 2], [0.0; 2]);
        self.to_cartesian(&start.q, &start.p, &mut x, &mut px);
        let (x1, px1) = self.0.exact_cartesian(t, &x, &px)?;
        let mut end = start.clone();
        self.from_cartesian(&x1, &px1, &mut end.q, &mut end.p)
            .ok()?;
        // The free particle's bearing turns by less than π: take the branch of θ continuous
        // from the start.
        end.q[1] = start.q[1] + wrap_angle(end.q[1] - start.q[1]);
        Some(end)
    }
    fn is_cartesian(&self) -> bool {
        false
    }
    fn to_cartesian(&self, q: &Vector<U2>, p: &Vector<U2>, x: &mut [f64], px: &mut [f64]) {
        let (r, th, pr, pt) = Self::unpack(q, p);
        let (sin, cos) = th.sin_cos();
        x[0] = r * sin;
        x[1] = r * cos;
        // p = p_r e_r + (p_θ/r) e_θ with e_r = (sin θ, cos θ), e_θ = (cos θ, −sin θ).
        px[0] = pr * sin + pt / r * cos;
        px[1] = pr * cos - pt / r * sin;
    }
    fn from_cartesian(
        &self,
        x: &[f64],
        px: &[f64],
        q: &mut Vector<U2>,
        p: &mut Vector<U2>,
    ) -> Result<(), String> {
        let r = x[0].hypot(x[1]);
        if r == 0.0 {
            return Err("the polar chart is singular at r = 0".to_string());
        }
        let th = x[0].atan2(x[1]);
        let (sin, cos) = th.sin_cos();
        q[0] = r;
        q[1] = th;
        p[0] = px[0] * sin + px[1] * cos;
        p[1] = r * (px[0] * cos - px[1] * sin);
        Ok(())
    }
}

/// `a` wrapped into (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = a - TAU * (a / TAU).round();
    if w <= -PI {
        w + TAU
    } else {
        w
    }
}

const MASS: ParamSpec = ParamSpec::number("m", "Mass.", 1.0, 0.0, true, 1e6);
const STIFFNESS: ParamSpec = ParamSpec::number("k", "Spring stiffness.", 1.0, 0.0, true, 1e6);
const REST_LENGTH: ParamSpec = ParamSpec::number("l", "Spring rest length.", 1.0, 0.0, true, 1e6);
const GRAVITY: ParamSpec = ParamSpec::number(
    "g",
    "Gravitational acceleration (along +y, downwards).",
    0.2,
    0.0,
    false,
    1e6,
);
const PENDULUM_CARTESIAN: ChartInfo = ChartInfo::new(
    "cartesian",
    &["x", "y"],
    true,
    "H = (p_x² + p_y²)/(2m) + k/2 (√(x² + y²) − l)² − m g y (001 eq. 73).",
);
const PENDULUM_POLAR: ChartInfo = ChartInfo::new(
    "polar",
    &["r", "θ"],
    false,
    "x = r sin θ, y = r cos θ (θ from the downward vertical): H = (p_r² + p_θ²/r²)/(2m) + k/2 (r − l)² − m g r cos θ (001 eq. 72); the mass matrix depends on r.",
);
const FREE_CARTESIAN: ChartInfo = ChartInfo::new(
    "cartesian",
    &["x", "y"],
    true,
    "H = (p_x² + p_y²)/(2m) (001 eq. 61).",
);
const FREE_POLAR: ChartInfo = ChartInfo::new(
    "polar",
    &["r", "θ"],
    false,
    "x = r sin θ, y = r cos θ: H = (p_r² + p_θ²/r²)/(2m) (001 eq. 62), θ cyclic, p_θ = y p_x − x p_y = −L.",
);

/// The system in Cartesian or polar coordinates, as `chart` says.
fn in_chart(spring: PlanarSpring, chart: &ChartInfo) -> AnySystem {
    if chart.id == PENDULUM_POLAR.id {
        AnySystem::PlanarPolar(PlanarPolar(spring))
    } else {
        AnySystem::PlanarCartesian(PlanarCartesian(spring))
    }
}

/// The planar elastic pendulum of these parameters (energy maps build both charts from it).
pub fn planar_pendulum(p: &ParamValues) -> PlanarSpring {
    PlanarSpring {
        m: p.number(&MASS),
        k: p.number(&STIFFNESS),
        l: p.number(&REST_LENGTH),
        g: p.number(&GRAVITY),
        kind: PlanarKind::Pendulum,
    }
}

/// The catalogue entry of `elastic_pendulum_2d`.
pub(super) fn pendulum_entry() -> SystemInfo {
    SystemInfo {
        id: Cow::Borrowed("elastic_pendulum_2d"),
        name: Cow::Borrowed("Planar elastic pendulum"),
        description: Cow::Borrowed("A mass on a spring in the plane under gravity along +y (y points down), paper 001 Appendix A: H = |p|²/(2m) + k/2 (|q| − l)² − m g y (eq. 73), or in polar coordinates (eq. 72). Undamped."),
        degrees_of_freedom: 2,
        charts: vec![PENDULUM_CARTESIAN, PENDULUM_POLAR],
        params: vec![MASS, STIFFNESS, REST_LENGTH, GRAVITY],
        q0: vec![0.6, 1.2],
        p0: vec![0.0, 0.0],
        invariants: Vec::new(),
        exact_solution: false,
        conformal_damping: true,
        world: World::PlanarSpring,
        build: Builder::Catalog(|p: &ParamValues, chart: &ChartInfo, _: f64| in_chart(planar_pendulum(p), chart)),
    }
}

/// The catalogue entry of `free_particle_2d`.
pub(super) fn free_particle_entry() -> SystemInfo {
    SystemInfo {
        id: Cow::Borrowed("free_particle_2d"),
        name: Cow::Borrowed("Free particle in the plane"),
        description: Cow::Borrowed("H = |p|²/(2m), paper 001 Sec. 5.2: linear momentum (p_x, p_y) and angular momentum L = x p_y − y p_x are conserved. Symplectic Euler keeps p_θ exactly in polar coordinates but not p_x, and keeps L exactly in Cartesian ones."),
        degrees_of_freedom: 2,
        charts: vec![FREE_CARTESIAN, FREE_POLAR],
        params: vec![MASS],
        q0: vec![1.0, 0.5],
        p0: vec![0.2, 1.0],
        invariants: vec![Cow::Borrowed("L"), Cow::Borrowed("p_x"), Cow::Borrowed("p_y")],
        exact_solution: true,
        conformal_damping: true,
        world: World::Plane,
        build: Builder::Catalog(|p: &ParamValues, chart: &ChartInfo, _: f64| {
            let spring = PlanarSpring {
                m: p.number(&MASS),
                k: 0.0,
                l: 0.0,
                g: 0.0,
                kind: PlanarKind::FreeParticle,
            };
            in_chart(spring, chart)
        }),
    }
}

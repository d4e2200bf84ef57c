//! Systems in several coordinate charts (paper 001): the charts' transformations and
//! derivatives, symplectic Euler on non-separable Hamiltonians, and the paper's measurements —
//! Sec. 2.3 (exact explicit Euler in transformed variables), Sec. 5.2 (which momenta symplectic
//! Euler keeps in which chart), Appendix B / Fig. 9 (order compensation), and Sec. 4 (the
//! non-invariance of a symplectic method under a change of chart, against the exact flow's
//! invariance).

// `with_system!` instantiates one body for every system; vectors of the 1-D ones are `Copy`, the
// N-body ones are not, so the clones stay.
#![allow(clippy::clone_on_copy)]

use crate::common;

use geomint_core::error::CoreError;
use geomint_core::methods::{Method, MethodId};
use geomint_core::simulation::{Columns, Limits, Simulation, SimulationSpec};
use geomint_core::system::{MechanicalSystem, State};
use geomint_core::systems::{self, AnySystem};
use geomint_core::with_system;
use nalgebra::DMatrix;
use serde_json::json;

use common::run_all;

/// A request in `chart`, sampling every `every` steps.
fn charted(
    system: &str,
    chart: &str,
    params: serde_json::Value,
    methods: &[&str],
    h: f64,
    t_end: f64,
) -> SimulationSpec {
    SimulationSpec {
        chart: Some(chart.into()),
        ..common::request(system, params, methods, h, t_end)
    }
}

/// Cartesian states of a run (the chart's own state when it is Cartesian).
fn cartesian(run: &Columns) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    match (&run.cartesian_q, &run.cartesian_p) {
        (Some(x), Some(px)) => (x.clone(), px.clone()),
        _ => (run.q.clone(), run.p.clone()),
    }
}

/// Every chart of every system with its parameters, built with step 0.1.
fn chart_systems() -> Vec<(String, AnySystem)> {
    let mut out = Vec::new();
    for info in systems::catalog() {
        for chart in &info.charts {
            let sys = common::default_system(info, chart, 0.1);
            out.push((format!("{}/{}", info.id, chart.id), sys));
        }
    }
    out
}

/// A Cartesian test state for a system of dimension n (away from every chart's singularity and
/// inside the compensating and Gompertz charts' ranges).
fn test_state(n: usize) -> (Vec<f64>, Vec<f64>) {
    match n {
        1 => (vec![0.7], vec![0.3]),
        2 => (vec![0.6, 1.1], vec![0.25, -0.4]),
        3 => (vec![0.5, 0.8, -0.6], vec![0.3, -0.2, 0.45]),
        _ => {
            let q: Vec<f64> = (0..n).map(|i| 1.0 + 0.37 * i as f64).collect();
            let p: Vec<f64> = (0..n).map(|i| 0.1 - 0.05 * i as f64).collect();
            (q, p)
        }
    }
}

#[test]
fn every_chart_round_trips_and_keeps_the_energy() {
    for (name, any) in chart_systems() {
        with_system!(&any, sys => {
            let n = nalgebra::Dim::value(&sys.dim());
            let (x, px) = test_state(n);
            let mut z = State::from_slices(sys.dim(), &x, &px);
            sys.from_cartesian(&x, &px, &mut z.q, &mut z.p).unwrap();
            let (mut x1, mut px1) = (vec![0.0; n], vec![0.0; n]);
            sys.to_cartesian(&z.q, &z.p, &mut x1, &mut px1);
            for i in 0..n {
                assert!((x1[i] - x[i]).abs() < 1e-14, "{name}: x[{i}] {} vs {}", x1[i], x[i]);
                assert!((px1[i] - px[i]).abs() < 1e-14, "{name}: p[{i}] {} vs {}", px1[i], px[i]);
            }
            // H is a scalar: the same in every chart (H̄(Q(q), P(q, p)) = H(q, p)).
            let info = common::info(name.split('/').next().unwrap());
            let first = common::default_system(&info, &info.charts[0], 0.1);
            let h_cart = with_system!(&first, c => {
                let w = State::from_slices(c.dim(), &x, &px);
                c.energy(&w.q, &w.p)
            });
            let h_chart = sys.energy(&z.q, &z.p);
            assert!(
                (h_chart - h_cart).abs() <= 1e-13 * (1.0 + h_cart.abs()),
                "{name}: H = {h_chart} in the chart, {h_cart} in Cartesian coordinates"
            );
        });
    }
}

#[test]
fn every_chart_has_consistent_first_and_second_derivatives() {
    for (name, any) in chart_systems() {
        with_system!(&any, sys => {
            let n = nalgebra::Dim::value(&sys.dim());
            let (x, px) = test_state(n);
            let mut z = State::from_slices(sys.dim(), &x, &px);
            sys.from_cartesian(&x, &px, &mut z.q, &mut z.p).unwrap();
            let (mut hq, mut hp) = (z.q.clone(), z.p.clone());
            sys.dh_dq(&z.q, &z.p, &mut hq);
            sys.dh_dp(&z.q, &z.p, &mut hp);
            let (mut hqq, mut hqp, mut hpp) =
                (DMatrix::zeros(n, n), DMatrix::zeros(n, n), DMatrix::zeros(n, n));
            let analytic = sys.hessian_h(&z.q, &z.p, &mut hqq, &mut hqp, &mut hpp);
            for j in 0..n {
                let d = 1e-6;
                let mut zp = z.clone();
                let mut zm = z.clone();
                zp.q[j] += d;
                zm.q[j] -= d;
                let dq = (sys.energy(&zp.q, &zp.p) - sys.energy(&zm.q, &zm.p)) / (2.0 * d);
                assert!((dq - hq[j]).abs() < 1e-7 * (1.0 + dq.abs()), "{name}: ∂H/∂q[{j}] {} vs {dq}", hq[j]);
                let (mut gp, mut gm) = (hq.clone(), hq.clone());
                let (mut vp, mut vm) = (hp.clone(), hp.clone());
                if analytic {
                    sys.dh_dq(&zp.q, &zp.p, &mut gp);
                    sys.dh_dq(&zm.q, &zm.p, &mut gm);
                    for i in 0..n {
                        let num = (gp[i] - gm[i]) / (2.0 * d);
                        assert!((num - hqq[(i, j)]).abs() < 1e-6 * (1.0 + num.abs()), "{name}: H_qq[{i},{j}] {} vs {num}", hqq[(i, j)]);
                    }
                }
                let mut zp = z.clone();
                let mut zm = z.clone();
                zp.p[j] += d;
                zm.p[j] -= d;
                let dp = (sys.energy(&zp.q, &zp.p) - sys.energy(&zm.q, &zm.p)) / (2.0 * d);
                assert!((dp - hp[j]).abs() < 1e-7 * (1.0 + dp.abs()), "{name}: ∂H/∂p[{j}] {} vs {dp}", hp[j]);
                if analytic {
                    sys.dh_dq(&zp.q, &zp.p, &mut gp);
                    sys.dh_dq(&zm.q, &zm.p, &mut gm);
                    sys.dh_dp(&zp.q, &zp.p, &mut vp);
                    sys.dh_dp(&zm.q, &zm.p, &mut vm);
                    for i in 0..n {
                        let mixed = (gp[i] - gm[i]) / (2.0 * d);
                        assert!((mixed - hqp[(i, j)]).abs() < 1e-6 * (1.0 + mixed.abs()), "{name}: H_qp[{i},{j}] {} vs {mixed}", hqp[(i, j)]);
                        let pp = (vp[i] - vm[i]) / (2.0 * d);
                        assert!((pp - hpp[(i, j)]).abs() < 1e-6 * (1.0 + pp.abs()), "{name}: H_pp[{i},{j}] {} vs {pp}", hpp[(i, j)]);
                    }
                }
            }
            // Every non-Cartesian chart gives Newton its analytic derivatives.
            assert!(analytic || sys.is_cartesian(), "{name}: no analytic ∇²H");
        });
    }
}

/// A system that hides its closed-form implicit stages, so symplectic Euler falls back to Newton.
struct NewtonOnly<'a, S>(&'a S);

impl<S: MechanicalSystem> MechanicalSystem for NewtonOnly<'_, S>
where
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<S::Dim>,
{
    type Dim = S::Dim;
    fn dim(&self) -> S::Dim {
        self.0.dim()
    }
    fn structure(&self) -> geomint_core::system::Structure {
        self.0.structure()
    }
    fn kinetic(
        &self,
        q: &geomint_core::system::Vector<S::Dim>,
        p: &geomint_core::system::Vector<S::Dim>,
    ) -> f64 {
        self.0.kinetic(q, p)
    }
    fn potential(&self, q: &geomint_core::system::Vector<S::Dim>) -> f64 {
        self.0.potential(q)
    }
    fn grad_potential(
        &self,
        q: &geomint_core::system::Vector<S::Dim>,
        out: &mut geomint_core::system::Vector<S::Dim>,
    ) {
        self.0.grad_potential(q, out)
    }
    fn velocity(
        &self,
        q: &geomint_core::system::Vector<S::Dim>,
        p: &geomint_core::system::Vector<S::Dim>,
        out: &mut geomint_core::system::Vector<S::Dim>,
    ) {
        self.0.velocity(q, p, out)
    }
    fn dh_dp(
        &self,
        q: &geomint_core::system::Vector<S::Dim>,
        p: &geomint_core::system::Vector<S::Dim>,
        out: &mut geomint_core::system::Vector<S::Dim>,
    ) {
        self.0.dh_dp(q, p, out)
    }
    fn dh_dq(
        &self,
        q: &geomint_core::system::Vector<S::Dim>,
        p: &geomint_core::system::Vector<S::Dim>,
        out: &mut geomint_core::system::Vector<S::Dim>,
    ) {
        self.0.dh_dq(q, p, out)
    }
    fn damping_rate(&self) -> f64 {
        self.0.damping_rate()
    }
    fn project_damped(
        &self,
        q: &geomint_core::system::Vector<S::Dim>,
        v: &geomint_core::system::Vector<S::Dim>,
        out: &mut geomint_core::system::Vector<S::Dim>,
    ) {
        self.0.project_damped(q, v, out)
    }
    fn hessian_h(
        &self,
        q: &geomint_core::system::Vector<S::Dim>,
        p: &geomint_core::system::Vector<S::Dim>,
        hqq: &mut DMatrix<f64>,
        hqp: &mut DMatrix<f64>,
        hpp: &mut DMatrix<f64>,
    ) -> bool {
        self.0.hessian_h(q, p, hqq, hqp, hpp)
    }
}

#[test]
fn closed_form_stages_agree_with_newton() {
    use geomint_core::methods;
    use geomint_core::run::Stepper;
    for (name, any) in chart_systems() {
        with_system!(&any, sys => {
            if sys.structure().separable_constant_mass {
                return;
            }
            let n = nalgebra::Dim::value(&sys.dim());
            let (x, px) = test_state(n);
            let mut start = State::from_slices(sys.dim(), &x, &px);
            sys.from_cartesian(&x, &px, &mut start.q, &mut start.p).unwrap();
            for id in [MethodId::SymplecticEuler, MethodId::SymplecticEulerAdjoint] {
                let choice = Method::new(id);
                let h = 0.05;
                let mut a = start.clone();
                methods::build(&choice, sys, "test", h).unwrap().step(sys, &mut a, h).unwrap();
                let wrapped = NewtonOnly(sys);
                let mut b = start.clone();
                methods::build(&choice, &wrapped, "test", h).unwrap().step(&wrapped, &mut b, h).unwrap();
                for i in 0..n {
                    assert!((a.q[i] - b.q[i]).abs() < 1e-13 * (1.0 + a.q[i].abs()), "{name} {id:?}: q[{i}] {} vs Newton {}", a.q[i], b.q[i]);
                    assert!((a.p[i] - b.p[i]).abs() < 1e-13 * (1.0 + a.p[i].abs()), "{name} {id:?}: p[{i}] {} vs Newton {}", a.p[i], b.p[i]);
                }
            }
        });
    }
}

#[test]
fn symplectic_euler_in_polar_coordinates_keeps_p_theta_exactly_but_not_p_x() {
    // 001 Sec. 5.2: θ is cyclic, so p_θ never changes; p_x = p_r sin θ + (p_θ/r) cos θ moves by
    // O(h²) per step. Measured as the largest one-step change over a run at h and h/2.
    let mut largest = Vec::new();
    for h in [0.02, 0.01] {
        let req = charted(
            "free_particle_2d",
            "polar",
            json!({}),
            &["symplectic_euler"],
            h,
            2.0,
        );
        let (_, runs) = run_all(&req);
        let run = &runs[0];
        let p_theta0 = run.p[0][1];
        assert!(run.p.iter().all(|p| p[1] == p_theta0), "p_θ changed");
        let (_, px) = cartesian(run);
        let step_change = px
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).abs())
            .fold(0.0, f64::max);
        largest.push(step_change);
    }
    let ratio = largest[0] / largest[1];
    eprintln!("polar symplectic Euler: max |Δp_x| per step {largest:?}, ratio {ratio}");
    assert!(largest[0] > 1e-6, "p_x should move: {largest:?}");
    assert!(
        (3.6..4.4).contains(&ratio),
        "per-step change of p_x should scale as h²: ratio {ratio}, {largest:?}"
    );
}

#[test]
fn symplectic_euler_in_cartesian_coordinates_keeps_angular_momentum_to_round_off() {
    // 001 Sec. 5.2.2: L = x p_y − y p_x is quadratic, so the P-series method keeps it exactly
    // (to round-off); in polar coordinates L = −p_θ is kept trivially.
    let req = charted(
        "free_particle_2d",
        "cartesian",
        json!({}),
        &["symplectic_euler"],
        0.01,
        10.0,
    );
    let (_, runs) = run_all(&req);
    let column = &runs[0].invariants["L"];
    let drift = column
        .iter()
        .map(|v| (v - column[0]).abs())
        .fold(0.0, f64::max);
    // 1000 steps with |x p_y| up to ~10: a few ulps per step at most.
    eprintln!("Cartesian symplectic Euler: max |L − L0| = {drift:e} over 1000 steps");
    assert!(drift < 1e-12, "L drifts by {drift}");
}

#[test]
fn explicit_euler_in_the_transformed_variable_is_exact() {
    // 001 Sec. 2.3, Figs. 2–3: y' = −y (y0 = 1, h = 0.3) and Gompertz (y0 = 3, a = 2, b = 0.5,
    // h = 0.9); in the compensating variable explicit Euler reproduces the exact solution.
    for (system, params, h, y0) in [
        ("exponential_decay", json!({"alpha": 1.0}), 0.3, 1.0),
        ("gompertz", json!({"a": 2.0, "b": 0.5}), 0.9, 3.0),
    ] {
        let mut worst = [0.0f64; 2];
        for (k, chart) in ["original", "transformed"].into_iter().enumerate() {
            let mut req = charted(system, chart, params.clone(), &["explicit_euler"], h, 9.0);
            req.q0 = Some(vec![y0]);
            req.p0 = Some(vec![0.0]);
            req.initial_cartesian = true;
            let (sim, runs) = run_all(&req);
            let (y, _) = cartesian(&runs[0]);
            let exact = with_system!(&sim.system, s => {
                let start = State::from_slices(s.dim(), &sim.q0, &sim.p0);
                runs[0].t.iter().map(|&t| {
                    let e = s.exact(t, &start).unwrap();
                    let (mut x, mut px) = ([0.0], [0.0]);
                    s.to_cartesian(&e.q, &e.p, &mut x, &mut px);
                    x[0]
                }).collect::<Vec<_>>()
            });
            worst[k] = y
                .iter()
                .zip(&exact)
                .map(|(a, b)| ((a[0] - b) / b).abs())
                .fold(0.0, f64::max);
        }
        eprintln!(
            "{system}: explicit Euler relative error, original {:e}, transformed {:e}",
            worst[0], worst[1]
        );
        assert!(
            worst[1] < 1e-13,
            "{system}: transformed explicit Euler is off by {:e}",
            worst[1]
        );
        assert!(
            worst[0] > 1e-2,
            "{system}: explicit Euler in y should be visibly wrong, {:e}",
            worst[0]
        );
    }
}

/// max |H(t) − H(0)| over a run of symplectic Euler on the undamped unit oscillator.
fn oscillator_energy_error(chart: &str, h: f64) -> f64 {
    let mut req = charted(
        "harmonic_oscillator",
        chart,
        json!({"omega": 1.0, "gamma": 0.0, "k": 2.0}),
        &["symplectic_euler"],
        h,
        10.0,
    );
    req.q0 = Some(vec![1.0]);
    req.p0 = Some(vec![0.0]);
    req.initial_cartesian = true;
    let (_, runs) = run_all(&req);
    let e = &runs[0].energy;
    e.iter().map(|v| (v - 0.5).abs()).fold(0.0, f64::max)
}

#[test]
fn the_compensating_coordinate_makes_symplectic_euler_second_order_in_energy() {
    // 001 Appendix B, Fig. 9: order 1 in the original coordinate, 2 in the eq. (82) one.
    let hs = [0.04, 0.02, 0.01, 0.005];
    for (chart, order) in [("cartesian", 1.0), ("compensating", 2.0)] {
        let errors: Vec<f64> = hs
            .iter()
            .map(|&h| oscillator_energy_error(chart, h))
            .collect();
        let slope = geomint_core::diagnostics::log_log_slope(&hs, &errors);
        eprintln!(
            "oscillator, symplectic Euler, {chart}: energy error order {slope:.3} ({errors:?})"
        );
        assert!(
            (slope - order).abs() < 0.1,
            "{chart}: energy error order {slope} ({errors:?})"
        );
    }
}

/// Largest Cartesian state difference between two runs sampled at the same times.
fn cartesian_distance(a: &Columns, b: &Columns) -> f64 {
    let ((xa, pa), (xb, pb)) = (cartesian(a), cartesian(b));
    assert_eq!(xa.len(), xb.len());
    let mut worst = 0.0f64;
    for k in 0..xa.len() {
        for i in 0..xa[k].len() {
            worst = worst
                .max((xa[k][i] - xb[k][i]).abs())
                .max((pa[k][i] - pb[k][i]).abs());
        }
    }
    worst
}

const TOLERANCE: f64 = 1e-10;

#[test]
fn the_exact_flow_is_chart_invariant_and_symplectic_euler_is_not() {
    // 001 Sec. 4: the same physical initial state in two charts. The reference (adaptive
    // DOP853, tolerance 1e-12) integrates the exact flow, which does not care about the chart;
    // symplectic Euler is a different map in each chart. The reference runs in segments of 1.0,
    // long enough for its error control to matter (short segments make DOP853 exact to
    // round-off); symplectic Euler at h = 0.01; both sampled at t = 0, 1, …, 10.
    for (system, charts, params) in [
        (
            "elastic_pendulum_2d",
            ["cartesian", "polar"],
            json!({"g": 0.2}),
        ),
        (
            "elastic_pendulum_3d",
            ["cartesian", "cylindrical"],
            json!({"epsilon": 0.1}),
        ),
    ] {
        let mut by_method = Vec::new();
        for method in ["reference", "symplectic_euler"] {
            let mut runs = Vec::new();
            for chart in charts {
                let (h, every) = if method == "reference" {
                    (1.0, 1)
                } else {
                    (0.01, 100)
                };
                let mut req = charted(system, chart, params.clone(), &["rk4"], h, 10.0);
                req.every = Some(every);
                req.methods[0].method = if method == "reference" {
                    Method::Reference {
                        tolerance: TOLERANCE,
                    }
                } else {
                    Method::new(MethodId::parse(method).unwrap())
                };
                let (sim, mut out) = run_all(&req);
                // Both start from the catalogue's Cartesian default, transformed into the chart.
                let (x0, _) = cartesian(&out[0]);
                let info = common::info(system);
                for (a, b) in x0[0].iter().zip(&info.q0) {
                    assert!(
                        (a - b).abs() < 1e-15,
                        "{system}/{chart}: starts at {a}, not {b}"
                    );
                }
                assert_eq!(sim.chart.id, chart);
                runs.push(out.remove(0));
            }
            by_method.push(cartesian_distance(&runs[0], &runs[1]));
        }
        let (reference, euler) = (by_method[0], by_method[1]);
        eprintln!("{system}: chart difference reference {reference:e}, symplectic Euler {euler:e}");
        assert!(
            reference < 100.0 * TOLERANCE,
            "{system}: reference runs differ by {reference:e} between charts"
        );
        assert!(
            euler > 1e3 * reference && euler > 1e-4,
            "{system}: symplectic Euler differs by only {euler:e} (reference {reference:e})"
        );
    }
}

#[test]
fn splittings_refuse_a_non_separable_chart_with_the_reason() {
    for method in ["position_verlet", "modin_3s", "csv1"] {
        let req = charted(
            "elastic_pendulum_2d",
            "polar",
            json!({}),
            &[method],
            0.1,
            1.0,
        );
        match Simulation::prepare(&req, &Limits::default()) {
            Err(CoreError::Unmet {
                method: m,
                system,
                requirement,
                ..
            }) => {
                assert_eq!(m, method);
                assert!(system.contains("polar"), "{system}");
                assert!(
                    requirement.describe().contains("separable"),
                    "{requirement:?}"
                );
            }
            other => panic!("{method} on polar: {other:?}"),
        }
    }
    let bad = charted(
        "elastic_pendulum_2d",
        "spherical",
        json!({}),
        &["rk4"],
        0.1,
        1.0,
    );
    match Simulation::prepare(&bad, &Limits::default()) {
        Err(e @ CoreError::UnknownChart { .. }) => {
            assert_eq!(e.field().unwrap().as_str(), "chart");
            assert!(e.to_string().contains("cartesian, polar"), "{e}");
        }
        other => panic!("unknown chart: {other:?}"),
    }
    // A Cartesian initial state on the polar chart's singularity names q0.
    let mut singular = charted(
        "elastic_pendulum_2d",
        "polar",
        json!({}),
        &["rk4"],
        0.1,
        1.0,
    );
    singular.q0 = Some(vec![0.0, 0.0]);
    singular.p0 = Some(vec![0.0, 0.0]);
    singular.initial_cartesian = true;
    match Simulation::prepare(&singular, &Limits::default()) {
        Err(e @ CoreError::OutsideChart { .. }) => {
            assert_eq!(e.field().unwrap().as_str(), "q0");
            assert!(e.to_string().contains("r = 0"), "{e}");
        }
        other => panic!("singular start: {other:?}"),
    }
}

#[test]
fn the_damped_cylindrical_pendulum_keeps_j3_exactly_and_dissipates_like_the_cartesian_one() {
    let mut energies = Vec::new();
    for chart in ["cartesian", "cylindrical"] {
        let req = charted(
            "elastic_pendulum_3d",
            chart,
            json!({"epsilon": 0.2}),
            &["symplectic_euler", "rk4"],
            0.005,
            20.0,
        );
        let (_, runs) = run_all(&req);
        if chart == "cylindrical" {
            for run in &runs {
                let j3 = &run.invariants["J3"];
                assert!(
                    j3.iter().all(|&v| v == j3[0]),
                    "J3 = p_φ must not move at all"
                );
            }
        }
        energies.push(runs[1].energy.last().copied().unwrap());
    }
    // rk4 at h = 0.005 is accurate to far below the difference the damping makes.
    let lost = energies[0];
    assert!(
        (energies[0] - energies[1]).abs() < 1e-8 * lost.abs().max(1.0),
        "{energies:?}"
    );
}

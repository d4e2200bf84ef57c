//! Typed-in systems compiled: every example definition's compiled derivatives against central
//! differences of its compiled energy, and a definition that runs away stops with the step it
//! diverged at.

use crate::common;
use crate::definitions::{defined, energy_error_by_halves, run};
use common::{method, run_to_columns};
use geomint::core::error::Field;
use geomint::core::run::Budget;
use geomint::core::simulation::{Limits, Simulation, SimulationSpec};
use serde_json::{json, Value};

#[test]
fn a_double_pendulum_as_a_general_hamiltonian_runs_the_methods_for_it_and_refuses_splittings() {
    let system = defined(json!({
        "coordinates": ["a", "b"], "momenta": ["pa", "pb"],
        "hamiltonian": "(pa^2 + 2*pb^2 - 2*pa*pb*cos(a - b)) / (2*(1 + sin(a - b)^2)) \
                        - 2*g*cos(a) - g*cos(b)",
        "parameters": {"g": 9.81},
        "positions": [["sin(a)", "-cos(a)"], ["sin(a) + sin(b)", "-cos(a) - cos(b)"]],
        "q0": [1.0, 0.5], "p0": [0, 0],
    }));
    // Both are symplectic: the energy error stays in a band (the second half of the run's no
    // larger than the first's), of the size of each method's order.
    for (id, band) in [("implicit_midpoint", 1e-4), ("symplectic_euler", 5e-2)] {
        let spec = SimulationSpec {
            every: Some(10),
            ..SimulationSpec::new(system.clone(), &[method(id)], 0.001, 20.0)
        };
        let c = run(&spec).unwrap_or_else(|e| panic!("{id}: {e}"));
        // Each sample carries the bodies where the definition's positions put them.
        let bodies = c.bodies.as_ref().expect("the bodies' coordinates");
        for (q, b) in c.q.iter().zip(bodies) {
            let (a, b2) = (q[0], q[1]);
            let expected = [a.sin(), -a.cos(), a.sin() + b2.sin(), -a.cos() - b2.cos()];
            for (x, e) in b.iter().zip(expected) {
                assert!((x - e).abs() < 1e-15, "{id}: {b:?} at q = {q:?}");
            }
        }
        let (first, second) = energy_error_by_halves(&c.energy);
        assert!(
            second < band && second < 1.5 * first,
            "{id}: {first:.2e}, {second:.2e}"
        );
    }
    for id in ["modin_3s", "velocity_verlet", "csv1", "kahan_li_8"] {
        let spec = SimulationSpec::new(system.clone(), &[method(id)], 0.01, 1.0);
        let error = run(&spec).expect_err("refused");
        let detail = geomint::core::error::ErrorDetail::from(error);
        assert_eq!(
            detail.field.as_deref(),
            Some("methods[0]"),
            "{id}: {detail:?}"
        );
        assert!(
            detail.message.contains("separable") || detail.message.contains("damp"),
            "{id}: {}",
            detail.message
        );
    }
    // The positions draw the bodies: two of them, at unit distance from each other.
    let info = system.resolve(&Field::new("system")).expect("resolves");
    let values =
        geomint::core::systems::params::resolve(&info, &Default::default(), &Field::new("params"))
            .expect("default parameters");
    let world = info.world(&values).expect("a world");
    let mut bodies = Vec::new();
    world.positions(&[1.0, 0.5], &mut bodies);
    assert_eq!(bodies.len(), 2);
    let d: f64 = (0..3).map(|i| (bodies[1][i] - bodies[0][i]).powi(2)).sum();
    assert!((d.sqrt() - 1.0).abs() < 1e-15, "{bodies:?}");
}

/// The page's example systems.
fn examples() -> Vec<(&'static str, Value)> {
    vec![
        (
            "damped Duffing oscillator",
            json!({
                "coordinates": ["x"],
                "potential": "alpha*x^2/2 + beta*x^4/4",
                "damping": {"gamma": "gamma"},
                "parameters": {"alpha": -1, "beta": 1, "gamma": 0.1},
            }),
        ),
        (
            "Hénon–Heiles with damping",
            json!({
                "coordinates": ["x", "y"],
                "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3",
                "damping": {"gamma": 0.01},
            }),
        ),
        (
            "double pendulum",
            json!({
                "coordinates": ["a", "b"],
                "hamiltonian": "(p_a^2 + 2*p_b^2 - 2*p_a*p_b*cos(a - b)) / (2*(1 + sin(a - b)^2)) \
                                - 2*g*cos(a) - g*cos(b)",
                "parameters": {"g": 9.81},
            }),
        ),
        (
            "damped Kepler problem",
            json!({
                "coordinates": ["x", "y"],
                "mass": "m",
                "potential": "-k/sqrt(x^2 + y^2)",
                "damping": {"epsilon": "eps", "matrix": [[1, 0], [0, 1]]},
                "parameters": {"k": 1, "m": 1, "eps": 0.01},
            }),
        ),
        (
            "chain of springs",
            json!({
                "coordinates": ["u1", "u2", "u3"],
                "mass": [1, 2, 1],
                "potential": "k/2*(u1^2 + (u2 - u1)^2 + (u3 - u2)^2 + u3^2) + c/4*(u2 - u1)^4",
                "damping": {"epsilon": 0.05, "matrix": [[1, -1, 0], [-1, 2, -1], [0, -1, 1]]},
                "parameters": {"k": 1, "c": 0.5},
            }),
        ),
    ]
}

/// Compares the compiled derivatives of `sys` with central differences of its energy (first
/// derivatives) and of its compiled first derivatives (second derivatives) at `points`.
fn check_derivatives<S: geomint::core::system::MechanicalSystem>(
    name: &str,
    sys: &S,
    points: &[(Vec<f64>, Vec<f64>)],
) -> usize
where
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<S::Dim>,
{
    use geomint::core::system::Vector;
    use nalgebra::DMatrix;
    let dim = sys.dim();
    let n = nalgebra::Dim::value(&dim);
    let vector =
        |x: &[f64]| Vector::<S::Dim>::from_iterator_generic(dim, nalgebra::U1, x.iter().copied());
    let close = |a: f64, b: f64, what: &str| {
        assert!(
            (a - b).abs() <= 1e-6 * (1.0 + a.abs().max(b.abs())),
            "{name}: {what}: compiled {a} against differences {b}"
        );
    };
    let mut checked = 0;
    for (q, p) in points {
        let (q, p) = (vector(q), vector(p));
        let (mut dq, mut dp) = (q.clone(), q.clone());
        sys.dh_dq(&q, &p, &mut dq);
        sys.dh_dp(&q, &p, &mut dp);
        let (mut hqq, mut hqp, mut hpp) = (
            DMatrix::zeros(n, n),
            DMatrix::zeros(n, n),
            DMatrix::zeros(n, n),
        );
        let general = sys.hessian_h(&q, &p, &mut hqq, &mut hqp, &mut hpp);
        if !general {
            // Separable: ∇²V, and ∂²H/∂p² = M⁻¹ from differences of the velocity.
            sys.hess_potential(&q, &mut hqq);
        }
        for j in 0..n {
            let delta = 1e-5 * (1.0 + q[j].abs());
            let (mut qa, mut qb) = (q.clone(), q.clone());
            qa[j] += delta;
            qb[j] -= delta;
            close(
                dq[j],
                (sys.energy(&qa, &p) - sys.energy(&qb, &p)) / (2.0 * delta),
                "∂H/∂q",
            );
            let (mut ga, mut gb) = (q.clone(), q.clone());
            sys.dh_dq(&qa, &p, &mut ga);
            sys.dh_dq(&qb, &p, &mut gb);
            for i in 0..n {
                close(hqq[(i, j)], (ga[i] - gb[i]) / (2.0 * delta), "∂²H/∂q²");
            }
            let delta = 1e-5 * (1.0 + p[j].abs());
            let (mut pa, mut pb) = (p.clone(), p.clone());
            pa[j] += delta;
            pb[j] -= delta;
            close(
                dp[j],
                (sys.energy(&q, &pa) - sys.energy(&q, &pb)) / (2.0 * delta),
                "∂H/∂p",
            );
            if general {
                let (mut ga, mut gb) = (q.clone(), q.clone());
                sys.dh_dq(&q, &pa, &mut ga);
                sys.dh_dq(&q, &pb, &mut gb);
                let (mut va, mut vb) = (q.clone(), q.clone());
                sys.dh_dp(&q, &pa, &mut va);
                sys.dh_dp(&q, &pb, &mut vb);
                for i in 0..n {
                    close(hqp[(i, j)], (ga[i] - gb[i]) / (2.0 * delta), "∂²H/∂q∂p");
                    close(hpp[(i, j)], (va[i] - vb[i]) / (2.0 * delta), "∂²H/∂p²");
                }
            }
        }
        checked += 1;
    }
    checked
}

#[test]
fn compiled_derivatives_agree_with_central_differences_for_every_example() {
    // A fixed pseudo-random sequence (SplitMix64): points with every coordinate of size 0.3 to
    // 1.2 and either sign (away from the Kepler singularity), momenta in (−1, 1).
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut uniform = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    for (name, definition) in examples() {
        let info = defined(definition)
            .resolve(&Field::new("system"))
            .expect("resolves");
        let values = geomint::core::systems::params::resolve(
            &info,
            &Default::default(),
            &Field::new("params"),
        )
        .expect("default parameters");
        let system = info.build(&values, &info.charts[0], 0.01).expect("builds");
        let n = system.dimension();
        let points: Vec<(Vec<f64>, Vec<f64>)> = (0..20)
            .map(|_| {
                let mut coordinate = || {
                    let size = 0.3 + 0.9 * uniform();
                    if uniform() < 0.5 {
                        -size
                    } else {
                        size
                    }
                };
                let q: Vec<f64> = (0..n).map(|_| coordinate()).collect();
                let p: Vec<f64> = (0..n).map(|_| 2.0 * uniform() - 1.0).collect();
                (q, p)
            })
            .collect();
        let checked = geomint_core::with_system!(&system, s => check_derivatives(name, s, &points));
        assert_eq!(checked, 20, "{name}");
    }
}

#[test]
fn a_definition_that_runs_away_stops_with_the_step_it_diverged_at() {
    // V = −x⁴: released with energy, x reaches infinity in finite time.
    let system = defined(json!({
        "coordinates": ["x"], "potential": "-x^4", "q0": [1], "p0": [1],
    }));
    let spec = SimulationSpec::new(system, &[method("rk4")], 0.01, 100.0);
    let sim = Simulation::prepare(&spec, &Limits::default()).expect("prepares");
    let (columns, outcome) = run_to_columns(&sim, 0, None, Budget::default()).expect("runs");
    let geomint::core::run::RunEnd::Diverged { step, .. } = outcome.stop else {
        panic!("finished: {:?}", outcome.stop)
    };
    // The blow-up time of x' = p, p' = 4x³ from (1, 1) with H = 1/2 − 1 = −1/2 is
    // ∫₁^∞ dx / √(2x⁴ − 1) ≈ 0.8; rk4 with h = 0.01 reaches a non-finite state shortly after.
    let t = step as f64 * 0.01;
    assert!((0.7..1.5).contains(&t), "diverged at t = {t}");
    assert!(columns.q.iter().flatten().all(|x| x.is_finite()));
}

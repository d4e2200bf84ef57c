//! Bad inputs to the core return typed errors naming the field; analytic gradients agree with
//! finite differences (property tests); the exact damping flow never raises the energy.

use crate::common;

use common::request;
use geomint::api::method::read_method;
use geomint::core::error::CoreError;
use geomint::core::error::Field;
use geomint::core::methods::state_flows;
use geomint::core::methods::{Base, Method, MethodId};
use geomint::core::simulation::{Limits, MethodAt, Simulation, SimulationSpec};
use geomint::core::system::{MechanicalSystem, State};
use geomint::core::systems::{ElasticPendulum3d, NBody, PairPotential, Pendulum};
use nalgebra::{DVector, Dyn, U3};
use proptest::prelude::*;
use serde_json::json;

fn field_of(req: SimulationSpec) -> String {
    match Simulation::prepare(&req, &Limits::default()) {
        Ok(_) => panic!("request was accepted"),
        Err(e) => e.field().map_or("-".to_string(), |f| f.to_string()),
    }
}

#[test]
fn bad_requests_name_the_offending_field() {
    let ok = || request("pendulum", json!({}), &["modin_3s"], 0.1, 10.0);
    assert!(Simulation::prepare(&ok(), &Limits::default()).is_ok());
    assert_eq!(field_of(SimulationSpec { h: 0.0, ..ok() }), "h");
    assert_eq!(field_of(SimulationSpec { h: -1.0, ..ok() }), "h");
    assert_eq!(
        field_of(SimulationSpec {
            h: f64::NAN,
            ..ok()
        }),
        "h"
    );
    assert_eq!(
        field_of(SimulationSpec {
            t_end: f64::INFINITY,
            ..ok()
        }),
        "t_end"
    );
    assert_eq!(
        field_of(SimulationSpec {
            h: 1e-9,
            t_end: 1e3,
            ..ok()
        }),
        "t_end"
    ); // 1e12 steps
    assert_eq!(
        field_of(SimulationSpec {
            every: Some(1),
            h: 1e-4,
            t_end: 200.0,
            ..ok()
        }),
        "output.every"
    ); // 2e6 samples
    assert_eq!(
        field_of(SimulationSpec {
            q0: Some(vec![1.0, 2.0]),
            ..ok()
        }),
        "q0"
    );
    assert_eq!(
        field_of(SimulationSpec {
            p0: Some(vec![f64::NAN]),
            ..ok()
        }),
        "p0[0]"
    );
    assert_eq!(
        field_of(request(
            "pendulum",
            json!({"gamma": -1.0}),
            &["modin_3s"],
            0.1,
            1.0
        )),
        "params.gamma"
    );
    assert_eq!(
        field_of(request(
            "pendulum",
            json!({"gamma": 1.0, "epsilon": 2.0}),
            &["modin_3s"],
            0.1,
            1.0
        )),
        "params.epsilon"
    );
    assert_eq!(
        field_of(request(
            "pendulum",
            json!({"omega": 1.0}),
            &["modin_3s"],
            0.1,
            1.0
        )),
        "params.omega"
    );
    assert_eq!(
        field_of(request(
            "pendulum",
            json!({"gamma": "x"}),
            &["modin_3s"],
            0.1,
            1.0
        )),
        "params.gamma"
    );
    assert_eq!(
        field_of(request(
            "elastic_pendulum_3d",
            json!({"m": 0.0}),
            &["modin_3s"],
            0.1,
            1.0
        )),
        "params.m"
    );
    assert_eq!(
        field_of(request(
            "nbody",
            json!({"masses": [1.0, -1.0]}),
            &["csv1"],
            0.1,
            1.0
        )),
        "params.masses"
    );
    assert_eq!(
        field_of(request(
            "nbody",
            json!({"potential": "coulomb"}),
            &["csv1"],
            0.1,
            1.0
        )),
        "params.potential"
    );
    assert_eq!(
        field_of(request(
            "nbody",
            json!({"masses": [1.0, 1.0]}),
            &["csv1"],
            0.1,
            1.0
        )),
        "q0"
    );
    assert_eq!(
        field_of(request("pendulum", json!({}), &[], 0.1, 1.0)),
        "methods"
    );
    assert_eq!(
        field_of(request(
            "pendulum",
            json!({"gamma": 1.5}),
            &["csv2"],
            4.0 / 3.0,
            10.0
        )),
        "h"
    );
    // A method object: its options are checked as it is read into a method, then the method
    // against the system.
    let object = |v: serde_json::Value| -> String {
        let field = Field::new("methods").index(0);
        match read_method(&v, &field).unwrap().at(&field) {
            Err(e) => e.field().unwrap().to_string(),
            Ok(at) => field_of(SimulationSpec {
                methods: vec![at],
                ..ok()
            }),
        }
    };
    assert_eq!(
        object(json!({"id": "modin_rks", "inner": "explicit_euler"})),
        "methods[0].inner"
    );
    assert_eq!(
        object(json!({"id": "triple_jump", "base": "heun"})),
        "methods[0].base"
    );
    assert_eq!(
        object(json!({"id": "csv1", "inner": "rk4"})),
        "methods[0].inner"
    );
    assert_eq!(
        object(json!({"id": "reference", "tolerance": 0.0})),
        "methods[0].tolerance"
    );
    let unknown = Field::new("methods").index(0);
    assert_eq!(
        read_method(&json!("leapfrog"), &unknown)
            .unwrap_err()
            .field
            .as_deref(),
        Some("methods[0]")
    );
    assert!(matches!(
        Simulation::prepare(
            &request("no_such_system", json!({}), &["heun"], 0.1, 1.0),
            &Limits::default()
        ),
        Err(CoreError::UnknownSystem { .. })
    ));
}

#[test]
fn unmet_requirements_name_the_requirement() {
    let err = Simulation::prepare(
        &request("elastic_pendulum_3d", json!({}), &["csv1"], 0.1, 1.0),
        &Limits::default(),
    )
    .unwrap_err();
    match err {
        CoreError::Unmet {
            method,
            requirement,
            ..
        } => {
            assert_eq!(method, "csv1");
            assert!(
                requirement.describe().contains("conformal damping"),
                "{requirement:?}"
            );
        }
        other => panic!("{other:?}"),
    }
    // A triple jump inherits its base's requirements.
    let tj = request("elastic_pendulum_3d", json!({}), &[], 0.1, 1.0);
    let tj = SimulationSpec {
        methods: vec![MethodAt {
            method: Method::triple_jump(Base::Cimp),
            field: Field::new("methods").index(0),
        }],
        ..tj
    };
    assert!(matches!(
        Simulation::prepare(&tj, &Limits::default()),
        Err(CoreError::Unmet { .. })
    ));
}

fn check_gradient<S: MechanicalSystem>(sys: &S, q: &nalgebra::OVector<f64, S::Dim>) -> f64
where
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<S::Dim>,
{
    let mut g = q.clone();
    sys.grad_potential(q, &mut g);
    let mut worst: f64 = 0.0;
    for i in 0..q.len() {
        let d = 1e-6 * (1.0 + q[i].abs());
        let (mut a, mut b) = (q.clone(), q.clone());
        a[i] += d;
        b[i] -= d;
        let fd = (sys.potential(&a) - sys.potential(&b)) / (2.0 * d);
        worst = worst.max((fd - g[i]).abs() / (1.0 + g[i].abs()));
    }
    worst
}

proptest! {
    #[test]
    fn elastic_pendulum_gradient_matches_finite_differences(x in -2.0..2.0f64, y in -2.0..2.0f64, z in 0.3..2.0f64) {
        let sys = ElasticPendulum3d { m: 1.2, k: 3.0, l: 1.0, g: 9.81, epsilon: 0.1 };
        prop_assert!(check_gradient(&sys, &nalgebra::Vector3::new(x, y, z)) < 1e-6);
    }

    #[test]
    fn nbody_gradients_match_finite_differences(coords in proptest::collection::vec(-2.0..2.0f64, 9)) {
        let q = DVector::from_vec(coords);
        let spread = (0..3).flat_map(|i| (i + 1..3).map(move |j| (i, j)))
            .map(|(i, j)| (q.fixed_rows::<3>(3 * i) - q.fixed_rows::<3>(3 * j)).norm()).fold(f64::MAX, f64::min);
        prop_assume!(spread > 0.5);
        for potential in [PairPotential::Gravity { g: 1.0, softening: 0.1 }, PairPotential::LennardJones { epsilon: 1.0, sigma: 0.4 }] {
            let sys = NBody { masses: vec![1.0, 2.0, 0.5], potential, gamma: 0.0 };
            prop_assert!(check_gradient(&sys, &q) < 1e-6);
        }
    }

    #[test]
    fn exact_damping_flow_never_raises_the_energy(q in proptest::collection::vec(-2.0..2.0f64, 3), p in proptest::collection::vec(-2.0..2.0f64, 3), tau in 0.0..5.0f64) {
        let sys = ElasticPendulum3d { m: 1.0, k: 1.0, l: 1.0, g: 1.0, epsilon: 0.5 };
        let mut z = State::from_slices(U3, &q, &p);
        prop_assume!(z.q.norm() > 1e-3);
        let before = sys.energy(&z.q, &z.p);
        let mut w = z.q;
        state_flows::damp(&sys, &mut z, tau, &mut w);
        prop_assert!(sys.energy(&z.q, &z.p) <= before + 1e-15);
        // The damping flow leaves the tangential momentum, and so J₃, unchanged.
        prop_assert!(((z.q[0] * z.p[1] - z.q[1] * z.p[0]) - (q[0] * p[1] - q[1] * p[0])).abs() < 1e-12);
    }

    #[test]
    fn pendulum_gradient_matches_finite_differences(q in -10.0..10.0f64) {
        let sys = Pendulum { gamma: 0.0 };
        prop_assert!(check_gradient(&sys, &nalgebra::Vector1::new(q)) < 1e-8);
    }
}

#[test]
fn nbody_dimension_is_three_per_body() {
    let sys = NBody {
        masses: vec![1.0; 5],
        potential: PairPotential::Gravity {
            g: 1.0,
            softening: 0.0,
        },
        gamma: 0.0,
    };
    assert_eq!(sys.dim(), Dyn(15));
}

#[test]
fn one_huge_reference_step_fails_cleanly_instead_of_running_unbounded() {
    // ω = 1000 over a single step of 10⁴: far more adaptive steps than one segment may take.
    let req = request(
        "harmonic_oscillator",
        json!({"omega": 1000.0, "gamma": 0.0}),
        &["reference"],
        1e4,
        1e4,
    );
    let sim = Simulation::prepare(&req, &Limits::default()).unwrap();
    let began = std::time::Instant::now();
    let result = common::run_to_columns(&sim, 0, None, Default::default());
    assert!(
        matches!(result, Err(CoreError::Step { step: 1, .. })),
        "{result:?}"
    );
    assert!(began.elapsed().as_secs_f64() < 10.0);
}

#[test]
fn epsilon_errors_name_epsilon_and_show_its_own_range() {
    let err = Simulation::prepare(
        &request("pendulum", json!({"epsilon": 3e6}), &["csv1"], 0.1, 1.0),
        &Limits::default(),
    )
    .unwrap_err();
    assert_eq!(err.field().unwrap().as_str(), "params.epsilon");
    assert!(
        err.to_string()
            .contains("3000000 is outside the valid range [0, 2000000]"),
        "{err}"
    );
}

#[test]
fn composition_sub_steps_that_make_a_solve_singular_are_refused() {
    let [w1, w0, _] = geomint::core::methods::composition::triple_jump_weights();
    let tj = |base: &str, gamma: f64, h: f64| SimulationSpec {
        methods: vec![MethodAt {
            method: Method::triple_jump(Base::of(MethodId::parse(base).unwrap()).unwrap()),
            field: Field::new("methods").index(0),
        }],
        ..request("pendulum", json!({ "gamma": gamma }), &[], h, 10.0 * h)
    };
    // csv2 divides by 1 − γτ/2 with τ = w₁h: singular at γh = 2/w₁ ≈ 1.480.
    assert_eq!(field_of(tj("csv2", 1.0, 2.0 / w1)), "h");
    // The backward-Euler half kick of velocity Verlet divides by 1 + γτ with τ = w₀h < 0.
    assert_eq!(field_of(tj("velocity_verlet", 1.0, -1.0 / w0)), "h");
    // Nearby step sizes are fine.
    assert!(Simulation::prepare(&tj("csv2", 1.0, 1.9 / w1), &Limits::default()).is_ok());
    assert!(
        Simulation::prepare(&tj("velocity_verlet", 1.0, -0.9 / w0), &Limits::default()).is_ok()
    );
}

#[test]
fn jacobian_defect_works_with_the_reference_comparison_but_not_for_the_reference_itself() {
    let mut req = request("pendulum", json!({"gamma": 0.1}), &["csv1"], 0.1, 2.0);
    req.jacobian_defect = true;
    req.compare_to_reference = true;
    let (_, runs) = common::run_all(&req);
    assert!(runs[0].energy_error.is_some());
    assert!(runs[0]
        .jacobian_defect
        .as_ref()
        .unwrap()
        .iter()
        .skip(1)
        .all(|d| *d < 1e-12));
    let with_reference = SimulationSpec {
        methods: request("pendulum", json!({}), &["csv1", "reference"], 0.1, 2.0).methods,
        ..req
    };
    assert_eq!(field_of(with_reference), "methods[1]");
}

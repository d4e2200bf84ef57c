//! Rowlands' method through the requests: damped and non-separable systems refused with the
//! reason, no tangent map (jacobian_defect refused), the processor option parsed, defaulted and
//! checked, stability maps that need an undamped axis, and the analytic Hessians against
//! differences.

use crate::common;
use crate::rowlands::{case_of, distance, measure, run, Variant};
use geomint::api::method::{MethodOptions, MethodSpec};
use geomint::api::system::NoStoredSystems;
use geomint::api::{ErrorCode, ErrorDetail, SimulateRequest};
use geomint::core::error::Field;
use geomint::core::error::{CoreError, StepError};
use geomint::core::methods::rowlands::{Processor, Rowlands};
use geomint::core::methods::{Group, Method, MethodId, MethodOption};
use geomint::core::run::{integrate, Budget, Schedule, Stepper};
use geomint::core::simulation::{Limits, Simulation, SimulationSpec};
use geomint::core::system::{MechanicalSystem, State, Structure, Vector};
use geomint::core::systems::{ElasticPendulum3d, Pendulum};
use geomint::core::tangent::Tangent;
use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DefaultAllocator, U1};
use serde_json::json;

#[test]
fn the_driver_reports_the_given_start_processed_samples_and_leaves_the_processed_end() {
    let case = case_of("elastic_pendulum_3d");
    for p in Processor::ALL {
        let v = Variant::Choice(Method::Rowlands { processor: p });
        // `run` checks the first sample is the start and the last the end state. Sampling does
        // not disturb the kernel: sampling every step ends where sampling only the end does.
        let (every_step, _) = measure(case, &v, 0.05, 1);
        let (only_end, _) = measure(case, &v, 0.05, u64::MAX);
        assert_eq!(every_step.end, only_end.end, "{}", v.label());
        assert_eq!(only_end.samples, 2);
    }
    // A run without steps leaves the state as given.
    let pendulum = Pendulum { gamma: 0.0 };
    let start = State::from_slices(U1, &[2.0], &[0.3]);
    let mut st = Rowlands::new(&pendulum, Processor::Cheap);
    let mut z = start.clone();
    let schedule = Schedule {
        h: 0.1,
        steps: 0,
        every: 1,
    };
    integrate(
        &pendulum,
        &mut st,
        &mut z,
        schedule,
        Budget::default(),
        &mut common::Discard,
    )
    .unwrap();
    assert_eq!(z, start);
}

fn rowlands_request(system: &str, params: serde_json::Value) -> SimulationSpec {
    common::request(system, params, &["rowlands"], 0.1, 1.0)
}

#[test]
fn damped_and_non_separable_systems_are_refused_with_the_reason() {
    // Damped: the oscillator's and the elastic pendulum's default damping.
    for (system, params) in [
        ("harmonic_oscillator", json!({})),
        ("elastic_pendulum_3d", json!({})),
        ("pendulum", json!({"gamma": 0.1})),
    ] {
        let req = rowlands_request(system, params);
        let err = Simulation::prepare(&req, &Limits::default()).unwrap_err();
        match &err {
            CoreError::Unmet {
                method,
                requirement,
                ..
            } => {
                assert_eq!(method, "rowlands(cheap)");
                let requirement = requirement.describe();
                assert!(requirement.starts_with("no damping"), "{requirement}");
                assert!(requirement.contains("conservative"), "{requirement}");
            }
            other => panic!("{system}: {other:?}"),
        }
        let detail = ErrorDetail::from(&err);
        assert_eq!(detail.field.as_deref(), Some("methods[0]"));
        assert_eq!(detail.code, ErrorCode::UnmetRequirement);
        assert!(detail.message.contains("no damping"), "{}", detail.message);
    }
    // Undamped, it runs.
    assert!(Simulation::prepare(
        &rowlands_request("elastic_pendulum_3d", json!({"epsilon": 0})),
        &Limits::default()
    )
    .is_ok());

    // Non-separable: the planar elastic pendulum in polar coordinates, whose mass matrix
    // depends on r.
    let req = SimulationSpec {
        chart: Some("polar".into()),
        ..rowlands_request("elastic_pendulum_2d", json!({}))
    };
    let err = Simulation::prepare(&req, &Limits::default()).unwrap_err();
    match &err {
        CoreError::Unmet { requirement, .. } => {
            assert!(
                requirement.describe().contains("separable Hamiltonian"),
                "{requirement:?}"
            )
        }
        other => panic!("{other:?}"),
    }
    let detail = ErrorDetail::from(&err);
    assert_eq!(detail.field.as_deref(), Some("methods[0]"));
    assert_eq!(detail.code, ErrorCode::UnmetRequirement);
    assert!(
        detail.message.contains("separable Hamiltonian"),
        "{}",
        detail.message
    );
    // In Cartesian coordinates it runs.
    assert!(Simulation::prepare(
        &rowlands_request("elastic_pendulum_2d", json!({})),
        &Limits::default()
    )
    .is_ok());
}

#[test]
fn rowlands_has_no_tangent_map_and_refuses_jacobian_defect() {
    let pendulum = Pendulum { gamma: 0.0 };
    let z = State::from_slices(U1, &[2.0], &[0.3]);
    let mut st = Rowlands::new(&pendulum, Processor::Cheap);
    let mut tangent = Tangent::new(&pendulum, &z);
    let mut z1 = z.clone();
    match st.step_tangent(&pendulum, &mut z1, 0.1, &mut tangent) {
        Err(StepError::TangentUnsupported { reason }) => assert!(reason.contains("rowlands")),
        other => panic!("{other:?}"),
    }
    let req = SimulationSpec {
        jacobian_defect: true,
        ..rowlands_request("pendulum", json!({"gamma": 0}))
    };
    match Simulation::prepare(&req, &Limits::default()) {
        Err(e @ CoreError::NoStepJacobian { .. }) => {
            assert_eq!(e.field().unwrap().as_str(), "methods[0]");
            assert!(e.to_string().contains("no step Jacobian"), "{e}");
        }
        other => panic!("{:?}", other.map(|_| ())),
    }
}

#[test]
fn the_processor_option_parses_defaults_to_cheap_and_is_checked() {
    let object = |id: &str, processor: Option<&str>| {
        MethodSpec::Options(MethodOptions {
            id: id.into(),
            processor: processor.map(str::to_string),
            ..Default::default()
        })
    };
    let at = |f: &str| Field::new(f);
    let plain = MethodSpec::Id("rowlands".into())
        .to_method(&at("methods[0]"))
        .unwrap();
    assert_eq!(
        plain,
        Method::Rowlands {
            processor: Processor::Cheap
        }
    );
    assert_eq!(plain.label(), "rowlands(cheap)");
    assert_eq!(plain, Method::new(MethodId::Rowlands));
    for p in Processor::ALL {
        let c = object("rowlands", Some(p.as_str()))
            .to_method(&at("methods[0]"))
            .unwrap();
        assert_eq!(c, Method::Rowlands { processor: p });
        assert_eq!(c.label(), format!("rowlands({})", p.as_str()));
        assert_eq!(c.order(), if p == Processor::None { 2 } else { 4 });
    }
    match object("rowlands", Some("fancy")).to_method(&at("methods[1]")) {
        Err(e @ CoreError::UnknownName { .. }) => {
            assert_eq!(e.field().unwrap().as_str(), "methods[1].processor");
            assert!(e.to_string().contains("none, original, cheap"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    match object("velocity_verlet", Some("cheap")).to_method(&at("methods[0]")) {
        Err(e @ CoreError::UnknownOption { .. }) => {
            assert_eq!(e.field().unwrap().as_str(), "methods[0].processor")
        }
        other => panic!("{other:?}"),
    }
    let info = MethodId::Rowlands.info();
    assert_eq!(
        (info.order, info.symplectic, info.symmetric, info.group),
        (4, true, true, Group::Geometric)
    );
    assert_eq!(info.options, &[MethodOption::Processor]);
    assert!(info.reference.paper.starts_with("001"));

    // Through the API's request parser.
    let req = SimulateRequest::from_slice(
        br#"{"system": "pendulum", "params": {"gamma": 0}, "h": 0.1, "t_end": 1,
             "methods": [{"id": "rowlands", "processor": "original"}]}"#,
    )
    .unwrap();
    let sim = req.prepare(&Limits::default(), &NoStoredSystems).unwrap();
    assert_eq!(
        sim.methods[0],
        Method::Rowlands {
            processor: Processor::Original
        }
    );
    let err = SimulateRequest::from_slice(
        br#"{"system": "pendulum", "h": 0.1, "t_end": 1, "methods": [{"id": "rowlands", "processor": 2}]}"#,
    )
    .unwrap_err();
    assert_eq!(err.field.as_deref(), Some("methods[0].processor"));
}

#[test]
fn stability_maps_of_rowlands_need_an_undamped_axis() {
    use geomint::core::stability::{map, StabilityAxis};
    let rowlands = Method::new(MethodId::Rowlands);
    let h = StabilityAxis {
        min: 0.0,
        max: 1.0,
        n: 5,
    };
    let damped = StabilityAxis {
        min: 0.0,
        max: 1.0,
        n: 3,
    };
    assert!(matches!(
        map(&rowlands, 2.0, damped, h),
        Err(CoreError::Unmet { .. })
    ));
    let undamped = StabilityAxis {
        min: 0.0,
        max: 0.0,
        n: 2,
    };
    // The kernel is Verlet with ω̂² = ω²(1 − h²ω²/12): stable up to hω̂ = 2, here for every h ≤ 1.
    let m = map(&rowlands, 2.0, undamped, h).unwrap();
    assert!(m.stable.iter().all(|&s| s), "{:?}", m.spectral_radius);
}

/// `S` with the trait's default (difference) Hessian.
struct DifferenceHessian<S>(S);

impl<S: MechanicalSystem> MechanicalSystem for DifferenceHessian<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    type Dim = S::Dim;
    fn dim(&self) -> S::Dim {
        self.0.dim()
    }
    fn structure(&self) -> Structure {
        self.0.structure()
    }
    fn kinetic(&self, q: &Vector<S::Dim>, p: &Vector<S::Dim>) -> f64 {
        self.0.kinetic(q, p)
    }
    fn potential(&self, q: &Vector<S::Dim>) -> f64 {
        self.0.potential(q)
    }
    fn grad_potential(&self, q: &Vector<S::Dim>, out: &mut Vector<S::Dim>) {
        self.0.grad_potential(q, out)
    }
    fn velocity(&self, q: &Vector<S::Dim>, p: &Vector<S::Dim>, out: &mut Vector<S::Dim>) {
        self.0.velocity(q, p, out)
    }
    fn damping_rate(&self) -> f64 {
        self.0.damping_rate()
    }
}

#[test]
fn analytic_hessians_match_differences_and_the_directional_product_matches_them() {
    let pendulum = Pendulum { gamma: 0.0 };
    let elastic = ElasticPendulum3d {
        m: 1.3,
        k: 2.0,
        l: 0.8,
        g: 1.0,
        epsilon: 0.0,
    };
    fn compare<S: MechanicalSystem>(sys: S, q: &[f64]) -> f64
    where
        DefaultAllocator: Allocator<S::Dim>,
    {
        let q = State::from_slices(sys.dim(), q, q).q;
        let n = q.len();
        let (mut a, mut d) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        assert_eq!(sys.hess_potential(&q, &mut a), 0, "analytic");
        let sys = DifferenceHessian(sys);
        assert_eq!(sys.hess_potential(&q, &mut d), 2 * n as u64);
        (a - d).amax()
    }
    assert!(compare(pendulum.clone(), &[2.0]) < 1e-9);
    assert!(compare(elastic.clone(), &[0.3, -0.7, -0.9]) < 1e-8);

    // A run with the difference Hessian (so directional products after the first) ends where the
    // analytic one does, to about the products' accuracy times h²/12.
    let z = State::from_slices(
        nalgebra::U3,
        &[0.0, 1.55884573, -0.6],
        &[1.34164079, 0.0, 0.0],
    );
    let schedule = Schedule::new(0.05, 4.0, 10);
    let mut analytic = Rowlands::new(&elastic, Processor::Cheap);
    let a = run(&elastic, &mut analytic, &z, schedule);
    let differences = DifferenceHessian(elastic);
    let mut directional = Rowlands::new(&differences, Processor::Cheap);
    let d = run(&differences, &mut directional, &z, schedule);
    let gap = distance(&a.end, &d.end);
    assert!(gap < 1e-11, "{gap:e}");
    assert!(d.force_evaluations > a.force_evaluations);
}

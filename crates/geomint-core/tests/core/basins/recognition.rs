//! How attractors are recognised, beyond the criteria of the maps above: the forced damped
//! pendulum's rotating orbits with θ an angle, checked against the adaptive reference; attractors
//! the request gives, by proximity; the Kapitza pendulum's upright orbit as one attractor on
//! either side of π; and the refusals of bad angles and attractors.

use geomint_core::error::Field;
use geomint_core::methods::{Method, MethodId};
use geomint_core::simulation::Limits;
use geomint_core::studies::basins::{
    self, AttractorKind, BasinRun, BasinsSpec, GivenAttractor, Recognition,
};
use geomint_core::studies::sweep::Target;
use geomint_core::systems::custom::Damping;
use geomint_core::systems::SystemRef;

use super::{axis, double_well_map, forced_pendulum_map, run, sweep};
use crate::chaos_map::expr;
use crate::sections::separable;

#[test]
fn the_forced_damped_pendulum_turns_once_a_period_one_way_or_the_other() {
    let n = 16;
    // Taken as a number, θ gains ±2π a period on the rotating orbits: nothing recurs.
    let job = forced_pendulum_map(n, &[])
        .prepare(&Limits::default())
        .unwrap();
    let doc = run(&job.one_cell_at_a_time());
    let map = &doc.runs[0];
    assert_eq!(map.undecided.len(), n * n, "{:?}", map.attractors);
    assert!(
        map.undecided[0].reason.contains("periodic"),
        "{:?}",
        map.undecided[0]
    );
    // As an angle, every cell locks onto one of two period-1 orbits — not onto an orbit of
    // period 2 whose points coincide, which is how one approached with a multiplier near −1
    // first looks.
    let job = forced_pendulum_map(n, &["theta"])
        .prepare(&Limits::default())
        .unwrap();
    let doc = run(&job);
    for run in &doc.runs {
        assert_eq!(run.undecided_fraction, 0.0, "{:?}", run.undecided.first());
        assert_eq!(run.decided_by.recurrence, n * n);
        assert_eq!(
            run.attractors.len(),
            2,
            "{}: {:?}",
            run.label.method,
            run.attractors
        );
        assert!(run.attractors.iter().all(|a| a.period == Some(1)));
        // Reported on the circle.
        for a in &run.attractors {
            assert!(
                a.points[0][0].abs() <= std::f64::consts::PI,
                "{:?}",
                a.points
            );
        }
    }
    // csv1's stroboscopic points lie within its first-order error of the reference's, and the
    // two orbits turn opposite ways: one with p > 0 where θ ≈ −0.82, one with p < 0.
    let (csv1, reference) = (&doc.runs[0], &doc.runs[1]);
    let mut momenta = Vec::new();
    for (a, b) in csv1.attractors.iter().zip(&reference.attractors) {
        assert_eq!(a.name, b.name);
        let gap = a.points[0]
            .iter()
            .zip(&b.points[0])
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(gap < 1e-2, "{:?} against {:?}", a.points, b.points);
        momenta.push(b.points[0][1]);
    }
    momenta.sort_by(f64::total_cmp);
    assert!(momenta[0] < -0.5 && momenta[1] > 0.5, "{momenta:?}");
    // Cell by cell the two maps differ where the boundary is: it is fractal (Grebogi, Ott &
    // Yorke), and on the 101 × 101 preset its uncertainty exponent is about 0.03, so an error
    // of any size moves labels near it. What both maps share is the pair of attractors above
    // and basins interleaved at the grid's scale: every box of the basin entropy straddles the
    // boundary, and most cells have a neighbour of the other label.
    for run in &doc.runs {
        let m = &run.metrics;
        println!("{}: fractions {:?}, {m:?}", run.label.method, run.fractions);
        assert_eq!(m.boundary_boxes, m.boxes, "{m:?}");
        assert!(m.uncertain_fractions[0].fraction > 0.5, "{m:?}");
    }
}

#[test]
fn given_attractors_take_the_first_labels_and_decide_cells_by_proximity() {
    let n = 16;
    // The pendulum's two rotating orbits as the reference finds them.
    let found = forced_pendulum_map(n, &["theta"]);
    let doc = run(&found.prepare(&Limits::default()).unwrap());
    let reference = &doc.runs[1];
    let mut given = found.clone();
    given.attractors = reference
        .attractors
        .iter()
        .enumerate()
        .map(|(i, a)| GivenAttractor {
            name: format!("turn {}", i + 1),
            // One point given 2π further on: angles are compared modulo 2π.
            points: vec![vec![a.points[0][0] + std::f64::consts::TAU, a.points[0][1]]],
            radius: 0.05,
            field: Field::new("attractors").index(i),
        })
        .collect();
    let doc_given = run(&given.prepare(&Limits::default()).unwrap());
    for (with, without) in doc_given.runs.iter().zip(&doc.runs) {
        // The same partition, named by the request, decided earlier.
        assert_eq!(with.attractors.len(), 2, "{:?}", with.attractors);
        assert!(with
            .attractors
            .iter()
            .all(|a| a.kind == AttractorKind::Given));
        assert_eq!(with.attractors[0].name, "turn 1");
        assert_eq!(with.labels, without.labels);
        assert!(
            with.decided_by.proximity > n * n / 2,
            "{:?}",
            with.decided_by
        );
        assert_eq!(
            with.decided_by.proximity + with.decided_by.recurrence,
            n * n
        );
        let mean = |r: &BasinRun| r.decided_at.iter().flatten().sum::<f64>() / (n * n) as f64;
        assert!(
            mean(with) < mean(without),
            "{} against {}",
            mean(with),
            mean(without)
        );
    }
    // A system nothing drives: the double well's minima given by name take the cells the
    // energy argument decides, and a given attractor no cell reaches keeps its label.
    let mut spec = double_well_map(12, 0.05, &[Method::new(MethodId::Csv2)]);
    let plain = run(&spec.prepare(&Limits::default()).unwrap());
    spec.attractors = [("left", -1.0), ("right", 1.0), ("nowhere", 5.0)]
        .iter()
        .enumerate()
        .map(|(i, &(name, x))| GivenAttractor {
            name: name.into(),
            points: vec![vec![x, 0.0]],
            radius: 0.05,
            field: Field::new("attractors").index(i),
        })
        .collect();
    let named = run(&spec.prepare(&Limits::default()).unwrap());
    let (named, plain) = (&named.runs[0], &plain.runs[0]);
    let cells =
        |r: &BasinRun, name: &str| r.attractors.iter().find(|a| a.name == name).unwrap().cells;
    let minimum_at = |r: &BasinRun, sign: f64| {
        r.attractors
            .iter()
            .find(|a| a.equilibrium.as_ref().is_some_and(|e| e.q[0] * sign > 0.5))
            .unwrap()
            .cells
    };
    assert_eq!(cells(named, "left"), minimum_at(plain, -1.0));
    assert_eq!(cells(named, "right"), minimum_at(plain, 1.0));
    assert_eq!(cells(named, "nowhere"), 0);
    assert_eq!(named.attractors[2].label, 2);
    assert_eq!(named.undecided_fraction, plain.undecided_fraction);
}

#[test]
fn bad_angles_and_given_attractors_are_refused_naming_the_field() {
    let base = double_well_map(4, 0.1, &[Method::new(MethodId::Csv2)]);
    let refused = |spec: BasinsSpec| match spec.prepare(&Limits::default()) {
        Ok(_) => panic!("accepted"),
        Err(e) => (e.field().map(|f| f.as_str().to_string()), e.to_string()),
    };
    let given = |name: &str, points: Vec<Vec<f64>>, radius: f64, i: usize| GivenAttractor {
        name: name.into(),
        points,
        radius,
        field: Field::new("attractors").index(i),
    };
    let mut spec = base.clone();
    spec.recognition.angles = vec!["p_x".into()];
    let (field, message) = refused(spec);
    assert_eq!(field.as_deref(), Some("recognition.angles[0]"), "{message}");
    assert!(message.contains("momentum"), "{message}");
    let mut spec = base.clone();
    spec.recognition.angles = vec!["x".into(), "theta".into()];
    let (field, message) = refused(spec);
    assert_eq!(field.as_deref(), Some("recognition.angles[1]"), "{message}");
    assert!(
        message.contains("`x`") || message.contains("x"),
        "{message}"
    );
    let mut spec = base.clone();
    spec.attractors = vec![given("a", vec![vec![1.0, 0.0, 0.0]], 0.1, 0)];
    assert_eq!(refused(spec).0.as_deref(), Some("attractors[0].points[0]"));
    let mut spec = base.clone();
    spec.attractors = vec![given("a", vec![vec![1.0, f64::NAN]], 0.1, 0)];
    assert_eq!(
        refused(spec).0.as_deref(),
        Some("attractors[0].points[0][1]")
    );
    let mut spec = base.clone();
    spec.attractors = vec![given("a", Vec::new(), 0.1, 0)];
    assert_eq!(refused(spec).0.as_deref(), Some("attractors[0].points"));
    let mut spec = base.clone();
    spec.attractors = vec![given("a", vec![vec![1.0, 0.0]], -0.1, 0)];
    assert_eq!(refused(spec).0.as_deref(), Some("attractors[0].radius"));
    let mut spec = base.clone();
    spec.attractors = vec![
        given("a", vec![vec![1.0, 0.0]], 0.1, 0),
        given("a", vec![vec![-1.0, 0.0]], 0.1, 1),
    ];
    assert_eq!(refused(spec).0.as_deref(), Some("attractors[1].name"));
    // More than the document can hold.
    let mut spec = base;
    spec.attractors = (0..=basins::MAX_ATTRACTORS)
        .map(|i| given(&format!("a{i}"), vec![vec![i as f64, 0.0]], 0.1, i))
        .collect();
    let (field, message) = refused(spec);
    assert_eq!(field.as_deref(), Some("attractors"), "{message}");
    assert!(message.contains("64"), "{message}");
}

#[test]
fn the_kapitza_pendulum_stands_upright_as_one_attractor_on_either_side_of_pi() {
    // θ″ + νθ′ + (1 + A cos ωt) sin θ = 0, the pivot shaken fast enough ((Aω⁻¹)² = 4 > 2) that
    // θ = π is stable (Kapitza). Cells around π settle onto the upright orbit, whose stroboscopic
    // point is stored at +π on one side and just above −π on the other: as angles, one orbit
    // (compared as plain numbers they were two, 41 and 40 cells).
    let omega: f64 = 20.0;
    let period = std::f64::consts::TAU / omega;
    let pi = std::f64::consts::PI;
    let system = SystemRef::Defined(separable(
        &["theta"],
        "-(1 + A*cos(omega*t))*cos(theta)",
        Some(Damping::Conformal {
            gamma: expr("damping.gamma", "nu/2"),
        }),
        &[("nu", 0.5), ("A", 40.0), ("omega", omega)],
    ));
    let spec = BasinsSpec {
        sweep: sweep(
            system,
            &[Method::new(MethodId::Csv1)],
            period / 64.0,
            200.0 * period,
            vec![
                axis(0, Target::Q0(0), (pi - 0.3, pi + 0.3), 9),
                axis(1, Target::P0(0), (-0.5, 0.5), 9),
            ],
        ),
        exits: Vec::new(),
        recognition: Recognition {
            period: Some(period),
            angles: vec!["theta".into()],
            ..Recognition::default()
        },
        attractors: Vec::new(),
    };
    let doc = run(&spec.prepare(&Limits::default()).unwrap());
    let map = &doc.runs[0];
    assert_eq!(map.attractors.len(), 1, "{:?}", map.attractors);
    let upright = &map.attractors[0];
    assert_eq!((upright.period, upright.cells), (Some(1), 81));
    assert!(
        (upright.points[0][0].abs() - pi).abs() < 1e-4,
        "{:?}",
        upright.points
    );
    assert!(upright.points[0][1].abs() < 1e-4, "{:?}", upright.points);
}

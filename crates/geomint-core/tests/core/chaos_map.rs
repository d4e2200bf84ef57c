//! Chaos maps: sweeps whose runs report indicators, over initial states on an energy surface;
//! in SIMD lanes with the one-cell path's numbers bit for bit; sweeps that collect each cell's
//! section points.

use std::sync::Arc;

use geomint_core::chaos::{ChaosSpec, Indicator, Statistic};
use geomint_core::error::{CoreError, Field};
use geomint_core::methods::{Base, Method, MethodId};
use geomint_core::run::Budget;
use geomint_core::sections::{Crossing, CrossingKind, Direction, SectionSpec, SurfaceSpec};
use geomint_core::simulation::crossings::CrossingColumns;
use geomint_core::simulation::{
    EnergySurface, InitialCoordinates, InputFields, Limits, MethodAt, Sample, SampleSink,
    Simulation, SimulationSpec, Watching,
};
use geomint_core::studies::engine::Local;
use geomint_core::studies::sweep::{
    self, Axis, Scale, SweepDocument, SweepJob, SweepLine, SweepSpec, Target,
};
use geomint_core::system::MechanicalSystem;
use geomint_core::systems::custom::{self, CustomDefinition, Energy, Expression, Mass};
use geomint_core::systems::{
    params, AnySystem, HenonHeiles, ParamValue, SystemInfo, SystemRef, World,
};

/// The Hénon–Heiles (y, p_y) section at x = 0 and energy `e`, n × n cells over [−0.5, 0.5]²,
/// p_x solved from the energy, with `chaos`.
pub(crate) fn section(e: f64, n: usize, t_end: f64, chaos: ChaosSpec) -> SweepSpec {
    let axis = |k: usize, target| Axis {
        target,
        min: -0.5,
        max: 0.5,
        n,
        scale: Scale::Linear,
        field: Field::new("axes").index(k),
    };
    SweepSpec {
        system: "henon_heiles".into(),
        params: Default::default(),
        charts: Vec::new(),
        initial_coordinates: None,
        q0: Some(vec![0.0, 0.0]),
        p0: Some(vec![0.0, 0.0]),
        methods: vec![MethodAt {
            method: Method::triple_jump(Base::VelocityVerlet),
            field: InputFields::default().methods.index(0),
        }],
        h: Some(0.05),
        t_end,
        every: Some(1_000_000),
        energy_reference: None,
        axes: vec![axis(0, Target::Q0(1)), axis(1, Target::P0(1))],
        chaos: Some(chaos),
        energy_surface: Some(EnergySurface {
            energy: e,
            momentum: 0,
            field: Field::new("energy_surface"),
        }),
        section: None,
        digest: "test".into(),
    }
}

#[test]
fn a_megno_map_of_the_henon_heiles_section_marks_the_cells_off_the_surface() {
    let spec = section(
        0.125,
        11,
        200.0,
        ChaosSpec::new(&[Indicator::Megno, Indicator::Fli]),
    );
    let job = spec.prepare(&Limits::default()).expect("a valid sweep");
    let document = sweep::run(&job, &Local, Budget::default(), &|_: SweepLine| true).expect("runs");
    let run = &document.runs[0];
    let chaos = run.chaos.as_ref().expect("chaos columns");
    let sys = HenonHeiles::new(1.0, 0.0);
    let (mut on, mut off, mut chaotic) = (0, 0, 0);
    for cell in 0..document.cells {
        let (y, py) = (
            document.axes[0].values[cell % 11],
            document.axes[1].values[cell / 11],
        );
        // p_x² = 2E − p_y² − y² + 2y³/3 must not be negative.
        let reachable = 2.0 * 0.125 - py * py - y * y + 2.0 * y * y * y / 3.0 >= 0.0;
        assert_eq!(
            run.errors[cell].is_none(),
            reachable,
            "cell {cell}: {:?}",
            run.errors[cell]
        );
        if reachable {
            on += 1;
            let megno = chaos.megno_mean[cell].expect("⟨Y⟩");
            assert!(megno.is_finite() && chaos.fli[cell].unwrap().is_finite());
            chaotic += usize::from(megno > 4.0);
            assert_eq!(chaos.sali[cell], None);
        } else {
            off += 1;
            assert!(run.errors[cell]
                .as_deref()
                .unwrap()
                .contains("energy_surface.energy"));
            assert_eq!(chaos.megno_mean[cell], None);
        }
    }
    // The solved start lies on the surface: at the centre (y, p_y) = (0, 0), p_x = √(2E) = ½.
    let mut spec = SimulationSpec {
        q0: Some(vec![0.0, 0.0]),
        p0: Some(vec![0.0, 0.0]),
        ..SimulationSpec::new(
            "henon_heiles",
            &[Method::triple_jump(Base::VelocityVerlet)],
            0.05,
            1.0,
        )
    };
    let surface = EnergySurface {
        energy: 0.125,
        momentum: 0,
        field: Field::new("energy_surface"),
    };
    let info = geomint_core::systems::info("henon_heiles", &Field::new("system")).unwrap();
    surface.apply(&mut spec, &info).unwrap();
    assert_eq!(spec.p0, Some(vec![0.5, 0.0]));
    let z = geomint_core::system::State::from_slices(nalgebra::U2, &[0.0, 0.3], &[0.0, 0.1]);
    let mut z1 = z.clone();
    surface.solve(&sys, &mut z1).unwrap();
    assert!((sys.energy(&z1.q, &z1.p) - 0.125).abs() < 1e-15 && z1.p[0] > 0.0);
    eprintln!("E = 1/8, 11 × 11: {on} cells on the surface ({chaotic} with ⟨Y⟩ > 4 at T = 200), {off} off it");
    assert!(on > 50 && off > 20 && chaotic > 0 && chaotic < on);
}

#[test]
fn a_threshold_stops_cells_which_keep_their_values_and_stop_time() {
    let chaos = ChaosSpec {
        stop_when: vec![(Statistic::MegnoMean, 6.0)],
        ..ChaosSpec::new(&[Indicator::Megno])
    };
    let spec = section(1.0 / 6.0, 5, 400.0, chaos);
    let job = spec.prepare(&Limits::default()).expect("a valid sweep");
    let document = sweep::run(&job, &Local, Budget::default(), &|_: SweepLine| true).expect("runs");
    let run = &document.runs[0];
    let chaos = run.chaos.as_ref().unwrap();
    let mut stopped = 0;
    for cell in 0..document.cells {
        if let Some(t) = chaos.stopped_at[cell] {
            stopped += 1;
            assert!(chaos.megno_mean[cell].unwrap() >= 6.0);
            assert!(t <= 400.0);
            assert_eq!(run.steps[cell], (t / 0.05).round() as u64);
        } else if run.errors[cell].is_none() {
            assert!(chaos.megno_mean[cell].unwrap() < 6.0 || run.steps[cell] == 8000);
        }
    }
    assert!(stopped > 0, "no cell stopped");
}

#[test]
fn a_surface_no_cell_reaches_is_refused_with_the_least_energy_of_the_grid() {
    let spec = section(-0.01, 5, 10.0, ChaosSpec::new(&[Indicator::Megno]));
    let error = spec.prepare(&Limits::default()).unwrap_err();
    let CoreError::NoEnergySolution {
        ref field, lowest, ..
    } = error
    else {
        panic!("{error}")
    };
    assert_eq!(field.as_str(), "energy_surface.energy");
    // The least H over the grid is V at y = 0, p_y = 0 (p_x = 0): zero, above E = −0.01.
    assert_eq!(lowest, 0.0);
    // An axis over the momentum solved for.
    let mut twice = section(0.125, 5, 10.0, ChaosSpec::new(&[Indicator::Megno]));
    twice.axes[1].target = Target::P0(0);
    let error = twice.prepare(&Limits::default()).unwrap_err();
    assert_eq!(error.field().unwrap().as_str(), "energy_surface.solve_for");
}

pub(crate) fn run(job: &SweepJob) -> SweepDocument {
    sweep::run(job, &Local, Budget::default(), &|_: SweepLine| true).expect("runs")
}

/// The document as text without its wall time: the shortest decimals that read back to the
/// same bits, −0 included.
pub(crate) fn numbers(doc: &SweepDocument) -> String {
    let mut v = serde_json::to_value(doc).unwrap();
    v.as_object_mut().unwrap().remove("wall_ms");
    v.to_string()
}

pub(crate) fn methods(methods: &[Method]) -> Vec<MethodAt> {
    methods
        .iter()
        .enumerate()
        .map(|(i, m)| MethodAt {
            method: m.clone(),
            field: InputFields::default().methods.index(i),
        })
        .collect()
}

#[test]
fn chaos_maps_in_lanes_give_the_one_cell_paths_numbers_bit_for_bit() {
    let all = [
        Indicator::Lyapunov,
        Indicator::Megno,
        Indicator::Fli,
        Indicator::Sali,
        Indicator::Gali,
    ];
    // Every indicator with four vectors and an odd grid; above the escape energy 1/6, where
    // orbits leave and blow up; thresholds met on the grid of updates; several methods in one
    // sweep; one vector, whose sums the lanes keep themselves. 9 × 9 and 7 × 7 cells: the last
    // group of sixteen holds one cell.
    let mut specs = vec![SweepSpec {
        every: Some(333),
        ..section(
            0.125,
            9,
            100.0,
            ChaosSpec {
                deviations: Some(4),
                qr_every: Some(7),
                ..ChaosSpec::new(&all)
            },
        )
    }];
    specs.push(SweepSpec {
        methods: methods(&[
            Method::new(MethodId::VelocityVerlet),
            Method::new(MethodId::SymplecticEuler),
            Method::new(MethodId::BlanesMoanSrkn11),
            Method::new(MethodId::PositionVerlet),
        ]),
        every: Some(97),
        ..section(
            0.4,
            7,
            60.0,
            ChaosSpec {
                deviations: Some(1),
                ..ChaosSpec::new(&[Indicator::Lyapunov, Indicator::Megno, Indicator::Fli])
            },
        )
    });
    specs.push(section(
        1.0 / 6.0,
        7,
        300.0,
        ChaosSpec {
            deviations: Some(2),
            qr_every: Some(5),
            stop_when: vec![(Statistic::MegnoMean, 4.0), (Statistic::Sali, 1e-6)],
            ..ChaosSpec::new(&[Indicator::Megno, Indicator::Sali])
        },
    ));
    // The planar elastic pendulum released at rest, in Cartesian coordinates (in lanes) and in
    // polar ones (one by one in the same groups), as the `elastic_pendulum_chaos` preset.
    let axis = |k: usize, min: f64, max: f64| Axis {
        target: Target::Q0(k),
        min,
        max,
        n: 5,
        scale: Scale::Linear,
        field: Field::new("axes").index(k),
    };
    specs.push(SweepSpec {
        system: "elastic_pendulum_2d".into(),
        charts: ["cartesian", "polar"]
            .iter()
            .enumerate()
            .map(|(i, c)| (Some(c.to_string()), Field::new("charts").index(i)))
            .collect(),
        initial_coordinates: Some(InitialCoordinates::Cartesian),
        methods: methods(&[Method::new(MethodId::SymplecticEuler)]),
        h: Some(0.01),
        every: Some(250),
        axes: vec![axis(0, -1.5, 1.5), axis(1, -1.5, 0.0)],
        energy_surface: None,
        ..section(
            0.125,
            5,
            20.0,
            ChaosSpec {
                deviations: Some(4),
                ..ChaosSpec::new(&[Indicator::Lyapunov, Indicator::Megno])
            },
        )
    });
    // The undamped elastic 3-D pendulum (paper 000's), over a plane of starts, every vector.
    let start_axis = |k: usize, target, min: f64, max: f64| Axis {
        target,
        min,
        max,
        n: 5,
        scale: Scale::Linear,
        field: Field::new("axes").index(k),
    };
    specs.push(SweepSpec {
        system: "elastic_pendulum_3d".into(),
        params: [("epsilon".to_string(), ParamValue::Number(0.0))].into(),
        q0: Some(vec![0.0, 1.55884573, -0.6]),
        p0: Some(vec![1.34164079, 0.0, 0.0]),
        methods: methods(&[
            Method::new(MethodId::VelocityVerlet),
            Method::triple_jump(Base::VelocityVerlet),
        ]),
        h: Some(0.02),
        every: Some(150),
        axes: vec![
            start_axis(0, Target::Q0(0), -0.5, 0.5),
            start_axis(1, Target::P0(1), -1.0, 1.0),
        ],
        energy_surface: None,
        ..section(
            0.125,
            5,
            20.0,
            ChaosSpec {
                deviations: Some(6),
                ..ChaosSpec::new(&[Indicator::Lyapunov, Indicator::Megno, Indicator::Gali])
            },
        )
    });
    // A saddle, whose vector the range guard rescales between updates and samples that fall
    // between updates: the tracker must see those powers of two at the samples and the lanes'
    // sums at the next update.
    specs.push(SweepSpec {
        system: SystemRef::Defined(crate::sections::separable(&["x"], "-625*x^2/2", None, &[])),
        q0: Some(vec![0.0]),
        p0: Some(vec![0.0]),
        methods: methods(&[Method::new(MethodId::VelocityVerlet)]),
        h: Some(0.01),
        every: Some(300),
        axes: vec![
            start_axis(0, Target::Q0(0), -1.0, 1.0),
            start_axis(1, Target::P0(0), -1.0, 1.0),
        ],
        energy_surface: None,
        ..section(
            0.125,
            5,
            25.0,
            ChaosSpec {
                deviations: Some(1),
                qr_every: Some(1000),
                ..ChaosSpec::new(&[Indicator::Lyapunov, Indicator::Megno, Indicator::Fli])
            },
        )
    });
    // Hénon–Heiles typed in, with a full mass matrix and with a scalar one: the lanes call its
    // compiled functions.
    specs.push(SweepSpec {
        system: SystemRef::Defined(typed_in_henon_heiles(true)),
        ..section(
            0.125,
            7,
            60.0,
            ChaosSpec {
                deviations: Some(2),
                ..ChaosSpec::new(&[Indicator::Lyapunov, Indicator::Megno, Indicator::Sali])
            },
        )
    });
    specs.push(SweepSpec {
        system: SystemRef::Defined(typed_in_henon_heiles(false)),
        every: Some(97),
        ..section(0.4, 5, 60.0, ChaosSpec::new(&[Indicator::Megno]))
    });
    // (failed, diverged, stopped by a threshold, finished)
    let mut outcomes = [0usize; 4];
    for spec in specs {
        let job = spec.prepare(&Limits::default()).expect("a valid sweep");
        assert!(job.runs_in_lanes(), "{:?}", spec.methods);
        let one_by_one = job.clone().cell_by_cell();
        assert!(!one_by_one.runs_in_lanes());
        let doc = run(&job);
        assert_eq!(numbers(&doc), numbers(&run(&one_by_one)));
        for r in &doc.runs {
            let chaos = r.chaos.as_ref().expect("chaos columns");
            for c in 0..doc.cells {
                let k = if r.errors[c].is_some() {
                    0
                } else if r.diverged_at[c].is_some() {
                    1
                } else if chaos.stopped_at[c].is_some() {
                    2
                } else {
                    3
                };
                outcomes[k] += 1;
            }
        }
    }
    println!("outcomes (failed, diverged, stopped, finished): {outcomes:?}");
    assert!(outcomes.iter().all(|&n| n > 0), "outcomes {outcomes:?}");
}

/// Hénon–Heiles with λ a parameter, typed in, with the mass matrix [[1.5, 0.25], [0.25, 1]]
/// (`full`) or 1.5 I.
pub(crate) fn typed_in_henon_heiles(full: bool) -> Arc<SystemInfo> {
    let mass = if full {
        Mass::Matrix(vec![
            vec![expr("mass", "1.5"), expr("mass", "0.25")],
            vec![expr("mass", "0.25"), expr("mass", "1")],
        ])
    } else {
        Mass::Scalar(expr("mass", "1.5"))
    };
    typed_in_xy(
        mass,
        "(x^2 + y^2)/2 + lambda*(x^2*y - y^3/3)",
        vec![("lambda".into(), 1.0)],
    )
}

/// A member `name` of a definition.
pub(crate) fn expr(name: &str, text: &str) -> Expression {
    Expression {
        text: text.to_string(),
        field: Field::new("system").key(name),
    }
}

/// An undamped separable system in x and y, typed in.
pub(crate) fn typed_in_xy(
    mass: Mass,
    potential: &str,
    parameters: Vec<(String, f64)>,
) -> Arc<SystemInfo> {
    let definition = CustomDefinition {
        field: Field::new("system"),
        name: None,
        coordinates: vec!["x".into(), "y".into()],
        momenta: None,
        energy: Energy::Separable {
            mass,
            potential: expr("potential", potential),
        },
        damping: None,
        parameters,
        invariants: Vec::new(),
        positions: None,
        q0: None,
        p0: None,
    };
    custom::define(definition, "test").expect("a valid definition")
}

/// The cells of a sweep over initial states share one compilation of a typed-in system: the
/// same parameter values give the same compiled functions, others their own.
#[test]
fn a_typed_in_system_and_its_drawing_are_compiled_once_for_the_same_parameter_values() {
    let info = typed_in_henon_heiles(false);
    let chart = info.chart(None, &Field::new("chart")).expect("the chart");
    let field = Field::new("params");
    let params = |lambda: f64| {
        let given = [("lambda".to_string(), ParamValue::Number(lambda))].into();
        params::resolve(&info, &given, &field).expect("valid parameters")
    };
    let with = |lambda: f64| match info.build(&params(lambda), chart, 0.05).expect("compiles") {
        AnySystem::Custom2(sys) => sys,
        _ => panic!("two degrees of freedom"),
    };
    let (a, b, c) = (with(1.0), with(1.0), with(0.5));
    assert!(std::ptr::eq(a.model(), b.model()));
    assert!(!std::ptr::eq(a.model(), c.model()));
    let q = nalgebra::Vector2::new(0.3, -0.2);
    let grad = |sys: &geomint_core::systems::CustomSystem<nalgebra::U2>| {
        let mut g = nalgebra::Vector2::zeros();
        sys.grad_potential(&q, &mut g);
        g
    };
    // ∇V = (x + 2λxy, y + λ(x² − y²)).
    assert!((grad(&b) - nalgebra::Vector2::new(0.18, -0.15)).amax() < 1e-15);
    assert!((grad(&c) - nalgebra::Vector2::new(0.24, -0.175)).amax() < 1e-15);
    // The drawing of its bodies, which every run prepares, is compiled once too.
    let drawing = |lambda: f64| match info.world(&params(lambda)).expect("compiles") {
        World::Drawn(drawing) => drawing,
        other => panic!("a typed-in system is drawn: {other:?}"),
    };
    let (a, b, c) = (drawing(1.0), drawing(1.0), drawing(0.5));
    assert!(Arc::ptr_eq(&a, &b));
    assert!(!Arc::ptr_eq(&a, &c));
}

#[test]
fn chaos_maps_the_lanes_cannot_take_run_cell_by_cell() {
    let megno = || ChaosSpec::new(&[Indicator::Megno]);
    // Damped (the θ-kicks are no longer kicks), and a method that is not a splitting.
    let mut damped = section(0.125, 3, 10.0, megno());
    damped
        .params
        .insert("gamma".into(), ParamValue::Number(0.01));
    let rk4 = SweepSpec {
        methods: methods(&[Method::new(MethodId::Rk4)]),
        ..section(0.125, 3, 10.0, megno())
    };
    for spec in [damped, rk4] {
        let job = spec.prepare(&Limits::default()).expect("a valid sweep");
        assert!(!job.runs_in_lanes(), "{:?}", spec.methods);
        assert!(run(&job).runs[0].chaos.as_ref().unwrap().megno_mean[4].is_some());
    }
}

#[test]
fn a_chaos_map_in_lanes_stopped_by_its_budget_leaves_its_cells_unfinished() {
    let job = section(0.125, 5, 100.0, ChaosSpec::new(&[Indicator::Megno]))
        .prepare(&Limits::default())
        .expect("a valid sweep");
    assert!(job.runs_in_lanes());
    let past = Budget {
        cancel: None,
        deadline: Some(std::time::Instant::now()),
    };
    let doc = sweep::run(&job, &Local, past, &|_: SweepLine| true).expect("a partial map");
    // Every cell on the surface is unfinished; those off it fail before any step.
    let errors = &doc.runs[0].errors;
    assert!(!doc.unfinished_cells.is_empty());
    for &cell in &doc.unfinished_cells {
        assert!(errors[cell].as_deref().unwrap().contains("time limit"));
    }
}

/// The crossings of one run, as a sink receives them.
#[derive(Default)]
struct Points(CrossingColumns);

impl SampleSink for Points {
    fn on_sample(&mut self, _: &Sample<'_>) {}
    fn on_crossing(&mut self, c: &Crossing<'_>) {
        if c.kind == CrossingKind::Section {
            self.0.push(c);
        }
    }
}

#[test]
fn a_sweep_collects_each_cells_section_points_as_its_own_run_would() {
    let section_y = |max_points| SectionSpec {
        surface: SurfaceSpec::Where {
            text: "y".into(),
            direction: Direction::Up,
        },
        max_points,
        field: Field::new("section"),
    };
    // Bound orbits: H < 1/6 over the whole grid.
    let axis = |k: usize, target| Axis {
        target,
        min: -0.2,
        max: 0.2,
        n: 3,
        scale: Scale::Linear,
        field: Field::new("axes").index(k),
    };
    let spec = SweepSpec {
        p0: Some(vec![0.3, 0.0]),
        axes: vec![axis(0, Target::Q0(1)), axis(1, Target::P0(1))],
        energy_surface: None,
        chaos: None,
        every: Some(100),
        section: Some(section_y(6)),
        ..section(0.125, 3, 60.0, ChaosSpec::new(&[Indicator::Megno]))
    };
    let job = spec.prepare(&Limits::default()).expect("a valid sweep");
    assert!(!job.runs_in_lanes(), "the lanes watch no section");
    let doc = run(&job);
    let sections = doc.runs[0].sections.as_ref().expect("sections");
    let (mut truncated, mut points) = (0, 0);
    for cell in 0..doc.cells {
        let (y, py) = (doc.axes[0].values[cell % 3], doc.axes[1].values[cell / 3]);
        let mut alone = SimulationSpec::new(
            SystemRef::Id("henon_heiles".into()),
            &[Method::triple_jump(Base::VelocityVerlet)],
            0.05,
            60.0,
        );
        alone.q0 = Some(vec![0.0, y]);
        alone.p0 = Some(vec![0.3, py]);
        alone.every = Some(100);
        let watching = Watching {
            section: Some(section_y(6)),
            ..Watching::default()
        };
        let sim = Simulation::prepare(&alone, &Limits::default())
            .and_then(|s| s.watching(&watching))
            .expect("the cell's run alone");
        let mut own = Points::default();
        sim.run_method(0, None, Budget::default(), &mut own)
            .expect("runs");
        let cell_section = sections[cell].as_ref().expect("every cell starts");
        // Bit for bit, as text: the shortest decimals that read back to the same bits.
        assert_eq!(
            serde_json::to_string(&cell_section.points).unwrap(),
            serde_json::to_string(&own.0).unwrap(),
            "cell {cell}"
        );
        assert!(own.0.len() <= 6);
        for (q, p) in own.0.q.iter().zip(&own.0.p) {
            assert!(q[1].abs() <= 1e-13 && p[1] > 0.0);
        }
        truncated += usize::from(cell_section.truncated);
        points += own.0.len();
    }
    assert!(
        truncated > 0 && points > 0,
        "{truncated} truncated, {points} points"
    );

    // The points of every cell count against the sample limit.
    let limits = Limits {
        max_samples: 9 * 6 - 1,
        ..Limits::default()
    };
    let e = spec.prepare(&limits).expect_err("too many points");
    assert_eq!(e.field().map(Field::as_str), Some("section.max_points"));
}

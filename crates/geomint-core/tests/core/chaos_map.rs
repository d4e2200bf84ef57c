//! Chaos maps: sweeps whose runs report indicators, over initial states on an energy surface.

use geomint_core::chaos::{ChaosSpec, Indicator, Statistic};
use geomint_core::error::{CoreError, Field};
use geomint_core::methods::{Base, Method};
use geomint_core::run::Budget;
use geomint_core::simulation::{EnergySurface, InputFields, Limits, MethodAt, SimulationSpec};
use geomint_core::studies::engine::Local;
use geomint_core::studies::sweep::{self, Axis, Scale, SweepLine, SweepSpec, Target};
use geomint_core::system::MechanicalSystem;
use geomint_core::systems::HenonHeiles;

/// The Hénon–Heiles (y, p_y) section at x = 0 and energy `e`, n × n cells over [−0.5, 0.5]²,
/// p_x solved from the energy, with `chaos`.
fn section(e: f64, n: usize, t_end: f64, chaos: ChaosSpec) -> SweepSpec {
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
    let sys = HenonHeiles {
        lambda: 1.0,
        gamma: 0.0,
    };
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

//! Plain sweeps (no indicators) over initial states in SIMD lanes: every number of the document
//! is the one-cell path's, bit for bit, with the one-run stepper's fused stretches between
//! samples, runs that blow up inside a stretch (taken again step by step), and runs the lanes
//! give back to the one-cell path.

use geomint_core::chaos::ChaosSpec;
use geomint_core::error::Field;
use geomint_core::methods::{Base, Method, MethodId};
use geomint_core::simulation::Limits;
use geomint_core::studies::sweep::{Axis, Scale, SweepSpec, Target};
use geomint_core::systems::custom::Mass;
use geomint_core::systems::SystemRef;

use crate::chaos_map::{expr, methods, numbers, run, section, typed_in_henon_heiles, typed_in_xy};

/// The Hénon–Heiles (y, p_y) section at x = 0 and energy `e` (n × n cells), without indicators.
fn plain(e: f64, n: usize, t_end: f64) -> SweepSpec {
    SweepSpec {
        chaos: None,
        ..section(e, n, t_end, ChaosSpec::new(&[]))
    }
}

/// A two-dimensional oscillator, typed in: p₀ on the grid up to 10³⁰⁸, where the state's
/// components stay finite while their sum overflows.
fn huge_oscillator() -> SweepSpec {
    let axis = |k: usize| Axis {
        target: Target::P0(k),
        min: 0.25e308,
        max: 1e308,
        n: 4,
        scale: Scale::Linear,
        field: Field::new("axes").index(k),
    };
    SweepSpec {
        system: SystemRef::Defined(typed_in_xy(
            Mass::Scalar(expr("mass", "1")),
            "(x^2 + y^2)/2",
            Vec::new(),
        )),
        energy_surface: None,
        axes: vec![axis(0), axis(1)],
        methods: methods(&[Method::triple_jump(Base::PositionVerlet)]),
        every: Some(50),
        ..plain(0.1, 4, 20.0)
    }
}

#[test]
fn plain_sweeps_in_lanes_give_the_one_cell_paths_numbers_bit_for_bit() {
    let specs = vec![
        // A composition whose steps end and begin with a kick (fused between samples); odd
        // sampling, and the last group of sixteen holds one cell.
        SweepSpec {
            every: Some(333),
            ..plain(0.125, 9, 100.0)
        },
        // Above the escape energy, where orbits leave and blow up inside a fused stretch; seams
        // of drifts (position Verlet), of kicks, and none (symplectic Euler, velocity Verlet's
        // θ-kicks).
        SweepSpec {
            methods: methods(&[
                Method::new(MethodId::VelocityVerlet),
                Method::new(MethodId::SymplecticEuler),
                Method::new(MethodId::BlanesMoanSrkn11),
                Method::new(MethodId::PositionVerlet),
                Method::triple_jump(Base::PositionVerlet),
            ]),
            every: Some(97),
            ..plain(0.4, 7, 200.0)
        },
        // Every step sampled (a sweep's default), with stretches of one step.
        SweepSpec {
            every: None,
            ..plain(1.0 / 6.0, 7, 30.0)
        },
        // Typed in, with a full mass matrix and with a scalar one: the lanes call its compiled
        // functions.
        SweepSpec {
            system: SystemRef::Defined(typed_in_henon_heiles(true)),
            every: Some(1000),
            ..plain(0.125, 7, 120.0)
        },
        SweepSpec {
            system: SystemRef::Defined(typed_in_henon_heiles(false)),
            methods: methods(&[Method::triple_jump(Base::VelocityVerlet)]),
            every: Some(97),
            ..plain(0.4, 5, 200.0)
        },
        huge_oscillator(),
    ];
    // (failed, diverged, finished)
    let mut outcomes = [0usize; 3];
    for spec in specs {
        let job = spec.prepare(&Limits::default()).expect("a valid sweep");
        assert!(job.runs_in_lanes(), "{:?}", spec.methods);
        let one_by_one = job.clone().cell_by_cell();
        assert!(!one_by_one.runs_in_lanes());
        let doc = run(&job);
        assert_eq!(
            numbers(&doc),
            numbers(&run(&one_by_one)),
            "{:?}",
            spec.methods
        );
        for r in &doc.runs {
            for c in 0..doc.cells {
                let k = if r.errors[c].is_some() {
                    0
                } else if r.diverged_at[c].is_some() {
                    1
                } else {
                    2
                };
                outcomes[k] += 1;
            }
        }
    }
    println!("outcomes (failed, diverged, finished): {outcomes:?}");
    assert!(outcomes.iter().all(|&n| n > 0), "outcomes {outcomes:?}");
}

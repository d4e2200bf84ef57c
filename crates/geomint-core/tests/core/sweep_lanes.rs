//! Plain sweeps (no indicators) over initial states in SIMD lanes: every number of the document
//! is the one-cell path's, bit for bit, with the one-run stepper's fused stretches between
//! samples, runs that blow up inside a stretch (taken again step by step), runs the lanes
//! give back to the one-cell path, and a driven system's runs (its clock one more coordinate).

use std::sync::Arc;

use geomint_core::chaos::ChaosSpec;
use geomint_core::error::Field;
use geomint_core::methods::composition::Scheme;
use geomint_core::methods::{Base, Method, MethodId};
use geomint_core::simulation::{EnergyReference, Limits};
use geomint_core::studies::sweep::{Axis, Scale, SweepSpec, Target};
use geomint_core::systems::custom::{self, CustomDefinition, Damping, Energy, Mass};
use geomint_core::systems::{ParamValue, SystemInfo, SystemRef};

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
        // Driven and damped, a clock among the coordinates: the forced Duffing oscillator, typed
        // in, over (x₀, p₀), with csv1 and modin_3s.
        SweepSpec {
            system: SystemRef::Defined(crate::sections::duffing(0.5, 0.3, 1.2)),
            q0: None,
            p0: None,
            energy_surface: None,
            energy_reference: Some(EnergyReference::Initial),
            axes: vec![
                Axis {
                    target: Target::Q0(0),
                    min: -1.5,
                    max: 1.5,
                    n: 5,
                    scale: Scale::Linear,
                    field: Field::new("axes").index(0),
                },
                Axis {
                    target: Target::P0(0),
                    min: -1.0,
                    max: 1.0,
                    n: 4,
                    scale: Scale::Linear,
                    field: Field::new("axes").index(1),
                },
            ],
            methods: methods(&[Method::new(MethodId::Csv1), Method::new(MethodId::Modin3s)]),
            every: Some(50),
            ..plain(0.125, 4, 60.0)
        },
        // The same over its forcing and damping: one system per lane.
        SweepSpec {
            system: SystemRef::Defined(crate::sections::duffing(0.5, 0.3, 1.2)),
            q0: Some(vec![0.5]),
            p0: Some(vec![0.0]),
            energy_surface: None,
            energy_reference: Some(EnergyReference::Initial),
            axes: vec![
                Axis {
                    target: Target::Param("A".into()),
                    min: 0.0,
                    max: 0.4,
                    n: 5,
                    scale: Scale::Linear,
                    field: Field::new("axes").index(0),
                },
                Axis {
                    target: Target::Param("delta".into()),
                    min: 0.1,
                    max: 0.5,
                    n: 4,
                    scale: Scale::Linear,
                    field: Field::new("axes").index(1),
                },
            ],
            methods: methods(&[Method::new(MethodId::Csv1)]),
            every: Some(50),
            ..plain(0.125, 4, 60.0)
        },
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

/// A plain sweep of the built-in `system` over `axes` (each `(target, min, max, n)`), from
/// (`q0`, `p0`).
fn over(
    system: &str,
    params: &[(&str, f64)],
    (q0, p0): (&[f64], &[f64]),
    axes: &[(Target, f64, f64, usize)],
    t_end: f64,
) -> SweepSpec {
    SweepSpec {
        system: system.into(),
        params: params
            .iter()
            .map(|&(name, v)| (name.to_string(), ParamValue::Number(v)))
            .collect(),
        q0: Some(q0.to_vec()),
        p0: Some(p0.to_vec()),
        energy_surface: None,
        // A step axis gives the step.
        h: (!axes.iter().any(|a| a.0 == Target::Step)).then_some(0.05),
        axes: axes
            .iter()
            .enumerate()
            .map(|(k, (target, min, max, n))| Axis {
                target: target.clone(),
                min: *min,
                max: *max,
                n: *n,
                scale: Scale::Linear,
                field: Field::new("axes").index(k),
            })
            .collect(),
        ..plain(0.125, 1, t_end)
    }
}

/// A damped pendulum of one degree of freedom, typed in, with a conformal (`gamma`) or a
/// position-dependent Rayleigh damping.
fn typed_in_damped_pendulum(conformal: bool) -> Arc<SystemInfo> {
    let damping = if conformal {
        Damping::Conformal {
            gamma: expr("damping", "gamma"),
        }
    } else {
        Damping::Rayleigh {
            epsilon: expr("damping", "2*gamma"),
            matrix: vec![vec![expr("damping", "1 + theta^2/2")]],
        }
    };
    let definition = CustomDefinition {
        field: Field::new("system"),
        name: None,
        coordinates: vec!["theta".into()],
        momenta: None,
        energy: Energy::Separable {
            mass: Mass::Scalar(expr("mass", "m")),
            potential: expr("potential", "-m*g*cos(theta)"),
        },
        damping: Some(damping),
        parameters: vec![("m".into(), 1.0), ("g".into(), 1.0), ("gamma".into(), 0.1)],
        invariants: Vec::new(),
        positions: None,
        q0: None,
        p0: None,
    };
    custom::define(definition, "test").expect("a valid definition")
}

/// Sweeps over parameters and the step of damped systems: one system per lane, the exact
/// damping flows in lanes, groups of cells that share the step; every number of the document
/// is the one-cell path's.
#[test]
fn sweeps_over_parameters_and_the_step_in_lanes_give_the_one_cell_paths_numbers_bit_for_bit() {
    // Not in lanes: a Runge–Kutta method, θ-kicks with damping, modin_2s's kick-and-damp (cell
    // by cell inside the lane groups).
    let elsewhere = [
        Method::new(MethodId::Heun),
        Method::new(MethodId::VelocityVerlet),
        Method::new(MethodId::Modin2s),
    ];
    let projector = [
        Method::new(MethodId::Modin3s),
        Method::composition(Scheme::of(MethodId::KahanLi8).unwrap(), Base::Modin3s),
    ];
    let conformal = [Method::new(MethodId::Csv1), Method::triple_jump(Base::Csv1)];
    let damped = methods(&[&projector[..], &conformal, &elsewhere].concat());
    let projector = methods(&[&projector[..], &elsewhere].concat());
    let specs = vec![
        // The oscillator over (h, γ), the step varying fastest; under-, critically and
        // over-damped, and steps past the stability limit h = 2 that diverge.
        SweepSpec {
            methods: damped.clone(),
            every: Some(7),
            ..over(
                "harmonic_oscillator",
                &[],
                (&[1.0], &[0.0]),
                &[
                    (Target::Step, 0.1, 2.9, 5),
                    (Target::Param("gamma".into()), 0.0, 1.5, 7),
                ],
                400.0,
            )
        },
        // The same over (γ, h), the step varying slowest.
        SweepSpec {
            methods: damped.clone(),
            every: Some(10),
            ..over(
                "harmonic_oscillator",
                &[],
                (&[1.0], &[0.5]),
                &[
                    (Target::Param("gamma".into()), 0.0, 0.5, 9),
                    (Target::Step, 0.05, 0.25, 3),
                ],
                100.0,
            )
        },
        // The 3-D elastic pendulum with damping along the spring (a projector), over its
        // stiffness and its damping.
        // Measured against H₀ (the default for a damped system without an exact solution is a
        // reference run, which the lanes leave to the one-cell path).
        SweepSpec {
            methods: projector.clone(),
            energy_reference: Some(EnergyReference::Initial),
            every: Some(25),
            ..over(
                "elastic_pendulum_3d",
                &[],
                (&[0.3, 0.1, -1.2], &[0.0, 0.4, 0.1]),
                &[
                    (Target::Param("k".into()), 0.5, 40.0, 6),
                    (Target::Param("epsilon".into()), 0.0, 0.5, 4),
                ],
                60.0,
            )
        },
        // Damped, over the initial state only: one system for all lanes.
        SweepSpec {
            methods: projector.clone(),
            energy_reference: Some(EnergyReference::Initial),
            every: Some(13),
            ..over(
                "elastic_pendulum_3d",
                &[("epsilon", 0.05)],
                (&[0.3, 0.1, -1.2], &[0.0, 0.4, 0.1]),
                &[(Target::Q0(0), -0.5, 0.5, 5), (Target::P0(2), -1.0, 1.0, 5)],
                60.0,
            )
        },
        // Typed in, with conformal and position-dependent damping, over γ and the mass.
        SweepSpec {
            system: SystemRef::Defined(typed_in_damped_pendulum(true)),
            methods: damped.clone(),
            energy_reference: Some(EnergyReference::Initial),
            every: Some(9),
            ..over(
                "",
                &[],
                (&[2.0], &[0.0]),
                &[
                    (Target::Param("gamma".into()), 0.0, 0.4, 5),
                    (Target::Param("m".into()), 0.5, 2.0, 4),
                ],
                50.0,
            )
        },
        SweepSpec {
            system: SystemRef::Defined(typed_in_damped_pendulum(false)),
            methods: projector,
            energy_reference: Some(EnergyReference::Initial),
            every: Some(9),
            ..over(
                "",
                &[],
                (&[2.0], &[0.0]),
                &[
                    (Target::Param("gamma".into()), 0.0, 0.4, 5),
                    (Target::Step, 0.05, 0.2, 3),
                ],
                50.0,
            )
        },
    ];
    // (diverged, finished)
    let mut outcomes = [0usize; 2];
    for spec in specs {
        let job = spec.prepare(&Limits::default()).expect("a valid sweep");
        assert!(job.runs_in_lanes(), "{:?}", spec.system);
        let doc = run(&job);
        assert_eq!(
            numbers(&doc),
            numbers(&run(&job.clone().cell_by_cell())),
            "{:?}",
            spec.system
        );
        for r in &doc.runs {
            for c in 0..doc.cells {
                assert!(r.errors[c].is_none(), "{:?}", r.errors[c]);
                outcomes[usize::from(r.diverged_at[c].is_none())] += 1;
            }
        }
    }
    println!("outcomes (diverged, finished): {outcomes:?}");
    assert!(outcomes.iter().all(|&n| n > 0), "outcomes {outcomes:?}");
}

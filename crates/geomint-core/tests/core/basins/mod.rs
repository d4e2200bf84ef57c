//! Basin maps: the damped double well, decided by the energy argument and checked cell by cell
//! against the adaptive reference; Hénon–Heiles above its escape energy with three exits; the
//! forced damped Duffing oscillator's periodic attractors on its stroboscopic map; the forced
//! damped pendulum's rotating orbits, its angle taken modulo 2π; attractors the request gives. Each map is
//! run with a fixed-step method and with the adaptive DOP853 reference at 1e-12 as a second
//! run of the same map, and the labels compared.

use geomint_core::error::Field;
use geomint_core::methods::{Method, MethodId};
use geomint_core::run::Budget;
use geomint_core::sections::Direction;
use geomint_core::simulation::{EnergySurface, Limits};
use geomint_core::studies::basins::metrics::BOX;
use geomint_core::studies::basins::{
    self, AttractorKind, BasinRun, BasinsDocument, BasinsJob, BasinsLine, BasinsSpec, ExitSpec,
    GivenAttractor, Recognition,
};
use geomint_core::studies::engine::{Local, Study};
use geomint_core::studies::parts::{self, Shard};
use geomint_core::studies::sweep::{Axis, Scale, SweepSpec, Target};
use geomint_core::studies::StudySpec;
use geomint_core::systems::custom::Damping;
use geomint_core::systems::SystemRef;

use crate::chaos_map::{expr, methods};
use crate::sections::separable;

/// The reference run's tolerance.
pub(super) const REFERENCE: f64 = 1e-12;

pub(super) fn axis(k: usize, target: Target, (min, max): (f64, f64), n: usize) -> Axis {
    Axis {
        target,
        min,
        max,
        n,
        scale: Scale::Linear,
        field: Field::new("axes").index(k),
    }
}

pub(super) fn sweep(
    system: SystemRef,
    methods_: &[Method],
    h: f64,
    t_end: f64,
    axes: Vec<Axis>,
) -> SweepSpec {
    SweepSpec {
        system,
        params: Default::default(),
        charts: Vec::new(),
        initial_coordinates: None,
        q0: None,
        p0: None,
        methods: methods(methods_),
        h: Some(h),
        t_end,
        every: None,
        energy_reference: None,
        axes,
        chaos: None,
        energy_surface: None,
        section: None,
        digest: "test".into(),
    }
}

/// x″ + δx′ − x + x³ = 0: H = p²/2 − x²/2 + x⁴/4 with conformal damping γ = δ/2.
fn double_well(delta: f64) -> SystemRef {
    SystemRef::Defined(separable(
        &["x"],
        "-x^2/2 + x^4/4",
        Some(Damping::Conformal {
            gamma: expr("damping.gamma", "delta/2"),
        }),
        &[("delta", delta)],
    ))
}

pub(super) fn run(job: &BasinsJob) -> BasinsDocument {
    basins::run(job, &Local, Budget::default(), &|_: BasinsLine| true).expect("runs")
}

/// The share of the cells whose neighbours (up to 1 cell away) all share their label in run
/// `a` on which runs `a` and `b` agree, and how many such cells there are.
fn agreement(a: &BasinRun, b: &BasinRun, nx: usize, ny: usize) -> (f64, usize) {
    let label = |r: &BasinRun, x: usize, y: usize| r.labels[x + nx * y];
    let name = |r: &BasinRun, l: i64| (l >= 0).then(|| r.attractors[l as usize].name.clone());
    let (mut inside, mut agree) = (0usize, 0usize);
    for y in 1..ny - 1 {
        for x in 1..nx - 1 {
            let l = label(a, x, y);
            let uniform = (y - 1..=y + 1).all(|yy| (x - 1..=x + 1).all(|xx| label(a, xx, yy) == l));
            if !uniform || l < 0 {
                continue;
            }
            inside += 1;
            if name(a, l) == name(b, label(b, x, y)) {
                agree += 1;
            }
        }
    }
    (agree as f64 / inside.max(1) as f64, inside)
}

/// S_b from the labels, by the formula, written out again.
fn basin_entropy(labels: &[i64], nx: usize, ny: usize) -> f64 {
    let mut sum = 0.0;
    let mut boxes = 0;
    for by in 0..ny / BOX {
        for bx in 0..nx / BOX {
            let mut seen: std::collections::BTreeMap<i64, f64> = Default::default();
            for y in by * BOX..(by + 1) * BOX {
                for x in bx * BOX..(bx + 1) * BOX {
                    *seen.entry(labels[x + nx * y]).or_default() += 1.0;
                }
            }
            let n = (BOX * BOX) as f64;
            sum += seen.values().map(|c| -(c / n) * (c / n).ln()).sum::<f64>();
            boxes += 1;
        }
    }
    sum / boxes as f64
}

/// The damped double well (δ = 0.25) on n × n cells over (x₀, p₀) ∈ [−2, 2]², to t_end = 200.
pub(super) fn double_well_map(n: usize, h: f64, methods_: &[Method]) -> BasinsSpec {
    BasinsSpec {
        sweep: sweep(
            double_well(0.25),
            methods_,
            h,
            200.0,
            vec![
                axis(0, Target::Q0(0), (-2.0, 2.0), n),
                axis(1, Target::P0(0), (-2.0, 2.0), n),
            ],
        ),
        exits: Vec::new(),
        recognition: Recognition::default(),
        attractors: Vec::new(),
    }
}

#[test]
fn the_damped_double_well_is_decided_by_energy_and_agrees_with_the_reference() {
    let n = 30;
    let spec = double_well_map(
        n,
        0.05,
        &[
            Method::new(MethodId::Csv2),
            Method::new(MethodId::Rk4),
            Method::Reference {
                tolerance: REFERENCE,
            },
        ],
    );
    let job = spec.prepare(&Limits::default()).expect("prepares");

    // The landscape: minima at x = ±1 with V = −1/4, the saddle at 0 with V = 0, to round-off.
    let landscape = job.landscape().expect("an autonomous system has one");
    assert_eq!(landscape.points.len(), 3, "{:?}", landscape.points);
    for point in &landscape.points[..2] {
        assert!(point.is_minimum());
        assert!((point.q[0].abs() - 1.0).abs() <= 1e-14, "{:?}", point.q);
        assert!((point.energy + 0.25).abs() <= 1e-15);
        assert!((point.hessian_eigenvalues[0] - 2.0).abs() <= 1e-13);
    }
    assert_eq!(landscape.points[2].q, vec![0.0]);
    assert_eq!(landscape.barrier, Some(0.0));

    let doc = run(&job);
    let steps_to_t_end = (200.0f64 / 0.05) as u64 * (n * n) as u64;
    for run in &doc.runs {
        // Every cell decided, by the energy argument alone, into the two wells.
        assert_eq!(
            run.undecided_fraction,
            0.0,
            "{}: {:?}",
            run.label.method,
            &run.undecided[..run.undecided.len().min(3)]
        );
        assert_eq!(run.decided_by.energy, n * n);
        // Two attractors, both equilibria.
        let kinds: Vec<AttractorKind> = run.attractors.iter().map(|a| a.kind).collect();
        assert_eq!(kinds, [AttractorKind::Equilibrium; 2]);
        let sum: f64 = run.fractions.iter().sum();
        assert!((sum - 1.0).abs() <= 1e-12);
        // The map is symmetric under (x, p) → (−x, −p): the two basins are equal in size.
        assert_eq!(
            run.attractors[0].cells, run.attractors[1].cells,
            "{}",
            run.label.method
        );
        // The basin entropy the document reports is the formula's.
        let s_b = basin_entropy(&run.labels, n, n);
        assert!((run.metrics.basin_entropy.unwrap() - s_b).abs() <= 1e-15);
        // Early stopping: the runs stopped long before t_end.
        println!(
            "double well, {}: S_b {:.4}, S_bb {:.4}, α {:?}, margin ≤ {:.2e}, steps {:.1}% of running every cell to t_end",
            run.label.method,
            s_b,
            run.metrics.boundary_basin_entropy.unwrap(),
            run.metrics.uncertainty_exponent,
            run.largest_energy_margin.unwrap_or(0.0),
            100.0 * run.steps as f64 / steps_to_t_end as f64
        );
        if run.label.method != "reference" {
            assert!(run.steps * 4 < steps_to_t_end, "{} steps", run.steps);
        }
    }
    // Every cell the energy argument decided agrees with the adaptive reference (a cell-by-cell
    // comparison, boundary cells included, for the conformal method).
    let (csv2, rk4, reference) = (&doc.runs[0], &doc.runs[1], &doc.runs[2]);
    let name = |r: &BasinRun, i: usize| r.attractors[r.labels[i] as usize].name.clone();
    let wrong: Vec<usize> = (0..n * n)
        .filter(|&i| name(csv2, i) != name(reference, i))
        .collect();
    assert!(
        wrong.is_empty(),
        "cells where csv2 and the reference differ: {wrong:?}"
    );
    let (share, inside) = agreement(rk4, reference, n, n);
    assert!(
        share >= 0.999 && inside > (n * n) / 3,
        "rk4: {share} of {inside}"
    );
}

/// A study, not a promise: how the damped double well's map (δ = 0.25, 40 × 40 over [−2, 2]²,
/// t_end = 200) of the conformal csv2 and of rk4 changes as h is halved, against DOP853 at 1e-12:
/// the cells whose outcome differs from the reference's, and S_b.
#[test]
fn halving_h_brings_the_conformal_and_the_rk4_maps_to_the_reference() {
    let n = 40;
    let spec = |h: f64, methods_: &[Method]| double_well_map(n, h, methods_);
    let reference = spec(
        0.1,
        &[Method::Reference {
            tolerance: REFERENCE,
        }],
    );
    let reference = run(&reference.prepare(&Limits::default()).unwrap());
    let reference = &reference.runs[0];
    let name = |r: &BasinRun, i: usize| {
        (r.labels[i] >= 0).then(|| r.attractors[r.labels[i] as usize].name.clone())
    };
    let steps = [0.4, 0.2, 0.1, 0.05];
    // Per method, per h: the cells that differ from the reference.
    let mut differ = [Vec::new(), Vec::new()];
    for h in steps {
        let methods_ = [Method::new(MethodId::Csv2), Method::new(MethodId::Rk4)];
        let doc = run(&spec(h, &methods_).prepare(&Limits::default()).unwrap());
        for (k, run) in doc.runs.iter().enumerate() {
            let wrong = (0..n * n)
                .filter(|&i| name(run, i) != name(reference, i))
                .count();
            println!(
                "double well, {} at h = {h}: {wrong} of {} cells differ from DOP853, S_b {:.4} \
                 (reference {:.4}), largest energy margin {:.1e}",
                run.label.method,
                n * n,
                run.metrics.basin_entropy.unwrap(),
                reference.metrics.basin_entropy.unwrap(),
                run.largest_energy_margin.unwrap_or(0.0)
            );
            differ[k].push(wrong);
        }
    }
    println!(
        "cells that differ, h = {steps:?}: csv2 {:?}, rk4 {:?}",
        differ[0], differ[1]
    );
    // Each halving moves no map away from the reference, and at the smallest step both are the
    // reference's but for a few boundary cells.
    for wrong in &differ {
        assert!(wrong.windows(2).all(|w| w[1] <= w[0]), "{wrong:?}");
        assert!(*wrong.last().unwrap() * 100 <= n * n, "{wrong:?}");
    }
}

#[test]
fn a_basin_map_is_the_same_in_shards_as_in_one_piece() {
    let spec = BasinsSpec {
        sweep: sweep(
            double_well(0.3),
            &[Method::new(MethodId::Csv2)],
            0.1,
            100.0,
            vec![axis(0, Target::Q0(0), (-2.0, 2.0), 17)],
        ),
        exits: Vec::new(),
        recognition: Recognition::default(),
        attractors: Vec::new(),
    };
    let job = spec.prepare(&Limits::default()).unwrap();
    let whole = run(&job);
    let study = StudySpec::Basins(spec.clone());
    let parts: Vec<(String, parts::Part<_>)> = (0..3)
        .map(|i| {
            let part = parts::run_shard(
                &job,
                study.clone(),
                Shard { index: i, count: 3 },
                &|_, _| (),
            )
            .expect("a shard runs");
            (format!("part {i}"), part)
        })
        .collect();
    let (cells, wall_ms) = parts::merge(&job, &study, parts).expect("merges");
    let merged = job.document_of(geomint_core::studies::engine::Finished {
        cells: cells.into_iter().map(Some).collect(),
        stop: geomint_core::studies::StudyCompletion::Finished,
        wall_ms,
    });
    assert_eq!(without_wall_time(&whole), without_wall_time(&merged));
    assert_eq!(whole.runs[0].labels.len(), job.cells());
}

/// The document without its wall time, as text.
fn without_wall_time(d: &BasinsDocument) -> String {
    let mut v = serde_json::to_value(d).unwrap();
    v.as_object_mut().unwrap().remove("wall_ms");
    v.to_string()
}

#[test]
fn cells_in_lanes_end_as_each_alone_bit_for_bit() {
    // Cells of every kind of decision: the damped double well (typed in; the energy
    // argument), Hénon–Heiles's escapes (built in; exits, some cells off the energy surface),
    // the same with an escape radius small enough that some orbits diverge first, and two driven
    // systems (recurrence, angles, a given attractor). Methods
    // the lanes take (csv1, velocity Verlet's triple jump) beside ones they do not (rk4).
    let well = BasinsSpec {
        sweep: sweep(
            double_well(0.25),
            &[Method::new(MethodId::Csv1), Method::new(MethodId::Rk4)],
            0.05,
            200.0,
            vec![
                axis(0, Target::Q0(0), (-2.0, 2.0), 23),
                axis(1, Target::P0(0), (-2.0, 2.0), 19),
            ],
        ),
        exits: Vec::new(),
        recognition: Recognition::default(),
        attractors: Vec::new(),
    };
    let escapes = henon_heiles_escapes(
        21,
        &[Method::triple_jump(
            geomint_core::methods::Base::VelocityVerlet,
        )],
        0.02,
    );
    let mut diverging = escapes.clone();
    diverging.recognition.escape_radius = 1.9;
    // Driven systems (typed in, a clock among the coordinates): recurrence on the stroboscopic
    // map, the forced pendulum's angle modulo 2π, and proximity to a given attractor.
    let mut duffing = forced_pendulum_map(14, &[]);
    duffing.sweep.system = SystemRef::Defined(crate::sections::duffing(0.5, 0.1, 1.0));
    duffing.sweep.methods = methods(&[Method::new(MethodId::Csv1), Method::new(MethodId::Rk4)]);
    duffing.sweep.axes = vec![
        axis(0, Target::Q0(0), (-1.8, 1.8), 17),
        axis(1, Target::P0(0), (-1.0, 1.0), 15),
    ];
    // The same from starts within an escape radius that some orbits then leave between two
    // stroboscope points, where the lanes look at a driven system's cells without its observer.
    let mut duffing_diverging = duffing.clone();
    duffing_diverging.recognition.escape_radius = 1.35;
    duffing_diverging.sweep.axes[0] = axis(0, Target::Q0(0), (-1.3, 1.3), 17);
    let mut pendulum = forced_pendulum_map(16, &["theta"]);
    pendulum.sweep.methods = methods(&[Method::new(MethodId::Csv1)]);
    pendulum.attractors = vec![GivenAttractor {
        name: "forwards".into(),
        points: vec![vec![-0.8162, 1.7592]],
        radius: 0.05,
        field: Field::new("attractors").index(0),
    }];
    for spec in [
        well,
        escapes,
        diverging,
        duffing,
        duffing_diverging,
        pendulum,
    ] {
        let must_diverge = spec.recognition.escape_radius < 2.0;
        let lanes = spec.prepare(&Limits::default()).unwrap();
        let alone = spec
            .prepare(&Limits::default())
            .unwrap()
            .one_cell_at_a_time();
        assert!(lanes.group() > 1, "the lanes take some run");
        assert_eq!(alone.group(), 1);
        let (in_lanes, one_by_one) = (run(&lanes), run(&alone));
        assert_eq!(without_wall_time(&in_lanes), without_wall_time(&one_by_one));
        let decided_by = &in_lanes.runs[0].decided_by;
        println!(
            "{}: {decided_by:?}, {} steps",
            in_lanes.system, in_lanes.runs[0].steps
        );
        let decided = decided_by.energy
            + decided_by.exit
            + decided_by.divergence
            + decided_by.recurrence
            + decided_by.proximity;
        assert!(decided > 200, "{decided_by:?}");
        assert!(
            !must_diverge || decided_by.divergence > 10,
            "{decided_by:?}"
        );
    }
}

/// Hénon–Heiles at E = 0.25, above the escape energy 1/6: the section x = 0 over (y, p_y), and
/// three exits beyond the three saddles, two units out along the channels at 90°, 210° and
/// 330°.
fn henon_heiles_escapes(n: usize, methods_: &[Method], h: f64) -> BasinsSpec {
    let exit = |i: usize, name: &str, text: &str| ExitSpec {
        name: name.into(),
        text: text.into(),
        direction: Direction::Up,
        field: Field::new("exits").index(i),
    };
    let mut sweep = sweep(
        "henon_heiles".into(),
        methods_,
        h,
        100.0,
        vec![
            axis(0, Target::Q0(1), (-0.6, 1.0), n),
            axis(1, Target::P0(1), (-0.6, 0.6), n),
        ],
    );
    sweep.q0 = Some(vec![0.0, 0.0]);
    sweep.p0 = Some(vec![0.0, 0.0]);
    sweep.energy_surface = Some(EnergySurface {
        energy: 0.25,
        momentum: 0,
        field: Field::new("energy_surface"),
    });
    BasinsSpec {
        sweep,
        exits: vec![
            exit(0, "up", "y - 2"),
            exit(1, "left", "-sqrt(3)/2*x - y/2 - 2"),
            exit(2, "right", "sqrt(3)/2*x - y/2 - 2"),
        ],
        recognition: Recognition::default(),
        attractors: Vec::new(),
    }
}

#[test]
fn henon_heiles_above_the_escape_energy_leaves_through_three_exits_as_the_reference_does() {
    let n = 24;
    let spec = henon_heiles_escapes(
        n,
        &[
            Method::triple_jump(geomint_core::methods::Base::VelocityVerlet),
            Method::Reference {
                tolerance: REFERENCE,
            },
        ],
        0.01,
    );
    let job = spec.prepare(&Limits::default()).expect("prepares");
    let landscape = job.landscape().unwrap();
    // The minimum at the origin and the three saddles at V = 1/6.
    assert_eq!(
        landscape.points.iter().filter(|p| p.is_minimum()).count(),
        1
    );
    assert_eq!(
        landscape.points.iter().filter(|p| p.index() == 1).count(),
        3,
        "{:?}",
        landscape.points
    );
    assert!((landscape.barrier.unwrap() - 1.0 / 6.0).abs() <= 1e-15);
    let doc = run(&job);
    let (map, reference) = (&doc.runs[0], &doc.runs[1]);
    let exits: Vec<&str> = map
        .attractors
        .iter()
        .filter(|a| a.kind == AttractorKind::Exit)
        .map(|a| a.name.as_str())
        .collect();
    assert_eq!(exits.len(), 3, "{:?}", map.attractors);
    // Cells off the energy surface fail to start and say so; every other cell leaves or
    // stays.
    for u in &map.undecided {
        assert!(u.reason.contains("energy"), "{}", u.reason);
    }
    let (share, inside) = agreement(map, reference, n, n);
    println!(
        "Hénon–Heiles E = 0.25: {} exits, fractions {:?}, S_b {:?}, S_bb {:?}, agreement {share} over {inside} interior cells",
        exits.len(),
        map.fractions,
        map.metrics.basin_entropy,
        map.metrics.boundary_basin_entropy
    );
    assert!(share >= 0.999 && inside >= 50, "{share} of {inside}");
}

#[test]
fn the_forced_damped_duffing_oscillator_locks_onto_a_period_one_orbit_in_each_well() {
    let n = 16;
    let omega: f64 = 1.0;
    let system = SystemRef::Defined(crate::sections::duffing(0.5, 0.1, omega));
    let period = 2.0 * std::f64::consts::PI / omega;
    let h = period / 64.0;
    let spec = BasinsSpec {
        sweep: sweep(
            system,
            &[
                Method::new(MethodId::Csv1),
                Method::Reference {
                    tolerance: REFERENCE,
                },
            ],
            h,
            200.0 * period,
            vec![
                axis(0, Target::Q0(0), (-1.8, 1.8), n),
                axis(1, Target::P0(0), (-1.0, 1.0), n),
            ],
        ),
        exits: Vec::new(),
        recognition: Recognition {
            period: Some(period),
            ..Recognition::default()
        },
        attractors: Vec::new(),
    };
    let job = spec.prepare(&Limits::default()).expect("prepares");
    assert!(job.landscape().is_none());
    let doc = run(&job);
    for run in &doc.runs {
        let periodic: Vec<_> = run
            .attractors
            .iter()
            .filter(|a| a.kind == AttractorKind::Periodic)
            .collect();
        assert_eq!(
            periodic.len(),
            2,
            "{}: {:?}",
            run.label.method,
            run.attractors
        );
        assert!(periodic.iter().all(|a| a.period == Some(1)));
        // One in each well.
        let mut sides: Vec<bool> = periodic.iter().map(|a| a.points[0][0] > 0.0).collect();
        sides.sort();
        assert_eq!(sides, [false, true]);
        assert_eq!(run.undecided_fraction, 0.0, "{:?}", run.undecided.first());
    }
    let (share, inside) = agreement(&doc.runs[0], &doc.runs[1], n, n);
    assert!(share >= 0.999 && inside >= 40, "{share} of {inside}");
}

#[test]
fn bad_basin_maps_are_refused_naming_the_field() {
    let base = BasinsSpec {
        sweep: sweep(
            double_well(0.2),
            &[Method::new(MethodId::Csv2)],
            0.1,
            10.0,
            vec![axis(0, Target::Q0(0), (-2.0, 2.0), 5)],
        ),
        exits: Vec::new(),
        recognition: Recognition::default(),
        attractors: Vec::new(),
    };
    let refused = |spec: BasinsSpec| match spec.prepare(&Limits::default()) {
        Ok(_) => panic!("accepted"),
        Err(e) => (e.field().map(|f| f.as_str().to_string()), e.to_string()),
    };
    // Up to 1024 points along an axis (a sweep stops at 401), not one more.
    let mut spec = base.clone();
    spec.sweep.axes = vec![
        axis(0, Target::Q0(0), (-2.0, 2.0), 1000),
        axis(1, Target::P0(0), (-2.0, 2.0), 1024),
    ];
    assert_eq!(spec.prepare(&Limits::default()).unwrap().cells(), 1_024_000);
    assert!(spec.sweep.prepare(&Limits::default()).is_err());
    spec.sweep.axes[1].n = 1025;
    let (field, message) = refused(spec);
    assert_eq!(field.as_deref(), Some("axes[1].n"), "{message}");
    assert!(message.contains("1024"), "{message}");
    // An axis over a parameter.
    let mut spec = base.clone();
    spec.sweep.axes = vec![axis(0, Target::Param("delta".into()), (0.1, 0.2), 3)];
    assert_eq!(refused(spec).0.as_deref(), Some("axes[0].name"));
    // A driving period for a system nothing drives.
    let mut spec = base.clone();
    spec.recognition.period = Some(1.0);
    assert_eq!(refused(spec).0.as_deref(), Some("recognition.period"));
    // An exit that does not parse names its field.
    let mut spec = base.clone();
    spec.exits = vec![ExitSpec {
        name: "right".into(),
        text: "x - * 2".into(),
        direction: Direction::Up,
        field: Field::new("exits").index(0),
    }];
    let (field, message) = refused(spec);
    assert_eq!(field.as_deref(), Some("exits[0].where"), "{message}");
    // An undamped system with no exits settles nowhere.
    let mut spec = base.clone();
    spec.sweep.system = "henon_heiles".into();
    spec.sweep.axes = vec![axis(0, Target::Q0(1), (-0.5, 0.5), 3)];
    assert_eq!(refused(spec).0.as_deref(), Some("exits"));
    // A driven system without its period.
    let mut spec = base;
    spec.sweep.system = SystemRef::Defined(crate::sections::duffing(0.5, 0.1, 1.0));
    spec.sweep.methods = methods(&[Method::new(MethodId::Csv1)]);
    assert_eq!(refused(spec).0.as_deref(), Some("recognition.period"));
}

#[test]
fn the_study_trait_counts_the_map_cells() {
    let spec = henon_heiles_escapes(4, &[Method::new(MethodId::VelocityVerlet)], 0.05);
    let job = spec.prepare(&Limits::default()).unwrap();
    assert_eq!(job.cells(), 16);
}

#[test]
fn the_wada_test_tells_three_stripes_from_hénon_heiles() {
    use geomint_core::studies::basins::metrics::basin_metrics;
    // Three vertical stripes 0 | 1 | 2: basin 1 touches both boundaries, 0 and 2 one each.
    let (nx, ny) = (30, 10);
    let labels: Vec<i64> = (0..nx * ny).map(|c| ((c % nx) / 10) as i64).collect();
    let started = vec![true; nx * ny];
    let metrics = basin_metrics(&labels, &started, &[nx, ny]);
    let shares: Vec<(i64, f64)> = metrics.wada.iter().map(|w| (w.label, w.share)).collect();
    assert_eq!(shares, [(0, 0.5), (1, 1.0), (2, 0.5)]);
    // Two basins: no Wada test.
    let two: Vec<i64> = labels.iter().map(|&l| l.min(1)).collect();
    assert!(basin_metrics(&two, &started, &[nx, ny]).wada.is_empty());
    // Hénon–Heiles's escape basins, which are Wada (Aguirre, Vallejo & Sanjuán 2001): every
    // exit's boundary against the rest comes within a cell of nearly all of the boundary.
    let spec = henon_heiles_escapes(40, &[Method::new(MethodId::VelocityVerlet)], 0.01);
    let doc = run(&spec.prepare(&Limits::default()).unwrap());
    let wada = &doc.runs[0].metrics.wada;
    println!("Hénon–Heiles E = 0.25, 40 × 40: Wada shares {wada:?}");
    assert_eq!(wada.len(), 3);
    assert!(wada.iter().all(|w| w.share >= 0.95), "{wada:?}");
}

/// θ″ + νθ′ + sin θ = F cos t: H = p²/2 − cos θ − Fθ cos t with conformal damping γ = ν/2.
pub(super) fn forced_pendulum() -> SystemRef {
    SystemRef::Defined(separable(
        &["theta"],
        "-cos(theta) - F*theta*cos(t)",
        Some(Damping::Conformal {
            gamma: expr("damping.gamma", "nu/2"),
        }),
        &[("nu", 0.1), ("F", 2.0)],
    ))
}

/// The forced damped pendulum (ν = 0.1, F = 2) on n × n cells over θ₀ ∈ [−π, π],
/// p₀ ∈ [−4, 4], with csv1 at T/64 and the adaptive reference, to 200 T.
pub(super) fn forced_pendulum_map(n: usize, angles: &[&str]) -> BasinsSpec {
    let period = std::f64::consts::TAU;
    let pi = std::f64::consts::PI;
    BasinsSpec {
        sweep: sweep(
            forced_pendulum(),
            &[
                Method::new(MethodId::Csv1),
                Method::Reference {
                    tolerance: REFERENCE,
                },
            ],
            period / 64.0,
            200.0 * period,
            vec![
                axis(0, Target::Q0(0), (-pi, pi), n),
                axis(1, Target::P0(0), (-4.0, 4.0), n),
            ],
        ),
        exits: Vec::new(),
        recognition: Recognition {
            period: Some(period),
            angles: angles.iter().map(|a| a.to_string()).collect(),
            ..Recognition::default()
        },
        attractors: Vec::new(),
    }
}

mod recognition;

//! Sweeps (core): the Fig. 6 preset reproduces the energy-error map bit for bit; shards merged
//! in any order reproduce the local run bit for bit, and merging refuses missing, duplicate and
//! foreign parts; csv1's divergence over (γ, h) follows the spectral radius of its propagation
//! matrix; energy errors over an h axis show the method's order against the exact solution;
//! J₃ stays at round-off over an ε axis; a cell outside a chart is that cell's error; sweeps of
//! the map's kind run in SIMD lanes with the one-cell path's numbers bit for bit, and leave the
//! same partial document at the time limit.

use geomint::api::studies::EnergyMapRequest;
use geomint::api::sweep::{energy_map_preset, SweepRequest};
use geomint::api::system::NoStoredSystems;
use geomint::core::methods::{Method, MethodId};
use geomint::core::run::Budget;
use geomint::core::simulation::Limits;
use geomint::core::stability::propagation_matrix;
use geomint::core::stability::Spectrum;
use geomint::core::studies::energy_map;
use geomint::core::studies::engine::{Local, Study};
use geomint::core::studies::parts::{merge, run_shard, Part, Shard, ShardError};
use geomint::core::studies::sweep::{self, RunMetrics, SweepDocument, SweepJob};
use geomint::core::studies::{StudyCompletion, StudySpec};
use serde_json::{json, Value};

fn job(request: &Value) -> SweepJob {
    SweepRequest::from_value(request)
        .unwrap()
        .to_spec(&NoStoredSystems)
        .unwrap()
        .prepare(&Limits::default())
        .unwrap()
}

fn run(job: &SweepJob) -> SweepDocument {
    sweep::run(job, &Local, Budget::default(), &|_| true).unwrap()
}

/// The document without its wall time, for comparing runs bit for bit.
fn numbers(doc: &SweepDocument) -> Value {
    let mut v = serde_json::to_value(doc).unwrap();
    v.as_object_mut().unwrap().remove("wall_ms");
    v
}

fn map_request() -> EnergyMapRequest {
    EnergyMapRequest::from_value(&json!({"nx": 9, "ny": 7, "t_max": 400})).unwrap()
}

#[test]
fn the_fig6_preset_reproduces_the_energy_map_bit_for_bit() {
    let request = map_request();
    let map_job = request.to_spec().unwrap().prepare().unwrap();
    let map = energy_map::run(&map_job, &Local, Budget::default(), &|_| true).unwrap();
    let doc = run(&job(&energy_map_preset(&request)));

    assert_eq!(doc.cells, 63);
    assert_eq!(doc.axes[0].values, map.xs);
    assert_eq!(doc.axes[1].values, map.ys);
    let (cartesian, polar) = (&doc.runs[0], &doc.runs[1]);
    assert_eq!(
        (cartesian.chart.as_str(), polar.chart.as_str()),
        ("cartesian", "polar")
    );
    let bits = |v: &[Option<f64>]| v.iter().map(|x| x.map(f64::to_bits)).collect::<Vec<_>>();
    assert_eq!(
        bits(&cartesian.energy_error_l2),
        bits(&map.epsilon_cartesian)
    );
    assert_eq!(bits(&polar.energy_error_l2), bits(&map.epsilon_polar));
    assert_eq!(
        bits(&cartesian.diverged_at),
        bits(&map.cartesian_diverged_at)
    );
    assert_eq!(bits(&polar.diverged_at), bits(&map.polar_diverged_at));
    // The grid holds the pivot (x₀, y₀) = (0, 0), where polar coordinates do not exist: that
    // cell says so, and only that one.
    let pivot = 3 * 9 + 4;
    assert_eq!((map.xs[4], map.ys[3]), (0.0, 0.0));
    let failed: Vec<usize> = (0..doc.cells)
        .filter(|&c| polar.errors[c].is_some())
        .collect();
    assert_eq!(failed, vec![pivot]);
    assert!(polar.errors[pivot].as_ref().unwrap().contains("polar"));
    // The map has divergences to compare at all, and cells where each chart is the better one.
    assert!(map.summary.polar_diverged > 0);
    assert!(map.summary.cartesian_better > 0 && map.summary.polar_better > 0);

    // On Fig. 6's 21-point axes over [−1.5, 1.5], (max − min)·(k/(n − 1)) and
    // (max − min)·k/(n − 1) differ by an ulp at 10 points of 21: the sweep spaces its points as
    // the map always did, so the preset's grid is the map's on any axis.
    let fig6 = EnergyMapRequest::from_value(&json!({"nx": 21, "ny": 21, "t_max": 1})).unwrap();
    let map_job = fig6.to_spec().unwrap().prepare().unwrap();
    let map = energy_map::run(&map_job, &Local, Budget::default(), &|_| true).unwrap();
    let preset = job(&energy_map_preset(&fig6));
    let values = |k: usize| preset.grid.axes[k].values();
    assert_eq!((values(0), values(1)), (map.xs.clone(), map.ys.clone()));
    let quotient_last: Vec<f64> = (0..21).map(|k| -1.5 + 3.0 * (k as f64 / 20.0)).collect();
    let differ = (0..21).filter(|&k| quotient_last[k] != map.xs[k]).count();
    assert_eq!(differ, 10, "{quotient_last:?} {:?}", map.xs);
}

#[test]
fn shards_merged_in_any_order_equal_the_local_run() {
    let job = job(&energy_map_preset(&map_request()));
    let local = numbers(&run(&job));
    let spec = job.spec().unwrap();
    for count in [1, 2, 5, 63] {
        let mut parts: Vec<(String, Part<Vec<RunMetrics>>)> = (0..count)
            .map(|index| {
                let shard = Shard { index, count };
                let part = run_shard(&job, spec.clone(), shard, &|_, _| {}).unwrap();
                // Through JSON, as a part travels between machines.
                let text = serde_json::to_string(&part).unwrap();
                (
                    format!("part-{index}"),
                    serde_json::from_str(&text).unwrap(),
                )
            })
            .collect();
        parts.reverse();
        let (cells, _) = merge(&job, &spec, parts.clone()).unwrap();
        assert_eq!(numbers(&job.document(cells, 0.0)), local, "{count} shards");

        if count > 1 {
            let mut missing = parts.clone();
            missing.remove(1);
            assert!(matches!(
                merge(&job, &spec, missing),
                Err(ShardError::Missing { .. })
            ));
            let mut twice = parts.clone();
            twice.push(("again".into(), parts[0].1.clone()));
            assert!(matches!(
                merge(&job, &spec, twice),
                Err(ShardError::Duplicate { .. })
            ));
        }
        let mut foreign = parts.clone();
        if let StudySpec::Sweep(sweep) = &mut foreign[0].1.spec {
            sweep.t_end += 1.0;
        }
        let refused = merge(&job, &spec, foreign).unwrap_err();
        assert!(matches!(refused, ShardError::Foreign { .. }));
        assert!(refused.to_string().starts_with(&foreign_name(&parts)));
    }
}

fn foreign_name(parts: &[(String, Part<Vec<RunMetrics>>)]) -> String {
    parts[0].0.clone()
}

#[test]
fn another_spec_has_another_digest() {
    let a = energy_map_preset(&map_request());
    let mut b = a.clone();
    b["t_end"] = json!(401.0);
    let digest = |v: &Value| {
        SweepRequest::from_value(v)
            .unwrap()
            .digest(&NoStoredSystems)
    };
    assert_eq!(digest(&a), digest(&a.clone()));
    assert_ne!(digest(&a), digest(&b));
    // Key order in the text does not matter: the digest is of the canonical form.
    let reordered: Value = serde_json::from_str(&reverse_keys(&a)).unwrap();
    assert_eq!(digest(&a), digest(&reordered));
}

fn reverse_keys(v: &Value) -> String {
    let object = v.as_object().unwrap();
    let members: Vec<String> = object
        .iter()
        .rev()
        .map(|(k, v)| format!("{}:{}", serde_json::to_string(k).unwrap(), v))
        .collect();
    format!("{{{}}}", members.join(","))
}

#[test]
fn csv1_diverges_over_gamma_and_h_where_its_spectral_radius_exceeds_one() {
    let t_end = 200.0;
    let request = json!({
        "system": "harmonic_oscillator",
        "methods": ["csv1"],
        "t_end": t_end,
        "every": 10,
        "axes": [
            {"name": "params.gamma", "min": 0.0, "max": 2.0, "n": 11},
            {"name": "h", "min": 0.2, "max": 3.0, "n": 15}
        ]
    });
    let doc = run(&job(&request));
    let csv1 = Method::new(MethodId::Csv1);
    let (mut unstable, mut stable, mut between) = (0, 0, 0);
    for cell in 0..doc.cells {
        let gamma = doc.axes[0].values[cell % 11];
        let h = doc.axes[1].values[cell / 11];
        let rho = Spectrum::of(&propagation_matrix(&csv1, 1.0, gamma, h).unwrap()).spectral_radius;
        let steps = (t_end / h).ceil();
        let diverged = doc.runs[0].diverged_at[cell].is_some();
        // Energy grows like ρ^(2n): past a factor e^12 it has left 100·(1 + H₀) far behind.
        if steps * rho.ln() > 6.0 {
            assert!(
                diverged,
                "γ = {gamma}, h = {h}: ρ = {rho} but no divergence"
            );
            unstable += 1;
        } else if rho <= 1.0 + 1e-12 {
            assert!(!diverged, "γ = {gamma}, h = {h}: ρ = {rho} but diverged");
            stable += 1;
        } else {
            between += 1;
        }
    }
    assert!(
        unstable >= 20 && stable >= 20,
        "{unstable} unstable, {stable} stable"
    );
    assert!(between <= 10, "{between} cells near the boundary");
    assert_eq!(doc.energy_reference, sweep::EnergyReference::Exact);
}

#[test]
fn an_h_axis_shows_the_order_against_the_exact_solution() {
    let request = json!({
        "system": "harmonic_oscillator",
        "params": {"gamma": 0.1},
        "methods": ["csv2", "rk4"],
        "t_end": 10,
        "axes": [{"name": "h", "min": 0.0125, "max": 0.1, "n": 4, "scale": "log"}]
    });
    let doc = run(&job(&request));
    for (h, expected) in doc.axes[0].values.iter().zip([0.0125, 0.025, 0.05, 0.1]) {
        assert!((h / expected - 1.0).abs() < 1e-15, "{h}");
    }
    for (run, order) in doc.runs.iter().zip([2.0, 4.0]) {
        let e: Vec<f64> = run.energy_error_max.iter().map(|e| e.unwrap()).collect();
        for k in 1..e.len() {
            let observed = (e[k] / e[k - 1]).log2();
            assert!(
                (observed - order).abs() < 0.15,
                "{}: order {observed}",
                run.method
            );
        }
        // Steps follow h: t_end/h each.
        assert_eq!(run.steps, vec![800, 400, 200, 100]);
    }
}

#[test]
fn j3_stays_at_round_off_over_an_epsilon_axis() {
    let request = json!({
        "system": "elastic_pendulum_3d",
        "methods": ["modin_3s"],
        "h": 0.05,
        "t_end": 100,
        "every": 10,
        "energy_reference": "reference",
        "axes": [{"name": "params.epsilon", "min": 0.0, "max": 0.1, "n": 3}]
    });
    let doc = run(&job(&request));
    let run = &doc.runs[0];
    for cell in 0..3 {
        let drift = run.invariant_drift["J3"][cell].unwrap();
        assert!(drift < 1e-13, "cell {cell}: J3 drift {drift}");
        let error = run.energy_error_max[cell].unwrap();
        assert!(
            error > 1e-9 && error < 1e-2,
            "cell {cell}: energy error {error}"
        );
    }
}

#[test]
fn refusals_name_the_axis() {
    let refused = |request: Value| -> (String, String) {
        let e = SweepRequest::from_value(&request)
            .and_then(|r| Ok(r.to_spec(&NoStoredSystems)?.prepare(&Limits::default())?))
            .unwrap_err();
        (e.field.unwrap_or_default(), e.message)
    };
    let base = json!({"system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 10,
        "axes": [{"name": "params.gamma", "min": 0, "max": 1, "n": 3}]});
    let with = |key: &str, value: Value| {
        let mut v = base.clone();
        v[key] = value;
        v
    };
    let cases = [
        (
            with(
                "axes",
                json!([{"name": "params.gamma", "min": -1, "max": 1, "n": 3}]),
            ),
            "axes[0].min",
        ),
        (
            with(
                "axes",
                json!([{"name": "params.gamma", "min": 0, "max": 1, "n": 0}]),
            ),
            "axes[0].n",
        ),
        (
            with(
                "axes",
                json!([{"name": "params.nope", "min": 0, "max": 1, "n": 2}]),
            ),
            "axes[0].name",
        ),
        (
            with("axes", json!([{"name": "x", "min": 0, "max": 1, "n": 2}])),
            "axes[0].name",
        ),
        (
            with(
                "axes",
                json!([{"name": "h", "min": 1e-9, "max": 1, "n": 2}]),
            ),
            "axes[0]",
        ),
        (with("h", Value::Null), "h"),
        (
            with(
                "axes",
                json!([{"name": "q0[0]", "min": 1, "max": 0, "n": 2}]),
            ),
            "axes[0]",
        ),
        (with("axes", json!([])), "axes"),
        (
            with(
                "axes",
                json!([{"name": "params.gamma", "min": 0, "max": 1, "n": 2, "step": 1}]),
            ),
            "axes[0].step",
        ),
        (with("energy_reference", json!("exact")), "energy_reference"),
    ];
    for (request, field) in cases {
        let (at, message) = refused(request);
        assert!(at.starts_with(field), "{field}: got {at}: {message}");
    }
    // A smallest step that takes too many steps is blamed on the axis's end.
    let mut small_h = with(
        "axes",
        json!([{"name": "h", "min": 1e-7, "max": 1, "n": 2}]),
    );
    small_h.as_object_mut().unwrap().remove("h");
    let (at, message) = refused(small_h);
    assert_eq!(at, "axes[0].min", "{message}");
}

#[test]
fn sweeps_of_the_maps_kind_run_in_lanes_with_the_numbers_of_cell_by_cell() {
    // Every metric of every run — errors, divergence, the last finite state in Cartesian
    // coordinates, steps and force evaluations — bit for bit between the lanes and the one-cell
    // path, over grids that reach every outcome, and over a shard that starts off a group of four.
    let preset = |method: &str, params: Value, x: [f64; 2], y: [f64; 2], n: [usize; 2]| {
        let map = EnergyMapRequest::from_value(&json!({"method": method, "params": params,
            "x": x, "y": y, "nx": n[0], "ny": n[1], "t_max": 300}))
        .unwrap();
        energy_map_preset(&map)
    };
    let mut requests = Vec::new();
    for method in ["symplectic_euler", "symplectic_euler_adjoint"] {
        // Fig. 6's window: divergent polar runs, the pivot, a last group of three.
        requests.push(preset(method, json!({}), [-3.0, 3.0], [-3.0, 3.0], [9, 7]));
        // Another pendulum, far enough out that the energy leaves its band.
        requests.push(preset(
            method,
            json!({"m": 1.3, "k": 0.7, "g": 0.4}),
            [0.2, 40.0],
            [-2.0, 1.1],
            [5, 3],
        ));
        // Starts so far out that H₀ overflows.
        requests.push(preset(
            method,
            json!({}),
            [1e200, 1e201],
            [-1e155, 1e160],
            [3, 2],
        ));
    }
    // Axes over the initial momenta, from a start off the pivot.
    requests.push(
        json!({"system": "elastic_pendulum_2d", "charts": ["polar", "cartesian"],
        "initial_coordinates": "cartesian", "q0": [1.0, -0.5],
        "methods": ["symplectic_euler_adjoint", "symplectic_euler"], "h": 0.05, "t_end": 20,
        "axes": [{"name": "p0[0]", "min": -4, "max": 4, "n": 5},
                 {"name": "p0[1]", "min": -4, "max": 4, "n": 3}]}),
    );
    let mut outcomes = [0usize; 4];
    for request in &requests {
        let job = job(request);
        assert!(job.runs_in_lanes(), "{request}");
        // As text: the shortest decimal that reads back to the same bits, −0 included.
        let in_lanes = numbers(&run(&job)).to_string();
        let one_by_one = job.clone().cell_by_cell();
        assert!(!one_by_one.runs_in_lanes());
        assert_eq!(
            in_lanes,
            numbers(&run(&one_by_one)).to_string(),
            "{request}"
        );
        let shard = 1..job.cells().min(7);
        let part = |job: &SweepJob| {
            let cells = geomint::core::studies::engine::Executor::run(
                &Local,
                job,
                shard.clone(),
                Budget::default(),
                &|_, _| {},
            );
            serde_json::to_string(&cells.unwrap()).unwrap()
        };
        assert_eq!(part(&job), part(&one_by_one), "{request}: cells {shard:?}");
        let doc = run(&job);
        let full = doc
            .runs
            .iter()
            .flat_map(|r| &r.steps)
            .max()
            .copied()
            .unwrap();
        for r in &doc.runs {
            for c in 0..doc.cells {
                let k = if r.errors[c].is_some() {
                    0
                } else if r.steps[c] < full {
                    1 // stopped: not finite
                } else if r.diverged_at[c].is_some() {
                    2 // left its energy band, to the end
                } else {
                    3
                };
                outcomes[k] += 1;
            }
        }
    }
    println!("outcomes (failed, not finite, blown, finished): {outcomes:?}");
    assert!(outcomes.iter().all(|&n| n > 0), "outcomes {outcomes:?}");
    // Sampled more sparsely: not the maps' kernel, but the lanes of plain runs (the Cartesian
    // chart's; the polar chart's one by one in the same groups), with the same numbers.
    let mut sparse = energy_map_preset(&map_request());
    sparse["every"] = json!(2);
    let sparse = job(&sparse);
    assert!(sparse.runs_in_lanes());
    assert_eq!(
        numbers(&run(&sparse)).to_string(),
        numbers(&run(&sparse.clone().cell_by_cell())).to_string()
    );
    // Not the maps' kind: another method.
    let mut other = energy_map_preset(&map_request());
    other["methods"] = json!(["rk4"]);
    assert!(!job(&other).runs_in_lanes());
}

#[test]
fn a_sweep_in_lanes_stopped_by_its_budget_leaves_its_cells_unfinished_or_fails() {
    let job = job(&energy_map_preset(&map_request()));
    assert!(job.runs_in_lanes());
    let past = Budget {
        cancel: None,
        deadline: Some(std::time::Instant::now()),
    };
    let doc = sweep::run(&job, &Local, past, &|_| true).unwrap();
    assert_eq!(doc.stop, StudyCompletion::TimeLimit);
    assert_eq!(doc.unfinished_cells, (0..job.cells()).collect::<Vec<_>>());
    let cancelled = std::sync::atomic::AtomicBool::new(true);
    let budget = Budget {
        cancel: Some(&cancelled),
        deadline: None,
    };
    let refused = sweep::run(&job, &Local, budget, &|_| true).unwrap_err();
    assert!(refused.to_string().contains("cancelled"), "{refused}");
}

#[test]
fn a_cell_outside_the_chart_keeps_its_failure_when_the_lanes_reach_the_time_limit() {
    // In the polar chart only, the middle cell starts at the pivot, outside the chart: as on the
    // one-cell path, it keeps its failure after the time limit, and only the others are
    // unfinished.
    let past = Budget {
        cancel: None,
        deadline: Some(std::time::Instant::now()),
    };
    let polar = job(
        &json!({"system": "elastic_pendulum_2d", "charts": ["polar"],
        "initial_coordinates": "cartesian",
        "methods": ["symplectic_euler", "symplectic_euler_adjoint"], "h": 0.05, "t_end": 20,
        "axes": [{"name": "q0[0]", "min": -1, "max": 1, "n": 3},
                 {"name": "q0[1]", "min": -1, "max": 1, "n": 3}]}),
    );
    assert!(polar.runs_in_lanes());
    let stopped = |job: &SweepJob| numbers(&sweep::run(job, &Local, past, &|_| true).unwrap());
    let in_lanes = stopped(&polar);
    assert_eq!(in_lanes, stopped(&polar.clone().cell_by_cell()));
    assert_eq!(
        in_lanes["unfinished_cells"],
        json!([0, 1, 2, 3, 5, 6, 7, 8])
    );
    for run in in_lanes["runs"].as_array().unwrap() {
        let pivot = run["errors"][4].as_str().unwrap();
        assert!(!pivot.contains("not run"), "{pivot}");
        assert!(
            run["errors"][0].as_str().unwrap().contains("not run"),
            "{run}"
        );
    }
}

//! The Hénon–Heiles MEGNO map: ⟨Y⟩ over the (y, p_y) section at x = 0, p_x ≥ 0 from H = 1/8,
//! T = 1000, h = 0.05, the triple jump of velocity Verlet (fourth order), one deviation vector —
//! the `henon_heiles_megno` preset's request on a grid of n × n cells, run as any sweep is (all
//! cores, four cells side by side in SIMD lanes). n is 101 by default and `GEOMINT_CHAOS_GRID`
//! (401 for the full map). Reports the wall and CPU time, ns per cell-step, the cells on the
//! energy surface and those with ⟨Y⟩ > 4, and writes the map (y, p_y, ⟨Y⟩ per line) to
//! `target/chaos-map-<n>.tsv`; with `GEOMINT_PEERS_PYTHON` set (`scripts/bench-chaos` sets up the
//! venv and sets it) the peers' script `scripts/bench-chaos-peers.py` then runs heyoka and
//! pynamicalsys on the same grid in the same run and compares their maps with this one.
//! Then the same map of the same potential typed in as text on `GEOMINT_CHAOS_TYPED_GRID` × the
//! same (101 by default; 0 skips it): in lanes, then cell by cell (the same numbers, checked),
//! the ratio of the two, and how far its ⟨Y⟩ is from the built-in system's when the grids are
//! the same. Last, the same typed-in potential swept without indicators (energy errors against
//! H₀ sampled every step, as sweeps sample by default, and every 100 steps), in lanes and cell by
//! cell. Last, sweeps over parameters and the step on `GEOMINT_SWEEP_GRID` × the same (101 by
//! default; 0 skips them), in lanes and cell by cell: the damped oscillator over (γ, h) and the
//! damped 3-D elastic pendulum over (k, ε).

use std::io::Write;
use std::time::Instant;

use geomint::api::sweep::{presets, SweepRequest};
use geomint::api::system::NoStoredSystems;
use geomint::core::run::Budget;
use geomint::core::studies::engine::Local;
use geomint::core::studies::sweep::{self, SweepDocument, SweepJob, SweepLine};
use serde_json::{json, Value};

mod cpu_time;
use cpu_time::cpu_seconds;

fn main() {
    let grid = |name: &str, default: usize| -> usize {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let n = grid("GEOMINT_CHAOS_GRID", 101);
    let doc = megno_map(n, "MEGNO, built-in, in lanes", &|_| {}, false);
    let megno = &doc.runs[0].chaos.as_ref().expect("indicators").megno_mean;
    let path = format!("target/chaos-map-{n}.tsv");
    let mut out =
        std::io::BufWriter::new(std::fs::File::create(&path).expect("target/ is writable"));
    for (cell, m) in megno.iter().enumerate() {
        let (y, py) = (doc.axes[0].values[cell % n], doc.axes[1].values[cell / n]);
        let value = m.map_or("nan".to_string(), |m| m.to_string());
        writeln!(out, "{y}\t{py}\t{value}").expect("written");
    }
    out.flush().expect("written");
    println!("map written to {path}");
    match std::env::var("GEOMINT_PEERS_PYTHON") {
        Ok(python) => {
            let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/bench-chaos-peers.py");
            let status = std::process::Command::new(python)
                .args([script, &n.to_string()])
                .status()
                .expect("the peers' script runs");
            assert!(status.success(), "the peers' script failed");
        }
        Err(_) => println!("(run scripts/bench-chaos for the peers in the same run)"),
    }
    let typed_n = grid("GEOMINT_CHAOS_TYPED_GRID", 101);
    if typed_n > 0 {
        let typed = json!({"coordinates": ["x", "y"], "mass": 1,
            "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3"});
        let doc = both_ways(typed_n, "MEGNO, typed in", |request| {
            request["system"] = typed.clone();
        });
        if typed_n == n {
            // Chaotic orbits part at the first rounding that differs; regular ones stay close.
            let theirs = &doc.runs[0].chaos.as_ref().expect("indicators").megno_mean;
            let pairs: Vec<(f64, f64)> = megno
                .iter()
                .zip(theirs)
                .filter_map(|(a, b)| Some(((*a)?, (*b)?)))
                .collect();
            let same = pairs
                .iter()
                .filter(|(a, b)| (*a > 4.0) == (*b > 4.0))
                .count();
            let mut regular: Vec<f64> = pairs
                .iter()
                .filter(|(a, b)| *a < 4.0 && *b < 4.0)
                .map(|(a, b)| (a - b).abs())
                .collect();
            regular.sort_by(f64::total_cmp);
            let median = regular.get(regular.len() / 2).copied().unwrap_or(f64::NAN);
            println!(
                "  same verdict (⟨Y⟩ > 4) in {same} of {} cells; median |Δ⟨Y⟩| on regular cells \
                 {median:.1e}",
                pairs.len()
            );
        }
        // No indicators: the energy error against H₀ at every step (a sweep's default
        // sampling), and every 100 steps.
        for every in [1, 100] {
            both_ways(
                typed_n,
                &format!("no indicators, sampled every {every}, typed in"),
                |request| {
                    request["system"] = typed.clone();
                    request["every"] = json!(every);
                    request
                        .as_object_mut()
                        .expect("an object")
                        .remove("indicators");
                },
            );
        }
    }
    let sweep_n = grid("GEOMINT_SWEEP_GRID", 101);
    if sweep_n > 0 {
        parameter_sweeps(sweep_n);
    }
}

/// The preset's map on n × n cells changed by `edit`, in lanes and then cell by cell: checks
/// that both give the same numbers, prints the ratio of their wall times and returns the
/// document.
fn both_ways(n: usize, label: &str, edit: impl Fn(&mut Value)) -> SweepDocument {
    let wall = Instant::now();
    let doc = megno_map(n, &format!("{label}, in lanes"), &edit, false);
    let in_lanes = wall.elapsed().as_secs_f64();
    let wall = Instant::now();
    let alone = megno_map(n, &format!("{label}, cell by cell"), &edit, true);
    let cell_by_cell = wall.elapsed().as_secs_f64();
    assert_eq!(
        serde_json::to_string(&doc.runs).expect("numbers"),
        serde_json::to_string(&alone.runs).expect("numbers"),
        "the lanes give the one-cell path's numbers"
    );
    println!(
        "  {label}: the same numbers both ways; in lanes {:.1}× the cells per second of cell by \
         cell",
        cell_by_cell / in_lanes
    );
    doc
}

/// The preset's map on n × n cells changed by `edit`, in lanes where the sweep runs so or
/// `one_by_one`; prints its times.
fn megno_map(n: usize, label: &str, edit: &dyn Fn(&mut Value), one_by_one: bool) -> SweepDocument {
    let mut request = presets()
        .into_iter()
        .find(|p| p.id == "henon_heiles_megno")
        .expect("the preset")
        .request;
    request["axes"][0]["n"] = json!(n);
    request["axes"][1]["n"] = json!(n);
    edit(&mut request);
    let job = sweep_job(&request, one_by_one);
    let (cpu, wall) = (cpu_seconds(), Instant::now());
    let doc =
        sweep::run(&job, &Local, Budget::default(), &|_: SweepLine| true).expect("the map runs");
    let (wall, cpu) = (wall.elapsed().as_secs_f64(), cpu_seconds() - cpu);
    let run = &doc.runs[0];
    let steps: u64 = run.steps.iter().sum();
    let cells = match &run.chaos {
        Some(chaos) => {
            let on = chaos.megno_mean.iter().filter(|m| m.is_some()).count();
            let chaotic = chaos
                .megno_mean
                .iter()
                .filter(|m| m.is_some_and(|m| m > 4.0))
                .count();
            format!("{on} cells on the surface, {chaotic} with ⟨Y⟩ > 4")
        }
        None => format!(
            "{} cells on the surface",
            run.errors.iter().filter(|e| e.is_none()).count()
        ),
    };
    println!(
        "Hénon–Heiles map {n} × {n} ({label}): {wall:.2} s wall, {cpu:.2} s CPU on {} threads, \
         {:.1} ns per cell-step (CPU), {cells}, {steps} steps",
        rayon::current_num_threads(),
        cpu * 1e9 / steps.max(1) as f64,
    );
    doc
}

/// The sweep `request` prepared, in lanes where it runs so or `one_by_one`.
fn sweep_job(request: &Value, one_by_one: bool) -> SweepJob {
    let job = SweepRequest::from_value(request)
        .map_err(|e| e.message)
        .and_then(|r| {
            r.to_spec(&NoStoredSystems)
                .map_err(|e| e.message)?
                .prepare(&Default::default())
                .map_err(|e| e.to_string())
        })
        .expect("a valid sweep");
    assert!(job.runs_in_lanes(), "the sweep runs in lanes");
    if one_by_one {
        job.cell_by_cell()
    } else {
        job
    }
}

/// Sweeps over parameters and the step (one system per lane; cells of one step share lanes),
/// n × n cells, in lanes and then cell by cell: the same numbers, checked, and the ratio.
fn parameter_sweeps(n: usize) {
    let sweeps = [
        (
            "the csv1_stability preset's oscillator over (γ, h), T = 20000",
            json!({
                "system": "harmonic_oscillator",
                "methods": ["csv1"],
                "t_end": 20000,
                "every": 100,
                "axes": [
                    {"name": "params.gamma", "min": 0.0, "max": 2.0, "n": n},
                    {"name": "h", "min": 0.1, "max": 3.0, "n": n}
                ]
            }),
        ),
        (
            "the damped 3-D elastic pendulum over (k, ε), modin_3s, h = 0.01, T = 100, \
             energy against H₀",
            json!({
                "system": "elastic_pendulum_3d",
                "methods": ["modin_3s"],
                "q0": [0.3, 0.1, -1.2],
                "p0": [0.0, 0.4, 0.1],
                "h": 0.01,
                "t_end": 100,
                "every": 100,
                "energy_reference": "initial",
                "axes": [
                    {"name": "params.k", "min": 0.5, "max": 40.0, "n": n},
                    {"name": "params.epsilon", "min": 0.0, "max": 0.5, "n": n}
                ]
            }),
        ),
    ];
    for (label, request) in sweeps {
        let mut docs = Vec::new();
        let mut walls = Vec::new();
        for one_by_one in [false, true] {
            let job = sweep_job(&request, one_by_one);
            let wall = Instant::now();
            docs.push(
                sweep::run(&job, &Local, Budget::default(), &|_: SweepLine| true)
                    .expect("the sweep runs"),
            );
            walls.push(wall.elapsed().as_secs_f64());
        }
        assert_eq!(
            serde_json::to_string(&docs[0].runs).expect("numbers"),
            serde_json::to_string(&docs[1].runs).expect("numbers"),
            "the lanes give the one-cell path's numbers"
        );
        let steps: u64 = docs[0].runs[0].steps.iter().sum();
        println!(
            "{label}, {n} × {n}: in lanes {:.2} s, cell by cell {:.2} s, the same numbers; \
             {:.1}× the cells per second ({steps} steps)",
            walls[0],
            walls[1],
            walls[1] / walls[0]
        );
    }
}

//! Basin maps at the size, 1000 × 1000 cells by default (`GEOMINT_BASINS_GRID`): the
//! `forced_duffing` preset (periodic attractors on the stroboscopic map; a driven system, its
//! clock one more coordinate to the lanes) and the `henon_heiles_escapes` preset (three exits, sixteen cells side by side in SIMD
//! lanes), each cell stopped as soon as its outcome is decided. Reports the wall and CPU time,
//! ns per cell-step and what the map found, and writes each map (x, y, label name, decision
//! time per line) to `target/basins-<preset>-<n>.tsv`; with `GEOMINT_PEERS_PYTHON` set
//! (`scripts/bench-basins` sets up the venv and sets it) the peers' script
//! `scripts/bench-basins-peers.py` then runs pynamicalsys on a sample of the same cells in the
//! same run, times it, and compares its labels with these.

use std::io::Write;
use std::time::Instant;

use geomint::api::basins::{presets, BasinsRequest};
use geomint::api::system::NoStoredSystems;
use geomint::core::run::Budget;
use geomint::core::simulation::Limits;
use geomint::core::studies::basins::{self, BasinsLine};
use geomint::core::studies::engine::Local;
use serde_json::json;

mod cpu_time;
use cpu_time::cpu_seconds;

fn main() {
    let n: usize = std::env::var("GEOMINT_BASINS_GRID")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1000);
    for id in ["forced_duffing", "henon_heiles_escapes"] {
        map(id, n);
    }
    match std::env::var("GEOMINT_PEERS_PYTHON") {
        Ok(python) => {
            let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/bench-basins-peers.py");
            let status = std::process::Command::new(python)
                .args([script, &n.to_string()])
                .status()
                .expect("the peers' script runs");
            assert!(status.success(), "the peers' script failed");
        }
        Err(_) => println!("(run scripts/bench-basins for the peers in the same run)"),
    }
}

/// The preset `id` on n × n cells: timed, summarised and written out.
fn map(id: &str, n: usize) {
    let mut request = presets()
        .into_iter()
        .find(|p| p.id == id)
        .expect("the preset")
        .request;
    request["axes"][0]["n"] = json!(n);
    request["axes"][1]["n"] = json!(n);
    let (basins_request, sweep) = BasinsRequest::from_value(&request).expect("the preset reads");
    let spec = basins_request
        .to_spec(&sweep, &NoStoredSystems)
        .expect("the preset is a map");
    let job = spec.prepare(&Limits::default()).expect("the map prepares");
    let (cpu, wall) = (cpu_seconds(), Instant::now());
    let doc =
        basins::run(&job, &Local, Budget::default(), &|_: BasinsLine| true).expect("the map runs");
    let (wall, cpu) = (wall.elapsed().as_secs_f64(), cpu_seconds() - cpu);
    let run = &doc.runs[0];
    let started = doc.cells - run.not_started;
    let shares: Vec<String> = run
        .attractors
        .iter()
        .zip(&run.fractions)
        .map(|(a, f)| format!("{} {f:.3}", a.name))
        .collect();
    println!(
        "{id} {n} × {n} ({}): {wall:.2} s wall, {cpu:.2} s CPU on {} threads, {started} cells \
         that start an orbit, {} steps, {:.1} ns per cell-step (CPU), {:.2} µs per cell (wall); \
         {}; undecided {:.4}; S_b {:?}, S_bb {:?}, α {:?}",
        run.label.method,
        rayon::current_num_threads(),
        run.steps,
        cpu * 1e9 / run.steps.max(1) as f64,
        wall * 1e6 / started.max(1) as f64,
        shares.join(", "),
        run.undecided_fraction,
        run.metrics.basin_entropy,
        run.metrics.boundary_basin_entropy,
        run.metrics.uncertainty_exponent,
    );
    let path = format!("target/basins-{id}-{n}.tsv");
    let mut out =
        std::io::BufWriter::new(std::fs::File::create(&path).expect("target/ is writable"));
    for (cell, (&label, t)) in run.labels.iter().zip(&run.decided_at).enumerate() {
        let (x, y) = (doc.axes[0].values[cell % n], doc.axes[1].values[cell / n]);
        let name = match usize::try_from(label) {
            Ok(k) => run.attractors[k].name.replace(' ', "_"),
            Err(_) => "undecided".into(),
        };
        let t = t.map_or("nan".to_string(), |t| t.to_string());
        writeln!(out, "{x}\t{y}\t{name}\t{t}").expect("written");
    }
    out.flush().expect("written");
    println!("  map written to {path}");
}

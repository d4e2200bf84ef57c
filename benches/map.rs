//! The energy-error map of paper 001 Fig. 6 (101 × 101 cells, symplectic Euler, h = 0.2, both
//! charts): wall and CPU time with the cells side by side in SIMD lanes against cell by cell,
//! first on a short horizon (t_max = 2000, interleaved, median of 3) with the bits of both
//! compared, then the full map (t_max = 50 000, 5.05·10⁹ steps) side by side only; with
//! `GEOMINT_MAP_FULL_BOTH` set, the full map cell by cell too. Reports ns per step and chart and
//! the parallel efficiency, CPU time / (wall time × threads).

use std::time::Instant;

use geomint::api::studies::EnergyMapRequest;
use geomint::core::run::Budget;
use geomint::core::studies::energy_map::{CellPath, EnergyMapCells, EnergyMapJob};
use serde_json::json;

mod cpu_time;
use cpu_time::cpu_seconds;

/// The map `geomint study energy-map` runs for `{"nx": 101, "ny": 101, "t_max": …}`: Fig. 6's
/// pendulum, symplectic Euler, h = 0.2.
fn fig6(t_max: f64) -> EnergyMapJob {
    let request = json!({"nx": 101, "ny": 101, "t_max": t_max});
    EnergyMapRequest::from_value(&request)
        .and_then(|r| Ok(r.to_spec()?.prepare()?))
        .expect("a valid map")
}

/// One map on `path`: the map, wall seconds, CPU seconds.
fn timed(job: &EnergyMapJob, path: CellPath) -> (EnergyMapCells, f64, f64) {
    let (cpu, wall) = (cpu_seconds(), Instant::now());
    let map = job
        .run_with(path, Budget::default(), &|_, _| {})
        .expect("a valid map")
        .expect("not cancelled");
    (map, wall.elapsed().as_secs_f64(), cpu_seconds() - cpu)
}

fn report(label: &str, map: &EnergyMapCells, wall: f64, cpu: f64) {
    let threads = rayon::current_num_threads();
    println!(
        "{label:<34} {wall:>8.2} s wall {cpu:>8.2} s CPU {:>6.2} ns/step  efficiency {:>4.0} % of {threads} threads  ({} steps)",
        cpu * 1e9 / map.steps as f64,
        100.0 * cpu / (wall * threads as f64),
        map.steps,
    );
}

fn bits(map: &EnergyMapCells) -> Vec<(Option<u64>, Option<u64>)> {
    map.cartesian
        .iter()
        .chain(&map.polar)
        .map(|r| (r.epsilon.map(f64::to_bits), r.diverged_at.map(f64::to_bits)))
        .collect()
}

fn main() {
    let short = fig6(2000.0);
    let mut runs = [Vec::new(), Vec::new()];
    for _ in 0..3 {
        for (k, path) in [CellPath::Lanes, CellPath::CellByCell]
            .into_iter()
            .enumerate()
        {
            runs[k].push(timed(&short, path));
        }
    }
    assert_eq!(bits(&runs[0][0].0), bits(&runs[1][0].0), "the same bits");
    let mut medians = Vec::new();
    for (label, mut timings) in ["t_max 2000, side by side", "t_max 2000, cell by cell"]
        .into_iter()
        .zip(runs)
    {
        timings.sort_by(|a, b| a.1.total_cmp(&b.1));
        let (map, wall, cpu) = &timings[1];
        report(label, map, *wall, *cpu);
        medians.push(*wall);
    }
    println!(
        "side by side is {:.2}× faster (wall)",
        medians[1] / medians[0]
    );

    let full = fig6(50_000.0);
    let (map, wall, cpu) = timed(&full, CellPath::Lanes);
    report("Fig. 6 full size, side by side", &map, wall, cpu);
    if std::env::var_os("GEOMINT_MAP_FULL_BOTH").is_some() {
        let (one_by_one, wall, cpu) = timed(&full, CellPath::CellByCell);
        report("Fig. 6 full size, cell by cell", &one_by_one, wall, cpu);
        assert_eq!(bits(&map), bits(&one_by_one), "the same bits");
    }
}

//! The energy-error map of paper 001 Fig. 6 on a coarse grid (21 × 21, t_max = 2000): cells of
//! both signs of ε(x,y) − ε(r,θ), every predicted cell diverging in polar coordinates, and every
//! polar divergence inside the region Sec. 4.1's boundary predicts (up to one grid cell: with
//! h = 0.2 the discrete motion need not turn back exactly where the exact one does).

use geomint_core::error::Field;
use geomint_core::methods::{Method, MethodId};
use geomint_core::run::Budget;
use geomint_core::simulation::MethodAt;
use geomint_core::studies::energy_map::{
    CellPath, ChartRun, EnergyMapCells, EnergyMapJob, EnergyMapSpec,
};
use geomint_core::systems::ParamValue;

const N: usize = 21;

/// A map of `method` on the pendulum with `params` (m, k, l, g) over an nx × ny grid.
fn map_of(
    method: MethodId,
    [m, k, l, g]: [f64; 4],
    t_max: f64,
    (nx, ny): (usize, usize),
    (x, y): ([f64; 2], [f64; 2]),
) -> EnergyMapJob {
    let params = [("m", m), ("k", k), ("l", l), ("g", g)]
        .map(|(name, v)| (name.to_string(), ParamValue::Number(v)))
        .into();
    EnergyMapSpec {
        method: MethodAt {
            method: Method::new(method),
            field: Field::new("method"),
        },
        params,
        h: 0.2,
        t_max,
        nx,
        ny,
        x,
        y,
    }
    .prepare()
    .unwrap()
}

fn fig6(t_max: f64) -> EnergyMapJob {
    let grid = ([-1.5, 1.5], [-1.5, 1.5]);
    map_of(
        MethodId::SymplecticEuler,
        [1.0, 1.0, 1.0, 0.02],
        t_max,
        (N, N),
        grid,
    )
}

#[test]
fn a_coarse_fig6_map_has_both_signs_and_divergences_only_where_predicted() {
    let spec = fig6(2000.0);
    let progress = std::sync::atomic::AtomicUsize::new(0);
    let map = spec
        .run(Budget::default(), &|done, total| {
            assert!(done <= total);
            progress.fetch_max(done, std::sync::atomic::Ordering::Relaxed);
        })
        .unwrap()
        .unwrap();
    assert_eq!(progress.into_inner(), N * N);
    let diff = map.difference();
    let positive = diff.iter().flatten().filter(|&&d| d > 0.0).count();
    let negative = diff.iter().flatten().filter(|&&d| d < 0.0).count();
    let cell = |k: usize| (map.xs[k % N], map.ys[k / N]);
    let diverged: Vec<usize> = (0..N * N)
        .filter(|&k| map.polar[k].diverged_at.is_some())
        .collect();
    let predicted: Vec<usize> = (0..N * N).filter(|&k| map.predicted_divergent[k]).collect();
    eprintln!(
        "21×21, t_max 2000: ε(x,y) > ε(r,θ) in {positive} cells, < in {negative}; polar diverged in {} (predicted {})",
        diverged.len(),
        predicted.len()
    );
    assert!(positive >= 10 && negative >= 10, "{positive} / {negative}");
    assert!(
        predicted.iter().all(|k| diverged.contains(k)),
        "a predicted cell did not diverge"
    );
    // Divergences outside the predicted region lie within one grid diagonal of the boundary.
    let spacing = 3.0 / (N - 1) as f64 * std::f64::consts::SQRT_2;
    for &k in &diverged {
        let (x, y) = cell(k);
        let r = x.hypot(y);
        let boundary = 2.0 + 2.0 * 0.02 * (y / r);
        assert!(
            r >= boundary - spacing,
            "polar divergence at ({x}, {y}), r = {r}, boundary {boundary}"
        );
    }
    // In Cartesian coordinates only the pivot itself (the spring's direction is undefined).
    for k in 0..N * N {
        if map.cartesian[k].diverged_at.is_some() {
            assert_eq!(cell(k), (0.0, 0.0));
        }
    }
    assert_eq!(
        map.polar[N * N / 2].epsilon,
        None,
        "the polar chart has no pivot cell"
    );
}

#[test]
fn the_same_map_twice_is_bit_identical() {
    let spec = fig6(400.0);
    let a = spec.run(Budget::default(), &|_, _| {}).unwrap().unwrap();
    let b = spec.run(Budget::default(), &|_, _| {}).unwrap().unwrap();
    for k in 0..N * N {
        let bits = |m: &geomint_core::studies::energy_map::EnergyMapCells| {
            (
                m.polar[k].epsilon.map(f64::to_bits),
                m.cartesian[k].epsilon.map(f64::to_bits),
            )
        };
        assert_eq!(bits(&a), bits(&b), "cell {k}");
    }
}

/// Every number of a map as bits (NaN included), cell by cell.
fn map_bits(map: &EnergyMapCells) -> Vec<[Option<u64>; 5]> {
    let bits = |x: Option<f64>| x.map(f64::to_bits);
    (0..map.energy.len())
        .map(|k| {
            [
                Some(map.energy[k].to_bits()),
                bits(map.cartesian[k].epsilon),
                bits(map.cartesian[k].diverged_at),
                bits(map.polar[k].epsilon),
                bits(map.polar[k].diverged_at),
            ]
        })
        .collect()
}

#[test]
fn cells_run_side_by_side_give_the_bits_of_cells_run_one_by_one() {
    let mut jobs = Vec::new();
    for id in [MethodId::SymplecticEuler, MethodId::SymplecticEulerAdjoint] {
        // Fig. 6 (divergent polar cells, the pivot, 441 cells: a last group of one).
        let fig6 = ([-1.5, 1.5], [-1.5, 1.5]);
        jobs.push(map_of(id, [1.0, 1.0, 1.0, 0.02], 2000.0, (N, N), fig6));
        // Another pendulum (1/m inexact), a grid off the pivot and of 5 × 3 cells.
        let off = ([0.2, 2.9], [-2.0, 1.1]);
        jobs.push(map_of(id, [1.3, 0.7, 1.0, 0.4], 300.0, (5, 3), off));
        // Starts so far out that H₀ overflows: blown up at t = 0.
        let far = ([1e200, 1e201], [-1e155, 1e160]);
        jobs.push(map_of(id, [1.3, 0.7, 1.0, 0.4], 300.0, (5, 3), far));
    }
    let mut steps = 0;
    for job in &jobs {
        assert!(job.runs_in_lanes(), "{:?}", job.method);
        let run = |path| {
            job.run_with(path, Budget::default(), &|_, _| {})
                .unwrap()
                .unwrap()
        };
        let side_by_side = run(CellPath::Lanes);
        let one_by_one = run(CellPath::CellByCell);
        assert_eq!(
            map_bits(&side_by_side),
            map_bits(&one_by_one),
            "{:?} {:?}",
            job.method,
            job.pendulum
        );
        assert_eq!(side_by_side.steps, one_by_one.steps);
        steps += one_by_one.steps;
    }
    // The grids reach every outcome: finished, blown up, non-finite, and no polar chart.
    let fig6 = jobs[0].run(Budget::default(), &|_, _| {}).unwrap().unwrap();
    assert!(fig6.polar.iter().any(|r| r.epsilon.is_some()));
    assert!(fig6.polar.iter().any(|r| r.diverged_at.is_some()));
    assert!(fig6.cartesian.iter().any(|r| r.diverged_at.is_some()));
    assert!(fig6.polar.iter().any(|r| *r
        == ChartRun {
            epsilon: None,
            diverged_at: None
        }));
    eprintln!(
        "{} maps, {steps} steps: the same bits side by side",
        jobs.len()
    );
}

#[test]
fn a_spent_budget_leaves_every_cell_unfinished_in_lanes_as_cell_by_cell() {
    let job = fig6(2000.0);
    assert!(job.runs_in_lanes());
    let past = Budget {
        cancel: None,
        deadline: Some(std::time::Instant::now()),
    };
    for path in [CellPath::Lanes, CellPath::CellByCell] {
        let map = job.run_with(path, past, &|_, _| {}).unwrap().unwrap();
        // Both look at the clock before the first step.
        assert_eq!(map.unfinished.len(), N * N, "{path:?}");
        assert_eq!(map.steps, 0);
    }
    let cancel = std::sync::atomic::AtomicBool::new(true);
    let cancelled = Budget {
        cancel: Some(&cancel),
        deadline: None,
    };
    for path in [CellPath::Lanes, CellPath::CellByCell] {
        assert!(job.run_with(path, cancelled, &|_, _| {}).unwrap().is_none());
    }
}

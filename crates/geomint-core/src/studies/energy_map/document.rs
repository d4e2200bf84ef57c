//! The map as the service answers it: the document with its summary and boundary curve, the
//! progress lines of its stream, and the run that reports them.

use serde::Serialize;

use super::{run_on, EnergyMapCells, EnergyMapJob};
use crate::error::{CoreError, ErrorDetail};
use crate::run::Budget;
use crate::studies::engine::Executor;
use crate::studies::StudyCompletion;

/// Points on the analytic boundary curve.
const BOUNDARY_POINTS: usize = 360;

/// Counts over the map.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct MapSummary {
    /// Cells in the grid.
    pub cells: usize,
    /// Cells where ε(x,y) < ε(r,θ): Cartesian coordinates are more accurate.
    pub cartesian_better: usize,
    /// Cells where ε(r,θ) < ε(x,y).
    pub polar_better: usize,
    /// Cells whose polar run diverged.
    pub polar_diverged: usize,
    /// Cells whose Cartesian run diverged (the pivot only, where the spring has no direction).
    pub cartesian_diverged: usize,
    /// Cells in the region where Sec. 4.1 predicts the polar run to pass through the pivot.
    pub predicted_divergent: usize,
    /// Polar divergences outside that region (near its boundary, where the discrete motion
    /// reaches a little further than the exact one).
    pub diverged_outside_prediction: usize,
}

/// The map. Per-cell arrays are row-major: entry j·nx + i belongs to (x₀, y₀) = (xs[i], ys[j]).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct EnergyMapDocument {
    /// The method's label.
    pub method: String,
    /// m, k, l, g.
    pub params: MapParams,
    /// Step size.
    pub h: f64,
    /// Final time.
    pub t_max: f64,
    /// Steps per cell and chart.
    pub steps_per_run: u64,
    /// Grid x₀ values.
    pub xs: Vec<f64>,
    /// Grid y₀ values.
    pub ys: Vec<f64>,
    /// H at the start of each cell (p₀ = 0); `null` where it overflows (a start so far out that
    /// the cell is blown up at t = 0).
    #[cfg_attr(feature = "openapi", schema(value_type = Vec<Option<f64>>))]
    pub energy: Vec<f64>,
    /// ℓ² energy error of eq. (50) in Cartesian coordinates (`null`: diverged, or not run).
    pub epsilon_cartesian: Vec<Option<f64>>,
    /// ℓ² energy error in polar coordinates (`null`: diverged, the pivot, or not run).
    pub epsilon_polar: Vec<Option<f64>>,
    /// ε(x,y) − ε(r,θ) where both exist.
    pub difference: Vec<Option<f64>>,
    /// Time at which the polar run diverged (`null`: it did not).
    pub polar_diverged_at: Vec<Option<f64>>,
    /// Time at which the Cartesian run diverged.
    pub cartesian_diverged_at: Vec<Option<f64>>,
    /// Whether r₀ ≥ 2l + 2mg/k·cos θ₀ (Sec. 4.1).
    pub predicted_divergent: Vec<bool>,
    /// The boundary r = 2l + 2mg/k·cos θ as (x, y) points.
    pub boundary: Vec<[f64; 2]>,
    /// Counts.
    pub summary: MapSummary,
    /// Steps taken in all.
    pub steps: u64,
    /// Wall time in milliseconds.
    pub wall_ms: f64,
    /// `time_limit` when the time limit stopped some cells before they finished.
    pub stop: StudyCompletion,
    /// The cells the time limit stopped (their ε and divergence times are `null`), in order.
    pub unfinished_cells: Vec<usize>,
}

/// The pendulum's parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct MapParams {
    /// Mass.
    pub m: f64,
    /// Stiffness.
    pub k: f64,
    /// Rest length.
    pub l: f64,
    /// Gravity.
    pub g: f64,
}

/// What a map's progress stream carries.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum MapLine {
    /// Cells done so far (sent at most about 100 times per map).
    Progress {
        /// Cells done.
        done: usize,
        /// Cells in all.
        total: usize,
    },
    /// The map.
    Result(Box<EnergyMapDocument>),
    /// A failure.
    Error {
        /// What went wrong.
        error: ErrorDetail,
    },
    /// The last line of a complete stream.
    End,
}

/// Runs the map on `executor`, reporting progress about every 1 % of the cells; an error when
/// the cancellation flag stopped it, the cells it finished when the time limit did.
pub fn run<E: Executor>(
    job: &EnergyMapJob,
    executor: &E,
    budget: Budget<'_>,
    emit: &(dyn Fn(MapLine) -> bool + Sync),
) -> Result<EnergyMapDocument, CoreError> {
    let progress = |done, total| {
        emit(MapLine::Progress { done, total });
    };
    let finished = run_on(job, executor, budget, &progress)?;
    Ok(document(job, job.map_of(&finished), finished.wall_ms))
}

fn document(spec: &EnergyMapJob, map: EnergyMapCells, wall_ms: f64) -> EnergyMapDocument {
    let difference = map.difference();
    let polar_diverged_at: Vec<Option<f64>> = map.polar.iter().map(|r| r.diverged_at).collect();
    let cartesian_diverged_at: Vec<Option<f64>> =
        map.cartesian.iter().map(|r| r.diverged_at).collect();
    let summary = MapSummary {
        cells: difference.len(),
        cartesian_better: difference.iter().flatten().filter(|&&d| d < 0.0).count(),
        polar_better: difference.iter().flatten().filter(|&&d| d > 0.0).count(),
        polar_diverged: polar_diverged_at.iter().flatten().count(),
        cartesian_diverged: cartesian_diverged_at.iter().flatten().count(),
        predicted_divergent: map.predicted_divergent.iter().filter(|&&p| p).count(),
        diverged_outside_prediction: polar_diverged_at
            .iter()
            .zip(&map.predicted_divergent)
            .filter(|(d, &p)| d.is_some() && !p)
            .count(),
    };
    let s = &spec.pendulum;
    EnergyMapDocument {
        method: map.method,
        params: MapParams {
            m: s.m,
            k: s.k,
            l: s.l,
            g: s.g,
        },
        h: spec.h,
        t_max: spec.t_max,
        steps_per_run: spec.steps,
        boundary: spec.boundary(BOUNDARY_POINTS),
        xs: map.xs,
        ys: map.ys,
        energy: map.energy,
        epsilon_cartesian: map.cartesian.iter().map(|r| r.epsilon).collect(),
        epsilon_polar: map.polar.iter().map(|r| r.epsilon).collect(),
        difference,
        polar_diverged_at,
        cartesian_diverged_at,
        predicted_divergent: map.predicted_divergent,
        summary,
        steps: map.steps,
        wall_ms,
        stop: if map.unfinished.is_empty() {
            StudyCompletion::Finished
        } else {
            StudyCompletion::TimeLimit
        },
        unfinished_cells: map.unfinished,
    }
}

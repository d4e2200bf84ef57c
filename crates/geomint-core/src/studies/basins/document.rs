//! A basin map's document: per run the labels, decision times, the attractors' table, the
//! shares and the metrics; and the lines of its progress stream.

use serde::Serialize;

use super::landscape::CriticalPoint;
use super::metrics::BasinMetrics;
use super::outcome::OrbitOutcome;
use crate::error::ErrorDetail;
use crate::studies::sweep::{AxisDocument, RunLabel};
use crate::studies::StudyCompletion;
use crate::systems::wrap_angle;

/// What kind of outcome a label stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
// Its schema kept the name it was published under.
#[cfg_attr(feature = "openapi", schema(as = Kind))]
pub enum AttractorKind {
    /// A damped orbit settles at a minimum of V (the equilibrium, p = 0), or an orbit starts at
    /// rest on a critical point.
    Equilibrium,
    /// An undamped orbit is trapped in a minimum's well for good.
    Well,
    /// A periodic orbit of the driven system's stroboscopic map.
    Periodic,
    /// The orbit left through an exit.
    Exit,
    /// The orbit escaped to infinity without an exit.
    Diverged,
    /// The orbit was still inside at t_end (a map with exits).
    Stayed,
    /// An attractor the request named, recognised by proximity.
    Given,
}

/// One label's entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Attractor {
    /// The label cells carry.
    pub label: i64,
    /// Its kind.
    pub kind: AttractorKind,
    /// Its name in words (`equilibrium 2 (minimum)`, an exit's name, `period-3 orbit 1`).
    pub name: String,
    /// The period, in driving periods, of a periodic orbit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub period: Option<usize>,
    /// The critical point of V (position, energy, Hessian eigenvalues) of an equilibrium or a
    /// well.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub equilibrium: Option<CriticalPoint>,
    /// The stroboscopic points of a periodic orbit, or a given attractor's points, each (q, p)
    /// without the clock.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<Vec<f64>>,
    /// A given attractor's radius.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    /// Cells with this label.
    pub cells: usize,
    #[serde(skip)]
    pub(super) outcome: OrbitOutcome,
}

impl Attractor {
    /// Whether `outcome` is this attractor: the same well, exit or kind, or a periodic orbit of
    /// the same period whose points lie within 10⁻³ (relative) of these, the components that are
    /// `angles` compared modulo 2π (an orbit through θ = π may be stored at +π in one cell and
    /// just above −π in another).
    pub(super) fn matches(&self, outcome: &OrbitOutcome, angles: &[bool]) -> bool {
        let gap = |k: usize, u: f64, v: f64| {
            if angles.get(k).copied().unwrap_or(false) {
                wrap_angle(u - v).abs()
            } else {
                (u - v).abs()
            }
        };
        match (&self.outcome, outcome) {
            (OrbitOutcome::Cycle { points: a }, OrbitOutcome::Cycle { points: b }) => {
                a.len() == b.len()
                    && (0..b.len()).any(|shift| {
                        a.iter().enumerate().all(|(j, x)| {
                            let y = &b[(j + shift) % b.len()];
                            x.iter()
                                .zip(y)
                                .enumerate()
                                .all(|(k, (&u, &v))| gap(k, u, v) <= 1e-3 * (1.0 + u.abs()))
                        })
                    })
            }
            (a, b) => a == b,
        }
    }
}

/// A cell without a label, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct UndecidedCell {
    /// The cell.
    pub cell: usize,
    /// Why it has no label.
    pub reason: String,
}

/// How many cells each criterion decided.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DecidedBy {
    /// The energy argument (an equilibrium's or a well's).
    pub energy: usize,
    /// A located exit crossing.
    pub exit: usize,
    /// Recurrence on the stroboscopic map.
    pub recurrence: usize,
    /// Proximity to a given attractor.
    pub proximity: usize,
    /// Divergence.
    pub divergence: usize,
    /// Reaching t_end inside (a map with exits).
    pub t_end: usize,
    /// Nothing: undecided or failed.
    pub undecided: usize,
}

/// One run's map.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct BasinRun {
    /// The method and chart.
    pub label: RunLabel,
    /// One label per cell in cell order (the first axis fastest); −1 where undecided.
    pub labels: Vec<i64>,
    /// When each cell's outcome was decided (null where undecided).
    pub decided_at: Vec<Option<f64>>,
    /// The labels' entries, in label order.
    pub attractors: Vec<Attractor>,
    /// Each label's share of the cells that start an orbit.
    pub fractions: Vec<f64>,
    /// The share of the cells that start an orbit left undecided.
    pub undecided_fraction: f64,
    /// Cells that start no orbit (off the energy surface, outside the chart): label −1, their
    /// reason in `undecided`, left out of the shares and the metrics.
    pub not_started: usize,
    /// The cells without a label and why.
    pub undecided: Vec<UndecidedCell>,
    /// Cells per criterion.
    pub decided_by: DecidedBy,
    /// The largest energy margin the energy argument used (twice the method's largest energy
    /// rise on the orbit before it decided).
    pub largest_energy_margin: Option<f64>,
    /// Basin entropy, boundary basin entropy, uncertainty exponent.
    #[serde(flatten)]
    pub metrics: BasinMetrics,
    /// Steps over all cells.
    pub steps: u64,
}

/// A basin map.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct BasinsDocument {
    /// The system's id.
    pub system: String,
    /// The axes.
    pub axes: Vec<AxisDocument>,
    /// Cells in all.
    pub cells: usize,
    /// The exits' names, in exit order.
    pub exits: Vec<String>,
    /// The critical points of V the search found (systems nothing drives), minima first.
    pub equilibria: Option<Vec<CriticalPoint>>,
    /// The lowest critical value that is not a minimum: below it (less the margin) the energy
    /// argument decides.
    pub lowest_saddle_energy: Option<f64>,
    /// One map per method and chart.
    pub runs: Vec<BasinRun>,
    /// The request's identity.
    pub digest: String,
    /// Wall time in milliseconds.
    pub wall_ms: f64,
    /// Whether every cell was run.
    pub stop: StudyCompletion,
    /// The cells the time limit left unrun.
    pub unfinished_cells: Vec<usize>,
}

/// What a basin map's progress stream carries.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum BasinsLine {
    /// Cells done so far (sent at most about 100 times per map).
    Progress {
        /// Cells done.
        done: usize,
        /// Cells in all.
        total: usize,
    },
    /// The map.
    Result(Box<BasinsDocument>),
    /// A failure.
    Error {
        /// What went wrong.
        error: ErrorDetail,
    },
    /// The last line of a complete stream.
    End,
}

//! Studies: computations over many runs, each a pure function from a typed spec to a typed
//! result, with progress reported as it goes.
//!
//! - [`convergence`]: errors at t_end against the step size, per method and chart, with the
//!   fitted orders.
//! - [`work_precision`]: wall time against energy error, per method and setting.
//! - [`energy_map`]: energy-error maps of the planar elastic pendulum, Cartesian against polar
//!   coordinates (paper 001 Fig. 6), cells in parallel.
//! - [`stability`]: linear stability maps over (γ, h) and the analysis at one point (paper 003
//!   Ch. 3).
//! - [`sweep`]: any system over a grid of one or two axes (parameters, step size, initial
//!   state), per cell and run energy errors, invariant drift and divergence; sharded.
//! - [`settings`]: what the settings-based studies share.
//!
//! A study that reaches its time limit answers with what it finished (as a run does), marked
//! [`StudyStop::TimeLimit`], rather than failing: the time limit depends on the machine's load,
//! and the finished part is the client's.

pub mod convergence;
pub mod energy_map;
pub mod engine;
pub mod parts;
pub mod settings;
pub mod stability;
pub mod sweep;
pub mod work_precision;

/// Whether a study did all its work.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum StudyStop {
    /// Everything was computed.
    Finished,
    /// The time limit passed first: what was not finished is marked so in the document.
    TimeLimit,
}

/// A study's spec as it travels: to NATS workers, and inside part files, so that a worker or a
/// merge prepares exactly the study the server or the first array task prepared.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StudySpec {
    /// A sweep (energy maps run as sweeps too).
    Sweep(sweep::SweepSpec),
    /// Linear stability maps.
    Stability(stability::StabilitySpec),
    /// A convergence study.
    Convergence(convergence::ConvergenceSpec),
    /// A work–precision study.
    WorkPrecision(work_precision::WorkPrecisionSpec),
}

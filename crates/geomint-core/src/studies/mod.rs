//! Studies: computations over many runs, each a pure function from a typed spec to a typed
//! result, run by one engine ([`engine`]): a study is a list of independent cells, an executor
//! runs them (all cores here, a shard of them in an array task, NATS workers in the service),
//! and progress, cancellation and time limits are the engine's. Every study below is such a list
//! and runs wherever the engine runs; [`parts`] cuts studies into shards and puts them back.
//!
//! - [`sweep`]: any system over a grid of one or two axes (parameters, step size, initial
//!   state), per cell and run energy errors, invariant drift and divergence.
//! - [`energy_map`]: energy-error maps of the planar elastic pendulum, Cartesian against polar
//!   coordinates (paper 001 Fig. 6): a sweep, and its document.
//! - [`basins`]: where each orbit of a grid of initial states ends up (an equilibrium, a
//!   periodic orbit of a driven system, an exit), decided cell by cell as early as it can be,
//!   with the basin entropy and the uncertainty exponent.
//! - [`stability`]: linear stability maps over (γ, h), a cell per row, and the analysis at one
//!   point (paper 003 Ch. 3).
//! - [`convergence`]: errors at t_end against the step size, per method and chart, with the
//!   fitted orders; a cell per setting.
//! - [`work_precision`]: wall time against energy error, per method and setting; its cells are
//!   timed one at a time.
//! - [`settings`]: what the settings-based studies share (a setting, the truth, progress);
//!   [`measure`]: one setting's errors and timings.
//!
//! To add a study: a spec that prepares into a job implementing [`engine::Study`] (its cells and
//! what one cell computes), a variant of [`StudySpec`] so that workers can prepare it, and a
//! document made from the engine's [`engine::Finished`] cells.
//!
//! A study that reaches its time limit answers with what it finished (as a run does), marked
//! [`StudyStop::TimeLimit`], rather than failing: the time limit depends on the machine's load,
//! and the finished part is the client's.

pub mod basins;
pub mod convergence;
pub mod energy_map;
pub mod engine;
pub mod measure;
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
    /// A basin map.
    Basins(basins::BasinsSpec),
}

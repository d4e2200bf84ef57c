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
//! what one cell computes), [`parts::Travelling`] for the spec (how a worker runs a shard of it)
//! and its line in `travelling_studies!` below, and a document made from the engine's
//! [`engine::Finished`] cells.
//!
//! A study that reaches its time limit answers with what it finished (as a run does), marked
//! [`StudyCompletion::TimeLimit`], rather than failing: the time limit depends on the machine's load,
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

/// Whether a study did all its work (its documents' `stop`; `StudyStop` in the OpenAPI
/// document, the name it has always had there).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = StudyStop))]
#[serde(rename_all = "snake_case")]
pub enum StudyCompletion {
    /// Everything was computed.
    Finished,
    /// The time limit passed first: what was not finished is marked so in the document.
    TimeLimit,
}

/// Every study that travels — to NATS workers, into part files — one line each: its variant of
/// [`StudySpec`] and of [`parts::AnyPart`], from its spec's type, which says how a shard of it
/// runs ([`parts::Travelling`], implemented beside the study).
macro_rules! travelling_studies {
    ($($(#[$doc:meta])* $variant:ident($spec:ty),)+) => {
        /// A study's spec as it travels: to NATS workers, and inside part files, so that a
        /// worker or a merge prepares exactly the study the server or the first array task
        /// prepared.
        #[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(tag = "kind", rename_all = "snake_case")]
        pub enum StudySpec {
            $($(#[$doc])* $variant($spec),)+
        }

        /// A part of any kind of study, as a worker sends it (the receiver knows the kind it
        /// asked for, and reads the cells as that kind's).
        #[derive(Clone, Debug, serde::Serialize)]
        #[serde(untagged)]
        pub enum AnyPart {
            $($(#[$doc])* $variant(parts::Part<<$spec as parts::Travelling>::Cell>),)+
        }

        impl AnyPart {
            /// How many cells it holds.
            pub fn len(&self) -> usize {
                match self {
                    $(AnyPart::$variant(part) => part.cells.len(),)+
                }
            }

            /// Whether it holds no cell.
            pub fn is_empty(&self) -> bool {
                self.len() == 0
            }

            /// Its wall time in milliseconds.
            pub fn wall_ms(&self) -> f64 {
                match self {
                    $(AnyPart::$variant(part) => part.wall_ms,)+
                }
            }
        }

        impl StudySpec {
            /// Prepares the study within `limits` and runs its shard `shard` of the cells
            /// `within` (or of all) here, to the end.
            pub(crate) fn run_part(
                &self,
                shard: parts::Shard,
                within: Option<std::ops::Range<usize>>,
                limits: &crate::simulation::Limits,
                done: &(dyn Fn() + Sync),
            ) -> Result<AnyPart, crate::error::CoreError> {
                use parts::Travelling;
                let at = parts::ShardAt {
                    spec: self,
                    shard,
                    within,
                    done,
                };
                match self {
                    $(StudySpec::$variant(spec) => spec.run_shard(&at, limits).map(AnyPart::$variant),)+
                }
            }
        }
    };
}

travelling_studies! {
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

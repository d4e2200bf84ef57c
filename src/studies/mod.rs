//! Every kind of study the service runs, each in one module that says how it is read from its
//! request, run, streamed, recorded and reported. What runs a study is written once over
//! [`StudyKind`]: the HTTP routes ([`crate::http::studies`]), the command line (`geomint study
//! KIND`, whole, one `--shard` of it, or `merge` of the shards' parts; [`crate::cli::study`])
//! and jobs ([`crate::jobs`]). [`NAMES`] and [`visit`] list the kinds, from one registry line
//! each.
//!
//! To add a study: its spec, job and document in the core ([`crate::core::studies`]), a module
//! here implementing [`StudyKind`], its line in the registry below, and its route (a function
//! with the route's OpenAPI description that calls [`crate::http::studies`]' generic answer).

/// The methods of a kind whose job (`self.job`) is a study made from its cells alone
/// ([`crate::core::studies::engine::Documented`]), with its spec in `self.spec`: sweeps and
/// basin maps, which run, stream and shard alike.
macro_rules! documented_kind {
    ($line:ty, $document:ty) => {
        fn spec(&self) -> StudySpec {
            self.spec.clone()
        }

        fn cells(&self) -> usize {
            self.job.cells()
        }

        fn steps(&self) -> u64 {
            self.job.steps()
        }

        fn group(&self) -> usize {
            self.job.group()
        }

        fn run<E: Executor>(
            &self,
            executor: &E,
            budget: Budget<'_>,
            emit: &(dyn Fn($line) -> bool + Sync),
        ) -> Result<$document, CoreError> {
            engine::run_documented(&self.job, executor, budget, emit)
        }

        fn result_line(document: $document) -> $line {
            <$line as CellLine>::result(document)
        }

        fn error_line(error: ErrorDetail) -> $line {
            <$line as CellLine>::error(error)
        }

        fn end_line() -> $line {
            <$line as CellLine>::end()
        }

        fn summary(&self, document: &$document) -> Option<String> {
            Some(format!("{:.1} s", document.wall_ms / 1e3))
        }
    };
}

/// The methods of a kind whose job (`self.job`) is a settings study
/// ([`crate::core::studies::settings::StudyJob`]) run by `$run`, with its spec in `self.spec`:
/// convergence and work–precision studies.
macro_rules! settings_kind {
    ($line:ty, $document:ty, $run:path) => {
        fn spec(&self) -> StudySpec {
            self.spec.clone()
        }

        fn cells(&self) -> usize {
            self.job.len()
        }

        fn steps(&self) -> u64 {
            self.job
                .settings
                .iter()
                .fold(0u64, |n, (_, sim)| n.saturating_add(sim.schedule.steps))
        }

        fn run<E: Executor>(
            &self,
            executor: &E,
            budget: Budget<'_>,
            emit: &(dyn Fn($line) -> bool + Sync),
        ) -> Result<$document, CoreError> {
            $run(&self.job, executor, budget, emit)
        }

        fn result_line(document: $document) -> $line {
            <$line as ProgressLine>::result(document)
        }

        fn error_line(error: ErrorDetail) -> $line {
            <$line as ProgressLine>::error(error)
        }

        fn end_line() -> $line {
            <$line as ProgressLine>::end()
        }
    };
}

/// How the command line reports a settings study's reference run.
pub(crate) fn reference_report(reference: &str, reference_ms: f64, total: usize) -> Report {
    Report::Line(format!(
        "errors against the {reference} ({reference_ms:.0} ms); {total} settings"
    ))
}

/// An error as the command line reports it: in scientific notation, `-` where there is none.
pub(crate) fn error_text(error: Option<f64>) -> String {
    error.map_or("-".into(), |e| format!("{e:.2e}"))
}

pub mod basins;
pub mod convergence;
pub mod energy_map;
pub mod merged;
pub mod stability;
pub mod sweep;
pub mod work_precision;

use serde::Serialize;
use serde_json::Value;

use crate::api::system::StoredSystems;
use crate::core::error::{CoreError, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::engine::{Executor, Order};
use crate::core::studies::StudySpec;
use crate::recording::RecordingError;

/// How a study's route answers besides its JSON document.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Answers {
    /// NDJSON progress lines, then the result.
    pub stream: bool,
    /// Its Rerun recording, as an attachment of this name.
    pub recording: Option<&'static str>,
}

/// A line of a study's progress as the command line reports it on standard error.
#[derive(Clone, Debug, PartialEq)]
pub enum Report {
    /// Cells done so far, written over the last count.
    Cells {
        /// Cells done.
        done: usize,
        /// Cells in all.
        total: usize,
    },
    /// A line of text.
    Line(String),
}

/// A kind of study, read and prepared: everything the routes, the command line and jobs need.
pub trait StudyKind: Sized + Send + Sync + 'static {
    /// Its name: the last segment of its route, `geomint study NAME`, a job's `study`.
    const NAME: &'static str;
    /// What it computes, in a line (`geomint study --help`).
    const ABOUT: &'static str;
    /// How its route answers besides JSON.
    const ANSWERS: Answers;

    /// Its document.
    type Document: Serialize + Send + 'static;
    /// A line of its NDJSON stream (a kind that does not stream never makes one).
    type Line: Serialize + Send + 'static;

    /// Reads `request` (its route's body) and prepares the study within `limits`, with the
    /// stored systems `systems`; errors name fields inside `request`.
    fn prepare(
        request: &Value,
        systems: &dyn StoredSystems,
        limits: &Limits,
    ) -> Result<Self, ErrorDetail>;

    /// Prepares it from the spec a part carries, where its document and recording need nothing
    /// else: `merge` prefers it, since a spec has stored systems written out (and parts written
    /// before they carried their request have only it); `None` for a kind that needs its
    /// request.
    fn from_spec(_spec: &StudySpec, _limits: &Limits) -> Option<Result<Self, CoreError>> {
        None
    }

    /// Its spec as it travels to workers and into parts.
    fn spec(&self) -> StudySpec;

    /// The request a part file carries for `merge` to prepare the study again from, read
    /// anywhere: `request` as given, or with stored systems written out where the kind's
    /// document or recording needs the request itself.
    fn portable_request(&self, request: &Value) -> Value {
        request.clone()
    }

    /// The limits its shards run under, from the command line's `limits`: those of the whole
    /// study (an energy map's runs are bounded by its total only).
    fn shard_limits(&self, limits: &Limits) -> Limits {
        *limits
    }

    /// Its cells: grid points, rows or settings.
    fn cells(&self) -> usize;

    /// About how many steps it takes in all.
    fn steps(&self) -> u64;

    /// Cells that run together in SIMD lanes: a part holds a whole number of groups.
    fn group(&self) -> usize {
        1
    }

    /// How its cells may run: in parallel, or one at a time where they are timed.
    fn order(&self) -> Order {
        Order::Parallel
    }

    /// Runs it on `executor` to its document, reporting progress lines through `emit` (which
    /// answers false once nobody listens).
    fn run<E: Executor>(
        &self,
        executor: &E,
        budget: Budget<'_>,
        emit: &(dyn Fn(Self::Line) -> bool + Sync),
    ) -> Result<Self::Document, CoreError>;

    /// The stream's line carrying the document.
    fn result_line(document: Self::Document) -> Self::Line;
    /// The stream's line carrying a failure.
    fn error_line(error: ErrorDetail) -> Self::Line;
    /// The stream's last line.
    fn end_line() -> Self::Line;

    /// Its recording of `document` (called only when [`StudyKind::ANSWERS`] names one).
    fn record(&self, document: &Self::Document) -> Result<Vec<u8>, RecordingError>;

    /// How the command line reports `line` (nothing for `None`).
    fn report(line: &Self::Line) -> Option<Report>;

    /// What the command line says once the document is made.
    fn summary(&self, _document: &Self::Document) -> Option<String> {
        None
    }
}

/// What is done with a kind once it is found by name: [`visit`] calls [`Visit::kind`] with it.
pub trait Visit {
    /// What the visit gives.
    type Output;
    /// Does it with the kind `K`.
    fn kind<K: StudyKind>(self) -> Self::Output;
}

/// The registry: every kind of study, one line each.
macro_rules! registry {
    ($($kind:ty),+ $(,)?) => {
        /// Every kind of study by name, in the registry's order.
        pub const NAMES: &[&str] = &[$(<$kind as StudyKind>::NAME),+];

        /// Every kind's name with its line of description.
        pub fn about() -> Vec<(&'static str, &'static str)> {
            vec![$((<$kind as StudyKind>::NAME, <$kind as StudyKind>::ABOUT)),+]
        }

        /// Calls `visit` with the kind named `name`; `None` if there is no such kind.
        pub fn visit<V: Visit>(name: &str, visit: V) -> Option<V::Output> {
            $(if name == <$kind as StudyKind>::NAME {
                return Some(visit.kind::<$kind>());
            })+
            None
        }
    };
}

registry!(
    sweep::Sweep,
    basins::Basins,
    energy_map::EnergyMap,
    stability::Stability,
    convergence::Convergence,
    work_precision::WorkPrecision,
);

/// The error for a study name that is no kind's, at `field`.
pub fn unknown(field: &str, name: &str) -> ErrorDetail {
    ErrorDetail::at(
        crate::core::error::ErrorCode::InvalidValue,
        field,
        format!("unknown study `{name}`; one of {}", NAMES.join(", ")),
    )
}

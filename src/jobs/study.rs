//! The studies a job can run — every study route's — each read from the body its route takes,
//! prepared as that route prepares it, and run on a job's executor to the same document.

use serde_json::Value;

use super::stored::Stored;
use crate::core::error::{CoreError, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::store::systems::SystemStore;
use crate::studies::{self, StudyKind, Visit};

/// A finished study's document: its JSON, and its Rerun recording where the study has one.
pub struct Results {
    /// The document as the study's route answers it.
    pub json: Vec<u8>,
    /// The recording, as the route answers `?format=rrd`.
    pub rrd: Option<Vec<u8>>,
}

type Compute = Box<dyn FnOnce(&Stored<'_>, Budget<'_>) -> Result<Results, CoreError> + Send>;

/// A study read and prepared, ready to run on a job's executor.
pub struct Prepared {
    /// Its cells.
    pub cells: usize,
    /// About how many steps it takes.
    pub steps: u64,
    /// Cells that run together (SIMD lanes): a part holds a whole number of groups.
    pub group: usize,
    compute: Compute,
}

impl Prepared {
    /// Runs the study on `executor` to its document.
    pub fn run(self, executor: &Stored<'_>, budget: Budget<'_>) -> Result<Results, CoreError> {
        (self.compute)(executor, budget)
    }

    /// `study`, to run to its JSON document and its recording where it has one.
    fn of<K: StudyKind>(study: K) -> Prepared {
        Prepared {
            cells: study.cells(),
            steps: study.steps(),
            group: study.group(),
            compute: Box::new(move |executor, budget| {
                let doc = study.run(executor, budget, &|_| true)?;
                let fault = |e: String| CoreError::Executor { message: e };
                Ok(Results {
                    json: serde_json::to_vec(&doc).map_err(|e| fault(e.to_string()))?,
                    rrd: K::ANSWERS
                        .recording
                        .map(|_| study.record(&doc).map_err(|e| fault(e.to_string())))
                        .transpose()?,
                })
            }),
        }
    }
}

/// Reads and prepares the study `study` from `request` as its route would (errors name fields
/// inside `request`).
pub fn prepare(
    study: &str,
    request: &Value,
    systems: &SystemStore,
    limits: &Limits,
) -> Result<Prepared, ErrorDetail> {
    let read = Read {
        request,
        systems,
        limits,
    };
    studies::visit(study, read)
        .ok_or_else(|| studies::unknown("study", study))?
        .map_err(|e| within("request", e))
}

/// Reads and prepares the kind of study visited.
struct Read<'a> {
    request: &'a Value,
    systems: &'a SystemStore,
    limits: &'a Limits,
}

impl Visit for Read<'_> {
    type Output = Result<Prepared, ErrorDetail>;
    fn kind<K: StudyKind>(self) -> Self::Output {
        K::prepare(self.request, self.systems, self.limits).map(Prepared::of)
    }
}

/// `error` for input nested under `field`: its field `f` becomes `field.f` (or `field[i]…`),
/// none becomes `field`.
fn within(field: &str, mut error: ErrorDetail) -> ErrorDetail {
    error.field = Some(match error.field.take() {
        Some(f) if f.starts_with('[') => format!("{field}{f}"),
        Some(f) if !f.is_empty() => format!("{field}.{f}"),
        _ => field.to_string(),
    });
    error
}

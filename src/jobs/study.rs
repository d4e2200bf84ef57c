//! The studies a job can run — every study route's — each read from the body its route takes,
//! prepared as that route prepares it, and run on a job's executor to the same document.

use serde::Serialize;
use serde_json::Value;

use super::stored::Stored;
use crate::api::basins::BasinsRequest;
use crate::api::stability::StabilityRequest;
use crate::api::studies::{ConvergenceRequest, EnergyMapRequest, WorkPrecisionRequest};
use crate::api::sweep::SweepRequest;
use crate::core::error::{CoreError, ErrorCode, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::engine::{self, CellLine, Documented, Study};
use crate::core::studies::settings::StudyJob;
use crate::core::studies::{convergence, energy_map, stability, work_precision};
use crate::recording::{self, RecordingError};
use crate::store::systems::SystemStore;

/// The kinds of study, named as their routes (`/api/v1/studies/NAME`, `/api/v1/stability`).
pub const STUDIES: [&str; 6] = [
    "sweep",
    "basins",
    "energy-map",
    "stability",
    "convergence",
    "work-precision",
];

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
}

fn results<D: Serialize>(
    doc: &D,
    record: Option<&dyn Fn(&D) -> Result<Vec<u8>, RecordingError>>,
) -> Result<Results, CoreError> {
    let fault = |e: String| CoreError::Executor { message: e };
    Ok(Results {
        json: serde_json::to_vec(doc).map_err(|e| fault(e.to_string()))?,
        rrd: record
            .map(|record| record(doc).map_err(|e| fault(e.to_string())))
            .transpose()?,
    })
}

/// A study whose document is made from its cells (a sweep, a basin map), with its recording.
fn documented<S: Documented + Send + 'static>(
    job: S,
    record: fn(&CellDocument<S>) -> Result<Vec<u8>, RecordingError>,
) -> Prepared {
    Prepared {
        cells: job.cells(),
        steps: job.steps(),
        group: job.group(),
        compute: Box::new(move |executor, budget| {
            let doc = engine::run_documented(&job, executor, budget, &|_| true)?;
            results(&doc, Some(&record))
        }),
    }
}

/// The document of a study made from its cells.
type CellDocument<S> = <<S as Documented>::Line as CellLine>::Document;

/// A settings study's cells and steps.
fn settings_size(job: &StudyJob) -> (usize, u64) {
    let steps = job
        .settings
        .iter()
        .fold(0u64, |n, (_, sim)| n.saturating_add(sim.schedule.steps));
    (job.len(), steps)
}

/// Reads and prepares the study `study` from `request` as its route would (errors name fields
/// inside `request`).
pub fn prepare(
    study: &str,
    request: &Value,
    systems: &SystemStore,
    limits: &Limits,
) -> Result<Prepared, ErrorDetail> {
    if !STUDIES.contains(&study) {
        return Err(unknown_study(study));
    }
    prepare_kind(study, request, systems, limits).map_err(|e| within("request", e))
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

fn unknown_study(study: &str) -> ErrorDetail {
    ErrorDetail::at(
        ErrorCode::InvalidValue,
        "study",
        format!("unknown study `{study}`; one of {}", STUDIES.join(", ")),
    )
}

fn prepare_kind(
    study: &str,
    body: &Value,
    systems: &SystemStore,
    limits: &Limits,
) -> Result<Prepared, ErrorDetail> {
    Ok(match study {
        "sweep" => {
            let job = SweepRequest::from_value(body)?
                .to_spec(systems)?
                .prepare(limits)?;
            documented(job, recording::sweep::rrd_bytes)
        }
        "basins" => {
            let (request, sweep) = BasinsRequest::from_value(body)?;
            let job = request.to_spec(&sweep, systems)?.prepare(limits)?;
            documented(job, recording::basins::rrd_bytes)
        }
        "energy-map" => {
            let job = EnergyMapRequest::from_value(body)?.to_spec()?.prepare()?;
            Prepared {
                cells: job.sweep().cells(),
                steps: job.sweep().steps(),
                group: job.sweep().group(),
                compute: Box::new(move |executor, budget| {
                    let doc = energy_map::run(&job, executor, budget, &|_| true)?;
                    results(&doc, Some(&recording::energy_map::rrd_bytes))
                }),
            }
        }
        "stability" => {
            let request = StabilityRequest::from_value(body)?;
            let job = request.to_spec()?.prepare()?;
            Prepared {
                cells: job.cells(),
                steps: job.steps(),
                group: job.group(),
                compute: Box::new(move |executor, budget| {
                    let doc = stability::maps(&job, executor, budget)?;
                    let spec = recording::Spec::of(&request);
                    results(&doc, Some(&|d| recording::stability::rrd_bytes(&spec, d)))
                }),
            }
        }
        "convergence" => {
            let job = ConvergenceRequest::from_value(body)?
                .to_spec(systems)?
                .prepare(limits)?;
            let (cells, steps) = settings_size(&job);
            Prepared {
                cells,
                steps,
                group: 1,
                compute: Box::new(move |executor, budget| {
                    let doc = convergence::run(&job, executor, budget, &|_| true)?;
                    results(&doc, None)
                }),
            }
        }
        "work-precision" => {
            let request = WorkPrecisionRequest::from_value(body)?;
            let job = request.to_spec(systems)?.prepare(limits)?;
            let request = request.inlined(systems);
            let (cells, steps) = settings_size(&job);
            Prepared {
                cells,
                steps,
                group: 1,
                compute: Box::new(move |executor, budget| {
                    let doc = work_precision::run(&job, executor, budget, &|_| true)?;
                    let spec = recording::Spec::of(&request);
                    results(
                        &doc,
                        Some(&|d| recording::work_precision::rrd_bytes(&spec, d)),
                    )
                }),
            }
        }
        other => return Err(unknown_study(other)),
    })
}

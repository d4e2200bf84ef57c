//! A work–precision study: wall time against energy error per method and setting, the settings
//! timed one at a time (`POST /api/v1/studies/work-precision`,
//! [`crate::core::studies::work_precision`]); a cell is a setting.

use serde_json::Value;

use super::{error_text, reference_report, Answers, Report, StudyKind};
use crate::api::studies::WorkPrecisionRequest;
use crate::api::system::StoredSystems;
use crate::core::error::{CoreError, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::engine::{Executor, Order};
use crate::core::studies::settings::{ProgressLine, StudyJob};
use crate::core::studies::work_precision::{self, StudyLine, WorkPrecisionDocument};
use crate::core::studies::StudySpec;
use crate::recording::{self, RecordingError};

/// A work–precision study, prepared, with its request (typed-in systems written out) for its
/// recording.
pub struct WorkPrecision {
    request: WorkPrecisionRequest,
    spec: StudySpec,
    job: StudyJob,
}

impl StudyKind for WorkPrecision {
    const NAME: &'static str = "work-precision";
    const ABOUT: &'static str = "Wall time against energy error per method and setting";
    const ANSWERS: Answers = Answers {
        stream: true,
        recording: Some("geomint-work-precision.rrd"),
    };
    type Document = WorkPrecisionDocument;
    type Line = StudyLine;

    fn prepare(
        request: &Value,
        systems: &dyn StoredSystems,
        limits: &Limits,
    ) -> Result<Self, ErrorDetail> {
        let request = WorkPrecisionRequest::from_value(request)?;
        let spec = request.to_spec(systems)?;
        let job = spec.prepare(limits)?;
        Ok(WorkPrecision {
            request: request.inlined(systems),
            spec: StudySpec::WorkPrecision(spec),
            job,
        })
    }

    fn portable_request(&self, request: &Value) -> Value {
        serde_json::to_value(&self.request).unwrap_or_else(|_| request.clone())
    }

    fn order(&self) -> Order {
        Order::Timed
    }

    settings_kind!(StudyLine, WorkPrecisionDocument, work_precision::run);

    fn record(&self, document: &WorkPrecisionDocument) -> Result<Vec<u8>, RecordingError> {
        recording::work_precision::rrd_bytes(&recording::Spec::of(&self.request), document)
    }

    fn report(line: &StudyLine) -> Option<Report> {
        match line {
            StudyLine::Reference {
                reference,
                reference_ms,
                total,
            } => Some(reference_report(reference, *reference_ms, *total)),
            StudyLine::Point { done, total, point } => Some(Report::Line(format!(
                "[{done}/{total}] {} {}: {:.3} ms, max energy error {}",
                point.method,
                point
                    .h
                    .map(|h| format!("h = {h}"))
                    .or(point.tolerance.map(|t| format!("tol = {t:e}")))
                    .unwrap_or_default(),
                point.wall_ms,
                error_text(point.max_energy_error)
            ))),
            _ => None,
        }
    }
}

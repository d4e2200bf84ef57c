//! A convergence study: errors at t_end against the step size per method and chart, with the
//! fitted orders (`POST /api/v1/studies/convergence`, [`crate::core::studies::convergence`]); a
//! cell is a setting. Its route answers JSON or a progress stream, without a recording.

use serde_json::Value;

use super::{error_text, reference_report, Answers, Report, StudyKind};
use crate::api::studies::ConvergenceRequest;
use crate::api::system::StoredSystems;
use crate::core::error::{CoreError, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::convergence::{self, ConvergenceDocument, ConvergenceLine};
use crate::core::studies::engine::Executor;
use crate::core::studies::settings::{ProgressLine, StudyJob};
use crate::core::studies::StudySpec;
use crate::recording::RecordingError;

/// A convergence study, prepared.
pub struct Convergence {
    spec: StudySpec,
    job: StudyJob,
}

impl StudyKind for Convergence {
    const NAME: &'static str = "convergence";
    const ABOUT: &'static str =
        "Errors at t_end against the step size per method and chart, with the fitted orders";
    const ANSWERS: Answers = Answers {
        stream: true,
        recording: None,
    };
    type Document = ConvergenceDocument;
    type Line = ConvergenceLine;

    fn prepare(
        request: &Value,
        systems: &dyn StoredSystems,
        limits: &Limits,
    ) -> Result<Self, ErrorDetail> {
        let spec = ConvergenceRequest::from_value(request)?.to_spec(systems)?;
        let job = spec.prepare(limits)?;
        Ok(Convergence {
            spec: StudySpec::Convergence(spec),
            job,
        })
    }

    fn from_spec(spec: &StudySpec, limits: &Limits) -> Option<Result<Self, CoreError>> {
        let StudySpec::Convergence(study) = spec else {
            return None;
        };
        Some(study.prepare(limits).map(|job| Convergence {
            spec: spec.clone(),
            job,
        }))
    }

    settings_kind!(ConvergenceLine, ConvergenceDocument, convergence::run);

    fn record(&self, _document: &ConvergenceDocument) -> Result<Vec<u8>, RecordingError> {
        Err(RecordingError::Unexpected(
            "a convergence study has no recording".into(),
        ))
    }

    fn report(line: &ConvergenceLine) -> Option<Report> {
        match line {
            ConvergenceLine::Reference {
                reference,
                reference_ms,
                total,
            } => Some(reference_report(reference, *reference_ms, *total)),
            ConvergenceLine::Point { done, total, point } => Some(Report::Line(format!(
                "[{done}/{total}] {} ({}) h = {}: state error {}, energy error {}, max {}",
                point.method,
                point.chart,
                point.h,
                error_text(point.state_error),
                error_text(point.energy_error),
                error_text(point.max_energy_error)
            ))),
            _ => None,
        }
    }
}

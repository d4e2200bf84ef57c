//! A sweep: any system over a grid of one or two axes, per cell and run its energy errors,
//! invariant drift and divergence (`POST /api/v1/studies/sweep`, [`crate::core::studies::sweep`]).

use serde_json::Value;

use super::{Answers, Report, StudyKind};
use crate::api::sweep::SweepRequest;
use crate::api::system::StoredSystems;
use crate::core::error::{CoreError, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::engine::{self, CellLine, Executor, Study};
use crate::core::studies::sweep::{SweepDocument, SweepJob, SweepLine};
use crate::core::studies::StudySpec;
use crate::recording::{self, RecordingError};

/// A sweep, prepared.
pub struct Sweep {
    spec: StudySpec,
    job: SweepJob,
}

impl StudyKind for Sweep {
    const NAME: &'static str = "sweep";
    const ABOUT: &'static str =
        "Any system over one or two axes: energy errors, invariant drift and divergence per cell";
    const ANSWERS: Answers = Answers {
        stream: true,
        recording: Some("geomint-sweep.rrd"),
    };
    type Document = SweepDocument;
    type Line = SweepLine;

    fn prepare(
        request: &Value,
        systems: &dyn StoredSystems,
        limits: &Limits,
    ) -> Result<Self, ErrorDetail> {
        let spec = SweepRequest::from_value(request)?.to_spec(systems)?;
        let job = spec.prepare(limits)?;
        Ok(Sweep {
            spec: StudySpec::Sweep(spec),
            job,
        })
    }

    fn from_spec(spec: &StudySpec, limits: &Limits) -> Option<Result<Self, CoreError>> {
        let StudySpec::Sweep(sweep) = spec else {
            return None;
        };
        Some(sweep.prepare(limits).map(|job| Sweep {
            spec: spec.clone(),
            job,
        }))
    }

    documented_kind!(SweepLine, SweepDocument);

    fn record(&self, document: &SweepDocument) -> Result<Vec<u8>, RecordingError> {
        recording::sweep::rrd_bytes(document)
    }

    fn report(line: &SweepLine) -> Option<Report> {
        match *line {
            SweepLine::Progress { done, total } => Some(Report::Cells { done, total }),
            _ => None,
        }
    }
}

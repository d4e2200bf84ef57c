//! A basin map: over a grid of initial states, where each orbit ends up — an attractor or an
//! exit — decided cell by cell as early as it can be (`POST /api/v1/studies/basins`,
//! [`crate::core::studies::basins`]).

use serde_json::Value;

use super::{Answers, Report, StudyKind};
use crate::api::basins::BasinsRequest;
use crate::api::system::StoredSystems;
use crate::core::error::{CoreError, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::basins::{BasinsDocument, BasinsJob, BasinsLine};
use crate::core::studies::engine::{self, CellLine, Executor, Study};
use crate::core::studies::StudySpec;
use crate::recording::{self, RecordingError};

/// A basin map, prepared.
pub struct Basins {
    spec: StudySpec,
    job: BasinsJob,
}

impl StudyKind for Basins {
    const NAME: &'static str = "basins";
    const ABOUT: &'static str =
        "Where each orbit of a grid of initial states ends up (attractors, exits), with basin metrics";
    const ANSWERS: Answers = Answers {
        stream: true,
        recording: Some("geomint-basins.rrd"),
    };
    type Document = BasinsDocument;
    type Line = BasinsLine;

    fn prepare(
        request: &Value,
        systems: &dyn StoredSystems,
        limits: &Limits,
    ) -> Result<Self, ErrorDetail> {
        let (request, sweep) = BasinsRequest::from_value(request)?;
        let spec = request.to_spec(&sweep, systems)?;
        let job = spec.prepare(limits)?;
        Ok(Basins {
            spec: StudySpec::Basins(spec),
            job,
        })
    }

    fn from_spec(spec: &StudySpec, limits: &Limits) -> Option<Result<Self, CoreError>> {
        let StudySpec::Basins(map) = spec else {
            return None;
        };
        Some(map.prepare(limits).map(|job| Basins {
            spec: spec.clone(),
            job,
        }))
    }

    documented_kind!(BasinsLine, BasinsDocument);

    fn record(&self, document: &BasinsDocument) -> Result<Vec<u8>, RecordingError> {
        recording::basins::rrd_bytes(document)
    }

    fn report(line: &BasinsLine) -> Option<Report> {
        match *line {
            BasinsLine::Progress { done, total } => Some(Report::Cells { done, total }),
            _ => None,
        }
    }
}

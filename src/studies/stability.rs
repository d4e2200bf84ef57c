//! Linear stability maps of the damped oscillator over (γ, h), one per method (paper 003 Ch. 3;
//! `POST /api/v1/stability`, [`crate::core::studies::stability`]); a cell is a row of the
//! maps. Its route answers JSON or a recording, without a progress stream.

use serde_json::Value;

use super::{Answers, Report, StudyKind};
use crate::api::stability::StabilityRequest;
use crate::api::system::StoredSystems;
use crate::core::error::{CoreError, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::engine::{Executor, Study};
use crate::core::studies::stability::{self, StabilityDocument, StabilityJob};
use crate::core::studies::StudySpec;
use crate::recording::{self, RecordingError};

/// Stability maps, prepared, with the request their recording shows.
pub struct Stability {
    request: StabilityRequest,
    job: StabilityJob,
}

impl StudyKind for Stability {
    const NAME: &'static str = "stability";
    const ABOUT: &'static str =
        "Linear stability maps of the damped oscillator over (gamma, h), one per method";
    const ANSWERS: Answers = Answers {
        stream: false,
        recording: Some("geomint-stability.rrd"),
    };
    type Document = StabilityDocument;
    /// No stream: the maps answer whole.
    type Line = ();

    fn prepare(
        request: &Value,
        _systems: &dyn StoredSystems,
        _limits: &Limits,
    ) -> Result<Self, ErrorDetail> {
        let request = StabilityRequest::from_value(request)?;
        let job = request.to_spec()?.prepare()?;
        Ok(Stability { request, job })
    }

    fn spec(&self) -> StudySpec {
        StudySpec::Stability(self.job.spec.clone())
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
        _emit: &(dyn Fn(()) -> bool + Sync),
    ) -> Result<StabilityDocument, CoreError> {
        stability::maps(&self.job, executor, budget)
    }

    fn result_line(_document: StabilityDocument) {}

    fn error_line(_error: ErrorDetail) {}

    fn end_line() {}

    fn record(&self, document: &StabilityDocument) -> Result<Vec<u8>, RecordingError> {
        recording::stability::rrd_bytes(&recording::Spec::of(&self.request), document)
    }

    fn report(_line: &()) -> Option<Report> {
        None
    }
}

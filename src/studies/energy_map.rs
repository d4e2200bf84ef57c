//! An energy-error map of the planar elastic pendulum, Cartesian against polar coordinates
//! (paper 001 Fig. 6; `POST /api/v1/studies/energy-map`, [`crate::core::studies::energy_map`]):
//! a sweep underneath, whose parts are a sweep's.

use serde_json::Value;

use super::{Answers, Report, StudyKind};
use crate::api::studies::EnergyMapRequest;
use crate::api::system::StoredSystems;
use crate::core::error::{CoreError, ErrorCode, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::energy_map::{self, EnergyMapDocument, EnergyMapJob, MapLine};
use crate::core::studies::engine::{Executor, Study};
use crate::core::studies::StudySpec;
use crate::recording::{self, RecordingError};

/// An energy map, prepared.
pub struct EnergyMap {
    spec: StudySpec,
    job: EnergyMapJob,
}

impl StudyKind for EnergyMap {
    const NAME: &'static str = "energy-map";
    const ABOUT: &'static str =
        "Energy-error map of the planar elastic pendulum, Cartesian against polar coordinates";
    const ANSWERS: Answers = Answers {
        stream: true,
        recording: Some("geomint-energy-map.rrd"),
    };
    type Document = EnergyMapDocument;
    type Line = MapLine;

    fn prepare(
        request: &Value,
        _systems: &dyn StoredSystems,
        _limits: &Limits,
    ) -> Result<Self, ErrorDetail> {
        let job = EnergyMapRequest::from_value(request)?
            .to_spec()?
            .prepare()?;
        let spec = job.sweep().spec().ok_or_else(|| {
            ErrorDetail::new(ErrorCode::Internal, "an energy map's sweep has no spec")
        })?;
        Ok(EnergyMap { spec, job })
    }

    fn spec(&self) -> StudySpec {
        self.spec.clone()
    }

    fn shard_limits(&self, _limits: &Limits) -> Limits {
        // As the map prepares its sweep: bounded by its total steps, not per run.
        Limits {
            max_steps: u64::MAX,
            max_samples: u64::MAX,
        }
    }

    fn cells(&self) -> usize {
        self.job.sweep().cells()
    }

    fn steps(&self) -> u64 {
        self.job.sweep().steps()
    }

    fn group(&self) -> usize {
        self.job.sweep().group()
    }

    fn run<E: Executor>(
        &self,
        executor: &E,
        budget: Budget<'_>,
        emit: &(dyn Fn(MapLine) -> bool + Sync),
    ) -> Result<EnergyMapDocument, CoreError> {
        energy_map::run(&self.job, executor, budget, emit)
    }

    fn result_line(document: EnergyMapDocument) -> MapLine {
        MapLine::Result(Box::new(document))
    }

    fn error_line(error: ErrorDetail) -> MapLine {
        MapLine::Error { error }
    }

    fn end_line() -> MapLine {
        MapLine::End
    }

    fn record(&self, document: &EnergyMapDocument) -> Result<Vec<u8>, RecordingError> {
        recording::energy_map::rrd_bytes(document)
    }

    fn report(line: &MapLine) -> Option<Report> {
        match *line {
            MapLine::Progress { done, total } => Some(Report::Cells { done, total }),
            _ => None,
        }
    }

    fn summary(&self, doc: &EnergyMapDocument) -> Option<String> {
        let s = &doc.summary;
        Some(format!(
            "{:.1} s for {} steps: Cartesian better in {} cells, polar in {}; polar diverged in {} \
             ({} outside the predicted region)",
            doc.wall_ms / 1e3,
            doc.steps,
            s.cartesian_better,
            s.polar_better,
            s.polar_diverged,
            s.diverged_outside_prediction
        ))
    }
}

//! Work–precision studies — the body of `POST /api/v1/studies/work-precision` and of
//! `geomint study work-precision` — their strict parser, and the study itself.
//!
//! A study runs one system from one initial state to `t_end` with several methods, each at
//! several step sizes (or, for the adaptive `reference`, tolerances), and measures per setting the
//! wall time, the force evaluations, the largest energy error over `samples` evenly spaced sample
//! times, the error of the final state and the drift of the system's invariants. The errors are
//! taken against the exact solution where the system has one, otherwise against a reference run
//! (by default the adaptive DOP853 at tolerance 1e-13, one segment per sample interval; a study
//! may name another, e.g. a high-order composition at a small step, which keeps the energy error
//! bounded over long horizons). Per method it fits log₁₀(ms) = a + b·log₁₀(max energy error).
//!
//! Settings run one after another on one thread, so that their wall times are comparable. Every
//! step size must divide t_end/samples, so that the samples are step endpoints.

use std::collections::BTreeMap;

use serde::Serialize;
use serde_json::{Map, Value};
use utoipa::ToSchema;

use super::document::SystemSummary;
use super::error::ErrorDetail;
use super::request::{check_fields, missing, object, present, wrong_type};
use super::study::{
    self, invalid, measure_timed, prepare_reference, prepare_setting, progress_lines, run_spec,
    stop_name, too_many_settings, Common, Fields, Setting,
};
pub use super::study::{RunSpec, StudyJob, MAX_SETTINGS, MAX_STUDY_STEPS, REFERENCE_TOLERANCE};
use crate::core::methods::MethodId;
use crate::core::run::Budget;
use crate::core::simulate::{Limits, Request};

/// The fields of a study request.
pub const STUDY_FIELDS: &[&str] = &[
    "system",
    "params",
    "q0",
    "p0",
    "t_end",
    "samples",
    "runs",
    "reference",
];
pub use super::study::RUN_FIELDS;
/// Default number of sample times.
pub const DEFAULT_SAMPLES: u64 = 50;

/// A work–precision study.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({
    "system": "elastic_pendulum_3d",
    "params": {"epsilon": 0.0001},
    "t_end": 1000,
    "runs": [
        {"method": {"id": "kahan_li_8", "base": "modin_3s"}, "h": [0.8, 0.4, 0.2]},
        {"method": "rk4", "h": [0.05, 0.025]},
        {"method": "reference", "tolerance": [1e-8, 1e-10]}
    ]
}))]
pub struct WorkPrecisionRequest {
    /// System id.
    pub system: String,
    /// System parameters (as for a simulation).
    #[schema(value_type = Object)]
    pub params: Map<String, Value>,
    /// Initial positions (default: the system's).
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default: the system's).
    pub p0: Option<Vec<f64>>,
    /// Final time (finite, > 0).
    pub t_end: f64,
    /// Evenly spaced sample times t_k = k·t_end/samples, k = 1…samples (default 50, 1 to 1000),
    /// over which the largest energy error is taken.
    pub samples: u64,
    /// The methods, each with its step sizes (or for `reference` its tolerances).
    pub runs: Vec<RunSpec>,
    /// The run the errors are measured against where the system has no exact solution
    /// (default: `reference` at tolerance 1e-13). Give one step size or tolerance.
    pub reference: Option<RunSpec>,
}

/// One setting of a study: what ran and what it measured.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct WorkPrecisionPoint {
    /// Index of the run in the request's `runs`.
    pub run: usize,
    /// The method's label, e.g. `kahan_li_8(modin_3s)`; `reference` for every tolerance.
    pub method: String,
    /// The step size (fixed-step methods).
    pub h: Option<f64>,
    /// The tolerance (the adaptive reference).
    pub tolerance: Option<f64>,
    /// Wall time of the run in milliseconds: building the stepper, the steps and the samples
    /// (for runs under 20 ms the median of 5 runs).
    pub wall_ms: f64,
    /// Steps taken (segments of t_end/samples for the adaptive reference).
    pub steps: u64,
    /// Gradient evaluations.
    pub force_evaluations: u64,
    /// max_k |H(t_k) − H_exact(t_k)| over the samples (`null` if the run did not finish).
    pub max_energy_error: Option<f64>,
    /// Euclidean norm of (q, p)(t_end) − (q, p)_exact(t_end) (`null` if it did not finish).
    pub final_state_error: Option<f64>,
    /// max_k |I(t_k) − I(0)| per invariant of the system.
    pub invariant_drift: BTreeMap<String, f64>,
    /// `finished`, `diverged`, `time_limit` or `cancelled`.
    pub stop: String,
}

/// The cost-versus-error line of one method: log₁₀(ms) ≈ intercept + slope·log₁₀(max energy
/// error), by least squares over its finished settings with a positive error.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct WorkPrecisionFit {
    /// Index of the run in the request's `runs`.
    pub run: usize,
    /// The method's label.
    pub method: String,
    /// d log₁₀(ms) / d log₁₀(error): about −1/p for a method of order p.
    pub slope: Option<f64>,
    /// log₁₀(ms) at an error of 1.
    pub intercept: Option<f64>,
    /// Settings in the fit.
    pub points: usize,
}

/// The answer to a study.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct WorkPrecisionDocument {
    /// The system, parameters resolved.
    pub system: SystemSummary,
    /// Final time.
    pub t_end: f64,
    /// Sample times.
    pub samples: u64,
    /// What the errors are measured against: `exact solution` or the reference run's label and
    /// setting.
    pub reference: String,
    /// Wall time of the reference run in milliseconds (0 for an exact solution).
    pub reference_ms: f64,
    /// Every setting, in request order.
    pub points: Vec<WorkPrecisionPoint>,
    /// One line per run.
    pub fits: Vec<WorkPrecisionFit>,
}

impl WorkPrecisionRequest {
    /// Parses a study from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&super::request::parse_json(bytes)?)
    }

    /// Parses a study from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = object(value, None)?;
        check_fields(obj, STUDY_FIELDS, "")?;
        let common = Common::parse(obj)?;
        let runs = match present(obj, "runs") {
            Some(v) => v
                .as_array()
                .ok_or_else(|| wrong_type("runs", "a list of {method, h} objects", v))?
                .iter()
                .enumerate()
                .map(|(i, r)| run_spec(r, &format!("runs[{i}]"), false))
                .collect::<Result<Vec<_>, _>>()?,
            None => {
                return Err(missing(
                    "runs",
                    "the methods with their step sizes, e.g. [{\"method\": \"rk4\", \"h\": [0.1, 0.05]}]",
                ))
            }
        };
        Ok(WorkPrecisionRequest {
            system: common.system,
            params: common.params,
            q0: common.q0,
            p0: common.p0,
            t_end: common.t_end,
            samples: common.samples.unwrap_or(DEFAULT_SAMPLES),
            runs,
            reference: common.reference,
        })
    }

    /// The settings of run `spec` (the request's `field`), checked against its method.
    fn settings_of(spec: &RunSpec, field: &str) -> Result<Vec<(String, Setting)>, ErrorDetail> {
        let adaptive = spec.method.id() == MethodId::Reference.as_str();
        let listed = |name: &str, values: &[f64], make: fn(f64) -> Setting| {
            values
                .iter()
                .enumerate()
                .map(|(j, &v)| (format!("{field}.{name}[{j}]"), make(v)))
                .collect()
        };
        match (adaptive, spec.h.is_empty(), spec.tolerance.is_empty()) {
            (false, false, true) => Ok(listed("h", &spec.h, Setting::Step)),
            (true, true, false) => Ok(listed("tolerance", &spec.tolerance, Setting::Tolerance)),
            (false, _, false) => Err(invalid(
                format!("{field}.tolerance"),
                "only the adaptive `reference` takes tolerances; give step sizes `h`",
            )),
            (true, false, _) => Err(invalid(
                format!("{field}.h"),
                "the adaptive `reference` takes tolerances, not step sizes",
            )),
            (false, true, true) => Err(missing(
                &format!("{field}.h"),
                "the step sizes, e.g. [0.1, 0.05]",
            )),
            (true, true, true) => Err(missing(
                &format!("{field}.tolerance"),
                "the tolerances, e.g. [1e-8, 1e-10]",
            )),
        }
    }

    /// Validates the study (cheap: nothing is integrated).
    pub fn prepare(&self, limits: &Limits) -> Result<StudyJob, ErrorDetail> {
        study::check_t_end(self.t_end)?;
        study::check_samples(self.samples)?;
        if self.runs.is_empty() {
            return Err(invalid(
                "runs",
                "give at least one method with its settings",
            ));
        }
        let template = Request {
            system: self.system.clone(),
            params: self.params.clone(),
            t_end: self.t_end,
            q0: self.q0.clone(),
            p0: self.p0.clone(),
            ..Request::default()
        };
        let mut settings = Vec::new();
        for (i, spec) in self.runs.iter().enumerate() {
            let field = format!("runs[{i}]");
            let method = format!("{field}.method");
            for (path, setting) in Self::settings_of(spec, &field)? {
                if settings.len() == MAX_SETTINGS {
                    return Err(too_many_settings(
                        "runs",
                        "count the step sizes and tolerances of every run",
                    ));
                }
                let fields = Fields {
                    method: &method,
                    setting: &path,
                    chart: "system",
                };
                let sim = prepare_setting(
                    &template,
                    &spec.method,
                    setting,
                    self.samples,
                    &fields,
                    limits,
                )?;
                settings.push((i, sim));
            }
        }
        let first = &settings[0].1;
        let reference = prepare_reference(
            first,
            &template,
            self.reference.as_ref(),
            self.samples,
            limits,
        )?;
        let system = SystemSummary::of(first);
        StudyJob::new(
            settings,
            reference,
            system,
            self.t_end,
            self.samples,
            "runs",
        )
    }
}

progress_lines! {
    /// What a work–precision study's progress stream carries.
    StudyLine, WorkPrecisionPoint, WorkPrecisionDocument
}

/// Runs a study, reporting each line to `emit` (which returns false once nobody listens) and
/// returning the document.
pub fn run(
    job: &StudyJob,
    budget: Budget<'_>,
    emit: &dyn Fn(StudyLine) -> bool,
) -> Result<WorkPrecisionDocument, ErrorDetail> {
    let (truth, points) = study::run_settings(job, budget, emit, |run, sim, truth| {
        let choice = &sim.methods[0];
        let (outcome, sink, wall_ms) = measure_timed(sim, truth.energies.as_deref(), budget)?;
        let finished = outcome.stop == crate::core::run::StopReason::Finished;
        let adaptive = choice.id == MethodId::Reference;
        let point = WorkPrecisionPoint {
            run,
            method: if adaptive {
                "reference".into()
            } else {
                choice.label()
            },
            h: (!adaptive).then_some(sim.schedule.h),
            tolerance: if adaptive { choice.tolerance } else { None },
            wall_ms,
            steps: outcome.stats.steps,
            force_evaluations: outcome.stats.force_evaluations,
            max_energy_error: finished.then_some(sink.max_energy_error),
            final_state_error: sink
                .last
                .as_ref()
                .filter(|_| finished)
                .and_then(|last| truth.state_error(sim, last)),
            invariant_drift: sink
                .names
                .iter()
                .zip(&sink.drift)
                .map(|(n, &d)| (n.to_string(), d))
                .collect(),
            stop: stop_name(&outcome.stop).to_string(),
        };
        Ok((point, outcome.stop))
    })?;

    let mut fits = Vec::new();
    for run in 0..job.settings.last().map_or(0, |s| s.0 + 1) {
        let mine: Vec<&WorkPrecisionPoint> = points.iter().filter(|p| p.run == run).collect();
        let Some(first) = mine.first() else { continue };
        let data: Vec<(f64, f64)> = mine
            .iter()
            .filter_map(|p| {
                p.max_energy_error
                    .filter(|&e| e > 0.0 && e.is_finite())
                    .map(|e| (e, p.wall_ms))
            })
            .filter(|&(_, ms)| ms > 0.0)
            .collect();
        let (slope, intercept) = study::fit(&data);
        fits.push(WorkPrecisionFit {
            run,
            method: first.method.clone(),
            slope,
            intercept,
            points: data.len(),
        });
    }
    Ok(WorkPrecisionDocument {
        system: job.system.clone(),
        t_end: job.t_end,
        samples: job.samples,
        reference: truth.description,
        reference_ms: truth.ms,
        points,
        fits,
    })
}

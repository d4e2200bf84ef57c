//! Work–precision studies: one system from one initial state to `t_end`, run with several
//! methods, each at several step sizes (or, for the adaptive `reference`, tolerances); per
//! setting the wall time, the force evaluations, the largest energy error over `samples` evenly
//! spaced sample times, the error of the final state and the drift of the system's invariants.
//! The errors are taken against the exact solution where the system has one, otherwise against a
//! reference run (by default the adaptive DOP853 at tolerance 1e-13, one segment per sample
//! interval; a study may name another, e.g. a high-order composition at a small step, which keeps
//! the energy error bounded over long horizons). Per method it fits
//! log₁₀(ms) = a + b·log₁₀(max energy error).
//!
//! Settings run one after another on one thread, so that their wall times are comparable. Every
//! step size must divide t_end/samples, so that the samples are step endpoints.

use std::collections::BTreeMap;

use serde::Serialize;

use super::engine::{Executor, Order};
use super::settings::{
    self, check_samples, check_t_end, measure_timed, prepare_reference, prepare_setting,
    progress_lines, stop_name, RunSpec, Setting, SettingsStudy, StudyJob, Truth, MAX_REPEATS,
    MAX_SETTINGS,
};
use super::StudySpec;
use crate::diagnostics::fit_log_log;
use crate::error::{CoreError, Field, Range};
use crate::methods::Method;
use crate::run::{Budget, RunEnd};
use crate::simulation::{Limits, Simulation, SimulationSpec, SystemSummary};
use crate::studies::parts::{Part, ShardAt, Travelling};
use crate::systems::{ParamValue, SystemRef};

/// Default number of sample times.
pub const DEFAULT_SAMPLES: u64 = 50;

/// A work–precision study as asked for.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WorkPrecisionSpec {
    /// System id.
    pub system: SystemRef,
    /// System parameters.
    pub params: BTreeMap<String, ParamValue>,
    /// Initial positions.
    pub q0: Option<Vec<f64>>,
    /// Initial momenta.
    pub p0: Option<Vec<f64>>,
    /// Final time.
    pub t_end: f64,
    /// Sample times.
    pub samples: u64,
    /// The methods with their settings.
    pub runs: Vec<RunSpec>,
    /// The reference run, where the system has no exact solution.
    pub reference: Option<RunSpec>,
    /// Timings per setting (1 to [`MAX_REPEATS`]; a run under 20 ms is timed at least 5 times).
    #[serde(default = "one_timing")]
    pub repeats: u64,
}

fn one_timing() -> u64 {
    1
}

/// One setting of a study: what ran and what it measured.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct WorkPrecisionPoint {
    /// Index of the run in the request's `runs`.
    pub run: usize,
    /// The method's label, e.g. `kahan_li_8(modin_3s)`; `reference` for every tolerance.
    pub method: String,
    /// The step size (fixed-step methods).
    pub h: Option<f64>,
    /// The tolerance (the adaptive reference).
    pub tolerance: Option<f64>,
    /// Wall time of the run in milliseconds: building the stepper, the steps and the samples;
    /// the median of `timings_ms` when the setting was timed more than once.
    pub wall_ms: f64,
    /// Every timing of the setting in milliseconds, fastest first, when it was timed more than
    /// once (the request's `repeats`; a run under 20 ms is always timed 5 times).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub timings_ms: Vec<f64>,
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
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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

progress_lines! {
    /// What a work–precision study's progress stream carries.
    StudyLine, WorkPrecisionPoint, WorkPrecisionDocument
}

impl WorkPrecisionSpec {
    /// The settings of run `spec`, each with its field, checked against its method.
    fn settings_of(spec: &RunSpec) -> Result<Vec<(Field, Setting)>, CoreError> {
        let adaptive = matches!(spec.method.method, Method::Reference { .. });
        let field = &spec.field;
        let listed = |name: &str, values: &[f64], make: fn(f64) -> Setting| {
            values
                .iter()
                .enumerate()
                .map(|(j, &v)| (field.key(name).index(j), make(v)))
                .collect()
        };
        match (adaptive, spec.h.is_empty(), spec.tolerance.is_empty()) {
            (false, false, true) => Ok(listed("h", &spec.h, Setting::Step)),
            (true, true, false) => Ok(listed("tolerance", &spec.tolerance, Setting::Tolerance)),
            (false, _, false) => Err(CoreError::Unsupported {
                field: field.key("tolerance"),
                reason: "only the adaptive `reference` takes tolerances; give step sizes `h`",
            }),
            (true, false, _) => Err(CoreError::Unsupported {
                field: field.key("h"),
                reason: "the adaptive `reference` takes tolerances, not step sizes",
            }),
            (false, true, true) => Err(CoreError::Missing {
                field: field.key("h"),
                what: "the step sizes, e.g. [0.1, 0.05]",
            }),
            (true, true, true) => Err(CoreError::Missing {
                field: field.key("tolerance"),
                what: "the tolerances, e.g. [1e-8, 1e-10]",
            }),
        }
    }

    /// Validates the study (cheap: nothing is integrated).
    pub fn prepare(&self, limits: &Limits) -> Result<StudyJob, CoreError> {
        check_t_end(self.t_end)?;
        check_samples(self.samples)?;
        Range::closed(1.0, false, MAX_REPEATS as f64)
            .check(self.repeats as f64, &Field::new("repeats"))?;
        if self.runs.is_empty() {
            return Err(CoreError::Empty {
                field: Field::new("runs"),
                what: "method with its settings",
            });
        }
        let template = SimulationSpec {
            params: self.params.clone(),
            q0: self.q0.clone(),
            p0: self.p0.clone(),
            ..SimulationSpec::new(self.system.clone(), &[], 0.0, self.t_end)
        };
        let mut template = template;
        template.fields.chart = Field::new("system");
        let mut settings = Vec::new();
        for (i, spec) in self.runs.iter().enumerate() {
            for (at, setting) in Self::settings_of(spec)? {
                if settings.len() == MAX_SETTINGS {
                    return Err(CoreError::TooMany {
                        field: Field::new("runs"),
                        what:
                            "settings per study (count the step sizes and tolerances of every run)",
                        limit: MAX_SETTINGS,
                        got: None,
                    });
                }
                let sim =
                    prepare_setting(&template, &spec.method, setting, self.samples, &at, limits)?;
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
            StudySpec::WorkPrecision(self.clone()),
            settings,
            reference,
            system,
            self.t_end,
            self.samples,
            "runs",
        )
    }
}

/// Measures one setting: its wall time (timed again when short) and its errors against the
/// truth.
fn point(
    job: &StudyJob,
    run: usize,
    sim: &Simulation,
    truth: &Truth,
    budget: Budget<'_>,
) -> Result<WorkPrecisionPoint, CoreError> {
    let method = &sim.methods[0];
    let repeats = match &job.spec {
        StudySpec::WorkPrecision(spec) => spec.repeats,
        _ => 1,
    };
    let repeats = usize::try_from(repeats).unwrap_or(usize::MAX);
    let (outcome, sink, timings) = measure_timed(sim, truth.energies.as_deref(), budget, repeats)?;
    let wall_ms = settings::median(&timings);
    let finished = outcome.stop == RunEnd::Finished;
    let tolerance = match method {
        Method::Reference { tolerance } => Some(*tolerance),
        _ => None,
    };
    Ok(WorkPrecisionPoint {
        run,
        method: if tolerance.is_some() {
            "reference".into()
        } else {
            method.label()
        },
        h: tolerance.is_none().then_some(sim.schedule.h),
        tolerance,
        wall_ms,
        timings_ms: if timings.len() > 1 {
            timings
        } else {
            Vec::new()
        },
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
    })
}

/// The settings of `job` as the engine runs them, measured against `truth`.
pub fn study(job: &StudyJob, truth: Truth) -> SettingsStudy<'_, WorkPrecisionPoint> {
    SettingsStudy::new(job, truth, point, Order::Timed)
}

/// Runs a study on `executor`, its settings timed one at a time in order, reporting each line to
/// `emit`, and returns the document.
pub fn run<E: Executor>(
    job: &StudyJob,
    executor: &E,
    budget: Budget<'_>,
    emit: &(dyn Fn(StudyLine) -> bool + Sync),
) -> Result<WorkPrecisionDocument, CoreError> {
    let (truth, points) =
        settings::run_settings(job, executor, budget, emit, |truth| study(job, truth))?;

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
        let fit = fit_log_log(&data);
        fits.push(WorkPrecisionFit {
            run,
            method: first.method.clone(),
            slope: fit.map(|f| f.0),
            intercept: fit.map(|f| f.1),
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

/// A shard of it, as a worker or an array task runs it.
impl Travelling for WorkPrecisionSpec {
    type Cell = WorkPrecisionPoint;

    fn run_shard(
        &self,
        at: &ShardAt<'_>,
        limits: &crate::simulation::Limits,
    ) -> Result<Part<Self::Cell>, CoreError> {
        let job = self.prepare(limits)?;
        at.run(&study(&job, job.truth(Budget::default())?))
    }
}

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
use std::time::Instant;

use serde::Serialize;
use serde_json::{Map, Value};
use utoipa::ToSchema;

use super::document::SystemSummary;
use super::error::{codes, ErrorDetail};
use super::request::{
    check_fields, method, missing, number, object, present, wrong_type, MethodSpec,
};
use crate::core::methods::MethodId;
use crate::core::run::{Budget, StopReason};
use crate::core::simulate::{Limits, Request, Sample, SampleSink, Simulation};

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
/// The fields of one entry of `runs` (and of `reference`).
pub const RUN_FIELDS: &[&str] = &["method", "h", "tolerance"];
/// Most settings (step sizes and tolerances over all runs) in one study.
pub const MAX_SETTINGS: usize = 64;
/// Most fixed steps over all settings of one study.
pub const MAX_STUDY_STEPS: u64 = 200_000_000;
/// Default number of sample times.
pub const DEFAULT_SAMPLES: u64 = 50;
/// Runs shorter than this many milliseconds are timed [`SHORT_RUN_REPEATS`] times.
const SHORT_RUN_MS: f64 = 20.0;
/// Timings of a short run; its wall time is their median.
const SHORT_RUN_REPEATS: usize = 5;
/// Tolerance of the default reference run.
pub const REFERENCE_TOLERANCE: f64 = 1e-13;

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

/// A method with its settings.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct RunSpec {
    /// The method.
    pub method: MethodSpec,
    /// Step sizes (fixed-step methods), each dividing t_end/samples.
    pub h: Vec<f64>,
    /// Tolerances (the adaptive `reference` only), in [1e-14, 1e-2].
    pub tolerance: Vec<f64>,
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

/// A validated study, ready to run.
#[derive(Clone, Debug)]
pub struct StudyJob {
    /// One prepared simulation per setting, with its run index.
    settings: Vec<(usize, Simulation)>,
    /// The reference run, where the system has no exact solution.
    reference: Option<Simulation>,
    system: SystemSummary,
    t_end: f64,
    samples: u64,
}

impl StudyJob {
    /// Number of settings.
    pub fn len(&self) -> usize {
        self.settings.len()
    }

    /// Whether the study has no settings (never, once validated).
    pub fn is_empty(&self) -> bool {
        self.settings.is_empty()
    }
}

fn invalid(field: impl Into<String>, message: impl std::fmt::Display) -> ErrorDetail {
    let field = field.into();
    ErrorDetail::at(
        codes::INVALID_VALUE,
        field.clone(),
        format!("{field}: {message}"),
    )
}

fn numbers(v: &Value, field: &str) -> Result<Vec<f64>, ErrorDetail> {
    let list = v
        .as_array()
        .ok_or_else(|| wrong_type(field, "a list of numbers", v))?;
    list.iter()
        .enumerate()
        .map(|(i, x)| number(x, &format!("{field}[{i}]")))
        .collect()
}

/// A `{"method", "h" | "tolerance"}` entry; `single` asks for one number instead of a list.
fn run_spec(v: &Value, field: &str, single: bool) -> Result<RunSpec, ErrorDetail> {
    let o = object(v, Some(field))?;
    check_fields(o, RUN_FIELDS, &format!("{field}."))?;
    let method = match present(o, "method") {
        Some(m) => method(m, &format!("{field}.method"))?,
        None => {
            return Err(missing(
                &format!("{field}.method"),
                "the method, e.g. \"rk4\" or {\"id\": \"kahan_li_8\", \"base\": \"modin_3s\"}",
            ))
        }
    };
    let list = |name: &str| -> Result<Vec<f64>, ErrorDetail> {
        let path = format!("{field}.{name}");
        match present(o, name) {
            None => Ok(Vec::new()),
            Some(x) if single => Ok(vec![number(x, &path)?]),
            Some(x) => numbers(x, &path),
        }
    };
    Ok(RunSpec {
        method,
        h: list("h")?,
        tolerance: list("tolerance")?,
    })
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
        let system = match present(obj, "system") {
            Some(Value::String(s)) => s.clone(),
            Some(v) => return Err(wrong_type("system", "a string", v)),
            None => return Err(missing("system", "the system id, e.g. \"pendulum\"")),
        };
        let params = match present(obj, "params") {
            Some(v) => object(v, Some("params"))?.clone(),
            None => Map::new(),
        };
        let t_end = match present(obj, "t_end") {
            Some(v) => number(v, "t_end")?,
            None => return Err(missing("t_end", "the final time")),
        };
        let samples = match present(obj, "samples") {
            Some(v) => v
                .as_u64()
                .ok_or_else(|| wrong_type("samples", "a whole number from 1 to 1000", v))?,
            None => DEFAULT_SAMPLES,
        };
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
        let reference = present(obj, "reference")
            .map(|v| run_spec(v, "reference", true))
            .transpose()?;
        Ok(WorkPrecisionRequest {
            system,
            params,
            q0: present(obj, "q0").map(|v| numbers(v, "q0")).transpose()?,
            p0: present(obj, "p0").map(|v| numbers(v, "p0")).transpose()?,
            t_end,
            samples,
            runs,
            reference,
        })
    }

    /// One simulation request for `method` at step `h` (or segment length with `tolerance`).
    fn core_request(&self, method: &MethodSpec, h: f64, tolerance: Option<f64>) -> Request {
        let mut input = method.to_input();
        if let (Some(t), crate::core::methods::MethodInput::Object { tolerance: tol, .. }) =
            (tolerance, &mut input)
        {
            *tol = Some(t);
        } else if let Some(t) = tolerance {
            input = crate::core::methods::MethodInput::Object {
                id: "reference".into(),
                inner: None,
                base: None,
                tolerance: Some(t),
                processor: None,
            };
        }
        let steps = (self.t_end / h).round().max(1.0) as u64;
        Request {
            system: self.system.clone(),
            params: self.params.clone(),
            chart: None,
            initial_cartesian: false,
            methods: vec![input],
            h,
            t_end: self.t_end,
            q0: self.q0.clone(),
            p0: self.p0.clone(),
            every: Some((steps / self.samples).max(1)),
            compare_to_reference: false,
            jacobian_defect: false,
        }
    }

    /// Prepares one setting of run `field` (e.g. `runs[1]`), naming its fields in errors.
    fn prepare_setting(
        &self,
        spec: &RunSpec,
        field: &str,
        setting: Setting,
        limits: &Limits,
    ) -> Result<Simulation, ErrorDetail> {
        let segment = self.t_end / self.samples as f64;
        let (h, tolerance, path) = match setting {
            Setting::Step(j, h) => {
                let path = format!("{field}.h[{j}]");
                if !(h.is_finite() && h > 0.0) {
                    return Err(invalid(path, format!("must be finite and > 0, got {h}")));
                }
                let per_segment = segment / h;
                if (per_segment - per_segment.round()).abs() > 1e-9 * per_segment.max(1.0)
                    || per_segment.round() < 1.0
                {
                    return Err(invalid(
                        path,
                        format!(
                            "must divide t_end/samples = {segment} so that the samples are step \
                             endpoints; {h} does not"
                        ),
                    ));
                }
                (h, None, path)
            }
            Setting::Tolerance(j, t) => {
                let path = format!("{field}.tolerance[{j}]");
                if !(t.is_finite() && (1e-14..=1e-2).contains(&t)) {
                    return Err(invalid(path, format!("must lie in [1e-14, 1e-2], got {t}")));
                }
                (segment, Some(t), path)
            }
        };
        let req = self.core_request(&spec.method, h, tolerance);
        Simulation::prepare(&req, limits).map_err(|e| {
            let detail = ErrorDetail::from_core(&e, &req, limits);
            let renamed = match detail.field.as_deref() {
                Some(f) if f.starts_with("methods[0]") => {
                    Some(f.replacen("methods[0]", &format!("{field}.method"), 1))
                }
                Some("methods") => Some(format!("{field}.method")),
                Some("h") => Some(path.clone()),
                // Too many steps for this setting: its step size is at fault, not t_end.
                Some("t_end") if detail.code == codes::TOO_MANY_STEPS => Some(path.clone()),
                Some(other) => Some(other.to_string()),
                None => None,
            };
            ErrorDetail {
                field: renamed,
                ..detail
            }
        })
    }

    /// Validates the study (cheap: nothing is integrated).
    pub fn prepare(&self, limits: &Limits) -> Result<StudyJob, ErrorDetail> {
        if !(self.t_end.is_finite() && self.t_end > 0.0) {
            return Err(invalid(
                "t_end",
                format!("must be finite and > 0, got {}", self.t_end),
            ));
        }
        if !(1..=1000).contains(&self.samples) {
            return Err(invalid(
                "samples",
                format!("must lie in 1…1000, got {}", self.samples),
            ));
        }
        if self.runs.is_empty() {
            return Err(invalid(
                "runs",
                "give at least one method with its settings",
            ));
        }
        let mut settings = Vec::new();
        let mut total_steps: u64 = 0;
        for (i, spec) in self.runs.iter().enumerate() {
            let field = format!("runs[{i}]");
            let adaptive = spec.method.id() == MethodId::Reference.as_str();
            let chosen: Vec<Setting> =
                match (adaptive, spec.h.is_empty(), spec.tolerance.is_empty()) {
                    (false, false, true) => spec
                        .h
                        .iter()
                        .enumerate()
                        .map(|(j, &h)| Setting::Step(j, h))
                        .collect(),
                    (true, true, false) => spec
                        .tolerance
                        .iter()
                        .enumerate()
                        .map(|(j, &t)| Setting::Tolerance(j, t))
                        .collect(),
                    (false, _, false) => {
                        return Err(invalid(
                            format!("{field}.tolerance"),
                            "only the adaptive `reference` takes tolerances; give step sizes `h`",
                        ))
                    }
                    (true, false, _) => {
                        return Err(invalid(
                            format!("{field}.h"),
                            "the adaptive `reference` takes tolerances, not step sizes",
                        ))
                    }
                    (false, true, true) => {
                        return Err(missing(
                            &format!("{field}.h"),
                            "the step sizes, e.g. [0.1, 0.05]",
                        ))
                    }
                    (true, true, true) => {
                        return Err(missing(
                            &format!("{field}.tolerance"),
                            "the tolerances, e.g. [1e-8, 1e-10]",
                        ))
                    }
                };
            for setting in chosen {
                if settings.len() == MAX_SETTINGS {
                    return Err(invalid(
                        "runs",
                        format!(
                            "at most {MAX_SETTINGS} settings (step sizes and tolerances) per study"
                        ),
                    ));
                }
                let sim = self.prepare_setting(spec, &field, setting, limits)?;
                total_steps = total_steps.saturating_add(sim.schedule.steps);
                settings.push((i, sim));
            }
        }
        if total_steps > MAX_STUDY_STEPS {
            return Err(ErrorDetail::at(
                codes::TOO_MANY_STEPS,
                "runs",
                format!(
                    "runs: {total_steps} steps over all settings exceed the limit of \
                     {MAX_STUDY_STEPS} per study; use fewer or larger steps"
                ),
            ));
        }
        let first = &settings[0].1;
        let reference = if first.exact_final_state().is_some() {
            None
        } else {
            let sim = match &self.reference {
                Some(spec) => {
                    let setting = match (spec.h.first(), spec.tolerance.first()) {
                        (Some(&h), None) => Setting::Step(0, h),
                        (None, Some(&t)) => Setting::Tolerance(0, t),
                        (None, None) => {
                            return Err(missing(
                                "reference.h",
                                "the reference's step size (or tolerance)",
                            ))
                        }
                        (Some(_), Some(_)) => {
                            return Err(invalid(
                                "reference",
                                "give either `h` or `tolerance`, not both",
                            ))
                        }
                    };
                    self.prepare_setting(spec, "reference", setting, limits)
                        .map_err(|mut e| {
                            if let Some(f) = &e.field {
                                e.field = Some(
                                    f.replace(".h[0]", ".h")
                                        .replace(".tolerance[0]", ".tolerance"),
                                );
                            }
                            e
                        })?
                }
                None => {
                    let default = RunSpec {
                        method: MethodSpec::Id("reference".into()),
                        h: Vec::new(),
                        tolerance: vec![REFERENCE_TOLERANCE],
                    };
                    self.prepare_setting(
                        &default,
                        "reference",
                        Setting::Tolerance(0, REFERENCE_TOLERANCE),
                        limits,
                    )?
                }
            };
            Some(sim)
        };
        Ok(StudyJob {
            system: SystemSummary::of(first),
            settings,
            reference,
            t_end: self.t_end,
            samples: self.samples,
        })
    }
}

/// A setting as requested: (index in its list, value).
#[derive(Clone, Copy, Debug)]
enum Setting {
    Step(usize, f64),
    Tolerance(usize, f64),
}

/// What a study's progress stream carries.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum StudyLine {
    /// The reference run is done (or the exact solution is used).
    Reference {
        /// What the errors are measured against.
        reference: String,
        /// Its wall time in milliseconds.
        reference_ms: f64,
        /// Settings to run.
        total: usize,
    },
    /// One setting is done.
    Point {
        /// Settings done so far.
        done: usize,
        /// Settings in all.
        total: usize,
        /// The setting's measurements.
        point: WorkPrecisionPoint,
    },
    /// The whole study.
    Result(WorkPrecisionDocument),
    /// A failure (the reference run, a server fault).
    Error {
        /// What went wrong.
        error: ErrorDetail,
    },
    /// The last line of a complete stream.
    End,
}

/// Collects what a study measures from one run's samples.
struct Measure<'a> {
    names: &'static [&'static str],
    reference_energies: Option<&'a [f64]>,
    max_energy_error: f64,
    invariants_at_start: Vec<f64>,
    drift: Vec<f64>,
    energies: Vec<f64>,
    last: Option<(Vec<f64>, Vec<f64>)>,
}

impl<'a> Measure<'a> {
    fn new(names: &'static [&'static str], reference_energies: Option<&'a [f64]>) -> Self {
        Measure {
            names,
            reference_energies,
            max_energy_error: 0.0,
            invariants_at_start: Vec::new(),
            drift: Vec::new(),
            energies: Vec::new(),
            last: None,
        }
    }
}

/// Runs the setting `sim` and measures it; short runs are timed again (their numbers are the
/// same, bit for bit) and give the median wall time, so that one scheduling hiccup does not move
/// a point of the diagram.
fn measure_setting<'a>(
    sim: &Simulation,
    energies: Option<&'a [f64]>,
    budget: Budget<'_>,
) -> Result<(crate::core::simulate::Outcome, Measure<'a>, f64), ErrorDetail> {
    let failed = |e: crate::core::error::CoreError| {
        ErrorDetail::new(
            codes::STEP_FAILED,
            format!("{}: {e}", sim.methods[0].label()),
        )
    };
    let mut sink = Measure::new(sim.invariant_names(), energies);
    let began = Instant::now();
    let outcome = sim
        .run_method(0, energies, budget, &mut sink)
        .map_err(failed)?;
    let mut times = vec![began.elapsed().as_secs_f64() * 1e3];
    while outcome.stop == StopReason::Finished
        && times.len() < SHORT_RUN_REPEATS
        && times[0] < SHORT_RUN_MS
    {
        let mut again = Measure::new(sim.invariant_names(), energies);
        let began = Instant::now();
        sim.run_method(0, energies, budget, &mut again)
            .map_err(failed)?;
        times.push(began.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let wall_ms = times[times.len() / 2];
    Ok((outcome, sink, wall_ms))
}

impl SampleSink for Measure<'_> {
    fn on_sample(&mut self, s: &Sample<'_>) {
        if let Some(e) = s.energy_error {
            self.max_energy_error = self.max_energy_error.max(e.abs());
        }
        if self.invariants_at_start.is_empty() {
            self.invariants_at_start = s.invariants.to_vec();
            self.drift = vec![0.0; s.invariants.len()];
        }
        for (k, (&v, &v0)) in s
            .invariants
            .iter()
            .zip(&self.invariants_at_start)
            .enumerate()
        {
            self.drift[k] = self.drift[k].max((v - v0).abs());
        }
        if self.reference_energies.is_none() {
            self.energies.push(s.energy);
        }
        self.last = Some((s.q.to_vec(), s.p.to_vec()));
    }
}

fn stop_name(stop: &StopReason) -> &'static str {
    match stop {
        StopReason::Finished => "finished",
        StopReason::Diverged { .. } => "diverged",
        StopReason::Cancelled { .. } => "cancelled",
        _ => "time_limit",
    }
}

/// The least-squares line through (log₁₀ error, log₁₀ ms).
fn fit(points: &[(f64, f64)]) -> (Option<f64>, Option<f64>) {
    if points.len() < 2 {
        return (None, None);
    }
    let n = points.len() as f64;
    let xs = points.iter().map(|p| p.0.log10());
    let ys = points.iter().map(|p| p.1.log10());
    let (mx, my) = (xs.clone().sum::<f64>() / n, ys.clone().sum::<f64>() / n);
    let sxy: f64 = xs.clone().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.map(|x| (x - mx).powi(2)).sum();
    if sxx <= 0.0 {
        return (None, None);
    }
    let slope = sxy / sxx;
    (Some(slope), Some(my - slope * mx))
}

/// Runs a study, reporting each line to `emit` (which returns false once nobody listens) and
/// returning the document.
pub fn run(
    job: &StudyJob,
    budget: Budget<'_>,
    emit: &dyn Fn(StudyLine) -> bool,
) -> Result<WorkPrecisionDocument, ErrorDetail> {
    let total = job.settings.len();
    // The reference: energies at the sample times and the final state.
    let started = Instant::now();
    let (reference, energies, final_state) = match &job.reference {
        None => {
            let exact = job.settings[0].1.exact_final_state();
            ("exact solution".to_string(), None, exact)
        }
        Some(sim) => {
            let mut sink = Measure::new(sim.invariant_names(), None);
            let outcome = sim.run_method(0, None, budget, &mut sink).map_err(|e| {
                ErrorDetail::new(codes::STEP_FAILED, format!("the reference run failed: {e}"))
            })?;
            if outcome.stop != StopReason::Finished {
                return Err(ErrorDetail::new(
                    codes::TIMEOUT,
                    format!(
                        "the reference run did not finish ({})",
                        stop_name(&outcome.stop)
                    ),
                ));
            }
            let choice = &sim.methods[0];
            let description = match choice.id {
                MethodId::Reference => format!(
                    "adaptive DOP853 reference at tolerance {:e}",
                    choice.tolerance.unwrap_or(REFERENCE_TOLERANCE)
                ),
                _ => format!("{} at h = {}", choice.label(), sim.schedule.h),
            };
            (description, Some(sink.energies), sink.last)
        }
    };
    let reference_ms = if job.reference.is_some() {
        started.elapsed().as_secs_f64() * 1e3
    } else {
        0.0
    };
    emit(StudyLine::Reference {
        reference: reference.clone(),
        reference_ms,
        total,
    });

    let mut points = Vec::with_capacity(total);
    for (done, (run, sim)) in job.settings.iter().enumerate() {
        let choice = &sim.methods[0];
        let (outcome, sink, wall_ms) = measure_setting(sim, energies.as_deref(), budget)?;
        let finished = outcome.stop == StopReason::Finished;
        let final_state_error = match (&sink.last, &final_state) {
            (Some((q, p)), Some((qr, pr))) if finished => Some(
                q.iter()
                    .chain(p)
                    .zip(qr.iter().chain(pr))
                    .map(|(a, b)| (a - b).powi(2))
                    .sum::<f64>()
                    .sqrt(),
            ),
            _ => None,
        };
        let adaptive = choice.id == MethodId::Reference;
        let point = WorkPrecisionPoint {
            run: *run,
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
            final_state_error,
            invariant_drift: sink
                .names
                .iter()
                .zip(&sink.drift)
                .map(|(n, &d)| (n.to_string(), d))
                .collect(),
            stop: stop_name(&outcome.stop).to_string(),
        };
        let listening = emit(StudyLine::Point {
            done: done + 1,
            total,
            point: point.clone(),
        });
        points.push(point);
        if !listening || matches!(outcome.stop, StopReason::Cancelled { .. }) {
            return Err(ErrorDetail::new(
                codes::OVERLOADED,
                "the study was cancelled",
            ));
        }
    }

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
        let (slope, intercept) = fit(&data);
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
        reference,
        reference_ms,
        points,
        fits,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fit_recovers_a_power_law() {
        // ms = 3·error^(−1/4)
        let points: Vec<(f64, f64)> = [1e-2, 1e-4, 1e-6, 1e-8]
            .iter()
            .map(|&e: &f64| (e, 3.0 * e.powf(-0.25)))
            .collect();
        let (slope, intercept) = fit(&points);
        assert!((slope.unwrap() + 0.25).abs() < 1e-12);
        assert!((intercept.unwrap() - 3f64.log10()).abs() < 1e-12);
        assert_eq!(fit(&points[..1]), (None, None));
    }
}

//! What the studies share — [work–precision](super::work_precision) and
//! [convergence](super::convergence): the fields every study has and their parser, settings
//! prepared as simulations, the run that errors are measured against (the exact solution or a
//! reference run in the system's Cartesian chart), one setting's measurements from its samples,
//! the least-squares line of a log–log diagram, and the lines of a study's progress stream.
//!
//! A study runs one system from one initial state to `t_end`, sampled at the same `samples` times
//! t_k = k·t_end/samples in every setting, so that errors over the samples compare between
//! settings and a reference run supplies the energies at exactly those times.

use std::time::Instant;

use serde::Serialize;
use serde_json::{Map, Value};
use utoipa::ToSchema;

use super::document::SystemSummary;
use super::error::{codes, ErrorDetail};
use super::request::{
    check_fields, method, missing, number, numbers, object, present, wrong_type, MethodOptions,
    MethodSpec,
};
use crate::core::methods::MethodId;
use crate::core::run::{Budget, StopReason};
use crate::core::simulate::{Limits, Outcome, Request, Sample, SampleSink, Simulation};

/// The fields of one `{method, h | tolerance}` entry (a work–precision run, a reference).
pub const RUN_FIELDS: &[&str] = &["method", "h", "tolerance"];
/// Most settings (step sizes and tolerances over all runs) in one study.
pub const MAX_SETTINGS: usize = 64;
/// Most fixed steps over all settings of one study.
pub const MAX_STUDY_STEPS: u64 = 200_000_000;
/// Most sample times.
pub const MAX_SAMPLES: u64 = 1000;
/// Tolerance of the default reference run.
pub const REFERENCE_TOLERANCE: f64 = 1e-13;
/// Runs shorter than this many milliseconds are timed [`SHORT_RUN_REPEATS`] times.
const SHORT_RUN_MS: f64 = 20.0;
/// Timings of a short run; its wall time is their median.
const SHORT_RUN_REPEATS: usize = 5;

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

/// An `invalid_value` error at `field`.
pub(crate) fn invalid(field: impl Into<String>, message: impl std::fmt::Display) -> ErrorDetail {
    let field = field.into();
    ErrorDetail::at(
        codes::INVALID_VALUE,
        field.clone(),
        format!("{field}: {message}"),
    )
}

/// A `{"method", "h" | "tolerance"}` entry; `single` asks for one number instead of a list.
pub(crate) fn run_spec(v: &Value, field: &str, single: bool) -> Result<RunSpec, ErrorDetail> {
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

/// The fields every study has.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Common {
    pub system: String,
    pub params: Map<String, Value>,
    pub q0: Option<Vec<f64>>,
    pub p0: Option<Vec<f64>>,
    pub t_end: f64,
    pub samples: Option<u64>,
    pub reference: Option<RunSpec>,
}

impl Common {
    /// Reads the common fields of the study object `obj` (whose other fields the caller reads).
    pub(crate) fn parse(obj: &Map<String, Value>) -> Result<Self, ErrorDetail> {
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
        let samples = present(obj, "samples")
            .map(|v| {
                v.as_u64().ok_or_else(|| {
                    wrong_type(
                        "samples",
                        &format!("a whole number from 1 to {MAX_SAMPLES}"),
                        v,
                    )
                })
            })
            .transpose()?;
        Ok(Common {
            system,
            params,
            q0: present(obj, "q0").map(|v| numbers(v, "q0")).transpose()?,
            p0: present(obj, "p0").map(|v| numbers(v, "p0")).transpose()?,
            t_end,
            samples,
            reference: present(obj, "reference")
                .map(|v| run_spec(v, "reference", true))
                .transpose()?,
        })
    }
}

/// Checks a study's final time.
pub(crate) fn check_t_end(t_end: f64) -> Result<(), ErrorDetail> {
    if !(t_end.is_finite() && t_end > 0.0) {
        return Err(invalid(
            "t_end",
            format!("must be finite and > 0, got {t_end}"),
        ));
    }
    Ok(())
}

/// Checks a study's number of sample times.
pub(crate) fn check_samples(samples: u64) -> Result<(), ErrorDetail> {
    if !(1..=MAX_SAMPLES).contains(&samples) {
        return Err(invalid(
            "samples",
            format!("must lie in 1…{MAX_SAMPLES}, got {samples}"),
        ));
    }
    Ok(())
}

/// How many steps of `h` make up `span`, if a whole number of them does (within round-off).
pub(crate) fn whole_steps(span: f64, h: f64) -> Option<u64> {
    let n = span / h;
    let whole = n.round();
    ((n - whole).abs() <= 1e-9 * n.max(1.0) && whole >= 1.0).then_some(whole as u64)
}

/// A setting as requested.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Setting {
    /// A fixed step size.
    Step(f64),
    /// A tolerance of the adaptive reference.
    Tolerance(f64),
}

/// The request fields a setting's errors name.
pub(crate) struct Fields<'a> {
    /// The method, e.g. `runs[1].method`.
    pub method: &'a str,
    /// The step size or tolerance, e.g. `runs[1].h[2]`.
    pub setting: &'a str,
    /// The chart, e.g. `charts[1]`.
    pub chart: &'a str,
}

/// Prepares one setting: `method` at step `h` on `template` (system, parameters, chart, initial
/// state, t_end) — for a tolerance, the adaptive reference in segments of t_end/samples —
/// sampled at the `samples` times of the study. Every step size must divide t_end/samples, so
/// that the samples are step endpoints.
pub(crate) fn prepare_setting(
    template: &Request,
    method: &MethodSpec,
    setting: Setting,
    samples: u64,
    fields: &Fields<'_>,
    limits: &Limits,
) -> Result<Simulation, ErrorDetail> {
    let segment = template.t_end / samples as f64;
    let path = fields.setting;
    let (h, spec) = match setting {
        Setting::Step(h) => {
            if !(h.is_finite() && h > 0.0) {
                return Err(invalid(path, format!("must be finite and > 0, got {h}")));
            }
            if whole_steps(segment, h).is_none() {
                return Err(invalid(
                    path,
                    format!(
                        "must divide t_end/samples = {segment} so that the samples are step \
                         endpoints; {h} does not"
                    ),
                ));
            }
            (h, method.clone())
        }
        Setting::Tolerance(t) => {
            if !(t.is_finite() && (1e-14..=1e-2).contains(&t)) {
                return Err(invalid(path, format!("must lie in [1e-14, 1e-2], got {t}")));
            }
            let options = match method {
                MethodSpec::Options(o) => o.clone(),
                MethodSpec::Id(id) => MethodOptions {
                    id: id.clone(),
                    ..Default::default()
                },
            };
            let spec = MethodSpec::Options(MethodOptions {
                tolerance: Some(t),
                ..options
            });
            (segment, spec)
        }
    };
    let steps = (template.t_end / h).round().max(1.0) as u64;
    let req = Request {
        methods: vec![spec.to_input()],
        h,
        every: Some((steps / samples).max(1)),
        ..template.clone()
    };
    Simulation::prepare(&req, limits).map_err(|e| {
        let detail = ErrorDetail::from_core(&e, &req, limits);
        let renamed = match detail.field.as_deref() {
            Some(f) if f.starts_with("methods[0]") => {
                Some(f.replacen("methods[0]", fields.method, 1))
            }
            Some("methods") => Some(fields.method.to_string()),
            Some("h") => Some(path.to_string()),
            Some("chart") => Some(fields.chart.to_string()),
            // Too many steps for this setting: its step size is at fault, not t_end.
            Some("t_end") if detail.code == codes::TOO_MANY_STEPS => Some(path.to_string()),
            Some(other) => Some(other.to_string()),
            None => None,
        };
        // A message that starts with the old name starts with the new one.
        let message = match (detail.field.as_deref(), renamed.as_deref()) {
            (Some(old), Some(new)) if old != new && detail.message.starts_with(old) => {
                format!("{new}{}", &detail.message[old.len()..])
            }
            _ => detail.message.clone(),
        };
        ErrorDetail {
            field: renamed,
            message,
            ..detail
        }
    })
}

/// The reference run of a study whose first setting is `first`: none where the system has an
/// exact solution; otherwise `spec` (one step size or tolerance) or by default the adaptive
/// DOP853 at tolerance [`REFERENCE_TOLERANCE`], from `template` in the system's first (Cartesian)
/// chart, sampled at the study's sample times.
pub(crate) fn prepare_reference(
    first: &Simulation,
    template: &Request,
    spec: Option<&RunSpec>,
    samples: u64,
    limits: &Limits,
) -> Result<Option<Simulation>, ErrorDetail> {
    if first.exact_final_state().is_some() {
        return Ok(None);
    }
    let template = Request {
        chart: None,
        initial_cartesian: false,
        ..template.clone()
    };
    let default = RunSpec {
        method: MethodSpec::Id(MethodId::Reference.as_str().into()),
        h: Vec::new(),
        tolerance: vec![REFERENCE_TOLERANCE],
    };
    let spec = spec.unwrap_or(&default);
    let (setting, field) = match (spec.h.first(), spec.tolerance.first()) {
        (Some(&h), None) => (Setting::Step(h), "reference.h"),
        (None, Some(&t)) => (Setting::Tolerance(t), "reference.tolerance"),
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
    let fields = Fields {
        method: "reference.method",
        setting: field,
        chart: "reference",
    };
    prepare_setting(&template, &spec.method, setting, samples, &fields, limits).map(Some)
}

/// The error for a study with more than [`MAX_SETTINGS`] settings, at `field`.
pub(crate) fn too_many_settings(field: &str, what: &str) -> ErrorDetail {
    invalid(
        field,
        format!("at most {MAX_SETTINGS} settings per study; {what}"),
    )
}

/// A validated study, ready to run.
#[derive(Clone, Debug)]
pub struct StudyJob {
    /// One prepared simulation per setting, with the index of its run (or series).
    pub(crate) settings: Vec<(usize, Simulation)>,
    /// The reference run, where the system has no exact solution.
    pub(crate) reference: Option<Simulation>,
    pub(crate) system: SystemSummary,
    pub(crate) t_end: f64,
    pub(crate) samples: u64,
}

impl StudyJob {
    /// The job of `settings` (at least one), refused at `field` when they take more than
    /// [`MAX_STUDY_STEPS`] steps in all.
    pub(crate) fn new(
        settings: Vec<(usize, Simulation)>,
        reference: Option<Simulation>,
        system: SystemSummary,
        t_end: f64,
        samples: u64,
        field: &str,
    ) -> Result<Self, ErrorDetail> {
        let total_steps = settings
            .iter()
            .fold(0u64, |n, (_, sim)| n.saturating_add(sim.schedule.steps));
        if total_steps > MAX_STUDY_STEPS {
            return Err(ErrorDetail::at(
                codes::TOO_MANY_STEPS,
                field,
                format!(
                    "{field}: {total_steps} steps over all settings exceed the limit of \
                     {MAX_STUDY_STEPS} per study; use fewer or larger steps"
                ),
            ));
        }
        Ok(StudyJob {
            settings,
            reference,
            system,
            t_end,
            samples,
        })
    }

    /// Number of settings.
    pub fn len(&self) -> usize {
        self.settings.len()
    }

    /// Whether the study has no settings (never, once validated).
    pub fn is_empty(&self) -> bool {
        self.settings.is_empty()
    }

    /// Runs the reference (or takes the exact solution).
    fn truth(&self, budget: Budget<'_>) -> Result<Truth, ErrorDetail> {
        let Some(sim) = &self.reference else {
            return Ok(Truth {
                description: "exact solution".into(),
                ms: 0.0,
                energies: None,
                final_state: None,
            });
        };
        let started = Instant::now();
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
        Ok(Truth {
            description,
            ms: started.elapsed().as_secs_f64() * 1e3,
            energies: Some(sink.energies),
            final_state: sink.last,
        })
    }
}

/// What a study's errors are measured against.
#[derive(Clone, Debug)]
pub(crate) struct Truth {
    /// `exact solution`, or the reference run's label and setting.
    pub description: String,
    /// Wall time of the reference run in milliseconds (0 for an exact solution).
    pub ms: f64,
    /// The reference energies at the sample times (None for an exact solution).
    pub energies: Option<Vec<f64>>,
    /// The reference run's final state in Cartesian coordinates.
    final_state: Option<(Vec<f64>, Vec<f64>)>,
}

impl Truth {
    /// The Euclidean distance of a Cartesian state at t_end from the true one of `sim`'s run.
    pub(crate) fn state_error(&self, sim: &Simulation, last: &(Vec<f64>, Vec<f64>)) -> Option<f64> {
        let truth = match &self.final_state {
            Some(state) => state.clone(),
            None => sim.exact_final_cartesian()?,
        };
        let (q, p) = last;
        Some(
            q.iter()
                .chain(p)
                .zip(truth.0.iter().chain(&truth.1))
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt(),
        )
    }
}

/// Collects what a study measures from one run's samples.
pub(crate) struct Measure<'a> {
    pub names: &'static [&'static str],
    reference_energies: Option<&'a [f64]>,
    /// max_k |H(t_k) − H_exact(t_k)|.
    pub max_energy_error: f64,
    /// H − H_exact at the last sample.
    pub last_energy_error: Option<f64>,
    invariants_at_start: Vec<f64>,
    /// max_k |I(t_k) − I(0)| per invariant.
    pub drift: Vec<f64>,
    energies: Vec<f64>,
    /// The last state, in Cartesian coordinates.
    pub last: Option<(Vec<f64>, Vec<f64>)>,
}

impl<'a> Measure<'a> {
    fn new(names: &'static [&'static str], reference_energies: Option<&'a [f64]>) -> Self {
        Measure {
            names,
            reference_energies,
            max_energy_error: 0.0,
            last_energy_error: None,
            invariants_at_start: Vec::new(),
            drift: Vec::new(),
            energies: Vec::new(),
            last: None,
        }
    }
}

impl SampleSink for Measure<'_> {
    fn on_sample(&mut self, s: &Sample<'_>) {
        if let Some(e) = s.energy_error {
            self.max_energy_error = self.max_energy_error.max(e.abs());
        }
        self.last_energy_error = s.energy_error;
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
        let (q, p) = s.cartesian.unwrap_or((s.q, s.p));
        self.last = Some((q.to_vec(), p.to_vec()));
    }
}

/// Runs the setting `sim` once against the reference `energies` and measures it; also returns
/// the wall time in milliseconds.
pub(crate) fn measure_once<'a>(
    sim: &Simulation,
    energies: Option<&'a [f64]>,
    budget: Budget<'_>,
) -> Result<(Outcome, Measure<'a>, f64), ErrorDetail> {
    let mut sink = Measure::new(sim.invariant_names(), energies);
    let began = Instant::now();
    let outcome = sim
        .run_method(0, energies, budget, &mut sink)
        .map_err(|e| {
            ErrorDetail::new(
                codes::STEP_FAILED,
                format!("{}: {e}", sim.methods[0].label()),
            )
        })?;
    Ok((outcome, sink, began.elapsed().as_secs_f64() * 1e3))
}

/// [`measure_once`], with short runs timed again (their numbers are the same, bit for bit): the
/// wall time is the median, so that one scheduling hiccup does not move a point of a diagram.
pub(crate) fn measure_timed<'a>(
    sim: &Simulation,
    energies: Option<&'a [f64]>,
    budget: Budget<'_>,
) -> Result<(Outcome, Measure<'a>, f64), ErrorDetail> {
    let (outcome, sink, first) = measure_once(sim, energies, budget)?;
    let mut times = vec![first];
    while outcome.stop == StopReason::Finished
        && times.len() < SHORT_RUN_REPEATS
        && times[0] < SHORT_RUN_MS
    {
        times.push(measure_once(sim, energies, budget)?.2);
    }
    times.sort_by(f64::total_cmp);
    Ok((outcome, sink, times[times.len() / 2]))
}

/// How a run stopped, as studies report it.
pub(crate) fn stop_name(stop: &StopReason) -> &'static str {
    match stop {
        StopReason::Finished => "finished",
        StopReason::Diverged { .. } => "diverged",
        StopReason::Cancelled { .. } => "cancelled",
        _ => "time_limit",
    }
}

/// The least-squares line through (log₁₀ x, log₁₀ y): (slope, intercept), or nothing for fewer
/// than two distinct x.
pub(crate) fn fit(points: &[(f64, f64)]) -> (Option<f64>, Option<f64>) {
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

/// The lines of a study's progress stream, as the study and the HTTP layer build them.
pub trait ProgressLine: Serialize + Send + 'static {
    /// One setting's measurements.
    type Point: Clone;
    /// The whole study.
    type Document: Serialize + Send + 'static;
    /// The reference run is done (or the exact solution is used).
    fn reference(reference: String, reference_ms: f64, total: usize) -> Self;
    /// A setting is done.
    fn point(done: usize, total: usize, point: Self::Point) -> Self;
    /// The study is done.
    fn result(document: Self::Document) -> Self;
    /// The study failed.
    fn error(error: ErrorDetail) -> Self;
    /// The last line of a complete stream.
    fn end() -> Self;
}

/// A study's run function: the job, given a time budget and where to report its lines (see
/// [`run_settings`]), to its document.
pub type Runner<L> = fn(
    &StudyJob,
    Budget<'_>,
    &dyn Fn(L) -> bool,
) -> Result<<L as ProgressLine>::Document, ErrorDetail>;

/// Declares a study's progress line type, `$name`, carrying `$point` per setting and `$document`
/// at the end, and implements [`ProgressLine`] for it.
macro_rules! progress_lines {
    ($(#[$meta:meta])* $name:ident, $point:ty, $document:ty) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq, serde::Serialize, utoipa::ToSchema)]
        #[serde(tag = "type", rename_all = "snake_case")]
        pub enum $name {
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
                point: $point,
            },
            /// The whole study.
            Result($document),
            /// A failure (the reference run, a server fault).
            Error {
                /// What went wrong.
                error: $crate::api::error::ErrorDetail,
            },
            /// The last line of a complete stream.
            End,
        }

        impl $crate::api::study::ProgressLine for $name {
            type Point = $point;
            type Document = $document;
            fn reference(reference: String, reference_ms: f64, total: usize) -> Self {
                Self::Reference { reference, reference_ms, total }
            }
            fn point(done: usize, total: usize, point: $point) -> Self {
                Self::Point { done, total, point }
            }
            fn result(document: $document) -> Self {
                Self::Result(document)
            }
            fn error(error: $crate::api::error::ErrorDetail) -> Self {
                Self::Error { error }
            }
            fn end() -> Self {
                Self::End
            }
        }
    };
}
pub(crate) use progress_lines;

/// Runs a study: the reference (or the exact solution), then every setting in order, measured by
/// `measure` (given the setting's run index, its simulation and the truth; it returns the point
/// and how the run stopped). Reports each line to `emit`, which returns false once nobody
/// listens; a cancelled run or a missing listener ends the study.
pub(crate) fn run_settings<L: ProgressLine>(
    job: &StudyJob,
    budget: Budget<'_>,
    emit: &dyn Fn(L) -> bool,
    measure: impl Fn(usize, &Simulation, &Truth) -> Result<(L::Point, StopReason), ErrorDetail>,
) -> Result<(Truth, Vec<L::Point>), ErrorDetail> {
    let total = job.settings.len();
    let truth = job.truth(budget)?;
    emit(L::reference(truth.description.clone(), truth.ms, total));
    let mut points = Vec::with_capacity(total);
    for (done, (run, sim)) in job.settings.iter().enumerate() {
        let (point, stop) = measure(*run, sim, &truth)?;
        let listening = emit(L::point(done + 1, total, point.clone()));
        points.push(point);
        if !listening || matches!(stop, StopReason::Cancelled { .. }) {
            return Err(ErrorDetail::new(
                codes::OVERLOADED,
                "the study was cancelled",
            ));
        }
    }
    Ok((truth, points))
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

    #[test]
    fn whole_steps_allow_round_off_only() {
        assert_eq!(whole_steps(10.0, 0.04), Some(250));
        assert_eq!(whole_steps(10.0, 0.04 / 32.0), Some(8000));
        assert_eq!(whole_steps(10.0, 0.3), None);
        assert_eq!(whole_steps(1.0, 3.0), None);
    }
}

//! Convergence studies — the body of `POST /api/v1/studies/convergence` and of
//! `geomint study convergence` — their strict parser, and the study itself.
//!
//! A study runs one system from one physical initial state to `t_end` with several methods, in
//! one or several coordinate charts, each at several step sizes, and measures per setting the
//! errors at t_end against the exact solution (where the system has one) or a reference run: the
//! state error in Cartesian coordinates, so that runs in different charts compare (the exact flow
//! does not depend on the chart), and the energy error (H is the same in every chart) at t_end
//! and as the largest over the sample times. Per method and chart — a *series* — it fits the
//! observed order: the least-squares slope of log error against log h, over the errors above
//! round-off (1e-14).
//!
//! The reference run (by default the adaptive DOP853 at tolerance 1e-13, one segment per sample
//! interval) runs in the system's first, Cartesian chart. Every setting is sampled at the same
//! times t_k = k·t_end/samples; by default `samples` is the largest number up to 1000 that every
//! setting's step count is a multiple of.

use serde::Serialize;
use serde_json::{Map, Value};
use utoipa::ToSchema;

use super::document::SystemSummary;
use super::error::ErrorDetail;
use super::request::{
    check_fields, initial_coordinates, methods, missing, numbers, object, present, string,
    wrong_type, InitialCoordinates, MethodSpec,
};
use super::study::{
    self, invalid, measure_once, prepare_reference, prepare_setting, progress_lines, stop_name,
    too_many_settings, whole_steps, Common, Fields, RunSpec, Setting, StudyJob, MAX_SAMPLES,
    MAX_SETTINGS,
};
use crate::core::error::CoreError;
use crate::core::run::{Budget, StopReason};
use crate::core::simulate::{Limits, Request};
use crate::core::systems;

/// The fields of a convergence study.
pub const CONVERGENCE_FIELDS: &[&str] = &[
    "system",
    "params",
    "chart",
    "charts",
    "initial_coordinates",
    "q0",
    "p0",
    "t_end",
    "methods",
    "h",
    "samples",
    "reference",
];
/// Largest default number of sample times.
pub const DEFAULT_MAX_SAMPLES: u64 = MAX_SAMPLES;
/// Errors at or below this are round-off, which does not shrink with h: the fits leave them out.
pub const ROUND_OFF: f64 = 1e-14;

/// A convergence study.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({
    "system": "harmonic_oscillator",
    "params": {"omega": 1, "gamma": 0},
    "charts": ["cartesian", "compensating"],
    "q0": [1], "p0": [0],
    "t_end": 10,
    "methods": ["symplectic_euler"],
    "h": [0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125]
}))]
pub struct ConvergenceRequest {
    /// System id.
    pub system: String,
    /// System parameters (as for a simulation).
    #[schema(value_type = Object)]
    pub params: Map<String, Value>,
    /// One coordinate chart (default: the system's first, Cartesian one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chart: Option<String>,
    /// Several charts, instead of `chart`: every method runs in each, from the same physical
    /// initial state.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub charts: Vec<String>,
    /// The coordinates `q0` and `p0` are given in: `chart` (the default with one chart) or
    /// `cartesian` (the default, and the only choice, with several charts). Omitted `q0`/`p0`
    /// are the catalogue's Cartesian defaults.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub initial_coordinates: Option<InitialCoordinates>,
    /// Initial positions (default: the system's).
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default: the system's).
    pub p0: Option<Vec<f64>>,
    /// Final time (finite, > 0).
    pub t_end: f64,
    /// The methods, as in a simulation (ids, or objects with options).
    pub methods: Vec<MethodSpec>,
    /// Step sizes, each dividing t_end into a whole number of steps.
    pub h: Vec<f64>,
    /// Evenly spaced sample times t_k = k·t_end/samples, k = 1…samples, over which the largest
    /// energy error is taken (1 to 1000; every step size must divide t_end/samples). Default:
    /// the largest number up to 1000 that divides every setting's step count.
    pub samples: Option<u64>,
    /// The run the errors are measured against where the system has no exact solution
    /// (default: `reference` at tolerance 1e-13), in the system's Cartesian chart. Give one step
    /// size or tolerance.
    pub reference: Option<RunSpec>,
}

/// One setting: a method in a chart at one step size, and its errors at t_end.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct ConvergencePoint {
    /// Index of the series (method and chart) in the document's `series`.
    pub series: usize,
    /// The method's label, e.g. `kahan_li_8(modin_3s)`.
    pub method: String,
    /// The chart the method ran in.
    pub chart: String,
    /// The step size.
    pub h: f64,
    /// Steps taken.
    pub steps: u64,
    /// Euclidean norm of (x, p_x)(t_end) − (x, p_x)_exact(t_end) in Cartesian coordinates
    /// (`null` if the run did not finish).
    pub state_error: Option<f64>,
    /// |H(t_end) − H_exact(t_end)| (`null` if the run did not finish).
    pub energy_error: Option<f64>,
    /// max_k |H(t_k) − H_exact(t_k)| over the sample times (`null` if the run did not finish).
    pub max_energy_error: Option<f64>,
    /// `finished`, `diverged`, `time_limit` or `cancelled`.
    pub stop: String,
}

/// The observed order of one error: log₁₀ error ≈ intercept + order·log₁₀ h, by least squares
/// over the series' finished settings with an error above round-off (1e-14).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
pub struct OrderFit {
    /// The slope d log error / d log h (`null` with fewer than two settings).
    pub order: Option<f64>,
    /// log₁₀ error at h = 1.
    pub intercept: Option<f64>,
    /// Settings in the fit.
    pub points: usize,
}

/// One method in one chart, with its fitted orders.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct ConvergenceSeries {
    /// The method's label.
    pub method: String,
    /// The chart.
    pub chart: String,
    /// The method, and its chart when the study has several.
    pub label: String,
    /// Order of the state error at t_end.
    pub state: OrderFit,
    /// Order of the energy error at t_end.
    pub energy: OrderFit,
    /// Order of the largest energy error over the samples.
    pub max_energy: OrderFit,
}

/// The answer to a convergence study.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct ConvergenceDocument {
    /// The system, parameters resolved, with the initial state in Cartesian coordinates.
    pub system: SystemSummary,
    /// The charts, in request order.
    pub charts: Vec<String>,
    /// Final time.
    pub t_end: f64,
    /// Sample times.
    pub samples: u64,
    /// What the errors are measured against: `exact solution` or the reference run's label and
    /// setting.
    pub reference: String,
    /// Wall time of the reference run in milliseconds (0 for an exact solution).
    pub reference_ms: f64,
    /// Every setting: per method, per chart, per step size, in request order.
    pub points: Vec<ConvergencePoint>,
    /// One entry per method and chart (method by method, charts in order), with its orders.
    pub series: Vec<ConvergenceSeries>,
}

progress_lines! {
    /// What a convergence study's progress stream carries.
    ConvergenceLine, ConvergencePoint, ConvergenceDocument
}

/// Greatest common divisor.
fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The largest divisor of `n` that is at most `most`.
fn largest_divisor(n: u64, most: u64) -> u64 {
    (1..=most.min(n)).rev().find(|d| n % d == 0).unwrap_or(1)
}

impl ConvergenceRequest {
    /// Parses a study from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&super::request::parse_json(bytes)?)
    }

    /// Parses a study from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = object(value, None)?;
        check_fields(obj, CONVERGENCE_FIELDS, "")?;
        let common = Common::parse(obj)?;
        let charts = match present(obj, "charts") {
            Some(v) => v
                .as_array()
                .ok_or_else(|| wrong_type("charts", "a list of chart ids", v))?
                .iter()
                .enumerate()
                .map(|(j, c)| string(c, &format!("charts[{j}]")))
                .collect::<Result<Vec<_>, _>>()?,
            None => Vec::new(),
        };
        if present(obj, "charts").is_some() && charts.is_empty() {
            return Err(invalid("charts", "give at least one chart"));
        }
        let methods = match present(obj, "methods") {
            Some(v) => methods(v)?,
            None => {
                return Err(missing(
                    "methods",
                    "the methods, e.g. [\"symplectic_euler\", \"rk4\"]",
                ))
            }
        };
        let h = match present(obj, "h") {
            Some(v) => numbers(v, "h")?,
            None => {
                return Err(missing(
                    "h",
                    "the step sizes, e.g. [0.04, 0.02, 0.01, 0.005]",
                ))
            }
        };
        Ok(ConvergenceRequest {
            system: common.system,
            params: common.params,
            chart: present(obj, "chart")
                .map(|v| string(v, "chart"))
                .transpose()?,
            charts,
            initial_coordinates: present(obj, "initial_coordinates")
                .map(initial_coordinates)
                .transpose()?,
            q0: common.q0,
            p0: common.p0,
            t_end: common.t_end,
            methods,
            h,
            samples: common.samples,
            reference: common.reference,
        })
    }

    /// The charts to run in, each with the field that names it (`None`: the default chart).
    fn chart_list(&self) -> Result<Vec<(Option<&str>, String)>, ErrorDetail> {
        match (&self.chart, self.charts.as_slice()) {
            (Some(_), [_, ..]) => Err(invalid(
                "charts",
                "give either `chart` (one) or `charts` (several), not both",
            )),
            (Some(c), []) => Ok(vec![(Some(c.as_str()), "chart".into())]),
            (None, []) => Ok(vec![(None, "chart".into())]),
            (None, list) => {
                for (j, c) in list.iter().enumerate() {
                    if list[..j].contains(c) {
                        return Err(invalid(
                            format!("charts[{j}]"),
                            format!("`{c}` is listed twice"),
                        ));
                    }
                }
                Ok(list
                    .iter()
                    .enumerate()
                    .map(|(j, c)| (Some(c.as_str()), format!("charts[{j}]")))
                    .collect())
            }
        }
    }

    /// The number of steps of every step size, or an error naming the first that does not
    /// divide t_end.
    fn step_counts(&self) -> Result<Vec<u64>, ErrorDetail> {
        if self.h.is_empty() {
            return Err(invalid("h", "give at least one step size"));
        }
        self.h
            .iter()
            .enumerate()
            .map(|(k, &h)| {
                let field = format!("h[{k}]");
                if !(h.is_finite() && h > 0.0) {
                    return Err(invalid(field, format!("must be finite and > 0, got {h}")));
                }
                whole_steps(self.t_end, h).ok_or_else(|| {
                    invalid(
                        field,
                        format!(
                            "must divide t_end = {} into a whole number of steps; t_end/h = {}",
                            self.t_end,
                            self.t_end / h
                        ),
                    )
                })
            })
            .collect()
    }

    /// Validates the study (cheap: nothing is integrated).
    pub fn prepare(&self, limits: &Limits) -> Result<StudyJob, ErrorDetail> {
        let info = systems::info(&self.system)
            .map_err(|e| ErrorDetail::from_core(&e, &Request::default(), limits))?;
        let charts = self.chart_list()?;
        for (chart, field) in &charts {
            systems::chart_of(&info, *chart).map_err(|e| match e {
                CoreError::Invalid { message, .. } => invalid(field.as_str(), message),
                other => invalid(field.as_str(), other),
            })?;
        }
        let several = charts.len() > 1;
        let given = self.q0.is_some() || self.p0.is_some();
        if several && given && self.initial_coordinates == Some(InitialCoordinates::Chart) {
            return Err(invalid(
                "initial_coordinates",
                "with several charts q0 and p0 are one physical state: give them in `cartesian` \
                 coordinates",
            ));
        }
        let initial_cartesian = match self.initial_coordinates {
            Some(c) => c == InitialCoordinates::Cartesian,
            None => several,
        };
        study::check_t_end(self.t_end)?;
        if self.methods.is_empty() {
            return Err(invalid("methods", "give at least one method"));
        }
        let steps = self.step_counts()?;
        let count = self.methods.len() * charts.len() * self.h.len();
        if count > MAX_SETTINGS {
            return Err(too_many_settings(
                "h",
                &format!(
                    "{} methods × {} charts × {} step sizes make {count}",
                    self.methods.len(),
                    charts.len(),
                    self.h.len()
                ),
            ));
        }
        let samples = match self.samples {
            Some(n) => n,
            None => largest_divisor(steps.iter().copied().fold(0, gcd), DEFAULT_MAX_SAMPLES),
        };
        study::check_samples(samples)?;

        let mut settings = Vec::with_capacity(count);
        for (i, method) in self.methods.iter().enumerate() {
            let method_field = format!("methods[{i}]");
            for (j, (chart, chart_field)) in charts.iter().enumerate() {
                let template = Request {
                    system: self.system.clone(),
                    params: self.params.clone(),
                    chart: chart.map(str::to_string),
                    initial_cartesian,
                    t_end: self.t_end,
                    q0: self.q0.clone(),
                    p0: self.p0.clone(),
                    ..Request::default()
                };
                for (k, &h) in self.h.iter().enumerate() {
                    let fields = Fields {
                        method: &method_field,
                        setting: &format!("h[{k}]"),
                        chart: chart_field,
                    };
                    let sim = prepare_setting(
                        &template,
                        method,
                        Setting::Step(h),
                        samples,
                        &fields,
                        limits,
                    )?;
                    settings.push((i * charts.len() + j, sim));
                }
            }
        }

        // One physical initial state: the first setting's, in Cartesian coordinates.
        let first = &settings[0].1;
        let (x0, px0) = first.cartesian_state(&first.q0, &first.p0);
        let reference_template = Request {
            system: self.system.clone(),
            params: self.params.clone(),
            t_end: self.t_end,
            q0: Some(x0.clone()),
            p0: Some(px0.clone()),
            ..Request::default()
        };
        let reference = prepare_reference(
            first,
            &reference_template,
            self.reference.as_ref(),
            samples,
            limits,
        )?;
        if reference.is_some() {
            // The reference starts where every setting starts.
            for (_, sim) in &settings {
                let (x, px) = sim.cartesian_state(&sim.q0, &sim.p0);
                let apart = x
                    .iter()
                    .chain(&px)
                    .zip(x0.iter().chain(&px0))
                    .any(|(a, b)| (a - b).abs() > 1e-12 * (1.0 + b.abs()));
                if apart {
                    return Err(invalid(
                        "q0",
                        format!(
                            "the initial state in the `{}` chart at h = {} is another physical \
                             state than at the first setting; give q0 and p0 in Cartesian \
                             coordinates",
                            sim.chart, sim.schedule.h
                        ),
                    ));
                }
            }
        }
        let system = SystemSummary {
            q0: x0,
            p0: px0,
            ..SystemSummary::of(first)
        };
        StudyJob::new(settings, reference, system, self.t_end, samples, "h")
    }
}

/// The observed order of `data` (h, error), over the finite errors above [`ROUND_OFF`].
fn order_of(data: impl Iterator<Item = (f64, Option<f64>)>) -> OrderFit {
    let data: Vec<(f64, f64)> = data
        .filter_map(|(h, e)| {
            e.filter(|&e| e > ROUND_OFF && e.is_finite())
                .map(|e| (h, e))
        })
        .collect();
    let (order, intercept) = study::fit(&data);
    OrderFit {
        order,
        intercept,
        points: data.len(),
    }
}

/// Runs a study, reporting each line to `emit` (which returns false once nobody listens) and
/// returning the document.
pub fn run(
    job: &StudyJob,
    budget: Budget<'_>,
    emit: &dyn Fn(ConvergenceLine) -> bool,
) -> Result<ConvergenceDocument, ErrorDetail> {
    let (truth, points) = study::run_settings(job, budget, emit, |series, sim, truth| {
        let (outcome, sink, _) = measure_once(sim, truth.energies.as_deref(), budget)?;
        let finished = outcome.stop == StopReason::Finished;
        let point = ConvergencePoint {
            series,
            method: sim.methods[0].label(),
            chart: sim.chart.clone(),
            h: sim.schedule.h,
            steps: outcome.stats.steps,
            state_error: sink
                .last
                .as_ref()
                .filter(|_| finished)
                .and_then(|last| truth.state_error(sim, last)),
            energy_error: sink.last_energy_error.filter(|_| finished).map(f64::abs),
            max_energy_error: sink
                .last_energy_error
                .filter(|_| finished)
                .map(|_| sink.max_energy_error),
            stop: stop_name(&outcome.stop).to_string(),
        };
        Ok((point, outcome.stop))
    })?;

    let mut charts: Vec<String> = Vec::new();
    for p in &points {
        if !charts.contains(&p.chart) {
            charts.push(p.chart.clone());
        }
    }
    let count = job.settings.last().map_or(0, |s| s.0 + 1);
    let series = (0..count)
        .filter_map(|s| {
            let mine: Vec<&ConvergencePoint> = points
                .iter()
                .filter(|p| p.series == s && p.stop == "finished")
                .collect();
            let first = points.iter().find(|p| p.series == s)?;
            let fit = |error: fn(&ConvergencePoint) -> Option<f64>| {
                order_of(mine.iter().map(|p| (p.h, error(p))))
            };
            Some(ConvergenceSeries {
                method: first.method.clone(),
                chart: first.chart.clone(),
                label: if charts.len() > 1 {
                    format!("{} [{}]", first.method, first.chart)
                } else {
                    first.method.clone()
                },
                state: fit(|p| p.state_error),
                energy: fit(|p| p.energy_error),
                max_energy: fit(|p| p.max_energy_error),
            })
        })
        .collect();
    Ok(ConvergenceDocument {
        system: job.system.clone(),
        charts,
        t_end: job.t_end,
        samples: job.samples,
        reference: truth.description,
        reference_ms: truth.ms,
        points,
        series,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn field_of(body: Value) -> Option<String> {
        ConvergenceRequest::from_value(&body)
            .and_then(|r| r.prepare(&Limits::default()))
            .unwrap_err()
            .field
    }

    #[test]
    fn default_samples_divide_every_step_count() {
        assert_eq!(largest_divisor(250, 1000), 250);
        assert_eq!(largest_divisor(8000, 1000), 1000);
        assert_eq!(largest_divisor(1024 * 3, 1000), 768);
        assert_eq!(largest_divisor(7, 1000), 7);
        assert_eq!([250u64, 500, 1000].into_iter().fold(0, gcd), 250);
        let req = ConvergenceRequest::from_value(&json!({
            "system": "harmonic_oscillator", "t_end": 9, "methods": ["rk4"], "h": [0.3, 0.45]}))
        .unwrap();
        assert_eq!(req.prepare(&Limits::default()).unwrap().samples, 10);
    }

    #[test]
    fn fields_are_named() {
        let ok = json!({"system": "harmonic_oscillator", "t_end": 1, "methods": ["rk4"],
            "h": [0.1, 0.05]});
        let with = |key: &str, v: Value| {
            let mut body = ok.clone();
            body[key] = v;
            body
        };
        assert_eq!(
            field_of(with("h", json!([0.1, 0.3]))).as_deref(),
            Some("h[1]")
        );
        assert_eq!(field_of(with("h", json!([]))).as_deref(), Some("h"));
        assert_eq!(
            field_of(with("methods", json!([]))).as_deref(),
            Some("methods")
        );
        assert_eq!(
            field_of(with("chart", json!("polar"))).as_deref(),
            Some("chart")
        );
        assert_eq!(
            field_of(with("charts", json!(["cartesian", "cartesian"]))).as_deref(),
            Some("charts[1]")
        );
        let mut both = with("charts", json!(["cartesian", "compensating"]));
        both["chart"] = json!("cartesian");
        assert_eq!(field_of(both).as_deref(), Some("charts"));
        let mut in_chart = with("charts", json!(["cartesian", "compensating"]));
        in_chart["q0"] = json!([0.5]);
        in_chart["initial_coordinates"] = json!("chart");
        assert_eq!(field_of(in_chart).as_deref(), Some("initial_coordinates"));
        assert_eq!(field_of(with("samples", json!(3))).as_deref(), Some("h[0]"));
        assert_eq!(
            field_of(with(
                "methods",
                json!(["rk4", {"id": "kahan_li_8", "base": "heun"}])
            ))
            .as_deref(),
            Some("methods[1].base")
        );
    }
}

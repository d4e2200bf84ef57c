//! Convergence studies: one system from one physical initial state to `t_end`, run with several
//! methods, in one or several coordinate charts, each at several step sizes; per setting the
//! errors at t_end against the exact solution (where the system has one) or a reference run — the
//! state error in Cartesian coordinates, so that runs in different charts compare (the exact flow
//! does not depend on the chart), and the energy error (H is the same in every chart) at t_end
//! and as the largest over the sample times. Per method and chart — a *series* — the observed
//! order: the least-squares slope of log error against log h, over the errors above round-off.
//!
//! The reference run (by default the adaptive DOP853 at tolerance 1e-13, one segment per sample
//! interval) runs in the system's first, Cartesian chart. Every setting is sampled at the same
//! times t_k = k·t_end/samples; by default `samples` is the largest number up to 1000 that every
//! setting's step count is a multiple of.

use std::collections::BTreeMap;

use serde::Serialize;

use super::engine::{Executor, Order};
use super::settings::{
    self, check_samples, check_t_end, measure_once, prepare_reference, prepare_setting,
    progress_lines, stop_name, whole_steps, RunSpec, Setting, SettingsStudy, StudyJob, Truth,
    MAX_SAMPLES, MAX_SETTINGS,
};
use super::StudySpec;
use crate::diagnostics::fit_log_log;
use crate::error::{CoreError, Field, Range};
use crate::run::{Budget, RunEnd};
use crate::simulation::{
    InitialCoordinates, InputFields, Limits, MethodAt, Simulation, SimulationSpec, SystemSummary,
};
use crate::studies::parts::{Part, ShardAt, Travelling};
use crate::systems::{ParamValue, SystemRef};

/// Errors at or below this are round-off, which does not shrink with h: the fits leave them out.
pub const ROUND_OFF: f64 = 1e-14;

/// A convergence study as asked for.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ConvergenceSpec {
    /// System id.
    pub system: SystemRef,
    /// System parameters.
    pub params: BTreeMap<String, ParamValue>,
    /// One chart (`chart`), or none for the default.
    pub chart: Option<String>,
    /// Several charts (`charts`), instead of `chart`.
    pub charts: Vec<String>,
    /// The coordinates `q0` and `p0` are given in (default: the chart's with one chart,
    /// Cartesian with several).
    pub initial_coordinates: Option<InitialCoordinates>,
    /// Initial positions.
    pub q0: Option<Vec<f64>>,
    /// Initial momenta.
    pub p0: Option<Vec<f64>>,
    /// Final time.
    pub t_end: f64,
    /// The methods, each with its field (`methods[i]`).
    pub methods: Vec<MethodAt>,
    /// Step sizes, each dividing t_end.
    pub h: Vec<f64>,
    /// Sample times (default: the largest divisor up to 1000 of every step count).
    pub samples: Option<u64>,
    /// The reference run, where the system has no exact solution.
    pub reference: Option<RunSpec>,
}

/// One setting: a method in a chart at one step size, and its errors at t_end.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct OrderFit {
    /// The slope d log error / d log h (`null` with fewer than two settings).
    pub order: Option<f64>,
    /// log₁₀ error at h = 1.
    pub intercept: Option<f64>,
    /// Settings in the fit.
    pub points: usize,
}

/// One method in one chart, with its fitted orders.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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

/// The sample times a study takes when none are asked for: as many as divide every run's
/// step count, at most [`MAX_SAMPLES`], so that every run is sampled at the same times.
pub fn default_samples(step_counts: &[u64]) -> u64 {
    largest_divisor(step_counts.iter().copied().fold(0, gcd), MAX_SAMPLES)
}

impl ConvergenceSpec {
    /// The charts to run in, each with the field that names it (`None`: the default chart).
    fn chart_list(&self) -> Result<Vec<(Option<&str>, Field)>, CoreError> {
        match (&self.chart, self.charts.as_slice()) {
            (Some(_), [_, ..]) => Err(CoreError::Either {
                field: Field::new("charts"),
                first: "`chart` (one)",
                second: "`charts` (several)",
            }),
            (Some(c), []) => Ok(vec![(Some(c.as_str()), Field::new("chart"))]),
            (None, []) => Ok(vec![(None, Field::new("chart"))]),
            (None, list) => {
                let charts = Field::new("charts");
                for (j, c) in list.iter().enumerate() {
                    if list[..j].contains(c) {
                        return Err(CoreError::Duplicate {
                            field: charts.index(j),
                            value: c.clone(),
                        });
                    }
                }
                Ok(list
                    .iter()
                    .enumerate()
                    .map(|(j, c)| (Some(c.as_str()), charts.index(j)))
                    .collect())
            }
        }
    }

    /// The number of steps of every step size, or an error naming the first that does not
    /// divide t_end.
    fn step_counts(&self) -> Result<Vec<u64>, CoreError> {
        let hs = Field::new("h");
        if self.h.is_empty() {
            return Err(CoreError::Empty {
                field: hs,
                what: "step size",
            });
        }
        self.h
            .iter()
            .enumerate()
            .map(|(k, &h)| {
                let field = hs.index(k);
                Range::POSITIVE.check(h, &field)?;
                whole_steps(self.t_end, h).ok_or(CoreError::NotADivisor {
                    field,
                    h,
                    span: self.t_end,
                    span_name: "t_end",
                    purpose: "into a whole number of steps",
                    show_ratio: true,
                })
            })
            .collect()
    }

    /// Validates the study (cheap: nothing is integrated).
    pub fn prepare(&self, limits: &Limits) -> Result<StudyJob, CoreError> {
        let info = self.system.resolve(&Field::new("system"))?;
        let charts = self.chart_list()?;
        for (chart, field) in &charts {
            info.chart(*chart, field)?;
        }
        let initial_cartesian = InitialCoordinates::cartesian_in_study(
            self.initial_coordinates,
            charts.len(),
            self.q0.is_some() || self.p0.is_some(),
        )?;
        check_t_end(self.t_end)?;
        if self.methods.is_empty() {
            return Err(CoreError::Empty {
                field: Field::new("methods"),
                what: "method",
            });
        }
        let steps = self.step_counts()?;
        let count = self.methods.len() * charts.len() * self.h.len();
        if count > MAX_SETTINGS {
            return Err(CoreError::TooMany {
                field: Field::new("h"),
                what: "settings per study",
                limit: MAX_SETTINGS,
                got: Some(count),
            });
        }
        let samples = check_samples(match self.samples {
            Some(n) => n,
            None => default_samples(&steps),
        })?;

        let mut settings = Vec::with_capacity(count);
        for (i, method) in self.methods.iter().enumerate() {
            for (j, (chart, chart_field)) in charts.iter().enumerate() {
                let template = SimulationSpec {
                    system: self.system.clone(),
                    params: self.params.clone(),
                    chart: chart.map(str::to_string),
                    initial_cartesian,
                    methods: Vec::new(),
                    h: 0.0,
                    t_end: self.t_end,
                    q0: self.q0.clone(),
                    p0: self.p0.clone(),
                    every: None,
                    compare_to_reference: false,
                    jacobian_defect: false,
                    fields: InputFields {
                        chart: chart_field.clone(),
                        ..InputFields::default()
                    },
                };
                for (k, &h) in self.h.iter().enumerate() {
                    let at = Field::new("h").index(k);
                    let sim =
                        prepare_setting(&template, method, Setting::Step(h), samples, &at, limits)?;
                    settings.push((i * charts.len() + j, sim));
                }
            }
        }

        // One physical initial state: the first setting's, in Cartesian coordinates.
        let first = &settings[0].1;
        let (x0, px0) = first.cartesian_state(&first.q0, &first.p0);
        let reference_template = SimulationSpec {
            params: self.params.clone(),
            q0: Some(x0.clone()),
            p0: Some(px0.clone()),
            ..SimulationSpec::new(self.system.clone(), &[], 0.0, self.t_end)
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
                    return Err(CoreError::StateDiffers {
                        field: Field::new("q0"),
                        chart: sim.chart.id.to_string(),
                        h: sim.schedule.h,
                    });
                }
            }
        }
        let system = SystemSummary {
            q0: x0,
            p0: px0,
            ..SystemSummary::of(first)
        };
        let spec = StudySpec::Convergence(self.clone());
        StudyJob::new(spec, settings, reference, system, self.t_end, samples, "h")
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
    let fit = fit_log_log(&data);
    OrderFit {
        order: fit.map(|f| f.0),
        intercept: fit.map(|f| f.1),
        points: data.len(),
    }
}

/// Measures one setting: its errors at t_end against the truth.
fn point(
    _job: &StudyJob,
    series: usize,
    sim: &Simulation,
    truth: &Truth,
    budget: Budget<'_>,
) -> Result<ConvergencePoint, CoreError> {
    let (outcome, sink, _) = measure_once(sim, truth.energies.as_deref(), budget)?;
    let finished = outcome.stop == RunEnd::Finished;
    Ok(ConvergencePoint {
        series,
        method: sim.methods[0].label(),
        chart: sim.chart.id.to_string(),
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
    })
}

/// The settings of `job` as the engine runs them, measured against `truth`.
pub fn study(job: &StudyJob, truth: Truth) -> SettingsStudy<'_, ConvergencePoint> {
    SettingsStudy::new(job, truth, point, Order::Parallel)
}

/// Runs a study on `executor` (its settings in parallel: errors do not depend on timing),
/// reporting each line to `emit`, and returns the document.
pub fn run<E: Executor>(
    job: &StudyJob,
    executor: &E,
    budget: Budget<'_>,
    emit: &(dyn Fn(ConvergenceLine) -> bool + Sync),
) -> Result<ConvergenceDocument, CoreError> {
    let (truth, points) =
        settings::run_settings(job, executor, budget, emit, |truth| study(job, truth))?;

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

/// A shard of it, as a worker or an array task runs it.
impl Travelling for ConvergenceSpec {
    type Cell = ConvergencePoint;

    fn run_shard(
        &self,
        at: &ShardAt<'_>,
        limits: &crate::simulation::Limits,
    ) -> Result<Part<Self::Cell>, CoreError> {
        let job = self.prepare(limits)?;
        at.run(&study(&job, job.truth(Budget::default())?))
    }
}

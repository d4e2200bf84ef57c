//! What the settings-based studies share — [work–precision](super::work_precision) and
//! [convergence](super::convergence): a setting (a method at a step size, or the adaptive
//! reference at a tolerance) prepared as a simulation sampled at the study's sample times, the
//! run that errors are measured against (the exact solution or a reference run in the system's
//! Cartesian chart), one setting's measurements ([`measure`](super::measure)), and the
//! progress lines. Each setting is a cell of the study engine ([`SettingsStudy`]), measured
//! against the truth.
//!
//! A study runs one system from one initial state to `t_end`, sampled at the same `samples` times
//! t_k = k·t_end/samples in every setting, so that errors over the samples compare between
//! settings and a reference run supplies the energies at exactly those times.

use std::ops::Range as Cells;
use std::time::Instant;

use serde::de::DeserializeOwned;
use serde::Serialize;

pub use super::measure::{measure_once, measure_timed, median, stop_name, Measure, MAX_REPEATS};

use super::engine::{self, Executor, Order, Study};
use super::StudySpec;
use crate::error::{CoreError, ErrorDetail, Field, Range, StepScope};
use crate::methods::{Method, MethodId, TOLERANCE_RANGE};
use crate::run::{Budget, RunEnd};
use crate::simulation::{InputFields, Limits, MethodAt, Simulation, SimulationSpec, SystemSummary};

/// Most settings (step sizes and tolerances over all runs) in one study.
pub const MAX_SETTINGS: usize = 64;
/// Most fixed steps over all settings of one study.
pub const MAX_STUDY_STEPS: u64 = 200_000_000;
/// Most sample times.
pub const MAX_SAMPLES: u64 = 1000;
/// Tolerance of the default reference run.
pub const REFERENCE_TOLERANCE: f64 = 1e-13;

/// A method with its settings, as a study lists it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunSpec {
    /// The method and its field (`runs[1].method`).
    pub method: MethodAt,
    /// Step sizes (fixed-step methods), each dividing t_end/samples.
    pub h: Vec<f64>,
    /// Tolerances (the adaptive `reference` only), in [1e-14, 1e-2].
    pub tolerance: Vec<f64>,
    /// The run's field (`runs[1]`, `reference`).
    pub field: Field,
}

/// Checks a study's final time.
pub fn check_t_end(t_end: f64) -> Result<f64, CoreError> {
    Range::POSITIVE.check(t_end, &Field::new("t_end"))
}

/// Checks a study's number of sample times.
pub fn check_samples(samples: u64) -> Result<u64, CoreError> {
    if (1..=MAX_SAMPLES).contains(&samples) {
        Ok(samples)
    } else {
        Err(CoreError::Count {
            field: Field::new("samples"),
            got: samples,
            min: 1,
            max: MAX_SAMPLES,
            what: "sample times",
        })
    }
}

/// How many steps of `h` make up `span`, if a whole number of them does (within round-off).
pub fn whole_steps(span: f64, h: f64) -> Option<u64> {
    let n = span / h;
    let whole = n.round();
    ((n - whole).abs() <= 1e-9 * n.max(1.0) && whole >= 1.0).then_some(whole as u64)
}

/// A setting as requested.
#[derive(Clone, Copy, Debug)]
pub enum Setting {
    /// A fixed step size.
    Step(f64),
    /// A tolerance of the adaptive reference.
    Tolerance(f64),
}

/// Prepares one setting: `method` at step `h` on `template` (system, parameters, chart, initial
/// state, t_end, and the fields naming them) — for a tolerance, the adaptive reference in
/// segments of t_end/samples — sampled at the `samples` times of the study. Every step size must
/// divide t_end/samples, so that the samples are step endpoints. `at` names the setting
/// (`runs[1].h[2]`).
pub fn prepare_setting(
    template: &SimulationSpec,
    method: &MethodAt,
    setting: Setting,
    samples: u64,
    at: &Field,
    limits: &Limits,
) -> Result<Simulation, CoreError> {
    let segment = template.t_end / samples as f64;
    let (h, method_value) = match setting {
        Setting::Step(h) => {
            Range::POSITIVE.check(h, at)?;
            if whole_steps(segment, h).is_none() {
                return Err(CoreError::NotADivisor {
                    field: at.clone(),
                    h,
                    span: segment,
                    span_name: "t_end/samples",
                    purpose: "so that the samples are step endpoints",
                    show_ratio: false,
                });
            }
            (h, method.method)
        }
        Setting::Tolerance(t) => {
            let tolerance = TOLERANCE_RANGE.check(t, at)?;
            (segment, Method::Reference { tolerance })
        }
    };
    let steps = (template.t_end / h).round().max(1.0) as u64;
    let spec = SimulationSpec {
        methods: vec![MethodAt {
            method: method_value,
            field: method.field.clone(),
        }],
        h,
        every: Some((steps / samples).max(1)),
        fields: InputFields {
            h: at.clone(),
            steps: at.clone(),
            ..template.fields.clone()
        },
        ..template.clone()
    };
    Simulation::prepare(&spec, limits)
}

/// The reference run of a study whose first setting is `first`: none where the system has an
/// exact solution; otherwise `spec` (one step size or tolerance) or by default the adaptive
/// DOP853 at tolerance [`REFERENCE_TOLERANCE`], from `template` in the system's first (Cartesian)
/// chart, sampled at the study's sample times. A `spec` given where the exact solution serves
/// instead is checked all the same: a wrong one is refused, not silently ignored.
pub fn prepare_reference(
    first: &Simulation,
    template: &SimulationSpec,
    spec: Option<&RunSpec>,
    samples: u64,
    limits: &Limits,
) -> Result<Option<Simulation>, CoreError> {
    let exact = first.exact_final_state().is_some();
    if exact && spec.is_none() {
        return Ok(None);
    }
    let field = Field::new("reference");
    let default = RunSpec {
        method: MethodAt {
            method: Method::new(MethodId::Reference),
            field: field.key("method"),
        },
        h: Vec::new(),
        tolerance: vec![REFERENCE_TOLERANCE],
        field: field.clone(),
    };
    let spec = spec.unwrap_or(&default);
    let (setting, at) = match (spec.h.first(), spec.tolerance.first()) {
        (Some(&h), None) => (Setting::Step(h), field.key("h")),
        (None, Some(&t)) => (Setting::Tolerance(t), field.key("tolerance")),
        (None, None) => {
            return Err(CoreError::Missing {
                field: field.key("h"),
                what: "the reference's step size (or tolerance)",
            })
        }
        (Some(_), Some(_)) => {
            return Err(CoreError::Either {
                field,
                first: "`h`",
                second: "`tolerance`",
            })
        }
    };
    let template = SimulationSpec {
        chart: None,
        initial_cartesian: false,
        fields: InputFields {
            chart: field.clone(),
            ..template.fields.clone()
        },
        ..template.clone()
    };
    let reference = prepare_setting(&template, &spec.method, setting, samples, &at, limits)?;
    Ok((!exact).then_some(reference))
}

/// A validated study, ready to run.
#[derive(Clone, Debug)]
pub struct StudyJob {
    /// The spec it was prepared from (what workers and parts carry).
    pub spec: StudySpec,
    /// One prepared simulation per setting, with the index of its run (or series).
    pub settings: Vec<(usize, Simulation)>,
    /// The reference run, where the system has no exact solution.
    pub reference: Option<Simulation>,
    /// The system as the document reports it.
    pub system: SystemSummary,
    /// Final time.
    pub t_end: f64,
    /// Sample times.
    pub samples: u64,
}

impl StudyJob {
    /// The job of `settings` (at least one), refused at `field` when they take more than
    /// [`MAX_STUDY_STEPS`] steps in all.
    pub fn new(
        spec: StudySpec,
        settings: Vec<(usize, Simulation)>,
        reference: Option<Simulation>,
        system: SystemSummary,
        t_end: f64,
        samples: u64,
        field: &str,
    ) -> Result<Self, CoreError> {
        let total_steps = settings
            .iter()
            .fold(0u64, |n, (_, sim)| n.saturating_add(sim.schedule.steps));
        if total_steps > MAX_STUDY_STEPS {
            return Err(CoreError::TooManySteps {
                field: Field::new(field),
                steps: total_steps,
                limit: MAX_STUDY_STEPS,
                scope: StepScope::PerStudy,
            });
        }
        Ok(StudyJob {
            spec,
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

    /// Runs the reference (or takes the exact solution). A reference run stopped by the time limit
    /// is a truth all the same: the settings after it start past the deadline and stop at once,
    /// so the study answers with every setting `time_limit` rather than failing.
    pub fn truth(&self, budget: Budget<'_>) -> Result<Truth, CoreError> {
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
        let outcome = sim
            .run_method(0, None, budget, &mut sink)
            .map_err(|e| match e {
                CoreError::Step {
                    step, t, source, ..
                } => CoreError::Step {
                    field: None,
                    run: Some("the reference run failed".into()),
                    step,
                    t,
                    source,
                },
                other => other,
            })?;
        let stopped_early = match outcome.stop {
            RunEnd::Finished => false,
            RunEnd::TimeLimit { .. } | RunEnd::Event { .. } => true,
            RunEnd::Cancelled { .. } => {
                return Err(CoreError::Cancelled {
                    what: "study",
                    shutdown: false,
                })
            }
            RunEnd::Diverged { .. } | RunEnd::Indicator(_) => {
                return Err(CoreError::ReferenceUnfinished {
                    field: Field::new("reference"),
                    stop: stop_name(&outcome.stop).into(),
                })
            }
        };
        let method = &sim.methods[0];
        let mut description = match method {
            Method::Reference { tolerance } => {
                format!("adaptive DOP853 reference at tolerance {tolerance:e}")
            }
            _ => format!("{} at h = {}", method.label(), sim.schedule.h),
        };
        if stopped_early {
            description.push_str(", stopped at the time limit");
        }
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
pub struct Truth {
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
    pub fn state_error(&self, sim: &Simulation, last: &(Vec<f64>, Vec<f64>)) -> Option<f64> {
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

/// The lines of a study's progress stream.
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

/// Declares a study's progress line type, `$name`, carrying `$point` per setting and `$document`
/// at the end, and implements [`ProgressLine`] for it.
macro_rules! progress_lines {
    ($(#[$meta:meta])* $name:ident, $point:ty, $document:ty) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq, serde::Serialize)]
        #[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
                error: $crate::error::ErrorDetail,
            },
            /// The last line of a complete stream.
            End,
        }

        impl $crate::studies::settings::ProgressLine for $name {
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
            fn error(error: $crate::error::ErrorDetail) -> Self {
                Self::Error { error }
            }
            fn end() -> Self {
                Self::End
            }
        }
    };
}
pub(crate) use progress_lines;

/// How a study measures one setting: given the setting's run (or series) index, its simulation,
/// the truth and the budget, its point.
pub type Measurer<P> =
    fn(&StudyJob, usize, &Simulation, &Truth, Budget<'_>) -> Result<P, CoreError>;

/// A settings study as the engine runs it: one cell per setting, measured against the truth.
pub struct SettingsStudy<'a, P> {
    job: &'a StudyJob,
    truth: Truth,
    measure: Measurer<P>,
    order: Order,
}

impl<'a, P> SettingsStudy<'a, P> {
    /// The settings of `job`, each measured by `measure` against `truth`, in `order`.
    pub fn new(job: &'a StudyJob, truth: Truth, measure: Measurer<P>, order: Order) -> Self {
        SettingsStudy {
            job,
            truth,
            measure,
            order,
        }
    }

    /// One setting's point.
    fn point(&self, setting: usize, budget: Budget<'_>) -> Result<P, CoreError> {
        let (run, sim) = &self.job.settings[setting];
        (self.measure)(self.job, *run, sim, &self.truth, budget)
    }
}

impl<P: Clone + Send + Sync + Serialize + DeserializeOwned> Study for SettingsStudy<'_, P> {
    type Cell = P;

    fn name(&self) -> &'static str {
        "study"
    }

    fn cells(&self) -> usize {
        self.job.settings.len()
    }

    fn order(&self) -> Order {
        self.order
    }

    /// A setting always has its point: one stopped by the time limit says so itself.
    fn run_cells(
        &self,
        cells: Cells<usize>,
        budget: Budget<'_>,
    ) -> Result<Vec<Option<P>>, CoreError> {
        cells
            .map(|cell| self.point(cell, budget).map(Some))
            .collect()
    }

    fn spec(&self) -> Option<StudySpec> {
        Some(self.job.spec.clone())
    }

    fn steps(&self) -> u64 {
        self.job
            .settings
            .iter()
            .fold(0u64, |n, (_, sim)| n.saturating_add(sim.schedule.steps))
    }
}

/// Runs a study on `executor`: the reference (or the exact solution) here, then every setting
/// of the study `make` builds on the truth. Reports each line to `emit`: the reference, then
/// each setting's point as it comes. Returns the truth and the points in setting order. A
/// setting an executor could not finish before the deadline is measured here with the time
/// already up, so that it says `time_limit` as one stopped mid-run does.
pub fn run_settings<'a, L: ProgressLine, E: Executor>(
    job: &'a StudyJob,
    executor: &E,
    budget: Budget<'_>,
    emit: &(dyn Fn(L) -> bool + Sync),
    make: impl FnOnce(Truth) -> SettingsStudy<'a, L::Point>,
) -> Result<(Truth, Vec<L::Point>), CoreError>
where
    L::Point: Send + Sync + Serialize + DeserializeOwned,
{
    let total = job.settings.len();
    let truth = job.truth(budget)?;
    emit(L::reference(truth.description.clone(), truth.ms, total));
    let study = make(truth);
    // Settings finish in any order on several cores; counting and emitting under one lock keeps
    // the stream's `done` rising one by one.
    let done = std::sync::Mutex::new(0usize);
    let finished = engine::run(&study, executor, budget, &|_, point| {
        if let Some(point) = point {
            let mut done = done
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            *done += 1;
            emit(L::point(*done, total, point.clone()));
        }
    })?;
    let expired = Budget {
        cancel: None,
        deadline: Some(Instant::now()),
    };
    let points = finished
        .cells
        .into_iter()
        .enumerate()
        .map(|(setting, point)| match point {
            Some(point) => Ok(point),
            None => study.point(setting, expired),
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok((study.truth, points))
}

//! The JSON document of a simulation: the resolved system and one run per method with its
//! sample columns, how it stopped and its statistics. [`simulate`] computes it, running the
//! methods of a request in parallel on the same system and initial state.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use serde::Serialize;
use serde_json::{Map, Value};
use utoipa::ToSchema;

use super::error::{codes, ErrorDetail};
use crate::core::error::CoreError;
use crate::core::run::{Budget, RunStats, StopReason};
use crate::core::simulate::{Sample, SampleSink, Simulation, Trajectory};

/// The system a simulation ran on, with every parameter resolved.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct SystemSummary {
    /// System id.
    #[schema(example = "pendulum")]
    pub id: String,
    /// All parameters, defaults filled in (`epsilon` given as `gamma` = ε/2).
    #[schema(value_type = Object, example = json!({"gamma": 0.005}))]
    pub params: Map<String, Value>,
    /// The coordinate chart the runs are in.
    #[schema(example = "cartesian")]
    pub chart: String,
    /// Initial positions (in the chart's coordinates).
    pub q0: Vec<f64>,
    /// Initial momenta.
    pub p0: Vec<f64>,
}

/// The sampling of a simulation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
pub struct ScheduleSummary {
    /// Step size.
    pub h: f64,
    /// Steps per method: ceil(t_end/h).
    pub steps: u64,
    /// Sample every this many steps (and at the last step).
    pub every: u64,
    /// Time of the last step, steps·h.
    pub t_end: f64,
    /// Samples of a run that finishes.
    pub samples_per_method: u64,
}

/// Sample columns: one entry per sample in every column.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
pub struct Columns {
    /// Sample times t_k = k·h.
    pub t: Vec<f64>,
    /// Positions, one list per sample.
    pub q: Vec<Vec<f64>>,
    /// Momenta, one list per sample.
    pub p: Vec<Vec<f64>>,
    /// Cartesian positions per sample (for a first-order ODE: the original variable), present
    /// when the chart is not Cartesian: the chart's point transformation of `q`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cartesian_q: Option<Vec<Vec<f64>>>,
    /// Cartesian momenta per sample (the cotangent lift of `p`), with `cartesian_q`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cartesian_p: Option<Vec<Vec<f64>>>,
    /// Total energy H per sample.
    pub energy: Vec<f64>,
    /// H − H_exact per sample (exact solution, or the reference when asked); absent when
    /// unknown.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_error: Option<Vec<f64>>,
    /// The system's invariants by name, one value per sample.
    pub invariants: BTreeMap<String, Vec<f64>>,
    /// |det ∂Φ/∂z − e^{−2γh·n}| of the step ending at each sample (absent unless asked for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jacobian_defect: Option<Vec<f64>>,
}

impl Columns {
    /// Empty columns with an empty column for each invariant name.
    pub fn with_invariants<S: AsRef<str>>(names: &[S]) -> Self {
        Columns {
            invariants: names
                .iter()
                .map(|n| (n.as_ref().to_string(), Vec::new()))
                .collect(),
            ..Columns::default()
        }
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether no sample is held.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Appends the samples of `more` (the next samples of the same run) after these.
    pub fn extend(&mut self, more: Columns) {
        fn append(to: &mut Option<Vec<f64>>, more: Option<Vec<f64>>) {
            if let Some(more) = more {
                to.get_or_insert_with(Vec::new).extend(more);
            }
        }
        self.t.extend(more.t);
        self.q.extend(more.q);
        self.p.extend(more.p);
        if let Some(more) = more.cartesian_q {
            self.cartesian_q.get_or_insert_with(Vec::new).extend(more);
        }
        if let Some(more) = more.cartesian_p {
            self.cartesian_p.get_or_insert_with(Vec::new).extend(more);
        }
        self.energy.extend(more.energy);
        append(&mut self.energy_error, more.energy_error);
        for (name, values) in more.invariants {
            self.invariants.entry(name).or_default().extend(values);
        }
        append(&mut self.jacobian_defect, more.jacobian_defect);
    }
}

/// Collects samples into [`Columns`].
#[derive(Debug)]
pub struct ColumnSink {
    names: &'static [&'static str],
    columns: Columns,
    invariants: Vec<Vec<f64>>,
}

impl ColumnSink {
    /// An empty sink for a system with these invariant names.
    pub fn new(names: &'static [&'static str]) -> Self {
        Self {
            names,
            columns: Columns::default(),
            invariants: vec![Vec::new(); names.len()],
        }
    }

    /// Samples collected so far.
    pub fn len(&self) -> usize {
        self.columns.t.len()
    }

    /// Whether no sample was collected.
    pub fn is_empty(&self) -> bool {
        self.columns.t.is_empty()
    }

    /// The columns collected so far; the sink starts over empty.
    pub fn take(&mut self) -> Columns {
        let mut columns = std::mem::take(&mut self.columns);
        columns.invariants = self
            .names
            .iter()
            .zip(self.invariants.iter_mut())
            .map(|(name, column)| (name.to_string(), std::mem::take(column)))
            .collect();
        columns
    }
}

impl SampleSink for ColumnSink {
    fn on_sample(&mut self, s: &Sample<'_>) {
        let c = &mut self.columns;
        c.t.push(s.t);
        c.q.push(s.q.to_vec());
        c.p.push(s.p.to_vec());
        if let Some((x, px)) = s.cartesian {
            c.cartesian_q.get_or_insert_with(Vec::new).push(x.to_vec());
            c.cartesian_p.get_or_insert_with(Vec::new).push(px.to_vec());
        }
        c.energy.push(s.energy);
        if let Some(e) = s.energy_error {
            c.energy_error.get_or_insert_with(Vec::new).push(e);
        }
        for (column, &v) in self.invariants.iter_mut().zip(s.invariants) {
            column.push(v);
        }
        if let Some(d) = s.jacobian_defect {
            c.jacobian_defect.get_or_insert_with(Vec::new).push(d);
        }
    }
}

/// Why a run stopped.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(tag = "reason", rename_all = "snake_case")]
pub enum Stop {
    /// All steps were taken.
    Finished,
    /// The state became non-finite at this step; the samples end before it.
    Diverged {
        /// The first step whose result is non-finite.
        step: u64,
        /// Its time.
        t: f64,
    },
    /// The run was cancelled (the client went away, or the server is shutting down).
    Cancelled {
        /// Steps completed.
        step: u64,
    },
    /// The request's time limit passed.
    TimeLimit {
        /// Steps completed.
        step: u64,
    },
    /// A step failed (for example Newton's method did not converge); the samples end before it.
    Failed {
        /// The step that failed, counted from 1.
        step: u64,
        /// The time at its start.
        t: f64,
        /// What went wrong.
        message: String,
    },
}

impl From<StopReason> for Stop {
    fn from(s: StopReason) -> Self {
        match s {
            StopReason::Finished => Stop::Finished,
            StopReason::Diverged { step, t } => Stop::Diverged { step, t },
            StopReason::Cancelled { step } => Stop::Cancelled { step },
            StopReason::TimeLimit { step } => Stop::TimeLimit { step },
        }
    }
}

impl Stop {
    /// Where the run diverged, if it did.
    pub fn diverged_at(&self) -> Option<DivergedAt> {
        match *self {
            Stop::Diverged { step, t } => Some(DivergedAt { step, t }),
            _ => None,
        }
    }
}

/// The first step whose state is non-finite.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
pub struct DivergedAt {
    /// Step index.
    pub step: u64,
    /// Its time.
    pub t: f64,
}

/// One point of the dissipation drift d = ln(max |q| over a half-oscillation) + γ t* (paper 003
/// eq. 4.4): constant for the exact flow, so a trend shows a wrong dissipation rate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
pub struct DriftPoint {
    /// Time t* of the amplitude peak.
    pub t: f64,
    /// d(t*).
    pub d: f64,
}

/// The dissipation drift of a run from its sample times and positions (1-DOF systems with
/// conformal damping; `None` for others).
pub fn dissipation_drift(sim: &Simulation, t: &[f64], q: &[Vec<f64>]) -> Option<Vec<DriftPoint>> {
    if sim.q0.len() != 1 {
        return None;
    }
    let run = Trajectory {
        t: t.to_vec(),
        q: q.to_vec(),
        ..Trajectory::default()
    };
    sim.dissipation_drift(&run).map(|points| {
        points
            .iter()
            .map(|p| DriftPoint { t: p.t, d: p.d })
            .collect()
    })
}

/// Run statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, ToSchema)]
pub struct Stats {
    /// Steps taken.
    pub steps: u64,
    /// Gradient evaluations (∇V or ∂H/∂q).
    pub force_evaluations: u64,
    /// Wall time of the integration loop in milliseconds.
    pub wall_time_ms: f64,
}

impl From<RunStats> for Stats {
    fn from(s: RunStats) -> Self {
        Stats {
            steps: s.steps,
            force_evaluations: s.force_evaluations,
            wall_time_ms: s.wall_time_ms,
        }
    }
}

/// One method's run.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct RunDocument {
    /// The method's label, e.g. `modin_3s` or `modin_rks(rk4)`.
    #[schema(example = "modin_3s")]
    pub method: String,
    /// The samples.
    #[serde(flatten)]
    pub columns: Columns,
    /// The dissipation drift (1-DOF systems with conformal damping only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dissipation_drift: Option<Vec<DriftPoint>>,
    /// Where the run diverged (null unless it did).
    pub diverged_at: Option<DivergedAt>,
    /// Why it stopped.
    pub stop: Stop,
    /// Statistics.
    pub stats: Stats,
}

/// The answer to a simulation request.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct SimulationDocument {
    /// The system, parameters resolved.
    pub system: SystemSummary,
    /// The sampling.
    pub schedule: ScheduleSummary,
    /// Names of the invariants in each run's `invariants`.
    pub invariants: Vec<String>,
    /// One run per method, in the order asked.
    pub runs: Vec<RunDocument>,
}

impl SystemSummary {
    /// The summary of a prepared simulation.
    pub fn of(sim: &Simulation) -> Self {
        let mut params = Map::new();
        for (name, &v) in &sim.params.numbers {
            params.insert(name.clone(), Value::from(v));
        }
        if let Some(masses) = &sim.params.masses {
            params.insert("masses".into(), Value::from(masses.clone()));
        }
        if let Some(potential) = &sim.params.potential {
            params.insert("potential".into(), Value::from(potential.clone()));
        }
        SystemSummary {
            id: sim.system_id.clone(),
            params,
            chart: sim.chart.clone(),
            q0: sim.q0.clone(),
            p0: sim.p0.clone(),
        }
    }
}

impl ScheduleSummary {
    /// The schedule of a prepared simulation.
    pub fn of(sim: &Simulation) -> Self {
        let s = sim.schedule;
        ScheduleSummary {
            h: s.h,
            steps: s.steps,
            every: s.every,
            t_end: s.steps as f64 * s.h,
            samples_per_method: s.samples(),
        }
    }
}

/// The stop of a run that ended in an error.
pub(crate) fn failed(error: CoreError) -> Stop {
    match error {
        CoreError::Step { step, t, source } => Stop::Failed {
            step,
            t,
            message: source.to_string(),
        },
        other => Stop::Failed {
            step: 0,
            t: 0.0,
            message: other.to_string(),
        },
    }
}

/// Runs method `index` of `sim` into a [`RunDocument`]; a failing step ends the run with
/// [`Stop::Failed`] and keeps the samples before it.
pub fn run_document(
    sim: &Simulation,
    index: usize,
    reference: Option<&[f64]>,
    budget: Budget<'_>,
) -> RunDocument {
    let mut sink = ColumnSink::new(sim.invariant_names());
    let started = Instant::now();
    let (stop, stats) = match sim.run_method(index, reference, budget, &mut sink) {
        Ok(outcome) => (Stop::from(outcome.stop), Stats::from(outcome.stats)),
        Err(e) => {
            tracing::warn!(method = %sim.methods[index].label(), error = %e, "run failed");
            let steps = match &e {
                CoreError::Step { step, .. } => step.saturating_sub(1),
                _ => 0,
            };
            let stats = Stats {
                steps,
                force_evaluations: 0,
                wall_time_ms: started.elapsed().as_secs_f64() * 1e3,
            };
            (failed(e), stats)
        }
    };
    let columns = sink.take();
    RunDocument {
        method: sim.methods[index].label(),
        dissipation_drift: dissipation_drift(sim, &columns.t, &columns.q),
        columns,
        diverged_at: stop.diverged_at(),
        stop,
        stats,
    }
}

/// The reference energies of `sim` (when it compares to the reference), with errors as the
/// interfaces report them.
pub fn reference_energies(
    sim: &Simulation,
    budget: Budget<'_>,
) -> Result<Option<Vec<f64>>, ErrorDetail> {
    sim.reference_energies(budget).map_err(|e| {
        if budget.deadline.is_some_and(|d| Instant::now() >= d) {
            ErrorDetail::at(
                codes::TIMEOUT,
                "compare_to_reference",
                "the reference run did not finish within the time limit; ask for fewer steps",
            )
        } else if let CoreError::Step { .. } = e {
            ErrorDetail::at(
                codes::STEP_FAILED,
                "compare_to_reference",
                format!("reference run: {e}"),
            )
        } else {
            ErrorDetail {
                code: codes::INVALID_VALUE.to_string(),
                message: e.to_string(),
                field: e.field().map(str::to_string),
            }
        }
    })
}

/// Runs `job(i)` for `i` in `0..count` on up to `workers` threads (the caller's thread alone when
/// `workers` ≤ 1) and returns the results in index order. A panic in a job resumes in the
/// caller.
pub fn for_each_method<T: Send>(
    count: usize,
    workers: usize,
    job: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    let workers = workers.clamp(1, count.max(1));
    if workers == 1 {
        return (0..count).map(job).collect();
    }
    let next = AtomicUsize::new(0);
    let span = tracing::Span::current();
    let mut results: Vec<(usize, T)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                scope.spawn(|| {
                    let _entered = span.enter();
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= count {
                            break done;
                        }
                        done.push((i, job(i)));
                    }
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| {
                h.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            })
            .collect()
    });
    results.sort_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, r)| r).collect()
}

/// Runs every method of `sim` (on up to `workers` threads) into a [`SimulationDocument`].
pub fn simulate(
    sim: &Simulation,
    workers: usize,
    budget: Budget<'_>,
) -> Result<SimulationDocument, ErrorDetail> {
    let reference = reference_energies(sim, budget)?;
    let runs = for_each_method(sim.methods.len(), workers, |i| {
        run_document(sim, i, reference.as_deref(), budget)
    });
    Ok(SimulationDocument {
        system: SystemSummary::of(sim),
        schedule: ScheduleSummary::of(sim),
        invariants: sim
            .invariant_names()
            .iter()
            .map(|s| s.to_string())
            .collect(),
        runs,
    })
}

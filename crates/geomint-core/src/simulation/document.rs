//! The results of a simulation: per method the sample columns, how the run stopped and its
//! statistics ([`RunDocument`]), with the resolved system and the sampling
//! ([`SimulationDocument`]). [`ColumnSink`] collects a run's samples into [`Columns`];
//! [`DocumentCollector`](super::stream::DocumentCollector) assembles a document from a run's
//! stream, which is how every document is made.

use std::collections::BTreeMap;

use serde::Serialize;

use super::crossings::{CrossingColumns, SurfaceInfo};
use super::run::{Sample, SampleSink};
use super::spec::EnergyReference;
use super::spec::Simulation;
use crate::chaos::{IndicatorValues, ThresholdCrossing};
use crate::diagnostics::DriftPoint;
use crate::error::CoreError;
use crate::run::{RunEnd, RunStats};
use crate::sections::SectionSummary;
#[cfg(feature = "openapi")]
use crate::systems::SystemId;
use crate::systems::{ParamValues, World};

/// The system a simulation ran on, with every parameter resolved.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SystemSummary {
    /// System id.
    #[cfg_attr(feature = "openapi", schema(value_type = SystemId, example = "pendulum"))]
    pub id: String,
    /// All parameters, defaults filled in (`epsilon` given as `gamma` = ε/2).
    #[cfg_attr(feature = "openapi", schema(example = json!({"gamma": 0.005})))]
    pub params: ParamValues,
    /// The coordinate chart the runs are in.
    #[cfg_attr(feature = "openapi", schema(example = "cartesian"))]
    pub chart: String,
    /// Initial positions (in the chart's coordinates).
    pub q0: Vec<f64>,
    /// Initial momenta.
    pub p0: Vec<f64>,
    /// How the system appears in space (for the recordings' 3-D view; not serialized).
    #[serde(skip)]
    pub world: World,
}

/// The sampling of a simulation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
    /// The bodies' coordinates per sample, body after body, 2 or 3 each as the definition's
    /// `positions` write them (user-defined systems with `positions` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bodies: Option<Vec<Vec<f64>>>,
    /// The finite-time Lyapunov spectrum per sample, largest first (with the indicator
    /// `lyapunov`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lyapunov: Option<Vec<Vec<f64>>>,
    /// MEGNO Y(t) per sample (with `megno`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub megno: Option<Vec<f64>>,
    /// MEGNO's running mean ⟨Y⟩(t) per sample (with `megno`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub megno_mean: Option<Vec<f64>>,
    /// The fast Lyapunov indicator per sample (with `fli`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fli: Option<Vec<f64>>,
    /// SALI per sample (with `sali`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sali: Option<Vec<f64>>,
    /// GALI_k per sample, k the deviation vectors (with `gali`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gali: Option<Vec<f64>>,
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
        if let Some(more) = more.bodies {
            self.bodies.get_or_insert_with(Vec::new).extend(more);
        }
        if let Some(more) = more.lyapunov {
            self.lyapunov.get_or_insert_with(Vec::new).extend(more);
        }
        append(&mut self.megno, more.megno);
        append(&mut self.megno_mean, more.megno_mean);
        append(&mut self.fli, more.fli);
        append(&mut self.sali, more.sali);
        append(&mut self.gali, more.gali);
    }
}

/// Collects samples into [`Columns`].
#[derive(Debug)]
pub struct ColumnSink {
    names: Vec<String>,
    columns: Columns,
    invariants: Vec<Vec<f64>>,
}

impl ColumnSink {
    /// An empty sink for a system with these invariant names.
    pub fn new(names: Vec<String>) -> Self {
        Self {
            invariants: vec![Vec::new(); names.len()],
            names,
            columns: Columns::default(),
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
        if let Some(b) = s.bodies {
            c.bodies.get_or_insert_with(Vec::new).push(b.to_vec());
        }
        if let Some(v) = s.indicators {
            let push = |column: &mut Option<Vec<f64>>, value: Option<f64>| {
                if let Some(x) = value {
                    column.get_or_insert_with(Vec::new).push(x);
                }
            };
            if let Some(l) = &v.lyapunov {
                c.lyapunov.get_or_insert_with(Vec::new).push(l.clone());
            }
            push(&mut c.megno, v.megno);
            push(&mut c.megno_mean, v.megno_mean);
            push(&mut c.fli, v.fli);
            push(&mut c.sali, v.sali);
            push(&mut c.gali, v.gali);
        }
    }
}

/// Why a run stopped.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
    /// The run's event ended it: the `stop_when` surface's `count`-th crossing, at `t`; the
    /// last sample is the step past it.
    Event {
        /// The step after which the run ended.
        step: u64,
        /// The time of the crossing.
        t: f64,
    },
    /// A chaos indicator reached its threshold (`stop_when`); the last sample is at its step.
    Indicator(ThresholdCrossing),
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

impl From<RunEnd> for Stop {
    fn from(s: RunEnd) -> Self {
        match s {
            RunEnd::Finished => Stop::Finished,
            RunEnd::Diverged { step, t } => Stop::Diverged { step, t },
            RunEnd::Cancelled { step } => Stop::Cancelled { step },
            RunEnd::TimeLimit { step } => Stop::TimeLimit { step },
            RunEnd::Event { step, t } => Stop::Event { step, t },
            RunEnd::Indicator(at) => Stop::Indicator(at),
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
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DivergedAt {
    /// Step index.
    pub step: u64,
    /// Its time.
    pub t: f64,
}

impl Stop {
    /// The stop of a run that ended in an error at a step (its samples end before it).
    pub fn failed(error: &CoreError) -> Stop {
        match error {
            CoreError::Step {
                step, t, source, ..
            } => Stop::Failed {
                step: *step,
                t: *t,
                message: source.to_string(),
            },
            other => Stop::Failed {
                step: 0,
                t: 0.0,
                message: other.to_string(),
            },
        }
    }

    /// Steps completed before a failure.
    pub fn failed_steps(error: &CoreError) -> u64 {
        match error {
            CoreError::Step { step, .. } => step.saturating_sub(1),
            _ => 0,
        }
    }
}

/// How one method's run ended: what the document and the stream's summary both report.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RunOutcome {
    /// The dissipation drift (1-DOF systems with conformal damping only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dissipation_drift: Option<Vec<DriftPoint>>,
    /// The chaos indicators at the run's last sample, under the names of the sample columns
    /// (when asked for).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub indicators: Option<IndicatorValues>,
    /// Where the run diverged (null unless it did).
    pub diverged_at: Option<DivergedAt>,
    /// Why it stopped.
    pub stop: Stop,
    /// Statistics.
    pub stats: RunStats,
    /// How the section went (runs with a `section` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub section_summary: Option<SectionSummary>,
}

/// One method's run.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RunDocument {
    /// The method's label, e.g. `modin_3s` or `modin_rks(rk4)`.
    #[cfg_attr(feature = "openapi", schema(example = "modin_3s"))]
    pub method: String,
    /// The samples.
    #[serde(flatten)]
    pub columns: Columns,
    /// How it ended.
    #[serde(flatten)]
    pub outcome: RunOutcome,
    /// The section's points (runs with a `section` only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub section: Option<CrossingColumns>,
    /// The crossings of the `stop_when` surface, the last of which ended the run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub events: Option<CrossingColumns>,
}

/// The answer to a simulation request.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SimulationDocument {
    /// The system, parameters resolved.
    pub system: SystemSummary,
    /// What the runs' `energy_error` is measured against (see the stream's header).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_reference: Option<EnergyReference>,
    /// The sampling.
    pub schedule: ScheduleSummary,
    /// Names of the invariants in each run's `invariants`.
    pub invariants: Vec<String>,
    /// One run per method, in the order asked.
    pub runs: Vec<RunDocument>,
    /// The section, as the header announced it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub section: Option<SurfaceInfo>,
    /// The event, as the header announced it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop_when: Option<SurfaceInfo>,
}

impl SystemSummary {
    /// The summary of a prepared simulation.
    pub fn of(sim: &Simulation) -> Self {
        SystemSummary {
            id: sim.system_id().to_string(),
            params: sim.params.clone(),
            chart: sim.chart.id.to_string(),
            q0: sim.q0.clone(),
            p0: sim.p0.clone(),
            world: sim.world().clone(),
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

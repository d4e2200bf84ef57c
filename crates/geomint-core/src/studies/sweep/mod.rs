//! Sweeps: one system run with one or more methods in one or more charts over a grid of one or
//! two axes — a system parameter (γ, ε, a stiffness…), the step size, or a component of the
//! initial state — and per cell and run the metrics of [`metrics`]: energy errors (final,
//! largest, ℓ² of paper 001 eq. 50), invariant drift, time of divergence, final state, work.
//!
//! A sweep is a study of the engine ([`super::engine`]): one cell per grid point, its runs'
//! metrics the cell's result. A cell's result depends only on the spec and the cell, so the local
//! executor (all cores), the batch arrays (`--shard i/n` then `merge`) and the NATS workers all
//! give bit-identical documents. The energy-error map of Fig. 6 is a sweep
//! ([`super::energy_map`]); sweeps whose runs have a batched stepper run a group of cells at a time in
//! SIMD lanes (`sweep/lanes.rs`), with the same numbers.

pub mod axis;
pub mod document;
mod lanes;
pub mod metrics;
mod prepare;
mod surface;

use std::collections::BTreeMap;
use std::ops::Range as Cells;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

pub use axis::{Axis, Grid, Scale, Target};
pub use document::{AxisDocument, ChaosColumns, RunColumns, SweepDocument};
pub use metrics::{ChaosMetrics, EnergyReference, RunMetrics};

use crate::chaos::ChaosSpec;
use crate::error::{CoreError, ErrorDetail, Field};
use crate::run::{step_count, Budget};
use crate::sections::SectionSpec;
use crate::simulation::{
    EnergySurface, InitialCoordinates, Limits, MethodAt, Simulation, SimulationSpec, Watching,
};
use crate::studies::engine::{self, CellLine, Documented, Executor, Finished, Study};
use crate::studies::parts::{Part, ShardAt, Travelling};
use crate::studies::{StudyCompletion, StudySpec};
use crate::system::MechanicalSystem;
use crate::systems::{ParamValue, SystemInfo, SystemRef};
use crate::with_system;
use metrics::MetricsTally;

/// Most runs (methods × charts) per cell.
pub const MAX_RUNS: usize = 16;
/// Most steps over all cells and runs of one sweep.
pub const MAX_TOTAL_STEPS: u64 = 20_000_000_000;

/// A sweep as asked for, in core terms.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SweepSpec {
    /// The system.
    pub system: SystemRef,
    /// Parameters fixed for the whole sweep (an axis overrides its own).
    pub params: BTreeMap<String, ParamValue>,
    /// Charts, each with its field; `None` is the system's default chart.
    pub charts: Vec<(Option<String>, Field)>,
    /// The coordinates of `q0`/`p0` and of the initial-state axes (default: the chart's with one
    /// chart, Cartesian with several).
    pub initial_coordinates: Option<InitialCoordinates>,
    /// Initial positions (default: the system's).
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default: the system's).
    pub p0: Option<Vec<f64>>,
    /// The methods.
    pub methods: Vec<MethodAt>,
    /// Step size (unless an axis varies it).
    pub h: Option<f64>,
    /// Final time.
    pub t_end: f64,
    /// Sample every this many steps (default 1: every step, as eq. 50 sums).
    pub every: Option<u64>,
    /// What energy errors are measured against (default: the exact solution where the system
    /// has one, else H₀ if nothing is damped, else a reference run).
    pub energy_reference: Option<EnergyReference>,
    /// One or two axes.
    pub axes: Vec<Axis>,
    /// The chaos indicators each run reports (a chaos map), if any.
    pub chaos: Option<ChaosSpec>,
    /// The energy surface the initial states lie on, one momentum solved per cell, if any.
    pub energy_surface: Option<EnergySurface>,
    /// A Poincaré section each run collects (a grid of orbits as one document), if any.
    #[serde(default)]
    pub section: Option<SectionSpec>,
    /// The identity of the request (a digest of its canonical form): parts of a sweep carry it,
    /// and merging refuses parts of another.
    pub digest: String,
}

/// A method in a chart: one run per cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RunLabel {
    /// The method's label.
    pub method: String,
    /// The chart's id.
    pub chart: String,
}

/// A validated sweep, ready to run over any range of its cells.
#[derive(Clone, Debug)]
pub struct SweepJob {
    /// One simulation template per run (the axes are applied per cell).
    templates: Vec<SimulationSpec>,
    /// The runs, in the order of `templates`.
    pub runs: Vec<RunLabel>,
    /// The grid.
    pub grid: Grid,
    /// What energy errors are measured against.
    pub against: EnergyReference,
    /// The system's entry.
    pub info: Arc<SystemInfo>,
    /// Steps over all cells and runs.
    pub total_steps: u64,
    /// The request's identity.
    pub digest: String,
    limits: Limits,
    /// How the cells run a group at a time, when the sweep is one the lanes run.
    lanes: Option<lanes::LanePlan>,
    /// The spec it was prepared from (what workers and parts carry).
    spec: SweepSpec,
    /// The chaos indicators of every run.
    chaos: Option<ChaosSpec>,
    /// The energy surface of every cell's initial state.
    surface: Option<EnergySurface>,
    /// What every run watches: the section, if any.
    watching: Option<Watching>,
}

impl SweepJob {
    /// Whether the cells run a group at a time in SIMD lanes (energy maps and chaos maps: see
    /// `sweep/lanes.rs`); the numbers are those of the one-cell path either way.
    pub fn runs_in_lanes(&self) -> bool {
        self.lanes.is_some()
    }

    /// The same sweep run cell by cell, through the generic stepper and observer.
    pub fn cell_by_cell(self) -> Self {
        Self {
            lanes: None,
            ..self
        }
    }

    /// Names of the system's invariants.
    pub fn invariant_names(&self) -> Vec<String> {
        self.info.invariants.iter().map(|n| n.to_string()).collect()
    }

    /// The spec of run `run` at `cell`, on the energy surface when the sweep has one.
    fn cell_spec_on_surface(&self, run: usize, point: &[f64]) -> Result<SimulationSpec, CoreError> {
        let mut spec = self.cell_spec(run, point);
        if let Some(surface) = &self.surface {
            surface.apply(&mut spec, &self.info)?;
        }
        Ok(spec)
    }

    /// Run `run` at the grid point `point`, prepared: on the energy surface, with the
    /// indicators, against the reference run when the sweep measures against it.
    pub(crate) fn cell_simulation(
        &self,
        run: usize,
        point: &[f64],
    ) -> Result<Simulation, CoreError> {
        let spec = self.cell_spec_on_surface(run, point)?;
        let mut sim = self.with_extras(Simulation::prepare(&spec, &self.limits)?)?;
        sim.compare_to_reference = self.against == EnergyReference::Reference;
        Ok(sim)
    }

    /// The initial state of run `run` at the grid point `point`, on the energy surface, where
    /// the axes move only the initial state and `prepared` is the run prepared at another
    /// point: [`Self::cell_simulation`]'s `q0` and `p0`, or its error, without preparing the
    /// run again (see [`Simulation::start_of`]).
    pub(crate) fn cell_start(
        &self,
        run: usize,
        point: &[f64],
        prepared: &Simulation,
    ) -> Result<(Vec<f64>, Vec<f64>), CoreError> {
        prepared.start_of(&self.cell_spec_on_surface(run, point)?)
    }

    /// `sim` with what every run of the sweep adds: the indicators and the section.
    fn with_extras(&self, sim: Simulation) -> Result<Simulation, CoreError> {
        let sim = match &self.chaos {
            Some(chaos) => sim.with_chaos(chaos)?,
            None => sim,
        };
        match &self.watching {
            Some(watching) => sim.watching(watching),
            None => Ok(sim),
        }
    }

    /// The spec of run `run` at `cell`.
    fn cell_spec(&self, run: usize, point: &[f64]) -> SimulationSpec {
        let mut spec = self.templates[run].clone();
        let defaults = (self.info.q0.as_slice(), self.info.p0.as_slice());
        for (axis, &value) in self.grid.axes.iter().zip(point) {
            axis.apply(&mut spec, value, defaults);
        }
        spec
    }

    /// Prepares every run at the corners of the grid: an input the sweep cannot take at all (a
    /// parameter out of its range at one end of its axis, too many steps at the smallest h) is
    /// an error of the request, named at the axis end that causes it. Returns whether any corner
    /// has damping.
    fn check_corners(&self) -> Result<bool, CoreError> {
        let ends = |axis: &Axis| [(axis.min, "min"), (axis.max, "max")];
        let mut corners: Vec<Vec<(f64, Field)>> = vec![Vec::new()];
        for axis in &self.grid.axes {
            corners = corners
                .into_iter()
                .flat_map(|c| {
                    ends(axis).map(|(v, end)| {
                        let mut c = c.clone();
                        c.push((v, axis.field.key(end)));
                        c
                    })
                })
                .collect();
        }
        let mut damped = false;
        for run in 0..self.templates.len() {
            for corner in &corners {
                let point: Vec<f64> = corner.iter().map(|(v, _)| *v).collect();
                let mut spec = match self.cell_spec_on_surface(run, &point) {
                    Ok(spec) => spec,
                    // Checked over the whole grid by `check_surface`.
                    Err(CoreError::AboveEnergySurface { .. }) => continue,
                    Err(e) => return Err(e),
                };
                for (axis, (_, end)) in self.grid.axes.iter().zip(corner) {
                    if axis.target == Target::Step {
                        spec.fields.h = end.clone();
                        spec.fields.steps = end.clone();
                    }
                }
                match Simulation::prepare(&spec, &self.limits) {
                    Ok(sim) => {
                        damped |= with_system!(&sim.system, s => s.damping_rate()) != 0.0;
                        self.with_extras(sim)?;
                    }
                    Err(CoreError::OutsideChart { .. }) => {}
                    Err(e) => {
                        let blamed = e.field().map(Field::as_str).and_then(|f| {
                            self.grid
                                .axes
                                .iter()
                                .zip(corner)
                                .find(|(a, _)| a.target.name() == f)
                                .map(|(a, (_, end))| match e {
                                    // The axis names a parameter the system does not have.
                                    CoreError::UnknownParameter { .. } => a.field.key("name"),
                                    _ => end.clone(),
                                })
                        });
                        return Err(match blamed {
                            Some(end) => e.at(end),
                            None => e,
                        });
                    }
                }
            }
        }
        Ok(damped)
    }

    /// Steps over all cells and runs.
    fn count_steps(&self) -> u64 {
        let per_cell: u64 = match self.grid.axes.iter().position(|a| a.target == Target::Step) {
            None => step_count(self.templates[0].h, self.templates[0].t_end),
            Some(k) => {
                let axis = &self.grid.axes[k];
                let others: u64 = self.cells() as u64 / axis.n as u64;
                let over_h: u64 = axis
                    .values()
                    .iter()
                    .map(|&h| step_count(h, self.templates[0].t_end))
                    .sum();
                return over_h
                    .saturating_mul(others)
                    .saturating_mul(self.templates.len() as u64);
            }
        };
        per_cell
            .saturating_mul(self.cells() as u64)
            .saturating_mul(self.templates.len() as u64)
    }

    /// The runs of one cell; `None` when the budget stopped one.
    fn cell(&self, cell: usize, budget: Budget<'_>) -> Result<Option<Vec<RunMetrics>>, CoreError> {
        let point = self.grid.point(cell);
        let mut results = Vec::with_capacity(self.templates.len());
        for run in 0..self.templates.len() {
            let sim = match self.cell_simulation(run, &point) {
                Ok(sim) => sim,
                Err(e) => {
                    results.push(RunMetrics::failed(e.to_string()));
                    continue;
                }
            };
            let reference = match sim.reference_energies(budget) {
                Ok(r) => r,
                Err(CoreError::TimeLimit { .. } | CoreError::Cancelled { .. }) => return Ok(None),
                Err(e) => {
                    results.push(RunMetrics::failed(e.to_string()));
                    continue;
                }
            };
            let mut measure = MetricsTally::new(self.against);
            match sim.run_method(0, reference.as_deref(), budget, &mut measure) {
                Ok(outcome) if outcome.stop.by_budget() => return Ok(None),
                Ok(outcome) => results.push(measure.finish(&outcome)),
                Err(e) => results.push(RunMetrics::failed(e.to_string())),
            }
        }
        Ok(Some(results))
    }

    /// The document of the sweep from what its cells came to: cells the time limit stopped
    /// are marked unfinished, with `time_limit` as the document's stop.
    pub fn document_of(&self, finished: Finished<Vec<RunMetrics>>) -> SweepDocument {
        let unfinished_cells = finished.unfinished();
        let not_run = || {
            let metrics = RunMetrics::failed("not run: the sweep reached its time limit".into());
            vec![metrics; self.runs.len()]
        };
        let cells = finished
            .cells
            .into_iter()
            .map(|cell| cell.unwrap_or_else(not_run))
            .collect();
        let mut document = self.document(cells, finished.wall_ms);
        document.stop = finished.stop;
        document.unfinished_cells = unfinished_cells;
        document
    }

    /// The grid's axes as documents show them.
    pub fn axis_documents(&self) -> Vec<AxisDocument> {
        self.grid
            .axes
            .iter()
            .map(|a| AxisDocument {
                name: a.target.name(),
                min: a.min,
                max: a.max,
                n: a.n,
                scale: a.scale,
                values: a.values(),
            })
            .collect()
    }

    /// The document of the sweep from every cell's results, in cell order.
    pub fn document(&self, cells: Vec<Vec<RunMetrics>>, wall_ms: f64) -> SweepDocument {
        let names = self.invariant_names();
        let mut runs: Vec<RunColumns> = self
            .runs
            .iter()
            .map(|label| {
                let extras = (self.chaos.is_some(), self.watching.is_some());
                RunColumns::new(label.clone(), &names, cells.len(), extras)
            })
            .collect();
        let (mut steps, mut force_evaluations) = (0u64, 0u64);
        for cell in cells {
            for (columns, metrics) in runs.iter_mut().zip(cell) {
                steps += metrics.steps;
                force_evaluations += metrics.force_evaluations;
                columns.push(metrics, &names);
            }
        }
        SweepDocument {
            system: self.info.id.to_string(),
            axes: self.axis_documents(),
            cells: self.cells(),
            energy_reference: self.against,
            invariants: names,
            runs,
            steps,
            force_evaluations,
            digest: self.digest.clone(),
            wall_ms,
            stop: StudyCompletion::Finished,
            unfinished_cells: Vec::new(),
        }
    }
}

/// What a sweep's progress stream carries.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum SweepLine {
    /// Cells done so far (sent at most about 100 times per sweep).
    Progress {
        /// Cells done.
        done: usize,
        /// Cells in all.
        total: usize,
    },
    /// The sweep.
    Result(Box<SweepDocument>),
    /// A failure.
    Error {
        /// What went wrong.
        error: ErrorDetail,
    },
    /// The last line of a complete stream.
    End,
}

impl Study for SweepJob {
    type Cell = Vec<RunMetrics>;

    fn name(&self) -> &'static str {
        "sweep"
    }

    fn cells(&self) -> usize {
        self.grid.cells()
    }

    fn group(&self) -> usize {
        self.lanes.as_ref().map_or(1, lanes::LanePlan::group)
    }

    fn run_cells(
        &self,
        cells: Cells<usize>,
        budget: Budget<'_>,
    ) -> Result<Vec<Option<Vec<RunMetrics>>>, CoreError> {
        match &self.lanes {
            Some(plan) => Ok(self.lane_group(plan, cells, budget)),
            None => cells.map(|cell| self.cell(cell, budget)).collect(),
        }
    }

    fn fits(&self, cell: &Vec<RunMetrics>) -> bool {
        cell.len() == self.runs.len()
    }

    fn spec(&self) -> Option<StudySpec> {
        Some(StudySpec::Sweep(self.spec.clone()))
    }

    fn steps(&self) -> u64 {
        self.total_steps
    }
}

/// Runs the sweep on `executor`, reporting progress through `emit`.
pub fn run<E: Executor + ?Sized>(
    job: &SweepJob,
    executor: &E,
    budget: Budget<'_>,
    emit: &(dyn Fn(SweepLine) -> bool + Sync),
) -> Result<SweepDocument, CoreError> {
    engine::run_documented(job, executor, budget, emit)
}

impl Documented for SweepJob {
    type Line = SweepLine;

    fn document_of(&self, finished: Finished<Vec<RunMetrics>>) -> SweepDocument {
        SweepJob::document_of(self, finished)
    }
}

impl CellLine for SweepLine {
    type Document = SweepDocument;

    fn progress(done: usize, total: usize) -> Self {
        SweepLine::Progress { done, total }
    }

    fn result(document: SweepDocument) -> Self {
        SweepLine::Result(Box::new(document))
    }

    fn error(error: ErrorDetail) -> Self {
        SweepLine::Error { error }
    }

    fn end() -> Self {
        SweepLine::End
    }
}

/// A shard of it, as a worker or an array task runs it.
impl Travelling for SweepSpec {
    type Cell = Vec<RunMetrics>;

    fn run_shard(
        &self,
        at: &ShardAt<'_>,
        limits: &crate::simulation::Limits,
    ) -> Result<Part<Self::Cell>, CoreError> {
        at.run(&self.prepare(limits)?)
    }
}

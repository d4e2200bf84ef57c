//! Sweeps whose runs go a group at a time in SIMD lanes, with the numbers of the one-cell path
//! bit for bit:
//! - energy maps over the initial state ([`LaneKernel`]: symplectic Euler or its adjoint on the
//!   planar elastic pendulum, the energy error against H₀ at every step; paper 001 Fig. 6's map
//!   is one), whose metrics come out of the same [`MetricsTally`] the one-cell path fills sample by
//!   sample;
//! - chaos maps over the initial state and plain sweeps over any axes (runs, with or without
//!   indicators, that [`Simulation::runs_in_lanes`]; cells of different parameters one system
//!   per lane, cells of different steps in different groups), whose samples go to the same
//!   observer and [`MetricsTally`] as on the one-cell path.

use std::ops::Range as Cells;

use super::metrics::{EnergyReference, MetricsTally, RunMetrics};
use super::{SweepJob, Target};
use crate::run::Budget;
use crate::simulation::{SampleSink, Simulation};
use crate::studies::energy_map::lanes::{LaneKernel, Tally, TallyStart, PENDULUM_LANES};
use crate::studies::engine::Study;
use crate::system::{MechanicalSystem, State};
use crate::systems::AnySystem;
use crate::with_system;

/// How the lanes run a sweep.
#[derive(Clone, Debug)]
pub(super) enum LanePlan {
    /// An energy map's runs.
    Energy(EnergyLanes),
    /// Runs that [`Simulation::runs_in_lanes`] (a chaos map's, or a plain sweep's), each
    /// prepared per group of cells, `group` cells at a time.
    Runs {
        /// Cells per group: [`LANES`](crate::methods::lanes::tangent::LANES), times the step
        /// axis's points when that axis varies fastest, so that each group holds a lane's worth
        /// of cells of every step.
        group: usize,
    },
}

impl LanePlan {
    /// Cells run side by side.
    pub(super) fn group(&self) -> usize {
        match self {
            LanePlan::Energy(_) => PENDULUM_LANES,
            LanePlan::Runs { group } => *group,
        }
    }
}

/// How the lanes run an energy map: one entry per run (method × chart), and the common
/// schedule.
#[derive(Clone, Debug)]
pub(super) struct EnergyLanes {
    runs: Vec<EnergyLaneRun>,
    h: f64,
    steps: u64,
}

/// One run's system (in its chart, as the one-cell path builds it) and its kernel.
#[derive(Clone, Debug)]
struct EnergyLaneRun {
    system: AnySystem,
    kernel: LaneKernel,
}

impl SweepJob {
    /// The plan, if the runs are those of an energy map over q₀ and p₀, or runs the lanes take:
    /// a chaos map's over q₀ and p₀, a plain sweep's over any axes (cells that differ in their
    /// parameters run one system per lane, and a group of cells shares lanes where it shares the
    /// step).
    pub(super) fn lane_plan(&self) -> Option<LanePlan> {
        let initial_state_only = self
            .grid
            .axes
            .iter()
            .all(|a| matches!(a.target, Target::Q0(_) | Target::P0(_)));
        // The lanes watch no section.
        if self.watching.is_some() {
            return None;
        }
        if self.tracks_chaos() {
            return (initial_state_only && self.some_run_in_lanes()).then(|| self.runs_plan());
        }
        initial_state_only
            .then(|| self.energy_lanes())
            .flatten()
            .map(LanePlan::Energy)
            .or_else(|| self.some_run_in_lanes().then(|| self.runs_plan()))
    }

    /// The plan for runs in lanes (the grid's first axis varies fastest).
    fn runs_plan(&self) -> LanePlan {
        let lanes = crate::methods::lanes::tangent::LANES;
        let group = match self.grid.axes.first() {
            Some(axis) if axis.target == Target::Step => lanes * axis.n,
            _ => lanes,
        };
        LanePlan::Runs { group }
    }

    /// Whether some run goes side by side, judged at the grid's middle, first and last cells
    /// (the first that can be prepared); the others then run one by one within the same groups
    /// of cells.
    fn some_run_in_lanes(&self) -> bool {
        let cells = self.cells();
        let probes = [cells / 2, 0, cells.saturating_sub(1)];
        self.against != EnergyReference::Reference
            && (0..self.templates.len()).any(|k| {
                probes
                    .iter()
                    .find_map(|&c| self.cell_simulation(k, &self.grid.point(c)).ok())
                    .is_some_and(|sim| sim.runs_in_lanes())
            })
    }

    /// The energy map's plan, if every run has a kernel, is sampled at every step and measured
    /// against H₀.
    fn energy_lanes(&self) -> Option<EnergyLanes> {
        if self.against != EnergyReference::Initial {
            return None;
        }
        let mut runs = Vec::with_capacity(self.templates.len());
        let mut schedule = None;
        for (k, template) in self.templates.iter().enumerate() {
            if template.every != Some(1) {
                return None;
            }
            // The template, or the first and last cells where its own start is outside the chart.
            let cells = [0, self.cells().saturating_sub(1)];
            let sim = std::iter::once(template.clone())
                .chain(cells.map(|c| self.cell_spec(k, &self.grid.point(c))))
                .find_map(|spec| Simulation::prepare(&spec, &self.limits).ok())?;
            let kernel = LaneKernel::of(&sim.methods[0], &sim.system)?;
            let this = (sim.schedule.h, sim.schedule.steps);
            if schedule.is_some_and(|s| s != this) {
                return None;
            }
            schedule = Some(this);
            runs.push(EnergyLaneRun {
                system: sim.system,
                kernel,
            });
        }
        let (h, steps) = schedule?;
        Some(EnergyLanes { runs, h, steps })
    }

    /// The runs of `cells` (at most [`LanePlan::group`]), side by side. As on the one-cell path, a cell
    /// is `None` when the budget stopped one of its runs, and keeps its results when every run
    /// either failed to start or finished (a cell whose starts are all outside the chart keeps
    /// its failures after the time limit).
    pub(super) fn lane_group(
        &self,
        plan: &LanePlan,
        cells: Cells<usize>,
        budget: Budget<'_>,
    ) -> Vec<Option<Vec<RunMetrics>>> {
        match plan {
            LanePlan::Energy(plan) => self.energy_group(plan, cells, budget),
            LanePlan::Runs { .. } => self.runs_group(cells, budget),
        }
    }

    /// The runs of `cells`, side by side: a run that cannot be prepared is that run's result,
    /// as on the one-cell path.
    fn runs_group(&self, cells: Cells<usize>, budget: Budget<'_>) -> Vec<Option<Vec<RunMetrics>>> {
        let mut results: Vec<Option<Vec<RunMetrics>>> = vec![Some(Vec::new()); cells.len()];
        for k in 0..self.templates.len() {
            let mut sims = Vec::with_capacity(cells.len());
            let mut prepared = Vec::with_capacity(cells.len());
            for cell in cells.clone() {
                match self.cell_simulation(k, &self.grid.point(cell)) {
                    Ok(sim) => {
                        prepared.push(Ok(sims.len()));
                        sims.push(sim);
                    }
                    Err(e) => prepared.push(Err(RunMetrics::failed(e.to_string()))),
                }
            }
            let mut measures: Vec<MetricsTally> = sims
                .iter()
                .map(|_| MetricsTally::new(self.against))
                .collect();
            let mut sinks: Vec<&mut dyn SampleSink> = measures
                .iter_mut()
                .map(|m| m as &mut dyn SampleSink)
                .collect();
            let Some(outcomes) = Simulation::run_side_by_side(&sims, budget, &mut sinks) else {
                return vec![None; cells.len()];
            };
            let mut metrics = Vec::with_capacity(sims.len());
            for ((sim, measure), outcome) in sims.iter().zip(measures).zip(outcomes) {
                metrics.push(match outcome {
                    Ok(Some(outcome)) => measure.finish(&outcome),
                    // Given back by the lanes: on its own, from the start.
                    Ok(None) => {
                        let mut measure = MetricsTally::new(self.against);
                        match sim.run_method(0, None, budget, &mut measure) {
                            Ok(outcome) if outcome.stop.by_budget() => {
                                return vec![None; cells.len()]
                            }
                            Ok(outcome) => measure.finish(&outcome),
                            Err(e) => RunMetrics::failed(e.to_string()),
                        }
                    }
                    Err(e) => RunMetrics::failed(e.to_string()),
                });
            }
            // The runs in cell order, each taken out of `metrics` once.
            for (result, run) in results.iter_mut().zip(prepared) {
                let run = run.map_or_else(|failed| failed, |i| std::mem::take(&mut metrics[i]));
                if let Some(runs) = result.as_mut() {
                    runs.push(run);
                }
            }
        }
        results
    }

    /// An energy map's runs of `cells`, side by side.
    fn energy_group(
        &self,
        plan: &EnergyLanes,
        cells: Cells<usize>,
        budget: Budget<'_>,
    ) -> Vec<Option<Vec<RunMetrics>>> {
        let n = cells.len();
        let mut results: Vec<Vec<Option<RunMetrics>>> =
            vec![Vec::with_capacity(plan.runs.len()); n];
        // Once the budget stopped a run, the later ones are only prepared, for their failures.
        let mut stopped = false;
        for (k, run) in plan.runs.iter().enumerate() {
            // Per cell, its start's place in `starts`, or its failure.
            let mut starts = Vec::with_capacity(n);
            let mut places = Vec::with_capacity(n);
            for cell in cells.clone() {
                let spec = self.cell_spec(k, &self.grid.point(cell));
                match Simulation::prepare(&spec, &self.limits) {
                    Ok(sim) => {
                        places.push(Ok(starts.len()));
                        starts.push(TallyStart {
                            q: [sim.q0[0], sim.q0[1]],
                            p: [sim.p0[0], sim.p0[1]],
                            energy: with_system!(&run.system, s => {
                                let z = State::from_slices(s.dim(), &sim.q0, &sim.p0);
                                s.energy(&z.q, &z.p)
                            }),
                        });
                    }
                    // As the one-cell path: a start outside the chart is that run's result.
                    Err(e) => places.push(Err(RunMetrics::failed(e.to_string()))),
                }
            }
            let tallies = if stopped {
                None
            } else {
                let measured = run.kernel.tally(&starts, plan.h, plan.steps, budget);
                stopped = measured.is_none();
                measured
            };
            for (result, place) in results.iter_mut().zip(places) {
                let metrics = match (place, &tallies) {
                    (Err(failed), _) => Some(failed),
                    (Ok(i), Some(tallies)) => Some(plan.metrics(run, &tallies[i])),
                    (Ok(_), None) => None,
                };
                result.push(metrics);
            }
        }
        results
            .into_iter()
            .map(|runs| runs.into_iter().collect())
            .collect()
    }
}

impl EnergyLanes {
    /// A run's metrics, as the one-cell path's [`MetricsTally`] would have them: a state that
    /// stopped being finite at step s ends the run there (s steps, the state of step s − 1);
    /// each step costs one force evaluation, as in the composer's symplectic Euler (one kick)
    /// and the charts' closed-form stages.
    fn metrics(&self, run: &EnergyLaneRun, tally: &Tally) -> RunMetrics {
        let at = |step: f64| (step != f64::INFINITY).then_some(step * self.h);
        let stopped_at = at(tally.non_finite);
        let steps = match stopped_at {
            Some(_) => tally.non_finite as u64,
            None => self.steps,
        };
        let (q, p) = (tally.q, tally.p);
        let cartesian = with_system!(&run.system, s => {
            if s.is_cartesian() {
                (q.to_vec(), p.to_vec())
            } else {
                let z = State::from_slices(s.dim(), &q, &p);
                let (mut x, mut px) = (vec![0.0; 2], vec![0.0; 2]);
                s.to_cartesian(&z.q, &z.p, &mut x, &mut px);
                (x, px)
            }
        });
        // Samples at steps 0 to `steps`, or to s − 1 for a run stopped at s.
        let samples = if stopped_at.is_some() {
            steps
        } else {
            steps + 1
        };
        MetricsTally::of_lane(
            at(tally.blown),
            (tally.sum, samples),
            (tally.max, tally.last),
            cartesian,
        )
        .finish_at(stopped_at, steps, steps)
    }
}

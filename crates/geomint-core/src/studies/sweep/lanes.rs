//! Sweeps whose every run has a batched stepper ([`LaneKernel`]: today symplectic Euler or its
//! adjoint on the planar elastic pendulum), with axes over the initial state only and the energy
//! error against H₀ at every step (paper 001 Fig. 6's energy map is one), run their cells four at
//! a time in SIMD lanes, with the numbers of the one-cell path bit for bit: the lanes do its
//! arithmetic operation for operation, and each run's metrics come out of the same [`Measure`]
//! the one-cell path fills sample by sample.

use std::ops::Range as Cells;

use super::metrics::{EnergyReference, Measure, RunMetrics};
use super::{SweepJob, Target};
pub(super) use crate::methods::lanes::LANES;
use crate::methods::lanes::{LaneKernel, Start, Tally};
use crate::run::Budget;
use crate::simulation::Simulation;
use crate::studies::engine::Study;
use crate::system::{MechanicalSystem, State};
use crate::systems::AnySystem;
use crate::with_system;

/// How the lanes run a sweep: one entry per run (method × chart), and the common schedule.
#[derive(Clone, Debug)]
pub(super) struct LanePlan {
    runs: Vec<LaneRun>,
    h: f64,
    steps: u64,
}

/// One run's system (in its chart, as the one-cell path builds it) and its kernel.
#[derive(Clone, Debug)]
struct LaneRun {
    system: AnySystem,
    kernel: LaneKernel,
}

impl SweepJob {
    /// The plan, if every run of the sweep has a kernel, is sampled at every step and measured
    /// against H₀, with axes over q₀ and p₀ only (the lanes share the parameters and the step).
    pub(super) fn lane_plan(&self) -> Option<LanePlan> {
        let initial_state_only = self
            .grid
            .axes
            .iter()
            .all(|a| matches!(a.target, Target::Q0(_) | Target::P0(_)));
        if self.against != EnergyReference::Initial || !initial_state_only {
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
            runs.push(LaneRun {
                system: sim.system,
                kernel,
            });
        }
        let (h, steps) = schedule?;
        Some(LanePlan { runs, h, steps })
    }

    /// The runs of `cells` (at most [`LANES`]), side by side. As on the one-cell path, a cell
    /// is `None` when the budget stopped one of its runs, and keeps its results when every run
    /// either failed to start or finished (a cell whose starts are all outside the chart keeps
    /// its failures after the time limit).
    pub(super) fn lane_group(
        &self,
        plan: &LanePlan,
        cells: Cells<usize>,
        budget: Budget<'_>,
    ) -> Vec<Option<Vec<RunMetrics>>> {
        let n = cells.len();
        debug_assert!(n <= LANES);
        let mut results: Vec<Vec<Option<RunMetrics>>> =
            vec![Vec::with_capacity(plan.runs.len()); n];
        // Once the budget stopped a run, the later ones are only prepared, for their failures.
        let mut stopped = false;
        for (k, run) in plan.runs.iter().enumerate() {
            let mut start = Start {
                q: [[0.0; LANES]; 2],
                p: [[0.0; LANES]; 2],
                energy: [0.0; LANES],
                idle: [true; LANES],
            };
            let mut failed: [Option<RunMetrics>; LANES] = Default::default();
            for (i, cell) in cells.clone().enumerate() {
                let spec = self.cell_spec(k, &self.grid.point(cell));
                match Simulation::prepare(&spec, &self.limits) {
                    Ok(sim) => {
                        for c in 0..2 {
                            start.q[c][i] = sim.q0[c];
                            start.p[c][i] = sim.p0[c];
                        }
                        start.energy[i] = with_system!(&run.system, s => {
                            let z = State::from_slices(s.dim(), &sim.q0, &sim.p0);
                            s.energy(&z.q, &z.p)
                        });
                        start.idle[i] = false;
                    }
                    // As the one-cell path: a start outside the chart is that run's result.
                    Err(e) => failed[i] = Some(RunMetrics::failed(e.to_string())),
                }
            }
            let tally = if stopped {
                None
            } else {
                let measured = run.kernel.tally(&start, plan.h, plan.steps, budget);
                stopped = measured.is_none();
                measured
            };
            for (i, result) in results.iter_mut().enumerate() {
                let metrics = match (failed[i].take(), &tally) {
                    (Some(failed), _) => Some(failed),
                    (None, Some(tally)) => Some(plan.metrics(run, tally, i)),
                    (None, None) => None,
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

impl LanePlan {
    /// Lane `i`'s metrics, as the one-cell path's [`Measure`] would have them: a state that
    /// stopped being finite at step s ends the run there (s steps, the state of step s − 1);
    /// each step costs one force evaluation, as in the composer's symplectic Euler (one kick)
    /// and the charts' closed-form stages.
    fn metrics(&self, run: &LaneRun, tally: &Tally, i: usize) -> RunMetrics {
        let at = |step: f64| (step != f64::INFINITY).then_some(step * self.h);
        let stopped_at = at(tally.non_finite[i]);
        let steps = match stopped_at {
            Some(_) => tally.non_finite[i] as u64,
            None => self.steps,
        };
        let q = [tally.q[0][i], tally.q[1][i]];
        let p = [tally.p[0][i], tally.p[1][i]];
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
        Measure::of_lane(
            at(tally.blown[i]),
            (tally.sum[i], samples),
            (tally.max[i], tally.last[i]),
            cartesian,
        )
        .finish_at(stopped_at, steps, steps)
    }
}

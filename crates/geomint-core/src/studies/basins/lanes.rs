//! A basin map's cells in SIMD lanes, each leaving its lane as soon as it is decided: the next
//! cell of the group takes the lane and the others go on, so a group costs the steps its cells
//! need to be decided rather than `t_end` for each.
//!
//! Every lane takes the one-cell path's steps one at a time ([`RunLanes::advance`] of one step is
//! the stepper's step, bit for bit; see [`crate::methods::lanes`]), and each cell's [`Decide`]
//! observer sees the same states at the same times as on the one-cell path, after the same
//! test for a state that is no longer finite; on a step where the observer would change and
//! decide nothing ([`Criteria::quiet_bounds`](super::outcome::Criteria::quiet_bounds): a
//! driven system's cell between its stroboscope points, finite and within the escape radius)
//! the lane does not hand it the state. So a cell's outcome, decision time and step count
//! are the one-cell path's to the bit, whatever lane it ran in and whichever cells ran beside it
//! (`tests/core/basins/` compares the two paths cell by cell).

use std::ops::{ControlFlow, Range};

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::outcome::{CellOutcome, Decide, OrbitOutcome};
use super::BasinsJob;
use crate::methods::lanes::{LaneForces, CHECK_EVERY};
use crate::run::{Budget, Observer, RunEnd};
use crate::simulation::{with_lane_systems, Simulation};
use crate::system::{MechanicalSystem, State, LANES};

/// Cells a group of the map holds when they run in lanes: several lanes' worth, so that a lane
/// whose cell is decided early takes another, and few enough that the cores share the map's
/// groups evenly.
pub(super) const GROUP: usize = 16 * LANES;

/// A cell's initial q and p.
type CellStart = (Vec<f64>, Vec<f64>);

/// A lane's cell: where its outcome goes, its observer, its steps so far and its state as the
/// observer last saw it.
struct LaneCell<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    slot: usize,
    decide: Decide<'a, S>,
    step: u64,
    state: State<S::Dim>,
}

impl BasinsJob {
    /// Run `run` of `cells`, side by side in lanes; `None` when its method and system do not go
    /// in lanes (the caller runs the cells one by one then). A cell the budget stopped is
    /// `None`.
    pub(super) fn decide_in_lanes(
        &self,
        run: usize,
        cells: Range<usize>,
        budget: Budget<'_>,
    ) -> Option<Vec<Option<CellOutcome>>> {
        let mut outcomes: Vec<Option<CellOutcome>> = vec![None; cells.len()];
        // The first cell that prepares is prepared whole; the others differ from it in their
        // initial state only (a basin map's axes), which is all that is prepared of them.
        let mut first: Option<Simulation> = None;
        let mut queue = Vec::with_capacity(cells.len());
        for (slot, cell) in cells.enumerate() {
            let point = self.sweep.grid.point(cell);
            let start = match &first {
                Some(prepared) => self.sweep.cell_start(run, &point, prepared),
                None => self.sweep.cell_simulation(run, &point).map(|sim| {
                    let start = (sim.q0.clone(), sim.p0.clone());
                    first = Some(sim);
                    start
                }),
            };
            match start {
                Ok(start) => queue.push((slot, start)),
                Err(e) => outcomes[slot] = Some(CellOutcome::failed(e)),
            }
        }
        let Some(first) = first else {
            return Some(outcomes);
        };
        with_lane_systems!(
            std::slice::from_ref(&first),
            systems => self.decide_lanes(systems[0], &first, &queue, &mut outcomes, budget),
            _ => None
        )?;
        Some(outcomes)
    }

    /// The cells of `queue` (slot in `outcomes`, initial q and p) in the lanes of `first`'s
    /// method on `sys`, every cell's system being `sys` (a basin map's axes move only the
    /// initial state).
    fn decide_lanes<S, const N: usize>(
        &self,
        sys: &S,
        first: &Simulation,
        queue: &[(usize, CellStart)],
        outcomes: &mut [Option<CellOutcome>],
        budget: Budget<'_>,
    ) -> Option<()>
    where
        S: MechanicalSystem + LaneForces<N> + PartialEq,
        DefaultAllocator: Allocator<S::Dim>,
    {
        let mut lanes = first.plain_lanes::<S, N>(sys)?;
        let (h, steps) = (first.schedule.h, first.schedule.steps);
        let t_end = steps as f64 * h;
        let mut waiting = queue.iter();
        let mut running: Vec<Option<LaneCell<'_, S>>> = (0..LANES).map(|_| None).collect();
        let unwatched = [false; LANES];
        let quiet_bounds = self.criteria.quiet_bounds::<N>();
        let mut round = 0u64;
        loop {
            // Free lanes take the next cells; a cell decided at its start takes none.
            for (l, lane) in running.iter_mut().enumerate() {
                while lane.is_none() {
                    let Some((slot, (q0, p0))) = waiting.next() else {
                        break;
                    };
                    let start = State::at_time(sys, 0.0, q0, p0);
                    let mut decide = Decide::new(sys, &self.criteria, &start, q0.len());
                    if decide.decided.is_some() {
                        outcomes[*slot] =
                            self.conclude(decide.decided.take(), RunEnd::Finished, 0, t_end);
                        continue;
                    }
                    lanes.set_state(l, start.q.as_slice(), start.p.as_slice());
                    *lane = Some(LaneCell {
                        slot: *slot,
                        decide,
                        step: 0,
                        state: start,
                    });
                }
            }
            if running.iter().all(Option::is_none) {
                return Some(());
            }
            // The one-cell path looks at the budget every CHECK_EVERY steps of a cell; here every
            // CHECK_EVERY steps of the lanes. The cells still running are left `None`.
            if round.is_multiple_of(CHECK_EVERY) && (budget.cancelled() || budget.expired()) {
                return Some(());
            }
            round += 1;
            // Divergence is looked at below as the one-cell path does, on the components.
            lanes.advance(sys, 1, &unwatched);
            let inside = quiet_bounds.map_or([false; LANES], |(q, p)| lanes.within(&q, &p));
            for (l, lane) in running.iter_mut().enumerate() {
                let Some(cell) = lane else {
                    continue;
                };
                cell.step += 1;
                if cell.step != steps && inside[l] && cell.decide.between_looks(cell.step) {
                    continue;
                }
                let (q, p) = lanes.state(l);
                cell.state.q.copy_from_slice(&q);
                cell.state.p.copy_from_slice(&p);
                let (step, t) = (cell.step, cell.step as f64 * h);
                let stop = if !cell.state.is_finite() {
                    RunEnd::Diverged { step, t }
                } else if let ControlFlow::Break(at) = cell.decide.on_step(step, t, &cell.state) {
                    RunEnd::Event { step, t: at }
                } else if step == steps {
                    RunEnd::Finished
                } else {
                    continue;
                };
                let Some(mut done) = lane.take() else {
                    continue;
                };
                outcomes[done.slot] = self.conclude(done.decide.decided.take(), stop, step, t_end);
            }
        }
    }
}

impl CellOutcome {
    /// A cell whose run could not start or failed.
    pub(super) fn failed(error: impl std::fmt::Display) -> Self {
        CellOutcome {
            outcome: OrbitOutcome::Failed {
                error: error.to_string(),
            },
            decided_at: None,
            steps: 0,
            energy_margin: None,
        }
    }
}

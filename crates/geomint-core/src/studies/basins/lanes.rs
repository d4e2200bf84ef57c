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
use crate::methods::lanes::LaneForces;
use crate::run::driver::{drive_lanes, LaneEnd, LaneGroup, LaneRun, LaneStretch};
use crate::run::{Budget, Observer, RunEnd};
use crate::simulation::lanes::PlainGroup;
use crate::simulation::{with_lane_systems, Simulation};
use crate::system::{MechanicalSystem, State, LANES};

/// Cells a group of the map holds when they run in lanes: several lanes' worth, so that a lane
/// whose cell is decided early takes another, and few enough that the cores share the map's
/// groups evenly.
pub(super) const GROUP: usize = 16 * LANES;

/// A cell's initial q and p.
type CellStart = (Vec<f64>, Vec<f64>);

/// A basin map's plain lanes, which leave divergence to the cells' looks, and which of them
/// are within the quiet bounds after each step.
struct CellLanes<'a, S, const N: usize> {
    plain: PlainGroup<'a, S, N>,
    quiet_bounds: Option<([f64; N], [f64; N])>,
    inside: [bool; LANES],
}

impl<S: LaneForces<N>, const N: usize> LaneGroup for CellLanes<'_, S, N> {
    #[inline]
    fn advance(&mut self, n: u64, running: &[bool; LANES]) -> LaneStretch {
        let stretch = self.plain.advance(n, running);
        if let Some((q, p)) = &self.quiet_bounds {
            self.inside = self.plain.lanes.within(q, p);
        }
        stretch
    }
}

/// A cell in a lane: its observer, which decides it, and its state as the observer last saw
/// it.
struct LaneCell<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    job: &'a BasinsJob,
    decide: Decide<'a, S>,
    state: State<S::Dim>,
    h: f64,
    steps: u64,
}

impl<S: MechanicalSystem + LaneForces<N>, const N: usize> LaneRun<CellLanes<'_, S, N>>
    for LaneCell<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    type Report = Option<CellOutcome>;

    /// A cell decided at its start takes no lane.
    fn enter(&mut self, group: &mut CellLanes<'_, S, N>, l: usize) -> ControlFlow<Self::Report> {
        if self.decide.decided.is_some() {
            return ControlFlow::Break(self.conclude(RunEnd::Finished, 0));
        }
        let (q, p) = (self.state.q.as_slice(), self.state.p.as_slice());
        group.plain.lanes.set_state(l, q, p);
        ControlFlow::Continue(())
    }

    /// Every step, as the one-cell path's observer watches them.
    #[inline]
    fn next_look(&self, step: u64) -> u64 {
        step + 1
    }

    /// Divergence is looked at as the one-cell path does, on the components.
    #[inline]
    fn look(
        &mut self,
        group: &mut CellLanes<'_, S, N>,
        l: usize,
        step: u64,
        _: Option<LaneEnd>,
    ) -> ControlFlow<Self::Report> {
        if step != self.steps && group.inside[l] && self.decide.between_looks(step) {
            return ControlFlow::Continue(());
        }
        let (q, p) = group.plain.lanes.state(l);
        self.state.q.copy_from_slice(&q);
        self.state.p.copy_from_slice(&p);
        let t = step as f64 * self.h;
        let stop = if !self.state.is_finite() {
            RunEnd::Diverged { step, t }
        } else if let ControlFlow::Break(at) = self.decide.on_step(step, t, &self.state) {
            RunEnd::Event { step, t: at }
        } else if step == self.steps {
            RunEnd::Finished
        } else {
            return ControlFlow::Continue(());
        };
        ControlFlow::Break(self.conclude(stop, step))
    }

    /// The budget stopped an undecided cell (a decided one has left its lane): it has no
    /// outcome.
    fn stopped(
        &mut self,
        _: &mut CellLanes<'_, S, N>,
        _: usize,
        _: u64,
        _: RunEnd,
    ) -> Self::Report {
        None
    }
}

impl<S: MechanicalSystem> LaneCell<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn conclude(&mut self, stop: RunEnd, step: u64) -> Option<CellOutcome> {
        let t_end = self.steps as f64 * self.h;
        self.job
            .conclude(self.decide.decided.take(), stop, step, t_end)
    }
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
        let lanes = first.plain_lanes::<S, N>(sys)?;
        let mut group = CellLanes {
            plain: PlainGroup::new(lanes, sys, false),
            quiet_bounds: self.criteria.quiet_bounds::<N>(),
            inside: [false; LANES],
        };
        let (h, steps) = (first.schedule.h, first.schedule.steps);
        let cells = queue.iter().map(|(_, (q0, p0))| {
            let state = State::at_time(sys, 0.0, q0, p0);
            LaneCell {
                job: self,
                decide: Decide::new(sys, &self.criteria, &state, q0.len()),
                state,
                h,
                steps,
            }
        });
        // The one-cell path looks at the budget every CHECK_EVERY steps of a cell; here every
        // CHECK_EVERY steps of the lanes. The cells still running are left `None`.
        drive_lanes(&mut group, cells, budget, |i, outcome| {
            outcomes[queue[i].0] = outcome;
        });
        Some(())
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

//! The run loop, for one run alone and for runs side by side in SIMD lanes, whatever the lanes
//! compute and whatever each run watches. One run
//! ([`integrate_tracked`](super::integrate_tracked)) is a lane of its own; a sweep's plain runs,
//! a chaos map's runs with their indicators and a basin map's cells go through [`drive_lanes`]
//! [`LANES`] at a time, and an energy map's cells four at a time (its kernel's lanes fill AVX2's
//! f64×4 registers).
//!
//! The loop knows two things: a [`LaneGroup`], which advances its lanes by a stretch of steps
//! and says which lanes' runs ended inside it, and a [`LaneRun`] per lane, the run's observer,
//! which loads its start into the lanes, says when it next needs to look at its lane (stretches
//! end there, and every [`LaneGroup::check_every`] steps of the group, where the budget is
//! looked at) and, when it looks, goes on or ends. A lane whose run ended takes the next run
//! waiting, so a run that ends early leaves its group without stopping the others. What a group
//! watches at every step (a basin cell's bounds, one run's surfaces) it watches inside its
//! stretches, which end where a run must look.

use std::ops::ControlFlow;

use super::{Budget, RunEnd};
use crate::system::LANES;

/// Steps of a group of lanes between two looks at the budget, and the one-run driver's for cheap
/// steps ([`Stepper::check_interval`](super::Stepper::check_interval)): stretches are cut there
/// on both paths, so a plain run's fused seams fall at the same steps.
pub const CHECK_EVERY: u64 = 1024;

/// How a lane's run ended inside a stretch: where its group stopped it (a plain lane at the
/// first step whose state does not sum to a finite number, the one-run path's stepper's test;
/// one run where it stops for any reason). Not `diverged` when every component is finite and
/// only their sum overflowed: a plain run is then given back, to run on its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LaneEnd {
    /// Steps taken in the stretch, that one included.
    pub steps: u64,
    /// Force evaluations of the lanes by then.
    pub force_evaluations: u64,
    /// Whether a component of the state is not finite (else only their sum overflows).
    pub diverged: bool,
}

/// Lanes that advance together: what a [`LaneRun`] runs in.
pub trait LaneGroup<const N: usize = LANES> {
    /// Takes up to `n` steps of the lanes `running`, stopping early where the group must look
    /// sooner. Every running lane takes the steps returned, but a lane whose run ended inside
    /// them, which took the steps its [`LaneEnd`] says.
    fn advance(&mut self, n: u64, running: &[bool; N]) -> LaneStretch<N>;

    /// Steps of the group between two looks at the budget.
    fn check_every(&self) -> u64 {
        CHECK_EVERY
    }
}

/// Per lane, whether its run ended inside a stretch.
pub type LaneEnds<const N: usize = LANES> = [Option<LaneEnd>; N];

/// What a stretch of a [`LaneGroup`] did.
pub struct LaneStretch<const N: usize = LANES> {
    /// Steps every running lane took.
    pub steps: u64,
    /// Per lane, whether its run ended inside the stretch.
    pub ended: LaneEnds<N>,
}

/// A run in a lane of a group `G`: its observers and what it reports when it ends.
pub trait LaneRun<G: LaneGroup<N>, const N: usize = LANES> {
    /// What the run reports when it ends.
    type Report;

    /// Loads the run's start into lane `l`; `Break` when it ends there, before any step.
    fn enter(&mut self, group: &mut G, l: usize) -> ControlFlow<Self::Report>;

    /// The step after `step` at which the run must next look at its lane (a stretch never
    /// passes it).
    fn next_look(&self, step: u64) -> u64;

    /// Lane `l` after a stretch that brought its run to `step`, or ended it there (`end`).
    fn look(
        &mut self,
        group: &mut G,
        l: usize,
        step: u64,
        end: Option<LaneEnd>,
    ) -> ControlFlow<Self::Report>;

    /// The budget stopped the run in lane `l` at `step` (`stop`: cancelled or out of time).
    fn stopped(&mut self, group: &mut G, l: usize, step: u64, stop: RunEnd) -> Self::Report;
}

/// Runs `runs` in `group`'s lanes in the order they come, each as a lane frees, and gives each
/// one's report, with its place in `runs`, to `finished` as it ends; when the budget stops the
/// group, the runs in its lanes report so, and those still waiting do not run.
pub fn drive_lanes<G, R, const N: usize>(
    group: &mut G,
    runs: impl IntoIterator<Item = R>,
    budget: Budget<'_>,
    mut finished: impl FnMut(usize, R::Report),
) where
    G: LaneGroup<N>,
    R: LaneRun<G, N>,
{
    let mut waiting = runs.into_iter().enumerate();
    // Each lane's run, its place in `runs` and its steps so far.
    let mut lanes: [Option<(usize, R, u64)>; N] = std::array::from_fn(|_| None);
    let mut running = [false; N];
    // Whether a lane was freed since the runs waiting last took the free lanes.
    let mut free = true;
    // Steps until the nearest look of the runs in the lanes.
    let mut to_look = u64::MAX;
    // Steps of the group, and the next at which the budget is looked at (no stretch ends past
    // it, so the group meets it).
    let (mut taken, mut check_at) = (0u64, 0u64);
    let check_every = group.check_every();
    loop {
        if free {
            for (l, lane) in lanes.iter_mut().enumerate() {
                while lane.is_none() {
                    let Some((i, mut run)) = waiting.next() else {
                        break;
                    };
                    match run.enter(group, l) {
                        ControlFlow::Continue(()) => {
                            to_look = to_look.min(run.next_look(0));
                            *lane = Some((i, run, 0));
                        }
                        ControlFlow::Break(report) => finished(i, report),
                    }
                }
                running[l] = lane.is_some();
            }
            free = false;
            if !running.contains(&true) {
                return;
            }
        }
        // Also before the first step: work started after the deadline stops at once.
        if taken == check_at {
            check_at = check_at.saturating_add(check_every);
            let stop: Option<fn(u64) -> RunEnd> = if budget.cancelled() {
                Some(|step| RunEnd::Cancelled { step })
            } else if budget.expired() {
                Some(|step| RunEnd::TimeLimit { step })
            } else {
                None
            };
            if let Some(stop) = stop {
                for (l, lane) in lanes.iter_mut().enumerate() {
                    if let Some((i, mut run, step)) = lane.take() {
                        finished(i, run.stopped(group, l, step, stop(step)));
                    }
                }
                return;
            }
        }
        let stretch = group.advance(to_look.min(check_at - taken), &running);
        taken += stretch.steps;
        to_look = u64::MAX;
        for (l, lane) in lanes.iter_mut().enumerate() {
            let Some((i, run, step)) = lane else {
                continue;
            };
            let end = stretch.ended[l];
            *step += end.map_or(stretch.steps, |end| end.steps);
            match run.look(group, l, *step, end) {
                ControlFlow::Continue(()) => to_look = to_look.min(run.next_look(*step) - *step),
                ControlFlow::Break(report) => {
                    finished(*i, report);
                    *lane = None;
                    running[l] = false;
                    free = true;
                }
            }
        }
    }
}

//! The one loop that drives runs side by side in SIMD lanes, whatever the lanes compute and
//! whatever each run watches: a sweep's plain runs, a chaos map's runs with their indicators
//! and a basin map's cells all go through [`drive`].
//!
//! The loop knows two things: a [`LaneGroup`], which advances its lanes by a stretch of steps
//! and says which lanes' runs ended inside it (a state no longer finite), and a [`LaneRun`] per
//! lane, the run's observer, which loads its start into the lanes, says when it next needs to
//! look at its lane (stretches end there, and at every [`CHECK_EVERY`] steps of the group, where
//! the budget is looked at) and, when it looks, goes on or ends. A lane whose run ended takes the
//! next run waiting, so a run that ends early leaves its group without stopping the others.

use std::ops::ControlFlow;

use crate::methods::lanes::runs::End;
use crate::methods::lanes::CHECK_EVERY;
use crate::run::Budget;
use crate::system::LANES;

/// Lanes that advance together: what a [`LaneRun`] runs in.
pub(crate) trait LaneGroup {
    /// Takes up to `n` steps of the lanes `running`, stopping early where the group must look
    /// sooner. Every running lane takes the steps returned, but a lane whose run ended inside
    /// them (its [`End`]), which took the steps its end says.
    fn advance(&mut self, n: u64, running: &[bool; LANES]) -> LaneStretch;
}

/// What a stretch of a [`LaneGroup`] did.
pub(crate) struct LaneStretch {
    /// Steps every running lane took.
    pub steps: u64,
    /// Per lane, whether its run ended inside the stretch.
    pub ended: [Option<End>; LANES],
}

/// A run in a lane of a group `G`: its observers and what it reports when it ends.
pub(crate) trait LaneRun<G: LaneGroup> {
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
        end: Option<End>,
    ) -> ControlFlow<Self::Report>;
}

/// Runs `runs` in `group`'s lanes in the order they come, each as a lane frees, and gives each
/// one's report, with its place in `runs`, to `finished` as it ends. False when the budget
/// stopped them (the runs still running are dropped unreported).
pub(crate) fn drive<G, R>(
    group: &mut G,
    runs: impl IntoIterator<Item = R>,
    budget: Budget<'_>,
    mut finished: impl FnMut(usize, R::Report),
) -> bool
where
    G: LaneGroup,
    R: LaneRun<G>,
{
    let mut waiting = runs.into_iter().enumerate();
    // Each lane's run, its place in `runs` and its steps so far.
    let mut lanes: [Option<(usize, R, u64)>; LANES] = std::array::from_fn(|_| None);
    // Steps of the group, for the looks at the budget.
    let mut taken = 0u64;
    loop {
        for (l, lane) in lanes.iter_mut().enumerate() {
            while lane.is_none() {
                let Some((i, mut run)) = waiting.next() else {
                    break;
                };
                match run.enter(group, l) {
                    ControlFlow::Continue(()) => *lane = Some((i, run, 0)),
                    ControlFlow::Break(report) => finished(i, report),
                }
            }
        }
        let running: [bool; LANES] = std::array::from_fn(|l| lanes[l].is_some());
        if !running.contains(&true) {
            return true;
        }
        if taken.is_multiple_of(CHECK_EVERY) && (budget.cancelled() || budget.expired()) {
            return false;
        }
        let to_look = lanes
            .iter()
            .flatten()
            .map(|(_, run, step)| run.next_look(*step) - step);
        let n = to_look.fold(CHECK_EVERY - taken % CHECK_EVERY, u64::min);
        let stretch = group.advance(n, &running);
        taken += stretch.steps;
        for (l, lane) in lanes.iter_mut().enumerate() {
            let Some((i, run, step)) = lane else {
                continue;
            };
            let end = stretch.ended[l];
            *step += end.map_or(stretch.steps, |end| end.steps);
            if let ControlFlow::Break(report) = run.look(group, l, *step, end) {
                finished(*i, report);
                *lane = None;
            }
        }
    }
}

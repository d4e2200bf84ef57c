//! The two kinds of lane groups a simulation's runs take — plain runs ([`PlainGroup`]) and runs
//! with their chaos indicators ([`TrackedGroup`]) — and the run that samples them
//! ([`SampledRun`]), which does in its lane what [`integrate_tracked`] does for one run: the
//! samples, the indicators' updates on their grid and their thresholds, and divergence (the
//! budget is the driver's).
//!
//! [`integrate_tracked`]: crate::run::integrate_tracked

use std::ops::ControlFlow;
use std::time::Instant;

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim};

use crate::chaos::{ChaosPlan, OneVectorLanes, Statistic, ThresholdCrossing, Tracker};
use crate::methods::lanes::runs::RunLanes;
use crate::methods::lanes::{LaneForces, TangentLanes};
use crate::run::driver::{LaneEnd, LaneGroup, LaneRun, LaneStretch};
use crate::run::{Observer, RunEnd, RunStats, Schedule};
use crate::simulation::RunReport;
use crate::system::{MechanicalSystem, State, LANES};

/// Plain runs' lanes with the forces they take (one system for all, or one each), watching
/// the running lanes for a state that stops being finite unless told not to.
pub(crate) struct PlainGroup<'a, F, const N: usize> {
    pub lanes: RunLanes<N>,
    forces: &'a F,
    /// Whether stretches stop a lane at its first state that does not sum to a finite number
    /// (else its run looks at its components itself).
    watch: bool,
    started: Instant,
}

impl<'a, F: LaneForces<N>, const N: usize> PlainGroup<'a, F, N> {
    pub fn new(lanes: RunLanes<N>, forces: &'a F, watch: bool) -> Self {
        PlainGroup {
            lanes,
            forces,
            watch,
            started: Instant::now(),
        }
    }
}

impl<F: LaneForces<N>, const N: usize> LaneGroup for PlainGroup<'_, F, N> {
    #[inline]
    fn advance(&mut self, n: u64, running: &[bool; LANES]) -> LaneStretch {
        let watched = if self.watch { running } else { &[false; LANES] };
        LaneStretch {
            steps: n,
            ended: self.lanes.advance(self.forces, n, watched),
        }
    }
}

/// Runs with deviation vectors in lanes, with their indicators' trackers, one per lane. The
/// runs enter together, at the group's start: the group's steps are theirs.
pub(crate) struct TrackedGroup<'a, S: MechanicalSystem, const N: usize>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    lanes: TangentLanes<N>,
    sys: &'a S,
    plan: &'a ChaosPlan,
    h: f64,
    step: u64,
    trackers: Vec<Option<Tracker<S::Dim>>>,
    /// Powers of two the lanes took out of each lane's vectors since its tracker last saw them.
    exponents: Vec<Vec<i32>>,
    /// With one vector and nothing to look at between samples, the lanes keep the sums and
    /// update them together; each run's tracker takes them over at its samples.
    sums: Option<OneVectorLanes<LANES>>,
    /// Per lane: the threshold its indicators passed at the last stretch's end.
    passed: [Option<(Statistic, f64, f64)>; LANES],
    started: Instant,
}

impl<'a, S: MechanicalSystem, const N: usize> TrackedGroup<'a, S, N>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    pub fn new(lanes: TangentLanes<N>, sys: &'a S, plan: &'a ChaosPlan, h: f64) -> Self {
        TrackedGroup {
            lanes,
            sys,
            plan,
            h,
            step: 0,
            trackers: (0..LANES).map(|_| None).collect(),
            exponents: vec![vec![0; plan.deviations]; LANES],
            sums: OneVectorLanes::new(plan, h),
            passed: [None; LANES],
            started: Instant::now(),
        }
    }
}

impl<S: MechanicalSystem + LaneForces<N>, const N: usize> LaneGroup for TrackedGroup<'_, S, N>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// The stretch, stopped early after a step that leaves a lane not finite or with a vector
    /// out of range, then the indicators' updates that fall on its end.
    #[inline]
    fn advance(&mut self, n: u64, running: &[bool; LANES]) -> LaneStretch {
        let qr_every = self.plan.qr_every.max(1);
        let advanced = self.lanes.advance(self.sys, n, running);
        self.step += advanced.steps;
        let step = self.step;
        let mut ended = [None; LANES];
        // Lanes whose indicators this step updates: the one-run path leaves them alone after a
        // step whose state's components are finite but overflow when summed.
        let mut update = [false; LANES];
        for l in (0..LANES).filter(|&l| running[l]) {
            if advanced.not_finite[l] {
                if !self.lanes.finite(l) {
                    ended[l] = Some(LaneEnd {
                        steps: advanced.steps,
                        force_evaluations: self.lanes.force_evaluations(),
                        diverged: true,
                    });
                }
                continue;
            }
            if advanced.out_of_range[l] {
                self.lanes.guard(l, &mut self.exponents[l]);
            }
            update[l] = step.is_multiple_of(qr_every);
        }
        self.passed = [None; LANES];
        let lanes = &mut self.lanes;
        if let Some(sums) = self.sums.as_mut() {
            if update.contains(&true) {
                let (r, kept) = lanes.normalise_first(&update);
                let e = std::array::from_fn(|l| self.exponents[l][0]);
                sums.update(step, &r, &e, &kept);
                for l in 0..LANES {
                    let (exponents, tracker) = (&mut self.exponents[l], &mut self.trackers[l]);
                    if kept[l] {
                        exponents[0] = 0;
                    } else if let Some(tracker) = tracker.as_mut().filter(|_| update[l]) {
                        // A vector with no length: the tracker replaces it.
                        sums.hand_to(l, tracker);
                        hand_over(lanes, l, tracker, exponents);
                        tracker.after_step(step);
                        lanes.load(l, &tracker.tangent.jac);
                        sums.take_from(l, tracker);
                    }
                }
            }
        } else {
            for l in (0..LANES).filter(|&l| update[l]) {
                let Some(tracker) = self.trackers[l].as_mut() else {
                    continue;
                };
                hand_over(lanes, l, tracker, &mut self.exponents[l]);
                // The tracker's own guard finds the vectors in range: it only updates.
                self.passed[l] = tracker.after_step(step);
                lanes.load(l, &tracker.tangent.jac);
            }
        }
        LaneStretch {
            steps: advanced.steps,
            ended,
        }
    }
}

/// Gives lane `l`'s deviation vectors and the exponents the lanes took out of them to its
/// tracker.
fn hand_over<D: Dim, const N: usize>(
    lanes: &TangentLanes<N>,
    l: usize,
    tracker: &mut Tracker<D>,
    exponents: &mut [i32],
) where
    DefaultAllocator: Allocator<D>,
{
    lanes.store(l, &mut tracker.tangent.jac);
    tracker.add_exponents(exponents);
    exponents.fill(0);
}

/// What a [`SampledRun`] needs of its lanes besides the steps: to load a run's start, to read
/// its state at a sample with what goes with it, and whether an indicator passed its threshold.
pub(crate) trait SampledLanes<D: Dim>: LaneGroup
where
    DefaultAllocator: Allocator<D>,
{
    /// Loads the start `z` into lane `l`; reports the indicators at the start to `observer`.
    fn load<O: Observer<D>>(&mut self, l: usize, z: &State<D>, observer: &mut O);

    /// Lane `l`'s state into `z`; reports the indicators at `step` to `observer`.
    fn sample<O: Observer<D>>(&mut self, l: usize, step: u64, z: &mut State<D>, observer: &mut O);

    /// The threshold lane `l`'s indicators passed at the last stretch's end: the statistic,
    /// its value and the threshold.
    fn passed(&self, _l: usize) -> Option<(Statistic, f64, f64)> {
        None
    }

    /// Force evaluations of each lane so far.
    fn force_evaluations(&self) -> u64;

    /// When the group started, for its runs' wall times.
    fn started(&self) -> Instant;
}

impl<F: LaneForces<N>, D: Dim, const N: usize> SampledLanes<D> for PlainGroup<'_, F, N>
where
    DefaultAllocator: Allocator<D>,
{
    fn load<O: Observer<D>>(&mut self, l: usize, z: &State<D>, _: &mut O) {
        self.lanes.set_state(l, z.q.as_slice(), z.p.as_slice());
    }

    fn sample<O: Observer<D>>(&mut self, l: usize, _: u64, z: &mut State<D>, _: &mut O) {
        let (q, p) = self.lanes.state(l);
        z.q.copy_from_slice(&q);
        z.p.copy_from_slice(&p);
    }

    fn force_evaluations(&self) -> u64 {
        self.lanes.force_evaluations()
    }

    fn started(&self) -> Instant {
        self.started
    }
}

impl<S, const N: usize> SampledLanes<S::Dim> for TrackedGroup<'_, S, N>
where
    S: MechanicalSystem + LaneForces<N>,
    DefaultAllocator: Allocator<S::Dim>,
{
    /// The run's start with a new tracker.
    fn load<O: Observer<S::Dim>>(&mut self, l: usize, z: &State<S::Dim>, observer: &mut O) {
        for i in 0..N {
            self.lanes.q[i][l] = z.q[i];
            self.lanes.p[i][l] = z.p[i];
        }
        let mut tracker = Tracker::new(self.sys, z, self.plan, self.h);
        self.lanes.load(l, &tracker.tangent.jac);
        self.exponents[l].fill(0);
        if let Some(sums) = self.sums.as_mut() {
            sums.take_from(l, &tracker);
        }
        observer.on_indicators(&tracker.peek(0));
        self.trackers[l] = Some(tracker);
    }

    /// The run's tracker brought up to date with the lanes first.
    fn sample<O: Observer<S::Dim>>(
        &mut self,
        l: usize,
        step: u64,
        z: &mut State<S::Dim>,
        observer: &mut O,
    ) {
        for i in 0..N {
            z.q[i] = self.lanes.q[i][l];
            z.p[i] = self.lanes.p[i][l];
        }
        let Some(tracker) = self.trackers[l].as_mut() else {
            return;
        };
        match &self.sums {
            // The lanes' next update still needs the exponents since the last: the tracker,
            // which only reads the run here, is given a copy.
            Some(sums) => {
                sums.hand_to(l, tracker);
                self.lanes.store(l, &mut tracker.tangent.jac);
                tracker.add_exponents(&self.exponents[l]);
            }
            None => hand_over(&self.lanes, l, tracker, &mut self.exponents[l]),
        }
        observer.on_indicators(&tracker.peek(step));
    }

    fn passed(&self, l: usize) -> Option<(Statistic, f64, f64)> {
        self.passed[l]
    }

    fn force_evaluations(&self) -> u64 {
        self.lanes.force_evaluations()
    }

    fn started(&self) -> Instant {
        self.started
    }
}

/// A simulation's run in a lane: its observer, which takes its samples (and indicators), and
/// its state as last sampled. `None` as its report is a run given back: a plain run whose
/// state's components stayed finite while their sum overflowed, after which the one-run path
/// cuts its stretches where the lanes do not.
pub(crate) struct SampledRun<O, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    pub observer: O,
    pub state: State<D>,
    pub schedule: Schedule,
    /// Steps between the indicators' updates (the samples' for a plain run).
    pub update_every: u64,
}

/// A run's report: how it stopped at `step`, with its force evaluations by then and the wall
/// time since `group` started.
fn report<D: Dim, G: SampledLanes<D>>(
    group: &G,
    stop: RunEnd,
    step: u64,
    force_evaluations: u64,
) -> Option<RunReport>
where
    DefaultAllocator: Allocator<D>,
{
    Some(RunReport {
        stop,
        stats: RunStats {
            steps: step,
            force_evaluations,
            wall_time_ms: group.started().elapsed().as_secs_f64() * 1e3,
        },
    })
}

impl<O, D, G> LaneRun<G> for SampledRun<O, D>
where
    O: Observer<D>,
    D: Dim,
    G: SampledLanes<D>,
    DefaultAllocator: Allocator<D>,
{
    type Report = Option<RunReport>;

    fn enter(&mut self, group: &mut G, l: usize) -> ControlFlow<Self::Report> {
        group.load(l, &self.state, &mut self.observer);
        self.observer.on_sample(0, 0.0, &self.state);
        if self.schedule.steps == 0 {
            return ControlFlow::Break(report(group, RunEnd::Finished, 0, 0));
        }
        ControlFlow::Continue(())
    }

    /// The next sample, update of the indicators, or the end.
    #[inline]
    fn next_look(&self, step: u64) -> u64 {
        let next = |m: u64| (step / m + 1) * m;
        let every = self.schedule.every.max(1);
        next(every)
            .min(next(self.update_every.max(1)))
            .min(self.schedule.steps)
    }

    #[inline]
    fn look(
        &mut self,
        group: &mut G,
        l: usize,
        step: u64,
        end: Option<LaneEnd>,
    ) -> ControlFlow<Self::Report> {
        let t = step as f64 * self.schedule.h;
        if let Some(end) = end {
            let stop = RunEnd::Diverged { step, t };
            let diverged = end.diverged.then_some(stop);
            return ControlFlow::Break(
                diverged.and_then(|stop| report(group, stop, step, end.force_evaluations)),
            );
        }
        let passed = group.passed(l);
        let sampled =
            step.is_multiple_of(self.schedule.every.max(1)) || step == self.schedule.steps;
        if sampled || passed.is_some() {
            group.sample(l, step, &mut self.state, &mut self.observer);
            self.observer.on_sample(step, t, &self.state);
        }
        if let Some((indicator, value, threshold)) = passed {
            let stop = RunEnd::Indicator(ThresholdCrossing {
                step,
                t,
                indicator,
                value,
                threshold,
            });
            return ControlFlow::Break(report(group, stop, step, group.force_evaluations()));
        }
        if step == self.schedule.steps {
            let finished = report(group, RunEnd::Finished, step, group.force_evaluations());
            return ControlFlow::Break(finished);
        }
        ControlFlow::Continue(())
    }

    fn stopped(&mut self, group: &mut G, _: usize, step: u64, stop: RunEnd) -> Self::Report {
        report(group, stop, step, group.force_evaluations())
    }
}

//! One run alone through the lanes' run loop ([`drive_lanes`]) as its one-lane instance: a
//! [`RunLane`] holds the stepper, its state, what it tracks and its observer, and takes a
//! stretch of steps at a time, showing each step to an observer that watches every step; the
//! lane's [`AloneRun`] takes the samples at its looks and ends the run. The budget is the
//! loop's, looked at every [`Track::check_every`] steps.
//!
//! What the one-run path has beside a group of lanes lives here: processing methods' output
//! states (formed at samples, at watched steps, and late, near a surface, for methods whose
//! output map may be applied to any state passed through), the watch of every step, and steps
//! that fail. The watch is the lane's, inside its stretch, so that a watched step costs the loop
//! nothing: the loop looks at the run at its samples, its end and the budget's checks only
//! (every step when the budget is looked at every step, as with each step's Jacobian).

use std::ops::ControlFlow;
use std::time::Instant;

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::driver::{drive_lanes, LaneEnd, LaneGroup, LaneRun, LaneStretch};
use super::track::Track;
use super::{Budget, Observer, RunEnd, RunStats, Schedule, Stepper};
use crate::error::{CoreError, StepError};
use crate::system::{MechanicalSystem, State};

/// What one run reports: how it ended and its statistics, or the step that failed.
type AloneReport = Result<(RunEnd, RunStats), CoreError>;

/// Runs `stepper` from `z` over `schedule` with `track`'s stretches, reporting samples to
/// `observer` (see [`integrate_tracked`](super::integrate_tracked)).
pub(super) fn drive_alone<S, M, O, T>(
    sys: &S,
    stepper: &mut M,
    z: &mut State<S::Dim>,
    schedule: Schedule,
    budget: Budget<'_>,
    track: T,
    observer: &mut O,
) -> AloneReport
where
    S: MechanicalSystem,
    M: Stepper<S> + ?Sized,
    O: Observer<S::Dim>,
    T: Track<S>,
    DefaultAllocator: Allocator<S::Dim>,
{
    let started = Instant::now();
    let watch = observer.watches_steps();
    let lazy = watch && stepper.processes_any_state();
    let mut lane = RunLane {
        check_every: track.check_every(stepper),
        processed: z.clone(),
        skipped: z.clone(),
        sys,
        stepper,
        z,
        observer,
        track,
        h: schedule.h,
        step: 0,
        watch,
        lazy,
        due_at: 0,
        skipped_at: None,
        formed_at: None,
        stop: None,
        failure: None,
    };
    let run = AloneRun {
        schedule,
        sample_at: schedule.every.max(1),
        processed_at: None,
        deadline: budget.deadline,
        started,
    };
    let mut report = None;
    drive_lanes(&mut lane, [run], budget, |_, ended| report = Some(ended));
    report.expect("a run that enters its lane reports when it ends")
}

/// One run's lane, the group of one it runs in: the stepper, the state it steps, what it tracks and its observer, with the
/// output states formed so far and how the run stopped inside a stretch.
struct RunLane<'a, S, M, O, T>
where
    S: MechanicalSystem,
    M: ?Sized,
    DefaultAllocator: Allocator<S::Dim>,
{
    sys: &'a S,
    stepper: &'a mut M,
    z: &'a mut State<S::Dim>,
    observer: &'a mut O,
    track: T,
    h: f64,
    check_every: u64,
    /// Steps taken.
    step: u64,
    /// Whether the observer sees every step.
    watch: bool,
    /// Whether a watched run's output states are formed only near a surface (see
    /// [`Observer::step_is_clear`]).
    lazy: bool,
    /// The run's next sample, or its end: a watched step there is not skipped, since it is
    /// sampled.
    due_at: u64,
    /// The output state last formed.
    processed: State<S::Dim>,
    /// The kernel state of the last step whose output state was not formed, and that step.
    skipped: State<S::Dim>,
    skipped_at: Option<u64>,
    /// The step whose output state this stretch formed for the watch, and whether it is
    /// `processed` (else the kernel state itself).
    formed_at: Option<(u64, bool)>,
    /// Why the run stopped inside the last stretch.
    stop: Option<RunEnd>,
    failure: Option<CoreError>,
}

impl<S, M, O, T> RunLane<'_, S, M, O, T>
where
    S: MechanicalSystem,
    M: Stepper<S> + ?Sized,
    O: Observer<S::Dim>,
    T: Track<S>,
    DefaultAllocator: Allocator<S::Dim>,
{
    /// The error of a step that failed, counted from 0; a failing processor is charged to the
    /// step it is applied with (the first, or the one that ends at the output).
    fn step_error(&self, step: u64, source: StepError) -> CoreError {
        CoreError::Step {
            field: None,
            run: None,
            step: step + 1,
            t: step as f64 * self.h,
            source,
        }
    }

    /// The output state of the current step into `processed`; whether it is there (else the
    /// kernel state is the output).
    fn form_output(&mut self) -> Result<bool, CoreError> {
        let (sys, h, step) = (self.sys, self.h, self.step);
        self.stepper
            .post_process(sys, self.z, h, &mut self.processed)
            .map_err(|e| self.step_error(step.saturating_sub(1), e))
    }

    /// The run's report once it stopped (`stop`): the output state, not the kernel's, left to
    /// the caller (it is `processed` if the last sample's was, at `processed_at`), and the
    /// statistics.
    fn finish(&mut self, stop: RunEnd, processed_at: Option<u64>, started: Instant) -> AloneReport {
        let step = self.step;
        if step > 0
            && !matches!(stop, RunEnd::Diverged { .. })
            && (processed_at == Some(step) || self.form_output()?)
        {
            self.z.clone_from(&self.processed);
        }
        let stats = RunStats {
            steps: step,
            force_evaluations: self.stepper.force_evaluations(),
            wall_time_ms: started.elapsed().as_secs_f64() * 1e3,
        };
        Ok((stop, stats))
    }

    /// Ends the run inside the stretch with `failure`.
    #[cold]
    fn fail(&mut self, failure: CoreError) -> ControlFlow<()> {
        self.failure = Some(failure);
        ControlFlow::Break(())
    }

    /// The watch of the step just taken: a step clear of every surface is skipped (its kernel
    /// state kept, its output state formed only if the next step is not clear), any other one's
    /// output state is formed and shown. `Break` when the watch ended the run there (an event,
    /// in `stop`, where it replaces a threshold passed at the same step) or a processor failed
    /// (in `failure`).
    #[inline(always)]
    fn watch_step(&mut self, due: bool) -> ControlFlow<()> {
        let (step, t) = (self.step, self.step as f64 * self.h);
        // The observer is asked after every step of a lazy run, due or not.
        if self.lazy && self.observer.step_is_clear(t, self.z) && !due {
            self.skipped.clone_from(self.z);
            self.skipped_at = Some(step);
            return ControlFlow::Continue(());
        }
        let mut event = false;
        if let Some(at) = self.skipped_at.take() {
            let (sys, h) = (self.sys, self.h);
            if let Err(e) = self
                .stepper
                .post_process(sys, &self.skipped, h, &mut self.processed)
            {
                return self.fail(self.step_error(at.saturating_sub(1), e));
            }
            if let ControlFlow::Break(t) =
                self.observer.on_clear_step(at as f64 * h, &self.processed)
            {
                self.stop = Some(RunEnd::Event { step, t });
                event = true;
            }
        }
        let is_processed = match self.form_output() {
            Ok(is_processed) => is_processed,
            Err(failure) => return self.fail(failure),
        };
        self.formed_at = Some((step, is_processed));
        if !event {
            let output = if is_processed {
                &self.processed
            } else {
                &*self.z
            };
            if let ControlFlow::Break(t) = self.observer.on_step(step, t, output) {
                self.stop = Some(RunEnd::Event { step, t });
                event = true;
            }
        }
        if event {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }

    /// Up to `n` steps, one at a time when watched; `Break` at a failure (in `failure`), or
    /// where the run stops (in `stop`): the stepper's own deadline, a non-finite state, a
    /// threshold of the indicators or an event.
    #[inline]
    fn stretch(&mut self, n: u64) -> ControlFlow<()> {
        // Processing starts with the run: a run the budget stopped before its first step
        // leaves the caller's state as it was.
        if self.step == 0 {
            let (sys, h) = (self.sys, self.h);
            if let Err(e) = self.stepper.pre_process(sys, self.z, h) {
                return self.fail(self.step_error(0, e));
            }
        }
        let until = self.step + n;
        self.formed_at = None;
        while self.step < until {
            let to = if self.watch { self.step + 1 } else { until };
            let stepped = self.track.stretch(
                self.sys,
                self.stepper,
                self.z,
                self.h,
                &mut self.step,
                to,
                self.observer,
            );
            let stop = match stepped {
                Ok(stop) => stop,
                Err((at, e)) => return self.fail(self.step_error(at, e)),
            };
            if let Some(RunEnd::TimeLimit { .. }) = stop {
                self.stop = stop;
                return ControlFlow::Break(());
            }
            if !self.z.is_finite() {
                let (step, t) = (self.step, self.step as f64 * self.h);
                self.stop = Some(RunEnd::Diverged { step, t });
                return ControlFlow::Break(());
            }
            // A chaos indicator past its threshold ends the run with a last sample (an event
            // at the same step takes its place).
            self.stop = stop;
            if self.watch {
                let due = self.step == self.due_at || self.stop.is_some();
                self.watch_step(due)?;
            }
            if self.stop.is_some() {
                return ControlFlow::Break(());
            }
        }
        ControlFlow::Continue(())
    }
}

impl<S, M, O, T> LaneGroup<1> for RunLane<'_, S, M, O, T>
where
    S: MechanicalSystem,
    M: Stepper<S> + ?Sized,
    O: Observer<S::Dim>,
    T: Track<S>,
    DefaultAllocator: Allocator<S::Dim>,
{
    fn check_every(&self) -> u64 {
        self.check_every
    }

    #[inline]
    fn advance(&mut self, n: u64, _running: &[bool; 1]) -> LaneStretch<1> {
        let from = self.step;
        let ended = self.stretch(n).is_break();
        let steps = self.step - from;
        let ended = ended.then(|| LaneEnd {
            steps,
            force_evaluations: self.stepper.force_evaluations(),
            diverged: matches!(self.stop, Some(RunEnd::Diverged { .. })),
        });
        LaneStretch {
            steps,
            ended: [ended],
        }
    }
}

/// The run in a [`RunLane`]: its samples (step 0, every `every`-th step, the last) and its end.
struct AloneRun {
    schedule: Schedule,
    /// The next sample's step.
    sample_at: u64,
    /// The step of the last sample whose output state is the lane's `processed`.
    processed_at: Option<u64>,
    deadline: Option<Instant>,
    started: Instant,
}

impl AloneRun {
    /// The next sample, or the end.
    #[inline]
    fn next_look_at(&self) -> u64 {
        self.sample_at.min(self.schedule.steps)
    }
}

impl<S, M, O, T> LaneRun<RunLane<'_, S, M, O, T>, 1> for AloneRun
where
    S: MechanicalSystem,
    M: Stepper<S> + ?Sized,
    O: Observer<S::Dim>,
    T: Track<S>,
    DefaultAllocator: Allocator<S::Dim>,
{
    type Report = AloneReport;

    fn enter(&mut self, lane: &mut RunLane<'_, S, M, O, T>, _: usize) -> ControlFlow<AloneReport> {
        lane.track.report(lane.observer, 0);
        lane.observer.on_sample(0, 0.0, lane.z);
        // The budget's deadline, for a stepper whose single step can take long.
        lane.stepper.set_deadline(self.deadline);
        if self.schedule.steps == 0 {
            return ControlFlow::Break(lane.finish(
                RunEnd::Finished,
                self.processed_at,
                self.started,
            ));
        }
        lane.due_at = self.next_look_at();
        ControlFlow::Continue(())
    }

    #[inline]
    fn next_look(&self, _step: u64) -> u64 {
        self.next_look_at()
    }

    #[inline]
    fn look(
        &mut self,
        lane: &mut RunLane<'_, S, M, O, T>,
        _: usize,
        step: u64,
        _end: Option<LaneEnd>,
    ) -> ControlFlow<AloneReport> {
        if let Some(failure) = lane.failure.take() {
            return ControlFlow::Break(Err(failure));
        }
        let stop = lane.stop.take();
        if let Some(stop @ (RunEnd::TimeLimit { .. } | RunEnd::Diverged { .. })) = stop {
            return ControlFlow::Break(lane.finish(stop, self.processed_at, self.started));
        }
        let sampled = step == self.sample_at;
        if sampled {
            self.sample_at = self.sample_at.saturating_add(self.schedule.every.max(1));
        }
        if sampled || step == self.schedule.steps || stop.is_some() {
            // The output state the watch formed at this step, or formed now.
            let is_processed = match lane.formed_at {
                Some((at, is_processed)) if at == step => is_processed,
                _ => match lane.form_output() {
                    Ok(is_processed) => is_processed,
                    Err(failure) => return ControlFlow::Break(Err(failure)),
                },
            };
            lane.track.report(lane.observer, step);
            if is_processed {
                self.processed_at = Some(step);
            }
            let output = if is_processed {
                &lane.processed
            } else {
                &*lane.z
            };
            lane.observer.on_sample(step, step as f64 * lane.h, output);
        }
        if stop.is_some() || step == self.schedule.steps {
            return ControlFlow::Break(lane.finish(
                stop.unwrap_or(RunEnd::Finished),
                self.processed_at,
                self.started,
            ));
        }
        lane.due_at = self.next_look_at();
        ControlFlow::Continue(())
    }

    fn stopped(
        &mut self,
        lane: &mut RunLane<'_, S, M, O, T>,
        _: usize,
        _: u64,
        stop: RunEnd,
    ) -> AloneReport {
        lane.finish(stop, self.processed_at, self.started)
    }
}

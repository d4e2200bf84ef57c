//! Running: advances a stepper over a run's steps, hands samples to an observer, and stops on
//! the end, a non-finite state, cancellation or a deadline. It knows nothing of any particular
//! method, and observers know nothing of integrators. One run alone and runs side by side in
//! SIMD lanes go through the one run loop of [`driver`], one run as a lane of its own.
//!
//! A run of step h to t_end has n = ceil(t_end/h − 1e-9) steps, all of size h; sample times are
//! t_k = k·h computed from the step index (never accumulated), so the same inputs give
//! bit-identical output. Samples are taken at step 0, every `every`-th step and the last step.
//!
//! An observer that watches every step ([`Observer::watches_steps`]: Poincaré sections, events)
//! is shown the state after each step, and may end the run there ([`RunEnd::Event`]); the
//! steps are then taken one at a time instead of in stretches, which changes nothing but the
//! fusion of a splitting's last flow with the next step's first (round-off, as sampling more
//! often does).

use std::ops::ControlFlow;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;
use serde::Serialize;

use super::chaos::{IndicatorValues, ThresholdCrossing, Tracker};
use super::error::{CoreError, StepError};
use super::system::{MechanicalSystem, State};
use super::tangent::Tangent;

mod alone;
pub mod driver;
mod track;
use alone::drive_alone;
use track::{Tangents, Untracked};

/// A one-step method for systems of type `S`. Explicit implementations keep their work buffers,
/// so a step allocates nothing. A stepper may keep the last force evaluation for the next step
/// (the end of one step is the start of the next), so `step` must be given the state its previous
/// call produced; start a new stepper, or [`restart`](Stepper::restart) it, for an unrelated state.
pub trait Stepper<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// Advances `z` by one step of size `h`.
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError>;

    /// Advances `z` by up to `n` steps of size `h` with nothing observed in between, stopping
    /// early after a step that leaves a non-finite state or at a step that fails. Returns the
    /// number of steps completed and, if one failed, its error (the state is then the one before
    /// that step). The default is the loop of [`Stepper::step`]; it is one call per stretch
    /// between samples, so a stepper chosen at run time ([`AnyStepper`]) dispatches once per
    /// stretch and the loop around a concrete `step` compiles to straight-line code.
    ///
    /// [`AnyStepper`]: crate::methods::AnyStepper
    #[inline]
    fn advance(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, n: u64) -> Advanced {
        step_by_step(self, sys, z, h, n)
    }

    /// Gradient (∇V or ∂H/∂q) evaluations so far.
    fn force_evaluations(&self) -> u64;

    /// How many steps may pass between two looks at the cancellation flag and the clock: many
    /// for cheap explicit steps (the lanes' interval, where their stretches are cut too, so
    /// that a run's fused seams fall where the lanes' do), one for steps that may take long
    /// (Newton, adaptive).
    fn check_interval(&self) -> u64 {
        driver::CHECK_EVERY
    }

    /// The deadline, for a stepper whose single step can take long (the adaptive reference):
    /// it then gives up inside a step with [`StepError::DeadlinePassed`], leaving the state as it
    /// was before that step. The driver sets it before the first step; the default ignores it.
    fn set_deadline(&mut self, _deadline: Option<Instant>) {}

    /// Forgets what the stepper carries from one step to the next (the force at the last
    /// position), so that its next step may start from an unrelated state. The default has
    /// nothing to forget.
    fn restart(&mut self) {}

    /// Processing (a method Φ = χ⁻¹ ∘ K ∘ χ whose kernel K is what `step` does): maps the
    /// caller's state to the kernel's, z ← χ(z). The driver calls it once, before the first step.
    /// The default does nothing. A processor that fails (a Newton solve inside it) leaves `z`
    /// as it was.
    fn pre_process(&mut self, _sys: &S, _z: &mut State<S::Dim>, _h: f64) -> Result<(), StepError> {
        Ok(())
    }

    /// Processing: writes the output state χ⁻¹(z) for the kernel state `z` into `out` and returns
    /// true; returns false (leaving `out` alone) when `z` itself is the output, as it is for every
    /// method without processing (the default). The driver calls it at the samples after step 0
    /// and at the end; it must leave the state `step` continues from (caches included) unchanged.
    fn post_process(
        &mut self,
        _sys: &S,
        _z: &State<S::Dim>,
        _h: f64,
        _out: &mut State<S::Dim>,
    ) -> Result<bool, StepError> {
        Ok(false)
    }

    /// Whether [`post_process`](Self::post_process) may be given any kernel state the run has
    /// passed through, not only the current one: true when the output map depends on nothing
    /// the steps carry. A watched run then forms output states only near a surface (see
    /// [`Observer::step_is_clear`]). The default, false, suits methods without processing.
    fn processes_any_state(&self) -> bool {
        false
    }

    /// Advances `z` by one step and multiplies `tangent.jac` by the step's Jacobian ∂Φ/∂z.
    fn step_tangent(
        &mut self,
        _sys: &S,
        _z: &mut State<S::Dim>,
        _h: f64,
        _tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        Err(StepError::TangentUnsupported {
            reason: "this method has no tangent map",
        })
    }
}

impl<S: MechanicalSystem, T: Stepper<S> + ?Sized> Stepper<S> for Box<T>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        (**self).step(sys, z, h)
    }
    #[inline]
    fn advance(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64, n: u64) -> Advanced {
        (**self).advance(sys, z, h, n)
    }
    fn force_evaluations(&self) -> u64 {
        (**self).force_evaluations()
    }
    fn check_interval(&self) -> u64 {
        (**self).check_interval()
    }
    fn set_deadline(&mut self, deadline: Option<Instant>) {
        (**self).set_deadline(deadline)
    }
    fn restart(&mut self) {
        (**self).restart()
    }
    fn pre_process(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        (**self).pre_process(sys, z, h)
    }
    fn post_process(
        &mut self,
        sys: &S,
        z: &State<S::Dim>,
        h: f64,
        out: &mut State<S::Dim>,
    ) -> Result<bool, StepError> {
        (**self).post_process(sys, z, h, out)
    }
    fn processes_any_state(&self) -> bool {
        (**self).processes_any_state()
    }
    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent<S::Dim>,
    ) -> Result<(), StepError> {
        (**self).step_tangent(sys, z, h, tangent)
    }
}

/// What [`Stepper::advance`] returns: the steps completed and, if a step failed, its error.
pub type Advanced = (u64, Result<(), StepError>);

/// [`Stepper::advance`] as `n` calls of [`Stepper::step`]: stops after the first step that
/// leaves a non-finite state, or at a failed step.
#[inline(always)]
pub fn step_by_step<S, M>(
    stepper: &mut M,
    sys: &S,
    z: &mut State<S::Dim>,
    h: f64,
    n: u64,
) -> Advanced
where
    S: MechanicalSystem,
    M: Stepper<S> + ?Sized,
    DefaultAllocator: Allocator<S::Dim>,
{
    for done in 0..n {
        if let Err(e) = stepper.step(sys, z, h) {
            return (done, Err(e));
        }
        if !finite(z) {
            return (done + 1, Ok(()));
        }
    }
    (n, Ok(()))
}

/// Whether every component of `z` is finite: one sum is finite iff every component is (overflow
/// aside, which is divergence too), and it is cheaper than testing each component.
#[inline(always)]
pub fn finite<D: nalgebra::Dim>(z: &State<D>) -> bool
where
    DefaultAllocator: Allocator<D>,
{
    (z.q.sum() + z.p.sum()).is_finite()
}

/// The number of steps for a run of step `h` to `t_end`: ceil(t_end/h − 1e-9).
pub fn step_count(h: f64, t_end: f64) -> u64 {
    (t_end / h - 1e-9).ceil().max(0.0) as u64
}

/// Fixed-step schedule of a run.
#[derive(Clone, Copy, Debug)]
pub struct Schedule {
    /// Step size.
    pub h: f64,
    /// Number of steps.
    pub steps: u64,
    /// Sample every this many steps (≥ 1); the last step is always sampled.
    pub every: u64,
}

impl Schedule {
    /// The schedule for step `h` to `t_end`, sampling every `every` steps.
    pub fn new(h: f64, t_end: f64, every: u64) -> Self {
        Self {
            h,
            steps: step_count(h, t_end),
            every: every.max(1),
        }
    }

    /// Number of samples the run produces if it finishes.
    pub fn samples(&self) -> u64 {
        let regular = self.steps / self.every + 1;
        if self.steps % self.every == 0 {
            regular
        } else {
            regular + 1
        }
    }
}

/// Limits checked inside the loop: blocking work cannot be aborted from outside.
#[derive(Clone, Copy, Debug, Default)]
pub struct Budget<'a> {
    /// Set to stop the run (a client went away).
    pub cancel: Option<&'a AtomicBool>,
    /// Stop when this instant passes.
    pub deadline: Option<Instant>,
}

impl Budget<'_> {
    /// Whether the cancellation flag is set.
    pub fn cancelled(&self) -> bool {
        self.cancel
            .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    }

    /// Whether the deadline has passed.
    pub fn expired(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}

/// How a run ended: all its steps, or where and why it stopped early (the simulation
/// document's `Stop` adds a failed run).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "reason")]
pub enum RunEnd {
    /// All steps were taken.
    Finished,
    /// The state became non-finite at this step (its samples end just before).
    Diverged {
        /// The first step whose result is non-finite.
        step: u64,
        /// Its time.
        t: f64,
    },
    /// The cancellation flag was set.
    Cancelled {
        /// Steps completed.
        step: u64,
    },
    /// The deadline passed.
    TimeLimit {
        /// Steps completed.
        step: u64,
    },
    /// An observer of every step ended the run (an event: the n-th crossing of a surface).
    Event {
        /// The step after which it ended (the first step past the event).
        step: u64,
        /// The time of the event itself, between that step's start and end.
        t: f64,
    },
    /// A chaos indicator reached the threshold the request set (`stop_when`).
    Indicator(ThresholdCrossing),
}

impl RunEnd {
    /// Whether the budget stopped the run (cancelled, or at the time limit).
    pub fn by_budget(&self) -> bool {
        matches!(self, RunEnd::Cancelled { .. } | RunEnd::TimeLimit { .. })
    }
}

/// Run statistics, shared by every output format.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = Stats))]
pub struct RunStats {
    /// Steps taken.
    pub steps: u64,
    /// Gradient evaluations (∇V or ∂H/∂q).
    pub force_evaluations: u64,
    /// Wall time of the integration loop in milliseconds.
    pub wall_time_ms: f64,
}

/// Receives the run's samples as they are produced.
pub trait Observer<D: nalgebra::Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// A sample at `step`, time `t`.
    fn on_sample(&mut self, step: u64, t: f64, z: &State<D>);

    /// The Jacobian determinant of the step that ended at `step` (only when asked for).
    fn on_step_determinant(&mut self, _step: u64, _det: f64) {}

    /// Whether [`on_step`](Self::on_step) is to see every step (the driver then steps one at a
    /// time). The default sees only samples.
    fn watches_steps(&self) -> bool {
        false
    }

    /// The state after `step`, at time `t` (for a processing method, its output state), when
    /// the observer [watches steps](Self::watches_steps). `Break(t_event)` ends the run after
    /// this step with [`RunEnd::Event`]; the step is then sampled.
    fn on_step(&mut self, _step: u64, _t: f64, _z: &State<D>) -> ControlFlow<f64> {
        ControlFlow::Continue(())
    }

    /// For a method whose output map may be applied late
    /// ([`Stepper::processes_any_state`]): whether the step that ended at the kernel state `z`
    /// (time `t`) crossed no watched surface, judged from the kernel states alone. The driver
    /// then forms no output state for it and skips [`on_step`](Self::on_step); it is asked
    /// after every such step. The default, false, sees every output state.
    fn step_is_clear(&mut self, _t: f64, _z: &State<D>) -> bool {
        false
    }

    /// The output state `z` at time `t` of the last step that was [clear](Self::step_is_clear),
    /// formed because the step after it is not: watched from the last output state seen, like
    /// [`on_step`](Self::on_step) (`Break(t_event)` ends the run after the step being taken).
    fn on_clear_step(&mut self, _t: f64, _z: &State<D>) -> ControlFlow<f64> {
        ControlFlow::Continue(())
    }

    /// The chaos indicators at the sample that follows (only when asked for).
    fn on_indicators(&mut self, _values: &IndicatorValues) {}
}

/// What a run propagates besides the state.
pub enum Tracking<'a, D: nalgebra::Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// Nothing.
    Off,
    /// Each step's Jacobian, whose determinant goes to the observer.
    Determinant,
    /// Deviation vectors and the chaos indicators, which go to the observer before each sample.
    Chaos(&'a mut Tracker<D>),
}

/// Runs `stepper` from `z` over `schedule`, reporting samples to `observer`, with no tangent
/// dynamics. See [`integrate_tracked`].
pub fn integrate<S, M, O>(
    sys: &S,
    stepper: &mut M,
    z: &mut State<S::Dim>,
    schedule: Schedule,
    budget: Budget<'_>,
    observer: &mut O,
) -> Result<(RunEnd, RunStats), CoreError>
where
    S: MechanicalSystem,
    M: Stepper<S> + ?Sized,
    O: Observer<S::Dim>,
    DefaultAllocator: Allocator<S::Dim>,
{
    drive_alone(sys, stepper, z, schedule, budget, Untracked, observer)
}

/// Runs `stepper` from `z` over `schedule`, reporting samples to `observer`, with the tangent
/// dynamics `tracking` asks for: none, each step's Jacobian (its determinant reported per
/// step), or deviation vectors with their chaos indicators (reported before each sample; a
/// threshold passed stops the run there, with a last sample).
///
/// For a processing method (see [`Stepper::pre_process`]) the sample at step 0 is the caller's
/// state as given, `z` is pre-processed once before the first step, the later samples are
/// post-processed kernel states, and on return `z` holds the post-processed final state (the
/// kernel state if the run diverged). Methods without processing see none of this: their loop is
/// the same. Tangent dynamics follow the kernel.
///
/// Each stepper type this is called with compiles the driver twice, with and without tangents:
/// callers that track run it with the enum of all steppers ([`AnyStepper`]), one copy per system,
/// and keep the per-method copies for [`integrate`] (the tangent steps cost far more than the
/// dispatch; the plain and watched stretches do not).
///
/// [`AnyStepper`]: crate::methods::AnyStepper
pub fn integrate_tracked<S, M, O>(
    sys: &S,
    stepper: &mut M,
    z: &mut State<S::Dim>,
    schedule: Schedule,
    budget: Budget<'_>,
    tracking: Tracking<'_, S::Dim>,
    observer: &mut O,
) -> Result<(RunEnd, RunStats), CoreError>
where
    S: MechanicalSystem,
    M: Stepper<S> + ?Sized,
    O: Observer<S::Dim>,
    DefaultAllocator: Allocator<S::Dim>,
{
    match tracking {
        Tracking::Off => drive_alone(sys, stepper, z, schedule, budget, Untracked, observer),
        tracking => {
            let jacobian = matches!(tracking, Tracking::Determinant).then(|| Tangent::new(sys, z));
            let tangents = Tangents { tracking, jacobian };
            drive_alone(sys, stepper, z, schedule, budget, tangents, observer)
        }
    }
}

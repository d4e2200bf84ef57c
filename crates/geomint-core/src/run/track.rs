//! How the run driver takes its stretches of steps: alone ([`Untracked`]) or with their tangent
//! maps ([`Tangents`]), each a type of its own so that a run without tangents compiles none of
//! their code.

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use super::{finite, Observer, RunEnd, Stepper, Tracking};
use crate::chaos::ThresholdCrossing;
use crate::error::StepError;
use crate::system::{MechanicalSystem, State};
use crate::tangent::Tangent;

/// How the driver takes its stretches of steps: with or without tangent dynamics. A type of its
/// own for each, so that a run without tangents compiles none of their code.
pub(super) trait Track<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// Steps between two looks at the budget.
    fn check_every<M: Stepper<S> + ?Sized>(&self, stepper: &M) -> u64;

    /// Reports what goes with the sample at `step` (the chaos indicators) to `observer`.
    fn report<O: Observer<S::Dim>>(&mut self, _observer: &mut O, _step: u64) {}

    /// Steps `z` from `*step` until `until`, counting in `*step`; stops early on a non-finite
    /// state or a reason of its own, which it returns. A failed step is returned with the count
    /// of steps before it.
    #[allow(clippy::too_many_arguments)]
    fn stretch<M: Stepper<S> + ?Sized, O: Observer<S::Dim>>(
        &mut self,
        sys: &S,
        stepper: &mut M,
        z: &mut State<S::Dim>,
        h: f64,
        step: &mut u64,
        until: u64,
        observer: &mut O,
    ) -> Result<Option<RunEnd>, (u64, StepError)>;
}

/// Steps alone: the stepper's own [`advance`](Stepper::advance) over each stretch.
pub(super) struct Untracked;

impl<S: MechanicalSystem> Track<S> for Untracked
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn check_every<M: Stepper<S> + ?Sized>(&self, stepper: &M) -> u64 {
        stepper.check_interval().max(1)
    }

    fn stretch<M: Stepper<S> + ?Sized, O: Observer<S::Dim>>(
        &mut self,
        sys: &S,
        stepper: &mut M,
        z: &mut State<S::Dim>,
        h: f64,
        step: &mut u64,
        until: u64,
        _observer: &mut O,
    ) -> Result<Option<RunEnd>, (u64, StepError)> {
        let (done, outcome) = stepper.advance(sys, z, h, until - *step);
        *step += done;
        match outcome {
            Ok(()) => Ok(None),
            Err(StepError::DeadlinePassed) => Ok(Some(RunEnd::TimeLimit { step: *step })),
            Err(e) => Err((*step, e)),
        }
    }
}

/// Steps with their tangent maps: each step's Jacobian (`jacobian`, for
/// [`Tracking::Determinant`]) or the chaos tracker's deviation vectors.
pub(super) struct Tangents<'a, D: nalgebra::Dim>
where
    DefaultAllocator: Allocator<D>,
{
    pub(super) tracking: Tracking<'a, D>,
    pub(super) jacobian: Option<Tangent<D>>,
}

impl<S: MechanicalSystem> Track<S> for Tangents<'_, S::Dim>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn check_every<M: Stepper<S> + ?Sized>(&self, stepper: &M) -> u64 {
        // Jacobian propagation costs O(n³) per step: look at the budget every step then.
        match self.tracking {
            Tracking::Determinant => 1,
            _ => stepper.check_interval().max(1),
        }
    }

    fn report<O: Observer<S::Dim>>(&mut self, observer: &mut O, step: u64) {
        if let Tracking::Chaos(tracker) = &mut self.tracking {
            observer.on_indicators(&tracker.peek(step));
        }
    }

    fn stretch<M: Stepper<S> + ?Sized, O: Observer<S::Dim>>(
        &mut self,
        sys: &S,
        stepper: &mut M,
        z: &mut State<S::Dim>,
        h: f64,
        step: &mut u64,
        until: u64,
        observer: &mut O,
    ) -> Result<Option<RunEnd>, (u64, StepError)> {
        match (&mut self.tracking, self.jacobian.as_mut()) {
            (Tracking::Determinant, Some(tg)) => {
                while *step < until {
                    tg.reset();
                    stepper
                        .step_tangent(sys, z, h, tg)
                        .map_err(|e| (*step, e))?;
                    *step += 1;
                    observer.on_step_determinant(*step, tg.jac.determinant());
                    if !z.is_finite() {
                        break;
                    }
                }
                Ok(None)
            }
            (Tracking::Chaos(tracker), _) => {
                while *step < until {
                    stepper
                        .step_tangent(sys, z, h, &mut tracker.tangent)
                        .map_err(|e| (*step, e))?;
                    *step += 1;
                    if !finite(z) {
                        break;
                    }
                    if let Some((indicator, value, threshold)) = tracker.after_step(*step) {
                        return Ok(Some(RunEnd::Indicator(ThresholdCrossing {
                            step: *step,
                            t: *step as f64 * h,
                            indicator,
                            value,
                            threshold,
                        })));
                    }
                }
                Ok(None)
            }
            _ => Untracked.stretch(sys, stepper, z, h, step, until, observer),
        }
    }
}

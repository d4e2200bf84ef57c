//! [`StepError`]: a failure inside one step.

use thiserror::Error;

/// A failure inside one step.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum StepError {
    /// Newton's method did not converge in an implicit step.
    #[error("Newton iteration did not converge in {iterations} iterations (last correction {residual:e})")]
    NewtonFailed {
        /// Iterations made.
        iterations: usize,
        /// Norm of the last Newton correction.
        residual: f64,
    },
    /// The adaptive reference integrator failed (step size underflow, too many steps).
    #[error("adaptive integrator failed: {message}")]
    AdaptiveFailed {
        /// The integrator's own message.
        message: String,
    },
    /// The deadline passed inside a step (the adaptive reference looks at it between its inner
    /// steps); the state is left as it was before the step.
    #[error("the deadline passed inside a step")]
    DeadlinePassed,
    /// The method has no tangent map for this system.
    #[error("the step Jacobian is not available for this method and system: {reason}")]
    TangentUnsupported {
        /// Why.
        reason: &'static str,
    },
}

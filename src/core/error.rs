//! Typed errors of the integrator core. Every error carries the numbers that explain it and, where
//! it comes from user input, the name of the offending field.

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
    /// The method has no tangent map for this system.
    #[error("the step Jacobian is not available for this method and system: {reason}")]
    TangentUnsupported {
        /// Why.
        reason: &'static str,
    },
}

/// Why a request to the core cannot be carried out. `field` names the input at fault.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum CoreError {
    /// The input is malformed or out of range.
    #[error("{field}: {message}")]
    Invalid {
        /// The offending input field, e.g. `h` or `params.omega`.
        field: String,
        /// What is wrong with it.
        message: String,
    },
    /// An unknown system id.
    #[error("unknown system `{id}`")]
    UnknownSystem {
        /// The id asked for.
        id: String,
    },
    /// A method the system does not qualify for.
    #[error("method `{method}` cannot run on `{system}`: it requires {requirement}")]
    Unmet {
        /// The method id.
        method: String,
        /// The system id.
        system: String,
        /// The unmet requirement, in words.
        requirement: String,
    },
    /// A step failed (Newton did not converge, …).
    #[error("step {step} (t = {t}): {source}")]
    Step {
        /// The step that failed, counted from 1.
        step: u64,
        /// The time at the start of that step.
        t: f64,
        /// What went wrong.
        source: StepError,
    },
}

impl CoreError {
    /// An `Invalid` error for `field`.
    pub fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        CoreError::Invalid {
            field: field.into(),
            message: message.into(),
        }
    }

    /// The input field the error concerns, if any.
    pub fn field(&self) -> Option<&str> {
        match self {
            CoreError::Invalid { field, .. } => Some(field),
            CoreError::UnknownSystem { .. } => Some("system"),
            CoreError::Unmet { .. } => Some("methods"),
            CoreError::Step { .. } => None,
        }
    }
}

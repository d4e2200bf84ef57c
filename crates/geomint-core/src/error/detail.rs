//! The error codes, and the error shape every interface reports (`{"code", "message",
//! "field"}`), made from a core error by its variant.

use std::fmt;

use serde::Serialize;

use super::CoreError;

/// The machine-readable kind of an error, as `error.code` carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum ErrorCode {
    /// The body is not valid JSON (syntax, truncation, a number beyond the range of f64).
    MalformedJson,
    /// The body exceeds the size limit.
    PayloadTooLarge,
    /// The body is not declared as JSON.
    UnsupportedMediaType,
    /// A field the request type does not have.
    UnknownField,
    /// A required field is absent.
    MissingField,
    /// A field has the wrong JSON type.
    InvalidType,
    /// A value is out of range or inconsistent with the rest of the request.
    InvalidValue,
    /// An unknown system id.
    UnknownSystem,
    /// An unknown method id.
    UnknownMethod,
    /// A method whose structural requirements the system does not meet.
    UnmetRequirement,
    /// More steps per method (or per study) than the limit.
    TooManySteps,
    /// More samples in all than the limit.
    TooManySamples,
    /// More stability-map cells in all than the limit.
    TooManyCells,
    /// A step failed (an implicit solve did not converge, …).
    StepFailed,
    /// No route for the path.
    NotFound,
    /// The route exists, but not for this HTTP method.
    MethodNotAllowed,
    /// Every run slot is busy (or the work was cancelled); retry later.
    Overloaded,
    /// The request took longer than the server's time limit.
    Timeout,
    /// The body could not be read.
    BadRequest,
    /// A fault of the server (details are logged, not shown).
    Internal,
    /// A recording alone exceeds the recording store's size cap.
    RecordingTooLarge,
    /// An uploaded file is not a complete Rerun recording of a version the viewer reads.
    InvalidRecording,
    /// A stored recording is not of a simulation, so it has no samples to plot.
    NotASimulation,
    /// An expression of a user-defined system is wrong (`position` says where).
    InvalidExpression,
    /// The system store holds its cap of definitions.
    TooManySystems,
    /// A built-in system cannot be deleted.
    BuiltInSystem,
    /// The distributed executor (the NATS server that hands out a sweep's shards) failed.
    ExecutorUnavailable,
    /// The file system of the stored data is full: nothing was stored, what was stored before
    /// is intact; storing works again once space is freed.
    StorageFull,
    /// The stored data cannot be written (a read-only or removed data directory).
    StorageUnavailable,
    /// No credentials where the route needs them, or a bearer token that is not valid.
    Unauthorized,
    /// The token is valid but lacks the scope the route needs, or does not own what it would
    /// change.
    Forbidden,
    /// The request is beyond the caller's quota (a stored count or size, or a run larger than
    /// its rate allows at all); retrying does not help.
    QuotaExceeded,
    /// The caller's rate (steps per minute) is used up for now; retry after `Retry-After`.
    RateLimited,
    /// The caller has its quota of runs in flight; retry once one ends.
    TooManyRuns,
    /// A job's result was asked for before the job was done (it is queued or running, or it
    /// failed or was cancelled).
    JobNotDone,
}

impl ErrorCode {
    /// The code as it appears in `error.code`.
    pub fn as_str(self) -> &'static str {
        use ErrorCode::*;
        match self {
            MalformedJson => "malformed_json",
            PayloadTooLarge => "payload_too_large",
            UnsupportedMediaType => "unsupported_media_type",
            UnknownField => "unknown_field",
            MissingField => "missing_field",
            InvalidType => "invalid_type",
            InvalidValue => "invalid_value",
            UnknownSystem => "unknown_system",
            UnknownMethod => "unknown_method",
            UnmetRequirement => "unmet_requirement",
            TooManySteps => "too_many_steps",
            TooManySamples => "too_many_samples",
            TooManyCells => "too_many_cells",
            StepFailed => "step_failed",
            NotFound => "not_found",
            MethodNotAllowed => "method_not_allowed",
            Overloaded => "overloaded",
            Timeout => "timeout",
            BadRequest => "bad_request",
            Internal => "internal",
            RecordingTooLarge => "recording_too_large",
            InvalidRecording => "invalid_recording",
            NotASimulation => "not_a_simulation",
            InvalidExpression => "invalid_expression",
            TooManySystems => "too_many_systems",
            BuiltInSystem => "built_in_system",
            ExecutorUnavailable => "executor_unavailable",
            StorageFull => "storage_full",
            StorageUnavailable => "storage_unavailable",
            Unauthorized => "unauthorized",
            Forbidden => "forbidden",
            QuotaExceeded => "quota_exceeded",
            RateLimited => "rate_limited",
            TooManyRuns => "too_many_runs",
            JobNotDone => "job_not_done",
        }
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What went wrong, for machines (`code`, `field`) and people (`message`): the error shape every
/// interface reports (HTTP answers as `{"error": {...}}`, streams as an `error` line, the command
/// line as text).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ErrorDetail {
    /// Stable error code.
    pub code: ErrorCode,
    /// Explanation.
    #[cfg_attr(
        feature = "openapi",
        schema(example = "h: must be finite and > 0, got -0.1")
    )]
    pub message: String,
    /// The input at fault as a path (`h`, `params.omega`, `methods[1].inner`, `q0[2]`), when
    /// the error concerns one.
    #[cfg_attr(feature = "openapi", schema(example = "h"))]
    pub field: Option<String>,
    /// For an error in the text of an expression: the 0-based index of the character where it
    /// is (Unicode characters, not bytes; the text's length for "at the end").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub position: Option<usize>,
}

impl ErrorDetail {
    /// An error with a code and a message, concerning no particular field.
    pub fn new(code: ErrorCode, message: impl Into<String>) -> Self {
        Self {
            code,
            message: message.into(),
            field: None,
            position: None,
        }
    }

    /// An error concerning `field`.
    pub fn at(code: ErrorCode, field: impl fmt::Display, message: impl Into<String>) -> Self {
        Self {
            code,
            message: message.into(),
            field: Some(field.to_string()),
            position: None,
        }
    }
}

impl fmt::Display for ErrorDetail {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.field {
            Some(field) if !self.message.starts_with(field.as_str()) => {
                write!(f, "{} (field `{field}`, {})", self.message, self.code)
            }
            _ => write!(f, "{} ({})", self.message, self.code),
        }
    }
}

impl std::error::Error for ErrorDetail {}

impl CoreError {
    /// The error code of this error: chosen by its kind, never by its wording.
    pub fn code(&self) -> ErrorCode {
        use CoreError::*;
        match self {
            UnknownSystem { .. } => ErrorCode::UnknownSystem,
            UnknownMethod { .. } => ErrorCode::UnknownMethod,
            UnknownParameter { .. } => ErrorCode::UnknownField,
            Missing { .. } => ErrorCode::MissingField,
            Unmet { .. } | TimeDependent { .. } => ErrorCode::UnmetRequirement,
            TooManySteps { .. } => ErrorCode::TooManySteps,
            TooManySamples { .. } => ErrorCode::TooManySamples,
            TooManyCells { .. } => ErrorCode::TooManyCells,
            Step { .. } => ErrorCode::StepFailed,
            Cancelled { .. } => ErrorCode::Overloaded,
            TimeLimit { .. } => ErrorCode::Timeout,
            Executor { .. } => ErrorCode::ExecutorUnavailable,
            Expression { .. } => ErrorCode::InvalidExpression,
            _ => ErrorCode::InvalidValue,
        }
    }
}

impl From<&CoreError> for ErrorDetail {
    fn from(e: &CoreError) -> Self {
        ErrorDetail {
            code: e.code(),
            message: e.to_string(),
            field: e.field().map(|f| f.to_string()),
            position: match e {
                CoreError::Expression { error, .. } => error.position(),
                _ => None,
            },
        }
    }
}

impl From<CoreError> for ErrorDetail {
    fn from(e: CoreError) -> Self {
        ErrorDetail::from(&e)
    }
}

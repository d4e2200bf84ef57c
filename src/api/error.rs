//! The error shape every interface reports: a stable machine-readable `code`, a message for
//! people and the offending input `field` (a path such as `params.omega`, `methods[1].inner` or
//! `q0[2]`). HTTP answers carry it as `{"error": {...}}`, NDJSON streams as an `error` line, and
//! the command line prints it.

use serde::Serialize;
use utoipa::ToSchema;

use crate::core::error::CoreError;
use crate::core::run::step_count;
use crate::core::simulate::{Limits, Request};
use crate::core::systems;

/// Error codes, as they appear in `error.code`.
pub mod codes {
    /// The body is not valid JSON (syntax, truncation, a number beyond the range of f64).
    pub const MALFORMED_JSON: &str = "malformed_json";
    /// The body exceeds the size limit.
    pub const PAYLOAD_TOO_LARGE: &str = "payload_too_large";
    /// The body is not declared as JSON.
    pub const UNSUPPORTED_MEDIA_TYPE: &str = "unsupported_media_type";
    /// A field the request type does not have.
    pub const UNKNOWN_FIELD: &str = "unknown_field";
    /// A required field is absent.
    pub const MISSING_FIELD: &str = "missing_field";
    /// A field has the wrong JSON type.
    pub const INVALID_TYPE: &str = "invalid_type";
    /// A value is out of range or inconsistent with the rest of the request.
    pub const INVALID_VALUE: &str = "invalid_value";
    /// An unknown system id.
    pub const UNKNOWN_SYSTEM: &str = "unknown_system";
    /// An unknown method id.
    pub const UNKNOWN_METHOD: &str = "unknown_method";
    /// A method whose structural requirements the system does not meet.
    pub const UNMET_REQUIREMENT: &str = "unmet_requirement";
    /// More steps per method than the limit.
    pub const TOO_MANY_STEPS: &str = "too_many_steps";
    /// More samples in all than the limit.
    pub const TOO_MANY_SAMPLES: &str = "too_many_samples";
    /// More stability-map cells in all than the limit.
    pub const TOO_MANY_CELLS: &str = "too_many_cells";
    /// A step failed (an implicit solve did not converge, …).
    pub const STEP_FAILED: &str = "step_failed";
    /// No route for the path.
    pub const NOT_FOUND: &str = "not_found";
    /// The route exists, but not for this HTTP method.
    pub const METHOD_NOT_ALLOWED: &str = "method_not_allowed";
    /// Every run slot is busy; retry later.
    pub const OVERLOADED: &str = "overloaded";
    /// The request took longer than the server's time limit.
    pub const TIMEOUT: &str = "timeout";
    /// The body could not be read.
    pub const BAD_REQUEST: &str = "bad_request";
    /// A fault of the server (details are logged, not shown).
    pub const INTERNAL: &str = "internal";
    /// A recording alone exceeds the recording store's size cap.
    pub const RECORDING_TOO_LARGE: &str = "recording_too_large";
    /// An uploaded file is not a complete Rerun recording of a version the viewer reads.
    pub const INVALID_RECORDING: &str = "invalid_recording";
    /// A stored recording is not of a simulation, so it has no samples to plot.
    pub const NOT_A_SIMULATION: &str = "not_a_simulation";
}

/// What went wrong, for machines (`code`, `field`) and people (`message`).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct ErrorDetail {
    /// Stable error code, e.g. `unknown_system`.
    #[schema(example = "invalid_value")]
    pub code: String,
    /// Explanation.
    #[schema(example = "must be finite and > 0, got -0.1")]
    pub message: String,
    /// The input at fault as a path (`h`, `params.omega`, `methods[1].inner`, `q0[2]`), when
    /// the error concerns one.
    #[schema(example = "h")]
    pub field: Option<String>,
}

/// The body of every HTTP error response: `{"error": {"code", "message", "field"}}`.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct ErrorBody {
    /// The error.
    pub error: ErrorDetail,
}

impl ErrorDetail {
    /// An error with a code and a message, concerning no particular field.
    pub fn new(code: &str, message: impl Into<String>) -> Self {
        Self {
            code: code.to_string(),
            message: message.into(),
            field: None,
        }
    }

    /// An error concerning `field`.
    pub fn at(code: &str, field: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            code: code.to_string(),
            message: message.into(),
            field: Some(field.into()),
        }
    }

    /// Classifies an error of [`Simulation::prepare`](crate::core::simulate::Simulation::prepare)
    /// or of a run, given the request and limits it was checked against.
    pub fn from_core(error: &CoreError, req: &Request, limits: &Limits) -> Self {
        match error {
            CoreError::Invalid { field, message } => {
                let code = classify_invalid(field, req, limits);
                Self::at(code, field.clone(), format!("{field}: {message}"))
            }
            CoreError::UnknownSystem { id } => {
                let known: Vec<&str> = systems::catalog().iter().map(|s| s.id).collect();
                Self::at(
                    codes::UNKNOWN_SYSTEM,
                    "system",
                    format!("unknown system `{id}`; known: {}", known.join(", ")),
                )
            }
            CoreError::Unmet { method, .. } => {
                // Name the first method (by position) that carries this label.
                let index = req.methods.iter().enumerate().find_map(|(i, input)| {
                    crate::core::methods::MethodChoice::parse(input, "")
                        .ok()
                        .filter(|c| &c.label() == method)
                        .map(|_| i)
                });
                let field = match index {
                    Some(i) => format!("methods[{i}]"),
                    None => "methods".to_string(),
                };
                Self::at(codes::UNMET_REQUIREMENT, field, error.to_string())
            }
            CoreError::Step { .. } => Self::new(codes::STEP_FAILED, error.to_string()),
        }
    }

    /// A core error outside a simulation request (studies, maps): `{field}: {message}` for
    /// invalid input, with `unknown_method` recognised; an unmet requirement names `methods`.
    pub fn core(error: &CoreError) -> Self {
        match error {
            CoreError::Invalid { field, message } => {
                let code = if message.starts_with("unknown method") {
                    codes::UNKNOWN_METHOD
                } else {
                    codes::INVALID_VALUE
                };
                Self::at(code, field.clone(), format!("{field}: {message}"))
            }
            CoreError::Unmet { .. } => {
                Self::at(codes::UNMET_REQUIREMENT, "methods", error.to_string())
            }
            CoreError::Step { .. } => Self::new(codes::STEP_FAILED, error.to_string()),
            other => Self::new(codes::INTERNAL, other.to_string()),
        }
    }

    /// Renames a field path that starts with `methods[0]` to `method`, for requests that gave a
    /// single `method`.
    pub fn singular_method(mut self) -> Self {
        if let Some(field) = &self.field {
            if let Some(rest) = field.strip_prefix("methods[0]") {
                self.field = Some(format!("method{rest}"));
            } else if field == "methods" {
                self.field = Some("method".to_string());
            }
        }
        self
    }
}

impl std::fmt::Display for ErrorDetail {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.field {
            Some(field) if !self.message.starts_with(field.as_str()) => {
                write!(f, "{} (field `{field}`, {})", self.message, self.code)
            }
            _ => write!(f, "{} ({})", self.message, self.code),
        }
    }
}

impl std::error::Error for ErrorDetail {}

/// The code of a `CoreError::Invalid`, from the numbers rather than the wording.
fn classify_invalid(field: &str, req: &Request, limits: &Limits) -> &'static str {
    let valid_span = req.h.is_finite() && req.h > 0.0 && req.t_end.is_finite() && req.t_end > 0.0;
    if field == "t_end" && valid_span && step_count(req.h, req.t_end) > limits.max_steps {
        return codes::TOO_MANY_STEPS;
    }
    if field == "output.every" && req.every != Some(0) {
        return codes::TOO_MANY_SAMPLES;
    }
    if let Some(name) = field.strip_prefix("params.") {
        if let Ok(info) = systems::info(&req.system) {
            let alias = info.conformal_damping && name == "epsilon";
            if !alias && !info.params.iter().any(|p| p.name == name) {
                return codes::UNKNOWN_FIELD;
            }
        }
    }
    codes::INVALID_VALUE
}

//! The one error type of the service. Every failure — a rejected body, a bad field, an unknown
//! route, an overloaded server, a fault — becomes an [`ApiError`] and answers with its status and
//! `{"error": {"code", "message", "field"}}`. Details of server faults are logged, never sent.

use axum::body::Body;
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use crate::access::Refusal;
use crate::core::error::{CoreError, ErrorCode, ErrorDetail};

/// The body of every HTTP error response: `{"error": {"code", "message", "field"}}`.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct ErrorBody {
    /// The error.
    pub error: ErrorDetail,
}

/// The refusals every route that reads a JSON body shares, documented once: a malformed or
/// oversized body, one not declared as JSON, and a server fault. Routes list them beside their
/// own answers (`responses((status = 200, …), JsonRefusals, SlotsBusy)`).
#[derive(utoipa::IntoResponses)]
pub enum JsonRefusals {
    /// Malformed JSON.
    #[response(status = 400, description = "Malformed JSON (code `malformed_json`)")]
    Malformed(ErrorBody),
    /// Too large a body.
    #[response(status = 413, description = "The body exceeds 1 MiB")]
    TooLarge(ErrorBody),
    /// Not JSON.
    #[response(status = 415, description = "The body is not declared as JSON")]
    NotJson(ErrorBody),
    /// A fault.
    #[response(status = 500, description = "A server fault (details are logged)")]
    Fault(ErrorBody),
}

/// The refusal of work when every slot is taken, with its hint, documented once.
#[derive(utoipa::IntoResponses)]
pub enum SlotsBusy {
    /// Every slot is busy.
    #[response(status = 503, description = "Every simulation slot is busy",
        headers(("Retry-After" = u64, description = "Seconds to wait before retrying")))]
    Busy(ErrorBody),
}

/// An error answer: status, error detail and, for 429 and 503, a `Retry-After` hint.
#[derive(Clone, Debug, PartialEq)]
pub struct ApiError {
    status: StatusCode,
    detail: ErrorDetail,
    retry_after_secs: Option<u64>,
}

/// The HTTP status of an error code.
pub fn status_for(code: ErrorCode) -> StatusCode {
    match code {
        ErrorCode::MalformedJson | ErrorCode::BadRequest => StatusCode::BAD_REQUEST,
        ErrorCode::PayloadTooLarge => StatusCode::PAYLOAD_TOO_LARGE,
        ErrorCode::UnsupportedMediaType => StatusCode::UNSUPPORTED_MEDIA_TYPE,
        ErrorCode::NotFound => StatusCode::NOT_FOUND,
        ErrorCode::MethodNotAllowed => StatusCode::METHOD_NOT_ALLOWED,
        ErrorCode::Overloaded => StatusCode::SERVICE_UNAVAILABLE,
        ErrorCode::Timeout => StatusCode::GATEWAY_TIMEOUT,
        ErrorCode::Internal => StatusCode::INTERNAL_SERVER_ERROR,
        ErrorCode::StorageUnavailable => StatusCode::INTERNAL_SERVER_ERROR,
        ErrorCode::RecordingTooLarge | ErrorCode::TooManySystems | ErrorCode::StorageFull => {
            StatusCode::INSUFFICIENT_STORAGE
        }
        ErrorCode::BuiltInSystem | ErrorCode::JobNotDone => StatusCode::CONFLICT,
        ErrorCode::Unauthorized => StatusCode::UNAUTHORIZED,
        ErrorCode::Forbidden | ErrorCode::QuotaExceeded => StatusCode::FORBIDDEN,
        ErrorCode::RateLimited | ErrorCode::TooManyRuns => StatusCode::TOO_MANY_REQUESTS,
        ErrorCode::ExecutorUnavailable => StatusCode::BAD_GATEWAY,
        ErrorCode::UnknownField
        | ErrorCode::MissingField
        | ErrorCode::InvalidType
        | ErrorCode::InvalidValue
        | ErrorCode::UnknownSystem
        | ErrorCode::UnknownMethod
        | ErrorCode::UnmetRequirement
        | ErrorCode::TooManySteps
        | ErrorCode::TooManySamples
        | ErrorCode::TooManyCells
        | ErrorCode::StepFailed
        | ErrorCode::InvalidRecording
        | ErrorCode::NotASimulation
        | ErrorCode::InvalidExpression => StatusCode::UNPROCESSABLE_ENTITY,
    }
}

impl ApiError {
    /// An error with an explicit status.
    pub fn new(status: StatusCode, detail: ErrorDetail) -> Self {
        Self {
            status,
            detail,
            retry_after_secs: None,
        }
    }

    /// A server fault: `context` is logged, the client sees a generic message.
    pub fn internal(context: impl std::fmt::Display) -> Self {
        tracing::error!(error = %context, "internal error");
        Self::new(
            StatusCode::INTERNAL_SERVER_ERROR,
            ErrorDetail::new(
                ErrorCode::Internal,
                "internal server error; the details are in the server log",
            ),
        )
    }

    /// A failed write to the stored data (`what`: "recording store", …): 507 `storage_full` when
    /// the file system is full, 500 `storage_unavailable` when it cannot be written, else a
    /// plain internal error.
    pub fn storage(what: &str, error: &(dyn std::error::Error + 'static)) -> Self {
        let mut source = Some(error);
        while let Some(e) = source {
            if let Some(io) = e.downcast_ref::<std::io::Error>() {
                let (code, message) = match io.kind() {
                    std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded => (
                        ErrorCode::StorageFull,
                        format!("{what}: the disk is full; nothing was stored"),
                    ),
                    std::io::ErrorKind::ReadOnlyFilesystem
                    | std::io::ErrorKind::PermissionDenied
                    | std::io::ErrorKind::NotFound
                    | std::io::ErrorKind::NotADirectory => (
                        ErrorCode::StorageUnavailable,
                        format!(
                            "{what}: the data directory cannot be written ({})",
                            io.kind()
                        ),
                    ),
                    _ => {
                        source = e.source();
                        continue;
                    }
                };
                tracing::error!(error = %error, "{what}: write failed");
                return Self::from(ErrorDetail::new(code, message));
            }
            source = e.source();
        }
        Self::internal(format!("{what}: {error}"))
    }

    /// Every run slot is busy: 503 with `Retry-After`.
    pub fn overloaded(retry_after_secs: u64) -> Self {
        Self {
            retry_after_secs: Some(retry_after_secs),
            ..Self::new(
                StatusCode::SERVICE_UNAVAILABLE,
                ErrorDetail::new(
                    ErrorCode::Overloaded,
                    "every simulation slot is busy; retry after the time in Retry-After",
                ),
            )
        }
    }

    /// The same error with a `Retry-After` hint of `secs` seconds (429 and 503 answers).
    pub fn with_retry_after(mut self, secs: u64) -> Self {
        self.retry_after_secs = Some(secs);
        self
    }

    /// No such resource.
    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(
            StatusCode::NOT_FOUND,
            ErrorDetail::new(ErrorCode::NotFound, message),
        )
    }

    /// The HTTP status.
    pub fn status_code(&self) -> StatusCode {
        self.status
    }

    /// The error detail sent to the client.
    pub fn detail(&self) -> &ErrorDetail {
        &self.detail
    }

    /// The `Retry-After` hint in seconds, if any.
    pub fn retry_after_secs(&self) -> Option<u64> {
        self.retry_after_secs
    }

    /// The JSON body of this error.
    pub fn body(&self) -> ErrorBody {
        ErrorBody {
            error: self.detail.clone(),
        }
    }
}

impl From<Refusal> for ApiError {
    fn from(refusal: Refusal) -> Self {
        let error = ApiError::from(refusal.detail);
        match refusal.retry_after_secs {
            Some(secs) => error.with_retry_after(secs),
            None => error,
        }
    }
}

impl From<ErrorDetail> for ApiError {
    fn from(detail: ErrorDetail) -> Self {
        if detail.code == ErrorCode::Internal {
            return ApiError::internal(detail.message);
        }
        Self::new(status_for(detail.code), detail)
    }
}

impl From<CoreError> for ApiError {
    fn from(error: CoreError) -> Self {
        ApiError::from(ErrorDetail::from(error))
    }
}

impl std::fmt::Display for ApiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.status, self.detail)
    }
}

impl std::error::Error for ApiError {}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = serde_json::to_vec(&self.body()).unwrap_or_else(|_| {
            br#"{"error":{"code":"internal","message":"internal server error","field":null}}"#
                .to_vec()
        });
        let mut response = Response::new(Body::from(body));
        *response.status_mut() = self.status;
        let headers = response.headers_mut();
        headers.insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/json"),
        );
        if let Some(secs) = self.retry_after_secs {
            headers.insert(header::RETRY_AFTER, HeaderValue::from(secs));
        }
        // RFC 6750: a refusal for want of credentials names the scheme that would pass.
        if self.status == StatusCode::UNAUTHORIZED {
            headers.insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"geomint\""),
            );
        }
        response
    }
}

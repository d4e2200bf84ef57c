//! [`ApiJson`], the JSON body extractor of the service. Unlike axum's own, every rejection — a
//! wrong content type, a body over the limit, malformed JSON, a number JSON cannot carry —
//! answers in the service's error shape; the request readers of [`crate::api`] then read the
//! value field by field.

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{header, StatusCode};
use serde_json::Value;

use axum::extract::rejection::{BytesRejection, FailedToBufferBody};

use super::error::ApiError;
use super::server::body_error;
use crate::api::json::parse_json;
use crate::core::error::{ErrorCode, ErrorDetail};

/// A JSON request body as a value; rejections are [`ApiError`]s.
#[derive(Clone, Debug)]
pub struct ApiJson(pub Value);

/// Whether a content type is JSON (`application/json` or `application/*+json`).
fn is_json(content_type: &str) -> bool {
    let essence = content_type
        .split(';')
        .next()
        .unwrap_or("")
        .trim()
        .to_ascii_lowercase();
    essence == "application/json"
        || (essence.starts_with("application/") && essence.ends_with("+json"))
}

impl<S> FromRequest<S> for ApiJson
where
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, ApiError> {
        // A body without a content type is accepted as JSON; any other declared type is not.
        if let Some(value) = req.headers().get(header::CONTENT_TYPE) {
            let text = value.to_str().unwrap_or("");
            if !is_json(text) {
                return Err(ApiError::new(
                    StatusCode::UNSUPPORTED_MEDIA_TYPE,
                    ErrorDetail::new(
                        ErrorCode::UnsupportedMediaType,
                        format!(
                            "the body must be JSON (Content-Type: application/json), not `{text}`"
                        ),
                    ),
                ));
            }
        }
        let bytes = Bytes::from_request(req, state)
            .await
            .map_err(|rejection| match rejection {
                BytesRejection::FailedToBufferBody(FailedToBufferBody::LengthLimitError(_)) => {
                    ApiError::new(
                        StatusCode::PAYLOAD_TOO_LARGE,
                        ErrorDetail::new(
                            ErrorCode::PayloadTooLarge,
                            "the request body exceeds the size limit",
                        ),
                    )
                }
                other => body_error(&other),
            })?;
        parse_json(&bytes).map(ApiJson).map_err(ApiError::from)
    }
}

//! [`ApiJson`], the JSON body extractor of the service. Unlike axum's own, every rejection — a
//! wrong content type, a body over the limit, malformed JSON, a number JSON cannot carry, a
//! field of the wrong type — answers in the service's error shape.

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::{header, StatusCode};
use serde::de::DeserializeOwned;

use super::error::ApiError;
use crate::api::error::{codes, ErrorDetail};
use crate::api::request::from_json;

/// A JSON request body, deserialized into `T`; rejections are [`ApiError`]s.
#[derive(Clone, Debug)]
pub struct ApiJson<T>(pub T);

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

impl<S, T> FromRequest<S> for ApiJson<T>
where
    S: Send + Sync,
    T: DeserializeOwned,
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
                        codes::UNSUPPORTED_MEDIA_TYPE,
                        format!(
                            "the body must be JSON (Content-Type: application/json), not `{text}`"
                        ),
                    ),
                ));
            }
        }
        let bytes = Bytes::from_request(req, state).await.map_err(|rejection| {
            if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
                ApiError::new(
                    StatusCode::PAYLOAD_TOO_LARGE,
                    ErrorDetail::new(
                        codes::PAYLOAD_TOO_LARGE,
                        "the request body exceeds the size limit",
                    ),
                )
            } else {
                ApiError::new(
                    StatusCode::BAD_REQUEST,
                    ErrorDetail::new(
                        codes::BAD_REQUEST,
                        format!("the request body could not be read: {rejection}"),
                    ),
                )
            }
        })?;
        from_json(&bytes).map(ApiJson).map_err(ApiError::from)
    }
}

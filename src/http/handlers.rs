//! Handlers of the read-only routes: health, the method catalogue, the OpenAPI document, and the
//! answers for unknown routes and methods.

use axum::extract::{Path, State};
use axum::http::{header, HeaderValue};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use utoipa::ToSchema;

use super::error::{ApiError, ErrorBody};
use super::openapi;
use super::paths;
use super::state::AppState;
use crate::core::error::{ErrorCode, ErrorDetail};
use crate::core::methods::{MethodId, MethodInfo};

/// The health answer.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct Health {
    /// Always `ok` when the service answers.
    #[schema(example = "ok")]
    pub status: String,
    /// The service version.
    pub version: String,
    /// Simulation threads running now.
    pub runs_in_progress: usize,
    /// Most simulation threads at once.
    pub max_concurrent: usize,
}

/// Liveness and load.
#[utoipa::path(get, path = paths::HEALTHZ, tag = "service",
    responses((status = 200, description = "The service is up", body = Health)))]
pub async fn healthz(State(state): State<AppState>) -> Json<Health> {
    Json(Health {
        status: "ok".to_string(),
        version: env!("CARGO_PKG_VERSION").to_string(),
        runs_in_progress: state.runs_in_progress(),
        max_concurrent: state.config.max_concurrent,
    })
}

/// The method catalogue: order, kind, geometric properties, requirements and citation.
#[utoipa::path(get, path = paths::METHODS, tag = "catalog",
    responses((status = 200, description = "Every method", body = Vec<MethodInfo>)))]
pub async fn list_methods() -> Json<Vec<&'static MethodInfo>> {
    Json(MethodId::ALL.iter().map(|m| m.info()).collect())
}

/// One method of the catalogue.
#[utoipa::path(get, path = paths::METHOD, tag = "catalog",
    params(("id" = String, Path, description = "Method id", example = "modin_3s")),
    responses(
        (status = 200, description = "The method", body = MethodInfo),
        (status = 404, description = "No such method", body = ErrorBody),
    ))]
pub async fn get_method(Path(id): Path<String>) -> Result<Json<&'static MethodInfo>, ApiError> {
    MethodId::parse(&id)
        .map(|m| Json(m.info()))
        .ok_or_else(|| ApiError::not_found(format!("unknown method `{id}`")))
}

/// This API's OpenAPI 3 document, with the security each operation needs under the server's
/// policy for clients without a token.
#[utoipa::path(get, path = paths::OPENAPI, tag = "service",
    responses((status = 200, description = "The OpenAPI document", content_type = "application/json")))]
pub async fn openapi_json(State(state): State<AppState>) -> Response {
    static DOCS: [std::sync::OnceLock<String>; 3] = [const { std::sync::OnceLock::new() }; 3];
    let anonymous = state.access.anonymous();
    let doc = DOCS[anonymous as usize].get_or_init(|| openapi::document_for(anonymous).to_string());
    let mut response = doc.clone().into_response();
    response.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    response
}

/// The answer for a path no route matches.
pub async fn not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::not_found(format!(
        "no route for `{}`; see {}",
        uri.path(),
        paths::OPENAPI
    ))
}

/// The answer for a route asked with a method it does not take.
pub async fn method_not_allowed(method: axum::http::Method, uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        axum::http::StatusCode::METHOD_NOT_ALLOWED,
        ErrorDetail::new(
            ErrorCode::MethodNotAllowed,
            format!("`{}` does not take {method}", uri.path()),
        ),
    )
}

//! The system routes: `GET /api/v1/systems` lists the built-in systems and the stored
//! definitions, `GET /api/v1/systems/{id}` gives one (a stored one with its definition and the
//! facts derived from it), `POST /api/v1/systems` stores a definition and answers its id, and
//! `DELETE /api/v1/systems/{id}` removes a stored one. The definitions live in the
//! [`SystemStore`](crate::store::systems::SystemStore).

use std::sync::Arc;
use std::time::SystemTime;

use axum::extract::{Path as UrlPath, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;

use super::error::{ApiError, ErrorBody};
use super::extract::ApiJson;
use super::paths;
use super::state::{run_blocking, AppState};
use crate::api::system::SystemDefinition;
use crate::core::error::{ErrorCode, ErrorDetail, Field};
use crate::core::systems;
use crate::store::systems::{
    is_definition_id, unix_ms, StoredSystem, SystemEntry, SystemStoreError,
};

fn no_system(id: &str) -> ApiError {
    ApiError::not_found(format!(
        "no system `{id}`; see {} for the built-in and stored ones",
        paths::SYSTEMS
    ))
}

fn store_error(error: SystemStoreError) -> ApiError {
    match error {
        SystemStoreError::Full { .. } => ApiError::new(
            StatusCode::INSUFFICIENT_STORAGE,
            ErrorDetail::new(ErrorCode::TooManySystems, error.to_string()),
        ),
        SystemStoreError::Io(e) => ApiError::storage("system store", &e),
    }
}

/// The built-in systems, then the stored definitions: parameters with defaults and ranges,
/// default initial state, invariants; a stored one also with its definition and facts.
#[utoipa::path(get, path = paths::SYSTEMS, tag = "catalog",
    responses((status = 200, description = "Every system", body = Vec<SystemEntry>)))]
pub async fn list_systems(State(state): State<AppState>) -> Json<Vec<SystemEntry>> {
    let built_in = systems::catalog()
        .iter()
        .map(|info| SystemEntry::BuiltIn((**info).clone()));
    let stored = state
        .systems
        .list()
        .into_iter()
        .map(|s| SystemEntry::Stored((*s).clone()));
    Json(built_in.chain(stored).collect())
}

/// One system: a built-in one, or a stored definition with its facts.
#[utoipa::path(get, path = paths::SYSTEM, tag = "catalog",
    params(("id" = String, Path, description = "System id", example = "pendulum")),
    responses(
        (status = 200, description = "The system", body = SystemEntry),
        (status = 404, description = "No such system", body = ErrorBody),
    ))]
pub async fn get_system(
    State(state): State<AppState>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<SystemEntry>, ApiError> {
    if let Some(stored) = state.systems.get(&id) {
        return Ok(Json(SystemEntry::Stored((*stored).clone())));
    }
    systems::info(&id, &Field::new("id"))
        .map(|info| Json(SystemEntry::BuiltIn((*info).clone())))
        .map_err(|_| no_system(&id))
}

/// Stores a definition. The answer is its entry: `201 Created` with `Location` for a new one,
/// `200 OK` when the same definition is stored already (the id is a digest of the definition).
#[utoipa::path(post, path = paths::SYSTEMS, tag = "catalog",
    request_body(content = SystemDefinition, content_type = "application/json"),
    responses(
        (status = 201, description = "Stored", body = StoredSystem,
            headers(("Location" = String, description = "The system's URL"))),
        (status = 200, description = "The same definition was stored already", body = StoredSystem),
        (status = 400, description = "Malformed JSON", body = ErrorBody),
        (status = 422, description = "The definition is wrong; `field` names where, and for an \
            expression `position` the character", body = ErrorBody),
        (status = 507, description = "The store holds its cap of definitions", body = ErrorBody),
    ))]
pub async fn create_system(
    State(state): State<AppState>,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    let definition = SystemDefinition::read(&body, &Field::default())?;
    let store = Arc::clone(&state.systems);
    let (stored, new) = run_blocking(move || {
        let stored = StoredSystem::new(definition, unix_ms(SystemTime::now()))?;
        store.insert(stored).map_err(store_error)
    })
    .await??;
    let url = format!("{}/{}", paths::SYSTEMS, stored.info.id);
    if new {
        tracing::info!(id = %stored.info.id, "system stored");
    }
    let status = if new {
        StatusCode::CREATED
    } else {
        StatusCode::OK
    };
    let mut response = (status, Json(&*stored)).into_response();
    if let Ok(location) = HeaderValue::from_str(&url) {
        response.headers_mut().insert(header::LOCATION, location);
    }
    Ok(response)
}

/// Removes a stored definition (built-in systems stay).
#[utoipa::path(delete, path = paths::SYSTEM, tag = "catalog",
    params(("id" = String, Path, description = "A stored system's id", example = "sys-0123456789abcdef")),
    responses(
        (status = 204, description = "Removed"),
        (status = 404, description = "No such stored system", body = ErrorBody),
        (status = 409, description = "A built-in system", body = ErrorBody),
    ))]
pub async fn delete_system(
    State(state): State<AppState>,
    UrlPath(id): UrlPath<String>,
) -> Result<StatusCode, ApiError> {
    if systems::catalog().iter().any(|s| s.id == id) {
        return Err(ApiError::new(
            StatusCode::CONFLICT,
            ErrorDetail::new(
                ErrorCode::BuiltInSystem,
                format!("`{id}` is built in; only stored definitions can be deleted"),
            ),
        ));
    }
    if !is_definition_id(&id) {
        return Err(no_system(&id));
    }
    let store = Arc::clone(&state.systems);
    let target = id.clone();
    let removed = run_blocking(move || store.remove(&target))
        .await?
        .map_err(store_error)?;
    if removed {
        tracing::info!(%id, "system deleted");
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(no_system(&id))
    }
}

//! The system routes: `GET /api/v1/systems` lists the built-in systems and the stored
//! definitions, `GET /api/v1/systems/{id}` gives one (a stored one with its definition and the
//! facts derived from it), `POST /api/v1/systems` stores a definition and answers its id, and
//! `DELETE /api/v1/systems/{id}` removes a stored one. The definitions live in the
//! [`SystemStore`](crate::store::systems::SystemStore).

use std::sync::Arc;
use std::time::SystemTime;

use axum::extract::{Path as UrlPath, Query, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;

use super::error::{ApiError, ErrorBody};
use super::extract::ApiJson;
use super::paths;
use super::recordings::OwnerQuery;
use super::state::{run_blocking, AppState};
use crate::access::{Caller, Scope};
use crate::api::system::SystemDefinition;
use crate::core::error::{ErrorCode, ErrorDetail, Field};
use crate::core::systems;
use crate::store::systems::{
    is_definition_id, unix_ms, DefinitionOwner, Removal, StoredSystem, SystemEntry,
    SystemStoreError,
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
        SystemStoreError::OverQuota { .. } => ApiError::from(ErrorDetail::new(
            ErrorCode::QuotaExceeded,
            error.to_string(),
        )),
        SystemStoreError::Io(e) => ApiError::storage("system store", &e),
    }
}

/// The built-in systems, then the stored definitions: parameters with defaults and ranges,
/// default initial state, invariants; a stored one also with its definition, facts and owners.
/// `?owner=NAME` lists only the definitions that owner stored.
#[utoipa::path(get, path = paths::SYSTEMS, tag = "catalog",
    params(("owner" = Option<String>, Query, description = "Only the stored definitions of this \
        owner (a token's name, or `anonymous@ADDRESS`)", example = "alice")),
    responses((status = 200, description = "Every system", body = Vec<SystemEntry>)))]
pub async fn list_systems(
    State(state): State<AppState>,
    Query(query): Query<OwnerQuery>,
) -> Json<Vec<SystemEntry>> {
    let owner = query.owner.as_deref();
    let built_in = systems::catalog()
        .iter()
        .filter(|_| owner.is_none())
        .map(|info| SystemEntry::BuiltIn((**info).clone()));
    let stored = state
        .systems
        .list()
        .into_iter()
        .filter(|s| owner.is_none_or(|o| s.owners.iter().any(|mine| mine == o)))
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

/// Stores a definition for the caller. The answer is its entry: `201 Created` with `Location`
/// for a new one, `200 OK` when the same definition is stored already (the id is a digest of
/// the definition; the caller becomes one of its owners).
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
    caller: Caller,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    let definition = SystemDefinition::read(&body, &Field::default())?;
    let store = Arc::clone(&state.systems);
    let owner = DefinitionOwner {
        name: caller.owner,
        quota: caller.quotas.systems,
    };
    let (stored, new) = run_blocking(move || {
        let stored = StoredSystem::new(definition, unix_ms(SystemTime::now()))?;
        store.insert(stored, &owner).map_err(store_error)
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

/// Removes the caller's share of a stored definition: the definition goes with its last owner,
/// or at once for an `admin` token (built-in systems stay).
#[utoipa::path(delete, path = paths::SYSTEM, tag = "catalog",
    params(("id" = String, Path, description = "A stored system's id", example = "sys-0123456789abcdef")),
    responses(
        (status = 204, description = "Removed"),
        (status = 404, description = "No such stored system", body = ErrorBody),
        (status = 409, description = "A built-in system", body = ErrorBody),
    ))]
pub async fn delete_system(
    State(state): State<AppState>,
    caller: Caller,
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
    let admin = caller.scopes.grants(Scope::Admin);
    let owner = caller.owner;
    let removed = run_blocking(move || store.remove(&target, &owner, admin))
        .await?
        .map_err(store_error)?;
    match removed {
        Removal::Removed | Removal::Released => {
            tracing::info!(%id, ?removed, "system deleted");
            Ok(StatusCode::NO_CONTENT)
        }
        Removal::Missing => Err(no_system(&id)),
        Removal::NotOwner(owners) => Err(super::recordings::not_yours(
            "system",
            &id,
            Some(owners.join("`, `").as_str()).filter(|o| !o.is_empty()),
        )),
    }
}

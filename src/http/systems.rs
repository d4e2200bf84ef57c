//! The system routes: `GET /api/v1/systems` lists the built-in systems and the stored
//! definitions, `GET /api/v1/systems/{id}` gives one (a stored one with its definition and the
//! facts derived from it), `POST /api/v1/systems` stores a definition and answers its id, and
//! `DELETE /api/v1/systems/{id}` removes a stored one.
//!
//! A stored definition is the file `<id>.json` in the systems directory (beside the recordings),
//! written through a locked temporary file and renamed into place, so a crash leaves either the
//! whole file or none. The id is a digest of the definition ([`SystemDefinition::id`]): storing
//! the same definition twice keeps one file. When the service starts it reads the directory
//! back; a file that does not parse, does not check, or does not match its name is skipped with a
//! log line and left where it is for a person to look at.
//!
//! Requests name a stored system by its id like a built-in one; [`SystemStore::substitute`]
//! replaces the id by its definition before the request is checked.

use std::collections::BTreeMap;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock, RwLockReadGuard, RwLockWriteGuard};
use std::time::{SystemTime, UNIX_EPOCH};

use axum::extract::{Path as UrlPath, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use utoipa::ToSchema;

use super::error::{ApiError, ErrorBody};
use super::extract::ApiJson;
use super::paths;
use super::state::{run_blocking, AppState};
use super::tempfile::{remove_if_abandoned, write_atomically, TMP_PREFIX};
use crate::api::system::{SystemDefinition, SystemRequest};
use crate::core::error::{ErrorCode, ErrorDetail, Field};
use crate::core::systems::custom::Facts;
use crate::core::systems::{self, SystemInfo};

/// The default directory of stored definitions.
pub const DEFAULT_SYSTEMS_DIR: &str = "./data/systems";
/// The default cap on stored definitions.
pub const DEFAULT_MAX_SYSTEMS: usize = 1000;

/// Whether `id` has the form of a definition's id: `sys-` and 16 lowercase hex digits.
pub fn is_definition_id(id: &str) -> bool {
    id.strip_prefix("sys-").is_some_and(|hex| {
        hex.len() == 16 && hex.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
    })
}

/// A stored definition with what the service derived from it.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct StoredSystem {
    /// The catalogue entry the definition runs under (its `id` is the definition's).
    #[serde(flatten)]
    pub info: SystemInfo,
    /// The definition as stored.
    pub definition: SystemDefinition,
    /// Facts derived from the definition: dimension, separability, damping, methods that apply.
    pub facts: Facts,
    /// When it was stored (milliseconds since the Unix epoch).
    pub created_unix_ms: u64,
}

/// An entry of the system list: a built-in system, or a stored definition.
#[derive(Clone, Debug, Serialize, ToSchema)]
#[serde(untagged)]
pub enum SystemEntry {
    /// A built-in system.
    BuiltIn(SystemInfo),
    /// A stored definition.
    Stored(StoredSystem),
}

/// Why a definition was not stored or read back.
#[derive(Debug, thiserror::Error)]
pub enum SystemStoreError {
    /// File system trouble.
    #[error("system store: {0}")]
    Io(#[from] io::Error),
    /// The store holds its cap.
    #[error("the store holds {max} definitions, its cap; delete one first")]
    Full {
        /// The cap.
        max: usize,
    },
}

/// The stored definitions: a directory of `<id>.json` files and their checked entries in memory.
#[derive(Debug)]
pub struct SystemStore {
    dir: PathBuf,
    max: usize,
    entries: RwLock<BTreeMap<String, Arc<StoredSystem>>>,
}

impl SystemStore {
    /// Opens the store in `dir` (created when the first definition is stored) holding at most
    /// `max` definitions, and reads back the definitions found there.
    pub fn open(dir: impl Into<PathBuf>, max: usize) -> Self {
        let store = SystemStore {
            dir: dir.into(),
            max,
            entries: RwLock::default(),
        };
        let found = store.scan();
        if !found.is_empty() {
            tracing::info!(dir = %store.dir.display(), systems = found.len(), "stored systems found");
        }
        *store.write() = found;
        store
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn read(&self) -> RwLockReadGuard<'_, BTreeMap<String, Arc<StoredSystem>>> {
        self.entries.read().unwrap_or_else(|p| p.into_inner())
    }

    fn write(&self) -> RwLockWriteGuard<'_, BTreeMap<String, Arc<StoredSystem>>> {
        self.entries.write().unwrap_or_else(|p| p.into_inner())
    }

    fn path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.json"))
    }

    /// Reads every stored definition, skipping (with a log line) what is not one.
    fn scan(&self) -> BTreeMap<String, Arc<StoredSystem>> {
        let listing = match fs::read_dir(&self.dir) {
            Ok(listing) => listing,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return BTreeMap::new(),
            Err(e) => {
                tracing::warn!(dir = %self.dir.display(), error = %e, "cannot read the systems directory");
                return BTreeMap::new();
            }
        };
        let mut found = BTreeMap::new();
        for item in listing.flatten() {
            let path = item.path();
            let name = item.file_name().to_string_lossy().into_owned();
            if name.starts_with(TMP_PREFIX) {
                remove_if_abandoned(&path);
                continue;
            }
            match Self::read_file(&path, &name) {
                Ok(stored) => {
                    found.insert(stored.info.id.to_string(), Arc::new(stored));
                }
                Err(reason) => {
                    tracing::warn!(file = %path.display(), %reason, "skipping a stored system");
                }
            }
        }
        found
    }

    /// Reads and checks one stored definition.
    fn read_file(path: &Path, name: &str) -> Result<StoredSystem, String> {
        let id = name
            .strip_suffix(".json")
            .filter(|id| is_definition_id(id))
            .ok_or("not a stored definition's file name (sys-<16 hex digits>.json)")?;
        let bytes = fs::read(path).map_err(|e| e.to_string())?;
        let definition = SystemDefinition::from_slice(&bytes)
            .map_err(|e| format!("not a definition: {}", e.message))?;
        if definition.id() != id {
            return Err(format!(
                "the definition's id is {}, not its file name's",
                definition.id()
            ));
        }
        let created_unix_ms = fs::metadata(path)
            .and_then(|m| m.modified())
            .map(unix_ms)
            .unwrap_or(0);
        StoredSystem::new(definition, created_unix_ms).map_err(|e| {
            let field = e.field.map(|f| format!(" at `{f}`")).unwrap_or_default();
            format!("the definition does not check{field}: {}", e.message)
        })
    }

    /// The stored definition `id`.
    pub fn get(&self, id: &str) -> Option<Arc<StoredSystem>> {
        self.read().get(id).cloned()
    }

    /// Every stored definition, by id.
    pub fn list(&self) -> Vec<Arc<StoredSystem>> {
        self.read().values().cloned().collect()
    }

    /// Stores a checked definition; true when it is new. Blocking file I/O.
    pub fn insert(
        &self,
        stored: StoredSystem,
    ) -> Result<(Arc<StoredSystem>, bool), SystemStoreError> {
        let id = stored.info.id.to_string();
        if let Some(existing) = self.get(&id) {
            return Ok((existing, false));
        }
        // The write lock is held across the file write so two requests storing the same new
        // definition write it once, and the cap cannot be passed by racing requests.
        let mut entries = self.write();
        if let Some(existing) = entries.get(&id) {
            return Ok((Arc::clone(existing), false));
        }
        if entries.len() >= self.max {
            return Err(SystemStoreError::Full { max: self.max });
        }
        fs::create_dir_all(&self.dir)?;
        // Serializing a definition cannot fail (strings, finite numbers, string-keyed maps).
        let bytes = serde_json::to_vec_pretty(&stored.definition).unwrap_or_default();
        write_atomically(&self.dir, &self.path(&id), &bytes)?;
        let stored = Arc::new(stored);
        entries.insert(id, Arc::clone(&stored));
        Ok((stored, true))
    }

    /// Removes the stored definition `id`; false when there is none. Blocking file I/O.
    pub fn remove(&self, id: &str) -> Result<bool, SystemStoreError> {
        let mut entries = self.write();
        if !entries.contains_key(id) {
            return Ok(false);
        }
        match fs::remove_file(self.path(id)) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(e.into()),
        }
        entries.remove(id);
        Ok(true)
    }

    /// Replaces a stored definition's id by the definition, so that the request checks and runs
    /// it like one sent inline; any other system is left as it is.
    pub fn substitute(&self, system: &mut SystemRequest) {
        if let SystemRequest::Id(id) = system {
            if let Some(stored) = self.get(id) {
                *system = SystemRequest::Definition(Box::new(stored.definition.clone()));
            }
        }
    }
}

fn unix_ms(time: SystemTime) -> u64 {
    time.duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX))
}

impl StoredSystem {
    /// Checks `definition` into the entry it is stored as.
    pub fn new(definition: SystemDefinition, created_unix_ms: u64) -> Result<Self, ErrorDetail> {
        let info = definition.check(&Field::default())?;
        let facts = info
            .custom_model()
            .map(|model| model.facts())
            .ok_or_else(|| {
                ErrorDetail::new(ErrorCode::Internal, "a definition without its model")
            })?;
        Ok(StoredSystem {
            info: (*info).clone(),
            definition,
            facts,
            created_unix_ms,
        })
    }
}

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

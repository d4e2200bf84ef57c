//! Stored system definitions: the registry of users' systems that the server, the command line
//! (`--systems-dir`) and the NATS workers share.
//!
//! A stored definition is the file `<id>.json` in the systems directory (beside the recordings),
//! written through a locked temporary file and renamed into place, so a crash leaves either the
//! whole file or none. The id is a digest of the definition ([`SystemDefinition::id`]): storing
//! the same definition twice keeps one file. Opening the store reads the directory back; a file
//! that does not parse, does not check, or does not match its name is skipped with a log line and
//! left where it is for a person to look at.
//!
//! Requests name a stored system by its id like a built-in one: the store is the
//! [`StoredSystems`] the wire layer resolves such ids through, to the definition checked and
//! compiled once, when it was stored or read back.
//!
//! Writing and removing are blocking file I/O: call them off the async runtime.

use std::collections::BTreeMap;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Arc, RwLock, RwLockReadGuard, RwLockWriteGuard};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::Serialize;
use utoipa::ToSchema;

use super::tempfile::{remove_if_abandoned, write_atomically, TMP_PREFIX};
use crate::api::system::{StoredSystems, SystemDefinition};
use crate::core::error::{ErrorCode, ErrorDetail, Field};
use crate::core::systems::custom::Facts;
use crate::core::systems::SystemInfo;

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
    /// The entry as requests run it: checked and compiled once, shared by every run.
    #[serde(skip)]
    pub compiled: Arc<SystemInfo>,
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

}

impl StoredSystems for SystemStore {
    fn stored(&self, id: &str) -> Option<(SystemDefinition, Arc<SystemInfo>)> {
        self.get(id)
            .map(|s| (s.definition.clone(), Arc::clone(&s.compiled)))
    }
}

/// Milliseconds since the Unix epoch (0 before it).
pub fn unix_ms(time: SystemTime) -> u64 {
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
            compiled: info,
        })
    }
}


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
//! Each definition belongs to the callers that stored it: its owners, written beside it as
//! `<id>.owners` (a JSON list, atomically too; none for a definition stored before owners were
//! recorded). The same definition stored by two owners is one file with two owners; an owner
//! that deletes it gives up its share, and the file goes with the last owner (or at once, when
//! an `admin` token deletes it). Each owner's definitions count against its quota.
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
/// The suffix of a definition's owners file.
const OWNERS: &str = ".owners";

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
    /// Who stored it (tokens' names, or `anonymous@ADDRESS`): each of them, or an `admin`
    /// token, may delete it. Empty for a definition stored before owners were recorded.
    pub owners: Vec<String>,
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
    /// The owner holds its quota of definitions.
    #[error("`{owner}` has stored {quota} definitions, its quota; delete one first")]
    OverQuota {
        /// The owner.
        owner: String,
        /// Its quota.
        quota: usize,
    },
}

/// What [`SystemStore::remove`] did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Removal {
    /// The definition is gone.
    Removed,
    /// The owner gave up its share; others still own the definition.
    Released,
    /// No such stored definition.
    Missing,
    /// The caller neither owns it nor is an admin; its owners.
    NotOwner(Vec<String>),
}

/// Who stores a definition, and how many it may own (`None`: the store's cap).
#[derive(Clone, Debug)]
pub struct DefinitionOwner {
    /// The owner's name.
    pub name: String,
    /// Its quota of definitions.
    pub quota: Option<usize>,
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

    fn owners_path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}{OWNERS}"))
    }

    /// Writes the owners of `id` (removes the file when there are none).
    fn write_owners(&self, id: &str, owners: &[String]) -> io::Result<()> {
        if owners.is_empty() {
            return match fs::remove_file(self.owners_path(id)) {
                Err(e) if e.kind() != io::ErrorKind::NotFound => Err(e),
                _ => Ok(()),
            };
        }
        let bytes = serde_json::to_vec(owners).map_err(io::Error::other)?;
        write_atomically(&self.dir, &self.owners_path(id), &bytes)
    }

    /// How many definitions `owner` owns.
    pub fn owned_by(&self, owner: &str) -> usize {
        self.read()
            .values()
            .filter(|s| s.owners.iter().any(|o| o == owner))
            .count()
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
        let mut owners: BTreeMap<String, Vec<String>> = BTreeMap::new();
        for item in listing.flatten() {
            let path = item.path();
            let name = item.file_name().to_string_lossy().into_owned();
            if name.starts_with(TMP_PREFIX) {
                remove_if_abandoned(&path);
                continue;
            }
            if let Some(id) = name.strip_suffix(OWNERS).filter(|id| is_definition_id(id)) {
                match fs::read(&path)
                    .map_err(|e| e.to_string())
                    .and_then(|bytes| {
                        serde_json::from_slice::<Vec<String>>(&bytes).map_err(|e| e.to_string())
                    }) {
                    Ok(list) => {
                        owners.insert(id.to_string(), list);
                    }
                    Err(reason) => {
                        tracing::warn!(file = %path.display(), %reason, "skipping the owners of a stored system");
                    }
                }
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
        for (id, list) in owners {
            match found.get_mut(&id) {
                Some(stored) => Arc::make_mut(stored).owners = list,
                None => tracing::warn!(%id, "owners of a definition that is not stored"),
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

    /// Stores a checked definition for `owner`; true when the definition is new. A definition
    /// stored already gains `owner` among its owners. Blocking file I/O.
    pub fn insert(
        &self,
        stored: StoredSystem,
        owner: &DefinitionOwner,
    ) -> Result<(Arc<StoredSystem>, bool), SystemStoreError> {
        let id = stored.info.id.to_string();
        if let Some(existing) = self.get(&id) {
            if existing.owners.contains(&owner.name) {
                return Ok((existing, false));
            }
        }
        // The write lock is held across the file writes so two requests storing the same new
        // definition write it once, and neither the cap nor a quota can be passed by racing
        // requests.
        let mut entries = self.write();
        let owned = entries
            .values()
            .filter(|s| s.owners.contains(&owner.name))
            .count();
        let over_quota = || SystemStoreError::OverQuota {
            owner: owner.name.clone(),
            quota: owner.quota.unwrap_or(0),
        };
        if let Some(existing) = entries.get_mut(&id) {
            if existing.owners.contains(&owner.name) {
                return Ok((Arc::clone(existing), false));
            }
            if owner.quota.is_some_and(|q| owned >= q) {
                return Err(over_quota());
            }
            let mut owners = existing.owners.clone();
            owners.push(owner.name.clone());
            self.write_owners(&id, &owners)?;
            Arc::make_mut(existing).owners = owners;
            return Ok((Arc::clone(existing), false));
        }
        if entries.len() >= self.max {
            return Err(SystemStoreError::Full { max: self.max });
        }
        if owner.quota.is_some_and(|q| owned >= q) {
            return Err(over_quota());
        }
        fs::create_dir_all(&self.dir)?;
        // Serializing a definition cannot fail (strings, finite numbers, string-keyed maps).
        let bytes = serde_json::to_vec_pretty(&stored.definition).unwrap_or_default();
        // The owners first: a definition never exists on disk without them (a crash between
        // the two leaves owners of nothing, skipped at start-up).
        let owners = vec![owner.name.clone()];
        self.write_owners(&id, &owners)?;
        write_atomically(&self.dir, &self.path(&id), &bytes)?;
        let stored = Arc::new(StoredSystem { owners, ..stored });
        entries.insert(id, Arc::clone(&stored));
        Ok((stored, true))
    }

    /// Removes `owner`'s share of the stored definition `id`, or (`admin`) the definition
    /// whoever owns it; the definition goes with its last owner. Blocking file I/O.
    pub fn remove(&self, id: &str, owner: &str, admin: bool) -> Result<Removal, SystemStoreError> {
        let mut entries = self.write();
        let Some(existing) = entries.get_mut(id) else {
            return Ok(Removal::Missing);
        };
        let owns = existing.owners.iter().any(|o| o == owner);
        if !owns && !admin {
            return Ok(Removal::NotOwner(existing.owners.clone()));
        }
        let rest: Vec<String> = existing
            .owners
            .iter()
            .filter(|o| *o != owner)
            .cloned()
            .collect();
        if !admin && !rest.is_empty() {
            self.write_owners(id, &rest)?;
            Arc::make_mut(existing).owners = rest;
            return Ok(Removal::Released);
        }
        match fs::remove_file(self.path(id)) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(e.into()),
        }
        self.write_owners(id, &[])?;
        entries.remove(id);
        Ok(Removal::Removed)
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
            .map(geomint_core::systems::custom::facts)
            .ok_or_else(|| {
                ErrorDetail::new(ErrorCode::Internal, "a definition without its model")
            })?;
        Ok(StoredSystem {
            info: (*info).clone(),
            definition,
            facts,
            created_unix_ms,
            owners: Vec::new(),
            compiled: info,
        })
    }
}

//! The recordings the service keeps: `.rrd` files under a data directory, each beside a small
//! JSON sidecar with its summary, listed from an in-memory index that is rebuilt from the
//! directory at start-up.
//!
//! - Ids are generated here (a random UUID v4 as 32 lowercase hex digits) and checked strictly
//!   ([`is_valid_id`]) before any lookup: no part of a request ever becomes a path.
//! - A recording is written to a temporary file in the directory, checked (RRD header, stream
//!   footer, size), then renamed into place; its sidecar the same way, after it. A recording
//!   without a sidecar was interrupted and is never listed.
//! - An uploaded recording ([`RecordingStore::begin_upload`]) arrives in a locked temporary file
//!   too, is checked by the caller while it is there, and only then kept
//!   ([`RecordingStore::keep_upload`]); an upload that is refused or cut short leaves nothing.
//! - Every recording belongs to the caller that stored it (its `owner`, in the sidecar; none for
//!   those stored before owners were recorded). A new recording evicts only its owner's own
//!   oldest recordings: past the owner's quota, and past the store's size cap, where recordings
//!   without an owner go too. A recording larger than its owner's quota or the whole cap is
//!   refused, and so is one for which only other owners' recordings could make room.
//! - At start-up, files that are not complete recordings of this service (a torn `.rrd`, a
//!   sidecar that does not match its file, anything foreign) are skipped with a log line, and
//!   left alone; leftover temporary files of this service are removed. A temporary file is
//!   locked (an advisory lock on the open file) by its writer until it is renamed into place,
//!   so a second store opened on the same directory — another server, or another test in the
//!   same process — removes only the files whose writer is gone, never a write in progress.
//!
//! Everything here is blocking file I/O: call it off the async runtime.

use std::fs::{self, File};
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

use super::dates::rfc3339;
pub use super::entry::{Contents, Origin, RecordingEntry, RecordingOwner, SpecSummary};
use super::index::Index;
pub use super::tempfile::Upload;
use super::tempfile::{remove_if_abandoned, write_atomically, TempFile, TMP_PREFIX};
use crate::recording::RecordingError;

/// The sidecar's format tag.
const SIDECAR_FORMAT: &str = "geomint-recording/1";

/// Whether `id` is a recording id: exactly 32 lowercase hexadecimal digits.
pub fn is_valid_id(id: &str) -> bool {
    id.len() == 32 && id.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
}

/// A new random recording id.
pub fn new_id() -> String {
    uuid::Uuid::new_v4().simple().to_string()
}

/// The sidecar file of a recording.
#[derive(Serialize, Deserialize)]
struct Sidecar {
    format: String,
    #[serde(flatten)]
    entry: RecordingEntry,
}

/// Why a recording could not be stored.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// File system trouble.
    #[error("recording store: {0}")]
    Io(#[from] io::Error),
    /// Writing the recording failed.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The recording alone exceeds the size cap.
    #[error("the recording has {bytes} bytes, more than the store's cap of {max} bytes")]
    TooLarge {
        /// Size of the recording.
        bytes: u64,
        /// The cap.
        max: u64,
    },
    /// The written file is not a complete recording.
    #[error("the written recording is incomplete")]
    Incomplete,
    /// An upload is no longer in its temporary file (it was kept or discarded before).
    #[error("the upload was already kept or discarded")]
    UploadGone,
    /// The recording alone exceeds its owner's quota.
    #[error("the recording has {bytes} bytes, more than `{owner}`'s quota of {quota} bytes")]
    OverQuota {
        /// The owner.
        owner: String,
        /// Size of the recording.
        bytes: u64,
        /// The owner's quota.
        quota: u64,
    },
    /// Only other owners' recordings could make room under the store's cap.
    #[error(
        "the store's cap of {max} bytes is taken by other owners' recordings; it keeps \
             {bytes} more bytes only once they delete some"
    )]
    FullOfOthers {
        /// Size of the recording.
        bytes: u64,
        /// The cap.
        max: u64,
    },
}

/// The recordings under one data directory.
#[derive(Debug)]
pub struct RecordingStore {
    dir: PathBuf,
    max_bytes: u64,
    index: Mutex<Index>,
}

/// Whether the file at `path` is a complete RRD stream of `len` bytes: the RRD header at the
/// start and the stream footer at the end.
fn is_complete_rrd(path: &Path, len: u64) -> io::Result<bool> {
    let mut file = File::open(path)?;
    if file.metadata()?.len() != len || len < 16 {
        return Ok(false);
    }
    let mut head = [0u8; 4];
    file.read_exact(&mut head)?;
    let mut tail = [0u8; 12];
    file.seek(SeekFrom::End(-12))?;
    file.read_exact(&mut tail)?;
    Ok(&head == b"RRF2" && &tail[..8] == b"RRF2FOOT")
}

impl RecordingStore {
    /// The store in `dir` (created when the first recording is saved), capped at `max_bytes`;
    /// reads back the recordings already there.
    pub fn open(dir: impl Into<PathBuf>, max_bytes: u64) -> Self {
        let store = RecordingStore {
            dir: dir.into(),
            max_bytes,
            index: Mutex::new(Index::default()),
        };
        let found = store.scan();
        let mut index = store.lock();
        let mut found = found;
        found.sort_by(|a, b| (a.created_unix_ms, &a.id).cmp(&(b.created_unix_ms, &b.id)));
        for entry in found {
            index.insert(entry);
        }
        if !index.entries.is_empty() {
            tracing::info!(
                dir = %store.dir.display(),
                recordings = index.entries.len(),
                bytes = index.total,
                "recordings found"
            );
        }
        // A cap lowered since the last start: the oldest go, whoever owns them.
        let mut evicted = Vec::new();
        while index.total > store.max_bytes {
            let Some(id) = index.oldest_except("", None) else {
                break;
            };
            evicted.extend(index.remove(&id));
        }
        drop(index);
        store.delete_files(&evicted);
        store
    }

    /// Bytes of `owner`'s recordings now.
    pub fn owned_bytes(&self, owner: &str) -> u64 {
        self.lock().owned(owner)
    }

    /// The data directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The size cap in bytes.
    pub fn max_bytes(&self) -> u64 {
        self.max_bytes
    }

    /// Bytes stored now.
    pub fn total_bytes(&self) -> u64 {
        self.lock().total
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Index> {
        self.index.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn rrd_path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.rrd"))
    }

    fn sidecar_path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.json"))
    }

    /// The complete recordings in the directory; everything else is skipped with a log line.
    fn scan(&self) -> Vec<RecordingEntry> {
        let listing = match fs::read_dir(&self.dir) {
            Ok(listing) => listing,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Vec::new(),
            Err(e) => {
                tracing::warn!(dir = %self.dir.display(), error = %e, "cannot read the recordings directory");
                return Vec::new();
            }
        };
        let mut found = Vec::new();
        for item in listing.flatten() {
            let name = item.file_name().to_string_lossy().into_owned();
            let path = item.path();
            if name.starts_with(TMP_PREFIX) {
                remove_if_abandoned(&path);
                continue;
            }
            let (stem, ext) = match name.rsplit_once('.') {
                Some(parts) => parts,
                None => ("", ""),
            };
            if !is_valid_id(stem) || !(ext == "json" || ext == "rrd") {
                tracing::warn!(file = %path.display(), "skipping a file that is not a recording");
                continue;
            }
            if ext == "rrd" {
                if !self.sidecar_path(stem).is_file() {
                    tracing::warn!(file = %path.display(), "skipping a recording without its summary");
                }
                continue;
            }
            match self.read_sidecar(stem) {
                Ok(entry) => found.push(entry),
                Err(reason) => {
                    tracing::warn!(file = %path.display(), %reason, "skipping an incomplete recording");
                }
            }
        }
        found
    }

    /// The entry of a sidecar, if it and its `.rrd` file are complete and agree.
    fn read_sidecar(&self, id: &str) -> Result<RecordingEntry, String> {
        let text = fs::read(self.sidecar_path(id)).map_err(|e| e.to_string())?;
        let sidecar: Sidecar =
            serde_json::from_slice(&text).map_err(|e| format!("unreadable summary: {e}"))?;
        if sidecar.format != SIDECAR_FORMAT || sidecar.entry.id != id {
            return Err("the summary belongs to something else".into());
        }
        match is_complete_rrd(&self.rrd_path(id), sidecar.entry.bytes) {
            Ok(true) => Ok(sidecar.entry),
            Ok(false) => Err("the .rrd file is torn or does not match its summary".into()),
            Err(e) => Err(format!("the .rrd file cannot be read: {e}")),
        }
    }

    /// Stores a new recording: `write` writes it to the file it is given; the store checks it,
    /// moves it into place, records its summary and evicts the oldest recordings past the cap.
    pub fn save(
        &self,
        spec: SpecSummary,
        owner: &RecordingOwner,
        write: impl FnOnce(BufWriter<File>) -> Result<BufWriter<File>, RecordingError>,
    ) -> Result<RecordingEntry, StoreError> {
        fs::create_dir_all(&self.dir)?;
        let tmp = TempFile::create(&self.dir, ".rrd")?;
        // The writer gets its own handle on the file; the lock stays with `tmp`'s until the
        // file is renamed into place.
        let written = tmp
            .file
            .try_clone()
            .map_err(StoreError::from)
            .and_then(|handle| self.write_checked(&tmp.path, handle, write))
            .and_then(|bytes| self.within_quota(owner, bytes));
        match written {
            Ok(bytes) => self.keep(tmp, Contents::simulation(spec), owner, bytes),
            Err(e) => {
                tmp.discard();
                Err(e)
            }
        }
    }

    /// Starts an upload: a new locked temporary file in the data directory to write the
    /// uploaded bytes to (see [`Upload`]).
    pub fn begin_upload(&self) -> Result<Upload, StoreError> {
        fs::create_dir_all(&self.dir)?;
        Ok(Upload {
            tmp: Some(TempFile::create(&self.dir, ".rrd")?),
        })
    }

    /// Keeps a complete upload, checked by the caller, under a new id with its summary `contents`;
    /// evicts the oldest recordings past the cap, as [`RecordingStore::save`] does. An upload
    /// over the cap or without the RRD header and stream footer is removed and refused.
    pub fn keep_upload(
        &self,
        mut upload: Upload,
        contents: Contents,
        owner: &RecordingOwner,
    ) -> Result<RecordingEntry, StoreError> {
        let tmp = upload.tmp.take().ok_or(StoreError::UploadGone)?;
        let checked = (|| {
            tmp.file.sync_all()?;
            let bytes = tmp.file.metadata()?.len();
            if bytes > self.max_bytes {
                return Err(StoreError::TooLarge {
                    bytes,
                    max: self.max_bytes,
                });
            }
            if !is_complete_rrd(&tmp.path, bytes)? {
                return Err(StoreError::Incomplete);
            }
            self.within_quota(owner, bytes)
        })();
        match checked {
            Ok(bytes) => self.keep(tmp, contents, owner, bytes),
            Err(e) => {
                tmp.discard();
                Err(e)
            }
        }
    }

    /// Keeps `bytes`, a whole recording, under a new id with its summary `contents`, checked and
    /// capped as an upload is (a job's result: [`Contents::job`]).
    pub fn keep_bytes(
        &self,
        bytes: &[u8],
        contents: Contents,
        owner: &RecordingOwner,
    ) -> Result<RecordingEntry, StoreError> {
        let upload = self.begin_upload()?;
        upload.file()?.write_all(bytes)?;
        self.keep_upload(upload, contents, owner)
    }

    /// Writes the recording through `handle` and checks it: its size in bytes.
    fn write_checked(
        &self,
        path: &Path,
        handle: File,
        write: impl FnOnce(BufWriter<File>) -> Result<BufWriter<File>, RecordingError>,
    ) -> Result<u64, StoreError> {
        let writer = write(BufWriter::with_capacity(1 << 20, handle))?;
        let file = writer.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        let bytes = file.metadata()?.len();
        drop(file);
        if bytes > self.max_bytes {
            return Err(StoreError::TooLarge {
                bytes,
                max: self.max_bytes,
            });
        }
        if !is_complete_rrd(path, bytes)? {
            return Err(StoreError::Incomplete);
        }
        Ok(bytes)
    }

    /// `bytes`, unless they alone exceed `owner`'s quota.
    fn within_quota(&self, owner: &RecordingOwner, bytes: u64) -> Result<u64, StoreError> {
        match owner.quota {
            Some(quota) if bytes > quota => Err(StoreError::OverQuota {
                owner: owner.name.clone(),
                bytes,
                quota,
            }),
            _ => Ok(bytes),
        }
    }

    /// Moves a checked recording into place under a new id, with its sidecar, indexes it and
    /// makes room for it ([`RecordingStore::evict`]); removes it again when there is none.
    fn keep(
        &self,
        tmp: TempFile,
        contents: Contents,
        owner: &RecordingOwner,
        bytes: u64,
    ) -> Result<RecordingEntry, StoreError> {
        let id = new_id();
        let id = id.as_str();
        let created_unix_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_millis() as u64)
            .unwrap_or(0);
        let entry = RecordingEntry {
            id: id.to_string(),
            created: rfc3339(created_unix_ms),
            bytes,
            spec: contents.spec,
            origin: contents.origin,
            application_id: contents.application_id,
            created_unix_ms,
            owner: Some(owner.name.clone()),
            job: contents.job,
        };
        tmp.persist(&self.rrd_path(id))?;
        let sidecar = serde_json::to_vec_pretty(&Sidecar {
            format: SIDECAR_FORMAT.to_string(),
            entry: entry.clone(),
        })
        .map_err(io::Error::other)?;
        if let Err(e) = write_atomically(&self.dir, &self.sidecar_path(id), &sidecar) {
            let _ = fs::remove_file(self.rrd_path(id));
            return Err(e.into());
        }
        let evicted = {
            let mut index = self.lock();
            index.insert(entry.clone());
            let room = index.make_room(id, owner, self.max_bytes);
            if room.is_err() {
                index.remove(id);
            }
            room
        };
        let evicted = match evicted {
            Ok(evicted) => evicted,
            Err(e) => {
                self.delete_files(std::slice::from_ref(&entry));
                return Err(e);
            }
        };
        self.delete_files(&evicted);
        tracing::info!(id, bytes, origin = ?entry.origin, evicted = evicted.len(), "recording stored");
        Ok(entry)
    }

    fn delete_files(&self, entries: &[RecordingEntry]) {
        for entry in entries {
            tracing::info!(id = %entry.id, bytes = entry.bytes, "evicting the oldest recording");
            // The sidecar first: a recording without it is never listed again.
            let _ = fs::remove_file(self.sidecar_path(&entry.id));
            let _ = fs::remove_file(self.rrd_path(&entry.id));
        }
    }

    /// Every recording, newest first.
    pub fn list(&self) -> Vec<RecordingEntry> {
        self.list_owned(None)
    }

    /// The recordings of `owner` (all for `None`), newest first.
    pub fn list_owned(&self, owner: Option<&str>) -> Vec<RecordingEntry> {
        let index = self.lock();
        let mut entries: Vec<(u64, RecordingEntry)> = index
            .entries
            .values()
            .filter(|(_, e)| owner.is_none_or(|o| e.owner.as_deref() == Some(o)))
            .cloned()
            .collect();
        entries.sort_by(|a, b| (b.1.created_unix_ms, b.0).cmp(&(a.1.created_unix_ms, a.0)));
        entries.into_iter().map(|(_, e)| e).collect()
    }

    /// A recording's entry and the path of its file, if `id` is valid and stored.
    pub fn get(&self, id: &str) -> Option<(RecordingEntry, PathBuf)> {
        if !is_valid_id(id) {
            return None;
        }
        let index = self.lock();
        let (_, entry) = index.entries.get(id)?;
        Some((entry.clone(), self.rrd_path(id)))
    }

    /// Deletes a recording; false when `id` is not a stored recording.
    pub fn delete(&self, id: &str) -> bool {
        if !is_valid_id(id) {
            return false;
        }
        let removed = self.lock().remove(id);
        match removed {
            Some(entry) => {
                let _ = fs::remove_file(self.sidecar_path(&entry.id));
                let _ = fs::remove_file(self.rrd_path(&entry.id));
                true
            }
            None => false,
        }
    }
}

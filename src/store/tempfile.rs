//! Temporary files of the recording store: each is created in the data directory under the
//! `.tmp-` prefix and locked (an advisory lock on the open file) by its writer until it is renamed
//! into place, so that a second store opened on the same directory removes only the temporary
//! files whose writer is gone ([`remove_if_abandoned`]), never a write in progress. An [`Upload`]
//! is such a file receiving an uploaded `.rrd`.
//!
//! Everything here is blocking file I/O: call it off the async runtime.

use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::recordings::{new_id, StoreError};

/// Prefix of temporary files in the data directory.
pub const TMP_PREFIX: &str = ".tmp-";

/// A temporary file in the data directory, locked by its writer for as long as it is open.
#[derive(Debug)]
pub(crate) struct TempFile {
    pub(crate) path: PathBuf,
    pub(crate) file: File,
}

impl TempFile {
    /// Creates `dir/.tmp-<random><suffix>` and takes its lock. A store that scans the directory
    /// in between could remove the new file before it is locked; then it is made again.
    pub(crate) fn create(dir: &Path, suffix: &str) -> io::Result<Self> {
        use std::os::unix::fs::MetadataExt;
        loop {
            let path = dir.join(format!("{TMP_PREFIX}{}{suffix}", new_id()));
            let file = File::options().write(true).create_new(true).open(&path)?;
            file.lock()?;
            let ours = file.metadata()?;
            match fs::metadata(&path) {
                Ok(now) if now.ino() == ours.ino() && now.dev() == ours.dev() => {
                    return Ok(TempFile { path, file })
                }
                Ok(_) => continue,
                Err(e) if e.kind() == io::ErrorKind::NotFound => continue,
                Err(e) => return Err(e),
            }
        }
    }

    /// Moves the file to `path`; the lock goes with the open file, which is closed after.
    pub(crate) fn persist(self, path: &Path) -> io::Result<()> {
        let result = fs::rename(&self.path, path);
        if result.is_err() {
            let _ = fs::remove_file(&self.path);
        }
        result
    }

    /// Removes the file (a write that failed).
    pub(crate) fn discard(self) {
        let _ = fs::remove_file(&self.path);
    }
}

/// An `.rrd` upload being received: a temporary file in the data directory, locked by this
/// writer. Dropped before [`RecordingStore::keep_upload`] took it (a refused upload, a client
/// that went away), it removes its file.
#[derive(Debug)]
pub struct Upload {
    pub(crate) tmp: Option<TempFile>,
}

impl Upload {
    /// A handle to write the upload's bytes through.
    pub fn file(&self) -> Result<File, StoreError> {
        let tmp = self.tmp.as_ref().ok_or(StoreError::UploadGone)?;
        Ok(tmp.file.try_clone()?)
    }

    /// Where the upload is being written (to check it before it is kept).
    pub fn path(&self) -> Option<&Path> {
        self.tmp.as_ref().map(|t| t.path.as_path())
    }
}

impl Drop for Upload {
    fn drop(&mut self) {
        if let Some(tmp) = self.tmp.take() {
            tmp.discard();
        }
    }
}

/// Removes a leftover temporary file whose writer is gone (its lock is free); a file still
/// locked belongs to a write in progress and stays.
pub(crate) fn remove_if_abandoned(path: &Path) {
    let Ok(file) = File::open(path) else {
        return;
    };
    match file.try_lock() {
        Ok(()) => {
            tracing::info!(file = %path.display(), "removing an interrupted write");
            let _ = fs::remove_file(path);
        }
        Err(fs::TryLockError::WouldBlock) => {
            tracing::debug!(file = %path.display(), "a write in progress");
        }
        Err(fs::TryLockError::Error(e)) => {
            tracing::warn!(file = %path.display(), error = %e, "cannot check a temporary file");
        }
    }
}

/// Writes `bytes` to `path` through a locked temporary file in the same directory.
pub(crate) fn write_atomically(dir: &Path, path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut tmp = TempFile::create(dir, "")?;
    let written = tmp.file.write_all(bytes).and_then(|()| tmp.file.sync_all());
    match written {
        Ok(()) => tmp.persist(path),
        Err(e) => {
            tmp.discard();
            Err(e)
        }
    }
}

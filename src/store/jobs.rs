//! Jobs on disk: a directory per job under the jobs directory, each file written once through a
//! locked temporary file renamed into place ([`super::tempfile`]), except the event log, which is
//! appended to:
//!
//! - `job.json`: what the job is ([`JobRecord`]), written when it is submitted;
//! - `parts/FIRST-END.json`: the cells `FIRST..END` it has finished ([`StoredPart`]), each range
//!   written once; a range written twice (a part computed again after a crash) is the same bytes;
//! - `events.ndjson`: what happened to it, a JSON line per event, in order;
//! - `outcome.json`: how it ended ([`Outcome`]), once it has;
//! - `result.json`, and `result.rrd` for a study that has a recording: its document.
//!
//! A server that starts reads every job back ([`JobStore::open`]); those without an outcome go on
//! from their finished parts. A torn last event line (the server killed in the middle of a write)
//! is skipped when read back.
//!
//! Everything here is blocking file I/O: call it off the async runtime.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::tempfile::{TempFile, TMP_PREFIX};

/// The format tag of `job.json`.
pub const JOB_FORMAT: &str = "geomint-job/1";
/// The format tag of a stored part.
pub const JOB_PART_FORMAT: &str = "geomint-job-part/1";

/// What a job is, as submitted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobRecord {
    /// [`JOB_FORMAT`].
    pub format: String,
    /// Its id (32 lowercase hexadecimal digits, as a recording's).
    pub id: String,
    /// Who submitted it: a token's name or `anonymous@ADDRESS`.
    pub owner: String,
    /// The kind of study (`sweep`, `basins`, …, as in the study routes' paths).
    pub study: String,
    /// The study's request, as the study's route takes it.
    pub request: Value,
    /// Its priority among its owner's jobs (higher first).
    pub priority: i32,
    /// When it was submitted, in milliseconds since the Unix epoch.
    pub submitted_unix_ms: u64,
    /// Its cells.
    pub cells: usize,
    /// Cells per part (the last part may hold fewer).
    pub part_cells: usize,
    /// The bytes its owner's recordings may take in all, when it was submitted (its result's
    /// recording is kept in the recordings library within it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recordings_quota: Option<u64>,
}

impl JobRecord {
    /// How many parts its cells make.
    pub fn parts(&self) -> usize {
        self.cells.div_ceil(self.part_cells.max(1))
    }
}

/// The cells of one part, as stored (`T` holds them: a vector read back, a slice written).
#[derive(Serialize, Deserialize)]
pub struct StoredPart<T> {
    /// [`JOB_PART_FORMAT`].
    pub format: String,
    /// The first cell.
    pub first_cell: usize,
    /// The cells, in order.
    pub cells: T,
}

/// How a job ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// `done`, `failed` or `cancelled`.
    pub state: String,
    /// Why it failed: the error as the API reports it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<Value>,
    /// When it ended, in milliseconds since the Unix epoch.
    pub ended_unix_ms: u64,
    /// The id of its result's recording in the recordings library, when it was kept there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub recording: Option<String>,
}

/// Whether `id` is a job id: exactly 32 lowercase hexadecimal digits.
pub fn is_valid_id(id: &str) -> bool {
    super::recordings::is_valid_id(id)
}

/// The jobs directory.
#[derive(Clone, Debug)]
pub struct JobStore {
    dir: PathBuf,
}

/// One job's directory.
#[derive(Clone, Debug)]
pub struct JobDir {
    path: PathBuf,
}

fn write_atomically(dir: &Path, name: &str, bytes: &[u8]) -> io::Result<()> {
    let mut tmp = TempFile::create(dir, ".part")?;
    let written = tmp.file.write_all(bytes).and_then(|()| tmp.file.sync_all());
    match written {
        Ok(()) => tmp.persist(&dir.join(name)),
        Err(e) => {
            tmp.discard();
            Err(e)
        }
    }
}

fn read_json<T: DeserializeOwned>(path: &Path) -> Option<T> {
    let bytes = fs::read(path).ok()?;
    match serde_json::from_slice(&bytes) {
        Ok(value) => Some(value),
        Err(error) => {
            tracing::warn!(file = %path.display(), %error, "unreadable; ignored");
            None
        }
    }
}

impl JobStore {
    /// The store in `dir` (made when the first job is submitted) and the jobs it holds, oldest
    /// first; directories that are not jobs are left alone, and leftover temporary files removed.
    pub fn open(dir: impl Into<PathBuf>) -> (Self, Vec<(JobRecord, JobDir)>) {
        let store = JobStore { dir: dir.into() };
        let mut found = Vec::new();
        for entry in fs::read_dir(&store.dir).into_iter().flatten().flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            if !is_valid_id(&name) {
                continue;
            }
            let job = JobDir { path: entry.path() };
            for sub in [job.path.clone(), job.parts_dir()] {
                remove_temporary_files(&sub);
            }
            match read_json::<JobRecord>(&job.path.join("job.json")) {
                Some(record) if record.format == JOB_FORMAT && record.id == name => {
                    found.push((record, job))
                }
                _ => tracing::warn!(dir = %job.path.display(), "not a job; left alone"),
            }
        }
        found.sort_by(|(a, _), (b, _)| {
            (a.submitted_unix_ms, &a.id).cmp(&(b.submitted_unix_ms, &b.id))
        });
        (store, found)
    }

    /// Makes the directory of a new job and writes its record.
    pub fn create(&self, record: &JobRecord) -> io::Result<JobDir> {
        let job = JobDir {
            path: self.dir.join(&record.id),
        };
        fs::create_dir_all(job.parts_dir())?;
        let bytes = serde_json::to_vec_pretty(record).map_err(io::Error::other)?;
        write_atomically(&job.path, "job.json", &bytes)?;
        Ok(job)
    }
}

/// Removes temporary files in `dir` that no writer holds any more.
fn remove_temporary_files(dir: &Path) {
    for entry in fs::read_dir(dir).into_iter().flatten().flatten() {
        if entry.file_name().to_string_lossy().starts_with(TMP_PREFIX) {
            super::tempfile::remove_if_abandoned(&entry.path());
        }
    }
}

impl JobDir {
    fn parts_dir(&self) -> PathBuf {
        self.path.join("parts")
    }

    fn part_name(cells: &Range<usize>) -> String {
        format!("{}-{}.json", cells.start, cells.end)
    }

    /// The stored cells `cells`, if that part was finished and reads back whole; a part that
    /// does not (damaged, or of other cells) is logged and computed again.
    pub fn read_part<C: DeserializeOwned>(&self, cells: &Range<usize>) -> Option<Vec<C>> {
        let path = self.parts_dir().join(Self::part_name(cells));
        if !path.exists() {
            return None;
        }
        let part: StoredPart<Vec<C>> = read_json(&path)?;
        let fits = part.format == JOB_PART_FORMAT
            && part.first_cell == cells.start
            && part.cells.len() == cells.len();
        if !fits {
            tracing::warn!(file = %path.display(), "a part of other cells; computed again");
            return None;
        }
        Some(part.cells)
    }

    /// Stores the finished `cells` of the part starting at `first_cell`.
    pub fn write_part<C: Serialize>(&self, first_cell: usize, cells: &[C]) -> io::Result<()> {
        let part = StoredPart {
            format: JOB_PART_FORMAT.to_string(),
            first_cell,
            cells,
        };
        let bytes = serde_json::to_vec(&part).map_err(io::Error::other)?;
        let range = first_cell..first_cell + cells.len();
        write_atomically(&self.parts_dir(), &Self::part_name(&range), &bytes)
    }

    /// How many parts are stored.
    pub fn parts_stored(&self) -> usize {
        fs::read_dir(self.parts_dir())
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| {
                let name = e.file_name();
                let name = name.to_string_lossy();
                !name.starts_with(TMP_PREFIX) && name.ends_with(".json")
            })
            .count()
    }

    /// Appends an event line (without its newline).
    pub fn append_event(&self, line: &[u8]) -> io::Result<()> {
        let mut file: File = OpenOptions::new()
            .create(true)
            .append(true)
            .open(self.path.join("events.ndjson"))?;
        let mut bytes = Vec::with_capacity(line.len() + 1);
        bytes.extend_from_slice(line);
        bytes.push(b'\n');
        file.write_all(&bytes)
    }

    /// The events stored, in order. A last line without its newline (a write torn by a crash)
    /// is cut off the file, so that the next event starts a line of its own and every event's
    /// `seq` stays its place in the file.
    pub fn events(&self) -> Vec<String> {
        let path = self.path.join("events.ndjson");
        let mut bytes = fs::read(&path).unwrap_or_default();
        let whole = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        if whole < bytes.len() {
            bytes.truncate(whole);
            let cut = OpenOptions::new()
                .write(true)
                .open(&path)
                .and_then(|f| f.set_len(whole as u64));
            if let Err(error) = cut {
                tracing::warn!(file = %path.display(), %error, "a torn event could not be cut off");
            }
        }
        String::from_utf8_lossy(&bytes)
            .lines()
            .filter(|line| serde_json::from_str::<Value>(line).is_ok())
            .map(str::to_string)
            .collect()
    }

    /// How the job ended, if it has.
    pub fn outcome(&self) -> Option<Outcome> {
        read_json(&self.path.join("outcome.json"))
    }

    /// Records how the job ended.
    pub fn write_outcome(&self, outcome: &Outcome) -> io::Result<()> {
        let bytes = serde_json::to_vec_pretty(outcome).map_err(io::Error::other)?;
        write_atomically(&self.path, "outcome.json", &bytes)
    }

    /// Stores the job's result as `name` (`result.json`, `result.rrd`).
    pub fn write_result(&self, name: &str, bytes: &[u8]) -> io::Result<()> {
        write_atomically(&self.path, name, bytes)
    }

    /// Where the result `name` is kept.
    pub fn result_path(&self, name: &str) -> PathBuf {
        self.path.join(name)
    }

    /// Bytes the job keeps on disk.
    pub fn bytes(&self) -> u64 {
        fn size(dir: &Path) -> u64 {
            fs::read_dir(dir)
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| match e.file_type() {
                    Ok(t) if t.is_dir() => size(&e.path()),
                    _ => e.metadata().map(|m| m.len()).unwrap_or(0),
                })
                .sum()
        }
        size(&self.path)
    }

    /// Removes the job and everything it keeps.
    pub fn remove(&self) -> io::Result<()> {
        fs::remove_dir_all(&self.path)
    }
}

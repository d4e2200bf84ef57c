//! Jobs on disk: a directory per job under the jobs directory, each file written once through a
//! locked temporary file renamed into place ([`super::tempfile`]), except the event log, which is
//! appended to:
//!
//! - `job.json`: what the job is ([`JobRecord`]), written when it is submitted;
//! - `parts/FIRST-END.json`: the cells `FIRST..END` it has finished ([`StoredPart`]), each range
//!   written once; a range written twice (a part computed again after a crash) is the same bytes;
//! - `events.ndjson`: what happened to it, a JSON line per event, in order;
//! - `outcome.json`: how it ended ([`JobOutcome`]), once it has;
//! - `result.json`, and `result.rrd` for a study that has a recording: its document.
//!
//! A server that starts reads every job back ([`JobStore::open`]); those without an outcome go on
//! from their finished parts. A torn last event line (the server killed in the middle of a write)
//! is skipped when read back.
//!
//! Every file but the event log can be kept in a [`Replica`] too (a server with NATS keeps them
//! in a JetStream object store), under the name `ID/FILE`: a server whose disk was lost takes its
//! jobs back from there ([`JobStore::restore`]), and goes on from their finished parts.
//!
//! Everything here is blocking I/O: call it off the async runtime.

use std::collections::BTreeMap;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

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
pub struct JobOutcome {
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

/// A second place a job's files are kept, by name (`ID/FILE`), blocking: the calls come from
/// the jobs' own threads and the service's blocking threads.
pub trait Replica: Send + Sync + std::fmt::Debug {
    /// Keeps `bytes` as `name` (replacing what was kept under it).
    fn put(&self, name: &str, bytes: &[u8]) -> io::Result<()>;
    /// The bytes kept as `name`.
    fn get(&self, name: &str) -> io::Result<Vec<u8>>;
    /// The names kept.
    fn names(&self) -> io::Result<Vec<String>>;
    /// Forgets `name`.
    fn delete(&self, name: &str) -> io::Result<()>;
}

/// What a write of a job's file returns when the file is on disk but the replica did not take
/// it (inside an [`io::Error`] of the replica's kind).
#[derive(Debug)]
pub struct NotReplicated(pub String);

impl std::fmt::Display for NotReplicated {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for NotReplicated {}

/// The replica's `error`, as a write of a job's file returns it.
fn not_replicated(error: io::Error) -> io::Error {
    io::Error::new(error.kind(), NotReplicated(error.to_string()))
}

/// Jobs in the order they were submitted (then by id).
fn oldest_first(jobs: &mut [(JobRecord, JobDir)]) {
    jobs.sort_by(|(a, _), (b, _)| (a.submitted_unix_ms, &a.id).cmp(&(b.submitted_unix_ms, &b.id)));
}

/// The replica of a store and of its jobs' directories, once one is set.
type SharedReplica = Arc<OnceLock<Arc<dyn Replica>>>;

/// The jobs directory.
#[derive(Clone, Debug)]
pub struct JobStore {
    dir: PathBuf,
    replica: SharedReplica,
}

/// One job's directory.
#[derive(Clone, Debug)]
pub struct JobDir {
    path: PathBuf,
    /// The job's id: its files' prefix in the replica.
    id: String,
    replica: SharedReplica,
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
        let store = JobStore {
            dir: dir.into(),
            replica: SharedReplica::default(),
        };
        let mut found = Vec::new();
        for entry in fs::read_dir(&store.dir).into_iter().flatten().flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            if is_valid_id(&name) {
                found.extend(store.read_job(&name));
            }
        }
        oldest_first(&mut found);
        (store, found)
    }

    fn dir_of(&self, id: &str) -> JobDir {
        JobDir {
            path: self.dir.join(id),
            id: id.to_string(),
            replica: self.replica.clone(),
        }
    }

    /// The job `id` as its directory holds it, if that is a job.
    fn read_job(&self, id: &str) -> Option<(JobRecord, JobDir)> {
        let job = self.dir_of(id);
        for sub in [job.path.clone(), job.parts_dir()] {
            remove_temporary_files(&sub);
        }
        match read_json::<JobRecord>(&job.path.join("job.json")) {
            Some(record) if record.format == JOB_FORMAT && record.id == id => Some((record, job)),
            _ => {
                tracing::warn!(dir = %job.path.display(), "not a job; left alone");
                None
            }
        }
    }

    /// Keeps every file written from now on in `replica` too (the first replica set stays).
    pub fn replicate_to(&self, replica: Arc<dyn Replica>) {
        if self.replica.set(replica).is_err() {
            tracing::warn!("the jobs already have a replica; a second one is ignored");
        }
    }

    /// Takes back from the replica every job it keeps that this directory lacks (a server whose
    /// disk was lost, or a new one in its place): its files are written here, its record last,
    /// so that a restore cut short is done again from the start. The jobs taken back, oldest
    /// first; a job that cannot be (an object gone, the replica unreachable) is logged, and
    /// taken back at a later start.
    pub fn restore(&self) -> Vec<(JobRecord, JobDir)> {
        let Some(replica) = self.replica.get() else {
            return Vec::new();
        };
        let names = match replica.names() {
            Ok(names) => names,
            Err(error) => {
                tracing::error!(%error, "the jobs' replica cannot be listed; no job taken back");
                return Vec::new();
            }
        };
        // Each job's files by its id; only jobs with a record are taken back.
        let mut files: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
        for name in &names {
            if let Some((id, file)) = name.split_once('/') {
                files.entry(id).or_default().push(file);
            }
        }
        let mut found = Vec::new();
        for (id, files) in files {
            let wanted = is_valid_id(id)
                && files.contains(&"job.json")
                && !self.dir.join(id).join("job.json").exists();
            if !wanted {
                continue;
            }
            let job = self.dir_of(id);
            match job.take_back(replica.as_ref(), &files) {
                Ok(()) => {
                    found.extend(self.read_job(id));
                    tracing::info!(job = id, "job taken back from the replica");
                }
                Err(error) => {
                    tracing::error!(job = id, %error, "a job could not be taken back; it will be at the next start");
                    let _ = fs::remove_dir_all(&job.path);
                }
            }
        }
        oldest_first(&mut found);
        found
    }

    /// Makes the directory of a new job and writes its record.
    pub fn create(&self, record: &JobRecord) -> io::Result<JobDir> {
        let job = self.dir_of(&record.id);
        fs::create_dir_all(job.parts_dir())?;
        let bytes = serde_json::to_vec_pretty(record).map_err(io::Error::other)?;
        if let Err(error) = job.keep("job.json", &bytes) {
            // Refused, so not a job: the next server must not find it.
            let _ = fs::remove_dir_all(&job.path);
            return Err(error);
        }
        Ok(job)
    }
}

/// Whether `name` is a plain file name (no separator, not `.` or `..`, not a temporary file's).
fn is_file_name(name: &str) -> bool {
    !name.is_empty()
        && !name.contains(['/', '\\'])
        && name != "."
        && name != ".."
        && !name.starts_with(TMP_PREFIX)
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

    /// Writes the job's `files` (names under its directory) from the replica here, the record
    /// last; names this store never writes are skipped.
    fn take_back(&self, replica: &dyn Replica, files: &[&str]) -> io::Result<()> {
        fs::create_dir_all(self.parts_dir())?;
        let others = files.iter().copied().filter(|&f| f != "job.json");
        for file in others.chain(["job.json"]) {
            let place = match file.split('/').collect::<Vec<_>>()[..] {
                ["parts"] => None,
                [name] if is_file_name(name) => Some((self.path.clone(), name)),
                ["parts", name] if is_file_name(name) => Some((self.parts_dir(), name)),
                _ => None,
            };
            let Some((dir, name)) = place else {
                tracing::warn!(name = file, job = %self.id, "not a job's file; not taken back");
                continue;
            };
            let bytes = replica.get(&format!("{}/{file}", self.id))?;
            write_atomically(&dir, name, &bytes)?;
        }
        Ok(())
    }

    /// Writes `file` (a name under the job's directory: `job.json`, `parts/…`) once, and keeps
    /// it in the replica when there is one.
    fn keep(&self, file: &str, bytes: &[u8]) -> io::Result<()> {
        let (dir, name) = match file.rsplit_once('/') {
            Some((sub, name)) => (self.path.join(sub), name),
            None => (self.path.clone(), file),
        };
        write_atomically(&dir, name, bytes)?;
        match self.replica.get() {
            Some(replica) => {
                (replica.put(&format!("{}/{file}", self.id), bytes)).map_err(not_replicated)
            }
            None => Ok(()),
        }
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
        self.keep(&format!("parts/{}", Self::part_name(&range)), &bytes)
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

    /// Puts into the replica the job's files it lacks (a job begun while the server had no
    /// replica), its record last; how many. Nothing without a replica.
    pub fn replicate_missing(&self) -> io::Result<usize> {
        let Some(replica) = self.replica.get() else {
            return Ok(0);
        };
        let prefix = format!("{}/", self.id);
        let names = replica.names().map_err(not_replicated)?;
        let kept: std::collections::HashSet<&str> = names
            .iter()
            .filter_map(|n| n.strip_prefix(&prefix))
            .collect();
        let files = self.kept_files();
        let (record, others): (Vec<&String>, Vec<&String>) =
            files.iter().partition(|f| *f == "job.json");
        let mut put = 0;
        for file in others.into_iter().chain(record) {
            if !kept.contains(&file.as_str()) {
                let bytes = fs::read(self.path.join(file))?;
                (replica.put(&format!("{prefix}{file}"), &bytes)).map_err(not_replicated)?;
                put += 1;
            }
        }
        Ok(put)
    }

    /// The files kept in the replica as they are here (`job.json` first, then the others and
    /// `parts/…`): all but the event log and temporary files.
    fn kept_files(&self) -> Vec<String> {
        let names = |dir: &Path| -> Vec<String> {
            (fs::read_dir(dir).into_iter().flatten().flatten())
                .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| is_file_name(n) && n != "events.ndjson")
                .collect()
        };
        let mut files = names(&self.path);
        files.sort_by_key(|f| f != "job.json");
        files.extend(
            names(&self.parts_dir())
                .into_iter()
                .map(|n| format!("parts/{n}")),
        );
        files
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
    pub fn outcome(&self) -> Option<JobOutcome> {
        read_json(&self.path.join("outcome.json"))
    }

    /// Records how the job ended.
    pub fn write_outcome(&self, outcome: &JobOutcome) -> io::Result<()> {
        let bytes = serde_json::to_vec_pretty(outcome).map_err(io::Error::other)?;
        self.keep("outcome.json", &bytes)
    }

    /// Stores the job's result as `name` (`result.json`, `result.rrd`).
    pub fn write_result(&self, name: &str, bytes: &[u8]) -> io::Result<()> {
        self.keep(name, bytes)
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

    /// Removes the job and everything it keeps, here and in the replica.
    pub fn remove(&self) -> io::Result<()> {
        if let Some(replica) = self.replica.get() {
            // The names are the files here (not a listing of the whole bucket); the record
            // first: a removal cut short leaves files that no restore takes back.
            for file in self.kept_files() {
                replica
                    .delete(&format!("{}/{file}", self.id))
                    .map_err(not_replicated)?;
            }
        }
        fs::remove_dir_all(&self.path)
    }
}

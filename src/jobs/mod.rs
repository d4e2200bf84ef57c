//! Jobs: studies that outlive a request. A job is any study (the body its route takes) submitted
//! once; it runs in the background in parts, each stored as it finishes, so a closed connection,
//! a restart or a SIGKILL of the server loses at most the part that was running, and a job taken
//! up again gives its document bit for bit as if it had run through.
//!
//! - [`study`]: the studies a job can run, read and prepared as their routes do;
//! - [`stored`]: the executor that takes finished parts from disk and stores new ones;
//! - [`fair`]: how parts of different owners' jobs take turns;
//! - `status`: a job's state, status and events; `job`: one job in memory;
//! - `runner`: the thread that starts jobs and the threads that run them;
//! - this module: every job of the server ([`Jobs`]): submitting, listing, cancelling,
//!   removing. Files: [`crate::store::jobs`].
//!
//! At most [`ACTIVE_JOBS`] jobs are started at once, [`ACTIVE_PER_OWNER`] of them per owner; the
//! others wait, queued, without a thread. A started job's parts wait their turn at the fair gate
//! (one part at a time, as a part here runs on every core; [`JobsConfig::parts_in_flight`] at a
//! time on NATS workers) and then, to run here, for one of the service's simulation slots, so
//! that jobs yield to synchronous requests. A running job counts as one run in flight of its
//! owner.

pub mod fair;
mod job;
mod runner;
mod status;
pub mod stored;
pub mod study;

pub use job::Job;
pub use status::{EventKind, JobEvent, JobState, JobStatus};

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

use serde_json::Value;

use crate::access::Usage;
use crate::core::error::{ErrorCode, ErrorDetail};
use crate::core::simulation::Limits;
use crate::executor::StudyExecutor;
use crate::store::jobs::{JobRecord, JobStore, NotReplicated, Replica, JOB_FORMAT};
use crate::store::recordings::{RecordingOwner, RecordingStore};
use crate::store::systems::SystemStore;
use fair::FairGate;
use job::now_ms;
use study::Prepared;

/// Most jobs started at once (the others wait, queued).
pub const ACTIVE_JOBS: usize = 8;
/// Most jobs of one owner started at once.
pub const ACTIVE_PER_OWNER: usize = 2;
/// About how many steps a part takes by default (about a second of two cores on most systems):
/// the work a restart can lose, and the grain at which owners take turns.
pub const DEFAULT_PART_STEPS: u64 = 100_000_000;
/// Parts on NATS workers in flight at once by default: enough to keep a few workers busy with
/// parts of the default size, few enough that a job does not flood the queue.
pub const DEFAULT_PARTS_IN_FLIGHT: usize = 8;
/// Most parts of one job.
pub const MAX_PARTS: usize = 10_000;
/// The default number of jobs an owner may have unfinished.
pub const DEFAULT_MAX_JOBS_PER_OWNER: usize = 1000;
#[derive(Debug, Default)]
struct Board {
    jobs: BTreeMap<String, Arc<Job>>,
    /// Started jobs per owner.
    active: HashMap<String, usize>,
    running: usize,
}

/// Every job of the server, and what runs them.
#[derive(Debug)]
pub struct Jobs {
    store: JobStore,
    max_per_owner: usize,
    part_steps: u64,
    parts_in_flight: usize,
    time_limit: Duration,
    board: Mutex<Board>,
    changed: Condvar,
    /// Where parts that run on this machine take turns: one at a time, as each takes every core
    /// (and a work–precision study's timings compare only with nothing beside them).
    gate_here: FairGate,
    /// Where parts that run on NATS workers take turns: [`JobsConfig::parts_in_flight`] at a
    /// time.
    gate_workers: FairGate,
    stopping: AtomicBool,
}

/// What running jobs takes from the service: the stored systems and limits their requests are
/// prepared with, where their parts run, the runs in flight they count in, and the simulation
/// slots their parts that run here take one of.
#[derive(Clone, Debug)]
pub struct JobContext {
    /// The stored system definitions.
    pub systems: Arc<SystemStore>,
    /// The service's step and sample limits.
    pub limits: Limits,
    /// Where parts run: here or on NATS workers.
    pub executor: StudyExecutor,
    /// Runs in flight per owner.
    pub usage: Arc<Usage>,
    /// The service's shared simulation slots.
    pub slots: Arc<tokio::sync::Semaphore>,
    /// The recordings library, where a job's recording is kept too.
    pub recordings: Arc<RecordingStore>,
}

/// The error of a write of `what` to the jobs directory that failed: `storage_full` when the
/// disk is full, else `storage_unavailable` (naming the replica when the disk took the write
/// and the replica did not).
fn storage_error(what: &str, error: &std::io::Error) -> ErrorDetail {
    tracing::error!(%error, what, "a write to the jobs directory failed");
    let replica = error
        .get_ref()
        .and_then(|e| e.downcast_ref::<NotReplicated>());
    if let Some(replica) = replica {
        return ErrorDetail::new(
            ErrorCode::StorageUnavailable,
            format!("the jobs' replica did not keep {what} ({replica})"),
        );
    }
    match error.kind() {
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded => ErrorDetail::new(
            ErrorCode::StorageFull,
            format!("the jobs directory's disk is full: {what} was not stored"),
        ),
        kind => ErrorDetail::new(
            ErrorCode::StorageUnavailable,
            format!("the jobs directory cannot be written ({kind}): {what} was not stored"),
        ),
    }
}

/// Settings of the jobs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JobsConfig {
    /// The directory jobs are kept in.
    pub dir: PathBuf,
    /// Most unfinished jobs per owner.
    pub max_per_owner: usize,
    /// About how many steps a part takes.
    pub part_steps: u64,
    /// How long a job may run under one server before it fails (its parts are kept).
    pub time_limit: Duration,
    /// Parts on NATS workers in flight at once, over all jobs (a part here takes every core,
    /// so parts here run one at a time whatever this says).
    pub parts_in_flight: usize,
}

impl Jobs {
    /// The jobs kept in `config.dir` (none started yet: see [`Jobs::start`]).
    pub fn open(config: &JobsConfig) -> Self {
        let (store, found) = JobStore::open(&config.dir);
        let jobs = found
            .into_iter()
            .map(|(record, dir)| (record.id.clone(), Arc::new(Job::new(record, dir))))
            .collect();
        Jobs {
            store,
            max_per_owner: config.max_per_owner,
            part_steps: config.part_steps.max(1),
            parts_in_flight: config.parts_in_flight.max(1),
            time_limit: config.time_limit,
            board: Mutex::new(Board {
                jobs,
                ..Board::default()
            }),
            changed: Condvar::new(),
            gate_here: FairGate::new(1),
            gate_workers: FairGate::new(config.parts_in_flight),
            stopping: AtomicBool::new(false),
        }
    }

    fn board(&self) -> MutexGuard<'_, Board> {
        self.board.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The job `id`.
    pub fn get(&self, id: &str) -> Option<Arc<Job>> {
        self.board().jobs.get(id).cloned()
    }

    /// The jobs of `owner` (every one for `None`), oldest first.
    pub fn list(&self, owner: Option<&str>) -> Vec<Arc<Job>> {
        let mut jobs: Vec<Arc<Job>> = self
            .board()
            .jobs
            .values()
            .filter(|j| owner.is_none_or(|o| j.record.owner == o))
            .cloned()
            .collect();
        jobs.sort_by(|a, b| {
            (a.record.submitted_unix_ms, &a.record.id)
                .cmp(&(b.record.submitted_unix_ms, &b.record.id))
        });
        jobs
    }

    /// Why `owner`, with its `quota` of stored bytes, may store nothing more: its recordings in
    /// the library and its jobs' files (parts, results, records) together hold the quota or more.
    /// A job's recording kept in the library is there and in the job's own files: both copies
    /// count, as both take the disk.
    pub fn over_quota(
        &self,
        owner: &str,
        quota: Option<u64>,
        recordings: &RecordingStore,
    ) -> Option<ErrorDetail> {
        let quota = quota?;
        let owned: Vec<Arc<Job>> = (self.board().jobs.values())
            .filter(|j| j.record.owner == owner)
            .cloned()
            .collect();
        let jobs: u64 = owned.iter().map(|j| j.dir.bytes()).sum();
        let recordings = recordings.owned_bytes(owner);
        (jobs + recordings >= quota).then(|| {
            ErrorDetail::new(
                ErrorCode::QuotaExceeded,
                format!(
                    "`{owner}` keeps {jobs} bytes of jobs and {recordings} bytes of recordings, \
                     its quota of {quota} bytes or more: remove finished jobs (DELETE \
                     /api/v1/jobs/ID) or recordings to make room"
                ),
            )
        })
    }

    /// Submits `study` (`request`, read and prepared as `prepared`) for `owner` (with its quota
    /// of recording bytes): 429 when the owner has its quota of unfinished jobs; 507 or 500 when
    /// the job cannot be stored.
    pub fn submit(
        &self,
        owner: &RecordingOwner,
        study: &str,
        request: Value,
        priority: i32,
        prepared: &Prepared,
    ) -> Result<Arc<Job>, ErrorDetail> {
        let (quota, owner) = (owner.quota, owner.name.as_str());
        let unfinished = |board: &Board| {
            board
                .jobs
                .values()
                .filter(|j| j.record.owner == owner && !j.state().ended())
                .count()
        };
        let over_quota = |n: usize| {
            ErrorDetail::new(
                ErrorCode::TooManyRuns,
                format!("`{owner}` has {n} unfinished jobs, its quota; submit more once some end"),
            )
        };
        let n = unfinished(&self.board());
        if n >= self.max_per_owner {
            return Err(over_quota(n));
        }
        let cells = prepared.cells.max(1);
        let per_cell = (prepared.steps / cells as u64).max(1);
        // A whole number of the study's groups, so that its lanes stay full.
        let group = prepared.group.max(1);
        let part_cells = usize::try_from(self.part_steps / per_cell)
            .unwrap_or(usize::MAX)
            .clamp(cells.div_ceil(MAX_PARTS), cells)
            .div_ceil(group)
            * group;
        let record = JobRecord {
            format: JOB_FORMAT.to_string(),
            id: crate::store::recordings::new_id(),
            owner: owner.to_string(),
            study: study.to_string(),
            request,
            priority,
            submitted_unix_ms: now_ms(),
            cells: prepared.cells,
            part_cells,
            recordings_quota: quota,
        };
        // The files are written before the board is locked: its readers are the request handlers.
        let dir = self
            .store
            .create(&record)
            .map_err(|e| storage_error("the job", &e))?;
        let job = Arc::new(Job::new(record, dir));
        job.event(EventKind::Submitted, |e| e.priority = Some(priority));
        let mut board = self.board();
        let n = unfinished(&board);
        if n >= self.max_per_owner {
            drop(board);
            let _ = job.dir.remove();
            return Err(over_quota(n));
        }
        board.jobs.insert(job.record.id.clone(), job.clone());
        drop(board);
        self.changed.notify_all();
        Ok(job)
    }

    /// Cancels `job` if it has not ended (a queued job at once, a running one once its part
    /// stops, between steps); whether it had not ended. It never removes a job.
    pub fn cancel(&self, job: &Job) -> bool {
        let board = self.board();
        if job.state().ended() {
            return false;
        }
        job.cancelled.store(true, Ordering::Relaxed);
        job.stop.store(true, Ordering::Relaxed);
        // A queued job is ended after the board's lock, as ending writes files (to the replica
        // too); the flag set under it keeps the starter from starting it meanwhile.
        let queued = job.state() == JobState::Queued;
        drop(board);
        if queued {
            job.end(JobState::Cancelled, None);
        }
        self.wake_gates();
        true
    }

    /// Wakes every part waiting for its turn (after stop flags were set).
    fn wake_gates(&self) {
        self.gate_here.wake();
        self.gate_workers.wake();
    }

    /// The gate of parts that run here (`here`) or on workers.
    pub(super) fn gate(&self, here: bool) -> &FairGate {
        match here {
            true => &self.gate_here,
            false => &self.gate_workers,
        }
    }

    /// Removes an ended `job` and its files; false if it has not ended.
    pub fn remove(&self, job: &Job) -> Result<bool, ErrorDetail> {
        {
            let mut board = self.board();
            if !job.state().ended() {
                return Ok(false);
            }
            board.jobs.remove(&job.record.id);
        }
        if let Err(error) = job.dir.remove() {
            // Still there: it stays listed, and can be removed again.
            let id = job.record.id.clone();
            self.board()
                .jobs
                .insert(id, Arc::new(Job::new(job.record.clone(), job.dir.clone())));
            return Err(storage_error("the removal", &error));
        }
        Ok(true)
    }

    /// Keeps every job file written from now on in `replica` too, and takes back from it, when
    /// the jobs start, the jobs this server's directory lacks.
    pub fn replicate_to(&self, replica: Arc<dyn Replica>) {
        self.store.replicate_to(replica);
    }

    /// Takes back the jobs that the replica keeps and the directory lacks. Their event logs
    /// are not kept there: a job that had ended gets its last event again, so that its event
    /// stream ends; the others get theirs as they run.
    fn restore(&self) {
        for (record, dir) in self.store.restore() {
            let job = Arc::new(Job::new(record, dir));
            let last = match job.state() {
                JobState::Done => Some(EventKind::Done),
                JobState::Failed => Some(EventKind::Failed),
                JobState::Cancelled => Some(EventKind::Cancelled),
                JobState::Queued | JobState::Running => None,
            };
            if let Some(kind) = last {
                let error = job.live().error.clone();
                job.event(kind, |e| e.error = error);
            }
            let id = job.record.id.clone();
            self.board().jobs.entry(id).or_insert(job);
        }
        self.changed.notify_all();
    }

    /// Starts the thread that starts jobs (those left unfinished by a previous server first, in
    /// the order they were submitted; first those the replica keeps and the directory lacks are
    /// taken back).
    pub fn start(self: &Arc<Self>, context: JobContext) {
        let jobs = self.clone();
        let context = Arc::new(context);
        let spawned = std::thread::Builder::new()
            .name("geomint-jobs".into())
            .spawn(move || {
                jobs.restore();
                jobs.dispatch(&context)
            });
        if let Err(error) = spawned {
            tracing::error!(%error, "the job runner could not start; jobs stay queued");
        }
    }

    /// Stops every running job between steps (each keeps its finished parts and is taken up
    /// again by the next server) and starts no more.
    pub fn stop(&self) {
        self.stopping.store(true, Ordering::Relaxed);
        let board = self.board();
        for job in board.jobs.values() {
            if job.state() == JobState::Running {
                job.stop.store(true, Ordering::Relaxed);
            }
        }
        drop(board);
        self.wake_gates();
        self.changed.notify_all();
    }
}

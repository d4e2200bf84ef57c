//! Jobs: studies that outlive a request. A job is any study (the body its route takes) submitted
//! once; it runs in the background in parts, each stored as it finishes, so a closed connection,
//! a restart or a SIGKILL of the server loses at most the part that was running, and a job taken
//! up again gives its document bit for bit as if it had run through.
//!
//! - [`study`]: the studies a job can run, read and prepared as their routes do;
//! - [`stored`]: the executor that takes finished parts from disk and stores new ones;
//! - [`fair`]: how parts of different owners' jobs take turns;
//! - this module: the jobs in memory ([`Jobs`]), the thread that starts them, their states,
//!   events and outcomes. Files: [`crate::store::jobs`].
//!
//! At most [`ACTIVE_JOBS`] jobs are started at once, [`ACTIVE_PER_OWNER`] of them per owner; the
//! others wait, queued, without a thread. A started job's parts wait their turn at the fair gate
//! (one part at a time: a part runs on every core, or on the NATS workers) and then for one of
//! the service's simulation slots, so that jobs yield to synchronous requests. A running job
//! counts as one run in flight of its owner.

pub mod fair;
pub mod stored;
pub mod study;

use std::collections::{BTreeMap, HashMap};
use std::ops::Range;
use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use serde::Serialize;
use serde_json::Value;
use tokio::sync::watch;
use utoipa::ToSchema;

use crate::access::Usage;
use crate::core::error::{ErrorCode, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::executor::StudyExecutor;
use crate::store::dates::rfc3339;
use crate::store::jobs::{JobDir, JobRecord, JobStore, Outcome, JOB_FORMAT};
use crate::store::systems::SystemStore;
use fair::{Claim, FairGate};
use stored::{PartSink, Stored};
use study::Prepared;

/// Most jobs started at once (the others wait, queued).
pub const ACTIVE_JOBS: usize = 8;
/// Most jobs of one owner started at once.
pub const ACTIVE_PER_OWNER: usize = 2;
/// About how many steps a part takes by default (about a second of two cores on most systems):
/// the work a restart can lose, and the grain at which owners take turns.
pub const DEFAULT_PART_STEPS: u64 = 100_000_000;
/// Most parts of one job.
pub const MAX_PARTS: usize = 10_000;
/// The default number of jobs an owner may have unfinished.
pub const DEFAULT_MAX_JOBS_PER_OWNER: usize = 1000;

/// Where a job is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    /// Waiting to start (or to go on, after a restart).
    Queued,
    /// Started: its parts are running or waiting their turn.
    Running,
    /// Finished: its result can be fetched.
    Done,
    /// Stopped by an error, which its status gives.
    Failed,
    /// Cancelled by its owner.
    Cancelled,
}

impl JobState {
    /// Whether the job has ended.
    pub fn ended(self) -> bool {
        matches!(
            self,
            JobState::Done | JobState::Failed | JobState::Cancelled
        )
    }

    /// Its name, as the API writes it.
    pub fn name(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Done => "done",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }

    fn of_outcome(outcome: &Outcome) -> JobState {
        match outcome.state.as_str() {
            "done" => JobState::Done,
            "cancelled" => JobState::Cancelled,
            _ => JobState::Failed,
        }
    }
}

/// A job as its status route answers.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct JobStatus {
    /// Its id.
    #[schema(example = "0f3c9a4e2b7d4c1a8e6f5d3b2a190817")]
    pub id: String,
    /// The kind of study.
    #[schema(example = "sweep")]
    pub study: String,
    /// Who submitted it.
    pub owner: String,
    /// Its priority among its owner's jobs (higher first).
    pub priority: i32,
    /// Where it is.
    pub state: JobState,
    /// When it was submitted (RFC 3339).
    pub submitted: String,
    /// When it last started (RFC 3339; again after a restart).
    pub started: Option<String>,
    /// When it ended (RFC 3339).
    pub ended: Option<String>,
    /// Cells of the study.
    pub cells: usize,
    /// Cells finished.
    pub cells_done: usize,
    /// Parts the cells are run and stored in.
    pub parts: usize,
    /// Parts finished and stored.
    pub parts_done: usize,
    /// Why it failed.
    #[schema(value_type = Option<ErrorDetail>)]
    pub error: Option<Value>,
}

/// What happened to a job.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// It was submitted.
    Submitted,
    /// It started.
    Started,
    /// A part finished and was stored.
    Part,
    /// Its server stopped; it waits for the next one.
    Stopped,
    /// A server took it up again from its stored parts.
    Resumed,
    /// It is done: its result can be fetched.
    Done,
    /// It failed (`error` says why).
    Failed,
    /// It was cancelled.
    Cancelled,
}

/// One line of a job's event stream.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct JobEvent {
    /// Its number: 1, 2, … (`?after=` takes the last one seen).
    pub seq: usize,
    /// What happened.
    pub event: EventKind,
    /// When (RFC 3339).
    pub at: String,
    /// The job's state then.
    pub state: JobState,
    /// Parts finished then (since the job last started).
    pub parts_done: usize,
    /// Parts in all.
    pub parts: usize,
    /// Cells finished then (since the job last started).
    pub cells_done: usize,
    /// Cells in all.
    pub cells: usize,
    /// A part's first cell.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_cell: Option<usize>,
    /// A part's end (one past its last cell).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub end_cell: Option<usize>,
    /// The job's priority (when submitted).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub priority: Option<i32>,
    /// Why it failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<ErrorDetail>)]
    pub error: Option<Value>,
}

#[derive(Debug)]
struct Live {
    state: JobState,
    started_unix_ms: Option<u64>,
    ended_unix_ms: Option<u64>,
    cells_done: usize,
    parts_done: usize,
    error: Option<Value>,
}

/// A job: its record, its directory, and where it is now.
#[derive(Debug)]
pub struct Job {
    /// What was submitted.
    pub record: JobRecord,
    dir: JobDir,
    live: Mutex<Live>,
    /// Set to stop its computation (a cancellation, or the server stopping).
    stop: AtomicBool,
    cancelled: AtomicBool,
    /// Its event lines (with their newlines), in order.
    events: Mutex<Vec<String>>,
    /// The number of event lines, for streams to wait on.
    event_count: watch::Sender<usize>,
}

fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

impl Job {
    fn new(record: JobRecord, dir: JobDir) -> Job {
        let outcome = dir.outcome();
        let events: Vec<String> = dir.events().into_iter().map(|e| format!("{e}\n")).collect();
        let parts_done = dir.parts_stored().min(record.parts());
        let live = Live {
            state: outcome
                .as_ref()
                .map_or(JobState::Queued, JobState::of_outcome),
            started_unix_ms: None,
            ended_unix_ms: outcome.as_ref().map(|o| o.ended_unix_ms),
            cells_done: (parts_done * record.part_cells).min(record.cells),
            parts_done,
            error: outcome.and_then(|o| o.error),
        };
        let count = events.len();
        Job {
            record,
            dir,
            live: Mutex::new(live),
            stop: AtomicBool::new(false),
            cancelled: AtomicBool::new(false),
            events: Mutex::new(events),
            event_count: watch::channel(count).0,
        }
    }

    fn live(&self) -> MutexGuard<'_, Live> {
        self.live.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Where it is now.
    pub fn state(&self) -> JobState {
        self.live().state
    }

    /// Its status.
    pub fn status(&self) -> JobStatus {
        let live = self.live();
        let r = &self.record;
        JobStatus {
            id: r.id.clone(),
            study: r.study.clone(),
            owner: r.owner.clone(),
            priority: r.priority,
            state: live.state,
            submitted: rfc3339(r.submitted_unix_ms),
            started: live.started_unix_ms.map(rfc3339),
            ended: live.ended_unix_ms.map(rfc3339),
            cells: r.cells,
            cells_done: live.cells_done,
            parts: r.parts(),
            parts_done: live.parts_done,
            error: live.error.clone(),
        }
    }

    /// Records an event `kind` with the job's progress (`detail` fills in what the kind adds),
    /// in memory and on disk, and wakes the streams.
    fn event(&self, kind: EventKind, detail: impl FnOnce(&mut JobEvent)) {
        self.event_with(kind, |_| {}, detail);
    }

    /// [`Job::event`], with `change` made to the job's state first under the same lock, so
    /// that a stream never sees a state without the event that says it.
    fn event_with(
        &self,
        kind: EventKind,
        change: impl FnOnce(&mut Live),
        detail: impl FnOnce(&mut JobEvent),
    ) {
        let mut events = self.events.lock().unwrap_or_else(|p| p.into_inner());
        let mut event = {
            let mut live = self.live();
            change(&mut live);
            JobEvent {
                seq: events.len() + 1,
                event: kind,
                at: rfc3339(now_ms()),
                state: live.state,
                parts_done: live.parts_done,
                parts: self.record.parts(),
                cells_done: live.cells_done,
                cells: self.record.cells,
                first_cell: None,
                end_cell: None,
                priority: None,
                error: None,
            }
        };
        detail(&mut event);
        let text = serde_json::to_string(&event).unwrap_or_default();
        if let Err(error) = self.dir.append_event(text.as_bytes()) {
            tracing::warn!(job = %self.record.id, %error, "an event could not be stored");
        }
        events.push(format!("{text}\n"));
        self.event_count.send_replace(events.len());
    }

    /// Event lines after the `after`-th, and whether the job has ended (its last event is
    /// among them, or was before).
    pub fn events_after(&self, after: usize) -> (Vec<String>, bool) {
        let events = self.events.lock().unwrap_or_else(|p| p.into_inner());
        let lines: Vec<String> = events.iter().skip(after).cloned().collect();
        let ended = self.state().ended() && !events.is_empty();
        (lines, ended)
    }

    /// How many events the job has had.
    pub fn event_count(&self) -> usize {
        self.events.lock().unwrap_or_else(|p| p.into_inner()).len()
    }

    /// Its last event line.
    pub fn last_event(&self) -> Option<String> {
        let events = self.events.lock().unwrap_or_else(|p| p.into_inner());
        events.last().cloned()
    }

    /// A receiver of the number of event lines.
    pub fn watch_events(&self) -> watch::Receiver<usize> {
        self.event_count.subscribe()
    }

    /// The stored result `name` (`result.json`, `result.rrd`), if the job is done and has it.
    pub fn result(&self, name: &str) -> Option<PathBuf> {
        let path = self.dir.result_path(name);
        (self.state() == JobState::Done && path.is_file()).then_some(path)
    }

    /// Ends the job in `state` (with `error` for a failure): the outcome stored, then the event.
    fn end(&self, state: JobState, error: Option<Value>) {
        let ended = now_ms();
        let outcome = Outcome {
            state: state.name().to_string(),
            error: error.clone(),
            ended_unix_ms: ended,
        };
        if let Err(e) = self.dir.write_outcome(&outcome) {
            tracing::error!(job = %self.record.id, error = %e, "the outcome could not be stored");
        }
        let kind = match state {
            JobState::Done => EventKind::Done,
            JobState::Cancelled => EventKind::Cancelled,
            _ => EventKind::Failed,
        };
        let change = |live: &mut Live| {
            live.state = state;
            live.ended_unix_ms = Some(ended);
            live.error = error.clone();
        };
        self.event_with(kind, change, |e| e.error = error.clone());
    }
}

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
    time_limit: Duration,
    board: Mutex<Board>,
    changed: Condvar,
    gate: FairGate,
    stopping: AtomicBool,
}

/// What running jobs takes from the service: the stored systems and limits their requests are
/// prepared with, where their parts run, the runs in flight they count in, and the simulation
/// slots their parts take one of.
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
}

/// The error of a write to the jobs directory that failed: `storage_full` when the disk is full,
/// else `storage_unavailable`.
fn storage_error(error: &std::io::Error) -> ErrorDetail {
    tracing::error!(%error, "a write to the jobs directory failed");
    match error.kind() {
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded => ErrorDetail::new(
            ErrorCode::StorageFull,
            "the jobs directory's disk is full; nothing was stored",
        ),
        kind => ErrorDetail::new(
            ErrorCode::StorageUnavailable,
            format!("the jobs directory cannot be written ({kind})"),
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
            time_limit: config.time_limit,
            board: Mutex::new(Board {
                jobs,
                ..Board::default()
            }),
            changed: Condvar::new(),
            gate: FairGate::new(1),
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

    /// Submits `study` (`request`, read and prepared as `prepared`) for `owner`: 429 when the
    /// owner has its quota of unfinished jobs; 507 or 500 when the job cannot be stored.
    pub fn submit(
        &self,
        owner: &str,
        study: &str,
        request: Value,
        priority: i32,
        prepared: &Prepared,
    ) -> Result<Arc<Job>, ErrorDetail> {
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
        };
        // The files are written before the board is locked: its readers are the request handlers.
        let dir = self.store.create(&record).map_err(|e| storage_error(&e))?;
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
        if job.state() == JobState::Queued {
            job.end(JobState::Cancelled, None);
        }
        drop(board);
        self.gate.wake();
        true
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
        job.dir.remove().map_err(|e| storage_error(&e))?;
        Ok(true)
    }

    /// Starts the thread that starts jobs (those left unfinished by a previous server first, in
    /// the order they were submitted).
    pub fn start(self: &Arc<Self>, context: JobContext) {
        let jobs = self.clone();
        let context = Arc::new(context);
        let spawned = std::thread::Builder::new()
            .name("geomint-jobs".into())
            .spawn(move || jobs.dispatch(&context));
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
        self.gate.wake();
        self.changed.notify_all();
    }

    /// The next queued job to start: of the owner with the fewest started, then of the highest
    /// priority, then the first submitted.
    fn next_queued(board: &Board) -> Option<Arc<Job>> {
        let started = |owner: &str| board.active.get(owner).copied().unwrap_or(0);
        board
            .jobs
            .values()
            .filter(|j| {
                j.state() == JobState::Queued && started(&j.record.owner) < ACTIVE_PER_OWNER
            })
            .min_by_key(|j| {
                let r = &j.record;
                (
                    started(&r.owner),
                    -i64::from(r.priority),
                    r.submitted_unix_ms,
                )
            })
            .cloned()
    }

    fn dispatch(self: &Arc<Self>, context: &Arc<JobContext>) {
        let mut board = self.board();
        loop {
            if self.stopping.load(Ordering::Relaxed) {
                return;
            }
            while board.running < ACTIVE_JOBS {
                let Some(job) = Self::next_queued(&board) else {
                    break;
                };
                board.running += 1;
                *board.active.entry(job.record.owner.clone()).or_insert(0) += 1;
                job.live().state = JobState::Running;
                let (jobs, context, started) = (self.clone(), context.clone(), job.clone());
                let spawned = std::thread::Builder::new()
                    .name(format!("geomint-job-{}", &job.record.id[..8]))
                    .spawn(move || jobs.run(&started, &context));
                if let Err(error) = spawned {
                    tracing::error!(%error, "a job could not start; it stays queued");
                    job.live().state = JobState::Queued;
                    board.running -= 1;
                    if let Some(n) = board.active.get_mut(&job.record.owner) {
                        *n -= 1;
                    }
                    break;
                }
            }
            board = self
                .changed
                .wait_timeout(board, Duration::from_secs(1))
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// Runs `job` to its end, or until the server stops.
    fn run(&self, job: &Arc<Job>, context: &JobContext) {
        let resumed = job.dir.parts_stored() > 0;
        {
            let mut live = job.live();
            live.started_unix_ms = Some(now_ms());
            live.parts_done = 0;
            live.cells_done = 0;
        }
        let kind = if resumed {
            EventKind::Resumed
        } else {
            EventKind::Started
        };
        job.event(kind, |_| {});
        tracing::info!(job = %job.record.id, study = %job.record.study, resumed, "job started");
        let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| self.compute(job, context)));
        // The outcome is written before the board is locked: its readers are the request
        // handlers. A cancellation now finds the job running and only sets its flags.
        match outcome {
            Ok(Ok(())) => job.end(JobState::Done, None),
            _ if job.cancelled.load(Ordering::Relaxed) => job.end(JobState::Cancelled, None),
            _ if self.stopping.load(Ordering::Relaxed) => {
                job.live().state = JobState::Queued;
                job.event(EventKind::Stopped, |_| {});
            }
            Ok(Err(error)) => {
                let detail = serde_json::to_value(&error).unwrap_or(Value::Null);
                job.end(JobState::Failed, Some(detail));
            }
            Err(_) => {
                let detail = ErrorDetail::new(
                    ErrorCode::Internal,
                    "the job's computation panicked; the details are in the server log",
                );
                job.end(JobState::Failed, serde_json::to_value(detail).ok());
            }
        }
        tracing::info!(job = %job.record.id, state = job.state().name(), "job left the runner");
        let mut board = self.board();
        board.running -= 1;
        if let Some(n) = board.active.get_mut(&job.record.owner) {
            *n -= 1;
        }
        drop(board);
        self.changed.notify_all();
    }

    /// Prepares and runs `job`'s study on its stored parts, and stores its result.
    fn compute(&self, job: &Job, context: &JobContext) -> Result<(), ErrorDetail> {
        let r = &job.record;
        let prepared = study::prepare(&r.study, &r.request, &context.systems, &context.limits)?;
        if prepared.cells != r.cells {
            // A stored system changed or a new version reads the request otherwise: its parts
            // would not be this study's.
            return Err(ErrorDetail::new(
                ErrorCode::Internal,
                format!(
                    "the job's request now prepares a study of {} cells, not the {} it was \
                     submitted with; submit it again",
                    prepared.cells, r.cells
                ),
            ));
        }
        let _in_flight = context.usage.hold(&r.owner);
        let sink = Sink {
            jobs: self,
            job,
            context,
            unfinished: AtomicBool::new(false),
        };
        let executor = Stored {
            dir: &job.dir,
            inner: &context.executor,
            part_cells: r.part_cells,
            sink: &sink,
        };
        let budget = Budget {
            cancel: Some(&job.stop),
            deadline: Instant::now().checked_add(self.time_limit),
        };
        let results = prepared.run(&executor, budget)?;
        if sink.unfinished.load(Ordering::Relaxed) {
            return Err(ErrorDetail::new(
                ErrorCode::Timeout,
                format!(
                    "the job ran for its time limit of {} s without finishing; its finished parts \
                     are kept",
                    self.time_limit.as_secs()
                ),
            ));
        }
        let store = |name: &str, bytes: &[u8]| {
            job.dir
                .write_result(name, bytes)
                .map_err(|e| storage_error(&e))
        };
        store("result.json", &results.json)?;
        if let Some(rrd) = &results.rrd {
            store("result.rrd", rrd)?;
        }
        Ok(())
    }
}

/// A running job's turns and progress.
struct Sink<'a> {
    jobs: &'a Jobs,
    job: &'a Job,
    context: &'a JobContext,
    /// Whether a part stopped short (the time limit).
    unfinished: AtomicBool,
}

impl PartSink for Sink<'_> {
    fn turn(&self, steps: u64) -> Option<Box<dyn Send + '_>> {
        let r = &self.job.record;
        let claim = Claim {
            owner: r.owner.clone(),
            priority: r.priority,
            submitted: (r.submitted_unix_ms, r.id.clone()),
            steps,
        };
        let turn = self.jobs.gate.wait(claim, &self.job.stop)?;
        // Then one of the service's slots, so that a synchronous request finds the machine as
        // busy as it is.
        loop {
            if self.job.stop.load(Ordering::Relaxed) {
                return None;
            }
            if let Ok(slot) = self.context.slots.clone().try_acquire_owned() {
                return Some(Box::new((turn, slot)));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn cell_done(&self) {
        self.job.live().cells_done += 1;
    }

    fn part_unfinished(&self) {
        self.unfinished.store(true, Ordering::Relaxed);
    }

    fn part_done(&self, cells: Range<usize>, stored: bool) {
        self.job.live().parts_done += 1;
        if !stored {
            self.job.event(EventKind::Part, |e| {
                e.first_cell = Some(cells.start);
                e.end_cell = Some(cells.end);
            });
        }
    }
}

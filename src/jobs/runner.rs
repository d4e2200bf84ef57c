//! How jobs run: the thread that starts queued jobs, and a started job's thread, which runs its
//! study on its stored parts, takes turns at the fair gate and stores its result.

use std::ops::Range;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;

use super::fair::Claim;
use super::job::{now_ms, Job};
use super::status::{EventKind, JobState};
use super::stored::{PartSink, Stored};
use super::{storage_error, study, Board, JobContext, Jobs, ACTIVE_JOBS, ACTIVE_PER_OWNER};
use crate::core::error::{ErrorCode, ErrorDetail};
use crate::core::run::Budget;
use crate::store::recordings::{Contents, RecordingOwner};

impl Jobs {
    /// The next queued job to start: of the owner with the fewest started, then of the highest
    /// priority, then the first submitted.
    fn next_queued(board: &Board) -> Option<Arc<Job>> {
        let started = |owner: &str| board.active.get(owner).copied().unwrap_or(0);
        board
            .jobs
            .values()
            .filter(|j| {
                j.state() == JobState::Queued
                    && !j.cancelled.load(Ordering::Relaxed)
                    && started(&j.record.owner) < ACTIVE_PER_OWNER
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

    /// The job starter's loop: starts queued jobs, each on a thread of its own, while fewer than
    /// [`ACTIVE_JOBS`] run, and waits for a change; returns once the server stops.
    pub(super) fn dispatch(self: &Arc<Self>, context: &Arc<JobContext>) {
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
            Ok(Ok(recording)) => {
                job.live().recording = recording;
                job.end(JobState::Done, None);
            }
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

    /// Prepares and runs `job`'s study on its stored parts, and stores its result: the id of its
    /// recording in the recordings library, when it has one that was kept there.
    fn compute(&self, job: &Job, context: &JobContext) -> Result<Option<String>, ErrorDetail> {
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
        // A job begun while the server had no NATS goes into its bucket now, whole.
        let put =
            (job.dir.replicate_missing()).map_err(|e| storage_error("the job's files", &e))?;
        if put > 0 {
            tracing::info!(job = %r.id, files = put, "the job's files put into the replica");
        }
        let _in_flight = context.usage.hold(&r.owner);
        let sink = Sink {
            jobs: self,
            job,
            context,
            unfinished: AtomicBool::new(false),
            failure: Mutex::new(None),
        };
        let executor = Stored {
            dir: &job.dir,
            inner: &context.executor,
            part_cells: r.part_cells,
            in_flight: self.parts_in_flight,
            sink: &sink,
        };
        let budget = Budget {
            cancel: Some(&job.stop),
            deadline: Instant::now().checked_add(self.time_limit),
        };
        // A part the disk could not take fails the job as `storage_full` (or
        // `storage_unavailable`), not as its executor's failure; an owner out of room as
        // `quota_exceeded`. The parts stored before stay.
        let failure = || {
            sink.failure
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .take()
        };
        let results = prepared
            .run(&executor, budget)
            .map_err(|e| failure().unwrap_or_else(|| e.into()))?;
        if let Some(failure) = failure() {
            return Err(failure);
        }
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
        if let Some(full) = self.over_quota(&r.owner, r.recordings_quota, &context.recordings) {
            return Err(full);
        }
        let store = |name: &str, bytes: &[u8]| {
            job.dir
                .write_result(name, bytes)
                .map_err(|e| storage_error(&format!("the result ({name})"), &e))
        };
        store("result.json", &results.json)?;
        let Some(rrd) = &results.rrd else {
            return Ok(None);
        };
        store("result.rrd", rrd)?;
        // A copy in the recordings library, within its owner's quota there; the job's own copy
        // stays, so that deleting the library's (or its eviction) does not take the result.
        let owner = RecordingOwner {
            name: r.owner.clone(),
            quota: r.recordings_quota,
        };
        match (context.recordings).keep_bytes(rrd, Contents::job(&r.id, &r.study), &owner) {
            Ok(entry) => Ok(Some(entry.id)),
            Err(error) => {
                tracing::warn!(job = %r.id, %error, "the job's recording was not kept in the library");
                Ok(None)
            }
        }
    }
}

/// A running job's turns and progress.
struct Sink<'a> {
    jobs: &'a Jobs,
    job: &'a Job,
    context: &'a JobContext,
    /// Whether a part stopped short (the time limit).
    unfinished: AtomicBool,
    /// Why the job cannot go on: a finished part the disk could not take, or an owner out of
    /// room.
    failure: Mutex<Option<ErrorDetail>>,
}

impl Sink<'_> {
    /// Ends the job with `error` once its parts stop (the first reason given stays).
    fn fail(&self, error: ErrorDetail) {
        let mut failure = self.failure.lock().unwrap_or_else(|p| p.into_inner());
        failure.get_or_insert(error);
    }
}

impl PartSink for Sink<'_> {
    fn turn(&self, steps: u64, here: bool) -> Option<Box<dyn Send + '_>> {
        let r = &self.job.record;
        // A job's parts count against its owner's quota of stored bytes: none starts once the
        // owner has no room left.
        let recordings = &self.context.recordings;
        if let Some(full) = self
            .jobs
            .over_quota(&r.owner, r.recordings_quota, recordings)
        {
            self.fail(full);
            return None;
        }
        let claim = Claim {
            owner: r.owner.clone(),
            priority: r.priority,
            submitted: (r.submitted_unix_ms, r.id.clone()),
            steps,
        };
        let turn = self.jobs.gate(here).wait(claim, &self.job.stop)?;
        // Then, for a part that runs here, one of the service's slots, so that a synchronous
        // request finds the machine as busy as it is. A part on the workers only waits here.
        if !here {
            return Some(Box::new(turn));
        }
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

    fn not_stored(&self, cells: Range<usize>, error: &std::io::Error) {
        let what = format!("the part of cells {}..{}", cells.start, cells.end);
        self.fail(storage_error(&what, error));
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

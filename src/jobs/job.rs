//! A job in memory: its record, its directory, its state and its events.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Mutex, MutexGuard};
use std::time::{SystemTime, UNIX_EPOCH};

use serde_json::Value;
use tokio::sync::watch;

use super::status::{EventKind, JobEvent, JobState, JobStatus};
use crate::store::dates::rfc3339;
use crate::store::jobs::{JobDir, JobOutcome, JobRecord};

/// What changes while a job runs.
#[derive(Debug)]
pub(super) struct Live {
    pub(super) state: JobState,
    pub(super) started_unix_ms: Option<u64>,
    pub(super) ended_unix_ms: Option<u64>,
    pub(super) cells_done: usize,
    pub(super) parts_done: usize,
    pub(super) error: Option<Value>,
    /// Its result's recording in the recordings library.
    pub(super) recording: Option<String>,
}

/// A job: its record, its directory, and where it is now.
#[derive(Debug)]
pub struct Job {
    /// What was submitted.
    pub record: JobRecord,
    pub(super) dir: JobDir,
    live: Mutex<Live>,
    /// Set to stop its computation (a cancellation, or the server stopping).
    pub(super) stop: AtomicBool,
    pub(super) cancelled: AtomicBool,
    /// Its event lines (with their newlines), in order.
    events: Mutex<Vec<String>>,
    /// The number of event lines, for streams to wait on.
    event_count: watch::Sender<usize>,
}

pub(super) fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

impl Job {
    pub(super) fn new(record: JobRecord, dir: JobDir) -> Job {
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
            recording: outcome.as_ref().and_then(|o| o.recording.clone()),
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

    pub(super) fn live(&self) -> MutexGuard<'_, Live> {
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
            recording: live.recording.clone(),
        }
    }

    /// Records an event `kind` with the job's progress (`detail` fills in what the kind adds),
    /// in memory and on disk, and wakes the streams.
    pub(super) fn event(&self, kind: EventKind, detail: impl FnOnce(&mut JobEvent)) {
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
    pub(super) fn end(&self, state: JobState, error: Option<Value>) {
        let ended = now_ms();
        let outcome = JobOutcome {
            state: state.name().to_string(),
            error: error.clone(),
            ended_unix_ms: ended,
            recording: self.live().recording.clone(),
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

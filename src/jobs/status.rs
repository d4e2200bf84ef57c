//! A job's state, its status and its events, as the routes answer them.

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use crate::core::error::ErrorDetail;
use crate::store::jobs::JobOutcome;

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

    pub(super) fn of_outcome(outcome: &JobOutcome) -> JobState {
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
    /// The id of its result's recording in the recordings library (`/api/v1/recordings/{id}`),
    /// once it is done; null for a study without a recording, or one the owner's quota of
    /// recordings could not hold (its result route still answers `?format=rrd`).
    pub recording: Option<String>,
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

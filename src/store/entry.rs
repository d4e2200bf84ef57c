//! What the recordings store says of each recording: what it holds (a simulation's summary), how
//! it came, who owns it, its size and date — the entry written in its sidecar and listed.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::core::simulation::Simulation;

/// What a recording holds, in brief.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SpecSummary {
    /// System id.
    #[schema(example = "pendulum")]
    pub system: String,
    /// Method labels, in the order asked.
    pub methods: Vec<String>,
    /// Step size.
    pub h: f64,
    /// Steps per method.
    pub steps: u64,
    /// Sampling interval in steps.
    pub every: u64,
    /// Time of the last step.
    pub t_end: f64,
    /// Samples of a run that finishes.
    pub samples_per_method: u64,
}

impl SpecSummary {
    /// The summary of a prepared simulation.
    pub fn of(sim: &Simulation) -> Self {
        SpecSummary {
            system: sim.system_id().to_string(),
            methods: sim.methods.iter().map(|m| m.label()).collect(),
            h: sim.schedule.h,
            steps: sim.schedule.steps,
            every: sim.schedule.every,
            t_end: sim.schedule.steps as f64 * sim.schedule.h,
            samples_per_method: sim.schedule.samples(),
        }
    }
}

/// How a recording came into the store.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    /// Recorded by the server from a simulation request (`POST /api/v1/recordings` with JSON).
    #[default]
    Simulation,
    /// Uploaded as an `.rrd` file (`POST /api/v1/recordings` with `application/octet-stream`).
    Upload,
    /// A job's result (`job` says which).
    Job,
}

/// The job a recording is the result of.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct JobOrigin {
    /// The job's id.
    pub id: String,
    /// Its kind of study (`sweep`, `basins`, …).
    #[schema(example = "sweep")]
    pub study: String,
}

/// What is known of a recording before it is stored: what it holds and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Contents {
    /// The simulation it records, when it records one of this service's simulations.
    pub spec: Option<SpecSummary>,
    /// How it came.
    pub origin: Origin,
    /// The application id written in the recording.
    pub application_id: Option<String>,
    /// The job it is the result of.
    pub job: Option<JobOrigin>,
}

impl Contents {
    /// A recording this server made of `spec`.
    pub fn simulation(spec: SpecSummary) -> Self {
        Contents {
            spec: Some(spec),
            origin: Origin::Simulation,
            application_id: Some(crate::recording::APPLICATION_ID.to_string()),
            job: None,
        }
    }

    /// A recording this server made as the result of the job `id`, a `study`.
    pub fn job(id: &str, study: &str) -> Self {
        Contents {
            spec: None,
            origin: Origin::Job,
            application_id: Some(crate::recording::APPLICATION_ID.to_string()),
            job: Some(JobOrigin {
                id: id.to_string(),
                study: study.to_string(),
            }),
        }
    }
}

/// Who stores a recording, and the bytes its recordings may take in all (`None`: the store's cap).
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingOwner {
    /// The owner's name.
    pub name: String,
    /// Its quota of bytes.
    pub quota: Option<u64>,
}

/// One stored recording.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RecordingEntry {
    /// The id (32 lowercase hex digits).
    #[schema(example = "3f2a9c0d6b1e4f8a9d7c5b3a1e0f2d4c")]
    pub id: String,
    /// When it was stored (RFC 3339, UTC).
    #[schema(example = "2026-01-31T12:00:00.000Z")]
    pub created: String,
    /// Size of the `.rrd` file in bytes.
    pub bytes: u64,
    /// The simulation it records; null for an uploaded recording that is not one of this
    /// service's simulations (another application's, or a study's).
    pub spec: Option<SpecSummary>,
    /// How it came into the store.
    #[serde(default)]
    pub origin: Origin,
    /// The application id written in the recording (`geomint` for this service's own).
    #[serde(default)]
    #[schema(example = "geomint")]
    pub application_id: Option<String>,
    /// Milliseconds since the Unix epoch at creation (orders eviction).
    #[serde(default)]
    pub created_unix_ms: u64,
    /// Who stored it (a token's name, or `anonymous@ADDRESS`): only it or an `admin` token
    /// deletes it, and only its own recordings make room for it. Null for a recording stored
    /// before owners were recorded.
    #[serde(default)]
    #[schema(example = "alice")]
    pub owner: Option<String>,
    /// The job it is the result of (`origin` is `job`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub job: Option<JobOrigin>,
}

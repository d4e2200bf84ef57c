//! The job routes: `POST /api/v1/jobs` submits any study to run in the background (answered 202
//! at once), `GET /api/v1/jobs` lists the caller's jobs, `GET /api/v1/jobs/{id}` gives one's
//! status, `/events` streams what happens to it (NDJSON, resumable with `?after=`), `/result`
//! fetches its document (JSON, or its Rerun recording with `?format=rrd`), `POST …/cancel`
//! cancels it, and `DELETE` removes it once it has ended. See [`crate::jobs`].
//!
//! A job is its owner's: other callers get 404 for it, as for a job that does not exist (`admin`
//! sees and cancels every job). A submitted request is read and prepared at once, so a wrong
//! field is a 422 naming it (under `request.`), never a failed job.

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::sync::Arc;

use axum::body::{Body, Bytes};
use axum::extract::{Path, Query, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use serde_json::Value;
use utoipa::openapi::schema::{AdditionalProperties, ObjectBuilder, OneOfBuilder, Schema, Type};
use utoipa::openapi::{Ref, RefOr};
use utoipa::ToSchema;

use super::answer::{RecordFormat, ResponseFormat};
use super::error::{ApiError, ErrorBody, JsonRefusals};
use super::extract::ApiJson;
use super::paths;
use super::recordings::{rrd_response, RrdFile};
use super::state::{run_blocking, AppState};
use crate::access::{Caller, Scope};
use crate::api::json::{self, Obj};
use crate::api::NDJSON;
use crate::core::error::{ErrorCode, ErrorDetail, Field};
use crate::core::schema;
use crate::jobs::{study, Job, JobEvent, JobState, JobStatus, Jobs};
use crate::store::jobs::is_valid_id;
use crate::store::recordings::RecordingOwner;

/// A job to submit: the kind of study, the request its route takes, and a priority.
#[derive(Debug)]
pub struct JobRequest {
    /// The kind of study, as its route is named: `sweep`, `basins`, `energy-map`, `stability`,
    /// `convergence` or `work-precision`.
    pub study: String,
    /// The study's request: the body its route takes.
    pub request: Value,
    /// Its priority among the owner's jobs: higher runs first (default 0). Owners share the
    /// machine equally whatever their jobs' priorities.
    pub priority: i32,
}

/// Each study with the schema of its route's request.
const STUDY_REQUESTS: [(&str, &str); 6] = [
    ("sweep", "SweepRequest"),
    ("basins", "BasinsRequest"),
    ("energy-map", "EnergyMapRequest"),
    ("stability", "StabilityRequest"),
    ("convergence", "ConvergenceRequest"),
    ("work-precision", "WorkPrecisionRequest"),
];

impl utoipa::PartialSchema for JobRequest {
    /// One of six objects, one per study, each pairing the study's name with its route's
    /// request schema.
    fn schema() -> RefOr<Schema> {
        let mut one_of = OneOfBuilder::new().description(Some(
            "A study to run as a job: its kind (`study`, named as its route), the body its route \
             takes (`request`) and a priority among the owner's jobs.",
        ));
        for (study, request) in STUDY_REQUESTS {
            let priority = ObjectBuilder::new()
                .schema_type(Type::Integer)
                .minimum(Some(-1000))
                .maximum(Some(1000))
                .default(Some(Value::from(0)))
                .description(Some(
                    "Higher runs first among the owner's jobs; owners share the machine equally \
                     whatever their priorities.",
                ));
            one_of = one_of.item(
                ObjectBuilder::new()
                    .property(
                        "study",
                        schema::string_enum("The kind of study.", [study].into_iter()),
                    )
                    .required("study")
                    .property("request", Ref::from_schema_name(request))
                    .required("request")
                    .property("priority", priority)
                    .additional_properties(Some(AdditionalProperties::<Schema>::FreeForm(false))),
            );
        }
        one_of.into()
    }
}

impl ToSchema for JobRequest {}

impl JobRequest {
    /// Reads a job's body, naming the field at fault.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = Obj::new(value, Field::default(), &["study", "request", "priority"])?;
        let priority = obj.optional("priority", |v, field| {
            v.as_i64()
                .filter(|p| (-1000..=1000).contains(p))
                .map(|p| p as i32)
                .ok_or_else(|| {
                    ErrorDetail::at(
                        ErrorCode::InvalidValue,
                        field,
                        format!("must be a whole number in -1000..=1000, got {v}"),
                    )
                })
        })?;
        Ok(JobRequest {
            study: obj.required("study", "the kind of study, e.g. \"sweep\"", json::string)?,
            request: obj.required(
                "request",
                "the study's request, as its route takes it",
                |v, _| Ok(v.clone()),
            )?,
            priority: priority.unwrap_or(0),
        })
    }
}

/// `?after=N` of the event stream: the `seq` of the last event the client saw (0 when absent).
fn events_after(query: &BTreeMap<String, String>) -> Result<usize, ApiError> {
    match query.get("after") {
        None => Ok(0),
        Some(text) => text.parse().map_err(|_| {
            ApiError::from(ErrorDetail::at(
                ErrorCode::InvalidValue,
                "after",
                format!("must be the `seq` of an event, a whole number ≥ 0, got `{text}`"),
            ))
        }),
    }
}

fn jobs_of(state: &AppState) -> Result<&Arc<Jobs>, ApiError> {
    state.jobs.as_ref().ok_or_else(|| {
        ApiError::not_found("jobs are off on this server (it was started without a jobs directory)")
    })
}

/// The caller's job `id`: 404 for an id that is not a job, a job that does not exist, or
/// another owner's (unless the caller is `admin`).
fn own_job(state: &AppState, caller: &Caller, id: &str) -> Result<Arc<Job>, ApiError> {
    let missing = || ApiError::not_found(format!("no job `{id}`"));
    if !is_valid_id(id) {
        return Err(missing());
    }
    let job = jobs_of(state)?.get(id).ok_or_else(missing)?;
    let admin = caller.scopes.grants(Scope::Admin);
    match admin || job.record.owner == caller.owner {
        true => Ok(job),
        false => Err(missing()),
    }
}

/// Submits a study as a job: it is read and prepared now (a wrong field is 422 here), stored,
/// and answered 202 with its status; it runs in the background, in parts stored as they finish.
#[utoipa::path(post, path = paths::JOBS, tag = "jobs",
    request_body(content = JobRequest, content_type = "application/json"),
    responses(
        (status = 202, description = "The job, queued; `Location` is its status", body = JobStatus),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range: \
            `study` not a study, or a field of `request` as the study's route would name it \
            (`request.axes[0].min`); the study's own limits apply", body = ErrorBody),
        (status = 429, description = "The caller has its quota of unfinished jobs (code `too_many_runs`)",
            body = ErrorBody),
        (status = 404, description = "Jobs are off on this server", body = ErrorBody),
        JsonRefusals,
    ))]
pub async fn submit_job(
    State(state): State<AppState>,
    caller: Caller,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    let jobs = jobs_of(&state)?.clone();
    let request = JobRequest::from_value(&body)?;
    let owner = RecordingOwner {
        name: caller.owner.clone(),
        quota: caller.quotas.recordings_bytes,
    };
    let job = run_blocking(move || {
        let (systems, limits) = (&state.systems, &state.config.limits);
        let prepared = study::prepare(&request.study, &request.request, systems, limits)?;
        if let Some(full) = jobs.over_quota(&owner.name, owner.quota, &state.recordings) {
            return Err(full);
        }
        jobs.submit(
            &owner,
            &request.study,
            request.request,
            request.priority,
            &prepared,
        )
    })
    .await?
    .map_err(|detail| {
        // A quota of unfinished jobs frees up as they end.
        let retry = detail.code == ErrorCode::TooManyRuns;
        let error = ApiError::from(detail);
        if retry {
            error.with_retry_after(1)
        } else {
            error
        }
    })?;
    tracing::info!(job = %job.record.id, study = %job.record.study, "job submitted");
    let location = format!("{}/{}", paths::JOBS, job.record.id);
    let mut response = (StatusCode::ACCEPTED, Json(job.status())).into_response();
    if let Ok(value) = HeaderValue::from_str(&location) {
        response.headers_mut().insert(header::LOCATION, value);
    }
    Ok(response)
}

/// The caller's jobs, oldest first (`admin`: everyone's).
#[utoipa::path(get, path = paths::JOBS, tag = "jobs",
    responses(
        (status = 200, description = "The jobs", body = Vec<JobStatus>),
        (status = 404, description = "Jobs are off on this server", body = ErrorBody),
    ))]
pub async fn list_jobs(
    State(state): State<AppState>,
    caller: Caller,
) -> Result<Json<Vec<JobStatus>>, ApiError> {
    let admin = caller.scopes.grants(Scope::Admin);
    let owner = (!admin).then_some(caller.owner.as_str());
    let list = jobs_of(&state)?.list(owner);
    Ok(Json(list.iter().map(|j| j.status()).collect()))
}

/// A job's status: its state, the cells and parts finished, and why it failed.
#[utoipa::path(get, path = paths::JOB, tag = "jobs",
    params(("id" = String, Path, description = "The job id")),
    responses(
        (status = 200, description = "The job", body = JobStatus),
        (status = 404, description = "No such job of the caller's", body = ErrorBody),
    ))]
pub async fn get_job(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Json<JobStatus>, ApiError> {
    Ok(Json(own_job(&state, &caller, &id)?.status()))
}

/// A job as it was submitted (the body `POST /api/v1/jobs` took).
#[derive(Serialize, ToSchema)]
pub struct JobSubmission {
    /// The kind of study.
    #[schema(example = "sweep")]
    pub study: String,
    /// The body its study's route takes, as it was sent.
    #[schema(value_type = Object)]
    pub request: Value,
    /// Its priority among its owner's jobs.
    pub priority: i32,
}

/// A job as it was submitted: the study, the request its route takes, the priority (the body of
/// `POST /api/v1/jobs`), so that a client that did not submit it can show or submit it again.
#[utoipa::path(get, path = paths::JOB_REQUEST, tag = "jobs",
    params(("id" = String, Path, description = "The job id")),
    responses(
        (status = 200, description = "The job's submission", body = JobSubmission),
        (status = 404, description = "No such job of the caller's", body = ErrorBody),
    ))]
pub async fn job_request(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Json<JobSubmission>, ApiError> {
    let job = own_job(&state, &caller, &id)?;
    let r = &job.record;
    Ok(Json(JobSubmission {
        study: r.study.clone(),
        request: r.request.clone(),
        priority: r.priority,
    }))
}

/// Cancels a job that has not ended: a queued one at once, a running one between steps (its
/// finished parts are kept). A job that has ended is left as it is. Either way, its status.
#[utoipa::path(post, path = paths::JOB_CANCEL, tag = "jobs",
    params(("id" = String, Path, description = "The job id")),
    responses(
        (status = 200, description = "The job: `cancelled`, or `running` until its part stops \
            between steps, or as it ended", body = JobStatus),
        (status = 404, description = "No such job of the caller's", body = ErrorBody),
    ))]
pub async fn cancel_job(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Json<JobStatus>, ApiError> {
    let job = own_job(&state, &caller, &id)?;
    let jobs = jobs_of(&state)?.clone();
    let status = run_blocking(move || {
        jobs.cancel(&job);
        job.status()
    })
    .await?;
    Ok(Json(status))
}

/// Removes a job that has ended, with its result and its stored parts. A job that has not ended
/// is cancelled first (`POST …/cancel`): removing never stops a job, and cancelling never
/// removes one.
#[utoipa::path(delete, path = paths::JOB, tag = "jobs",
    params(("id" = String, Path, description = "The job id")),
    responses(
        (status = 204, description = "The job was removed"),
        (status = 404, description = "No such job of the caller's", body = ErrorBody),
        (status = 409, description = "The job has not ended (code `job_not_done`)", body = ErrorBody),
    ))]
pub async fn delete_job(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let job = own_job(&state, &caller, &id)?;
    let jobs = jobs_of(&state)?.clone();
    let removed = run_blocking(move || jobs.remove(&job))
        .await?
        .map_err(ApiError::from)?;
    if !removed {
        return Err(ApiError::from(ErrorDetail::new(
            ErrorCode::JobNotDone,
            format!("job `{id}` has not ended; cancel it first (POST …/{id}/cancel)"),
        )));
    }
    Ok(StatusCode::NO_CONTENT.into_response())
}

/// What happens to a job, as NDJSON lines: each with its `seq` (1, 2, …), `event` (`submitted`,
/// `started`, `part`, `stopped` when the server stopped, `resumed` when the next one took it up,
/// then `done`, `failed` with its `error`, or `cancelled`), its time and the job's progress. The
/// stream follows the job and always ends with its last event; `?after=N` starts after the event
/// with `seq` N, so a client that lost its connection goes on where it was (one that had seen
/// the last event gets it again).
#[utoipa::path(get, path = paths::JOB_EVENTS, tag = "jobs",
    params(("id" = String, Path, description = "The job id"),
        ("after" = Option<usize>, Query, description = "Start after the event with this `seq`")),
    responses(
        (status = 200, description = "The events, a JSON line each", content_type = "application/x-ndjson",
            body = JobEvent),
        (status = 404, description = "No such job of the caller's", body = ErrorBody),
        (status = 422, description = "`after` is not a whole number ≥ 0, or beyond the job's events",
            body = ErrorBody),
    ))]
pub async fn job_events(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
    Query(query): Query<BTreeMap<String, String>>,
) -> Result<Response, ApiError> {
    let after = events_after(&query)?;
    let job = own_job(&state, &caller, &id)?;
    let count = job.event_count();
    if after > count {
        return Err(ApiError::from(ErrorDetail::at(
            ErrorCode::InvalidValue,
            "after",
            format!("job `{id}` has had {count} events; `after` is the `seq` of one of them"),
        )));
    }
    let shutdown = state.cancellation();
    let count_changes = job.watch_events();
    // (events seen, whether this answer has sent a line yet); none once the last event is sent.
    let lines = futures_util::stream::unfold(Some((after, false)), move |state| {
        let job = job.clone();
        let mut count = count_changes.clone();
        let mut shutdown = shutdown.clone();
        async move {
            let (mut seen, sent) = state?;
            loop {
                let (mut lines, ended) = job.events_after(seen);
                if lines.is_empty() && ended && !sent {
                    // A client that saw the last event already gets it again: every stream ends
                    // with the job's last event.
                    lines.extend(job.last_event());
                }
                if !lines.is_empty() {
                    seen = (seen + lines.len()).min(job.event_count());
                    let next = (!ended).then_some((seen, true));
                    return Some((Ok::<_, Infallible>(Bytes::from(lines.concat())), next));
                }
                if ended {
                    return None;
                }
                tokio::select! {
                    changed = count.changed() => if changed.is_err() { return None },
                    _ = shutdown.wait_for(|&c| c) => return None,
                }
            }
        }
    });
    let mut response = Response::new(Body::from_stream(lines));
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(NDJSON));
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    Ok(response)
}

/// A done job's document: as its study's route answers it, JSON by default, or its Rerun
/// recording with `?format=rrd` (every study but a convergence study has one).
#[utoipa::path(get, path = paths::JOB_RESULT, tag = "jobs",
    params(("id" = String, Path, description = "The job id"),
        ("format" = Option<RecordFormat>, Query,
        description = "`rrd` the study's Rerun recording; `json` (default) its document")),
    responses(
        (status = 200, description = "The document", content(
            (Object = "application/json"), (RrdFile = "application/octet-stream"))),
        (status = 404, description = "No such job of the caller's", body = ErrorBody),
        (status = 409, description = "The job is not done (code `job_not_done`)", body = ErrorBody),
        (status = 422, description = "`format` is unknown, or `rrd` for a study without a recording",
            body = ErrorBody),
    ))]
pub async fn job_result(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
    Query(query): Query<BTreeMap<String, String>>,
) -> Result<Response, ApiError> {
    let format = ResponseFormat::requested(
        &query,
        &HeaderMap::new(),
        &[ResponseFormat::Json, ResponseFormat::Rrd],
    )?;
    let job = own_job(&state, &caller, &id)?;
    let state_now = job.state();
    if state_now != JobState::Done {
        return Err(ApiError::from(ErrorDetail::new(
            ErrorCode::JobNotDone,
            format!(
                "job `{id}` is {}; its result comes once it is done",
                state_now.name()
            ),
        )));
    }
    let name = match format {
        ResponseFormat::Rrd => "result.rrd",
        _ => "result.json",
    };
    let Some(path) = job.result(name) else {
        return Err(ApiError::from(ErrorDetail::at(
            ErrorCode::InvalidValue,
            "format",
            format!(
                "a {} study has no recording; ask for `json`",
                job.record.study
            ),
        )));
    };
    let bytes = tokio::fs::read(&path).await.map_err(ApiError::internal)?;
    if format == ResponseFormat::Rrd {
        let length = bytes.len() as u64;
        let file = format!("geomint-job-{id}.rrd");
        return Ok(rrd_response(Body::from(bytes), &file, Some(length)));
    }
    let mut response = Response::new(Body::from(bytes));
    response.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    Ok(response)
}

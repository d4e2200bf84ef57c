//! The recording routes: `POST /api/v1/recordings` runs a simulation and stores its Rerun
//! recording, `GET /api/v1/recordings` lists the stored ones, `GET /api/v1/recordings/{id}.rrd`
//! downloads one (`GET /api/v1/recordings/{id}` gives its entry), and
//! `DELETE /api/v1/recordings/{id}` removes it.
//!
//! Ids are checked strictly (32 lowercase hex digits) before any lookup; anything else, path
//! traversal attempts included, is answered 404. The simulation runs behind the same semaphore
//! and time limit as `POST /api/v1/simulate`; writing the file happens on the blocking pool.

use axum::body::{Body, Bytes};
use axum::extract::{Path, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use tokio::io::AsyncReadExt;
use utoipa::ToSchema;

use super::answer::Work;
use super::error::{ApiError, ErrorBody};
use super::extract::ApiJson;
use super::paths;
use super::state::{run_blocking, AppState};
use super::store::{is_valid_id, RecordingEntry, SpecSummary, StoreError};
use crate::api::SimulateRequest;
use crate::core::error::{ErrorCode, ErrorDetail};
use crate::recording::{self, RRD_MEDIA_TYPE};

/// The answer to a stored recording.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct RecordingCreated {
    /// The recording's id.
    #[schema(example = "3f2a9c0d6b1e4f8a9d7c5b3a1e0f2d4c")]
    pub id: String,
    /// Where to download it.
    #[schema(example = "/api/v1/recordings/3f2a9c0d6b1e4f8a9d7c5b3a1e0f2d4c.rrd")]
    pub url: String,
    /// Its size in bytes.
    pub bytes: u64,
}

/// A Rerun recording file (`.rrd`), as the Rerun viewer 0.33 and the Python `rerun-sdk` 0.33
/// read it.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct RrdFile(pub Vec<u8>);

/// The download URL of recording `id`.
pub fn download_url(id: &str) -> String {
    format!("{}/{id}.rrd", paths::RECORDINGS)
}

fn no_recording(name: &str) -> ApiError {
    ApiError::not_found(format!(
        "no recording `{name}`; ids are 32 lowercase hexadecimal digits (see {})",
        paths::RECORDINGS
    ))
}

/// An error of the store as the client sees it.
pub(crate) fn store_error(error: StoreError) -> ApiError {
    match error {
        StoreError::TooLarge { .. } => ApiError::from(ErrorDetail::at(
            ErrorCode::RecordingTooLarge,
            "output.every",
            format!("{error}; sample less often"),
        )),
        other => ApiError::internal(other),
    }
}

/// A `.rrd` answer: `application/octet-stream`, to be saved as `filename`.
pub(crate) fn rrd_response(body: Body, filename: &str, length: Option<u64>) -> Response {
    let mut response = Response::new(body);
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(RRD_MEDIA_TYPE),
    );
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{filename}\"")) {
        headers.insert(header::CONTENT_DISPOSITION, v);
    }
    if let Some(n) = length {
        headers.insert(header::CONTENT_LENGTH, HeaderValue::from(n));
    }
    response
}

/// Runs a simulation (the body is that of `POST /api/v1/simulate`) and stores its Rerun
/// recording: the spec, every run's energy, energy error, invariants, force evaluations, phase
/// portraits and motion in space, and a default blueprint. Past the store's size cap the
/// oldest recordings are deleted.
#[utoipa::path(post, path = paths::RECORDINGS, tag = "recordings",
    request_body(content = SimulateRequest, content_type = "application/json"),
    responses(
        (status = 201, description = "Stored", body = RecordingCreated,
            headers(("Location" = String, description = "The download URL"))),
        (status = 400, description = "Malformed JSON (code `malformed_json`)", body = ErrorBody),
        (status = 413, description = "The body exceeds the size limit", body = ErrorBody),
        (status = 415, description = "The body is not declared as JSON", body = ErrorBody),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of \
            range (as for POST /api/v1/simulate)", body = ErrorBody),
        (status = 503, description = "Every simulation slot is busy", body = ErrorBody,
            headers(("Retry-After" = u64, description = "Seconds to wait before retrying"))),
        (status = 504, description = "The reference run did not finish within the time limit", body = ErrorBody),
        (status = 507, description = "The recording alone exceeds the store's size cap \
            (code `recording_too_large`, field `output.every`)", body = ErrorBody),
        (status = 500, description = "A server fault (details are logged)", body = ErrorBody),
    ))]
pub async fn create_recording(
    State(state): State<AppState>,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    let request = SimulateRequest::from_value(&body)?;
    let sim = request.prepare(&state.config.limits)?;
    let work = Work::admit(&state, sim.methods.len()).await?;
    let workers = work.workers();
    let store = state.recordings.clone();
    tracing::info!(system = %sim.system_id(), methods = sim.methods.len(), steps = sim.schedule.steps, "recording started");
    let entry = work
        .run(move |budget| {
            let doc = sim.simulate(workers, budget)?;
            if budget
                .cancel
                .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
            {
                // The client went away or the server is stopping: nothing to keep.
                return Err(ApiError::new(
                    StatusCode::SERVICE_UNAVAILABLE,
                    ErrorDetail::new(ErrorCode::Overloaded, "the recording was cancelled"),
                ));
            }
            store
                .save(SpecSummary::of(&sim), |w| {
                    recording::write_rrd(w, &request, &doc)
                })
                .map_err(store_error)
        })
        .await?;
    let url = download_url(&entry.id);
    let mut response = (
        StatusCode::CREATED,
        Json(RecordingCreated {
            id: entry.id,
            url: url.clone(),
            bytes: entry.bytes,
        }),
    )
        .into_response();
    if let Ok(v) = HeaderValue::from_str(&url) {
        response.headers_mut().insert(header::LOCATION, v);
    }
    Ok(response)
}

/// The stored recordings, newest first: id, creation time, size and what each holds.
#[utoipa::path(get, path = paths::RECORDINGS, tag = "recordings",
    responses((status = 200, description = "Every stored recording", body = Vec<RecordingEntry>)))]
pub async fn list_recordings(State(state): State<AppState>) -> Json<Vec<RecordingEntry>> {
    Json(state.recordings.list())
}

/// One recording: `{id}.rrd` downloads the file (`application/octet-stream`, as an
/// attachment); `{id}` alone gives its entry as JSON.
#[utoipa::path(get, path = paths::RECORDING, tag = "recordings",
    params(("id" = String, Path,
        description = "The recording id followed by `.rrd` for the file, or the id alone for its entry",
        example = "3f2a9c0d6b1e4f8a9d7c5b3a1e0f2d4c.rrd")),
    responses(
        (status = 200, description = "The recording file, or its entry",
            content((RrdFile = "application/octet-stream"), (RecordingEntry = "application/json"))),
        (status = 404, description = "No such recording (also for anything that is not an id)", body = ErrorBody),
    ))]
pub async fn get_recording(
    State(state): State<AppState>,
    Path(name): Path<String>,
) -> Result<Response, ApiError> {
    let (id, file) = match name.strip_suffix(".rrd") {
        Some(id) => (id, true),
        None => (name.as_str(), false),
    };
    let (entry, path) = state
        .recordings
        .get(id)
        .ok_or_else(|| no_recording(&name))?;
    if !file {
        return Ok(Json(entry).into_response());
    }
    // Deleted (or evicted) since the lookup: as if it had never been there.
    let handle = tokio::fs::File::open(&path)
        .await
        .map_err(|_| no_recording(&name))?;
    let chunks = futures_util::stream::unfold(Some(handle), |state| async move {
        let mut file = state?;
        let mut buffer = vec![0u8; 256 * 1024];
        match file.read(&mut buffer).await {
            Ok(0) => None,
            Ok(n) => {
                buffer.truncate(n);
                Some((Ok(Bytes::from(buffer)), Some(file)))
            }
            Err(e) => Some((Err(e), None)),
        }
    });
    Ok(rrd_response(
        Body::from_stream(chunks),
        &format!("geomint-{}.rrd", entry.id),
        Some(entry.bytes),
    ))
}

/// Deletes a recording.
#[utoipa::path(delete, path = paths::RECORDING, tag = "recordings",
    params(("id" = String, Path, description = "The recording id",
        example = "3f2a9c0d6b1e4f8a9d7c5b3a1e0f2d4c")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 404, description = "No such recording", body = ErrorBody),
    ))]
pub async fn delete_recording(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    if !is_valid_id(&id) {
        return Err(no_recording(&id));
    }
    let store = state.recordings.clone();
    let key = id.clone();
    if run_blocking(move || store.delete(&key)).await? {
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(no_recording(&id))
    }
}

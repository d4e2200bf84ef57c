//! The recording routes: `POST /api/v1/recordings` runs a simulation and stores its Rerun
//! recording (a JSON body) or stores an uploaded `.rrd` file (an `application/octet-stream`
//! body), `GET /api/v1/recordings` lists the stored ones, `GET /api/v1/recordings/{id}.rrd`
//! downloads one (`GET /api/v1/recordings/{id}` gives its entry),
//! `GET /api/v1/recordings/{id}/samples` reads a simulation recording's samples back as JSON,
//! and `DELETE /api/v1/recordings/{id}` removes it.
//!
//! Ids are checked strictly (32 lowercase hex digits) before any lookup; anything else, path
//! traversal attempts included, is answered 404. The simulation runs behind the same semaphore
//! and time limit as `POST /api/v1/simulate`; writing the file happens on the blocking pool.
//!
//! An upload is bounded by the store's size cap (its declared length is checked before the body
//! is read, the bytes received as they come), written to a locked temporary file in the data
//! directory, decoded in full with Rerun's decoder ([`crate::recording::read::inspect`]), and only then
//! renamed into place; a refused upload leaves nothing behind and touches no other recording.
//! Files are served with `tower-http`'s `ServeFile`: the Rerun web viewer 0.33 fetches a
//! recording with one plain GET and decodes the body as it arrives, and range requests
//! (`Accept-Ranges: bytes`) serve resumed downloads.

use std::sync::atomic::Ordering;

use axum::body::Body;
use axum::extract::{FromRequest, Path, Query, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use futures_util::StreamExt;
use serde::Serialize;
use serde_json::Value;
use tokio::io::AsyncWriteExt;
use tower::ServiceExt;
use tower_http::services::ServeFile;
use utoipa::ToSchema;

use super::answer::{Client, Work};
use super::error::ApiError;
use super::error::ErrorBody;
use super::extract::ApiJson;
use super::paths;
use super::state::{run_blocking, AppState, Cost};
use crate::access::Caller;
use crate::api::SimulateRequest;
use crate::core::error::{ErrorCode, ErrorDetail};
use crate::recording::read::{self as recorded, ReadError, RecordedDocument};
use crate::recording::{self, RRD_MEDIA_TYPE};
use crate::store::recordings::{
    Contents, Origin, RecordingEntry, RecordingOwner, SpecSummary, StoreError,
};

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

/// The refusal to delete what another owner stored.
pub(crate) fn not_yours(what: &str, id: &str, owner: Option<&str>) -> ApiError {
    let whose = match owner {
        Some(owner) => format!("belongs to `{owner}`"),
        None => "was stored before owners were recorded".to_string(),
    };
    ApiError::from(ErrorDetail::at(
        ErrorCode::Forbidden,
        "id",
        format!("the {what} `{id}` {whose}: only its owner or an `admin` token deletes it"),
    ))
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
        StoreError::OverQuota { .. } => ApiError::from(ErrorDetail::new(
            ErrorCode::QuotaExceeded,
            error.to_string(),
        )),
        StoreError::FullOfOthers { .. } => {
            ApiError::from(ErrorDetail::new(ErrorCode::StorageFull, error.to_string()))
        }
        other => ApiError::storage("recording store", &other),
    }
}

/// Who a recording stored for `client` belongs to, with its quota of bytes.
fn owner_of(client: &Client) -> RecordingOwner {
    RecordingOwner {
        name: client.caller.owner.clone(),
        quota: client.caller.quotas.recordings_bytes,
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

/// The `Content-Length` a request declares, if any.
fn declared_length(headers: &HeaderMap) -> Option<u64> {
    headers
        .get(header::CONTENT_LENGTH)?
        .to_str()
        .ok()?
        .parse()
        .ok()
}

/// Whether a request's body is declared as an `.rrd` file.
pub(crate) fn is_rrd_upload(headers: &HeaderMap) -> bool {
    headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.split(';').next())
        .is_some_and(|essence| essence.trim().eq_ignore_ascii_case(RRD_MEDIA_TYPE))
}

/// The answer to a stored recording: 201, its id, URL and size, and `Location`.
fn created(entry: RecordingEntry) -> Response {
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
    response
}

/// Stores a recording. With a JSON body (that of `POST /api/v1/simulate`) the server runs the
/// simulation and records it: the spec, every run's energy, energy error, invariants, force
/// evaluations, phase portraits and motion in space, and a default blueprint. With an
/// `application/octet-stream` body it stores the uploaded `.rrd` file, once it is checked: a
/// complete Rerun recording (RRD header, every message decoding, the stream footer) written by
/// Rerun 0.23 to 0.33, the versions the page's viewer reads, and no larger than the store's size
/// cap. Past the cap the oldest recordings are deleted.
#[utoipa::path(post, path = paths::RECORDINGS, tag = "recordings",
    request_body(content(
        (SimulateRequest = "application/json"),
        (RrdFile = "application/octet-stream"),
    )),
    responses(
        (status = 201, description = "Stored", body = RecordingCreated,
            headers(("Location" = String, description = "The download URL"))),
        (status = 400, description = "Malformed JSON (code `malformed_json`), or an upload that \
            could not be read", body = ErrorBody),
        (status = 413, description = "The body exceeds the size limit: the body limit for JSON, \
            the store's size cap for an upload (code `payload_too_large`)", body = ErrorBody),
        (status = 415, description = "The body is neither JSON nor `application/octet-stream`", body = ErrorBody),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of \
            range (as for POST /api/v1/simulate); or the upload is not a complete Rerun \
            recording of a version the viewer reads (code `invalid_recording`, field `body`, \
            the message says what is wrong)", body = ErrorBody),
        (status = 503, description = "Every simulation slot is busy", body = ErrorBody,
            headers(("Retry-After" = u64, description = "Seconds to wait before retrying"))),
        (status = 507, description = "The recording alone exceeds the store's size cap \
            (code `recording_too_large`, field `output.every`)", body = ErrorBody),
        (status = 500, description = "A server fault (details are logged)", body = ErrorBody),
    ))]
pub async fn create_recording(
    State(state): State<AppState>,
    client: Client,
    request: Request,
) -> Result<Response, ApiError> {
    if is_rrd_upload(request.headers()) {
        return upload_recording(state, owner_of(&client), request).await;
    }
    // The route's own body limit is the store's cap (for uploads): JSON keeps the service's.
    if declared_length(request.headers()).is_some_and(|n| n > state.config.body_limit as u64) {
        return Err(payload_too_large("the request body exceeds the size limit"));
    }
    let ApiJson(body) = ApiJson::from_request(request, &state).await?;
    record_simulation(state, client, body).await
}

fn payload_too_large(message: impl Into<String>) -> ApiError {
    ApiError::new(
        StatusCode::PAYLOAD_TOO_LARGE,
        ErrorDetail::new(ErrorCode::PayloadTooLarge, message),
    )
}

/// An upload refused for its content, naming what is wrong.
fn invalid_upload(message: impl std::fmt::Display) -> ApiError {
    ApiError::from(ErrorDetail::at(
        ErrorCode::InvalidRecording,
        "body",
        format!("the upload is not a recording the viewer reads: {message}"),
    ))
}

/// Receives an `.rrd` upload into a locked temporary file, checks it and keeps it.
async fn upload_recording(
    state: AppState,
    owner: RecordingOwner,
    request: Request,
) -> Result<Response, ApiError> {
    let store = state.recordings.clone();
    let cap = store.max_bytes();
    let over_cap = move |bytes: String| {
        payload_too_large(format!(
            "the recording has {bytes} bytes, more than the store's size cap of {cap} bytes"
        ))
    };
    if let Some(n) = declared_length(request.headers()).filter(|&n| n > cap) {
        return Err(over_cap(n.to_string()));
    }
    let opener = store.clone();
    let upload = run_blocking(move || opener.begin_upload())
        .await?
        .map_err(store_error)?;
    let handle = upload.file().map_err(store_error)?;
    let mut file = tokio::fs::File::from_std(handle);
    let mut body = request.into_body().into_data_stream();
    let mut received = 0u64;
    // Dropping `upload` on any early return (or a client that goes away) removes its file.
    while let Some(chunk) = body.next().await {
        let chunk = chunk.map_err(|e| super::server::body_error(&e))?;
        received += chunk.len() as u64;
        if received > cap {
            return Err(over_cap(format!("more than {cap}")));
        }
        file.write_all(&chunk)
            .await
            .map_err(|e| store_error(e.into()))?;
    }
    file.flush().await.map_err(|e| store_error(e.into()))?;
    drop(file);
    if received == 0 {
        return Err(invalid_upload(
            "the body is empty; send the bytes of an .rrd file",
        ));
    }
    tracing::info!(bytes = received, "recording uploaded; checking it");
    let entry = run_blocking(move || -> Result<RecordingEntry, ApiError> {
        let path = upload
            .path()
            .ok_or_else(|| ApiError::internal(StoreError::UploadGone))?;
        let inspected = recorded::inspect(path).map_err(|e| match e {
            ReadError::Io(e) => ApiError::internal(e),
            other => invalid_upload(other),
        })?;
        let contents = Contents {
            spec: inspected.simulation.as_ref().map(SpecSummary::of),
            origin: Origin::Upload,
            application_id: inspected.application_id,
            job: None,
        };
        store
            .keep_upload(upload, contents, &owner)
            .map_err(|e| match e {
                StoreError::TooLarge { bytes, .. } => over_cap(bytes.to_string()),
                StoreError::Incomplete => {
                    invalid_upload("it lacks the RRD header or stream footer")
                }
                other => store_error(other),
            })
    })
    .await??;
    Ok(created(entry))
}

/// Runs the simulation of `body` and stores its recording.
async fn record_simulation(
    state: AppState,
    client: Client,
    body: Value,
) -> Result<Response, ApiError> {
    let request = SimulateRequest::from_value(&body)?;
    let sim = request.prepare(&state.config.limits, &*state.systems)?;
    let request = request.inlined(&*state.systems);
    let work = Work::admit(
        &state,
        sim.methods.len(),
        Cost::Steps(sim.cost()),
        client.clone(),
    )
    .await?;
    let workers = work.workers();
    let store = state.recordings.clone();
    let owner = owner_of(&client);
    tracing::info!(system = %sim.system_id(), methods = sim.methods.len(), steps = sim.schedule.steps, "recording started");
    let entry = work
        .run(move |budget| {
            let doc = sim.simulate(workers, budget)?;
            if budget.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                // The client went away or the server is stopping: nothing to keep.
                return Err(ApiError::new(
                    StatusCode::SERVICE_UNAVAILABLE,
                    ErrorDetail::new(ErrorCode::Overloaded, "the recording was cancelled"),
                ));
            }
            store
                .save(SpecSummary::of(&sim), &owner, |w| {
                    recording::write_rrd(w, &recording::Spec::of(&request), &doc)
                })
                .map_err(store_error)
        })
        .await?;
    Ok(created(entry))
}

/// The stored recordings, newest first: id, creation time, size, owner, what each holds, and
/// whether the caller may delete it; `?owner=NAME` lists only those of one owner.
#[utoipa::path(get, path = paths::RECORDINGS, tag = "recordings",
    params(("owner" = Option<String>, Query, description = "Only the recordings of this owner \
        (a token's name, or `anonymous@ADDRESS`)", example = "alice")),
    responses((status = 200, description = "Every stored recording", body = Vec<ListedRecording>)))]
pub async fn list_recordings(
    State(state): State<AppState>,
    caller: Caller,
    Query(query): Query<OwnerQuery>,
) -> Json<Vec<ListedRecording>> {
    let listed = state
        .recordings
        .list_owned(query.owner.as_deref())
        .into_iter();
    Json(
        listed
            .map(|entry| ListedRecording::for_caller(entry, &caller))
            .collect(),
    )
}

/// A recording as the list shows it to a caller.
#[derive(Clone, Debug, Serialize, ToSchema)]
pub struct ListedRecording {
    /// The recording.
    #[serde(flatten)]
    pub entry: RecordingEntry,
    /// Whether the caller may delete it: its owner or an `admin` token.
    pub may_delete: bool,
}

impl ListedRecording {
    /// `entry` as `caller` sees it.
    pub fn for_caller(entry: RecordingEntry, caller: &Caller) -> Self {
        ListedRecording {
            may_delete: caller.may_delete(entry.owner.iter().map(String::as_str)),
            entry,
        }
    }
}

/// `?owner=` of a listing.
#[derive(Debug, Default, serde::Deserialize)]
pub struct OwnerQuery {
    /// Only what this owner stored.
    pub owner: Option<String>,
}

/// One recording: `{id}.rrd` downloads the file (`application/octet-stream`, as an
/// attachment, with range requests); `{id}` alone gives its entry as JSON, as the list shows it
/// to the caller.
#[utoipa::path(get, path = paths::RECORDING, tag = "recordings",
    params(("id" = String, Path,
        description = "The recording id followed by `.rrd` for the file, or the id alone for its entry",
        example = "3f2a9c0d6b1e4f8a9d7c5b3a1e0f2d4c.rrd")),
    responses(
        (status = 200, description = "The recording file, or its entry",
            content((RrdFile = "application/octet-stream"), (ListedRecording = "application/json"))),
        (status = 206, description = "The requested byte range of the file (`Range: bytes=…`)",
            content((RrdFile = "application/octet-stream"))),
        (status = 404, description = "No such recording (also for anything that is not an id)", body = ErrorBody),
        (status = 416, description = "A byte range outside the file", body = ErrorBody),
    ))]
pub async fn get_recording(
    State(state): State<AppState>,
    caller: Caller,
    Path(name): Path<String>,
    request: Request,
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
        return Ok(Json(ListedRecording::for_caller(entry, &caller)).into_response());
    }
    // ServeFile answers conditional and range requests and streams the file in chunks.
    let response = ServeFile::new(&path)
        .oneshot(request)
        .await
        .map_err(ApiError::internal)?;
    // Deleted (or evicted) since the lookup: as if it had never been there.
    if response.status() == StatusCode::NOT_FOUND {
        return Err(no_recording(&name));
    }
    let mut response = response.map(Body::new);
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(RRD_MEDIA_TYPE),
    );
    let filename = format!("geomint-{}.rrd", entry.id);
    if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{filename}\"")) {
        headers.insert(header::CONTENT_DISPOSITION, v);
    }
    Ok(response)
}

/// The samples of a stored simulation recording, read back from its `.rrd` file with Rerun's
/// decoder (nothing is run again): the system and schedule of its recorded request, and per
/// method the sample times, energies, energy errors and invariants (exact), positions and
/// momenta (the recorded f32 phase points, first six degrees of freedom), Cartesian positions
/// (the recorded f32 bodies), the last step and the force evaluations.
#[utoipa::path(get, path = paths::RECORDING_SAMPLES, tag = "recordings",
    params(("id" = String, Path, description = "The recording id",
        example = "3f2a9c0d6b1e4f8a9d7c5b3a1e0f2d4c")),
    responses(
        (status = 200, description = "The recorded samples", body = RecordedDocument),
        (status = 404, description = "No such recording", body = ErrorBody),
        (status = 422, description = "Not a recording of a geomint simulation (code \
            `not_a_simulation`: another application's or a study's; it can be viewed, not \
            plotted), or more samples than the server's sample limit (code `too_many_samples`)",
            body = ErrorBody),
        (status = 503, description = "Every slot is busy", body = ErrorBody,
            headers(("Retry-After" = u64, description = "Seconds to wait before retrying"))),
    ))]
pub async fn recording_samples(
    State(state): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<RecordedDocument>, ApiError> {
    let (_, path) = state.recordings.get(&id).ok_or_else(|| no_recording(&id))?;
    // Decoding a large recording takes a core: it waits for a slot like a simulation.
    let permits = state.acquire(1, Cost::Read, None).await?;
    let max = state.config.limits.max_samples;
    let decoded = run_blocking(move || {
        let _permits = permits;
        recorded::samples(&path, max)
    })
    .await?;
    decoded.map(Json).map_err(|e| match e {
        ReadError::Io(e) if e.kind() == std::io::ErrorKind::NotFound => no_recording(&id),
        ReadError::Io(e) => ApiError::internal(e),
        ReadError::NotASimulation(message) => {
            ApiError::from(ErrorDetail::new(ErrorCode::NotASimulation, message))
        }
        e @ ReadError::TooManySamples { .. } => {
            ApiError::from(ErrorDetail::new(ErrorCode::TooManySamples, e.to_string()))
        }
        // A stored recording was checked when it was kept; one that no longer reads is a fault.
        ReadError::Invalid(message) => ApiError::internal(format!("recording {id}: {message}")),
    })
}

/// Deletes a recording: its owner may, and an `admin` token.
#[utoipa::path(delete, path = paths::RECORDING, tag = "recordings",
    params(("id" = String, Path, description = "The recording id",
        example = "3f2a9c0d6b1e4f8a9d7c5b3a1e0f2d4c")),
    responses(
        (status = 204, description = "Deleted"),
        (status = 404, description = "No such recording", body = ErrorBody),
    ))]
pub async fn delete_recording(
    State(state): State<AppState>,
    caller: Caller,
    Path(id): Path<String>,
) -> Result<StatusCode, ApiError> {
    let (entry, _) = state.recordings.get(&id).ok_or_else(|| no_recording(&id))?;
    if !caller.may_delete(entry.owner.iter().map(String::as_str)) {
        return Err(not_yours("recording", &id, entry.owner.as_deref()));
    }
    let store = state.recordings.clone();
    let key = id.clone();
    if run_blocking(move || store.delete(&key)).await? {
        Ok(StatusCode::NO_CONTENT)
    } else {
        Err(no_recording(&id))
    }
}

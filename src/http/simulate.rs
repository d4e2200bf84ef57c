//! `POST /api/v1/simulate`: validates the request (cheap, before any slot is taken), takes
//! simulation slots (503 when none frees in time), and integrates off the async runtime —
//! answering one JSON document, with `Accept: application/x-ndjson` (or `?format=ndjson`) an
//! NDJSON stream written as the runs compute, or with `?format=rrd` the Rerun recording of the
//! runs.
//!
//! Runs stop early, keeping their samples, when the request's time limit passes (`stop` =
//! `time_limit`, status 200), when the client goes away (the computation is cancelled and its
//! slots freed), or when the server shuts down (`cancelled`).

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use axum::body::{Body, Bytes};
use axum::extract::{Query, State};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::Response;
use futures_util::StreamExt;
use serde_json::Value;
use tokio::sync::{mpsc, oneshot};
use tokio_stream::wrappers::ReceiverStream;
use tracing::Instrument;

use super::answer::{Format, NDJSON};
use super::error::ApiError;
use super::extract::ApiJson;
use super::paths;
use super::recordings::RrdFile;
use super::state::{cancel_on_shutdown, run_blocking, AppState, CancelOnDrop};
use crate::api::document::{self, SimulationDocument};
use crate::api::error::ErrorBody;
use crate::api::request::SimulateRequest;
use crate::api::stream::{self, ndjson_line, StreamError, StreamLine};
use crate::core::run::Budget;
use crate::recording;

/// How long past the time limit a stream waits for a client that does not read.
const STALLED_CLIENT_GRACE: std::time::Duration = std::time::Duration::from_secs(10);

/// Runs a simulation: the system with its parameters and initial state, one or more methods in
/// parallel, sampled every `output.every` steps.
///
/// With `Accept: application/x-ndjson` the answer is a stream of lines: `header`, `samples`
/// chunks (`method` indexes the header's `methods`), a `summary` per method, and a final `end`.
/// Runs that pass the time limit stop with `stop.reason = time_limit` and keep their samples;
/// runs that diverge stop with `diverged_at` set.
#[utoipa::path(post, path = paths::SIMULATE, tag = "simulation",
    request_body(content = SimulateRequest, content_type = "application/json"),
    params(("Accept" = Option<String>, Header,
        description = "`application/x-ndjson` streams the answer as NDJSON lines (see StreamLine)"),
        ("format" = Option<String>, Query,
        description = "`rrd` answers with the Rerun recording of the runs (as an attachment); \
            `json` (the default) and `ndjson` as the Accept header says")),
    responses(
        (status = 200, description = "The runs, in the order asked",
            content((SimulationDocument = "application/json"), (StreamLine = "application/x-ndjson"),
                (RrdFile = "application/octet-stream"))),
        (status = 400, description = "Malformed JSON (code `malformed_json`)", body = ErrorBody),
        (status = 413, description = "The body exceeds 1 MiB", body = ErrorBody),
        (status = 415, description = "The body is not declared as JSON", body = ErrorBody),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range; \
            an unknown system or method; a method the system does not qualify for; more steps or \
            samples than the limits", body = ErrorBody),
        (status = 503, description = "Every simulation slot is busy", body = ErrorBody,
            headers(("Retry-After" = u64, description = "Seconds to wait before retrying"))),
        (status = 504, description = "The reference run did not finish within the time limit", body = ErrorBody),
        (status = 500, description = "A server fault (details are logged)", body = ErrorBody),
    ))]
pub async fn simulate(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    ApiJson(body): ApiJson<Value>,
) -> Result<Response, ApiError> {
    let format = Format::requested(&query, &headers, Format::ALL)?;
    let request = SimulateRequest::from_value(&body)?;
    let sim = request.prepare(&state.config.limits)?;
    let streaming = format == Format::Ndjson;
    let permits = state.acquire(sim.methods.len()).await?;
    let workers = permits.len();
    let deadline = Instant::now() + state.config.request_timeout;
    let cancel = Arc::new(AtomicBool::new(false));
    tracing::info!(
        system = %sim.system_id,
        methods = sim.methods.len(),
        steps = sim.schedule.steps,
        workers,
        streaming,
        "simulation started"
    );

    if streaming {
        return Ok(stream_response(
            &state, sim, permits, workers, cancel, deadline,
        ));
    }

    // The guard cancels the computation if this future is dropped (the client went away).
    let _guard = CancelOnDrop(cancel.clone());
    let shutdown = cancel_on_shutdown(&state, cancel.clone());
    let result = run_blocking(move || -> Result<Vec<u8>, ApiError> {
        let _permits = permits;
        let budget = Budget {
            cancel: Some(&cancel),
            deadline: Some(deadline),
        };
        let doc: SimulationDocument = document::simulate(&sim, workers, budget)?;
        format.encode(&doc, |d| recording::rrd_bytes(&request, d))
    })
    .await;
    shutdown.abort();
    Ok(format.respond(result??, "geomint.rrd"))
}

/// Starts the computation in the background and answers with its NDJSON stream.
fn stream_response(
    state: &AppState,
    sim: crate::core::simulate::Simulation,
    permits: Vec<tokio::sync::OwnedSemaphorePermit>,
    workers: usize,
    cancel: Arc<AtomicBool>,
    deadline: Instant,
) -> Response {
    let (tx, rx) = mpsc::channel::<Bytes>(16);
    let mut shutdown = state.cancellation();
    let task = async move {
        // Cancel the runs when the client goes away (the body, and so the receiver, is dropped)
        // or the server shuts down.
        let (done_tx, done_rx) = oneshot::channel::<()>();
        let watched = tx.clone();
        let flag = cancel.clone();
        tokio::spawn(async move {
            tokio::select! {
                _ = watched.closed() => {
                    tracing::info!("client went away; cancelling the simulation");
                    flag.store(true, Ordering::Relaxed);
                }
                Ok(_) = shutdown.wait_for(|&c| c) => flag.store(true, Ordering::Relaxed),
                _ = done_rx => {}
            }
        });
        let sender = tx.clone();
        let runtime = tokio::runtime::Handle::current();
        let result = run_blocking(move || {
            let _permits = permits;
            // Waits while the client reads slowly, but not past the time limit plus a grace
            // time: a client that stops reading cannot hold its slots for ever.
            let emit = |line: StreamLine| {
                let patience =
                    deadline.saturating_duration_since(Instant::now()) + STALLED_CLIENT_GRACE;
                let bytes = Bytes::from(ndjson_line(&line));
                let send = async { tokio::time::timeout(patience, sender.send(bytes)).await };
                let sent = matches!(runtime.block_on(send), Ok(Ok(())));
                if !sent {
                    cancel.store(true, Ordering::Relaxed);
                }
                sent
            };
            let budget = Budget {
                cancel: Some(&cancel),
                deadline: Some(deadline),
            };
            stream::stream(&sim, workers, budget, &emit);
        })
        .await;
        drop(done_tx);
        if let Err(error) = result {
            let line = StreamLine::Error(StreamError {
                method: None,
                error: error.detail().clone(),
            });
            let _ = tx.send(Bytes::from(ndjson_line(&line))).await;
            let _ = tx.send(Bytes::from(ndjson_line(&StreamLine::End))).await;
        }
        tracing::info!("simulation stream finished");
    };
    tokio::spawn(task.instrument(tracing::Span::current()));

    let body = Body::from_stream(ReceiverStream::new(rx).map(Ok::<_, Infallible>));
    let mut response = Response::new(body);
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(NDJSON));
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    headers.insert("x-accel-buffering", HeaderValue::from_static("no"));
    response
}

//! The study routes: `POST /api/v1/studies/work-precision` (see
//! [`work_precision`](crate::api::work_precision)) and `POST /api/v1/studies/convergence`
//! (see [`convergence`](crate::api::convergence)).
//!
//! A study is validated first (cheap), then takes one simulation slot — its settings run one
//! after another, so that their wall times compare — and runs off the async runtime. With
//! `Accept: application/x-ndjson` (or `?format=ndjson`) it streams a `reference` line, a `point`
//! line per finished setting (progress: `done` of `total`) and the `result`; a work–precision
//! study answers its Rerun recording with `?format=rrd`; otherwise the result document. The
//! request's time limit and a client that goes away stop it between steps.

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
use serde::Serialize;
use serde_json::Value;
use tokio::sync::mpsc;
use tokio::sync::OwnedSemaphorePermit;
use tokio_stream::wrappers::ReceiverStream;

use super::answer::{Format, NDJSON};
use super::error::ApiError;
use super::extract::ApiJson;
use super::paths;
use super::recordings::RrdFile;
use super::state::{cancel_on_shutdown, run_blocking, AppState, CancelOnDrop};
use crate::api::convergence::{self, ConvergenceDocument, ConvergenceLine, ConvergenceRequest};
use crate::api::error::{ErrorBody, ErrorDetail};
use crate::api::study::{ProgressLine, Runner, StudyJob};
use crate::api::work_precision::{self, StudyLine, WorkPrecisionDocument, WorkPrecisionRequest};
use crate::core::run::Budget;
use crate::recording;

/// One NDJSON line.
fn line<L: Serialize>(l: &L) -> Bytes {
    let mut bytes = serde_json::to_vec(l).unwrap_or_default();
    bytes.push(b'\n');
    Bytes::from(bytes)
}

/// Runs `study` off the async runtime with the request's budget and streams the lines it emits
/// as NDJSON. `emit` returns false once the client has gone away (the budget's cancellation flag
/// is then set, so the study stops between steps). A failure of the blocking task itself is sent
/// as `error_line`, and every stream ends with `end`.
pub(super) fn stream_study<L, F>(
    permits: Vec<OwnedSemaphorePermit>,
    deadline: Instant,
    cancel: Arc<AtomicBool>,
    shutdown: tokio::task::JoinHandle<()>,
    study: F,
    error_line: fn(ErrorDetail) -> L,
    end: fn() -> L,
) -> Response
where
    L: Serialize + Send + 'static,
    F: FnOnce(Budget<'_>, &(dyn Fn(L) -> bool + Sync)) + Send + 'static,
{
    let (tx, rx) = mpsc::channel::<Bytes>(16);
    let flag = cancel;
    tokio::spawn(async move {
        let sender = tx.clone();
        let result = run_blocking(move || {
            let _permits = permits;
            let budget = Budget {
                cancel: Some(&flag),
                deadline: Some(deadline),
            };
            let emit = |l: L| {
                let sent = sender.blocking_send(line(&l)).is_ok();
                if !sent {
                    flag.store(true, Ordering::Relaxed);
                }
                sent
            };
            study(budget, &emit);
            emit(end());
        })
        .await;
        shutdown.abort();
        if let Err(error) = result {
            let _ = tx.send(line(&error_line(error.detail().clone()))).await;
            let _ = tx.send(line(&end())).await;
        }
    });
    let body = Body::from_stream(ReceiverStream::new(rx).map(Ok::<_, Infallible>));
    let mut response = Response::new(body);
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(NDJSON));
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    response
}

/// Runs the validated study `job` with `run` in one simulation slot and answers in `format`:
/// NDJSON lines as it goes, or the finished document encoded by `encode` (`file` names a `.rrd`
/// attachment).
async fn answer<L: ProgressLine>(
    state: AppState,
    format: Format,
    job: StudyJob,
    run: Runner<L>,
    encode: impl FnOnce(&L::Document) -> Result<Vec<u8>, ApiError> + Send + 'static,
    file: &'static str,
) -> Result<Response, ApiError> {
    let streaming = format == Format::Ndjson;
    let permits = state.acquire(1).await?;
    let deadline = Instant::now() + state.config.request_timeout;
    let cancel = Arc::new(AtomicBool::new(false));
    let shutdown = cancel_on_shutdown(&state, cancel.clone());

    if streaming {
        return Ok(stream_study(
            permits,
            deadline,
            cancel,
            shutdown,
            move |budget, emit| {
                match run(&job, budget, emit) {
                    Ok(doc) => emit(L::result(doc)),
                    Err(error) => emit(L::error(error)),
                };
            },
            L::error,
            L::end,
        ));
    }

    let _guard = CancelOnDrop(cancel.clone());
    let result = run_blocking(move || -> Result<Vec<u8>, ApiError> {
        let _permits = permits;
        let budget = Budget {
            cancel: Some(&cancel),
            deadline: Some(deadline),
        };
        encode(&run(&job, budget, &|_| true)?)
    })
    .await;
    shutdown.abort();
    Ok(format.respond(result??, file))
}

/// Runs a work–precision study: one system, several methods at several step sizes (or
/// tolerances for the adaptive `reference`), each timed, with its largest energy error over the
/// sample times, its final-state error and its invariant drift against the exact solution or a
/// reference run, and per method the fitted line log₁₀(ms) = a + b·log₁₀(error).
#[utoipa::path(post, path = paths::WORK_PRECISION, tag = "studies",
    request_body(content = WorkPrecisionRequest, content_type = "application/json"),
    params(("Accept" = Option<String>, Header,
        description = "`application/x-ndjson` streams progress lines (see StudyLine)"),
        ("format" = Option<String>, Query,
        description = "`ndjson` as the Accept header; `rrd` the study's Rerun recording; `json` (default)")),
    responses(
        (status = 200, description = "The study",
            content((WorkPrecisionDocument = "application/json"), (StudyLine = "application/x-ndjson"),
                (RrdFile = "application/octet-stream"))),
        (status = 400, description = "Malformed JSON (code `malformed_json`)", body = ErrorBody),
        (status = 413, description = "The body exceeds 1 MiB", body = ErrorBody),
        (status = 415, description = "The body is not declared as JSON", body = ErrorBody),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range \
            (e.g. `runs[1].h[2]` does not divide t_end/samples); an unknown system or method; more than \
            64 settings or 2·10⁸ steps in all", body = ErrorBody),
        (status = 503, description = "Every simulation slot is busy", body = ErrorBody,
            headers(("Retry-After" = u64, description = "Seconds to wait before retrying"))),
        (status = 504, description = "The study did not finish within the time limit", body = ErrorBody),
        (status = 500, description = "A server fault (details are logged)", body = ErrorBody),
    ))]
pub async fn work_precision(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    ApiJson(body): ApiJson<Value>,
) -> Result<Response, ApiError> {
    let format = Format::requested(&query, &headers, Format::ALL)?;
    let request = WorkPrecisionRequest::from_value(&body)?;
    let job = request.prepare(&state.config.limits)?;
    tracing::info!(
        settings = job.len(),
        streaming = format == Format::Ndjson,
        "work-precision study started"
    );
    let encode = move |doc: &WorkPrecisionDocument| {
        format.encode(doc, |d| recording::work_precision::rrd_bytes(&request, d))
    };
    answer::<StudyLine>(
        state,
        format,
        job,
        work_precision::run,
        encode,
        "geomint-work-precision.rrd",
    )
    .await
}

/// Runs a convergence study: one system with several methods, in one or several coordinate
/// charts, each at several step sizes, with the errors at t_end — the state error in Cartesian
/// coordinates, the energy error at t_end and its largest value over the sample times — against
/// the exact solution or a reference run, and per method and chart the fitted orders (slopes of
/// log error against log h).
#[utoipa::path(post, path = paths::CONVERGENCE, tag = "studies",
    request_body(content = ConvergenceRequest, content_type = "application/json"),
    params(("Accept" = Option<String>, Header,
        description = "`application/x-ndjson` streams progress lines (see ConvergenceLine)"),
        ("format" = Option<String>, Query,
        description = "`ndjson` as the Accept header; `json` (default)")),
    responses(
        (status = 200, description = "The study",
            content((ConvergenceDocument = "application/json"), (ConvergenceLine = "application/x-ndjson"))),
        (status = 400, description = "Malformed JSON (code `malformed_json`)", body = ErrorBody),
        (status = 413, description = "The body exceeds 1 MiB", body = ErrorBody),
        (status = 415, description = "The body is not declared as JSON", body = ErrorBody),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range \
            (e.g. `h[2]` does not divide t_end into whole steps, `charts[1]` is not a chart of the system); \
            an unknown system or method, or a method the chart does not allow; more than 64 settings \
            (methods × charts × step sizes) or 2·10⁸ steps in all", body = ErrorBody),
        (status = 503, description = "Every simulation slot is busy", body = ErrorBody,
            headers(("Retry-After" = u64, description = "Seconds to wait before retrying"))),
        (status = 504, description = "The study did not finish within the time limit", body = ErrorBody),
        (status = 500, description = "A server fault (details are logged)", body = ErrorBody),
    ))]
pub async fn convergence(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    ApiJson(body): ApiJson<Value>,
) -> Result<Response, ApiError> {
    let format = Format::requested(&query, &headers, &[Format::Json, Format::Ndjson])?;
    let job = ConvergenceRequest::from_value(&body)?.prepare(&state.config.limits)?;
    tracing::info!(
        settings = job.len(),
        streaming = format == Format::Ndjson,
        "convergence study started"
    );
    let encode = |doc: &ConvergenceDocument| serde_json::to_vec(doc).map_err(ApiError::internal);
    answer::<ConvergenceLine>(state, format, job, convergence::run, encode, "").await
}

//! How a computing route answers, in one place: the form it answers in (one JSON document, an
//! NDJSON stream, or a Rerun recording — `?format=` or, for streams, the `Accept` header), and the
//! computation behind it ([`Work`]): simulation slots taken, a deadline and a cancellation flag
//! set when the client goes away or the server shuts down, the work run off the async runtime.
//!
//! Streams have bounded back-pressure: the computation waits for a slow reader, but not past the
//! request's deadline plus [`STALLED_CLIENT_GRACE`]; a client that stops reading is then dropped,
//! its computation cancelled and its slots freed — on every streaming route.

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::body::{Body, Bytes};
use axum::extract::{ConnectInfo, FromRequestParts};
use axum::http::request::Parts;
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::Response;
use futures_util::StreamExt;
use serde::Serialize;
use tokio::sync::{mpsc, OwnedSemaphorePermit};
use tokio_stream::wrappers::ReceiverStream;
use tracing::Instrument;

use super::error::ApiError;
use super::recordings::rrd_response;
use super::state::{run_blocking, AppState, Cost};
use crate::access::{Caller, RunGuard};
use crate::api::{ndjson_line, NDJSON};
use crate::core::error::{ErrorCode, ErrorDetail};
use crate::core::run::Budget;
use crate::recording::RecordingError;

/// How long past the time limit a stream waits for a client that does not read.
pub const STALLED_CLIENT_GRACE: Duration = Duration::from_secs(10);

/// Declares the schema of a route's `?format=` parameter: exactly the formats it offers.
macro_rules! format_schema {
    ($(#[$doc:meta])* $name:ident: $($format:ident),+) => {
        $(#[$doc])*
        pub struct $name;

        impl utoipa::PartialSchema for $name {
            fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
                crate::core::schema::string_enum(
                    "The form of the answer.",
                    [$(ResponseFormat::$format.name()),+].into_iter(),
                )
            }
        }

        impl utoipa::ToSchema for $name {}
    };
}

format_schema! {
    /// `?format=` of a route answering JSON, NDJSON or a recording.
    AnyFormat: Json, Ndjson, Rrd
}
format_schema! {
    /// `?format=` of a route answering JSON or NDJSON.
    StreamFormat: Json, Ndjson
}
format_schema! {
    /// `?format=` of a route answering JSON or a recording.
    RecordFormat: Json, Rrd
}

/// How a route answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResponseFormat {
    /// One JSON document (the default).
    Json,
    /// NDJSON lines written as the computation goes.
    Ndjson,
    /// A Rerun recording, as an attachment.
    Rrd,
}

/// Whether the client asks for a stream.
fn wants_stream(headers: &HeaderMap) -> bool {
    headers.get_all(header::ACCEPT).iter().any(|v| {
        v.to_str()
            .map(|s| {
                let s = s.to_ascii_lowercase();
                s.contains(NDJSON) || s.contains("application/ndjson")
            })
            .unwrap_or(false)
    })
}

impl ResponseFormat {
    /// Every format: what the simulation and the work–precision routes answer in.
    pub const ALL: &'static [ResponseFormat] = &[
        ResponseFormat::Json,
        ResponseFormat::Ndjson,
        ResponseFormat::Rrd,
    ];

    /// The name in `?format=`.
    pub fn name(self) -> &'static str {
        match self {
            ResponseFormat::Json => "json",
            ResponseFormat::Ndjson => "ndjson",
            ResponseFormat::Rrd => "rrd",
        }
    }

    /// The format a request asks for among those a route `offers` (JSON always):
    /// `?format=json|ndjson|rrd`, else NDJSON when `Accept` asks for it and the route streams,
    /// else JSON.
    pub fn requested(
        query: &BTreeMap<String, String>,
        headers: &HeaderMap,
        offers: &[ResponseFormat],
    ) -> Result<ResponseFormat, ApiError> {
        let streams = offers.contains(&ResponseFormat::Ndjson);
        let offered = |f: &ResponseFormat| *f == ResponseFormat::Json || offers.contains(f);
        match query.get("format").map(String::as_str) {
            None if streams && wants_stream(headers) => Ok(ResponseFormat::Ndjson),
            None => Ok(ResponseFormat::Json),
            Some(name) => ResponseFormat::ALL
                .iter()
                .copied()
                .find(|f| f.name() == name && offered(f))
                .ok_or_else(|| {
                    let known: Vec<&str> = ResponseFormat::ALL
                        .iter()
                        .filter(|f| offered(f))
                        .map(|f| f.name())
                        .collect();
                    ApiError::from(ErrorDetail::at(
                        ErrorCode::InvalidValue,
                        "format",
                        format!("unknown format `{name}`; one of {}", known.join(", ")),
                    ))
                }),
        }
    }

    /// The bytes of a finished `doc`: its recording (made by `record`) for
    /// [`ResponseFormat::Rrd`], its JSON otherwise.
    pub fn encode<T: Serialize>(
        self,
        doc: &T,
        record: impl FnOnce(&T) -> Result<Vec<u8>, RecordingError>,
    ) -> Result<Vec<u8>, ApiError> {
        match self {
            ResponseFormat::Rrd => record(doc).map_err(ApiError::internal),
            _ => serde_json::to_vec(doc).map_err(ApiError::internal),
        }
    }

    /// The response carrying `bytes` from [`ResponseFormat::encode`]: a `.rrd` attachment named
    /// `file`, or JSON.
    pub fn respond(self, bytes: Vec<u8>, file: &str) -> Response {
        if self == ResponseFormat::Rrd {
            let length = bytes.len() as u64;
            return rrd_response(Body::from(bytes), file, Some(length));
        }
        let mut response = Response::new(Body::from(bytes));
        response.headers_mut().insert(
            header::CONTENT_TYPE,
            HeaderValue::from_static("application/json"),
        );
        response
    }
}

/// Who a request came from: its address, for fair admission (none when the service runs
/// without a listener, as under `tower::ServiceExt::oneshot`), and its caller, whose quotas
/// bound the work it is admitted to.
#[derive(Clone, Debug)]
pub struct Client {
    /// The peer's address.
    pub address: Option<IpAddr>,
    /// The caller ([`super::auth`] authenticated it).
    pub caller: Arc<Caller>,
}

impl<S: Send + Sync> FromRequestParts<S> for Client {
    type Rejection = Infallible;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, Infallible> {
        let peer = parts.extensions.get::<ConnectInfo<SocketAddr>>();
        let _ = state;
        let caller = super::auth::caller_of(&parts.extensions);
        Ok(Client {
            address: peer.map(|info| info.0.ip()),
            caller,
        })
    }
}

/// A computation a request has been admitted to: its simulation slots, its deadline and its
/// cancellation flag (set when the server shuts down, or when the request goes away).
pub struct Work {
    permits: Vec<OwnedSemaphorePermit>,
    run: RunGuard,
    deadline: Instant,
    cancel: Arc<AtomicBool>,
    state: AppState,
}

impl Work {
    /// Admits a request that wants `slots` simulation threads and predicts `cost`: within its
    /// caller's quotas (runs in flight, steps per minute; else 429), one slot, waiting its turn
    /// as [`AppState::acquire`] says (else 503), plus up to `slots − 1` more that are free now.
    pub async fn admit(
        state: &AppState,
        slots: usize,
        cost: Cost,
        client: Client,
    ) -> Result<Work, ApiError> {
        let steps = match cost {
            Cost::Steps(n) => Some(n),
            Cost::Study | Cost::Read => None,
        };
        let run = state.access.usage.admit(&client.caller, steps)?;
        let permits = state.acquire(slots, cost, client.address).await?;
        Ok(Work {
            permits,
            run,
            deadline: Instant::now() + state.config.request_timeout,
            cancel: Arc::new(AtomicBool::new(false)),
            state: state.clone(),
        })
    }

    /// The simulation threads the request got.
    pub fn workers(&self) -> usize {
        self.permits.len()
    }

    /// Sets the cancellation flag when the server shuts down or `gone` completes (the client
    /// went away); abort the returned task once the computation is over.
    fn cancel_when(
        &self,
        gone: impl std::future::Future<Output = ()> + Send + 'static,
    ) -> tokio::task::JoinHandle<()> {
        let mut shutdown = self.state.cancellation();
        let flag = self.cancel.clone();
        tokio::spawn(async move {
            tokio::select! {
                () = gone => {
                    tracing::info!("client went away; cancelling the computation");
                    flag.store(true, Ordering::Relaxed);
                }
                Ok(_) = shutdown.wait_for(|&c| c) => flag.store(true, Ordering::Relaxed),
            }
        })
    }

    /// Runs `compute` off the async runtime with the request's budget and returns what it
    /// gives. If this future is dropped (the client went away), the computation is cancelled.
    pub async fn run<T: Send + 'static>(
        self,
        compute: impl FnOnce(Budget<'_>) -> Result<T, ApiError> + Send + 'static,
    ) -> Result<T, ApiError> {
        let watcher = self.cancel_when(std::future::pending());
        let _guard = CancelOnDrop(self.cancel.clone());
        let Work {
            permits,
            run,
            deadline,
            cancel,
            ..
        } = self;
        let result = run_blocking(move || {
            let _permits = (permits, run);
            compute(Budget {
                cancel: Some(&cancel),
                deadline: Some(deadline),
            })
        })
        .await;
        watcher.abort();
        result?
    }

    /// Answers with an NDJSON stream of the lines `produce` emits while it computes, its last
    /// line included. `emit` returns false once the client has gone away (the budget's flag is
    /// then set, so the computation stops between steps) or has not read for too long. A fault
    /// of the computation itself (a panic) is sent as `error_line` followed by `end`.
    pub fn stream<L, F>(
        self,
        produce: F,
        error_line: fn(ErrorDetail) -> L,
        end: fn() -> L,
    ) -> Response
    where
        L: Serialize + Send + 'static,
        F: FnOnce(Budget<'_>, &(dyn Fn(L) -> bool + Sync)) + Send + 'static,
    {
        let (tx, rx) = mpsc::channel::<Bytes>(16);
        // The client has gone away when the body, and so the receiver, is dropped.
        let watched = tx.clone();
        let watcher = self.cancel_when(async move { watched.closed().await });
        let Work {
            permits,
            run,
            deadline,
            cancel,
            ..
        } = self;
        let task = async move {
            let sender = tx.clone();
            let runtime = tokio::runtime::Handle::current();
            let result = run_blocking(move || {
                let _permits = (permits, run);
                // Waits while the client reads slowly, but not past the deadline plus a grace
                // time: a client that stops reading cannot hold its slots for ever.
                let emit = |line: L| {
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
                produce(budget, &emit);
            })
            .await;
            watcher.abort();
            if let Err(error) = result {
                let _ = tx
                    .send(Bytes::from(ndjson_line(&error_line(
                        error.detail().clone(),
                    ))))
                    .await;
                let _ = tx.send(Bytes::from(ndjson_line(&end()))).await;
            }
            tracing::info!("stream finished");
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
}

/// Sets a cancellation flag when dropped: a request future dropped because its client went
/// away stops its computation.
#[derive(Debug)]
struct CancelOnDrop(Arc<AtomicBool>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

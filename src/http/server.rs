//! The server loop: accepts connections up to a limit, serves each with hyper under a time
//! limit on reading a request's head (which also closes idle keep-alive connections), and shuts
//! down gracefully.
//!
//! A client cannot hold the server with connections that send nothing or send their headers a
//! byte at a time: the head must arrive within [`Config::header_timeout`], and a body within
//! [`Config::body_timeout`] ([`body_deadline`]). Past [`Config::max_connections`] the server
//! stops accepting until one closes, so descriptors never run out; those waiting sit in the
//! kernel's backlog.

use std::future::Future;
use std::net::SocketAddr;
use std::pin::pin;
use std::sync::Arc;
use std::time::Duration;

use axum::body::Body;
use axum::extract::{ConnectInfo, Request, State};
use axum::middleware::Next;
use axum::response::Response;
use futures_util::StreamExt;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::net::TcpListener;
use tokio::sync::{watch, Semaphore};
use tower::ServiceExt;

use super::state::{AppState, Config};
use super::{app, ApiError};
use crate::core::error::{ErrorCode, ErrorDetail};

/// The error a request body gives when it did not arrive in time.
#[derive(Debug, thiserror::Error)]
#[error("the request body did not arrive within {0:?}")]
pub struct BodyDeadline(pub Duration);

/// Middleware: the request body must arrive whole within `limit` of the handler's first read,
/// however it trickles in. The handler's reader then fails with [`BodyDeadline`] in its source
/// chain, which [`body_error`] answers as 408.
pub async fn body_deadline(
    State(limit): State<Duration>,
    request: Request,
    next: Next,
) -> Response {
    let (parts, body) = request.into_parts();
    let mut sleep = Box::pin(tokio::time::sleep(limit));
    let mut frames = body.into_data_stream();
    let mut expired = false;
    let guarded = futures_util::stream::poll_fn(move |cx| {
        if expired {
            return std::task::Poll::Ready(None);
        }
        if sleep.as_mut().poll(cx).is_ready() {
            expired = true;
            return std::task::Poll::Ready(Some(Err(axum::Error::new(BodyDeadline(limit)))));
        }
        frames.poll_next_unpin(cx)
    });
    next.run(Request::from_parts(parts, Body::from_stream(guarded)))
        .await
}

/// The answer to a request body that could not be read: 408 when it came too slowly, else 400.
pub fn body_error(error: &(dyn std::error::Error + 'static)) -> ApiError {
    let mut source: Option<&(dyn std::error::Error + 'static)> = Some(error);
    while let Some(e) = source {
        if let Some(BodyDeadline(limit)) = e.downcast_ref::<BodyDeadline>() {
            return ApiError::new(
                axum::http::StatusCode::REQUEST_TIMEOUT,
                ErrorDetail::new(
                    ErrorCode::Timeout,
                    format!(
                        "the request body did not arrive within {} s",
                        limit.as_secs_f64()
                    ),
                ),
            );
        }
        source = e.source();
    }
    ApiError::new(
        axum::http::StatusCode::BAD_REQUEST,
        ErrorDetail::new(
            ErrorCode::BadRequest,
            format!("the request body could not be read: {error}"),
        ),
    )
}

/// Serves `state` on `listener` until `shutdown` resolves; then stops accepting, lets running
/// simulations go on for the configured grace time, cancels what still runs, and returns once
/// every connection has closed.
pub async fn serve_on(
    listener: TcpListener,
    state: AppState,
    shutdown: impl Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    let config = state.config.clone();
    if let Some(jobs) = &state.jobs {
        jobs.start(state.job_context());
    }
    let router = app(state.clone());
    let connections = Arc::new(Semaphore::new(config.max_connections.max(1)));
    // Connections hold a receiver each: they start closing when `stop` goes, and the server
    // returns when every receiver of `closed` has been dropped.
    let (stop, stopping) = watch::channel(());
    let (closed, open) = watch::channel(());
    let mut shutdown = pin!(shutdown);
    loop {
        let permit = tokio::select! {
            permit = connections.clone().acquire_owned() => permit.expect("never closed"),
            () = &mut shutdown => break,
        };
        let (stream, peer) = tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok(accepted) => accepted,
                Err(error) => {
                    // Out of descriptors or a connection reset before it was accepted: wait a
                    // moment rather than spin, and go on.
                    tracing::warn!(%error, "accept failed");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        let _ = stream.set_nodelay(true);
        let service =
            router
                .clone()
                .map_request(move |mut request: Request<hyper::body::Incoming>| {
                    request.extensions_mut().insert(ConnectInfo(peer));
                    request.map(Body::new)
                });
        let connection = Connection {
            header_timeout: config.header_timeout,
            stopping: stopping.clone(),
            open: open.clone(),
        };
        tokio::spawn(async move {
            connection.serve(TokioIo::new(stream), service).await;
            drop(permit);
        });
    }
    drop(listener);
    // Jobs stop at once: each keeps its finished parts and goes on under the next server.
    if let Some(jobs) = &state.jobs {
        jobs.stop();
    }
    let grace = config.shutdown_grace;
    tracing::info!(grace_secs = grace.as_secs_f64(), "shutting down");
    tokio::spawn(async move {
        tokio::time::sleep(grace).await;
        state.cancel_runs();
    });
    drop(stop);
    drop(open);
    drop(stopping);
    closed.closed().await;
    Ok(())
}

/// One accepted connection's settings and its links to the server loop.
struct Connection {
    header_timeout: Duration,
    stopping: watch::Receiver<()>,
    open: watch::Receiver<()>,
}

impl Connection {
    /// Serves HTTP/1.1 requests on `io` until the client closes, a head takes longer than the
    /// header timeout, or the server stops (then after the request in flight).
    async fn serve<S>(mut self, io: TokioIo<tokio::net::TcpStream>, service: S)
    where
        S: tower::Service<Request<hyper::body::Incoming>, Response = Response>
            + Clone
            + Send
            + 'static,
        S::Future: Send + 'static,
        S::Error: std::error::Error + Send + Sync + 'static,
    {
        // hyper's HTTP/1 server itself, not the HTTP/1-or-2 detector: the detector waits for a
        // connection's first bytes with no time limit.
        let connection = http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(self.header_timeout)
            .serve_connection(io, TowerToHyperService::new(service))
            .with_upgrades();
        let mut connection = pin!(connection);
        let mut closing = false;
        loop {
            tokio::select! {
                result = connection.as_mut() => {
                    if let Err(error) = result {
                        tracing::debug!(%error, "connection ended with an error");
                    }
                    break;
                }
                _ = self.stopping.changed(), if !closing => {
                    closing = true;
                    connection.as_mut().graceful_shutdown();
                }
            }
        }
        drop(self.open);
    }
}

/// Resolves on Ctrl-C or SIGTERM.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        _ = ctrl_c => {}
        _ = terminate => {}
    }
}

/// Binds `addr` and serves until Ctrl-C or SIGTERM.
pub async fn serve(
    addr: SocketAddr,
    config: Config,
    queue: Option<crate::nats::Queue>,
) -> std::io::Result<()> {
    let listener = TcpListener::bind(addr).await?;
    let local = listener.local_addr()?;
    match config.static_dir.as_ref().filter(|d| d.is_dir()) {
        Some(dir) => tracing::info!(dir = %dir.display(), "serving static files at /"),
        None => tracing::info!("no static directory; / answers 404"),
    }
    tracing::info!(
        addr = %local,
        data_dir = %config.data_dir.display(),
        systems_dir = %config.systems_dir.display(),
        recordings_max_bytes = config.recordings_max_bytes,
        max_concurrent = config.max_concurrent,
        short_lane = config.short_lane,
        max_connections = config.max_connections,
        max_steps = config.limits.max_steps,
        max_samples = config.limits.max_samples,
        timeout_secs = config.request_timeout.as_secs_f64(),
        cors = ?config.cors_origins,
        nats = queue.as_ref().map(crate::nats::Queue::url),
        tokens = config.access.tokens_file.as_ref().map(|f| f.display().to_string()),
        anonymous = ?config.access.anonymous,
        "geomint listening on http://{local}"
    );
    let state = AppState::new(config).with_queue(queue);
    tokio::spawn(crate::access::reload::watch(state.access.clone()));
    serve_on(listener, state, shutdown_signal()).await
}

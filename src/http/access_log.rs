//! The access log: one line per request, written when its answer's body has been sent (or its
//! client went away), with who asked (a token's name, or `anonymous@ADDRESS`), the method, the
//! route (its path template, or the path of a page file), the status, the bytes of the body as
//! sent (after compression) and the time from the request's arrival to the body's end.
//!
//! Lines are tracing events of target `geomint::access` at INFO: `geomint serve --log-format
//! json` writes them, like every log line, as one JSON object each.

use std::net::SocketAddr;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Instant;

use axum::body::{Body, Bytes};
use axum::extract::{ConnectInfo, MatchedPath, Request};
use axum::middleware::Next;
use axum::response::Response;
use http_body::{Frame, SizeHint};
use pin_project_lite::pin_project;

use super::auth::LoggedCaller;

/// The longest path of a page file written in a line.
const MAX_PATH: usize = 200;

/// What a line says besides the bytes.
#[derive(Debug)]
struct Line {
    caller: String,
    method: String,
    route: String,
    status: u16,
    request_id: String,
    started: Instant,
}

impl Line {
    fn write(&self, bytes: u64) {
        tracing::info!(
            target: "geomint::access",
            caller = %self.caller,
            method = %self.method,
            route = %self.route,
            status = self.status,
            bytes,
            duration_ms = self.started.elapsed().as_secs_f64() * 1e3,
            request_id = %self.request_id,
            "access"
        );
    }
}

pin_project! {
    /// An answer's body that counts its bytes and writes the line when dropped.
    struct Counted {
        #[pin]
        inner: Body,
        bytes: u64,
        line: Option<Line>,
    }

    impl PinnedDrop for Counted {
        fn drop(this: Pin<&mut Self>) {
            let this = this.project();
            if let Some(line) = this.line.take() {
                line.write(*this.bytes);
            }
        }
    }
}

impl http_body::Body for Counted {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        let this = self.project();
        let polled = this.inner.poll_frame(cx);
        if let Poll::Ready(Some(Ok(frame))) = &polled {
            if let Some(data) = frame.data_ref() {
                *this.bytes += data.len() as u64;
            }
        }
        polled
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}

/// The middleware: notes the request, and gives its answer a body that writes the line.
pub async fn log(request: Request, next: Next) -> Response {
    let started = Instant::now();
    let route = match request.extensions().get::<MatchedPath>() {
        Some(route) => route.as_str().to_string(),
        None => request.uri().path().chars().take(MAX_PATH).collect(),
    };
    let address = request
        .extensions()
        .get::<ConnectInfo<SocketAddr>>()
        .map(|info| format!("anonymous@{}", info.0.ip()));
    let method = request.method().to_string();
    let request_id = request
        .headers()
        .get("x-request-id")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("-")
        .to_string();
    let response = next.run(request).await;
    let caller = match response.extensions().get::<LoggedCaller>() {
        Some(LoggedCaller(name)) => name.clone(),
        None => address.unwrap_or_else(|| "anonymous".into()),
    };
    let line = Line {
        caller,
        method,
        route,
        status: response.status().as_u16(),
        request_id,
        started,
    };
    response.map(|inner| {
        Body::new(Counted {
            inner,
            bytes: 0,
            line: Some(line),
        })
    })
}

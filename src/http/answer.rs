//! The forms a computing route answers in — one JSON document, an NDJSON stream, or a Rerun
//! recording — chosen by `?format=` (or, for streams, the `Accept` header), and the response of a
//! finished document.

use std::collections::BTreeMap;

use axum::body::Body;
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::Response;
use serde::Serialize;

use super::error::ApiError;
use super::recordings::rrd_response;
use crate::api::error::{codes, ErrorDetail};
use crate::recording::RecordingError;

/// The media type of NDJSON streams.
pub const NDJSON: &str = "application/x-ndjson";

/// How a route answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
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

impl Format {
    /// Every format: what the simulation and the work–precision routes answer in.
    pub const ALL: &'static [Format] = &[Format::Json, Format::Ndjson, Format::Rrd];

    /// The name in `?format=`.
    pub fn name(self) -> &'static str {
        match self {
            Format::Json => "json",
            Format::Ndjson => "ndjson",
            Format::Rrd => "rrd",
        }
    }

    /// The format a request asks for among those a route `offers` (JSON always):
    /// `?format=json|ndjson|rrd`, else NDJSON when `Accept` asks for it and the route streams,
    /// else JSON.
    pub fn requested(
        query: &BTreeMap<String, String>,
        headers: &HeaderMap,
        offers: &[Format],
    ) -> Result<Format, ApiError> {
        let streams = offers.contains(&Format::Ndjson);
        match query.get("format").map(String::as_str) {
            None if streams && wants_stream(headers) => Ok(Format::Ndjson),
            None => Ok(Format::Json),
            Some(name) => Format::ALL
                .iter()
                .copied()
                .find(|f| f.name() == name && (*f == Format::Json || offers.contains(f)))
                .ok_or_else(|| {
                    let known: Vec<&str> = Format::ALL
                        .iter()
                        .filter(|f| **f == Format::Json || offers.contains(f))
                        .map(|f| f.name())
                        .collect();
                    ApiError::from(ErrorDetail::at(
                        codes::INVALID_VALUE,
                        "format",
                        format!("unknown format `{name}`; one of {}", known.join(", ")),
                    ))
                }),
        }
    }

    /// The bytes of a finished `doc`: its recording (made by `record`) for [`Format::Rrd`], its
    /// JSON otherwise.
    pub fn encode<T: Serialize>(
        self,
        doc: &T,
        record: impl FnOnce(&T) -> Result<Vec<u8>, RecordingError>,
    ) -> Result<Vec<u8>, ApiError> {
        match self {
            Format::Rrd => record(doc).map_err(ApiError::internal),
            _ => serde_json::to_vec(doc).map_err(ApiError::internal),
        }
    }

    /// The response carrying `bytes` from [`Format::encode`]: a `.rrd` attachment named `file`,
    /// or JSON.
    pub fn respond(self, bytes: Vec<u8>, file: &str) -> Response {
        if self == Format::Rrd {
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

//! `POST /api/v1/studies/energy-map`: an energy-error map of the planar elastic pendulum in
//! Cartesian against polar coordinates (paper 001 Fig. 6; see
//! [`energy_map`](crate::api::energy_map)).
//!
//! The map is validated first (cheap), then takes every simulation slot it can get — its cells
//! run in parallel on all cores — and runs off the async runtime. With
//! `Accept: application/x-ndjson` (or `?format=ndjson`) it streams `progress` lines and the
//! `result`; with `?format=rrd` it answers the map's Rerun recording; otherwise the document. The
//! request's time limit and a client that goes away stop it between steps.

use std::collections::BTreeMap;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use axum::extract::{Query, State};
use axum::http::HeaderMap;
use axum::response::Response;
use serde_json::Value;

use super::answer::Format;
use super::error::ApiError;
use super::extract::ApiJson;
use super::paths;
use super::recordings::RrdFile;
use super::state::{cancel_on_shutdown, run_blocking, AppState, CancelOnDrop};
use super::studies::stream_study;
use crate::api::energy_map::{self, EnergyMapDocument, EnergyMapRequest, MapLine};
use crate::api::error::ErrorBody;
use crate::core::run::Budget;
use crate::recording;

/// An energy-error map (paper 001 Fig. 6): the planar elastic pendulum released at rest from
/// every point of an nx × ny grid of (x₀, y₀), integrated with one method in Cartesian and in
/// polar coordinates; per cell the ℓ² energy error of eq. (50) in each chart, their difference,
/// the polar divergences and Sec. 4.1's predicted region r₀ ≥ 2l + 2mg/k·cos θ₀ with its
/// boundary curve.
#[utoipa::path(post, path = paths::ENERGY_MAP, tag = "studies",
    request_body(content = EnergyMapRequest, content_type = "application/json"),
    params(("Accept" = Option<String>, Header,
        description = "`application/x-ndjson` streams progress lines (see MapLine)"),
        ("format" = Option<String>, Query,
        description = "`ndjson` as the Accept header; `rrd` the map's Rerun recording; `json` (default)")),
    responses(
        (status = 200, description = "The map",
            content((EnergyMapDocument = "application/json"), (MapLine = "application/x-ndjson"),
                (RrdFile = "application/octet-stream"))),
        (status = 400, description = "Malformed JSON (code `malformed_json`)", body = ErrorBody),
        (status = 413, description = "The body exceeds 1 MiB", body = ErrorBody),
        (status = 415, description = "The body is not declared as JSON", body = ErrorBody),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range; \
            a method that cannot run in polar coordinates (code `unmet_requirement`, field `method`); \
            more than 401 points per axis or 2·10¹⁰ steps in all", body = ErrorBody),
        (status = 503, description = "Every simulation slot is busy", body = ErrorBody,
            headers(("Retry-After" = u64, description = "Seconds to wait before retrying"))),
        (status = 504, description = "The map did not finish within the time limit", body = ErrorBody),
        (status = 500, description = "A server fault (details are logged)", body = ErrorBody),
    ))]
pub async fn energy_map(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    ApiJson(body): ApiJson<Value>,
) -> Result<Response, ApiError> {
    let format = Format::requested(&query, &headers, Format::ALL)?;
    let request = EnergyMapRequest::from_value(&body)?;
    let spec = request.prepare()?;
    let permits = state.acquire(state.config.max_concurrent).await?;
    let deadline = Instant::now() + state.config.request_timeout;
    let cancel = Arc::new(AtomicBool::new(false));
    tracing::info!(
        cells = spec.nx * spec.ny,
        steps = spec.steps,
        "energy map started"
    );
    let shutdown = cancel_on_shutdown(&state, cancel.clone());
    let t_max = request.t_max;
    if format == Format::Ndjson {
        return Ok(stream_study(
            permits,
            deadline,
            cancel,
            shutdown,
            move |budget, emit| {
                match energy_map::run(&spec, t_max, budget, emit) {
                    Ok(doc) => emit(MapLine::Result(Box::new(doc))),
                    Err(error) => emit(MapLine::Error { error }),
                };
            },
            |error| MapLine::Error { error },
            || MapLine::End,
        ));
    }
    let _guard = CancelOnDrop(cancel.clone());
    let result = run_blocking(move || -> Result<Vec<u8>, ApiError> {
        let _permits = permits;
        let budget = Budget {
            cancel: Some(&cancel),
            deadline: Some(deadline),
        };
        let doc = energy_map::run(&spec, t_max, budget, &|_| true)?;
        format.encode(&doc, recording::energy_map::rrd_bytes)
    })
    .await;
    shutdown.abort();
    Ok(format.respond(result??, "geomint-energy-map.rrd"))
}

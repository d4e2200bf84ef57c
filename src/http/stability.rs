//! `POST /api/v1/stability` and `POST /api/v1/stability/point`: the linear stability analysis of
//! the core on the damped oscillator (see [`crate::core::studies::stability`]).
//!
//! A map request is validated first (cheap, before any slot is taken), then takes the free
//! simulation slots — one, waiting up to the queue timeout (else 503 with `Retry-After`), plus
//! every other free one, since the maps' rows are computed in parallel over all cores (or one
//! when they go to NATS workers) — and computes off the async runtime. Its work is bounded by the
//! request's size (at most [`MAX_MAP_CELLS`](crate::core::studies::stability::MAX_MAP_CELLS)
//! cells); between rows it stops at the time limit (answering with the maps made, `stop:
//! time_limit`) or when the client goes away.
//!
//! With `?format=rrd` the maps come as a Rerun recording (each map a tensor of spectral radii and
//! an image of verdicts, see [`recording::stability`]).
//!
//! A point costs two steps of one method: it takes no slot, but still runs on the blocking pool
//! so that a fault answers 500.

use std::collections::BTreeMap;

use axum::extract::{Query, State};
use axum::http::HeaderMap;
use axum::response::Response;
use axum::Json;

use super::answer::{Client, RecordFormat};
use super::error::{ApiError, ErrorBody, JsonRefusals, SlotsBusy};
use super::extract::ApiJson;
use super::paths;
use super::recordings::RrdFile;
use super::state::{run_blocking, AppState};
use super::studies::answer;
use crate::api::stability::{PointRequest, StabilityRequest};
use crate::core::studies::stability::{self, PointDocument, StabilityDocument};
use crate::studies::stability::Stability;

/// Stability maps of the damped oscillator q'' + 2γq' + ω²q = 0 over a (γ, h) grid.
///
/// One map per method, at fixed ω: the spectral radius of the one-step matrix, the numerical
/// verdict and, for cimp, csv1 and csv2, the verdicts of the corrected and of the printed
/// analytic relations with their disagreement counts. Each grid has one row per h value and one
/// column per γ value; a spectral radius that is not finite (the method is undefined there, e.g.
/// csv2 at γh = 2) is `null`.
///
/// With `?format=rrd` the answer is the study's Rerun recording: per method the spectral radii
/// as a tensor (dimensions `h`, `gamma`) and the verdicts as a segmentation image whose classes
/// mark where the analytic relation disagrees.
#[utoipa::path(post, path = paths::STABILITY, tag = "stability",
    request_body(content = StabilityRequest, content_type = "application/json"),
    params(("format" = Option<RecordFormat>, Query,
        description = "`rrd` answers with the Rerun recording of the maps (as an attachment); \
            `json` (the default) with the JSON document")),
    responses(
        (status = 200, description = "One map per method, in the order asked",
            content((StabilityDocument = "application/json"), (RrdFile = "application/octet-stream"))),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range; \
            an unknown method or `reference`; more than 16 methods, an axis of more than 1000 points, \
            or more than 10⁶ cells in all (code `too_many_cells`)", body = ErrorBody),
        JsonRefusals, SlotsBusy,
    ))]
pub async fn stability_map(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    client: Client,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    answer::<Stability>(state, &headers, &query, client, &body).await
}

/// The stability analysis of one method at one (ω, γ, h).
///
/// The method's one-step matrix with trace, determinant, eigenvalues and spectral radius, the
/// exact flow's (det = e^{−2γh},
/// ½tr = e^{−γh} cos βh), the ½-trace error, the numerical verdict and, for cimp, csv1 and csv2,
/// the verdicts of the corrected and of the printed analytic relations. Numbers that are not
/// finite (overflow at extreme ω, γ, h) are `null`; where the method is undefined (csv2 at
/// γh = 2) the answer is 422 naming `h`.
#[utoipa::path(post, path = paths::STABILITY_POINT, tag = "stability",
    request_body(content = PointRequest, content_type = "application/json"),
    responses(
        (status = 200, description = "The analysis", body = PointDocument),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range; \
            an unknown method or `reference`; a method undefined at this point (csv2 at γh = 2); \
            a step that failed (code `step_failed`)", body = ErrorBody),
        JsonRefusals,
    ))]
pub async fn stability_point(ApiJson(body): ApiJson) -> Result<Json<PointDocument>, ApiError> {
    let spec = PointRequest::from_value(&body)?.to_spec()?.prepare()?;
    let document = run_blocking(move || stability::point(&spec)).await??;
    Ok(Json(document))
}

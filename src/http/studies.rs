//! The study routes: `POST /api/v1/studies/work-precision`, `/convergence`, `/energy-map`,
//! `/sweep` and `/basins` (and `POST /api/v1/stability`, [`super::stability`]), and `GET
//! /api/v1/studies/sweep/presets` and `/basins/presets` (see [`crate::studies`]).
//!
//! Every study route answers through [`answer`], generic over the kind of study. A study is
//! validated first (cheap), then takes its simulation slots — one for a work–precision study,
//! whose settings run one after another so that their wall times compare; every free one for the
//! others, whose cells run in parallel; one when the cells go to NATS workers and the server only
//! waits — and runs off the async runtime on the service's executor ([`crate::executor`]). With
//! `Accept: application/x-ndjson` (or `?format=ndjson`) a study that streams sends its progress
//! lines and the result; `?format=rrd` answers the study's Rerun recording where it has one;
//! otherwise the result document. The request's time limit and a client that goes away stop it
//! between steps.

use std::collections::BTreeMap;

use axum::extract::{Query, State};
use axum::http::HeaderMap;
use axum::response::Response;
use serde_json::Value;

use super::answer::{AnyFormat, Client, ResponseFormat, StreamFormat, Work};
use super::error::{ApiError, ErrorBody, JsonRefusals, SlotsBusy};
use super::extract::ApiJson;
use super::paths;
use super::recordings::RrdFile;
use super::state::{AppState, Cost};
use crate::api::basins::{self as basin_presets, BasinsRequest};
use crate::api::studies::{ConvergenceRequest, EnergyMapRequest, WorkPrecisionRequest};
use crate::api::sweep::{self as presets, Preset, SweepRequest};
use crate::core::studies::basins::{BasinsDocument, BasinsLine};
use crate::core::studies::convergence::{ConvergenceDocument, ConvergenceLine};
use crate::core::studies::energy_map::{EnergyMapDocument, MapLine};
use crate::core::studies::engine::Order;
use crate::core::studies::sweep::{SweepDocument, SweepLine};
use crate::core::studies::work_precision::{StudyLine, WorkPrecisionDocument};
use crate::studies::basins::Basins;
use crate::studies::convergence::Convergence;
use crate::studies::energy_map::EnergyMap;
use crate::studies::sweep::Sweep;
use crate::studies::work_precision::WorkPrecision;
use crate::studies::{Answers, StudyKind};

/// The formats a study's route answers in.
fn formats(answers: Answers) -> &'static [ResponseFormat] {
    match (answers.stream, answers.recording.is_some()) {
        (true, true) => ResponseFormat::ALL,
        (true, false) => &[ResponseFormat::Json, ResponseFormat::Ndjson],
        (false, true) => &[ResponseFormat::Json, ResponseFormat::Rrd],
        (false, false) => &[ResponseFormat::Json],
    }
}

/// Answers a study of kind `K` read from `body`: prepared first (cheap), then admitted with its
/// slots — one when its cells go to NATS workers or are timed one at a time, else every free
/// one — and run on the service's executor, its progress lines streamed, or its document or its
/// recording answered.
pub(super) async fn answer<K: StudyKind>(
    state: AppState,
    headers: &HeaderMap,
    query: &BTreeMap<String, String>,
    client: Client,
    body: &Value,
) -> Result<Response, ApiError> {
    let format = ResponseFormat::requested(query, headers, formats(K::ANSWERS))?;
    let study = K::prepare(body, &*state.systems, &state.config.limits)?;
    let distributed = state.executor.queue().is_some() && study.order() == Order::Parallel;
    let slots = match distributed || study.order() == Order::Timed {
        true => 1,
        false => state.config.max_concurrent,
    };
    let work = Work::admit(&state, slots, Cost::Study, client).await?;
    tracing::info!(
        study = K::NAME,
        cells = study.cells(),
        steps = study.steps(),
        slots = work.workers(),
        distributed,
        format = format.name(),
        "study started"
    );
    let executor = state.executor.clone();
    if format == ResponseFormat::Ndjson {
        return Ok(work.stream(
            move |budget, emit| {
                match study.run(&executor, budget, emit) {
                    Ok(doc) => emit(K::result_line(doc)),
                    Err(e) => emit(K::error_line(e.into())),
                };
                emit(K::end_line());
            },
            K::error_line,
            K::end_line,
        ));
    }
    let bytes = work
        .run(move |budget| {
            let doc = study.run(&executor, budget, &|_| true)?;
            format.encode(&doc, |doc| study.record(doc))
        })
        .await?;
    Ok(format.respond(bytes, K::ANSWERS.recording.unwrap_or_default()))
}

/// Runs a work–precision study: one system, several methods at several step sizes (or
/// tolerances for the adaptive `reference`), each timed, with its largest energy error over the
/// sample times, its final-state error and its invariant drift against the exact solution or a
/// reference run, and per method the fitted line log₁₀(ms) = a + b·log₁₀(error).
#[utoipa::path(post, path = paths::WORK_PRECISION, tag = "studies",
    request_body(content = WorkPrecisionRequest, content_type = "application/json"),
    params(("Accept" = Option<String>, Header,
        description = "`application/x-ndjson` streams progress lines (see StudyLine)"),
        ("format" = Option<AnyFormat>, Query,
        description = "`ndjson` as the Accept header; `rrd` the study's Rerun recording; `json` (default)")),
    responses(
        (status = 200, description = "The study",
            content((WorkPrecisionDocument = "application/json"), (StudyLine = "application/x-ndjson"),
                (RrdFile = "application/octet-stream"))),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range \
            (e.g. `runs[1].h[2]` does not divide t_end/samples); an unknown system or method; more than \
            64 settings or 2·10⁸ steps in all", body = ErrorBody),
        JsonRefusals, SlotsBusy,
    ))]
pub async fn work_precision(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    client: Client,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    answer::<WorkPrecision>(state, &headers, &query, client, &body).await
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
        ("format" = Option<StreamFormat>, Query,
        description = "`ndjson` as the Accept header; `json` (default)")),
    responses(
        (status = 200, description = "The study",
            content((ConvergenceDocument = "application/json"), (ConvergenceLine = "application/x-ndjson"))),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range \
            (e.g. `h[2]` does not divide t_end into whole steps, `charts[1]` is not a chart of the system); \
            an unknown system or method, or a method the chart does not allow; more than 64 settings \
            (methods × charts × step sizes) or 2·10⁸ steps in all", body = ErrorBody),
        JsonRefusals, SlotsBusy,
    ))]
pub async fn convergence(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    client: Client,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    answer::<Convergence>(state, &headers, &query, client, &body).await
}

/// An energy-error map (paper 001 Fig. 6): the planar elastic pendulum released at rest from
/// every point of an nx × ny grid of (x₀, y₀), integrated with one method in Cartesian and in
/// polar coordinates; per cell the ℓ² energy error of eq. (50) in each chart, their difference,
/// the polar divergences and Sec. 4.1's predicted region r₀ ≥ 2l + 2mg/k·cos θ₀ with its
/// boundary curve.
#[utoipa::path(post, path = paths::ENERGY_MAP, tag = "studies",
    request_body(content = EnergyMapRequest, content_type = "application/json"),
    params(("Accept" = Option<String>, Header,
        description = "`application/x-ndjson` streams progress lines (see MapLine)"),
        ("format" = Option<AnyFormat>, Query,
        description = "`ndjson` as the Accept header; `rrd` the map's Rerun recording; `json` (default)")),
    responses(
        (status = 200, description = "The map",
            content((EnergyMapDocument = "application/json"), (MapLine = "application/x-ndjson"),
                (RrdFile = "application/octet-stream"))),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range; \
            a method that cannot run in polar coordinates (code `unmet_requirement`, field `method`); \
            more than 401 points per axis or 2·10¹⁰ steps in all", body = ErrorBody),
        JsonRefusals, SlotsBusy,
    ))]
pub async fn energy_map(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    client: Client,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    answer::<EnergyMap>(state, &headers, &query, client, &body).await
}

/// A sweep: one system (built-in, stored or defined in the request) with one or more methods in
/// one or more charts over a grid of one or two axes — a number parameter (`params.gamma`), the
/// step size `h`, or a component of the initial state (`q0[i]`, `p0[i]`) — and per cell, method
/// and chart the energy error at the end, its largest value and its ℓ² mean (paper 001 eq. 50),
/// each invariant's drift, the time of divergence, the final state and the work. Cells run in
/// parallel on every free slot; the document is the same bit for bit whichever executor ran
/// its shards.
#[utoipa::path(post, path = paths::SWEEP, tag = "studies",
    request_body(content = SweepRequest, content_type = "application/json"),
    params(("Accept" = Option<String>, Header,
        description = "`application/x-ndjson` streams progress lines (see SweepLine)"),
        ("format" = Option<AnyFormat>, Query,
        description = "`ndjson` as the Accept header; `rrd` the sweep's Rerun recording (a tensor and a heatmap per run and metric); `json` (default)")),
    responses(
        (status = 200, description = "The sweep",
            content((SweepDocument = "application/json"), (SweepLine = "application/x-ndjson"),
                (RrdFile = "application/octet-stream"))),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range \
            (e.g. `axes[0].min` puts a parameter outside its range, `axes[1].name` is not an axis); an \
            unknown system, chart or method; more than 401 points per axis, 16 runs per cell or 2·10¹⁰ \
            steps in all", body = ErrorBody),
        JsonRefusals, SlotsBusy,
    ))]
pub async fn sweep(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    client: Client,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    answer::<Sweep>(state, &headers, &query, client, &body).await
}

/// Ready-made sweeps: paper 001 Fig. 6's energy-error map (its numbers equal the energy-map
/// route's) and csv1's divergence over (γ, h), the numerical counterpart of the stability map.
#[utoipa::path(get, path = paths::SWEEP_PRESETS, tag = "studies",
    responses((status = 200, description = "The presets", body = Vec<Preset>)))]
pub async fn sweep_presets() -> axum::Json<Vec<Preset>> {
    axum::Json(presets::presets())
}

/// Runs a basin map: over a grid of initial states, where each orbit ends up — the well a damped
/// orbit settles in (decided by the energy argument once its energy is below the lowest saddle),
/// the periodic orbit of a driven system's stroboscopic map it locks onto, the exit it leaves
/// through — with per run one label per cell, the time it was decided, the attractors' table,
/// each basin's share, the basin entropy, the boundary basin entropy and the uncertainty
/// exponent. Each cell stops as soon as its outcome is decided.
#[utoipa::path(post, path = paths::BASINS, tag = "studies",
    request_body(content = BasinsRequest, content_type = "application/json"),
    params(("Accept" = Option<String>, Header,
        description = "`application/x-ndjson` streams progress lines (see BasinsLine)"),
        ("format" = Option<AnyFormat>, Query,
        description = "`ndjson` as the Accept header; `rrd` the map's Rerun recording (per run the labels as a segmentation image whose classes name the attractors, the decision times); `json` (default)")),
    responses(
        (status = 200, description = "The map",
            content((BasinsDocument = "application/json"), (BasinsLine = "application/x-ndjson"),
                (RrdFile = "application/octet-stream"))),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range \
            (e.g. `axes[0].name` is not a component of the initial state, `exits[1].where` does not \
            parse, `recognition.period` is missing for a driven system); an unknown system, chart or \
            method; more than 401 points per axis or 2·10¹⁰ steps in all", body = ErrorBody),
        JsonRefusals, SlotsBusy,
    ))]
pub async fn basins(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    client: Client,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    answer::<Basins>(state, &headers, &query, client, &body).await
}

/// Ready-made basin maps: the damped double well, the forced damped Duffing oscillator, and
/// Hénon–Heiles's escapes at E = 0.25 without and with weak damping.
#[utoipa::path(get, path = paths::BASINS_PRESETS, tag = "studies",
    responses((status = 200, description = "The presets", body = Vec<Preset>)))]
pub async fn basins_presets() -> axum::Json<Vec<Preset>> {
    axum::Json(basin_presets::presets())
}

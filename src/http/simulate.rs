//! `POST /api/v1/simulate`: validates the request (cheap, before any slot is taken), takes
//! simulation slots (503 when none frees in time), and integrates off the async runtime —
//! answering one JSON document, with `Accept: application/x-ndjson` (or `?format=ndjson`) an
//! NDJSON stream written as the runs compute, or with `?format=rrd` the Rerun recording of the
//! runs. All three are the same run ([`Simulation::stream`](crate::core::simulation::Simulation)).
//!
//! Runs stop early, keeping their samples, when the request's time limit passes (`stop` =
//! `time_limit`, status 200), when the client goes away (the computation is cancelled and its
//! slots freed), or when the server shuts down (`cancelled`).
//!
//! `POST /api/v1/simulate/allowed-region` answers, for the same request with an energy level and
//! a plane, which points of the plane an orbit can start from (see [`allowed_region`]).

use std::collections::BTreeMap;

use axum::extract::{Query, State};
use axum::http::HeaderMap;
use axum::response::Response;

use super::answer::{AnyFormat, Client, ResponseFormat, Work};
use super::error::{ApiError, ErrorBody, JsonRefusals, SlotsBusy};
use super::extract::ApiJson;
use super::paths;
use super::recordings::RrdFile;
use super::state::{run_blocking, AppState, Cost};
use crate::api::allowed::AllowedRegionRequest;
use crate::api::SimulateRequest;
use crate::core::simulation::stream::StreamError;
use crate::core::simulation::{AllowedRegion, SimulationDocument, StreamLine};
use crate::recording;

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
        ("format" = Option<AnyFormat>, Query,
        description = "`rrd` answers with the Rerun recording of the runs (as an attachment); \
            `json` (the default) and `ndjson` as the Accept header says")),
    responses(
        (status = 200, description = "The runs, in the order asked",
            content((SimulationDocument = "application/json"), (StreamLine = "application/x-ndjson"),
                (RrdFile = "application/octet-stream"))),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range; \
            an unknown system or method; a method the system does not qualify for; more steps or \
            samples than the limits", body = ErrorBody),
        JsonRefusals, SlotsBusy,
    ))]
pub async fn simulate(
    State(state): State<AppState>,
    headers: HeaderMap,
    Query(query): Query<BTreeMap<String, String>>,
    client: Client,
    ApiJson(body): ApiJson,
) -> Result<Response, ApiError> {
    let format = ResponseFormat::requested(&query, &headers, ResponseFormat::ALL)?;
    let request = SimulateRequest::from_value(&body)?;
    let sim = request.prepare(&state.config.limits, &*state.systems)?;
    let request = request.inlined(&*state.systems);
    let work = Work::admit(&state, sim.methods.len(), Cost::Steps(sim.cost()), client).await?;
    let workers = work.workers();
    tracing::info!(
        system = %sim.system_id(),
        methods = sim.methods.len(),
        steps = sim.schedule.steps,
        workers,
        format = format.name(),
        "simulation started"
    );
    if format == ResponseFormat::Ndjson {
        return Ok(work.stream(
            move |budget, emit| sim.stream(workers, budget, emit),
            |error| {
                StreamLine::Error(StreamError {
                    method: None,
                    error,
                })
            },
            || StreamLine::End,
        ));
    }
    let bytes = work
        .run(move |budget| {
            let doc: SimulationDocument = sim.simulate(workers, budget)?;
            format.encode(&doc, |d| {
                recording::rrd_bytes(&recording::Spec::of(&request), d)
            })
        })
        .await?;
    Ok(format.respond(bytes, "geomint.rrd"))
}

/// Which points of a section's plane can start an orbit at an energy: the energetically allowed
/// region.
///
/// The body is the simulation request an orbit launched on the plane would send (with `energy`),
/// and `plane`: two of the system's coordinates or momenta, each sampled at `points` values.
/// Each grid point's state is the request's initial state with the plane's two names set to the
/// point; the energy's momentum is solved there as for a run. `allowed` says where it has a
/// value (the point lies on the energy surface), `lowest` the energy with that momentum at 0,
/// the least an orbit from the point can have. Nothing is integrated: the answer costs at most
/// 200 × 200 solves and takes no simulation slot.
#[utoipa::path(post, path = paths::ALLOWED_REGION, tag = "simulation",
    request_body(content = AllowedRegionRequest, content_type = "application/json"),
    responses(
        (status = 200, description = "The plane's grid, row by row from the first value up",
            body = AllowedRegion),
        (status = 422, description = "A field is unknown, missing, of the wrong type or out of range \
            (as for a simulation; `energy` and `plane` are required); an axis that is not one of the \
            system's names, is the solved momentum, or repeats the other; more than 200 points on \
            an axis", body = ErrorBody),
        JsonRefusals,
    ))]
pub async fn allowed_region(
    State(state): State<AppState>,
    ApiJson(body): ApiJson,
) -> Result<axum::Json<AllowedRegion>, ApiError> {
    let request = AllowedRegionRequest::from_value(&body)?;
    let (sim, level, plane) = request.prepare(&state.config.limits, &*state.systems)?;
    let region = run_blocking(move || sim.allowed_region(&level, &plane)).await??;
    Ok(axum::Json(region))
}

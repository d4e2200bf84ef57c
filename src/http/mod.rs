//! The HTTP service: routes, errors, limits, and the server loop.
//!
//! Every route is registered once, with its OpenAPI operation ([`routes`]): the document at
//! `GET /api/v1/openapi.json` lists them all with their requests, answers and errors, and the
//! README's "Using it" walks through them.
//!
//! Every error answers `{"error": {"code", "message", "field"}}` ([`ApiError`]), including those
//! of the middleware (body limit 413; 504 from a backstop past the time limit, which only a
//! computation that ignored its deadline would reach) and unknown routes (404, 405).

pub mod access_log;
pub mod answer;
pub mod assets;
pub mod auth;
pub mod error;
pub mod extract;
pub mod handlers;
pub mod jobs;
pub mod openapi;
pub mod recordings;
pub mod server;
pub mod simulate;
pub mod stability;
pub mod state;

pub mod studies;
pub mod systems;

use axum::body::Body;
use axum::extract::DefaultBodyLimit;
use axum::http::{header, HeaderValue, Method, StatusCode};
use axum::middleware::{from_fn_with_state, map_response};
use axum::response::{IntoResponse, Response};
use axum::Router;
use tower::util::option_layer;
use tower_http::compression::predicate::{DefaultPredicate, NotForContentType, Predicate};
use tower_http::compression::CompressionLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::timeout::TimeoutLayer;
use tower_http::trace::{DefaultOnFailure, DefaultOnResponse, TraceLayer};
use utoipa::OpenApi;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

pub use error::ApiError;
pub use error::ErrorBody;
pub use extract::ApiJson;
pub use server::{serve, serve_on, shutdown_signal};
pub use state::{run_blocking, AppState, Config, Cost};

use crate::core::error::{ErrorCode, ErrorDetail};

/// Paths of the routes.
pub mod paths {
    /// Liveness.
    pub const HEALTHZ: &str = "/healthz";
    /// The system catalogue.
    pub const SYSTEMS: &str = "/api/v1/systems";
    /// One system.
    pub const SYSTEM: &str = "/api/v1/systems/{id}";
    /// The method catalogue.
    pub const METHODS: &str = "/api/v1/methods";
    /// One method.
    pub const METHOD: &str = "/api/v1/methods/{id}";
    /// Simulations.
    pub const SIMULATE: &str = "/api/v1/simulate";
    /// Which points of a section's plane can start an orbit at an energy.
    pub const ALLOWED_REGION: &str = "/api/v1/simulate/allowed-region";
    /// Stability maps.
    pub const STABILITY: &str = "/api/v1/stability";
    /// Stability at one point.
    pub const STABILITY_POINT: &str = "/api/v1/stability/point";
    /// Work–precision studies.
    pub const WORK_PRECISION: &str = "/api/v1/studies/work-precision";
    /// Energy-error maps in Cartesian against polar coordinates.
    pub const ENERGY_MAP: &str = "/api/v1/studies/energy-map";
    /// Convergence studies.
    pub const CONVERGENCE: &str = "/api/v1/studies/convergence";
    /// Sweeps of any system over one or two axes.
    pub const SWEEP: &str = "/api/v1/studies/sweep";
    /// Ready-made sweeps.
    pub const SWEEP_PRESETS: &str = "/api/v1/studies/sweep/presets";
    /// Basin maps.
    pub const BASINS: &str = "/api/v1/studies/basins";
    /// Ready-made basin maps.
    pub const BASINS_PRESETS: &str = "/api/v1/studies/basins/presets";
    /// Jobs: submitted, listed.
    pub const JOBS: &str = "/api/v1/jobs";
    /// One job: its status; removed once it has ended.
    pub const JOB: &str = "/api/v1/jobs/{id}";
    /// Cancelling a job.
    pub const JOB_CANCEL: &str = "/api/v1/jobs/{id}/cancel";
    /// What happens to a job, as NDJSON.
    pub const JOB_EVENTS: &str = "/api/v1/jobs/{id}/events";
    /// A done job's document.
    pub const JOB_RESULT: &str = "/api/v1/jobs/{id}/result";
    /// A job as it was submitted.
    pub const JOB_REQUEST: &str = "/api/v1/jobs/{id}/request";
    /// The OpenAPI document.
    pub const OPENAPI: &str = "/api/v1/openapi.json";
    /// Stored recordings.
    pub const RECORDINGS: &str = "/api/v1/recordings";
    /// One stored recording: `{id}.rrd` is the file, `{id}` its entry.
    pub const RECORDING: &str = "/api/v1/recordings/{id}";
    /// A stored recording's samples, read back from its file.
    pub const RECORDING_SAMPLES: &str = "/api/v1/recordings/{id}/samples";
}

/// Every route with its OpenAPI operation, registered once: the router serves them and the
/// document ([`openapi::document`]) describes them. Layers are the routes' own (body limits);
/// [`app`] adds the service's.
pub fn routes(config: &Config) -> OpenApiRouter<AppState> {
    let api = OpenApiRouter::with_openapi(openapi::ApiDoc::openapi())
        .routes(routes!(handlers::healthz))
        .routes(routes!(systems::list_systems, systems::create_system))
        .routes(routes!(systems::get_system, systems::delete_system))
        .routes(routes!(handlers::list_methods))
        .routes(routes!(handlers::get_method))
        .routes(routes!(simulate::simulate))
        .routes(routes!(simulate::allowed_region))
        .routes(routes!(stability::stability_map))
        .routes(routes!(stability::stability_point))
        .routes(routes!(studies::work_precision))
        .routes(routes!(studies::energy_map))
        .routes(routes!(studies::convergence))
        .routes(routes!(studies::sweep))
        .routes(routes!(studies::sweep_presets))
        .routes(routes!(studies::basins))
        .routes(routes!(studies::basins_presets))
        .routes(routes!(jobs::submit_job, jobs::list_jobs))
        .routes(routes!(jobs::get_job, jobs::delete_job))
        .routes(routes!(jobs::cancel_job))
        .routes(routes!(jobs::job_events))
        .routes(routes!(jobs::job_result))
        .routes(routes!(jobs::job_request))
        .routes(routes!(handlers::openapi_json))
        .routes(routes!(recordings::list_recordings))
        .routes(routes!(
            recordings::get_recording,
            recordings::delete_recording
        ))
        .routes(routes!(recordings::recording_samples))
        .layer(DefaultBodyLimit::max(config.body_limit))
        .layer(RequestBodyLimitLayer::new(config.body_limit))
        .layer(from_fn_with_state(
            config.body_timeout,
            server::body_deadline,
        ));
    // Storing a recording takes a JSON body under the body limit or an .rrd upload under the
    // store's size cap; the handler enforces both (an upload is counted as it arrives), so this
    // route has no limit layer of its own beyond the JSON extractor's.
    let store = OpenApiRouter::new()
        .routes(routes!(recordings::create_recording))
        .layer(DefaultBodyLimit::max(config.body_limit))
        .layer(from_fn_with_state(
            config.body_timeout,
            server::body_deadline,
        ));
    api.merge(store)
}

/// The service: routes and middleware, shared by the server and the tests.
pub fn app(state: AppState) -> Router {
    let config = state.config.clone();
    let (api, doc) = routes(&config).split_for_parts();
    let scopes = serde_json::to_value(&doc)
        .map(|doc| auth::RouteScopes::of(&doc))
        .unwrap_or_default();
    let guard = (state.clone(), std::sync::Arc::new(scopes));
    let api = api
        .method_not_allowed_fallback(handlers::method_not_allowed)
        .with_state(state);
    let static_dir = config.static_dir.as_ref().filter(|dir| dir.is_dir());
    let router = match static_dir {
        Some(dir) => {
            let assets = assets::Assets::new(dir);
            api.fallback(move |request| assets.clone().serve(request))
        }
        None => api.fallback(handlers::not_found),
    };

    // NDJSON streams are not compressed: the encoder would hold lines back. Recordings are
    // compressed already.
    let compression = CompressionLayer::new().compress_when(
        DefaultPredicate::new()
            .and(NotForContentType::const_new(crate::api::NDJSON))
            .and(NotForContentType::const_new(
                crate::recording::RRD_MEDIA_TYPE,
            )),
    );
    // The middleware's own time limit is a backstop: simulations stop themselves at the
    // request time limit and answer with what they have.
    let backstop = config.request_timeout + std::time::Duration::from_secs(30);
    router
        .layer(from_fn_with_state(guard, auth::authorize))
        .layer(TimeoutLayer::with_status_code(StatusCode::GATEWAY_TIMEOUT, backstop))
        .layer(map_response(json_errors))
        .layer(map_response(nosniff))
        .layer(compression)
        .layer(option_layer(cors(&config.cors_origins)))
        .layer(PropagateRequestIdLayer::x_request_id())
        .layer(TraceLayer::new_for_http().make_span_with(|request: &axum::http::Request<Body>| {
            let id = request
                .headers()
                .get("x-request-id")
                .and_then(|v| v.to_str().ok())
                .unwrap_or("-");
            tracing::info_span!("request", method = %request.method(), uri = %request.uri(), id = %id)
        })
        .on_response(DefaultOnResponse::new().level(tracing::Level::INFO))
        // Every answer is logged at INFO with its status already. A 5xx is most often a 503 of a
        // full server, expected under load: at the default ERROR level one line per refusal would
        // flood the log exactly when the machine is busiest. Real faults are logged where they
        // happen, with their details.
        .on_failure(DefaultOnFailure::new().level(tracing::Level::DEBUG)))
        .layer(axum::middleware::from_fn(access_log::log))
        .layer(SetRequestIdLayer::x_request_id(MakeRequestUuid))
}

/// The CORS layer for `origins` (none when empty; any origin for `*`).
fn cors(origins: &[String]) -> Option<CorsLayer> {
    let origins: Vec<&str> = origins
        .iter()
        .map(|o| o.trim())
        .filter(|o| !o.is_empty())
        .collect();
    if origins.is_empty() {
        return None;
    }
    let allow = if origins.contains(&"*") {
        AllowOrigin::any()
    } else {
        let values: Vec<HeaderValue> = origins
            .iter()
            .filter_map(|o| match HeaderValue::from_str(o) {
                Ok(v) => Some(v),
                Err(_) => {
                    tracing::warn!(origin = %o, "ignoring an invalid CORS origin");
                    None
                }
            })
            .collect();
        AllowOrigin::list(values)
    };
    Some(
        CorsLayer::new()
            .allow_origin(allow)
            .allow_methods([Method::GET, Method::POST, Method::DELETE])
            .allow_headers([header::CONTENT_TYPE, header::ACCEPT, header::AUTHORIZATION])
            .expose_headers([
                header::RETRY_AFTER,
                header::LOCATION,
                header::CONTENT_DISPOSITION,
                header::HeaderName::from_static("x-request-id"),
            ]),
    )
}

/// Tells browsers to take every answer as the type it declares (an uploaded recording or a
/// message echoing input is never sniffed into a script or a page).
async fn nosniff(mut response: Response) -> Response {
    response.headers_mut().insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    response
}

/// Gives error answers produced outside the handlers (the body limit, the time limit, static
/// files) the service's JSON error shape.
async fn json_errors(response: Response) -> Response {
    let status = response.status();
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    if !(status.is_client_error() || status.is_server_error()) || is_json {
        return response;
    }
    let (code, message) = match status {
        StatusCode::PAYLOAD_TOO_LARGE => (
            ErrorCode::PayloadTooLarge,
            "the request body exceeds the size limit",
        ),
        StatusCode::NOT_FOUND => (ErrorCode::NotFound, "not found"),
        StatusCode::METHOD_NOT_ALLOWED => (ErrorCode::MethodNotAllowed, "method not allowed"),
        StatusCode::GATEWAY_TIMEOUT | StatusCode::REQUEST_TIMEOUT => (
            ErrorCode::Timeout,
            "the request took longer than the time limit",
        ),
        s if s.is_server_error() => (ErrorCode::Internal, "internal server error"),
        _ => (ErrorCode::BadRequest, "bad request"),
    };
    let (mut parts, _) = response.into_parts();
    let error = ApiError::new(status, ErrorDetail::new(code, message)).into_response();
    parts.headers.remove(header::CONTENT_LENGTH);
    parts.headers.remove(header::CONTENT_ENCODING);
    parts.headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    Response::from_parts(parts, error.into_body())
}

//! The HTTP service: routes, errors, limits, and the server loop.
//!
//! | route | |
//! |---|---|
//! | `GET /healthz` | liveness and load |
//! | `GET /api/v1/systems`, `GET /api/v1/systems/{id}` | the built-in systems and the stored definitions |
//! | `POST /api/v1/systems`, `DELETE /api/v1/systems/{id}` | store a system definition, or remove one |
//! | `GET /api/v1/methods`, `GET /api/v1/methods/{id}` | the method catalogue |
//! | `POST /api/v1/simulate` | run a simulation (JSON, NDJSON with `Accept: application/x-ndjson`, a Rerun recording with `?format=rrd`) |
//! | `POST /api/v1/stability` | linear stability maps over a (γ, h) grid |
//! | `POST /api/v1/stability/point` | linear stability analysis at one (ω, γ, h) |
//! | `POST /api/v1/studies/work-precision` | a work–precision study (JSON, NDJSON progress, or `?format=rrd`) |
//! | `POST /api/v1/studies/convergence` | a convergence study: errors at t_end against h, fitted orders (JSON or NDJSON progress) |
//! | `POST /api/v1/studies/energy-map` | an energy-error map, Cartesian against polar coordinates (JSON, NDJSON progress, or `?format=rrd`) |
//! | `POST /api/v1/recordings`, `GET /api/v1/recordings` | store a run's Rerun recording, or an uploaded `.rrd`; list them |
//! | `GET /api/v1/recordings/{id}.rrd`, `DELETE /api/v1/recordings/{id}` | download or delete one |
//! | `GET /api/v1/recordings/{id}/samples` | a stored simulation recording's samples, read back as JSON |
//! | `GET /api/v1/openapi.json` | the OpenAPI 3 document |
//! | `/` | the static directory, when there is one |
//!
//! Every error answers `{"error": {"code", "message", "field"}}` ([`ApiError`]), including those
//! of the middleware (body limit 413; 504 from a backstop past the time limit, which only a
//! computation that ignored its deadline would reach) and unknown routes (404, 405).

pub mod answer;
pub mod assets;
pub mod error;
pub mod extract;
pub mod handlers;
pub mod openapi;
pub mod recordings;
pub mod server;
pub mod simulate;
pub mod stability;
pub mod state;
pub mod store;
pub mod studies;
pub mod systems;
mod tempfile;

use axum::body::Body;
use axum::extract::DefaultBodyLimit;
use axum::http::{header, HeaderValue, Method, StatusCode};
use axum::middleware::{from_fn_with_state, map_response};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use tower::util::option_layer;
use tower_http::compression::predicate::{DefaultPredicate, NotForContentType, Predicate};
use tower_http::compression::CompressionLayer;
use tower_http::cors::{AllowOrigin, CorsLayer};
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::timeout::TimeoutLayer;
use tower_http::trace::{DefaultOnFailure, DefaultOnResponse, TraceLayer};

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
    /// The OpenAPI document.
    pub const OPENAPI: &str = "/api/v1/openapi.json";
    /// Stored recordings.
    pub const RECORDINGS: &str = "/api/v1/recordings";
    /// One stored recording: `{id}.rrd` is the file, `{id}` its entry.
    pub const RECORDING: &str = "/api/v1/recordings/{id}";
    /// A stored recording's samples, read back from its file.
    pub const RECORDING_SAMPLES: &str = "/api/v1/recordings/{id}/samples";
}

/// Every route as (method, path), as the router registers them.
pub const ROUTES: &[(&str, &str)] = &[
    ("get", paths::HEALTHZ),
    ("get", paths::SYSTEMS),
    ("post", paths::SYSTEMS),
    ("get", paths::SYSTEM),
    ("delete", paths::SYSTEM),
    ("get", paths::METHODS),
    ("get", paths::METHOD),
    ("post", paths::SIMULATE),
    ("post", paths::STABILITY),
    ("post", paths::STABILITY_POINT),
    ("post", paths::WORK_PRECISION),
    ("post", paths::ENERGY_MAP),
    ("post", paths::CONVERGENCE),
    ("post", paths::SWEEP),
    ("get", paths::SWEEP_PRESETS),
    ("get", paths::OPENAPI),
    ("post", paths::RECORDINGS),
    ("get", paths::RECORDINGS),
    ("get", paths::RECORDING),
    ("delete", paths::RECORDING),
    ("get", paths::RECORDING_SAMPLES),
];

/// The service: routes and middleware, shared by the server and the tests.
pub fn app(state: AppState) -> Router {
    let config = state.config.clone();
    let api = Router::new()
        .route(paths::HEALTHZ, get(handlers::healthz))
        .route(
            paths::SYSTEMS,
            get(systems::list_systems).post(systems::create_system),
        )
        .route(
            paths::SYSTEM,
            get(systems::get_system).delete(systems::delete_system),
        )
        .route(paths::METHODS, get(handlers::list_methods))
        .route(paths::METHOD, get(handlers::get_method))
        .route(paths::SIMULATE, post(simulate::simulate))
        .route(paths::STABILITY, post(stability::stability_map))
        .route(paths::STABILITY_POINT, post(stability::stability_point))
        .route(paths::WORK_PRECISION, post(studies::work_precision))
        .route(paths::ENERGY_MAP, post(studies::energy_map))
        .route(paths::CONVERGENCE, post(studies::convergence))
        .route(paths::SWEEP, post(studies::sweep))
        .route(paths::SWEEP_PRESETS, get(studies::sweep_presets))
        .route(paths::OPENAPI, get(handlers::openapi_json))
        .route(paths::RECORDINGS, get(recordings::list_recordings))
        .route(
            paths::RECORDING,
            get(recordings::get_recording).delete(recordings::delete_recording),
        )
        .route(paths::RECORDING_SAMPLES, get(recordings::recording_samples))
        .layer(DefaultBodyLimit::max(config.body_limit))
        .layer(RequestBodyLimitLayer::new(config.body_limit))
        .layer(from_fn_with_state(
            config.body_timeout,
            server::body_deadline,
        ));
    // Storing a recording takes a JSON body under the body limit or an .rrd upload under the
    // store's size cap; the handler enforces both (an upload is counted as it arrives), so this
    // route has no limit layer of its own beyond the JSON extractor's.
    let store = Router::new()
        .route(paths::RECORDINGS, post(recordings::create_recording))
        .layer(DefaultBodyLimit::max(config.body_limit))
        .layer(from_fn_with_state(
            config.body_timeout,
            server::body_deadline,
        ));
    let api = api
        .merge(store)
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
            .allow_headers([header::CONTENT_TYPE, header::ACCEPT])
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

//! `Authorization` headers fuzzed through the whole service (`app` in process, every middleware
//! included) with a tokens file: random bytes, random and malformed `Bearer` values, and near
//! misses of a real token (a character changed, cut, lengthened, another token's digest as the
//! token). The property: none passes (every answer is 401 in the error shape naming the
//! header), none answers 5xx. 10⁴ cases by default (each goes through the router, built once);
//! `PROPTEST_CASES` sets another count.

use std::sync::OnceLock;

use axum::body::Body;
use axum::http::{HeaderValue, Request};
use axum::Router;
use geomint::access::tokens::{digest, digest_text};
use geomint::access::{Anonymous, Quotas};
use geomint::http::{app, AppState, Config};
use proptest::prelude::*;
use proptest::test_runner::{Config as RunnerConfig, TestCaseError, TestRunner};
use serde_json::Value;
use tower::ServiceExt;

use crate::http_access::tokens_file;
use crate::server;

/// The service (its router, built once: building it is most of a case's cost otherwise), and a
/// valid token of it.
fn service() -> &'static (Router, String, tokio::runtime::Runtime) {
    static SERVICE: OnceLock<(Router, String, tokio::runtime::Runtime)> = OnceLock::new();
    SERVICE.get_or_init(|| {
        let dir = server::scratch_dir("fuzz-auth");
        let (file, secrets) = tokens_file(&dir, &[("admin", "admin", Quotas::default())]);
        let state = AppState::new(Config {
            data_dir: dir.join("recordings"),
            systems_dir: dir.join("systems"),
            access: geomint::access::AccessConfig {
                tokens_file: Some(file),
                anonymous: Anonymous::None,
                anonymous_quotas: Quotas::default(),
            },
            ..Config::default()
        });
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        (app(state), secrets["admin"].clone(), runtime)
    })
}

/// Sends `values` as `Authorization` headers to a route; the status.
fn send(path: &str, values: &[Vec<u8>]) -> Result<u16, TestCaseError> {
    let (router, _, runtime) = service();
    let mut request = Request::builder().method("GET").uri(path);
    for value in values {
        let Ok(value) = HeaderValue::from_bytes(value) else {
            return Ok(401); // not a header value hyper would pass on
        };
        request = request.header("authorization", value);
    }
    let request = request.body(Body::empty()).unwrap();
    let (status, bytes) = runtime.block_on(async {
        let response = router.clone().oneshot(request).await.unwrap();
        let status = response.status().as_u16();
        (
            status,
            axum::body::to_bytes(response.into_body(), usize::MAX)
                .await
                .unwrap(),
        )
    });
    prop_assert!(status < 500, "{path}: {status}");
    let answer: Value = serde_json::from_slice(&bytes)
        .map_err(|e| TestCaseError::fail(format!("{path}: {status}: not JSON: {e}")))?;
    prop_assert_eq!(status, 401, "{}: {:?} passed: {}", path, values, answer);
    prop_assert_eq!(&answer["error"]["code"], "unauthorized");
    prop_assert_eq!(&answer["error"]["field"], "Authorization");
    Ok(status)
}

/// A near miss of `token`.
fn near_miss(token: &str) -> impl Strategy<Value = Vec<u8>> {
    let token = token.to_string();
    let bytes = token.clone().into_bytes();
    prop_oneof![
        (any::<prop::sample::Index>(), any::<u8>()).prop_filter_map("a change", move |(i, b)| {
            let mut changed = bytes.clone();
            let i = i.index(changed.len());
            (changed[i] != b).then(|| {
                changed[i] = b;
                changed
            })
        }),
        any::<prop::sample::Index>().prop_map({
            let token = token.clone();
            move |i| token.as_bytes()[..i.index(token.len())].to_vec()
        }),
        "[ -~]{1,8}".prop_map({
            let token = token.clone();
            move |tail| format!("{token}{tail}").into_bytes()
        }),
        Just(token.to_ascii_uppercase().into_bytes()),
        Just(digest_text(&digest(&token)).into_bytes()),
    ]
}

fn header_value(token: String) -> impl Strategy<Value = Vec<u8>> {
    let scheme = prop::sample::select(vec![
        "Bearer ", "bearer ", "BEARER  ", "Basic ", "Bearer", "", " Bearer ", "Bearer\t",
    ]);
    prop_oneof![
        prop::collection::vec(any::<u8>(), 0..300),
        "[ -~]{0,300}".prop_map(String::into_bytes),
        (scheme.clone(), "[!-~]{1,300}").prop_map(|(s, t)| format!("{s}{t}").into_bytes()),
        (scheme, near_miss(&token)).prop_map(|(s, t)| [s.as_bytes(), &t].concat()),
    ]
}

#[test]
fn no_malformed_or_wrong_authorization_passes() {
    let (_, token, _) = service();
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(10_000);
    let mut runner = TestRunner::new(RunnerConfig {
        cases,
        failure_persistence: None,
        ..RunnerConfig::default()
    });
    let route = prop::sample::select(vec![
        "/api/v1/recordings",
        "/api/v1/methods",
        "/healthz",
        "/api/v1/systems/pendulum",
    ]);
    let values = prop::collection::vec(header_value(token.clone()), 1..3);
    runner
        .run(&(route, values), |(route, values)| {
            // Two copies of the real token are refused too; one alone passes, which the near
            // misses never are.
            send(route, &values).map(|_| ())
        })
        .unwrap();
    // The real token passes, so the refusals above are not of everything.
    let (router, token, runtime) = service();
    let request = Request::builder()
        .uri("/api/v1/recordings")
        .header("authorization", format!("Bearer {token}"))
        .body(Body::empty())
        .unwrap();
    let status = runtime
        .block_on(router.clone().oneshot(request))
        .unwrap()
        .status();
    assert_eq!(status.as_u16(), 200);
}

//! The HTTP API's refusals and limits over real HTTP: bad inputs get clean errors naming their
//! field, overload is answered 503 with Retry-After, a client that goes away frees its slot, the
//! time limit stops runs and keeps their samples, fifty concurrent requests are all answered.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use crate::http::{
    config, core_runs, expected_fragment, long_config, long_request, post, post_stream, wait_idle,
    Lines,
};
use crate::server;
use geomint::api::system::NoStoredSystems;
use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, get_json, start, Server};

/// Posts raw bytes and returns (status, error object).
async fn post_raw(
    server: &Server,
    body: impl Into<reqwest::Body>,
    content_type: Option<&str>,
) -> (u16, Value) {
    let mut request = client().post(server.url("/api/v1/simulate")).body(body);
    if let Some(ct) = content_type {
        request = request.header("content-type", ct);
    }
    let response = request.send().await.unwrap();
    let status = response.status().as_u16();
    assert_eq!(
        response.headers()["content-type"],
        "application/json",
        "status {status}"
    );
    let body: Value = response.json().await.unwrap();
    let error = body["error"].clone();
    let keys: BTreeSet<&str> = error
        .as_object()
        .expect("an error object")
        .keys()
        .map(String::as_str)
        .collect();
    assert_eq!(keys, BTreeSet::from(["code", "message", "field"]));
    assert!(!error["message"].as_str().unwrap().is_empty());
    (status, error)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_inputs_get_clean_errors() {
    let server = start(config()).await;
    let ok = r#""system": "pendulum", "methods": ["heun"], "h": 0.1, "t_end": 10"#;
    let osc = r#""system": "harmonic_oscillator", "h": 0.1, "t_end": 10"#;
    let cases: Vec<(String, u16, &str, Option<&str>)> = vec![
        (r#"{"system": "#.into(), 400, "malformed_json", None),
        ("".into(), 400, "malformed_json", None),
        ("[1, 2]".into(), 422, "invalid_type", None),
        (r#"{"system": "pendulum", "methods": ["heun"], "h": 1e999, "t_end": 10}"#.into(), 400, "malformed_json", Some("h")),
        (format!(r#"{{{ok}, "q0": [1e999]}}"#), 400, "malformed_json", Some("q0[0]")),
        (format!(r#"{{{ok}, "foo": 1}}"#), 422, "unknown_field", Some("foo")),
        (format!(r#"{{{ok}, "output": {{"every": 2, "format": "csv"}}}}"#), 422, "unknown_field", Some("output.format")),
        (format!(r#"{{{osc}, "methods": [{{"id": "rk4", "order": 4}}]}}"#), 422, "unknown_field", Some("methods[0].order")),
        (format!(r#"{{{ok}, "params": {{"omega": 1}}}}"#), 422, "unknown_field", Some("params.omega")),
        (r#"{"system": "double_pendulum", "methods": ["heun"], "h": 0.1, "t_end": 10}"#.into(), 422, "unknown_system", Some("system")),
        (format!(r#"{{{osc}, "methods": ["heun", "rk5"]}}"#), 422, "unknown_method", Some("methods[1]")),
        (format!(r#"{{{osc}, "method": {{"id": "modin_rks", "inner": "rk9"}}}}"#), 422, "unknown_method", Some("method.inner")),
        (format!(r#"{{{osc}, "methods": ["heun"], "method": "rk4"}}"#), 422, "invalid_value", Some("method")),
        (format!(r#"{{{osc}}}"#), 422, "missing_field", Some("methods")),
        (r#"{"system": "pendulum", "methods": ["heun"], "t_end": 10}"#.into(), 422, "missing_field", Some("h")),
        (r#"{"system": "elastic_pendulum_3d", "methods": ["heun", "csv1"], "h": 0.1, "t_end": 10}"#.into(), 422, "unmet_requirement", Some("methods[1]")),
        (r#"{"system": "pendulum", "methods": ["heun"], "h": 0, "t_end": 10}"#.into(), 422, "invalid_value", Some("h")),
        (r#"{"system": "pendulum", "methods": ["heun"], "h": -0.1, "t_end": 10}"#.into(), 422, "invalid_value", Some("h")),
        (r#"{"system": "pendulum", "methods": ["heun"], "h": "0.1", "t_end": 10}"#.into(), 422, "invalid_type", Some("h")),
        (r#"{"system": "pendulum", "methods": ["heun"], "h": 0.1, "t_end": 0}"#.into(), 422, "invalid_value", Some("t_end")),
        (r#"{"system": "pendulum", "methods": ["heun"], "h": 1e-7, "t_end": 10}"#.into(), 422, "too_many_steps", Some("t_end")),
        (r#"{"system": "pendulum", "methods": ["heun", "rk4"], "h": 1e-3, "t_end": 1000, "output": {"every": 1}}"#.into(), 422, "too_many_samples", Some("output.every")),
        (format!(r#"{{{ok}, "output": {{"every": 0}}}}"#), 422, "invalid_value", Some("output.every")),
        (format!(r#"{{{ok}, "output": {{"every": 2.5}}}}"#), 422, "invalid_type", Some("output.every")),
        (format!(r#"{{{ok}, "q0": [1, 2]}}"#), 422, "invalid_value", Some("q0")),
        (format!(r#"{{{ok}, "p0": [1, "x"]}}"#), 422, "invalid_type", Some("p0[1]")),
        (format!(r#"{{{ok}, "params": {{"gamma": -1}}}}"#), 422, "invalid_value", Some("params.gamma")),
        (format!(r#"{{{ok}, "params": {{"epsilon": 1e7}}}}"#), 422, "invalid_value", Some("params.epsilon")),
        (r#"{"system": "elastic_pendulum_3d", "methods": ["heun"], "h": 0.1, "t_end": 10, "jacobian_defect": true}"#.into(), 422, "invalid_value", Some("jacobian_defect")),
        (format!(r#"{{{ok}, "compare_to_reference": "yes"}}"#), 422, "invalid_type", Some("compare_to_reference")),
    ];
    for (body, status, code, field) in cases {
        let (got, error) = post_raw(&server, body.clone(), Some("application/json")).await;
        assert_eq!(
            (got, error["code"].as_str().unwrap()),
            (status, code),
            "{body}: {error}"
        );
        assert_eq!(error["field"].as_str(), field, "{body}: {error}");
    }

    // The unmet requirement is named.
    let (_, error) = post_raw(
        &server,
        r#"{"system": "elastic_pendulum_3d", "methods": ["csv2"], "h": 0.1, "t_end": 1}"#,
        Some("application/json"),
    )
    .await;
    assert!(
        error["message"]
            .as_str()
            .unwrap()
            .contains("conformal damping"),
        "{error}"
    );
    // A number JSON cannot carry is explained.
    let (_, error) = post_raw(&server, format!(r#"{{{ok}, "p0": [-1e400]}}"#), None).await;
    assert!(
        error["message"].as_str().unwrap().contains("out of range"),
        "{error}"
    );

    // A body over 1 MiB, streamed without a declared length: the server reads up to the limit.
    let big = format!(r#"{{"system": "{}"}}"#, "x".repeat((1 << 20) - 13));
    assert_eq!(big.len(), (1 << 20) + 1);
    let chunks: Vec<Result<Vec<u8>, std::io::Error>> = big
        .into_bytes()
        .chunks(64 * 1024)
        .map(|c| Ok(c.to_vec()))
        .collect();
    let streamed = reqwest::Body::wrap_stream(futures_util::stream::iter(chunks));
    let (status, error) = post_raw(&server, streamed, Some("application/json")).await;
    assert_eq!(
        (status, error["code"].as_str().unwrap()),
        (413, "payload_too_large")
    );
    // A declared length over the limit is refused before the body is read (a small limit here,
    // so that the whole body is sent before the answer comes).
    let small_limit = start(Config {
        body_limit: 1024,
        ..config()
    })
    .await;
    let (status, error) = post_raw(&small_limit, "x".repeat(4096), Some("application/json")).await;
    assert_eq!(
        (status, error["code"].as_str().unwrap()),
        (413, "payload_too_large")
    );

    // Not JSON.
    let (status, error) = post_raw(
        &server,
        "system=pendulum",
        Some("application/x-www-form-urlencoded"),
    )
    .await;
    assert_eq!(
        (status, error["code"].as_str().unwrap()),
        (415, "unsupported_media_type")
    );

    // Unknown routes and methods.
    let c = client();
    let response = c.get(server.url("/api/v2/simulate")).send().await.unwrap();
    assert_eq!(response.status(), 404);
    assert_eq!(
        response.json::<Value>().await.unwrap()["error"]["code"],
        "not_found"
    );
    let response = c.get(server.url("/api/v1/simulate")).send().await.unwrap();
    assert_eq!(response.status(), 405);
    assert_eq!(
        response.json::<Value>().await.unwrap()["error"]["code"],
        "method_not_allowed"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn overload_is_answered_503_with_retry_after() {
    let server = start(Config {
        queue_timeout: Duration::from_millis(50),
        ..long_config(1)
    })
    .await;
    let mut holder = Lines::new(post_stream(&server, &long_request()).await);
    assert_eq!(holder.next().await.unwrap()["type"], "header");
    assert_eq!(server.state.runs_in_progress(), 1);

    let small = json!({"system": "pendulum", "method": "heun", "h": 0.1, "t_end": 1});
    let started = Instant::now();
    let response = post(&server, &small).await;
    assert_eq!(response.status(), 503);
    assert!(
        started.elapsed() >= Duration::from_millis(50),
        "it waited the queue timeout"
    );
    assert_eq!(response.headers()["retry-after"], "1");
    let body: Value = response.json().await.unwrap();
    assert_eq!(body["error"]["code"], "overloaded");
    // Validation comes first: a bad request is still a 422 when the server is busy.
    let bad = post(
        &server,
        &json!({"system": "pendulum", "method": "heun", "h": -1, "t_end": 1}),
    )
    .await;
    assert_eq!(bad.status(), 422);
    let health = get_json(&server, "/healthz").await;
    assert_eq!(health["runs_in_progress"], 1);

    drop(holder);
    wait_idle(&server).await;
    assert_eq!(post(&server, &small).await.status(), 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_disconnect_frees_its_slot() {
    let server = start(long_config(1)).await;
    let mut stream = Lines::new(post_stream(&server, &long_request()).await);
    assert_eq!(stream.next().await.unwrap()["type"], "header");
    let chunk = stream.next().await.unwrap();
    assert_eq!(
        chunk["type"], "samples",
        "samples come while the run computes"
    );
    let small = json!({"system": "pendulum", "method": "heun", "h": 0.1, "t_end": 1});
    assert_eq!(post(&server, &small).await.status(), 503);

    drop(stream);
    let dropped = Instant::now();
    loop {
        let response = post(&server, &small).await;
        if response.status() == 200 {
            let doc: Value = response.json().await.unwrap();
            assert_eq!(doc["runs"][0]["stop"]["reason"], "finished");
            break;
        }
        assert_eq!(response.status(), 503);
        assert!(
            dropped.elapsed() < Duration::from_secs(3),
            "the slot was not freed"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    wait_idle(&server).await;

    // The same for a JSON request whose client gives up.
    let quick = reqwest::Client::builder()
        .no_proxy()
        .timeout(Duration::from_millis(300))
        .build()
        .unwrap();
    let gave_up = quick
        .post(server.url("/api/v1/simulate"))
        .json(&long_request())
        .send()
        .await;
    assert!(gave_up.unwrap_err().is_timeout());
    let freed = wait_idle(&server).await;
    assert!(freed < Duration::from_secs(3), "{freed:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_time_limit_stops_runs_and_keeps_their_samples() {
    let server = start(Config {
        request_timeout: Duration::from_millis(400),
        ..long_config(2)
    })
    .await;
    let started = Instant::now();
    let response = post(&server, &long_request()).await;
    assert_eq!(response.status(), 200);
    let doc: Value = response.json().await.unwrap();
    assert!(started.elapsed() < Duration::from_secs(3));
    let run = &doc["runs"][0];
    assert_eq!(run["stop"]["reason"], "time_limit");
    let steps = run["stats"]["steps"].as_u64().unwrap();
    assert_eq!(run["stop"]["step"], steps);
    assert!(steps > 0 && steps < 1_000_000_000);
    assert_eq!(
        run["t"].as_array().unwrap().len() as u64,
        steps / 10_000 + 1
    );

    // Streams stop the same way.
    let lines = Lines::new(post_stream(&server, &long_request()).await)
        .all()
        .await;
    let summary = lines.iter().find(|l| l["type"] == "summary").unwrap();
    assert_eq!(summary["stop"]["reason"], "time_limit");
    assert_eq!(lines.last().unwrap()["type"], "end");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fifty_concurrent_requests_are_all_answered_correctly() {
    let server = start(Config {
        max_concurrent: 64,
        ..config()
    })
    .await;
    let bodies: Vec<Value> = (0..50)
        .map(|i| {
            json!({"system": "harmonic_oscillator", "params": {"omega": 1.0 + 0.1 * i as f64},
                "methods": ["modin_3s", "rk4"], "h": 0.01, "t_end": 20, "output": {"every": 20}})
        })
        .collect();
    let c = client();
    let answers = futures_util::future::join_all(bodies.iter().map(|body| {
        let c = c.clone();
        let url = server.url("/api/v1/simulate");
        async move {
            let response = c.post(url).json(body).send().await.unwrap();
            (response.status().as_u16(), response.text().await.unwrap())
        }
    }))
    .await;
    for (body, (status, text)) in bodies.iter().zip(&answers) {
        assert_eq!(*status, 200);
        let req = geomint::api::SimulateRequest::from_value(body)
            .unwrap()
            .to_spec(&NoStoredSystems)
            .unwrap();
        let (sim, runs) = core_runs(&req);
        for (i, (traj, _)) in runs.iter().enumerate() {
            assert!(
                text.contains(&expected_fragment(&sim.methods[i].label(), traj)),
                "{body}"
            );
        }
    }
    assert_eq!(server.state.runs_in_progress(), 0);
}

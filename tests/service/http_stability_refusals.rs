//! The stability routes' refusals over real HTTP: bad inputs get clean errors naming the field,
//! a busy server answers maps 503 with Retry-After, and the OpenAPI document describes both routes.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use crate::http_stability::{config, post_error, MAP, POINT};
use crate::server;
use geomint::core::simulation::Limits;

use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, get_json, post_json as post, start};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_inputs_get_clean_errors_naming_the_field() {
    let server = start(config()).await;
    let axes = r#""gamma": {"min": 0, "max": 3.5, "n": 10}, "h": {"min": 0, "max": 1, "n": 10}"#;
    let map = |methods: &str, rest: &str| {
        format!(r#"{{"methods": {methods}, "omega": 3.51, {axes}{rest}}}"#)
    };
    let with_axes = |gamma: &str, h: &str| {
        format!(r#"{{"methods": ["csv1"], "omega": 3.51, "gamma": {gamma}, "h": {h}}}"#)
    };
    let ok_axis = r#"{"min": 0, "max": 1, "n": 10}"#;
    let thousand = r#"{"min": 0, "max": 1, "n": 1000}"#;
    let seventeen = format!("[{}]", vec!["\"heun\""; 17].join(", "));
    let cases: Vec<(String, u16, &str, Option<&str>)> = vec![
        (
            r#"{"methods": ["csv1"], "omega": "#.into(),
            400,
            "malformed_json",
            None,
        ),
        ("".into(), 400, "malformed_json", None),
        ("[1]".into(), 422, "invalid_type", None),
        (
            r#"{"methods": ["csv1"], "omega": 1e999}"#.into(),
            400,
            "malformed_json",
            Some("omega"),
        ),
        (
            with_axes(r#"{"min": 0, "max": -1e999, "n": 3}"#, ok_axis),
            400,
            "malformed_json",
            Some("gamma.max"),
        ),
        (
            map(r#"["csv1"]"#, r#", "step": 1"#),
            422,
            "unknown_field",
            Some("step"),
        ),
        (
            with_axes(ok_axis, r#"{"min": 0, "max": 1, "n": 10, "step": 0.1}"#),
            422,
            "unknown_field",
            Some("h.step"),
        ),
        (
            map(r#"["csv1", "rk5"]"#, ""),
            422,
            "unknown_method",
            Some("methods[1]"),
        ),
        (
            map(r#"[{"id": "modin_rks", "inner": "rk9"}]"#, ""),
            422,
            "unknown_method",
            Some("methods[0].inner"),
        ),
        (
            map(r#"[{"id": "rk4", "order": 4}]"#, ""),
            422,
            "unknown_field",
            Some("methods[0].order"),
        ),
        (
            map(r#"["csv1", "reference"]"#, ""),
            422,
            "invalid_value",
            Some("methods[1]"),
        ),
        (
            map(r#"[{"id": "reference", "tolerance": 1e-10}]"#, ""),
            422,
            "invalid_value",
            Some("methods[0].id"),
        ),
        (
            map(r#"[{"id": "triple_jump", "base": "heun"}]"#, ""),
            422,
            "invalid_value",
            Some("methods[0].base"),
        ),
        (
            map(r#"[{"id": "csv1", "base": "csv2"}]"#, ""),
            422,
            "invalid_value",
            Some("methods[0].base"),
        ),
        (map("[]", ""), 422, "invalid_value", Some("methods")),
        (map(&seventeen, ""), 422, "invalid_value", Some("methods")),
        (map(r#""csv1""#, ""), 422, "invalid_type", Some("methods")),
        (map("[3]", ""), 422, "invalid_type", Some("methods[0]")),
        (
            format!(r#"{{"omega": 3.51, {axes}}}"#),
            422,
            "missing_field",
            Some("methods"),
        ),
        (
            r#"{"methods": ["csv1"], "omega": 3.51, "gamma": {"min": 0, "max": 1, "n": 2}}"#.into(),
            422,
            "missing_field",
            Some("h"),
        ),
        (
            with_axes(r#"{"min": 0, "max": 1}"#, ok_axis),
            422,
            "missing_field",
            Some("gamma.n"),
        ),
        (
            format!(r#"{{"methods": ["csv1"], "omega": 0, {axes}}}"#),
            422,
            "invalid_value",
            Some("omega"),
        ),
        (
            format!(r#"{{"methods": ["csv1"], "omega": -3.51, {axes}}}"#),
            422,
            "invalid_value",
            Some("omega"),
        ),
        (
            format!(r#"{{"methods": ["csv1"], "omega": "3.51", {axes}}}"#),
            422,
            "invalid_type",
            Some("omega"),
        ),
        (
            with_axes(r#"{"min": -0.5, "max": 1, "n": 10}"#, ok_axis),
            422,
            "invalid_value",
            Some("gamma.min"),
        ),
        (
            with_axes(ok_axis, r#"{"min": 1, "max": 0.5, "n": 10}"#),
            422,
            "invalid_value",
            Some("h.max"),
        ),
        (
            with_axes(ok_axis, r#"{"min": -1, "max": 1, "n": 10}"#),
            422,
            "invalid_value",
            Some("h.min"),
        ),
        (
            with_axes(r#"{"min": 0, "max": 1, "n": 1}"#, ok_axis),
            422,
            "invalid_value",
            Some("gamma.n"),
        ),
        (
            with_axes(ok_axis, r#"{"min": 0, "max": 1, "n": 1001}"#),
            422,
            "invalid_value",
            Some("h.n"),
        ),
        (
            with_axes(ok_axis, r#"{"min": 0, "max": 1, "n": 2.5}"#),
            422,
            "invalid_type",
            Some("h.n"),
        ),
        (
            with_axes(ok_axis, r#"{"min": 0, "max": 1, "n": -3}"#),
            422,
            "invalid_type",
            Some("h.n"),
        ),
        (
            with_axes("[0, 1, 10]", ok_axis),
            422,
            "invalid_type",
            Some("gamma"),
        ),
        (
            format!(
                r#"{{"methods": ["csv1", "csv2", "cimp", "heun", "rk4"], "omega": 3.51, "gamma": {thousand}, "h": {thousand}}}"#
            ),
            422,
            "too_many_cells",
            Some("methods"),
        ),
    ];
    let point_cases: Vec<(String, u16, &str, Option<&str>)> = vec![
        (r#"{"method": "csv1""#.into(), 400, "malformed_json", None),
        (r#"{"method": "csv1", "omega": 3.51, "gamma": 1e999, "h": 0.1}"#.into(), 400, "malformed_json", Some("gamma")),
        (r#"{"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": 0.1, "n": 3}"#.into(), 422, "unknown_field", Some("n")),
        (r#"{"methods": ["csv1"], "omega": 3.51, "gamma": 0.5, "h": 0.1}"#.into(), 422, "unknown_field", Some("methods")),
        (r#"{"omega": 3.51, "gamma": 0.5, "h": 0.1}"#.into(), 422, "missing_field", Some("method")),
        (r#"{"method": "csv1", "omega": 3.51, "h": 0.1}"#.into(), 422, "missing_field", Some("gamma")),
        (r#"{"method": "rk5", "omega": 3.51, "gamma": 0.5, "h": 0.1}"#.into(), 422, "unknown_method", Some("method")),
        (r#"{"method": {"id": "triple_jump", "base": "rk9"}, "omega": 3.51, "gamma": 0.5, "h": 0.1}"#.into(), 422, "unknown_method", Some("method.base")),
        (r#"{"method": "reference", "omega": 3.51, "gamma": 0.5, "h": 0.1}"#.into(), 422, "invalid_value", Some("method")),
        (r#"{"method": {"id": "reference"}, "omega": 3.51, "gamma": 0.5, "h": 0.1}"#.into(), 422, "invalid_value", Some("method.id")),
        (r#"{"method": "csv1", "omega": 0, "gamma": 0.5, "h": 0.1}"#.into(), 422, "invalid_value", Some("omega")),
        (r#"{"method": "csv1", "omega": 3.51, "gamma": -0.5, "h": 0.1}"#.into(), 422, "invalid_value", Some("gamma")),
        (r#"{"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": 0}"#.into(), 422, "invalid_value", Some("h")),
        (r#"{"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": -0.1}"#.into(), 422, "invalid_value", Some("h")),
        (r#"{"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": true}"#.into(), 422, "invalid_type", Some("h")),
    ];
    let all = cases
        .into_iter()
        .map(|c| (MAP, c))
        .chain(point_cases.into_iter().map(|c| (POINT, c)));
    for (path, (body, status, code, field)) in all {
        let (got, error) = post_error(&server, path, body.clone(), "application/json").await;
        assert_eq!(
            (got, error["code"].as_str().unwrap()),
            (status, code),
            "{path} {body}: {error}"
        );
        assert_eq!(error["field"].as_str(), field, "{path} {body}: {error}");
    }

    // The refusal of `reference` says why.
    let (_, error) = post_error(
        &server,
        POINT,
        r#"{"method": "reference", "omega": 3.51, "gamma": 0.5, "h": 0.1}"#.into(),
        "application/json",
    )
    .await;
    assert!(
        error["message"]
            .as_str()
            .unwrap()
            .contains("no propagation matrix"),
        "{error}"
    );
    // Not JSON, and the wrong HTTP method.
    for path in [MAP, POINT] {
        let (status, error) = post_error(&server, path, "method=csv1".into(), "text/plain").await;
        assert_eq!(
            (status, error["code"].as_str().unwrap()),
            (415, "unsupported_media_type")
        );
        let response = client().get(server.url(path)).send().await.unwrap();
        assert_eq!(response.status(), 405);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_busy_server_answers_maps_503_with_retry_after() {
    let server = start(Config {
        max_concurrent: 1,
        queue_timeout: Duration::from_millis(50),
        long_queue_timeout: Duration::from_millis(50),
        limits: Limits {
            max_steps: 10_000_000_000,
            max_samples: 1_000_000,
        },
        ..config()
    })
    .await;
    // A long simulation holds the only slot while its stream is read.
    let holder = client()
        .post(server.url("/api/v1/simulate"))
        .header("accept", "application/x-ndjson")
        .json(
            &json!({"system": "pendulum", "method": "modin_3s", "h": 1e-3, "t_end": 1e6,
            "output": {"every": 10000}}),
        )
        .send()
        .await
        .unwrap();
    assert_eq!(holder.status(), 200);
    let started = Instant::now();
    while server.state.runs_in_progress() == 0 {
        assert!(
            started.elapsed() < Duration::from_secs(5),
            "the run did not start"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let body = json!({"methods": ["csv1"], "omega": 3.51,
        "gamma": {"min": 0, "max": 3.5, "n": 20}, "h": {"min": 0, "max": 1, "n": 20}});
    let started = Instant::now();
    let response = client()
        .post(server.url(MAP))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 503);
    assert!(
        started.elapsed() >= Duration::from_millis(50),
        "it waited the queue timeout"
    );
    assert_eq!(response.headers()["retry-after"], "1");
    assert_eq!(
        response.json::<Value>().await.unwrap()["error"]["code"],
        "overloaded"
    );
    // Validation comes first: a bad request is still a 422 when the server is busy.
    let mut bad = body.clone();
    bad["omega"] = json!(-1);
    let (status, _) = post(&server, MAP, &bad).await;
    assert_eq!(status, 422);
    // A point takes no slot.
    let (status, _) = post(
        &server,
        POINT,
        &json!({"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": 0.2}),
    )
    .await;
    assert_eq!(status, 200);

    drop(holder);
    let started = Instant::now();
    while server.state.runs_in_progress() > 0 {
        assert!(
            started.elapsed() < Duration::from_secs(10),
            "the run did not stop"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let (status, doc) = post(&server, MAP, &body).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(
        server.state.runs_in_progress(),
        0,
        "the map gave its slot back"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn openapi_documents_the_stability_routes() {
    let server = start(config()).await;
    let doc = get_json(&server, "/api/v1/openapi.json").await;
    for path in [MAP, POINT] {
        let post = &doc["paths"][path]["post"];
        assert!(
            post["responses"]["200"]["content"]["application/json"].is_object(),
            "{path}"
        );
        assert!(post["responses"]["422"].is_object(), "{path}");
    }
    assert!(doc["paths"][MAP]["post"]["responses"]["503"]["headers"]["Retry-After"].is_object());
    let schemas = doc["components"]["schemas"].as_object().unwrap();
    for (name, fields) in [
        ("StabilityRequest", geomint::api::stability::MAP_FIELDS),
        ("PointRequest", geomint::api::stability::POINT_FIELDS),
        ("AxisSpec", geomint::api::stability::AXIS_FIELDS),
    ] {
        let documented: BTreeSet<&str> = schemas[name]["properties"]
            .as_object()
            .unwrap_or_else(|| panic!("{name} missing"))
            .keys()
            .map(String::as_str)
            .collect();
        let parsed: BTreeSet<&str> = fields.iter().copied().collect();
        assert_eq!(
            documented, parsed,
            "{name}: the documented fields are the parsed ones"
        );
    }
    for name in [
        "StabilityDocument",
        "MapDocument",
        "PointDocument",
        "SpectrumDocument",
    ] {
        assert!(schemas.contains_key(name), "{name} missing");
    }
}

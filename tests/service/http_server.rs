//! The server around the routes over real HTTP: the OpenAPI document lists every route,
//! compression, CORS and request ids, panics in blocking work become 500, and shutdown cancels
//! running simulations after the grace time.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use crate::http::{
    config, long_config, long_request, pendulum_request, post_stream, Lines, NDJSON,
};
use crate::server;
use geomint::http::{AppState, Config};
use serde_json::{json, Value};
use server::{client, get_json, start, Server};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn openapi_lists_every_route() {
    let jobs = geomint::jobs::JobsConfig {
        dir: server::scratch_dir("openapi-jobs"),
        max_per_owner: 10,
        part_steps: 1_000_000,
        time_limit: Duration::from_secs(600),
        parts_in_flight: 1,
    };
    let server = start(Config {
        jobs: Some(jobs),
        ..config()
    })
    .await;
    let c = client();
    let doc = get_json(&server, "/api/v1/openapi.json").await;
    assert!(doc["openapi"].as_str().unwrap().starts_with("3."));
    let paths = doc["paths"].as_object().unwrap();
    let documented: BTreeSet<(String, String)> = paths
        .iter()
        .flat_map(|(path, ops)| {
            ops.as_object()
                .unwrap()
                .keys()
                .map(move |m| (m.clone(), path.clone()))
        })
        .collect();
    // The router and the document come from one registration (`http::routes`); every
    // documented route must answer below.
    assert_eq!(documented.len(), 32, "{documented:?}");
    // Two stored recordings: one to download, one to delete.
    let mut ids = Vec::new();
    for _ in 0..2 {
        let created: Value = c
            .post(server.url("/api/v1/recordings"))
            .json(&pendulum_request())
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        let id = created["id"].as_str();
        ids.push(id.unwrap_or_else(|| panic!("{created}")).to_string());
    }
    // Two stored system definitions: one to read, one to delete.
    let definition = json!({"coordinates": ["x"], "potential": "x^2/2"});
    let mut systems = Vec::new();
    for potential in ["x^2/2", "x^4/4"] {
        let stored: Value = c
            .post(server.url("/api/v1/systems"))
            .json(&json!({"coordinates": ["x"], "potential": potential}))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        systems.push(
            stored["id"]
                .as_str()
                .unwrap_or_else(|| panic!("{stored}"))
                .to_string(),
        );
    }
    // Two finished jobs: one to read, one to remove.
    let sweep = json!({"system": "pendulum", "t_end": 1, "h": 0.1,
        "methods": ["rk4"], "axes": [{"name": "params.gamma", "min": 0, "max": 1, "n": 3}]});
    let job = json!({"study": "sweep", "request": sweep});
    let mut jobs = Vec::new();
    for _ in 0..2 {
        let submitted: Value = c
            .post(server.url("/api/v1/jobs"))
            .json(&job)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        let id = submitted["id"].as_str();
        jobs.push(id.unwrap_or_else(|| panic!("{submitted}")).to_string());
    }
    for id in &jobs {
        let events = c
            .get(server.url(&format!("/api/v1/jobs/{id}/events")))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        let last: Value = serde_json::from_str(events.lines().last().unwrap()).unwrap();
        assert_eq!(last["event"], "done", "{events}");
    }
    // Every documented route answers (path parameters filled in).
    for (method, path) in &documented {
        let (recording, system, job_id) = match method.as_str() {
            "delete" => (ids[1].clone(), &systems[1], &jobs[1]),
            _ => (format!("{}.rrd", ids[0]), &systems[0], &jobs[0]),
        };
        let url = server.url(
            &path
                .replace("/systems/{id}", &format!("/systems/{system}"))
                .replace("/methods/{id}", "/methods/rk4")
                .replace("/jobs/{id}", &format!("/jobs/{job_id}"))
                .replace(
                    "/recordings/{id}/samples",
                    &format!("/recordings/{}/samples", ids[0]),
                )
                .replace("/recordings/{id}", &format!("/recordings/{recording}")),
        );
        let body = match path.as_str() {
            "/api/v1/stability" => json!({"methods": ["csv1"], "omega": 3.51,
                "gamma": {"min": 0, "max": 3.5, "n": 5}, "h": {"min": 0, "max": 1, "n": 5}}),
            "/api/v1/stability/point" => {
                json!({"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": 0.2})
            }
            "/api/v1/studies/work-precision" => json!({"system": "pendulum", "t_end": 10,
                "runs": [{"method": "rk4", "h": [0.1]}]}),
            "/api/v1/studies/energy-map" => json!({"nx": 3, "ny": 3, "t_max": 10}),
            "/api/v1/simulate/allowed-region" => json!({"system": "henon_heiles", "method": "rk4",
                "h": 0.1, "t_end": 1, "q0": [0, 0], "p0": [0, 0],
                "energy": {"value": 0.125, "momentum": "p_x"},
                "plane": {"x": {"name": "y", "min": -0.5, "max": 0.5, "points": 5},
                          "y": {"name": "p_y", "min": -0.5, "max": 0.5, "points": 5}}}),
            "/api/v1/studies/convergence" => json!({"system": "pendulum", "t_end": 1,
                "methods": ["rk4"], "h": [0.1, 0.05]}),
            "/api/v1/studies/sweep" => json!({"system": "pendulum", "t_end": 1, "h": 0.1,
                "methods": ["rk4"], "axes": [{"name": "params.gamma", "min": 0, "max": 1, "n": 3}]}),
            "/api/v1/studies/basins" => json!({"system": "pendulum", "t_end": 10, "h": 0.1,
                "methods": ["modin_3s"], "axes": [{"name": "q0[0]", "min": -1, "max": 1, "n": 3}]}),
            "/api/v1/systems" => definition.clone(),
            "/api/v1/jobs" => job.clone(),
            _ => pendulum_request(),
        };
        let (status, expected) = match method.as_str() {
            "get" => (c.get(url).send().await.unwrap().status(), 200),
            "delete" => (c.delete(url).send().await.unwrap().status(), 204),
            _ => (
                c.post(url).json(&body).send().await.unwrap().status(),
                // (The definition posted to /api/v1/systems is stored already: 200.)
                match path.as_str() {
                    "/api/v1/recordings" => 201,
                    "/api/v1/jobs" => 202,
                    _ => 200,
                },
            ),
        };
        assert_eq!(status, expected, "{method} {path}");
    }
    let _ = std::fs::remove_dir_all(&server.state.config.data_dir);
    let _ = std::fs::remove_dir_all(&server.state.config.systems_dir);
    let schemas = doc["components"]["schemas"].as_object().unwrap();
    for name in [
        "SimulateRequest",
        "SimulationDocument",
        "RunDocument",
        "StreamLine",
        "ErrorBody",
        "SystemEntry",
        "MethodEntry",
    ] {
        assert!(schemas.contains_key(name), "{name} missing");
    }
    let properties: BTreeSet<&str> = schemas["SimulateRequest"]["properties"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    let parsed: BTreeSet<&str> = geomint::api::simulate::REQUEST_FIELDS
        .iter()
        .copied()
        .collect();
    assert_eq!(
        properties, parsed,
        "the documented request fields are the parsed ones"
    );
    let simulate = &paths["/api/v1/simulate"]["post"];
    let content = simulate["responses"]["200"]["content"].as_object().unwrap();
    assert!(content.contains_key("application/json") && content.contains_key(NDJSON));
    assert!(simulate["responses"]["503"]["headers"]["Retry-After"].is_object());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn compression_cors_and_request_ids() {
    let server = start(Config {
        cors_origins: vec!["http://app.example".into()],
        ..config()
    })
    .await;
    let c = client();
    let response = c
        .get(server.url("/api/v1/systems"))
        .header("accept-encoding", "gzip")
        .send()
        .await
        .unwrap();
    assert_eq!(response.headers()["content-encoding"], "gzip");
    assert!(response.headers().contains_key("x-request-id"));
    let streamed = c
        .post(server.url("/api/v1/simulate"))
        .header("accept", NDJSON)
        .header("accept-encoding", "gzip")
        .json(&pendulum_request())
        .send()
        .await
        .unwrap();
    assert!(
        !streamed.headers().contains_key("content-encoding"),
        "streams are not compressed"
    );
    let lines = Lines::new(streamed).all().await;
    assert_eq!(lines.last().unwrap()["type"], "end");

    let allowed = c
        .get(server.url("/healthz"))
        .header("origin", "http://app.example")
        .send()
        .await
        .unwrap();
    assert_eq!(
        allowed.headers()["access-control-allow-origin"],
        "http://app.example"
    );
    let other = c
        .get(server.url("/healthz"))
        .header("origin", "http://other.example")
        .send()
        .await
        .unwrap();
    assert!(!other.headers().contains_key("access-control-allow-origin"));
    let preflight = c
        .request(reqwest::Method::OPTIONS, server.url("/api/v1/simulate"))
        .header("origin", "http://app.example")
        .header("access-control-request-method", "POST")
        .send()
        .await
        .unwrap();
    assert!(preflight.status().is_success());
    assert!(preflight.headers()["access-control-allow-methods"]
        .to_str()
        .unwrap()
        .contains("POST"));

    // CORS is off by default.
    let plain = start(config()).await;
    let response = c
        .get(plain.url("/healthz"))
        .header("origin", "http://app.example")
        .send()
        .await
        .unwrap();
    assert!(!response
        .headers()
        .contains_key("access-control-allow-origin"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn panics_in_blocking_work_become_500() {
    let result = geomint::http::run_blocking(|| -> u32 { panic!("secret detail") }).await;
    let error = result.unwrap_err();
    assert_eq!(error.status_code(), 500);
    assert_eq!(error.detail().code.as_str(), "internal");
    assert!(!error.detail().message.contains("secret"));
    assert_eq!(geomint::http::run_blocking(|| 6 * 7).await.unwrap(), 42);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_cancels_running_simulations_after_the_grace_time() {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let state = AppState::new(Config {
        shutdown_grace: Duration::from_millis(100),
        ..long_config(2)
    });
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let server = tokio::spawn(geomint::http::serve_on(listener, state.clone(), async {
        let _ = stop_rx.await;
    }));
    let handle = Server {
        base: format!("http://{addr}"),
        addr,
        state,
    };
    let mut stream = Lines::new(post_stream(&handle, &long_request()).await);
    assert_eq!(stream.next().await.unwrap()["type"], "header");
    let signalled = Instant::now();
    stop_tx.send(()).unwrap();
    let mut rest = Vec::new();
    while let Some(line) = stream.next().await {
        rest.push(line);
    }
    let summary = rest.iter().find(|l| l["type"] == "summary").unwrap();
    assert_eq!(summary["stop"]["reason"], "cancelled");
    assert_eq!(rest.last().unwrap()["type"], "end");
    tokio::time::timeout(Duration::from_secs(5), server)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    assert!(signalled.elapsed() < Duration::from_secs(3));
}

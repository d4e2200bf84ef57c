//! The HTTP API over real HTTP: each test starts `app(state)` on a loopback port and talks to it
//! with reqwest.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use crate::server;
use geomint::api::system::NoStoredSystems;
use geomint::core::methods::{Method, MethodId};
use geomint::core::run::{Budget, StopReason};
use geomint::core::simulation::{ColumnSink, Columns, Limits, Simulation, SimulationSpec};

use geomint::http::{AppState, Config};
use serde_json::{json, Value};
use server::{client, start, Server};

const NDJSON: &str = "application/x-ndjson";

/// A test configuration: a safety time limit so that no run outlives its test, and recordings
/// in a scratch directory of this test process.
fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(15),
        data_dir: server::scratch_dir("http"),
        systems_dir: server::scratch_dir("http-systems"),
        ..Config::default()
    }
}

async fn post(server: &Server, body: &Value) -> reqwest::Response {
    client()
        .post(server.url("/api/v1/simulate"))
        .json(body)
        .send()
        .await
        .unwrap()
}

async fn post_stream(server: &Server, body: &Value) -> reqwest::Response {
    client()
        .post(server.url("/api/v1/simulate"))
        .header("accept", NDJSON)
        .json(body)
        .send()
        .await
        .unwrap()
}

/// Reads NDJSON lines from a streaming response.
struct Lines {
    response: reqwest::Response,
    buffer: Vec<u8>,
}

impl Lines {
    fn new(response: reqwest::Response) -> Self {
        Self {
            response,
            buffer: Vec::new(),
        }
    }

    async fn next(&mut self) -> Option<Value> {
        loop {
            if let Some(i) = self.buffer.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.buffer.drain(..=i).collect();
                return Some(serde_json::from_slice(&line).expect("each line is JSON"));
            }
            match self.response.chunk().await.unwrap() {
                Some(chunk) => self.buffer.extend_from_slice(&chunk),
                None => {
                    assert!(self.buffer.is_empty(), "a partial last line");
                    return None;
                }
            }
        }
    }

    async fn all(mut self) -> Vec<Value> {
        let mut lines = Vec::new();
        while let Some(line) = self.next().await {
            lines.push(line);
        }
        lines
    }
}

/// The core's runs for a core request.
fn core_runs(req: &SimulationSpec) -> (Simulation, Vec<(Columns, StopReason)>) {
    let sim = Simulation::prepare(req, &Limits::default()).unwrap();
    let reference = sim.reference_energies(Budget::default()).unwrap();
    let runs = (0..sim.methods.len())
        .map(|i| {
            let mut sink = ColumnSink::new(sim.invariant_names());
            let outcome = sim
                .run_method(i, reference.as_deref(), Budget::default(), &mut sink)
                .unwrap();
            (sink.take(), outcome.stop)
        })
        .collect();
    (sim, runs)
}

/// The exact text the response must contain for run `traj` of `label`: every number in the
/// shortest form that round-trips, so a match is a bit-for-bit match.
fn expected_fragment(label: &str, traj: &Columns) -> String {
    fn s(v: &impl serde::Serialize) -> String {
        serde_json::to_string(v).unwrap()
    }
    let mut text = format!(
        "\"method\":{},\"t\":{},\"q\":{},\"p\":{},\"energy\":{}",
        s(&label.to_string()),
        s(&traj.t),
        s(&traj.q),
        s(&traj.p),
        s(&traj.energy)
    );
    if let Some(e) = &traj.energy_error {
        text.push_str(&format!(",\"energy_error\":{}", s(e)));
    }
    text.push_str(&format!(",\"invariants\":{}", s(&traj.invariants)));
    text
}

fn pendulum_request() -> Value {
    json!({
        "system": "pendulum",
        "params": {"epsilon": 0.01},
        "methods": ["modin_3s", "heun"],
        "h": 0.1,
        "t_end": 200,
        "q0": [2.827433],
        "p0": [0.0],
        "output": {"every": 10},
        "compare_to_reference": false
    })
}

/// A request that runs for a long time (cut short by cancellation or the time limit).
fn long_request() -> Value {
    json!({"system": "pendulum", "method": "modin_3s", "h": 1e-3, "t_end": 1e6, "output": {"every": 10000}})
}

/// `max_concurrent` slots and no short lane: small runs probe whether the long ones hold them.
fn long_config(max_concurrent: usize) -> Config {
    Config {
        max_concurrent,
        short_lane: 0,
        queue_timeout: Duration::ZERO,
        long_queue_timeout: Duration::ZERO,
        limits: Limits {
            max_steps: 10_000_000_000,
            max_samples: 1_000_000,
        },
        ..config()
    }
}

/// Waits until no simulation thread runs (so that no blocking work outlives the test).
async fn wait_idle(server: &Server) -> Duration {
    let started = Instant::now();
    while server.state.runs_in_progress() > 0 {
        assert!(
            started.elapsed() < Duration::from_secs(10),
            "runs did not stop"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    started.elapsed()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn catalogs_match_the_core() {
    let server = start(config()).await;
    let c = client();
    let systems: Value = c
        .get(server.url("/api/v1/systems"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(
        systems,
        serde_json::to_value(geomint::core::systems::catalog()).unwrap()
    );
    let ids: Vec<&str> = systems
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["id"].as_str().unwrap())
        .collect();
    assert_eq!(
        ids,
        [
            "harmonic_oscillator",
            "pendulum",
            "elastic_pendulum_3d",
            "nbody",
            "elastic_pendulum_2d",
            "free_particle_2d",
            "exponential_decay",
            "gompertz",
            "henon_heiles",
        ]
    );
    let omega = &systems[0]["params"][0];
    assert_eq!(
        (omega["name"].as_str(), omega["kind"].as_str()),
        (Some("omega"), Some("number"))
    );

    let methods: Value = c
        .get(server.url("/api/v1/methods"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let core: Vec<_> = geomint::core::methods::MethodId::ALL
        .iter()
        .map(|m| m.info())
        .collect();
    assert_eq!(methods, serde_json::to_value(core).unwrap());
    let methods = methods.as_array().unwrap();
    assert_eq!(methods.len(), geomint::core::methods::MethodId::ALL.len());
    for m in methods {
        for key in [
            "id",
            "name",
            "order",
            "kind",
            "symplectic",
            "conformal_symplectic",
            "requirements",
            "group",
            "options",
        ] {
            assert!(m.get(key).is_some(), "{key} missing in {m}");
        }
        assert!(m["reference"]["paper"].is_string() && m["reference"]["equation"].is_string());
    }
    let csv1 = methods.iter().find(|m| m["id"] == "csv1").unwrap();
    assert_eq!(
        csv1["requirements"],
        json!(["separable_constant_mass", "conformal_damping"])
    );

    let one: Value = c
        .get(server.url("/api/v1/systems/nbody"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(
        one["invariants"],
        json!(["L_x", "L_y", "L_z", "L_conformal"])
    );
    let rk4: Value = c
        .get(server.url("/api/v1/methods/rk4"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(rk4["order"], 4);
    let missing = c
        .get(server.url("/api/v1/methods/rk5"))
        .send()
        .await
        .unwrap();
    assert_eq!(missing.status(), 404);
    let body: Value = missing.json().await.unwrap();
    assert_eq!(body["error"]["code"], "not_found");

    let health: Value = c
        .get(server.url("/healthz"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(health["status"], "ok");
    assert_eq!(health["runs_in_progress"], 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulate_equals_the_core_bit_for_bit() {
    let server = start(config()).await;
    let response = post(&server, &pendulum_request()).await;
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "application/json");
    let text = response.text().await.unwrap();

    let req = SimulationSpec {
        q0: Some(vec![2.827433]),
        p0: Some(vec![0.0]),
        every: Some(10),
        ..SimulationSpec::new(
            "pendulum",
            &[Method::new(MethodId::Modin3s), Method::new(MethodId::Heun)],
            0.1,
            200.0,
        )
        .param("epsilon", 0.01)
    };
    let (sim, runs) = core_runs(&req);
    for (i, (traj, stop)) in runs.iter().enumerate() {
        assert_eq!(*stop, StopReason::Finished);
        let fragment = expected_fragment(&sim.methods[i].label(), traj);
        assert!(text.contains(&fragment), "run {i} differs from the core");
        assert_eq!(traj.t.len(), 201);
        let q: Vec<f64> = traj.q.iter().map(|q| q[0]).collect();
        let drift = sim.dissipation_drift(&traj.t, &q).unwrap();
        assert!(drift.len() > 5);
        let drift = format!(
            "\"dissipation_drift\":{}",
            serde_json::to_string(&drift).unwrap()
        );
        assert!(
            text.contains(&drift),
            "run {i}: drift differs from the core"
        );
    }

    let doc: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(doc["system"]["id"], "pendulum");
    assert_eq!(doc["system"]["params"], json!({"gamma": 0.005}));
    let runs = doc["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    for run in runs {
        assert_eq!(run["diverged_at"], Value::Null);
        assert_eq!(run["stop"]["reason"], "finished");
        assert_eq!(run["stats"]["steps"], 2000);
        assert!(run["stats"]["wall_time_ms"].as_f64().unwrap() >= 0.0);
        // The pendulum has no exact solution: no energy error unless compared to the reference.
        assert!(run.get("energy_error").is_none());
        assert_eq!(run["q"].as_array().unwrap().len(), 201);
    }
    // Damping takes energy away.
    let energy = runs[0]["energy"].as_array().unwrap();
    assert!(energy.last().unwrap().as_f64().unwrap() < energy[0].as_f64().unwrap());

    // The stream's summaries carry the same drift.
    let lines = Lines::new(post_stream(&server, &pendulum_request()).await)
        .all()
        .await;
    for (i, run) in runs.iter().enumerate() {
        let summary = lines
            .iter()
            .find(|l| l["type"] == "summary" && l["method"] == i)
            .unwrap();
        assert_eq!(summary["dissipation_drift"], run["dissipation_drift"]);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn energy_errors_and_reference_match_the_core() {
    let server = start(config()).await;
    // The oscillator's exact solution gives energy errors.
    let body = json!({"system": "harmonic_oscillator", "params": {"omega": 2.0, "gamma": 0.1},
        "methods": ["csv1", "rk4"], "h": 0.05, "t_end": 20, "q0": [1.0], "p0": [0.5]});
    let text = post(&server, &body).await.text().await.unwrap();
    let req = geomint::api::SimulateRequest::from_value(&body)
        .unwrap()
        .to_spec(&NoStoredSystems)
        .unwrap();
    let (sim, runs) = core_runs(&req);
    for (i, (traj, _)) in runs.iter().enumerate() {
        assert!(traj.energy_error.is_some());
        assert!(
            text.contains(&expected_fragment(&sim.methods[i].label(), traj)),
            "run {i}"
        );
    }

    // Against the reference integrator, on a system without an exact solution.
    let body = json!({"system": "elastic_pendulum_3d", "methods": ["modin_3s"], "h": 0.05, "t_end": 5,
        "compare_to_reference": true});
    let text = post(&server, &body).await.text().await.unwrap();
    let req = geomint::api::SimulateRequest::from_value(&body)
        .unwrap()
        .to_spec(&NoStoredSystems)
        .unwrap();
    let (_, runs) = core_runs(&req);
    let (traj, _) = &runs[0];
    assert_eq!(traj.energy_error.as_ref().unwrap().len(), traj.t.len());
    assert!(text.contains(&expected_fragment("modin_3s", traj)));
    let doc: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(doc["invariants"], json!(["J3"]));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn several_methods_keep_their_order() {
    let server = start(config()).await;
    let body = json!({"system": "harmonic_oscillator", "h": 0.01, "t_end": 10,
        "methods": ["rk4", {"id": "modin_rks", "inner": "rk4"}, {"id": "triple_jump", "base": "csv1"}, "heun", "modin_3s"]});
    let doc: Value = post(&server, &body).await.json().await.unwrap();
    let labels: Vec<&str> = doc["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["method"].as_str().unwrap())
        .collect();
    assert_eq!(
        labels,
        [
            "rk4",
            "modin_rks(rk4)",
            "triple_jump(csv1)",
            "heun",
            "modin_3s"
        ]
    );
    let evals = |i: usize| {
        doc["runs"][i]["stats"]["force_evaluations"]
            .as_u64()
            .unwrap()
    };
    assert_eq!(evals(0), 4 * 1000);
    assert_eq!(evals(3), 2 * 1000);
    // The same initial state for all.
    for run in doc["runs"].as_array().unwrap() {
        assert_eq!(run["q"][0], json!([1.0]));
    }
    // A fourth-order method beats a second-order one at the same step.
    let last_error = |i: usize| {
        doc["runs"][i]["energy_error"]
            .as_array()
            .unwrap()
            .last()
            .unwrap()
            .as_f64()
            .unwrap()
            .abs()
    };
    assert!(last_error(2) < last_error(4));

    // One method given as `method`.
    let one: Value = post(&server, &json!({"system": "pendulum", "method": {"id": "modin_rks", "inner": "rk4"}, "h": 0.1, "t_end": 1}))
        .await
        .json()
        .await
        .unwrap();
    assert_eq!(one["runs"].as_array().unwrap().len(), 1);
    assert_eq!(one["runs"][0]["method"], "modin_rks(rk4)");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn divergence_keeps_the_samples_before_it() {
    let server = start(config()).await;
    let body = json!({"system": "harmonic_oscillator", "method": "explicit_euler", "h": 3, "t_end": 3000,
        "params": {"omega": 10}, "output": {"every": 1}});
    let response = post(&server, &body).await;
    assert_eq!(response.status(), 200);
    let doc: Value = response.json().await.unwrap();
    let run = &doc["runs"][0];
    let step = run["diverged_at"]["step"].as_u64().expect("diverged");
    assert_eq!(run["stop"]["reason"], "diverged");
    assert_eq!(run["stop"]["step"], step);
    assert!(step < 1000);
    let req = geomint::api::SimulateRequest::from_value(&body)
        .unwrap()
        .to_spec(&NoStoredSystems)
        .unwrap();
    let (_, runs) = core_runs(&req);
    assert_eq!(
        runs[0].1,
        StopReason::Diverged {
            step,
            t: step as f64 * 3.0
        }
    );
    assert_eq!(run["t"].as_array().unwrap().len(), runs[0].0.t.len());
    assert!(run["q"].as_array().unwrap().last().unwrap()[0]
        .as_f64()
        .unwrap()
        .is_finite());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ndjson_stream_is_ordered_and_complete() {
    let server = start(config()).await;
    let body = json!({"system": "nbody", "methods": ["modin_3s", "rk4", "heun"], "h": 0.001, "t_end": 2,
        "output": {"every": 2}});
    let doc: Value = post(&server, &body).await.json().await.unwrap();
    let response = post_stream(&server, &body).await;
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], NDJSON);
    let lines = Lines::new(response).all().await;

    let header = &lines[0];
    assert_eq!(header["type"], "header");
    assert_eq!(header["methods"], json!(["modin_3s", "rk4", "heun"]));
    assert_eq!(
        header["invariants"],
        json!(["L_x", "L_y", "L_z", "L_conformal"])
    );
    assert_eq!(header["system"], doc["system"]);
    assert_eq!(lines.last().unwrap(), &json!({"type": "end"}));
    assert_eq!(lines.iter().filter(|l| l["type"] == "end").count(), 1);

    for (m, run) in doc["runs"].as_array().unwrap().iter().enumerate() {
        let mine: Vec<&Value> = lines.iter().filter(|l| l["method"] == m).collect();
        let (summary, chunks) = mine.split_last().unwrap();
        assert_eq!(
            summary["type"], "summary",
            "the summary comes after the chunks"
        );
        assert!(chunks.len() >= 4, "1001 samples come in several chunks");
        let mut t = Vec::new();
        let mut q = Vec::new();
        let mut lz = Vec::new();
        for chunk in chunks {
            assert_eq!(chunk["type"], "samples");
            assert_eq!(chunk["offset"], t.len(), "chunks are contiguous");
            let n = chunk["t"].as_array().unwrap().len();
            assert!(n <= 256);
            assert_eq!(chunk["q"].as_array().unwrap().len(), n);
            t.extend(chunk["t"].as_array().unwrap().iter().cloned());
            q.extend(chunk["q"].as_array().unwrap().iter().cloned());
            lz.extend(
                chunk["invariants"]["L_z"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .cloned(),
            );
        }
        assert_eq!(t.len(), 1001);
        assert_eq!(summary["samples"], t.len());
        assert_eq!(&Value::from(t), &run["t"]);
        assert_eq!(&Value::from(q), &run["q"]);
        assert_eq!(&Value::from(lz), &run["invariants"]["L_z"]);
        assert_eq!(summary["label"], run["method"]);
        assert_eq!(summary["stop"], run["stop"]);
        assert_eq!(summary["stats"]["steps"], run["stats"]["steps"]);
        assert_eq!(
            summary["stats"]["force_evaluations"],
            run["stats"]["force_evaluations"]
        );
    }
    let methods: BTreeSet<u64> = lines.iter().filter_map(|l| l["method"].as_u64()).collect();
    assert_eq!(methods, BTreeSet::from([0, 1, 2]));
}

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
    let health: Value = client()
        .get(server.url("/healthz"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn openapi_lists_every_route() {
    let server = start(config()).await;
    let c = client();
    let doc: Value = c
        .get(server.url("/api/v1/openapi.json"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
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
    assert_eq!(documented.len(), 21, "{documented:?}");
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
    // Every documented route answers (path parameters filled in).
    for (method, path) in &documented {
        let (recording, system) = match method.as_str() {
            "delete" => (ids[1].clone(), &systems[1]),
            _ => (format!("{}.rrd", ids[0]), &systems[0]),
        };
        let url = server.url(
            &path
                .replace("/systems/{id}", &format!("/systems/{system}"))
                .replace("/methods/{id}", "/methods/rk4")
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
            "/api/v1/studies/convergence" => json!({"system": "pendulum", "t_end": 1,
                "methods": ["rk4"], "h": [0.1, 0.05]}),
            "/api/v1/studies/sweep" => json!({"system": "pendulum", "t_end": 1, "h": 0.1,
                "methods": ["rk4"], "axes": [{"name": "params.gamma", "min": 0, "max": 1, "n": 3}]}),
            "/api/v1/systems" => definition.clone(),
            _ => pendulum_request(),
        };
        let (status, expected) = match method.as_str() {
            "get" => (c.get(url).send().await.unwrap().status(), 200),
            "delete" => (c.delete(url).send().await.unwrap().status(), 204),
            _ => (
                c.post(url).json(&body).send().await.unwrap().status(),
                // (The definition posted to /api/v1/systems is stored already: 200.)
                if path == "/api/v1/recordings" {
                    201
                } else {
                    200
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

//! The HTTP API over real HTTP: each test starts `app(state)` on a loopback port and talks to it
//! with reqwest.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use crate::server;
use geomint::api::system::NoStoredSystems;
use geomint::core::methods::{Method, MethodId};
use geomint::core::run::{Budget, RunEnd};
use geomint::core::simulation::{ColumnSink, Columns, Limits, Simulation, SimulationSpec};

use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, get_json, start, Server};

pub(crate) const NDJSON: &str = "application/x-ndjson";

/// A test configuration: a safety time limit so that no run outlives its test, and recordings
/// in a scratch directory of this test process.
pub(crate) fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(15),
        data_dir: server::scratch_dir("http"),
        systems_dir: server::scratch_dir("http-systems"),
        ..Config::default()
    }
}

pub(crate) async fn post(server: &Server, body: &Value) -> reqwest::Response {
    client()
        .post(server.url("/api/v1/simulate"))
        .json(body)
        .send()
        .await
        .unwrap()
}

pub(crate) async fn post_stream(server: &Server, body: &Value) -> reqwest::Response {
    client()
        .post(server.url("/api/v1/simulate"))
        .header("accept", NDJSON)
        .json(body)
        .send()
        .await
        .unwrap()
}

/// Reads NDJSON lines from a streaming response.
pub(crate) struct Lines {
    response: reqwest::Response,
    buffer: Vec<u8>,
}

impl Lines {
    pub(crate) fn new(response: reqwest::Response) -> Self {
        Self {
            response,
            buffer: Vec::new(),
        }
    }

    pub(crate) async fn next(&mut self) -> Option<Value> {
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

    pub(crate) async fn all(mut self) -> Vec<Value> {
        let mut lines = Vec::new();
        while let Some(line) = self.next().await {
            lines.push(line);
        }
        lines
    }
}

/// The core's runs for a core request.
pub(crate) fn core_runs(req: &SimulationSpec) -> (Simulation, Vec<(Columns, RunEnd)>) {
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
pub(crate) fn expected_fragment(label: &str, traj: &Columns) -> String {
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

pub(crate) fn pendulum_request() -> Value {
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
pub(crate) fn long_request() -> Value {
    json!({"system": "pendulum", "method": "modin_3s", "h": 1e-3, "t_end": 1e6, "output": {"every": 10000}})
}

/// `max_concurrent` slots and no short lane: small runs probe whether the long ones hold them.
pub(crate) fn long_config(max_concurrent: usize) -> Config {
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
pub(crate) async fn wait_idle(server: &Server) -> Duration {
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
    let systems = get_json(&server, "/api/v1/systems").await;
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

    let methods = get_json(&server, "/api/v1/methods").await;
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

    let one = get_json(&server, "/api/v1/systems/nbody").await;
    assert_eq!(
        one["invariants"],
        json!(["L_x", "L_y", "L_z", "L_conformal"])
    );
    let rk4 = get_json(&server, "/api/v1/methods/rk4").await;
    assert_eq!(rk4["order"], 4);
    let missing = c
        .get(server.url("/api/v1/methods/rk5"))
        .send()
        .await
        .unwrap();
    assert_eq!(missing.status(), 404);
    let body: Value = missing.json().await.unwrap();
    assert_eq!(body["error"]["code"], "not_found");

    let health = get_json(&server, "/healthz").await;
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
        assert_eq!(*stop, RunEnd::Finished);
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
        RunEnd::Diverged {
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

//! The command line: `geomint run`, `geomint systems`, `geomint methods`, run as a process.

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

use geomint::api::system::NoStoredSystems;
use geomint::core::run::Budget;
use geomint::core::simulation::{ColumnSink, Limits, Simulation};
use serde_json::{json, Value};

use crate::server;

fn geomint(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_geomint"))
        .args(args)
        .env_remove("GEOMINT_MAX_STEPS")
        .env_remove("GEOMINT_MAX_SAMPLES")
        .output()
        .unwrap()
}

/// A scratch directory of this test process.
fn scratch(name: &str) -> PathBuf {
    let dir = server::scratch_dir(&format!("cli-{name}"));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn spec() -> Value {
    json!({"system": "harmonic_oscillator", "params": {"omega": 1.5}, "methods": ["modin_3s", {"id": "triple_jump", "base": "csv1"}],
        "h": 0.01, "t_end": 30, "q0": [1.0], "p0": [0.25], "output": {"every": 5}})
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn catalogs_print_as_json() {
    let out = geomint(&["systems"]);
    assert!(out.status.success());
    let systems: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        systems,
        serde_json::to_value(geomint::core::systems::catalog()).unwrap()
    );
    let out = geomint(&["methods"]);
    assert!(out.status.success());
    let methods: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        methods.as_array().unwrap().len(),
        geomint::core::methods::MethodId::ALL.len()
    );
    assert_eq!(methods[0]["id"], "modin_3s");
}

#[test]
fn run_writes_json_and_ndjson_equal_to_the_core() {
    let dir = scratch("run");
    let spec_path = dir.join("spec.json");
    std::fs::write(&spec_path, serde_json::to_vec(&spec()).unwrap()).unwrap();
    let json_path = dir.join("out.json");
    let ndjson_path = dir.join("out.ndjson");

    let out = geomint(&[
        "run",
        spec_path.to_str().unwrap(),
        "-o",
        json_path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&json_path).unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    let labels: Vec<&str> = doc["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["method"].as_str().unwrap())
        .collect();
    assert_eq!(labels, ["modin_3s", "triple_jump(csv1)"]);

    // Bit for bit the core's numbers.
    let req = geomint::api::SimulateRequest::from_value(&spec())
        .unwrap()
        .to_spec(&NoStoredSystems)
        .unwrap();
    let sim = Simulation::prepare(&req, &Limits::default()).unwrap();
    for i in 0..2 {
        let mut sink = ColumnSink::new(sim.invariant_names());
        sim.run_method(i, None, Budget::default(), &mut sink)
            .unwrap();
        let traj = sink.take();
        let q = format!("\"q\":{}", serde_json::to_string(&traj.q).unwrap());
        let e = format!(
            "\"energy_error\":{}",
            serde_json::to_string(traj.energy_error.as_ref().unwrap()).unwrap()
        );
        assert!(text.contains(&q) && text.contains(&e), "run {i}");
    }

    let out = geomint(&[
        "run",
        spec_path.to_str().unwrap(),
        "-o",
        ndjson_path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let lines: Vec<Value> = std::fs::read_to_string(&ndjson_path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines[0]["type"], "header");
    assert_eq!(lines.last().unwrap()["type"], "end");
    for (m, run) in doc["runs"].as_array().unwrap().iter().enumerate() {
        let samples: usize = lines
            .iter()
            .filter(|l| l["type"] == "samples" && l["method"] == m)
            .map(|l| l["t"].as_array().unwrap().len())
            .sum();
        assert_eq!(samples, run["t"].as_array().unwrap().len());
        assert_eq!(samples, 601);
    }

    // Standard input to standard output.
    let mut child = Command::new(env!("CARGO_BIN_EXE_geomint"))
        .args(["run", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(&serde_json::to_vec(&spec()).unwrap())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    let from_stdout: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(from_stdout["runs"][1]["q"], doc["runs"][1]["q"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_specs_exit_2_naming_the_problem() {
    let dir = scratch("bad");
    let missing = dir.join("missing.json");
    let out = geomint(&["run", missing.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("missing.json"), "{}", stderr(&out));

    let cases = [
        ("{\"system\": ", "malformed"),
        (
            r#"{"system": "pendulum", "method": "heun", "h": -1, "t_end": 1}"#,
            "h: must be finite",
        ),
        (
            r#"{"system": "pendulum", "method": "heun", "h": 0.1, "t_end": 1, "colour": 1}"#,
            "colour",
        ),
        (
            r#"{"system": "pendulum", "method": "heun", "h": 0.1, "t_end": 1, "q0": [1e999]}"#,
            "q0[0]",
        ),
        (
            r#"{"system": "pendulum", "method": "rk5", "h": 0.1, "t_end": 1}"#,
            "unknown method",
        ),
        (
            r#"{"system": "elastic_pendulum_3d", "method": "csv1", "h": 0.1, "t_end": 1}"#,
            "conformal damping",
        ),
    ];
    for (i, (text, needle)) in cases.iter().enumerate() {
        let path = dir.join(format!("bad{i}.json"));
        std::fs::write(&path, text).unwrap();
        let out = geomint(&["run", path.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{text}");
        assert!(stderr(&out).contains(needle), "{text}: {}", stderr(&out));
        assert!(!stderr(&out).contains("panicked"));
        assert!(out.stdout.is_empty());
    }
    // A bad command line is exit 2 too (clap).
    assert_eq!(geomint(&["run"]).status.code(), Some(2));
    assert_eq!(
        geomint(&["serve", "--addr", "nowhere"]).status.code(),
        Some(2)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn run_writes_a_rerun_recording_by_extension() {
    let dir = scratch("rrd");
    let spec_path = dir.join("spec.json");
    std::fs::write(&spec_path, serde_json::to_vec(&spec()).unwrap()).unwrap();
    let rrd_path = dir.join("out.rrd");
    let out = geomint(&[
        "run",
        spec_path.to_str().unwrap(),
        "-o",
        rrd_path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let bytes = std::fs::read(&rrd_path).unwrap();
    // An RRD stream: its header, and the stream footer that ends a complete file.
    assert_eq!(&bytes[..4], b"RRF2");
    assert_eq!(&bytes[bytes.len() - 12..bytes.len() - 4], b"RRF2FOOT");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn study_convergence_writes_the_document_of_the_library() {
    use geomint::api::studies::ConvergenceRequest;
    use geomint::core::studies::convergence;
    let dir = scratch("convergence");
    let study = json!({"system": "harmonic_oscillator", "params": {"omega": 2, "gamma": 0.1},
        "methods": ["rk4", "csv1"], "h": [0.1, 0.05, 0.025], "t_end": 5});
    let spec_path = dir.join("study.json");
    std::fs::write(&spec_path, serde_json::to_vec(&study).unwrap()).unwrap();
    let out_path = dir.join("out.json");
    let out = geomint(&[
        "study",
        "convergence",
        spec_path.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    // Settings run in parallel: each is reported once, in the order they finish.
    let log = stderr(&out);
    assert!(log.contains("[6/6] "), "{log}");
    for method in ["rk4", "csv1"] {
        for h in ["0.1", "0.05", "0.025"] {
            let line = format!("] {method} (cartesian) h = {h}: state error");
            assert_eq!(log.matches(&line).count(), 1, "{line}: {log}");
        }
    }
    // Read with correctly rounded floats, so that numbers compare bit for bit.
    let written = geomint::api::json::parse_json(&std::fs::read(&out_path).unwrap()).unwrap();
    let job = ConvergenceRequest::from_value(&study)
        .unwrap()
        .to_spec(&NoStoredSystems)
        .unwrap()
        .prepare(&Limits::default())
        .unwrap();
    let doc = convergence::run(
        &job,
        &geomint::core::studies::engine::Local,
        Budget::default(),
        &|_| true,
    )
    .unwrap();
    assert_eq!(written, serde_json::to_value(&doc).unwrap());
    let rk4 = doc.series[0].state.order.unwrap();
    assert!((3.8..4.2).contains(&rk4), "rk4 order {rk4}");

    // No recording for convergence studies; a bad step size names its field.
    let rrd = dir.join("out.rrd");
    let out = geomint(&[
        "study",
        "convergence",
        spec_path.to_str().unwrap(),
        "-o",
        rrd.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("no recording"), "{}", stderr(&out));
    assert!(!rrd.exists());
    let mut bad = study.clone();
    bad["h"] = json!([0.1, 0.3]);
    std::fs::write(&spec_path, serde_json::to_vec(&bad).unwrap()).unwrap();
    let out = geomint(&["study", "convergence", spec_path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("h[1]: must divide t_end"),
        "{}",
        stderr(&out)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn study_energy_map_writes_json_and_refuses_a_bad_spec() {
    let dir = scratch("energy-map");
    let spec = dir.join("map.json");
    std::fs::write(&spec, r#"{"nx": 5, "ny": 5, "t_max": 20}"#).unwrap();
    let out_path = dir.join("map-out.json");
    let out = geomint(&[
        "study",
        "energy-map",
        spec.to_str().unwrap(),
        "-o",
        out_path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let doc: Value = serde_json::from_slice(&std::fs::read(&out_path).unwrap()).unwrap();
    assert_eq!(doc["summary"]["cells"], 25);
    assert_eq!(doc["steps_per_run"], 100);
    assert!(stderr(&out).contains("25/25 cells"), "{}", stderr(&out));
    std::fs::write(&spec, r#"{"method": "modin_3s"}"#).unwrap();
    let bad = geomint(&["study", "energy-map", spec.to_str().unwrap()]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(stderr(&bad).contains("method"), "{}", stderr(&bad));
    assert!(stderr(&bad).contains("polar chart"), "{}", stderr(&bad));
}

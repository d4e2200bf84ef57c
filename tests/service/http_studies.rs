//! Work–precision studies over real HTTP: the measurements against the simulate route and the
//! exact solution, the reference run, the NDJSON progress stream, the recording, and bad input.

use std::collections::BTreeSet;
use std::time::Duration;

use crate::decoded;
use crate::server;
use decoded::Decoded;

use geomint::core::system::{MechanicalSystem, State};
use geomint::core::systems::HarmonicOscillator;
use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, post_json as post, post_ndjson, start};

const STUDY: &str = "/api/v1/studies/work-precision";

fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(30),
        ..Config::default()
    }
}

fn points_of(doc: &Value) -> &Vec<Value> {
    doc["points"].as_array().expect("points")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn errors_are_those_of_the_simulate_route_against_the_exact_solution() {
    let server = start(config()).await;
    let (omega, gamma, t_end, samples) = (2.0, 0.1, 20.0, 40);
    let study = json!({
        "system": "harmonic_oscillator", "params": {"omega": omega, "gamma": gamma},
        "q0": [1.0], "p0": [0.0], "t_end": t_end, "samples": samples,
        "runs": [{"method": "csv1", "h": [0.1, 0.05]},
                 {"method": {"id": "kahan_li_8", "base": "csv1"}, "h": [0.5, 0.25]}]});
    let (status, doc) = post(&server, STUDY, &study).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["reference"], "exact solution");
    let points = points_of(&doc);
    assert_eq!(points.len(), 4);
    let sys = HarmonicOscillator { omega, gamma };
    let start_state = State::from_slices(nalgebra::U1, &[1.0], &[0.0]);
    let exact = sys.exact(t_end, &start_state).unwrap();
    for point in points {
        let h = point["h"].as_f64().unwrap();
        let method = point["method"].as_str().unwrap();
        let steps = (t_end / h).round() as u64;
        // The same run through the simulate route, sampled at the study's sample times.
        let spec = if method == "csv1" {
            json!("csv1")
        } else {
            json!({"id": "kahan_li_8", "base": "csv1"})
        };
        let (status, run) = post(
            &server,
            "/api/v1/simulate",
            &json!({"system": "harmonic_oscillator", "params": {"omega": omega, "gamma": gamma},
                "q0": [1.0], "p0": [0.0], "method": spec, "h": h, "t_end": t_end,
                "output": {"every": steps / samples}}),
        )
        .await;
        assert_eq!(status, 200, "{run}");
        let run = &run["runs"][0];
        let errors = run["energy_error"].as_array().unwrap();
        assert_eq!(errors.len() as u64, samples + 1);
        let max = errors
            .iter()
            .map(|e| e.as_f64().unwrap().abs())
            .fold(0.0, f64::max);
        assert_eq!(
            point["max_energy_error"].as_f64().map(f64::to_bits),
            Some(max.to_bits()),
            "{method} h={h}"
        );
        let q = run["q"][samples as usize][0].as_f64().unwrap();
        let p = run["p"][samples as usize][0].as_f64().unwrap();
        let state_error = (q - exact.q[0]).hypot(p - exact.p[0]);
        let got = point["final_state_error"].as_f64().unwrap();
        assert!(
            (got - state_error).abs() <= 1e-15 * (1.0 + state_error),
            "{method} h={h}: {got:e} vs {state_error:e}"
        );
        assert_eq!(point["steps"].as_u64(), Some(steps));
        assert_eq!(point["stop"], "finished");
        assert!(point["wall_ms"].as_f64().unwrap() > 0.0);
    }
    // csv1 is second order: halving h divides its energy error by about 4; kahan_li_8 of csv1 is
    // eighth order: by about 256.
    let err = |k: usize| points[k]["max_energy_error"].as_f64().unwrap();
    let csv1 = err(0) / err(1);
    let kl8 = err(2) / err(3);
    println!("energy error ratios per halving: csv1 {csv1:.2}, kahan_li_8(csv1) {kl8:.1}");
    assert!((3.5..4.5).contains(&csv1), "csv1 ratio {csv1}");
    assert!((150.0..400.0).contains(&kl8), "kahan_li_8 ratio {kl8}");
    // One fit per run, through its two settings.
    let fits = doc["fits"].as_array().unwrap();
    assert_eq!(fits.len(), 2);
    assert_eq!(fits[1]["method"], "kahan_li_8(csv1)");
    assert_eq!(fits[1]["points"], 2);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_an_exact_solution_a_reference_run_measures_the_errors() {
    let server = start(config()).await;
    let base = json!({
        "system": "elastic_pendulum_3d", "params": {"epsilon": 0.001}, "t_end": 100,
        "runs": [{"method": "modin_3s", "h": [0.05]},
                 {"method": "rk4", "h": [0.05]},
                 {"method": "reference", "tolerance": [1e-9, 1e-11]}]});
    let (status, doc) = post(&server, STUDY, &base).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(
        doc["reference"],
        "adaptive DOP853 reference at tolerance 1e-13"
    );
    let points = points_of(&doc);
    let drift = |k: usize| points[k]["invariant_drift"]["J3"].as_f64().unwrap();
    // 3S keeps J₃ exactly, RK4 does not.
    assert!(drift(0) < 1e-12, "modin_3s J3 drift {:e}", drift(0));
    assert!(drift(1) > 1e-9, "rk4 J3 drift {:e}", drift(1));
    assert_eq!(points[2]["method"], "reference");
    assert_eq!(points[2]["tolerance"].as_f64(), Some(1e-9));
    assert!(points[2]["h"].is_null());
    // A tighter tolerance is closer to the reference.
    let err = |k: usize| points[k]["max_energy_error"].as_f64().unwrap();
    assert!(err(3) < err(2) / 10.0, "{} vs {}", err(3), err(2));

    // Another reference: a composition at a small step gives the same errors to about 1e-12.
    let mut custom = base.clone();
    custom["reference"] = json!({"method": {"id": "kahan_li_8", "base": "modin_3s"}, "h": 0.025});
    let (status, other) = post(&server, STUDY, &custom).await;
    assert_eq!(status, 200, "{other}");
    assert_eq!(other["reference"], "kahan_li_8(modin_3s) at h = 0.025");
    for (a, b) in points.iter().zip(points_of(&other)) {
        let (ea, eb) = (
            a["max_energy_error"].as_f64().unwrap(),
            b["max_energy_error"].as_f64().unwrap(),
        );
        assert!((ea - eb).abs() < 1e-11, "{}: {ea:e} vs {eb:e}", a["method"]);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn progress_streams_as_ndjson_and_the_study_records_as_rrd() {
    let server = start(config()).await;
    let body = json!({
        "system": "pendulum", "t_end": 50, "samples": 10,
        "runs": [{"method": "modin_3s", "h": [0.1, 0.05]},
                 {"method": {"id": "triple_jump", "base": "csv1"}, "h": [0.1]}]});
    let (status, _, lines) = post_ndjson(&server, STUDY, "application/x-ndjson", &body).await;
    assert_eq!(status, 200);
    let kinds: Vec<&str> = lines.iter().map(|l| l["type"].as_str().unwrap()).collect();
    assert_eq!(
        kinds,
        ["reference", "point", "point", "point", "result", "end"]
    );
    assert_eq!(lines[0]["total"], 3);
    for (k, line) in lines[1..4].iter().enumerate() {
        assert_eq!(line["done"].as_u64(), Some(k as u64 + 1));
        assert_eq!(line["total"], 3);
    }
    assert_eq!(lines[4]["points"].as_array().unwrap().len(), 3);

    let response = client()
        .post(server.url(&format!("{STUDY}?format=rrd")))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(
        response.headers()["content-type"],
        "application/octet-stream"
    );
    let d = Decoded::of(&response.bytes().await.unwrap());
    let entities: BTreeSet<String> = d.chunks.keys().cloned().collect();
    for e in [
        "/spec",
        "/table",
        "/modin_3s/settings",
        "/modin_3s/curve",
        "/modin_3s/fit",
        "/triple_jump_csv1/settings",
    ] {
        assert!(entities.contains(e), "{e} missing from {entities:?}");
    }
    let points: Vec<rerun::components::Position2D> = d.static_batch(
        "/modin_3s/settings",
        rerun::Points2D::descriptor_positions().component,
    );
    assert_eq!(points.len(), 2);
    assert_eq!(d.activations, 1);
}

/// A setting timed `repeats` times reports every timing, fastest first, with their median as its
/// wall time, and the same errors bit for bit as one timing; `repeats` out of 1..=20 is refused.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn repeated_timings_give_the_median_and_the_spread_with_the_same_errors() {
    let server = start(config()).await;
    // rk4 at h = 0.001 over t = 2000 (2·10⁶ steps) takes well over 20 ms, so only `repeats`
    // times it again.
    let study = |repeats: Option<u64>| {
        let mut body = json!({"system": "pendulum", "t_end": 2000, "samples": 20,
            "runs": [{"method": "rk4", "h": [0.001]}, {"method": "csv1", "h": [0.5]}]});
        if let Some(n) = repeats {
            body["repeats"] = json!(n);
        }
        body
    };
    let (status, once) = post(&server, STUDY, &study(None)).await;
    assert_eq!(status, 200, "{once}");
    let (status, thrice) = post(&server, STUDY, &study(Some(3))).await;
    assert_eq!(status, 200, "{thrice}");
    for (one, three) in points_of(&once).iter().zip(points_of(&thrice)) {
        assert_eq!(one["max_energy_error"], three["max_energy_error"]);
        assert_eq!(one["final_state_error"], three["final_state_error"]);
        let timings: Vec<f64> = three["timings_ms"]
            .as_array()
            .expect("timings_ms with repeats")
            .iter()
            .map(|t| t.as_f64().unwrap())
            .collect();
        assert!(timings.len() >= 3, "{three}");
        assert!(
            timings.windows(2).all(|w| w[0] <= w[1]),
            "fastest first: {timings:?}"
        );
        assert_eq!(
            three["wall_ms"].as_f64().unwrap(),
            timings[timings.len() / 2]
        );
    }
    // Without repeats, the long run is timed once (no list) and the short one five times.
    let [long, short] = [&points_of(&once)[0], &points_of(&once)[1]];
    assert!(long["wall_ms"].as_f64().unwrap() >= 20.0, "{long}");
    assert!(long.get("timings_ms").is_none(), "{long}");
    assert_eq!(
        short["timings_ms"].as_array().map(Vec::len),
        Some(5),
        "{short}"
    );
    for bad in [json!(0), json!(21), json!(2.5)] {
        let mut body = study(None);
        body["repeats"] = bad.clone();
        let (status, answer) = post(&server, STUDY, &body).await;
        assert_eq!(status, 422, "{bad}: {answer}");
        assert_eq!(answer["error"]["field"], "repeats", "{bad}: {answer}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_studies_get_errors_naming_the_field() {
    let server = start(config()).await;
    let ok = json!({"system": "pendulum", "t_end": 10,
        "runs": [{"method": "rk4", "h": [0.1]}, {"method": "reference", "tolerance": [1e-8]}]});
    let with = |path: &str, value: Value| {
        let mut body = ok.clone();
        let mut target = &mut body;
        let parts: Vec<&str> = path.split('.').collect();
        for part in &parts[..parts.len() - 1] {
            target = match part.parse::<usize>() {
                Ok(i) => &mut target[i],
                Err(_) => &mut target[*part],
            };
        }
        target[parts[parts.len() - 1]] = value;
        body
    };
    let many: Vec<f64> = (1..=65).map(|k| 10.0 / (k as f64 * 50.0)).collect();
    let cases = [
        (
            with("runs.0.h", json!([0.3])),
            "runs[0].h[0]",
            "invalid_value",
        ),
        (
            with("runs.0.h", json!([0.1, -0.1])),
            "runs[0].h[1]",
            "invalid_value",
        ),
        (
            with("runs.0.tolerance", json!([1e-8])),
            "runs[0].tolerance",
            "invalid_value",
        ),
        (with("runs.1.h", json!([0.1])), "runs[1].h", "invalid_value"),
        (
            with("runs.1.tolerance", json!([1.0])),
            "runs[1].tolerance[0]",
            "invalid_value",
        ),
        (
            with("runs.0.method", json!("rk9")),
            "runs[0].method",
            "unknown_method",
        ),
        (
            with("runs.0.speed", json!(1)),
            "runs[0].speed",
            "unknown_field",
        ),
        (
            with("runs.0.method", json!({"id": "kahan_li_8", "base": "heun"})),
            "runs[0].method.base",
            "invalid_value",
        ),
        (
            json!({"system": "elastic_pendulum_3d", "t_end": 10, "runs": [{"method": "csv1", "h": [0.1]}]}),
            "runs[0].method",
            "unmet_requirement",
        ),
        (with("samples", json!(0)), "samples", "invalid_value"),
        (with("t_end", json!(-1)), "t_end", "invalid_value"),
        (with("runs", json!([])), "runs", "invalid_value"),
        (with("runs.0.h", json!(many)), "runs", "invalid_value"),
        (
            with("runs.0.h", json!([1e-7])),
            "runs[0].h[0]",
            "too_many_steps",
        ),
        // 41 settings of 5·10⁶ steps: within the per-setting limit, past the study's.
        (
            with("runs.0.h", json!(vec![2e-6; 41])),
            "runs",
            "too_many_steps",
        ),
        (with("system", json!("rocket")), "system", "unknown_system"),
        (with("colour", json!("red")), "colour", "unknown_field"),
    ];
    for (body, field, code) in cases {
        let (status, answer) = post(&server, STUDY, &body).await;
        assert_eq!(status, 422, "{field}: {answer}");
        assert_eq!(answer["error"]["field"], field, "{answer}");
        assert_eq!(answer["error"]["code"], code, "{answer}");
    }
    // The reference of a system without an exact solution: one setting, named.
    let mut both = ok.clone();
    both["system"] = json!("elastic_pendulum_3d");
    both["runs"] = json!([{"method": "rk4", "h": [0.1]}]);
    both["reference"] = json!({"method": "rk4", "h": 0.3});
    let (status, answer) = post(&server, STUDY, &both).await;
    assert_eq!(status, 422, "{answer}");
    assert_eq!(answer["error"]["field"], "reference.h");
    let (status, answer) = post(&server, &format!("{STUDY}?format=png"), &ok).await;
    assert_eq!(status, 422);
    assert_eq!(answer["error"]["field"], "format");
}

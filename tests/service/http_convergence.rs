//! Convergence studies over real HTTP: paper 001's Fig. 9 (symplectic Euler on the oscillator,
//! first order in energy in Cartesian coordinates and second order in the compensating chart),
//! fourth order of RK4 on the damped oscillator against the exact solution, second order of the
//! implicit midpoint rule on the planar elastic pendulum in polar coordinates against the
//! reference run, the NDJSON progress stream, and bad input.

use std::time::Duration;

use crate::server;

use geomint::core::system::{MechanicalSystem, State};
use geomint::core::systems::HarmonicOscillator;
use geomint::http::Config;
use serde_json::{json, Value};
use server::{post_json as post, post_ndjson, start};

const STUDY: &str = "/api/v1/studies/convergence";

fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(60),
        ..Config::default()
    }
}

/// Paper 001 Fig. 9: the unit oscillator from q = 1, p = 0 to t = 10, symplectic Euler in both
/// charts, h from 0.04 down by halves.
fn fig_9() -> Value {
    json!({
        "system": "harmonic_oscillator", "params": {"omega": 1, "gamma": 0},
        "charts": ["cartesian", "compensating"], "q0": [1], "p0": [0], "t_end": 10,
        "methods": ["symplectic_euler"], "h": [0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125]})
}

/// The fitted order of `error` (`state`, `energy` or `max_energy`) of series `s`.
fn order(doc: &Value, s: usize, error: &str) -> f64 {
    doc["series"][s][error]["order"]
        .as_f64()
        .unwrap_or_else(|| panic!("no {error} order for series {s}: {}", doc["series"][s]))
}

fn print_orders(title: &str, doc: &Value) {
    for s in doc["series"].as_array().unwrap() {
        println!(
            "{title}: {}: state {:.3}, energy at t_end {}, max energy {}",
            s["label"],
            s["state"]["order"].as_f64().unwrap_or(f64::NAN),
            s["energy"]["order"],
            s["max_energy"]["order"]
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fig_9_symplectic_euler_gains_an_order_in_energy_in_the_compensating_chart() {
    let server = start(config()).await;
    let (status, doc) = post(&server, STUDY, &fig_9()).await;
    assert_eq!(status, 200, "{doc}");
    print_orders("001 Fig. 9", &doc);
    assert_eq!(doc["reference"], "exact solution");
    assert_eq!(doc["charts"], json!(["cartesian", "compensating"]));
    // 250 steps at the largest h: every setting is sampled at t = 0.04 k.
    assert_eq!(doc["samples"], 250);
    assert_eq!(doc["system"]["q0"], json!([1.0]));
    let labels: Vec<&str> = doc["series"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["label"].as_str().unwrap())
        .collect();
    assert_eq!(
        labels,
        [
            "symplectic_euler [cartesian]",
            "symplectic_euler [compensating]"
        ]
    );
    // The largest energy error over the samples shows the orders cleanly; the error at t_end
    // alone is noisier (it passes near zero at some step sizes).
    let (cartesian, compensating) = (order(&doc, 0, "max_energy"), order(&doc, 1, "max_energy"));
    assert!((0.95..1.05).contains(&cartesian), "cartesian: {cartesian}");
    assert!(
        (1.9..2.2).contains(&compensating),
        "compensating: {compensating}"
    );
    // In Cartesian coordinates the state error is first order too.
    let state = order(&doc, 0, "state");
    assert!((0.95..1.05).contains(&state), "cartesian state: {state}");
    for s in 0..2 {
        assert_eq!(doc["series"][s]["max_energy"]["points"], 6);
    }

    // Each point is the simulate route's run, sampled at the study's sample times: the same
    // energy errors bit for bit.
    let points = doc["points"].as_array().unwrap();
    assert_eq!(points.len(), 12);
    for point in [&points[1], &points[8]] {
        let h = point["h"].as_f64().unwrap();
        let steps = point["steps"].as_u64().unwrap();
        let (status, run) = post(
            &server,
            "/api/v1/simulate",
            &json!({"system": "harmonic_oscillator", "params": {"omega": 1, "gamma": 0},
                "chart": point["chart"], "initial_coordinates": "cartesian", "q0": [1], "p0": [0],
                "method": "symplectic_euler", "h": h, "t_end": 10,
                "output": {"every": steps / 250}}),
        )
        .await;
        assert_eq!(status, 200, "{run}");
        let errors: Vec<f64> = run["runs"][0]["energy_error"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e.as_f64().unwrap().abs())
            .collect();
        assert_eq!(errors.len(), 251);
        let max = errors.iter().copied().fold(0.0, f64::max);
        assert_eq!(point["max_energy_error"].as_f64(), Some(max), "{point}");
        assert_eq!(point["energy_error"].as_f64(), errors.last().copied());
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rk4_is_fourth_order_in_the_state_on_the_damped_oscillator() {
    let server = start(config()).await;
    let (omega, gamma, t_end) = (2.0, 0.1, 10.0);
    let study = json!({
        "system": "harmonic_oscillator", "params": {"omega": omega, "gamma": gamma},
        "q0": [1.0], "p0": [0.0], "t_end": t_end, "methods": ["rk4", "csv1"],
        "h": [0.1, 0.05, 0.025, 0.0125]});
    let (status, doc) = post(&server, STUDY, &study).await;
    assert_eq!(status, 200, "{doc}");
    print_orders("damped oscillator", &doc);
    assert_eq!(doc["reference"], "exact solution");
    assert_eq!(doc["charts"], json!(["cartesian"]));
    assert_eq!(doc["series"][0]["label"], "rk4");
    let rk4 = order(&doc, 0, "state");
    assert!((3.9..4.1).contains(&rk4), "rk4 state order {rk4}");
    let csv1 = order(&doc, 1, "state");
    assert!((1.9..2.1).contains(&csv1), "csv1 state order {csv1}");

    // The state error is the distance from the exact solution at t_end, computed here.
    let sys = HarmonicOscillator { omega, gamma };
    let exact = sys
        .exact(t_end, &State::from_slices(nalgebra::U1, &[1.0], &[0.0]))
        .unwrap();
    let point = &doc["points"][2];
    let h = point["h"].as_f64().unwrap();
    let (status, run) = post(
        &server,
        "/api/v1/simulate",
        &json!({"system": "harmonic_oscillator", "params": {"omega": omega, "gamma": gamma},
            "q0": [1.0], "p0": [0.0], "method": "rk4", "h": h, "t_end": t_end}),
    )
    .await;
    assert_eq!(status, 200, "{run}");
    let q = run["runs"][0]["q"].as_array().unwrap().last().unwrap()[0]
        .as_f64()
        .unwrap();
    let p = run["runs"][0]["p"].as_array().unwrap().last().unwrap()[0]
        .as_f64()
        .unwrap();
    let expected = (q - exact.q[0]).hypot(p - exact.p[0]);
    let got = point["state_error"].as_f64().unwrap();
    assert!(
        (got - expected).abs() <= 1e-9 * expected,
        "{got:e} vs {expected:e}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_an_exact_solution_the_reference_run_gives_the_order() {
    let server = start(config()).await;
    let study = json!({
        "system": "elastic_pendulum_2d", "charts": ["cartesian", "polar"], "t_end": 4,
        "methods": ["implicit_midpoint"], "h": [0.1, 0.05, 0.025, 0.0125]});
    let (status, doc) = post(&server, STUDY, &study).await;
    assert_eq!(status, 200, "{doc}");
    print_orders("elastic pendulum 2d", &doc);
    assert_eq!(
        doc["reference"],
        "adaptive DOP853 reference at tolerance 1e-13"
    );
    // The catalogue's Cartesian default state, the same physical state in both charts.
    assert_eq!(doc["system"]["q0"], json!([0.6, 1.2]));
    for s in 0..2 {
        for error in ["state", "energy"] {
            let p = order(&doc, s, error);
            assert!((1.95..2.05).contains(&p), "series {s} {error}: {p}");
        }
    }
    // The implicit midpoint rule is not the same map in both charts: the errors differ.
    let err = |k: usize| doc["points"][k]["state_error"].as_f64().unwrap();
    assert!(
        (err(0) - err(4)).abs() > 1e-3 * err(0),
        "{} vs {}",
        err(0),
        err(4)
    );

    // A composition at a small step as the reference gives the same errors.
    let mut custom = study.clone();
    custom["reference"] = json!({"method": {"id": "kahan_li_8", "base": "modin_3s"}, "h": 0.025});
    let (status, other) = post(&server, STUDY, &custom).await;
    assert_eq!(status, 200, "{other}");
    assert_eq!(other["reference"], "kahan_li_8(modin_3s) at h = 0.025");
    for (a, b) in doc["points"]
        .as_array()
        .unwrap()
        .iter()
        .zip(other["points"].as_array().unwrap())
    {
        let (ea, eb) = (
            a["state_error"].as_f64().unwrap(),
            b["state_error"].as_f64().unwrap(),
        );
        assert!((ea - eb).abs() < 1e-10, "{a}: {ea:e} vs {eb:e}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn progress_streams_as_ndjson_and_ends_with_the_result() {
    let server = start(config()).await;
    let body = json!({
        "system": "exponential_decay", "charts": ["original", "transformed"], "q0": [1], "p0": [0],
        "t_end": 3, "methods": ["explicit_euler"], "h": [0.3, 0.15, 0.075]});
    for (url, accept) in [
        (STUDY.to_string(), "application/x-ndjson"),
        (format!("{STUDY}?format=ndjson"), "*/*"),
    ] {
        let (status, content_type, lines) = post_ndjson(&server, &url, accept, &body).await;
        assert_eq!(status, 200);
        assert_eq!(content_type, "application/x-ndjson");
        let kinds: Vec<&str> = lines.iter().map(|l| l["type"].as_str().unwrap()).collect();
        assert_eq!(
            kinds,
            [
                "reference",
                "point",
                "point",
                "point",
                "point",
                "point",
                "point",
                "result",
                "end"
            ]
        );
        assert_eq!(lines[0]["reference"], "exact solution");
        assert_eq!(lines[0]["total"], 6);
        // Settings run on both cores and stream as they finish: `done` counts up one by one,
        // and the streamed points are the document's, in whatever order they came.
        let mut streamed = Vec::new();
        for (k, line) in lines[1..7].iter().enumerate() {
            assert_eq!(line["done"].as_u64(), Some(k as u64 + 1));
            assert_eq!(line["total"], 6);
            streamed.push(line["point"].to_string());
        }
        let mut documented: Vec<String> = lines[7]["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(Value::to_string)
            .collect();
        streamed.sort();
        documented.sort();
        assert_eq!(streamed, documented);
        // 001 Sec. 2.3: explicit Euler is first order in y, exact in the transformed variable.
        let result = &lines[7];
        let p = order(result, 0, "state");
        assert!((0.95..1.1).contains(&p), "original: {p}");
        assert!(result["series"][1]["state"]["order"].is_null());
        assert_eq!(result["series"][1]["state"]["points"], 0);
        for point in &result["points"].as_array().unwrap()[3..] {
            assert!(point["state_error"].as_f64().unwrap() < 1e-15, "{point}");
        }
    }
    // The plain answer is the stream's result.
    let (status, doc) = post(&server, STUDY, &body).await;
    assert_eq!(status, 200);
    assert_eq!(doc["points"].as_array().unwrap().len(), 6);
    // No recording for this route.
    let (status, answer) = post(&server, &format!("{STUDY}?format=rrd"), &body).await;
    assert_eq!(status, 422, "{answer}");
    assert_eq!(answer["error"]["field"], "format");
    assert!(
        answer["error"]["message"]
            .as_str()
            .unwrap()
            .ends_with("one of json, ndjson"),
        "{answer}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_studies_get_errors_naming_the_field() {
    let server = start(config()).await;
    let ok = json!({"system": "elastic_pendulum_2d", "t_end": 1,
        "methods": ["rk4", "symplectic_euler"], "h": [0.1, 0.05]});
    let with = |changes: Value| {
        let mut body = ok.clone();
        for (k, v) in changes.as_object().unwrap() {
            body[k] = v.clone();
        }
        body
    };
    let many: Vec<f64> = (1..=33).map(|k| 1.0 / k as f64).collect();
    let cases = [
        (
            json!({"charts": ["cartesian", "spherical"]}),
            "charts[1]",
            "invalid_value",
        ),
        (json!({"chart": "spherical"}), "chart", "invalid_value"),
        (
            json!({"chart": "polar", "charts": ["polar"]}),
            "charts",
            "invalid_value",
        ),
        (json!({"charts": []}), "charts", "invalid_value"),
        (
            json!({"charts": ["polar", "polar"]}),
            "charts[1]",
            "invalid_value",
        ),
        (
            json!({"charts": ["cartesian", "polar"], "q0": [1, 0.1], "initial_coordinates": "chart"}),
            "initial_coordinates",
            "invalid_value",
        ),
        (json!({"h": [0.1, 0.05, 0.3]}), "h[2]", "invalid_value"),
        (json!({"h": [0.1, -0.05]}), "h[1]", "invalid_value"),
        (json!({"h": []}), "h", "invalid_value"),
        (json!({"samples": 4}), "h[0]", "invalid_value"),
        (json!({"samples": 0}), "samples", "invalid_value"),
        (json!({"methods": []}), "methods", "invalid_value"),
        (
            json!({"methods": ["rk4", "rk9"]}),
            "methods[1]",
            "unknown_method",
        ),
        (
            json!({"chart": "polar", "methods": ["rk4", "modin_3s"]}),
            "methods[1]",
            "unmet_requirement",
        ),
        (json!({"h": many}), "h", "invalid_value"),
        (json!({"h": [5e-8]}), "h[0]", "too_many_steps"),
        // 41 settings of 5·10⁶ steps: within the per-setting limit, past the study's.
        (
            json!({"t_end": 10, "methods": ["rk4"], "h": vec![2e-6; 41]}),
            "h",
            "too_many_steps",
        ),
        (
            json!({"reference": {"method": "rk4", "h": 0.3}}),
            "reference.h",
            "invalid_value",
        ),
        // Where the exact solution serves, a reference given is still checked.
        (
            json!({"system": "harmonic_oscillator", "reference": {"method": "reference", "tolerance": 1e-20}}),
            "reference.tolerance",
            "invalid_value",
        ),
        (json!({"t_end": -1}), "t_end", "invalid_value"),
        (json!({"system": "rocket"}), "system", "unknown_system"),
        (json!({"colour": "red"}), "colour", "unknown_field"),
    ];
    for (changes, field, code) in cases {
        let (status, answer) = post(&server, STUDY, &with(changes.clone())).await;
        assert_eq!(status, 422, "{changes}: {answer}");
        assert_eq!(answer["error"]["field"], field, "{changes}: {answer}");
        assert_eq!(answer["error"]["code"], code, "{changes}: {answer}");
    }
    let mut missing = ok.clone();
    missing.as_object_mut().unwrap().remove("methods");
    let (status, answer) = post(&server, STUDY, &missing).await;
    assert_eq!(status, 422);
    assert_eq!(answer["error"]["field"], "methods");
    assert_eq!(answer["error"]["code"], "missing_field");
}

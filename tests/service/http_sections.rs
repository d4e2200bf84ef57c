//! Poincaré sections, events, energy levels and driven systems through the API: the JSON
//! document and the NDJSON stream carry the same points as the core, bit for bit; a recording
//! holds them per orbit in the chart and in physical space; bad input is a 422 naming its field.

use std::time::Duration;

use geomint::api::SimulateRequest;
use geomint::core::run::Budget;
use geomint::core::simulation::Limits;
use geomint::http::Config;
use geomint::recording;
use serde_json::{json, Value};

use crate::decoded::Decoded;
use crate::server::{self, post_json, post_ndjson, start};

fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(30),
        data_dir: server::scratch_dir("http-sections"),
        systems_dir: server::scratch_dir("http-sections-systems"),
        ..Config::default()
    }
}

/// Hénon–Heiles at E = 1/8 from (0.1, 0) with p_x = 0.05, p_y solved, its section y = 0 upwards.
fn henon_heiles(extra: Value) -> Value {
    let mut body = json!({
        "system": {"coordinates": ["x", "y"], "mass": 1,
                   "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3"},
        "methods": [{"id": "kahan_li_8", "base": "velocity_verlet"}, "rk4"],
        "h": 0.08, "t_end": 400, "q0": [0.1, 0], "p0": [0.05, 0],
        "energy": {"value": 0.125, "momentum": "p_y"},
        "section": {"where": "y", "direction": "up", "max_points": 40},
        "output": {"every": 50}
    });
    for (k, v) in extra.as_object().unwrap() {
        body[k] = v.clone();
    }
    body
}

/// The document the core makes for `body`.
fn in_process(body: &Value) -> Value {
    let spec = SimulateRequest::from_value(body).unwrap();
    let sim = spec
        .prepare(&Limits::default(), &geomint::api::system::NoStoredSystems)
        .unwrap();
    serde_json::to_value(sim.simulate(2, Budget::default()).unwrap()).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_section_answers_its_points_in_json_and_ndjson_as_the_core_computes_them() {
    let server = start(config()).await;
    let body = henon_heiles(json!({}));
    let (status, doc) = post_json(&server, "/api/v1/simulate", &body).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["section"]["where"], "y");
    assert_eq!(doc["section"]["coordinates"], json!(["x", "y"]));
    assert_eq!(doc["section"]["momenta"], json!(["p_x", "p_y"]));
    // p_y was solved from the energy.
    let p_y = doc["system"]["p0"][1].as_f64().unwrap();
    assert!((0.5 * (0.05f64.powi(2) + p_y * p_y) + 0.005 - 0.125).abs() < 1e-16);
    for run in doc["runs"].as_array().unwrap() {
        let points = &run["section"];
        let n = points["t"].as_array().unwrap().len();
        assert_eq!(run["section_summary"]["points"], n);
        assert!(
            n >= 40 || run["section_summary"]["truncated"] == false,
            "{run}"
        );
        for (q, h) in points["q"]
            .as_array()
            .unwrap()
            .iter()
            .zip(points["energy"].as_array().unwrap())
        {
            assert!(q[1].as_f64().unwrap().abs() <= 1e-13);
            if run["method"] != "rk4" {
                assert!((h.as_f64().unwrap() - 0.125).abs() <= 1e-12);
            }
        }
    }
    // The same request gives the same bits, over HTTP and in process.
    let again = in_process(&body);
    for (a, b) in doc["runs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(again["runs"].as_array().unwrap())
    {
        for key in [
            "section",
            "section_summary",
            "t",
            "q",
            "p",
            "energy",
            "stop",
        ] {
            assert_eq!(a[key], b[key], "{key}");
        }
    }

    // Streamed: a header announcing the section, `crossings` chunks continuing each other.
    let (status, _, lines) =
        post_ndjson(&server, "/api/v1/simulate", "application/x-ndjson", &body).await;
    assert_eq!(status, 200);
    assert_eq!(lines[0]["section"]["where"], "y");
    for (m, run) in doc["runs"].as_array().unwrap().iter().enumerate() {
        let mut t = Vec::new();
        let mut q = Vec::new();
        for line in lines
            .iter()
            .filter(|l| l["type"] == "crossings" && l["method"] == m)
        {
            assert_eq!(line["surface"], "section");
            assert_eq!(line["offset"], t.len());
            t.extend(line["t"].as_array().unwrap().iter().cloned());
            q.extend(line["q"].as_array().unwrap().iter().cloned());
        }
        assert_eq!(Value::from(t), run["section"]["t"]);
        assert_eq!(Value::from(q), run["section"]["q"]);
        let summary = lines
            .iter()
            .find(|l| l["type"] == "summary" && l["method"] == m)
            .unwrap();
        assert_eq!(summary["section_summary"], run["section_summary"]);
    }
    assert_eq!(lines.last().unwrap()["type"], "end");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_event_stops_each_run_and_a_surface_never_crossed_says_so() {
    let server = start(config()).await;
    let body = henon_heiles(json!({
        "stop_when": {"where": "y", "direction": "up", "count": 3},
        "section": {"where": "y - 2"}
    }));
    let (status, doc) = post_json(&server, "/api/v1/simulate", &body).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["stop_when"]["count"], 3);
    for run in doc["runs"].as_array().unwrap() {
        assert_eq!(run["stop"]["reason"], "event", "{run}");
        let events = run["events"]["t"].as_array().unwrap();
        assert_eq!(events.len(), 3);
        assert_eq!(run["stop"]["t"], events[2]);
        let step = run["stop"]["step"].as_u64().unwrap();
        assert_eq!(
            run["t"]
                .as_array()
                .unwrap()
                .last()
                .unwrap()
                .as_f64()
                .unwrap(),
            step as f64 * 0.08
        );
        assert_eq!(run["section_summary"]["points"], 0);
        let note = run["section_summary"]["note"].as_str().unwrap();
        assert!(note.contains("never crossed upwards"), "{note}");
        assert_eq!(run["section"]["t"], json!([]));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_driven_system_has_its_stroboscopic_section() {
    let server = start(config()).await;
    let period = 2.0 * std::f64::consts::PI / 1.2;
    let body = json!({
        "system": {"coordinates": ["x"], "mass": 1,
                   "potential": "-x^2/2 + x^4/4 - A*x*cos(omega*t)",
                   "damping": {"gamma": "delta/2"},
                   "parameters": {"delta": 0.3, "A": 0.5, "omega": 1.2}},
        "method": {"id": "kahan_li_6", "base": "modin_3s"},
        "h": period / 64.0, "t_end": 50.0 * period, "q0": [1], "p0": [0],
        "section": {"period": period, "phase": 0}
    });
    let (status, doc) = post_json(&server, "/api/v1/simulate", &body).await;
    assert_eq!(status, 200, "{doc}");
    let t = doc["runs"][0]["section"]["t"].as_array().unwrap();
    assert_eq!(t.len(), 50);
    for (k, t) in t.iter().enumerate() {
        assert_eq!(t.as_f64().unwrap(), (k + 1) as f64 * period);
    }
    assert_eq!(doc["section"]["period"], period);
    // A driven definition says so, and lists only the methods that take time.
    let (status, entry) = post_json(&server, "/api/v1/systems", &body["system"]).await;
    assert!(status == 200 || status == 201, "{entry}");
    assert_eq!(entry["facts"]["time_dependent"], true);
    let methods: Vec<&str> = entry["facts"]["methods"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    assert!(methods.contains(&"csv1") && !methods.contains(&"csv2") && !methods.contains(&"cimp"));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_sections_events_and_levels_are_refused_naming_their_field() {
    let server = start(config()).await;
    let driven = json!({"coordinates": ["x"], "mass": 1, "potential": "x^2/2 - x*cos(t)",
                        "damping": {"gamma": 0.1}});
    let cases = [
        (
            json!({"section": {"where": "y +"}}),
            "invalid_expression",
            "section.where",
            Some(3),
        ),
        (
            json!({"section": {"where": "y + w"}}),
            "invalid_expression",
            "section.where",
            Some(4),
        ),
        (
            json!({"section": {"period": 0}}),
            "invalid_value",
            "section.period",
            None,
        ),
        (
            json!({"section": {"period": -2, "phase": 0}}),
            "invalid_value",
            "section.period",
            None,
        ),
        (
            json!({"section": {"where": "y", "period": 1}}),
            "invalid_value",
            "section",
            None,
        ),
        (
            json!({"section": {"where": "y", "phase": 1}}),
            "invalid_value",
            "section",
            None,
        ),
        (
            json!({"section": {"direction": "up"}}),
            "missing_field",
            "section.where",
            None,
        ),
        (
            json!({"section": {"where": "y", "direction": "sideways"}}),
            "invalid_value",
            "section.direction",
            None,
        ),
        (
            json!({"section": {"where": "y", "max_points": 0}}),
            "invalid_value",
            "section.max_points",
            None,
        ),
        (
            json!({"section": {"where": "y", "max_points": 600000}}),
            "too_many_samples",
            "section.max_points",
            None,
        ),
        (
            json!({"section": {"where": "y", "every": 2}}),
            "unknown_field",
            "section.every",
            None,
        ),
        (
            json!({"stop_when": {"count": 2}}),
            "missing_field",
            "stop_when.where",
            None,
        ),
        (
            json!({"stop_when": {"where": "x", "count": 0}}),
            "invalid_value",
            "stop_when.count",
            None,
        ),
        (
            json!({"stop_when": {"where": "x)"}}),
            "invalid_expression",
            "stop_when.where",
            Some(1),
        ),
        (
            json!({"energy": {"value": 0.001, "momentum": "p_y"}}),
            "invalid_value",
            "energy.value",
            None,
        ),
        (
            json!({"energy": {"value": 0.1, "momentum": "p_z"}}),
            "invalid_value",
            "energy.momentum",
            None,
        ),
        (
            json!({"system": driven.clone(), "q0": [1], "p0": [0], "methods": ["csv2"]}),
            "unmet_requirement",
            "methods[0]",
            None,
        ),
        (
            json!({"system": driven, "q0": [1], "p0": [0], "methods": ["rk4"], "jacobian_defect": true}),
            "invalid_value",
            "jacobian_defect",
            None,
        ),
    ];
    for (extra, code, field, position) in cases {
        let body = henon_heiles(extra.clone());
        let (status, error) = post_json(&server, "/api/v1/simulate", &body).await;
        let error = &error["error"];
        assert_eq!(status, 422, "{extra}: {error}");
        assert_eq!(error["code"], code, "{extra}: {error}");
        assert_eq!(error["field"], field, "{extra}: {error}");
        assert_eq!(error["position"].as_u64(), position, "{extra}: {error}");
    }
}

#[test]
fn a_recording_holds_the_section_per_orbit_in_the_chart_and_in_space() {
    let body = henon_heiles(json!({"methods": [{"id": "kahan_li_8", "base": "velocity_verlet"}]}));
    let spec = SimulateRequest::from_value(&body).unwrap();
    let doc = spec
        .prepare(&Limits::default(), &geomint::api::system::NoStoredSystems)
        .unwrap()
        .simulate(1, Budget::default())
        .unwrap();
    let rrd = recording::rrd_bytes(&recording::Spec::of(&spec), &doc).unwrap();
    let d = Decoded::of(&rrd);
    let section = doc.runs[0].section.as_ref().unwrap();
    let m = "kahan_li_8_velocity_verlet";
    for dof in 0..2 {
        let path = format!("/{m}/section/{dof}");
        assert_eq!(d.rows(&path), section.t.len(), "{path}");
        let chunk = d.chunks[path.as_str()]
            .iter()
            .find(|c| !c.is_static())
            .unwrap();
        let points: Vec<[f32; 2]> = chunk
            .iter_slices::<[f32; 2]>(rerun::Points2D::descriptor_positions().component)
            .flat_map(|s| s.to_vec())
            .collect();
        for (k, point) in points.iter().enumerate() {
            assert_eq!(*point, [section.q[k][dof] as f32, section.p[k][dof] as f32]);
        }
    }
    // In space: the first two coordinates, drawn as the definition's default positions.
    assert_eq!(d.rows(&format!("/{m}/world/section")), section.t.len());
    assert!(d.blueprint_entities.iter().any(|p| p.starts_with("/view/")));
}

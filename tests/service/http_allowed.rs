//! `POST /api/v1/simulate/allowed-region`: which points of a section's plane can start an orbit
//! at an energy. On the Hénon–Heiles plane y = 0 at E = 1/8 the allowed points are those with
//! (x² + p_x²)/2 ≤ E (V(x, 0) = x²/2, p_y solved), and a run launched from a point is refused
//! exactly where the region says so; bad input is a 422 naming its field.

use std::time::Duration;

use geomint::http::Config;
use serde_json::{json, Value};

use crate::server::{self, post_json, start};

fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(30),
        data_dir: server::scratch_dir("http-allowed"),
        systems_dir: server::scratch_dir("http-allowed-systems"),
        ..Config::default()
    }
}

/// The request a click on the Hénon–Heiles plane (x, p_x) at E = 1/8 sends, with `plane`.
fn henon_heiles(plane: Value) -> Value {
    json!({
        "system": {"name": "Hénon–Heiles", "coordinates": ["x", "y"], "mass": 1,
                   "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3"},
        "method": "velocity_verlet", "h": 0.08, "t_end": 10,
        "q0": [0, 0], "p0": [0, 0],
        "energy": {"value": 0.125, "momentum": "p_y"},
        "section": {"where": "y", "direction": "up", "max_points": 10},
        "plane": plane
    })
}

fn plane() -> Value {
    json!({"x": {"name": "x", "min": -0.6, "max": 0.6, "points": 25},
           "y": {"name": "p_x", "min": -0.6, "max": 0.6, "points": 13}})
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_allowed_region_is_the_disc_of_the_energy_and_runs_start_only_there() {
    let server = start(config()).await;
    let (status, doc) = post_json(
        &server,
        "/api/v1/simulate/allowed-region",
        &henon_heiles(plane()),
    )
    .await;
    assert_eq!(status, 200, "{doc}");
    let xs: Vec<f64> = serde_json::from_value(doc["x"].clone()).unwrap();
    let ys: Vec<f64> = serde_json::from_value(doc["y"].clone()).unwrap();
    assert_eq!((xs.len(), ys.len()), (25, 13));
    assert_eq!((xs[0], xs[24], ys[0], ys[12]), (-0.6, 0.6, -0.6, 0.6));
    let mut count = 0;
    for (j, &px) in ys.iter().enumerate() {
        for (i, &x) in xs.iter().enumerate() {
            let lowest = doc["lowest"][j][i].as_f64().unwrap();
            let expected = (x * x + px * px) / 2.0;
            assert!(
                (lowest - expected).abs() <= 1e-15,
                "H({x}, {px}) = {lowest}"
            );
            // Points on the circle itself are left out: round-off decides them.
            if (expected - 0.125).abs() > 1e-9 {
                assert_eq!(doc["allowed"][j][i], json!(expected < 0.125), "({x}, {px})");
            }
            count += u64::from(doc["allowed"][j][i] == json!(true));
        }
    }
    assert_eq!(doc["allowed_points"], json!(count));
    assert!(count > 50 && count < 25 * 13, "{count} allowed");

    // A run from an allowed point starts; one from a forbidden point is refused, naming `energy`.
    for (x, px, allowed) in [(0.3, 0.2, true), (-0.45, 0.3, false), (0.55, 0.0, false)] {
        let mut body = henon_heiles(Value::Null);
        body.as_object_mut().unwrap().remove("plane");
        body["q0"] = json!([x, 0]);
        body["p0"] = json!([px, 0]);
        let (status, answer) = post_json(&server, "/api/v1/simulate", &body).await;
        assert_eq!(status == 200, allowed, "({x}, {px}): {answer}");
        if !allowed {
            assert_eq!(answer["error"]["field"], "energy.value", "{answer}");
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_planes_are_refused_naming_the_field() {
    let server = start(config()).await;
    let mut cases: Vec<(Value, &str)> = vec![
        (json!({"y": plane()["y"]}), "plane.x"),
        (
            json!({"x": {"name": "z", "min": 0, "max": 1}, "y": plane()["y"]}),
            "plane.x.name",
        ),
        (
            json!({"x": {"name": "p_y", "min": 0, "max": 1}, "y": plane()["y"]}),
            "plane.x.name",
        ),
        (
            json!({"x": plane()["x"], "y": {"name": "x", "min": 0, "max": 1}}),
            "plane.y.name",
        ),
        (
            json!({"x": {"name": "x", "min": 1, "max": 0}, "y": plane()["y"]}),
            "plane.x.max",
        ),
        (
            json!({"x": plane()["x"], "y": {"name": "p_x", "min": 0, "max": 1, "points": 201}}),
            "plane.y.points",
        ),
        (
            json!({"x": plane()["x"], "y": plane()["y"], "z": 1}),
            "plane.z",
        ),
    ];
    let mut no_plane = henon_heiles(Value::Null);
    no_plane.as_object_mut().unwrap().remove("plane");
    let mut no_energy = henon_heiles(plane());
    no_energy.as_object_mut().unwrap().remove("energy");
    let mut bad_momentum = henon_heiles(plane());
    bad_momentum["energy"]["momentum"] = json!("p_z");
    let mut bad_h = henon_heiles(plane());
    bad_h["h"] = json!(-1);
    for (body, field) in [
        (no_plane, "plane"),
        (no_energy, "energy"),
        (bad_momentum, "energy.momentum"),
        (bad_h, "h"),
    ] {
        let (status, answer) = post_json(&server, "/api/v1/simulate/allowed-region", &body).await;
        assert_eq!(status, 422, "{answer}");
        assert_eq!(answer["error"]["field"], field, "{answer}");
    }
    for (p, field) in cases.drain(..) {
        let (status, answer) =
            post_json(&server, "/api/v1/simulate/allowed-region", &henon_heiles(p)).await;
        assert_eq!(status, 422, "{answer}");
        assert_eq!(answer["error"]["field"], field, "{answer}");
    }
}

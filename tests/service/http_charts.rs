//! Coordinate charts and energy-error maps over real HTTP: a run in the polar chart reports its
//! Cartesian state, runs from the same Cartesian start agree in both charts for the reference,
//! the energy-map route (JSON, NDJSON progress, the recording's image) and bad input.

use std::collections::BTreeSet;
use std::time::Duration;

use crate::decoded;
use crate::server;
use decoded::Decoded;

use geomint::http::Config;
use geomint::recording::energy_map::difference_color;
use rerun::components::ImageBuffer;
use rerun::{Image, SegmentationImage};
use serde_json::{json, Value};
use server::{client, get_json, post_json as post, start};

const MAP: &str = "/api/v1/studies/energy-map";

fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(60),
        ..Config::default()
    }
}

fn column(run: &Value, name: &str) -> Vec<Vec<f64>> {
    run[name]
        .as_array()
        .unwrap_or_else(|| panic!("{name} missing"))
        .iter()
        .map(|s| {
            s.as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect()
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_polar_run_reports_its_cartesian_state_and_matches_the_cartesian_reference() {
    let server = start(config()).await;
    let mut runs = Vec::new();
    for chart in ["cartesian", "polar"] {
        let (status, doc) = post(
            &server,
            "/api/v1/simulate",
            &json!({"system": "elastic_pendulum_2d", "chart": chart,
                    "initial_coordinates": "cartesian", "q0": [0.6, 1.2], "p0": [0.1, -0.2],
                    "methods": [{"id": "reference", "tolerance": 1e-10}, "symplectic_euler"],
                    "h": 0.5, "t_end": 5.0, "output": {"every": 1}}),
        )
        .await;
        assert_eq!(status, 200, "{doc}");
        assert_eq!(doc["system"]["chart"], chart);
        runs.push(doc);
    }
    let polar = &runs[1]["runs"][0];
    // The polar chart's own state (r, θ) and its Cartesian image.
    let (q, x) = (column(polar, "q"), column(polar, "cartesian_q"));
    assert!((q[0][0] - 0.6f64.hypot(1.2)).abs() < 1e-15);
    assert!((x[0][0] - 0.6).abs() < 1e-15 && (x[0][1] - 1.2).abs() < 1e-15);
    assert!(
        runs[0]["runs"][0].get("cartesian_q").is_none(),
        "the Cartesian chart needs no copy"
    );
    // The reference agrees across charts to about its tolerance; symplectic Euler does not.
    let difference = |k: usize| {
        let a = column(&runs[0]["runs"][k], "q");
        let b = column(&runs[1]["runs"][k], "cartesian_q");
        a.iter()
            .zip(&b)
            .flat_map(|(u, v)| u.iter().zip(v).map(|(s, t)| (s - t).abs()))
            .fold(0.0, f64::max)
    };
    let (reference, euler) = (difference(0), difference(1));
    assert!(reference < 1e-8, "reference differs by {reference:e}");
    assert!(euler > 1e-3, "symplectic Euler differs by only {euler:e}");

    // A non-separable chart refuses the splittings, naming the method.
    let (status, err) = post(
        &server,
        "/api/v1/simulate",
        &json!({"system": "elastic_pendulum_2d", "chart": "polar",
                "methods": ["rk4", "velocity_verlet"], "h": 0.1, "t_end": 1.0}),
    )
    .await;
    assert_eq!(status, 422, "{err}");
    assert_eq!(err["error"]["field"], "methods[1]");
    assert_eq!(err["error"]["code"], "unmet_requirement");
    assert!(
        err["error"]["message"]
            .as_str()
            .unwrap()
            .contains("polar chart"),
        "{err}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_energy_map_answers_json_ndjson_and_a_recording() {
    let server = start(config()).await;
    let body = json!({"nx": 11, "ny": 9, "t_max": 400});
    let (status, doc) = post(&server, MAP, &body).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["method"], "symplectic_euler");
    assert_eq!(doc["params"]["g"], 0.02);
    assert_eq!(doc["steps_per_run"], 2000);
    let cells = 11 * 9;
    for name in [
        "energy",
        "epsilon_cartesian",
        "epsilon_polar",
        "difference",
        "polar_diverged_at",
        "predicted_divergent",
    ] {
        assert_eq!(doc[name].as_array().unwrap().len(), cells, "{name}");
    }
    let summary = &doc["summary"];
    assert_eq!(summary["cells"], cells);
    assert!(
        summary["cartesian_better"].as_u64().unwrap() > 0,
        "{summary}"
    );
    assert!(summary["polar_better"].as_u64().unwrap() > 0, "{summary}");
    // The corners (r₀ ≈ 2.1) lie beyond the boundary and diverge in polar coordinates.
    assert!(
        summary["polar_diverged"].as_u64().unwrap() >= 4,
        "{summary}"
    );
    assert!(doc["difference"][0].is_null() && doc["predicted_divergent"][0] == true);

    // NDJSON: progress lines up to every cell, then the same result.
    let text = client()
        .post(server.url(MAP))
        .header("accept", "application/x-ndjson")
        .json(&body)
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    // Read with correctly rounded floats, as `post` does, so that numbers compare bit for bit.
    let lines: Vec<Value> = text
        .lines()
        .map(|l| geomint::api::json::parse_json(l.as_bytes()).unwrap())
        .collect();
    let kinds: Vec<&str> = lines.iter().map(|l| l["type"].as_str().unwrap()).collect();
    assert_eq!(kinds[kinds.len() - 2..], ["result", "end"]);
    let progress: Vec<u64> = lines
        .iter()
        .filter(|l| l["type"] == "progress")
        .map(|l| l["done"].as_u64().unwrap())
        .collect();
    assert!(
        !progress.is_empty() && progress.last() == Some(&(cells as u64)),
        "{progress:?}"
    );
    assert!(progress.windows(2).all(|w| w[0] < w[1]) || progress.len() == 1);
    let result = &lines[lines.len() - 2];
    assert_eq!(
        result["epsilon_polar"], doc["epsilon_polar"],
        "same numbers, bit for bit"
    );

    // The recording: the map as an RGB image coloured from the JSON, the divergence classes,
    // the boundary and the error tensors.
    let response = client()
        .post(server.url(&format!("{MAP}?format=rrd")))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let d = Decoded::of(&response.bytes().await.unwrap());
    let want: BTreeSet<String> = [
        "/",
        "/map/difference",
        "/map/divergence",
        "/map/boundary",
        "/epsilon/cartesian",
        "/epsilon/polar",
        "/summary",
    ]
    .map(String::from)
    .into();
    assert!(want.is_subset(&d.entity_paths()), "{:?}", d.entity_paths());
    let pixels: Vec<ImageBuffer> =
        d.static_batch("/map/difference", Image::descriptor_buffer().component);
    assert_eq!(pixels[0].0.len(), 3 * cells);
    for k in 0..cells {
        let want = difference_color(
            doc["epsilon_cartesian"][k].as_f64(),
            doc["epsilon_polar"][k].as_f64(),
        );
        assert_eq!(pixels[0].0[3 * k..3 * k + 3], want, "cell {k}");
    }
    let classes: Vec<ImageBuffer> = d.static_batch(
        "/map/divergence",
        SegmentationImage::descriptor_buffer().component,
    );
    assert_eq!(classes[0].0.len(), cells);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_maps_get_errors_naming_the_field() {
    let server = start(config()).await;
    for (body, field, code) in [
        (
            json!({"method": "velocity_verlet"}),
            "method",
            "unmet_requirement",
        ),
        (json!({"method": "rk9"}), "method", "unknown_method"),
        (json!({"nx": 0}), "nx", "invalid_value"),
        (json!({"ny": 1000}), "ny", "invalid_value"),
        (json!({"nx": "many"}), "nx", "invalid_type"),
        (json!({"x": [1.0, -1.0]}), "x", "invalid_value"),
        (json!({"y": [0.0]}), "y", "invalid_type"),
        (json!({"h": -0.2}), "h", "invalid_value"),
        (
            json!({"t_max": 1e9, "nx": 401, "ny": 401}),
            "t_max",
            "invalid_value",
        ),
        (json!({"params": {"k": -1}}), "params.k", "invalid_value"),
        // An unknown parameter is an unknown field, as on every other route.
        (
            json!({"params": {"gamma": 1}}),
            "params.gamma",
            "unknown_field",
        ),
        (json!({"colour": "red"}), "colour", "unknown_field"),
    ] {
        let (status, err) = post(&server, MAP, &body).await;
        assert_eq!(status, 422, "{body}: {err}");
        assert_eq!(err["error"]["field"], field, "{body}: {err}");
        assert_eq!(err["error"]["code"], code, "{body}: {err}");
    }
}

/// Starts so far out that H₀ overflows are blown up at t = 0, and their start energy is `null`,
/// as the published document says it may be.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_start_energy_that_overflows_is_null_as_documented() {
    let server = start(config()).await;
    let body = json!({"nx": 3, "ny": 4, "t_max": 10, "y": [-1.1, 5.679909810453618e272]});
    let (status, doc) = post(&server, MAP, &body).await;
    assert_eq!(status, 200, "{doc}");
    let energy = doc["energy"].as_array().unwrap();
    assert_eq!(energy.len(), 12);
    // The first row (y₀ = −1.1) is finite, the others overflow.
    assert!(energy[..3].iter().all(Value::is_f64), "{energy:?}");
    assert!(energy[3..].iter().all(Value::is_null), "{energy:?}");
    let openapi = get_json(&server, "/api/v1/openapi.json").await;
    let items =
        &openapi["components"]["schemas"]["EnergyMapDocument"]["properties"]["energy"]["items"];
    assert_eq!(items["type"], json!(["number", "null"]), "{items}");
}

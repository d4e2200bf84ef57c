//! `POST /api/v1/studies/basins`: the damped double well typed in, over (x₀, p₀); Hénon–Heiles
//! escapes through three named exits; the NDJSON stream; bad input a 422 naming its field.

use std::time::Duration;

use geomint::http::Config;
use serde_json::{json, Value};

use crate::server::{self, post_json, post_ndjson, start};

const PATH: &str = "/api/v1/studies/basins";

fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(60),
        data_dir: server::scratch_dir("http-basins"),
        systems_dir: server::scratch_dir("http-basins-systems"),
        ..Config::default()
    }
}

/// x″ + δx′ − x + x³ = 0 with δ = 2γ = 0.25, over (x₀, p₀) ∈ [−2, 2]².
fn double_well(n: u64) -> Value {
    json!({
        "system": {"name": "double well", "coordinates": ["x"], "mass": 1,
                   "potential": "-x^2/2 + x^4/4", "damping": {"gamma": "gamma"},
                   "parameters": {"gamma": 0.125}},
        "methods": ["csv2", "rk4"], "h": 0.05, "t_end": 200,
        "axes": [{"name": "q0[0]", "min": -2, "max": 2, "n": n},
                 {"name": "p0[0]", "min": -2, "max": 2, "n": n}]
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_double_well_splits_into_two_basins_by_the_energy_argument() {
    let server = start(config()).await;
    let (status, doc) = post_json(&server, PATH, &double_well(20)).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["cells"], 400);
    assert_eq!(doc["lowest_saddle_energy"], 0.0);
    let equilibria = doc["equilibria"].as_array().unwrap();
    assert_eq!(equilibria.len(), 3);
    for run in doc["runs"].as_array().unwrap() {
        let labels: Vec<i64> = serde_json::from_value(run["labels"].clone()).unwrap();
        assert_eq!(labels.len(), 400);
        assert!(labels.iter().all(|&l| l == 0 || l == 1), "{labels:?}");
        assert_eq!(run["decided_by"]["energy"], 400);
        let attractors = run["attractors"].as_array().unwrap();
        assert_eq!(attractors.len(), 2);
        for a in attractors {
            assert_eq!(a["kind"], "equilibrium");
            let x = a["equilibrium"]["q"][0].as_f64().unwrap();
            assert!((x.abs() - 1.0).abs() <= 1e-14, "{a}");
        }
        // Symmetric under (x, p) → (−x, −p): equal shares.
        assert_eq!(run["fractions"][0], run["fractions"][1]);
        let entropy = run["basin_entropy"].as_f64().unwrap();
        assert!(entropy > 0.0 && entropy < 2f64.ln(), "{entropy}");
        // Decided long before t_end: each decision time is on the step grid below it.
        let decided: Vec<f64> = serde_json::from_value(run["decided_at"].clone()).unwrap();
        assert!(decided.iter().all(|&t| (0.0..200.0).contains(&t)));
    }
    // The same request, the same bits.
    let (_, again) = post_json(&server, PATH, &double_well(20)).await;
    assert_eq!(doc["runs"], again["runs"]);
    assert_eq!(doc["digest"], again["digest"]);
    // No angles and no given attractors are the same map, with the same identity.
    let mut settings = double_well(20);
    settings["recognition"] = json!({});
    let mut empty = settings.clone();
    empty["recognition"] = json!({"angles": []});
    empty["attractors"] = json!([]);
    let (_, with_settings) = post_json(&server, PATH, &settings).await;
    let (_, same) = post_json(&server, PATH, &empty).await;
    assert_eq!(with_settings["digest"], same["digest"]);
    assert_eq!(doc["runs"], same["runs"]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn henon_heiles_escapes_through_three_named_exits_and_streams_its_progress() {
    let server = start(config()).await;
    let body = json!({
        "system": "henon_heiles", "methods": ["velocity_verlet"], "h": 0.01, "t_end": 100,
        "q0": [0, 0], "p0": [0, 0],
        "energy_surface": {"energy": 0.25, "solve_for": "p0[0]"},
        "axes": [{"name": "q0[1]", "min": -0.6, "max": 1.0, "n": 12},
                 {"name": "p0[1]", "min": -0.6, "max": 0.6, "n": 12}],
        "exits": [
            {"name": "up", "where": "y - 2", "direction": "up"},
            {"name": "left", "where": "-sqrt(3)/2*x - y/2 - 2", "direction": "up"},
            {"name": "right", "where": "sqrt(3)/2*x - y/2 - 2", "direction": "up"}
        ]
    });
    let (status, content_type, lines) =
        post_ndjson(&server, PATH, "application/x-ndjson", &body).await;
    assert_eq!(status, 200);
    assert_eq!(content_type, "application/x-ndjson");
    assert_eq!(lines.last().unwrap()["type"], "end");
    let progress: Vec<&Value> = lines.iter().filter(|l| l["type"] == "progress").collect();
    assert_eq!(progress.last().unwrap()["done"], 144);
    let doc = &lines.iter().find(|l| l["type"] == "result").unwrap();
    let run = &doc["runs"][0];
    let mut names: Vec<&str> = run["attractors"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["kind"] == "exit")
        .map(|a| a["name"].as_str().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["left", "right", "up"]);
    // Cells off the energy surface are undecided, each with its reason.
    for u in run["undecided"].as_array().unwrap() {
        assert!(u["reason"].as_str().unwrap().contains("energy"), "{u}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_basin_maps_are_422s_naming_the_field() {
    let server = start(config()).await;
    let cases: Vec<(Value, &str)> = vec![
        (
            {
                let mut b = double_well(4);
                b["axes"][0]["name"] = json!("params.gamma");
                b["axes"][0]["min"] = json!(0.1);
                b["axes"][0]["max"] = json!(0.2);
                b
            },
            "axes[0].name",
        ),
        (
            {
                let mut b = double_well(4);
                b["exits"] = json!([{"name": "right", "where": "x - * 2"}]);
                b
            },
            "exits[0].where",
        ),
        (
            {
                let mut b = double_well(4);
                b["exits"] = json!([{"name": "right", "where": "x - 2", "direction": "sideways"}]);
                b
            },
            "exits[0].direction",
        ),
        (
            {
                let mut b = double_well(4);
                b["recognition"] = json!({"period": std::f64::consts::TAU});
                b
            },
            "recognition.period",
        ),
        (
            {
                let mut b = double_well(4);
                b["recognition"] = json!({"tolerance": -1});
                b
            },
            "recognition.tolerance",
        ),
        (
            {
                let mut b = double_well(4);
                b["indicators"] = json!(["megno"]);
                b
            },
            "indicators",
        ),
        (
            {
                let mut b = double_well(4);
                b["exits"] =
                    json!([{"name": "a", "where": "x - 2"}, {"name": "a", "where": "x + 2"}]);
                b
            },
            "exits[1].name",
        ),
        (
            {
                let mut b = double_well(4);
                b["recognition"] = json!({"angles": ["p_x"]});
                b
            },
            "recognition.angles[0]",
        ),
        (
            {
                let mut b = double_well(4);
                b["attractors"] = json!([{"name": "left", "points": [[-1, 0, 0]], "radius": 0.1}]);
                b
            },
            "attractors[0].points[0]",
        ),
        (
            {
                let mut b = double_well(4);
                b["attractors"] = json!([{"name": "left", "points": [[-1, 0]], "radius": 0}]);
                b
            },
            "attractors[0].radius",
        ),
        (
            {
                let mut b = double_well(4);
                b["attractors"] = json!([{"name": "left", "points": [[-1, 0]]}]);
                b
            },
            "attractors[0].radius",
        ),
        (
            {
                // A basin map takes up to 1024 points along an axis (a sweep 401).
                let mut b = double_well(4);
                b["axes"][0]["n"] = json!(1025);
                b
            },
            "axes[0].n",
        ),
    ];
    for (body, field) in cases {
        let (status, error) = post_json(&server, PATH, &body).await;
        assert_eq!(status, 422, "{field}: {error}");
        assert_eq!(error["error"]["field"], field, "{error}");
    }
}

/// Every preset runs (on a coarse grid and a shorter time, which keep its shape) and finds what
/// its title says.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_preset_runs_and_finds_its_attractors() {
    let server = start(config()).await;
    let presets = server::get_json(&server, "/api/v1/studies/basins/presets").await;
    let presets = presets.as_array().unwrap();
    assert_eq!(presets.len(), 5);
    for preset in presets {
        let id = preset["id"].as_str().unwrap();
        let mut body = preset["request"].clone();
        for axis in body["axes"].as_array_mut().unwrap() {
            axis["n"] = json!(9);
        }
        let (status, doc) = post_json(&server, PATH, &body).await;
        assert_eq!(status, 200, "{id}: {doc}");
        let run = &doc["runs"][0];
        let kinds: Vec<&str> = run["attractors"]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a["kind"].as_str().unwrap())
            .collect();
        let count = |kind: &str| kinds.iter().filter(|&&k| k == kind).count();
        match id {
            // The two minima, and the saddle at the centre cell, which starts at rest on it.
            "double_well" => {
                assert_eq!(count("equilibrium"), 3, "{id}: {kinds:?}");
                assert_eq!(run["undecided_fraction"], 0.0);
            }
            "forced_duffing" => assert_eq!(count("periodic"), 2, "{id}: {kinds:?}"),
            // Round one way and round the other: period-1 orbits once θ is taken modulo 2π.
            "forced_pendulum" => {
                assert_eq!(count("periodic"), 2, "{id}: {kinds:?}");
                assert_eq!(run["undecided_fraction"], 0.0);
            }
            "henon_heiles_escapes" => assert_eq!(count("exit"), 3, "{id}: {kinds:?}"),
            "henon_heiles_escapes_damped" => {
                assert!(
                    count("exit") >= 2 && count("equilibrium") == 1,
                    "{id}: {kinds:?}"
                )
            }
            other => panic!("an unknown preset {other}"),
        }
        println!("{id}: {kinds:?}, decided by {}", run["decided_by"]);
    }
}

/// `geomint study basins`: the whole map from the command line is the route's, bit for bit, and
/// its shards merge to it with `geomint study merge`, in any order.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_command_line_map_and_its_merged_shards_equal_the_routes() {
    let server = start(config()).await;
    let body = double_well(7);
    let (status, routed) = post_json(&server, PATH, &body).await;
    assert_eq!(status, 200, "{routed}");
    let dir = server::scratch_dir("cli-basins");
    std::fs::create_dir_all(&dir).unwrap();
    let spec = dir.join("spec.json");
    std::fs::write(&spec, serde_json::to_vec(&body).unwrap()).unwrap();
    let geomint = |args: &[&std::ffi::OsStr]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_geomint"))
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let read = |p: &std::path::Path| -> Value {
        geomint::api::json::parse_json(&std::fs::read(p).unwrap()).unwrap()
    };
    let whole = dir.join("whole.json");
    geomint(&[
        "study".as_ref(),
        "basins".as_ref(),
        spec.as_os_str(),
        "-o".as_ref(),
        whole.as_os_str(),
    ]);
    let whole = read(&whole);
    assert_eq!(whole["runs"], routed["runs"]);
    assert_eq!(whole["digest"], routed["digest"]);
    let parts: Vec<std::path::PathBuf> =
        (0..3).map(|i| dir.join(format!("part-{i}.json"))).collect();
    for (i, part) in parts.iter().enumerate() {
        let shard = format!("{i}/3");
        geomint(&[
            "study".as_ref(),
            "basins".as_ref(),
            spec.as_os_str(),
            "--shard".as_ref(),
            shard.as_ref(),
            "-o".as_ref(),
            part.as_os_str(),
        ]);
    }
    let merged = dir.join("merged.json");
    geomint(&[
        "study".as_ref(),
        "merge".as_ref(),
        parts[2].as_os_str(),
        parts[0].as_os_str(),
        parts[1].as_os_str(),
        "-o".as_ref(),
        merged.as_os_str(),
    ]);
    assert_eq!(read(&merged)["runs"], routed["runs"]);
}

/// `?format=rrd`: the map's recording, read back with Rerun's own decoder: per run the labels
/// as a segmentation image (label + 1 per cell) whose classes name the attractors.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_recording_holds_the_labels_as_a_segmentation_named_by_the_attractors() {
    use rerun::components::{ImageBuffer, ImageFormat};
    use rerun::{AnnotationContext, SegmentationImage};

    let server = start(config()).await;
    let body = double_well(6);
    let (_, doc) = post_json(&server, PATH, &body).await;
    let response = server::client()
        .post(server.url(&format!("{PATH}?format=rrd")))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(
        response.headers()["content-type"],
        "application/octet-stream"
    );
    let d = crate::decoded::Decoded::of(&response.bytes().await.unwrap());
    let paths = d.entity_paths();
    for run in ["csv2_cartesian", "rk4_cartesian"] {
        for part in ["", "/labels", "/decided_at", "/decided_at/heatmap"] {
            assert!(
                paths.contains(&format!("/{run}{part}")),
                "{run}{part}: {paths:?}"
            );
        }
    }
    assert!(paths.contains("/summary"));
    let run = &doc["runs"][0];
    let labels: Vec<i64> = serde_json::from_value(run["labels"].clone()).unwrap();
    let buffers: Vec<ImageBuffer> = d.static_batch(
        "/csv2_cartesian/labels",
        SegmentationImage::descriptor_buffer().component,
    );
    let bytes: &[u8] = &buffers[0].0;
    let ids: Vec<u16> = bytes
        .chunks(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let expected: Vec<u16> = labels.iter().map(|&l| (l + 1) as u16).collect();
    assert_eq!(ids, expected);
    let formats: Vec<ImageFormat> = d.static_batch(
        "/csv2_cartesian/labels",
        SegmentationImage::descriptor_format().component,
    );
    assert_eq!((formats[0].0.width, formats[0].0.height), (6, 6));
    let contexts: Vec<rerun::components::AnnotationContext> = d.static_batch(
        "/csv2_cartesian",
        AnnotationContext::descriptor_context().component,
    );
    let names: Vec<String> = contexts[0]
        .0
        .iter()
        .map(|c| c.class_description.info.label.as_ref().unwrap().to_string())
        .collect();
    let mut expected_names = vec!["undecided".to_string()];
    for a in run["attractors"].as_array().unwrap() {
        expected_names.push(a["name"].as_str().unwrap().to_string());
    }
    assert_eq!(names, expected_names);
}

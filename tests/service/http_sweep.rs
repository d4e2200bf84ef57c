//! Sweeps through the service and the command line: `POST /api/v1/studies/sweep` (JSON, and
//! NDJSON progress ending in the same document), the presets (the Fig. 6 one equal to the
//! energy-map route's numbers), a stored definition swept by id, each cell's section points,
//! refusals naming their field;
//! and `geomint study sweep --shard` as Slurm and Kubernetes array tasks would run it (index
//! from `SLURM_ARRAY_TASK_ID` / `JOB_COMPLETION_INDEX`), merged by `geomint study merge` into
//! the document of the unsharded run bit for bit, with missing, duplicate and foreign parts
//! refused.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use crate::decoded;
use crate::server;

use decoded::Decoded;
use rerun::components::TensorData;
use rerun::external::re_sdk_types::datatypes::TensorBuffer;
use rerun::{Image, Tensor};

use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, get_json, post_json, post_ndjson, start};

fn config() -> Config {
    Config {
        request_timeout: Duration::from_secs(60),
        data_dir: server::scratch_dir("sweep"),
        systems_dir: server::scratch_dir("sweep-systems"),
        ..Config::default()
    }
}

/// A document without its wall time, for comparing bit for bit.
fn numbers(mut doc: Value) -> Value {
    doc.as_object_mut().unwrap().remove("wall_ms");
    doc
}

fn damped_pendulum_sweep() -> Value {
    json!({
        "system": "pendulum",
        "methods": ["modin_3s", "heun"],
        "h": 0.1,
        "t_end": 20,
        "every": 5,
        "energy_reference": "reference",
        "axes": [
            {"name": "params.gamma", "min": 0.01, "max": 1, "n": 5, "scale": "log"},
            {"name": "q0[0]", "min": 0.5, "max": 2.5, "n": 3}
        ]
    })
}

#[tokio::test]
async fn a_sweep_answers_json_and_ndjson_with_the_same_numbers() {
    let server = start(config()).await;
    let (status, doc) = post_json(&server, "/api/v1/studies/sweep", &damped_pendulum_sweep()).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["cells"], 15);
    assert_eq!(doc["energy_reference"], "reference");
    let runs = doc["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    // Both methods are second order at h = 0.1: errors against the reference are small, the
    // final one within the largest, and larger for the larger swing (q0 = 2.5 against 0.5) at
    // every γ, where the pendulum is further from linear.
    for run in runs {
        let max = |cell: usize| run["energy_error_max"][cell].as_f64().unwrap();
        for cell in 0..15 {
            let last = run["energy_error_final"][cell].as_f64().unwrap().abs();
            assert!(
                last <= max(cell) && max(cell) > 0.0 && max(cell) < 1e-2,
                "{run}"
            );
            assert_eq!(run["steps"][cell], 200);
            assert_eq!(run["final_q"][cell].as_array().unwrap().len(), 1);
        }
        for gamma in 0..5 {
            assert!(
                max(10 + gamma) > max(gamma),
                "{}: γ index {gamma}",
                run["method"]
            );
        }
    }

    let (status, content_type, lines) = post_ndjson(
        &server,
        "/api/v1/studies/sweep",
        "application/x-ndjson",
        &damped_pendulum_sweep(),
    )
    .await;
    assert_eq!(
        (status, content_type.as_str()),
        (200, "application/x-ndjson")
    );
    let kinds: Vec<&str> = lines.iter().map(|l| l["type"].as_str().unwrap()).collect();
    assert_eq!(kinds.last(), Some(&"end"));
    let progress: Vec<u64> = lines
        .iter()
        .filter(|l| l["type"] == "progress")
        .map(|l| l["done"].as_u64().unwrap())
        .collect();
    assert!(progress.windows(2).all(|w| w[0] < w[1]) && progress.last() == Some(&15));
    let result = lines.iter().find(|l| l["type"] == "result").unwrap();
    let mut streamed = result.clone();
    streamed.as_object_mut().unwrap().remove("type");
    assert_eq!(numbers(streamed), numbers(doc));
}

#[tokio::test]
async fn a_sweep_records_a_tensor_and_a_heatmap_per_run_and_metric() {
    let server = start(config()).await;
    let body = damped_pendulum_sweep();
    let (_, doc) = post_json(&server, "/api/v1/studies/sweep", &body).await;
    let response = client()
        .post(server.url("/api/v1/studies/sweep?format=rrd"))
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
    let paths = d.entity_paths();
    for run in doc["runs"].as_array().unwrap() {
        let part = format!(
            "{}_{}",
            run["method"].as_str().unwrap(),
            run["chart"].as_str().unwrap()
        );
        for metric in [
            "energy_error_final",
            "energy_error_max",
            "energy_error_l2",
            "diverged_at",
        ] {
            let path = format!("/{part}/{metric}");
            assert!(
                paths.contains(&path) && paths.contains(&format!("{path}/heatmap")),
                "{path}"
            );
        }
        // The tensor: q0[0] rows × γ columns, equal to the JSON bit for bit, NaN for null.
        let tensors: Vec<TensorData> = d.static_batch(
            &format!("/{part}/energy_error_max"),
            Tensor::descriptor_data().component,
        );
        let tensor = &tensors[0];
        assert_eq!(tensor.shape(), [3, 5]);
        let names: Vec<String> = (0..2)
            .map(|k| tensor.dim_name(k).unwrap().to_string())
            .collect();
        assert_eq!(names, ["q0[0]", "params.gamma"]);
        let TensorBuffer::F64(values) = &tensor.buffer else {
            panic!("f64 values")
        };
        let json: Vec<f64> = run["energy_error_max"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap_or(f64::NAN))
            .collect();
        assert_eq!(values.len(), 15);
        for (r, j) in values.iter().zip(&json) {
            assert_eq!(r.to_bits(), j.to_bits());
        }
        let images = d.static_batch::<rerun::components::ImageFormat>(
            &format!("/{part}/energy_error_max/heatmap"),
            Image::descriptor_format().component,
        );
        assert_eq!((images[0].width, images[0].height), (5, 3));
    }
    assert!(paths.contains("/summary"));
}

#[tokio::test]
async fn the_fig6_preset_equals_the_energy_map_route() {
    let server = start(config()).await;
    let presets = get_json(&server, "/api/v1/studies/sweep/presets").await;
    let ids: Vec<&str> = presets
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["id"].as_str().unwrap())
        .collect();
    assert_eq!(
        ids,
        vec![
            "fig6_energy_map",
            "henon_heiles_megno",
            "elastic_pendulum_chaos",
            "csv1_stability"
        ]
    );
    let mut fig6 = presets[0]["request"].clone();
    assert_eq!(fig6["axes"][0]["n"], 21);
    // A smaller grid and horizon, the same on both routes.
    fig6["axes"][0]["n"] = json!(7);
    fig6["axes"][1]["n"] = json!(5);
    fig6["t_end"] = json!(300);
    let (status, sweep) = post_json(&server, "/api/v1/studies/sweep", &fig6).await;
    assert_eq!(status, 200, "{sweep}");
    let map_request = json!({"nx": 7, "ny": 5, "t_max": 300});
    let (status, map) = post_json(&server, "/api/v1/studies/energy-map", &map_request).await;
    assert_eq!(status, 200);
    assert_eq!(
        sweep["runs"][0]["energy_error_l2"],
        map["epsilon_cartesian"]
    );
    assert_eq!(sweep["runs"][1]["energy_error_l2"], map["epsilon_polar"]);
    assert_eq!(sweep["runs"][1]["diverged_at"], map["polar_diverged_at"]);
    assert_eq!(sweep["axes"][0]["values"], map["xs"]);

    // The stability preset runs as given.
    let (status, stability) =
        post_json(&server, "/api/v1/studies/sweep", &presets[3]["request"]).await;
    assert_eq!(status, 200);
    let diverged = stability["runs"][0]["diverged_at"].as_array().unwrap();
    assert_eq!(diverged.len(), 21 * 30);
    assert!(diverged.iter().any(Value::is_null) && diverged.iter().any(Value::is_number));
}

#[tokio::test]
async fn a_stored_definition_sweeps_by_id_as_inline() {
    let server = start(config()).await;
    let definition = json!({
        "coordinates": ["x"], "momenta": ["p"],
        "mass": 1,
        "potential": "x^2/2 + b*x^4/4",
        "parameters": {"b": 1},
        "q0": [1], "p0": [0]
    });
    let (status, stored) = post_json(&server, "/api/v1/systems", &definition).await;
    assert_eq!(status, 201, "{stored}");
    let sweep_of = |system: Value| {
        json!({"system": system, "methods": ["velocity_verlet"], "h": 0.05, "t_end": 10,
            "axes": [{"name": "params.b", "min": 0, "max": 2, "n": 5}]})
    };
    let (status, by_id) = post_json(
        &server,
        "/api/v1/studies/sweep",
        &sweep_of(stored["id"].clone()),
    )
    .await;
    assert_eq!(status, 200, "{by_id}");
    let (_, inline) = post_json(&server, "/api/v1/studies/sweep", &sweep_of(definition)).await;
    assert_eq!(by_id["runs"], inline["runs"]);
    assert_eq!(by_id["energy_reference"], "initial");
    // Verlet's energy error is second order and stays bounded: small for every b.
    for e in by_id["runs"][0]["energy_error_max"].as_array().unwrap() {
        assert!(e.as_f64().unwrap() < 1e-2, "{e}");
    }
}

#[tokio::test]
async fn a_sweep_with_a_section_carries_each_cells_points() {
    let server = start(config()).await;
    let mut body = damped_pendulum_sweep();
    body["section"] = json!({"where": "q", "direction": "down", "max_points": 3});
    let (status, doc) = post_json(&server, "/api/v1/studies/sweep", &body).await;
    assert_eq!(status, 200, "{doc}");
    for run in doc["runs"].as_array().unwrap() {
        let sections = run["sections"].as_array().expect("sections per cell");
        assert_eq!(sections.len(), doc["cells"].as_u64().unwrap() as usize);
        let mut full = 0;
        for section in sections {
            let points = &section["points"];
            let t = points["t"].as_array().unwrap();
            assert!(t.len() <= 3, "{section}");
            // Lightly damped swings cross more often than the cap, which truncates them.
            if t.len() == 3 {
                full += 1;
                assert_eq!(section["truncated"], true, "{section}");
            }
            for q in points["q"].as_array().unwrap() {
                assert!(q[0].as_f64().unwrap().abs() <= 1e-13, "{section}");
            }
            for p in points["p"].as_array().unwrap() {
                assert!(p[0].as_f64().unwrap() < 0.0, "down: {section}");
            }
        }
        assert!(full > 0, "{}", run["method"]);
    }
    // Without a section, no such column.
    let (_, plain) = post_json(&server, "/api/v1/studies/sweep", &damped_pendulum_sweep()).await;
    assert!(plain["runs"][0].get("sections").is_none());
}

#[tokio::test]
async fn refusals_name_their_field() {
    let server = start(config()).await;
    let cases = [
        (
            json!({"axes": [{"name": "params.gamma", "min": 0, "max": 1, "n": 500}]}),
            "axes[0].n",
        ),
        (
            json!({"axes": [{"name": "p0[3]", "min": 0, "max": 1, "n": 5}]}),
            "p0",
        ),
        (json!({"charts": ["polar"]}), "charts[0]"),
        (json!({"every": 0}), "every"),
        (json!({"energy_reference": "exactly"}), "energy_reference"),
        (json!({"t_end": 1e9}), "t_end"),
        (json!({"section": {"where": "x +* 2"}}), "section.where"),
        (
            json!({"section": {"where": "q", "max_points": 0}}),
            "section.max_points",
        ),
        (
            json!({"section": {"where": "q", "bogus": 1}}),
            "section.bogus",
        ),
        // The points of every cell count against the sample limit.
        (
            json!({"section": {"where": "q", "max_points": 1000000}}),
            "section.max_points",
        ),
    ];
    for (change, field) in cases {
        let mut body = damped_pendulum_sweep();
        for (k, v) in change.as_object().unwrap() {
            body[k] = v.clone();
        }
        let (status, error) = post_json(&server, "/api/v1/studies/sweep", &body).await;
        assert_eq!(status, 422, "{field}: {error}");
        assert_eq!(error["error"]["field"], field, "{error}");
    }
}

fn geomint(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_geomint"));
    command.args(args);
    for var in [
        "SLURM_ARRAY_TASK_ID",
        "SLURM_ARRAY_TASK_MIN",
        "SLURM_ARRAY_TASK_COUNT",
        "JOB_COMPLETION_INDEX",
        "GEOMINT_SHARDS",
    ] {
        command.env_remove(var);
    }
    command.envs(env.iter().copied()).output().unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let dir = server::scratch_dir(&format!("sweep-cli-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn read(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn array_tasks_merge_to_the_local_sweep_bit_for_bit() {
    let dir = scratch("arrays");
    let spec = dir.join("spec.json");
    std::fs::write(&spec, serde_json::to_vec(&damped_pendulum_sweep()).unwrap()).unwrap();
    let whole = dir.join("whole.json");
    let out = geomint(&["study", "sweep", path(&spec), "-o", path(&whole)], &[]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let local = numbers(read(&whole));

    // deploy/sweep.slurm as the tasks of `sbatch --array=1-4` run it (SLURM_ARRAY_TASK_MIN = 1),
    // with this build's geomint first on the PATH.
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/sweep.slurm");
    let bin = Path::new(env!("CARGO_BIN_EXE_geomint")).parent().unwrap();
    let search = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let slurm: Vec<PathBuf> = (1..=4)
        .map(|task| {
            let id = task.to_string();
            let out = Command::new("bash")
                .arg(&script)
                .arg(&spec)
                .current_dir(&dir)
                .env("PATH", &search)
                .env("SLURM_ARRAY_TASK_ID", &id)
                .env("SLURM_ARRAY_TASK_MIN", "1")
                .env("SLURM_ARRAY_TASK_COUNT", "4")
                .env("SLURM_CPUS_PER_TASK", "2")
                .env_remove("JOB_COMPLETION_INDEX")
                .env_remove("GEOMINT_SHARDS")
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            dir.join(format!("parts/part-{task}.json"))
        })
        .collect();
    // The Indexed Job of deploy/sweep-job.yaml: its command with the index Kubernetes sets.
    let manifest = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("deploy/sweep-job.yaml"),
    )
    .unwrap();
    assert!(manifest.contains(
        r#"command: ["geomint", "study", "sweep", "/spec/spec.json", "--shard", "auto","#
    ));
    assert!(manifest.contains("completions: 16") && manifest.contains("value: \"16\""));
    let k8s: Vec<PathBuf> = (0..3)
        .map(|index| {
            let part = dir.join(format!("k8s-{index}.json"));
            let index = index.to_string();
            let env = [
                ("JOB_COMPLETION_INDEX", index.as_str()),
                ("GEOMINT_SHARDS", "3"),
            ];
            let out = geomint(
                &[
                    "study",
                    "sweep",
                    path(&spec),
                    "--shard",
                    "auto",
                    "-o",
                    path(&part),
                ],
                &env,
            );
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            part
        })
        .collect();
    for parts in [&slurm, &k8s] {
        let merged = dir.join("merged.json");
        let mut args = vec!["study", "merge"];
        args.extend(parts.iter().rev().map(|p| path(p)));
        args.extend(["-o", path(&merged)]);
        let out = geomint(&args, &[]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(numbers(read(&merged)), local);
    }

    // Refused: a missing shard, a shard twice, parts of two splits, a part of another sweep.
    let refused = |parts: &[&PathBuf], says: &str| {
        let mut args = vec!["study", "merge"];
        args.extend(parts.iter().map(|p| path(p)));
        let out = geomint(&args, &[]);
        assert_eq!(out.status.code(), Some(2));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(says), "{stderr}");
    };
    refused(
        &[&slurm[0], &slurm[1], &slurm[3]],
        "missing shards [2] of 4",
    );
    refused(
        &[&slurm[0], &slurm[1], &slurm[2], &slurm[3], &slurm[1]],
        "shard 1 is also in",
    );
    refused(&[&slurm[0], &k8s[1]], "shards of 4");
    let mut other = damped_pendulum_sweep();
    other["t_end"] = json!(21);
    let other_spec = dir.join("other.json");
    std::fs::write(&other_spec, serde_json::to_vec(&other).unwrap()).unwrap();
    let foreign = dir.join("foreign.json");
    let out = geomint(
        &[
            "study",
            "sweep",
            path(&other_spec),
            "--shard",
            "1/4",
            "-o",
            path(&foreign),
        ],
        &[],
    );
    assert!(out.status.success());
    refused(
        &[&slurm[0], &foreign, &slurm[2], &slurm[3]],
        "belongs to another study",
    );

    // Bad shard designations.
    for (shard, env, says) in [
        ("4/4", vec![], "is not a shard"),
        (
            "auto",
            vec![],
            "SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX",
        ),
        (
            "auto",
            vec![("JOB_COMPLETION_INDEX", "0")],
            "number of shards",
        ),
        ("0/100", vec![], "100 shards for 15 cells"),
    ] {
        let out = geomint(&["study", "sweep", path(&spec), "--shard", shard], &env);
        assert_eq!(out.status.code(), Some(2));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(says), "{shard}: {stderr}");
    }
}

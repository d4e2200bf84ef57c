//! Work past the request's time limit, over real HTTP: every route answers 200 with what it
//! finished, marked `time_limit`, never a 5xx (the time limit depends on the machine's load, so a
//! loaded machine meets it sooner). What finished is bit for bit what a run without the limit
//! gives; what did not is marked and `null`.
//!
//! - simulate: a reference run that uses up the time leaves the methods none (they stop at their
//!   first sample, without energy errors);
//! - sweeps and energy maps: the cells finished in time, the others listed in `unfinished_cells`;
//! - stability maps: the methods' maps made in time;
//! - convergence and work–precision: a reference run stopped by the limit is named so, and every
//!   setting is `time_limit`.

use std::time::Duration;

use crate::server;

use geomint::http::Config;
use serde_json::{json, Value};
use server::{post_json, post_ndjson, start};

/// One test at a time: they share the process's thread pool, and a test whose cells wait behind
/// another's would finish none before its limit (still correct, but nothing left to compare).
static ONE_AT_A_TIME: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());

fn config(request_timeout: Duration) -> Config {
    Config {
        request_timeout,
        ..Config::default()
    }
}

/// The server with the short limit, and one with room to finish.
async fn servers(limit: Duration) -> (server::Server, server::Server) {
    (
        start(config(limit)).await,
        start(config(Duration::from_secs(120))).await,
    )
}

/// Posts `request` to `path` on a server whose time limit it passes: the 200 answer, marked
/// `time_limit`, and its unfinished cells (some).
async fn cut_short(server: &server::Server, path: &str, request: &Value) -> (Value, Vec<usize>) {
    let (status, doc) = post_json(server, path, request).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["stop"], "time_limit");
    let unfinished: Vec<usize> = doc["unfinished_cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_u64().unwrap() as usize)
        .collect();
    assert!(!unfinished.is_empty());
    (doc, unfinished)
}

/// Per-cell columns of `doc` at `cell`: every array member of `columns` whose length is `cells`.
fn cell_values(columns: &Value, cell: usize, cells: usize) -> Vec<(String, Value)> {
    let mut out = Vec::new();
    for (name, column) in columns.as_object().unwrap() {
        if name == "unfinished_cells" {
            continue;
        }
        match column {
            Value::Array(values) if values.len() == cells => {
                out.push((name.clone(), values[cell].clone()));
            }
            Value::Object(_) => out.extend(
                cell_values(column, cell, cells)
                    .into_iter()
                    .map(|(inner, v)| (format!("{name}.{inner}"), v)),
            ),
            _ => {}
        }
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sweep_past_the_time_limit_keeps_the_cells_it_finished() {
    let _serial = ONE_AT_A_TIME.lock().await;
    let (short, long) = servers(Duration::from_millis(300)).await;
    // 400 cells of 2·10⁵ steps each: seconds of work, far past 300 ms.
    let request = json!({
        "system": "pendulum", "methods": ["modin_3s"], "h": 0.001, "t_end": 200,
        "energy_reference": "initial",
        "axes": [
            {"name": "params.gamma", "min": 0.01, "max": 0.5, "n": 20},
            {"name": "q0[0]", "min": 0.1, "max": 2.0, "n": 20}
        ]
    });
    let (partial, unfinished) = cut_short(&short, "/api/v1/studies/sweep", &request).await;
    let (status, full) = post_json(&long, "/api/v1/studies/sweep", &request).await;
    assert_eq!(status, 200, "{full}");
    assert_eq!(full["stop"], "finished");
    assert_eq!(full["unfinished_cells"], json!([]));
    let run = &partial["runs"][0];
    let cells = 400;
    let mut finished = 0;
    for cell in 0..cells {
        if unfinished.contains(&cell) {
            assert_eq!(run["energy_error_l2"][cell], Value::Null);
            assert_eq!(run["steps"][cell], 0);
            assert!(run["errors"][cell].as_str().unwrap().contains("time limit"));
        } else {
            finished += 1;
            assert_eq!(
                cell_values(run, cell, cells),
                cell_values(&full["runs"][0], cell, cells),
                "cell {cell}"
            );
        }
    }
    println!("sweep: {finished} of {cells} cells finished within 300 ms");

    // The stream ends with the same kind of document, then `end`.
    let (status, _, lines) = post_ndjson(
        &short,
        "/api/v1/studies/sweep",
        "application/x-ndjson",
        &request,
    )
    .await;
    assert_eq!(status, 200);
    let result = lines.iter().find(|l| l["type"] == "result").unwrap();
    assert_eq!(result["stop"], "time_limit");
    assert_eq!(lines.last().unwrap()["type"], "end");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_energy_map_past_the_time_limit_keeps_the_cells_it_finished() {
    let _serial = ONE_AT_A_TIME.lock().await;
    let (short, long) = servers(Duration::from_millis(300)).await;
    // 441 cells × 2 charts × 2.5·10⁵ steps: 2.2·10⁸ steps, seconds of work even four cells at a
    // time in SIMD lanes (about 10 ns per step in release).
    let request = json!({"nx": 21, "ny": 21, "t_max": 50000});
    let (partial, unfinished) = cut_short(&short, "/api/v1/studies/energy-map", &request).await;
    println!(
        "energy map: {} of 441 cells finished within 300 ms",
        441 - unfinished.len()
    );
    let (status, full) = post_json(&long, "/api/v1/studies/energy-map", &request).await;
    assert_eq!(status, 200);
    assert_eq!(full["stop"], "finished");
    let cells = 441;
    for cell in 0..cells {
        let (got, want) = (
            cell_values(&partial, cell, cells),
            cell_values(&full, cell, cells),
        );
        if unfinished.contains(&cell) {
            for (name, value) in &got {
                match name.as_str() {
                    // Known before any step.
                    "energy" | "predicted_divergent" => {
                        assert_eq!(
                            Some(value),
                            want.iter().find(|w| &w.0 == name).map(|w| &w.1)
                        )
                    }
                    _ => assert_eq!(value, &Value::Null, "cell {cell}: {name}"),
                }
            }
        } else {
            assert_eq!(got, want, "cell {cell}");
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stability_maps_past_the_time_limit_keep_the_maps_made() {
    let _serial = ONE_AT_A_TIME.lock().await;
    // The limit (1 ms) is checked before each map, and passes during the first: a map of
    // 301 × 301 cells takes tens of milliseconds.
    let (short, long) = servers(Duration::from_millis(1)).await;
    let request = json!({
        "methods": ["csv1", "rk4", "csv2"],
        "omega": 1,
        "gamma": {"min": 0, "max": 2, "n": 301},
        "h": {"min": 0, "max": 3, "n": 301}
    });
    let (status, partial) = post_json(&short, "/api/v1/stability", &request).await;
    assert_eq!(status, 200, "{partial}");
    assert_eq!(partial["stop"], "time_limit");
    let made = partial["maps"].as_array().unwrap();
    assert!(made.len() < 3);
    let (status, full) = post_json(&long, "/api/v1/stability", &request).await;
    assert_eq!(status, 200);
    assert_eq!(full["stop"], "finished");
    assert_eq!(full["maps"].as_array().unwrap().len(), 3);
    for (i, map) in made.iter().enumerate() {
        assert_eq!(map, &full["maps"][i]);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_simulation_whose_reference_uses_up_the_time_answers_with_its_runs_stopped() {
    let _serial = ONE_AT_A_TIME.lock().await;
    let short = start(config(Duration::from_millis(200))).await;
    // The adaptive reference at 10⁻¹² over 10⁶ steps of the 3-D pendulum: many seconds.
    let request = json!({
        "system": "elastic_pendulum_3d", "methods": ["modin_3s", "rk4"], "h": 0.01,
        "t_end": 10000, "output": {"every": 1000}, "compare_to_reference": true
    });
    let (status, doc) = post_json(&short, "/api/v1/simulate", &request).await;
    assert_eq!(status, 200, "{doc}");
    for run in doc["runs"].as_array().unwrap() {
        assert_eq!(run["stop"]["reason"], "time_limit", "{run}");
        assert_eq!(run["stop"]["step"], 0);
        assert_eq!(run["t"], json!([0.0]));
        assert!(run.get("energy_error").is_none(), "{run}");
    }
    let (status, _, lines) =
        post_ndjson(&short, "/api/v1/simulate", "application/x-ndjson", &request).await;
    assert_eq!(status, 200);
    assert_eq!(lines[0]["type"], "header");
    let chunks: Vec<&Value> = lines.iter().filter(|l| l["type"] == "samples").collect();
    assert_eq!(chunks.len(), 2);
    assert!(
        chunks.iter().all(|c| c.get("energy_error").is_none()),
        "{chunks:?}"
    );
    let summaries: Vec<&Value> = lines.iter().filter(|l| l["type"] == "summary").collect();
    assert_eq!(summaries.len(), 2);
    assert!(summaries
        .iter()
        .all(|s| s["stop"]["reason"] == "time_limit"));
    assert_eq!(lines.last().unwrap()["type"], "end");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn settings_studies_whose_reference_uses_up_the_time_mark_every_setting() {
    let _serial = ONE_AT_A_TIME.lock().await;
    let short = start(config(Duration::from_millis(200))).await;
    // No exact solution: the default reference (DOP853 at 10⁻¹³) over t = 10⁶, seconds of work
    // (over t = 10⁵ it takes 0.2 to 0.6 s, too close to the limit to be sure to pass it).
    let convergence = json!({
        "system": "elastic_pendulum_3d", "params": {"epsilon": 0.0001}, "t_end": 1000000,
        "samples": 100,
        "methods": ["modin_3s"], "h": [0.2, 0.1]
    });
    let precision = json!({
        "system": "elastic_pendulum_3d", "params": {"epsilon": 0.0001}, "t_end": 1000000,
        "samples": 100,
        "runs": [{"method": "modin_3s", "h": [0.2, 0.1]}]
    });
    for (path, request) in [
        ("/api/v1/studies/convergence", convergence),
        ("/api/v1/studies/work-precision", precision),
    ] {
        let (status, doc) = post_json(&short, path, &request).await;
        assert_eq!(status, 200, "{path}: {doc}");
        let reference = doc["reference"].as_str().unwrap();
        assert!(
            reference.ends_with("stopped at the time limit"),
            "{reference}"
        );
        let points = doc["points"].as_array().unwrap();
        assert_eq!(points.len(), 2);
        for point in points {
            assert_eq!(point["stop"], "time_limit", "{path}: {point}");
            assert_eq!(point["steps"], 0, "{path}: {point}");
        }
    }
}

//! A recording made by the server, read by Rerun's Python SDK (`rerun-sdk` 0.33.x) through
//! `tests/rrd_check.py`. Runs when `GEOMINT_PYTHON` names a Python with `rerun-sdk` installed,
//! for example a virtual environment's `bin/python`; otherwise it prints a notice and passes.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;
use std::time::Duration;

use geomint::http::{app, AppState, Config};
use serde_json::{json, Value};

use crate::server;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_rerun_sdk_reads_a_server_recording() {
    let Some(python) = std::env::var_os("GEOMINT_PYTHON") else {
        println!(
            "notice: GEOMINT_PYTHON is not set; skipping the rerun-sdk check of recordings \
             (set it to a Python with `pip install 'rerun-sdk==0.33.*'`)"
        );
        return;
    };
    let dir = server::scratch_dir("rrd-python");
    let _ = std::fs::remove_dir_all(&dir);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let state = AppState::new(Config {
        request_timeout: Duration::from_secs(15),
        data_dir: dir.clone(),
        ..Config::default()
    });
    tokio::spawn(async move {
        axum::serve(listener, app(state)).await.unwrap();
    });
    let c = reqwest::Client::builder().no_proxy().build().unwrap();
    let base = format!("http://{addr}");
    // Two methods, one of them with a label that is not a plain entity name; 10 s in steps of
    // 0.01 sampled every 4 steps: 251 samples, and 251 path rows.
    let body = json!({"system": "elastic_pendulum_3d", "params": {"epsilon": 0.1},
        "methods": ["modin_3s", {"id": "modin_rks", "inner": "rk4"}],
        "h": 0.01, "t_end": 10, "output": {"every": 4}});
    let created: Value = c
        .post(format!("{base}/api/v1/recordings"))
        .json(&body)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let rrd = c
        .get(format!("{base}{}", created["url"].as_str().unwrap()))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let answer = c
        .post(format!("{base}/api/v1/simulate"))
        .json(&body)
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();

    let samples = 251;
    let mut rows = BTreeMap::new();
    rows.insert("/".to_string(), 0);
    rows.insert("/spec".to_string(), 0);
    let mut energy = BTreeMap::new();
    for (i, m) in ["modin_3s", "modin_rks_rk4"].iter().enumerate() {
        for e in ["energy", "invariants/J3", "world/bodies", "world/path"] {
            rows.insert(format!("/{m}/{e}"), samples);
        }
        for dof in 0..3 {
            rows.insert(format!("/{m}/phase/{dof}/point"), samples);
            rows.insert(format!("/{m}/phase/{dof}/path"), samples);
        }
        rows.insert(format!("/{m}/force_evaluations"), 1);
        energy.insert(format!("/{m}/energy"), i);
    }
    let expected = json!({"application_id": "geomint", "rows": rows, "energy": energy});
    let rrd_path = dir.join("server.rrd");
    let expected_path = dir.join("expected.json");
    let answer_path = dir.join("answer.json");
    std::fs::write(&rrd_path, &rrd).unwrap();
    std::fs::write(&answer_path, &answer).unwrap();
    std::fs::write(&expected_path, serde_json::to_vec(&expected).unwrap()).unwrap();

    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/service/rrd_check.py");
    let out = Command::new(python)
        .arg(&script)
        .arg(&rrd_path)
        .arg(&expected_path)
        .arg(&answer_path)
        .output()
        .expect("GEOMINT_PYTHON runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "rrd_check.py failed:\n{stdout}");
    assert!(stdout.contains("/modin_rks_rk4/energy energies equal (251)"));
    assert!(stdout.contains(&format!("/modin_3s/phase/2/path rows={samples}")));
    let _ = std::fs::remove_dir_all(&dir);
}

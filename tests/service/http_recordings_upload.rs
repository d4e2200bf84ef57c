//! The recordings library over real HTTP, beyond what `http_recordings.rs` covers: `.rrd`
//! uploads (`POST /api/v1/recordings` with `application/octet-stream`) stored, listed and served
//! back byte for byte, with range requests; refused uploads (cut short, corrupted in the middle,
//! not Rerun at all, of a newer Rerun, empty, over the size cap with and without a declared
//! length) leaving the library untouched; and a stored recording's samples read back
//! (`GET /api/v1/recordings/{id}/samples`), compared with the JSON answer of the same request and
//! with Rerun's own decoder.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::decoded;
use crate::server;
use decoded::Decoded;

use geomint::core::simulation::Limits;
use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, start, Server};

/// A scratch data directory of this test process.
fn data_dir(name: &str) -> PathBuf {
    let dir = server::scratch_dir(&format!("uploads-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn config(dir: &Path, max_bytes: u64) -> Config {
    Config {
        request_timeout: Duration::from_secs(15),
        data_dir: dir.to_path_buf(),
        recordings_max_bytes: max_bytes,
        ..Config::default()
    }
}

fn pendulum() -> Value {
    json!({"system": "pendulum", "params": {"epsilon": 0.01}, "methods": ["modin_3s", "heun"],
        "h": 0.1, "t_end": 100, "output": {"every": 10}})
}

/// The recording of `body`, as `POST /api/v1/simulate?format=rrd` answers it.
async fn rrd_of(server: &Server, body: &Value) -> Vec<u8> {
    let response = client()
        .post(server.url("/api/v1/simulate?format=rrd"))
        .json(body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    response.bytes().await.unwrap().to_vec()
}

/// The JSON answer of `POST /api/v1/simulate` for `body`.
async fn json_of(server: &Server, body: &Value) -> Value {
    let (status, doc) = server::post_json(server, "/api/v1/simulate", body).await;
    assert_eq!(status, 200, "{doc}");
    doc
}

/// Uploads `body` (a reqwest body) as an `.rrd` file: the status and the JSON answer.
async fn upload(server: &Server, body: impl Into<reqwest::Body>) -> (u16, Value) {
    let response = client()
        .post(server.url("/api/v1/recordings"))
        .header("content-type", "application/octet-stream")
        .body(body)
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    (status, response.json().await.unwrap())
}

async fn get_json(server: &Server, path: &str) -> (u16, Value) {
    let response = client().get(server.url(path)).send().await.unwrap();
    let status = response.status().as_u16();
    let bytes = response.bytes().await.unwrap();
    (status, geomint::api::json::parse_json(&bytes).unwrap())
}

/// The file names in the data directory, sorted.
fn files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn floats(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

fn rows(value: &Value) -> Vec<Vec<f64>> {
    value.as_array().unwrap().iter().map(floats).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_uploaded_recording_is_stored_listed_served_and_read_back() {
    let dir = data_dir("valid");
    let server = start(config(&dir, 1 << 30)).await;
    let rrd = rrd_of(&server, &pendulum()).await;
    assert!(rrd.len() > 10_000, "{} bytes", rrd.len());

    let (status, created) = upload(&server, rrd.clone()).await;
    assert_eq!(status, 201, "{created}");
    let id = created["id"].as_str().unwrap().to_string();
    assert_eq!(created["bytes"], rrd.len() as u64);
    assert_eq!(created["url"], format!("/api/v1/recordings/{id}.rrd"));

    // Listed, with what the recording holds read from its own /spec.
    let (_, list) = get_json(&server, "/api/v1/recordings").await;
    assert_eq!(list.as_array().unwrap().len(), 1);
    let entry = &list[0];
    assert_eq!(entry["id"], id);
    assert_eq!(entry["origin"], "upload");
    assert_eq!(entry["application_id"], "geomint");
    assert_eq!(entry["spec"]["system"], "pendulum");
    assert_eq!(entry["spec"]["methods"], json!(["modin_3s", "heun"]));
    assert_eq!(entry["spec"]["h"], 0.1);
    assert_eq!(entry["spec"]["t_end"], 100.0);
    assert_eq!(entry["spec"]["samples_per_method"], 101);
    assert_eq!(files(&dir), [format!("{id}.json"), format!("{id}.rrd")]);

    // Served back byte for byte, with ranges.
    let url = server.url(&format!("/api/v1/recordings/{id}.rrd"));
    let whole = client().get(&url).send().await.unwrap();
    assert_eq!(whole.status(), 200);
    assert_eq!(whole.headers()["accept-ranges"], "bytes");
    assert_eq!(whole.headers()["content-type"], "application/octet-stream");
    assert_eq!(whole.bytes().await.unwrap().as_ref(), rrd.as_slice());
    let part = client()
        .get(&url)
        .header("range", "bytes=4-1027")
        .send()
        .await
        .unwrap();
    assert_eq!(part.status(), 206);
    assert_eq!(
        part.headers()["content-range"],
        format!("bytes 4-1027/{}", rrd.len()).as_str()
    );
    assert_eq!(part.bytes().await.unwrap().as_ref(), &rrd[4..1028]);
    let outside = client()
        .get(&url)
        .header("range", format!("bytes={}-", rrd.len() + 10))
        .send()
        .await
        .unwrap();
    assert_eq!(outside.status(), 416);

    // The samples, read back from the uploaded file: the JSON answer's energies bit for bit,
    // positions and momenta as the recording's f32 phase points, one row per recorded sample.
    let (status, samples) = get_json(&server, &format!("/api/v1/recordings/{id}/samples")).await;
    assert_eq!(status, 200, "{samples}");
    let answer = json_of(&server, &pendulum()).await;
    let decoded = Decoded::of(&rrd);
    // The request as recorded: the one sent, with its defaults written out.
    for key in ["system", "params", "methods", "h", "output"] {
        assert_eq!(samples["request"][key], pendulum()[key], "{key}");
    }
    assert_eq!(samples["request"]["t_end"], 100.0);
    assert_eq!(samples["system"], answer["system"]);
    assert_eq!(samples["schedule"], answer["schedule"]);
    for (k, m) in ["modin_3s", "heun"].iter().enumerate() {
        let (run, want) = (&samples["runs"][k], &answer["runs"][k]);
        assert_eq!(run["method"], *m);
        let energy = floats(&run["energy"]);
        assert_eq!(energy.len(), decoded.rows(&format!("/{m}/energy")));
        assert_eq!(energy.len(), 101);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&energy), bits(&floats(&want["energy"])), "{m} energy");
        for (a, b) in floats(&run["t"]).iter().zip(floats(&want["t"])) {
            assert!((a - b).abs() <= 1e-9, "{m} t: {a} against {b}");
        }
        for key in ["q", "p"] {
            let (got, exact) = (rows(&run[key]), rows(&want[key]));
            assert_eq!(got.len(), exact.len());
            for (g, e) in got.iter().zip(&exact) {
                assert_eq!(g, &vec![f64::from(e[0] as f32)], "{m} {key}");
            }
        }
        assert!(
            run.get("cartesian_q").is_none(),
            "the pendulum's world is its bob"
        );
        assert_eq!(run["last_step"], 1000);
        assert_eq!(run["force_evaluations"], want["stats"]["force_evaluations"]);
        let drift = run["dissipation_drift"].as_array().expect("a drift");
        assert_eq!(
            drift.len(),
            want["dissipation_drift"].as_array().unwrap().len()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Damages `valid` in a way the upload check must name.
fn damaged(valid: &[u8]) -> Vec<(&'static str, Vec<u8>, &'static str)> {
    let mut newer = valid.to_vec();
    newer[4..8].copy_from_slice(&[0, 34, 0, 0]);
    let mut middle = valid.to_vec();
    let n = middle.len();
    middle[n / 3..n / 2].fill(0);
    vec![
        ("cut short", valid[..valid.len() / 2].to_vec(), "cut short"),
        ("zeros in the middle", middle, "does not decode"),
        (
            "not Rerun",
            br#"{"system": "pendulum", "method": "heun"}"#.to_vec(),
            "not a Rerun recording (.rrd): the file starts with `{\"sy`",
        ),
        ("of a newer Rerun", newer, "written by Rerun 0.34.0"),
        ("empty", Vec::new(), "the body is empty"),
        ("only a header", valid[..12].to_vec(), "cut short"),
    ]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refused_uploads_name_what_is_wrong_and_leave_the_library_alone() {
    let dir = data_dir("refused");
    let server = start(config(&dir, 1 << 30)).await;
    // One recording already in the library, which no refusal may touch.
    let (status, kept) = server::post_json(&server, "/api/v1/recordings", &pendulum()).await;
    assert_eq!(status, 201, "{kept}");
    let kept_id = kept["id"].as_str().unwrap().to_string();
    let kept_bytes = std::fs::read(dir.join(format!("{kept_id}.rrd"))).unwrap();
    let (_, list_before) = get_json(&server, "/api/v1/recordings").await;
    let files_before = files(&dir);

    let valid = rrd_of(&server, &pendulum()).await;
    for (what, bytes, message) in damaged(&valid) {
        let (status, error) = upload(&server, bytes).await;
        assert_eq!(status, 422, "{what}: {error}");
        assert_eq!(error["error"]["code"], "invalid_recording", "{what}");
        assert_eq!(error["error"]["field"], "body", "{what}");
        let text = error["error"]["message"].as_str().unwrap();
        assert!(text.contains(message), "{what}: {text}");
        assert_eq!(files(&dir), files_before, "{what} left a file");
    }

    // Over the size cap: declared (refused before the body is read) and streamed without a
    // length (refused once the cap is passed). The capped store has a directory of its own: on
    // this one it would evict the recording above to fit its cap.
    let small_dir = data_dir("refused-small");
    let small = start(config(&small_dir, valid.len() as u64 - 1)).await;
    let (status, error) = upload(&small, valid.clone()).await;
    assert_eq!(status, 413, "{error}");
    assert_eq!(error["error"]["code"], "payload_too_large");
    let text = error["error"]["message"].as_str().unwrap();
    assert!(
        text.contains(&format!("size cap of {} bytes", valid.len() - 1)),
        "{text}"
    );
    let pieces: Vec<Result<Vec<u8>, std::io::Error>> =
        valid.chunks(16 * 1024).map(|c| Ok(c.to_vec())).collect();
    let streamed = reqwest::Body::wrap_stream(futures_util::stream::iter(pieces));
    let (status, error) = upload(&small, streamed).await;
    assert_eq!(status, 413, "{error}");
    assert_eq!(error["error"]["code"], "payload_too_large");
    assert_eq!(
        files(&small_dir),
        Vec::<String>::new(),
        "an oversized upload left a file"
    );
    let _ = std::fs::remove_dir_all(&small_dir);

    // Neither a JSON request nor an .rrd: refused as before.
    let response = client()
        .post(server.url("/api/v1/recordings"))
        .header("content-type", "text/plain")
        .body("hello")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 415);

    let (_, list_after) = get_json(&server, "/api/v1/recordings").await;
    assert_eq!(list_after, list_before);
    assert_eq!(
        std::fs::read(dir.join(format!("{kept_id}.rrd"))).unwrap(),
        kept_bytes
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn samples_follow_the_chart_and_refuse_what_they_cannot_read() {
    let dir = data_dir("samples");
    let server = start(config(&dir, 1 << 30)).await;
    // A run in the polar chart: Cartesian positions from the world view (x, 0, −y).
    let polar = json!({"system": "elastic_pendulum_2d", "chart": "polar",
        "initial_coordinates": "cartesian", "q0": [0.6, 1.2], "p0": [0.1, -0.2],
        "methods": ["rk4", "symplectic_euler"], "h": 0.05, "t_end": 5.0, "output": {"every": 2}});
    let (status, created) = server::post_json(&server, "/api/v1/recordings", &polar).await;
    assert_eq!(status, 201, "{created}");
    let id = created["id"].as_str().unwrap();
    let (status, samples) = get_json(&server, &format!("/api/v1/recordings/{id}/samples")).await;
    assert_eq!(status, 200, "{samples}");
    let answer = json_of(&server, &polar).await;
    assert_eq!(samples["system"]["chart"], "polar");
    assert_eq!(samples["invariants"], answer["invariants"]);
    for k in 0..2 {
        let (run, want) = (&samples["runs"][k], &answer["runs"][k]);
        let (got, exact) = (rows(&run["cartesian_q"]), rows(&want["cartesian_q"]));
        assert_eq!(got.len(), 51);
        for (g, e) in got.iter().zip(&exact) {
            let single: Vec<f64> = e.iter().map(|x| f64::from(*x as f32)).collect();
            assert_eq!(g, &single);
        }
        let (got, exact) = (rows(&run["q"]), rows(&want["q"]));
        for (g, e) in got.iter().zip(&exact) {
            assert_eq!(g.len(), 2);
            assert_eq!(g[1], f64::from(e[1] as f32), "θ");
        }
        let invariants: BTreeMap<String, Value> =
            serde_json::from_value(run["invariants"].clone()).unwrap();
        let expected: BTreeMap<String, Value> =
            serde_json::from_value(want["invariants"].clone()).unwrap();
        assert_eq!(invariants, expected);
    }

    // A recording that is not a simulation (a stability study's), uploaded: stored without a
    // spec, viewable but not plottable.
    let stability = client()
        .post(server.url("/api/v1/stability?format=rrd"))
        .json(&json!({"methods": ["csv1"], "omega": 3.51,
            "gamma": {"min": 0, "max": 3.5, "n": 5}, "h": {"min": 0, "max": 1, "n": 5}}))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let (status, study) = upload(&server, stability.to_vec()).await;
    assert_eq!(status, 201, "{study}");
    let study_id = study["id"].as_str().unwrap();
    let (_, entry) = get_json(&server, &format!("/api/v1/recordings/{study_id}")).await;
    assert_eq!(entry["spec"], Value::Null);
    assert_eq!(entry["origin"], "upload");
    let (status, error) =
        get_json(&server, &format!("/api/v1/recordings/{study_id}/samples")).await;
    assert_eq!(status, 422, "{error}");
    assert_eq!(error["error"]["code"], "not_a_simulation");

    // More samples than the server's limit: refused with the numbers.
    let strict = start(Config {
        limits: Limits {
            max_samples: 100,
            ..Limits::default()
        },
        ..config(&dir, 1 << 30)
    })
    .await;
    let (status, error) = get_json(&strict, &format!("/api/v1/recordings/{id}/samples")).await;
    assert_eq!(status, 422, "{error}");
    assert_eq!(error["error"]["code"], "too_many_samples");
    let text = error["error"]["message"].as_str().unwrap();
    assert!(
        text.contains("holds 102 samples, more than the 100"),
        "{text}"
    );

    let (status, error) = get_json(
        &server,
        "/api/v1/recordings/0123456789abcdef0123456789abcdef/samples",
    )
    .await;
    assert_eq!(status, 404, "{error}");
    let _ = std::fs::remove_dir_all(&dir);
}

//! The recording routes over real HTTP: storing, listing, downloading (decoded with Rerun's own
//! decoder) and deleting recordings, `simulate?format=rrd`, strict ids against path traversal,
//! eviction under the size cap, a restart on the same directory, and torn or foreign files in
//! it.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use crate::decoded;
use crate::server;
use decoded::Decoded;

use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, get_json, start, Server};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// A scratch data directory of this test process.
fn data_dir(name: &str) -> PathBuf {
    let dir = server::scratch_dir(&format!("recordings-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn config(dir: &PathBuf, max_bytes: u64) -> Config {
    Config {
        request_timeout: Duration::from_secs(15),
        data_dir: dir.clone(),
        recordings_max_bytes: max_bytes,
        ..Config::default()
    }
}

fn spec(every: u64) -> Value {
    json!({"system": "pendulum", "params": {"epsilon": 0.01}, "methods": ["modin_3s", "heun"],
        "h": 0.1, "t_end": 100, "output": {"every": every}})
}

async fn create(server: &Server, body: &Value) -> (u16, Value) {
    let response = client()
        .post(server.url("/api/v1/recordings"))
        .json(body)
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    (status, response.json().await.unwrap())
}

async fn list(server: &Server) -> Vec<Value> {
    client()
        .get(server.url("/api/v1/recordings"))
        .send()
        .await
        .unwrap()
        .json::<Value>()
        .await
        .unwrap()
        .as_array()
        .unwrap()
        .clone()
}

fn ids(entries: &[Value]) -> Vec<String> {
    entries
        .iter()
        .map(|e| e["id"].as_str().unwrap().to_string())
        .collect()
}

/// Temporal energy rows per method entity, decoded with `re_log_encoding`, in step order.
fn energies(rrd: &[u8]) -> BTreeMap<String, Vec<f64>> {
    let d = Decoded::of(rrd);
    d.chunks
        .keys()
        .filter(|path| path.ends_with("/energy"))
        .map(|path| {
            (
                path.clone(),
                d.scalars(path).into_iter().map(|r| r.1).collect(),
            )
        })
        .collect()
}

/// The answer's `"energy":[...]` text of each run, as the JSON answer carries it.
async fn json_energies(server: &Server, body: &Value) -> Vec<String> {
    let text = client()
        .post(server.url("/api/v1/simulate"))
        .json(body)
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    let doc: Value = serde_json::from_str(&text).unwrap();
    doc["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|run| {
            let n = run["energy"].as_array().unwrap().len();
            // Cut the exact text out of the answer: the array after `"energy":`.
            let start = text
                .find(&format!(
                    "\"method\":\"{}\"",
                    run["method"].as_str().unwrap()
                ))
                .unwrap();
            let from = start + text[start..].find("\"energy\":").unwrap() + "\"energy\":".len();
            let to = from + text[from..].find(']').unwrap() + 1;
            let array = text[from..to].to_string();
            assert_eq!(array.matches(',').count() + 1, n);
            array
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn store_list_download_and_delete() {
    let dir = data_dir("crud");
    let server = start(config(&dir, 1 << 30)).await;
    let c = client();
    let body = spec(10);
    let (status, created) = create(&server, &body).await;
    assert_eq!(status, 201, "{created}");
    let id = created["id"].as_str().unwrap().to_string();
    assert_eq!(id.len(), 32);
    assert_eq!(created["url"], format!("/api/v1/recordings/{id}.rrd"));

    let entries = list(&server).await;
    assert_eq!(ids(&entries), [id.clone()]);
    let entry = &entries[0];
    assert_eq!(entry["bytes"], created["bytes"]);
    assert_eq!(entry["spec"]["system"], "pendulum");
    assert_eq!(entry["spec"]["methods"], json!(["modin_3s", "heun"]));
    assert_eq!(entry["spec"]["samples_per_method"], 101);
    assert!(entry["created"].as_str().unwrap().ends_with('Z'));

    // The file: an attachment of the stated size, decoding to the JSON answer's energies.
    let response = c
        .get(server.url(created["url"].as_str().unwrap()))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    let headers = response.headers().clone();
    assert_eq!(headers["content-type"], "application/octet-stream");
    assert_eq!(
        headers["content-disposition"],
        format!("attachment; filename=\"geomint-{id}.rrd\"").as_str()
    );
    let rrd = response.bytes().await.unwrap();
    assert_eq!(rrd.len() as u64, created["bytes"].as_u64().unwrap());
    assert_eq!(
        std::fs::metadata(dir.join(format!("{id}.rrd")))
            .unwrap()
            .len(),
        rrd.len() as u64
    );
    let decoded = energies(&rrd);
    assert_eq!(
        decoded.keys().collect::<Vec<_>>(),
        ["/heun/energy", "/modin_3s/energy"]
    );
    let expected = json_energies(&server, &body).await;
    assert_eq!(
        serde_json::to_string(&decoded["/modin_3s/energy"]).unwrap(),
        expected[0]
    );
    assert_eq!(
        serde_json::to_string(&decoded["/heun/energy"]).unwrap(),
        expected[1]
    );
    // The entry alone, as JSON.
    let one = get_json(&server, &format!("/api/v1/recordings/{id}")).await;
    assert_eq!(one, entries[0]);

    // Deleted: gone from the list, the file and the disk; a second delete is 404.
    let url = server.url(&format!("/api/v1/recordings/{id}"));
    assert_eq!(c.delete(&url).send().await.unwrap().status(), 204);
    assert!(list(&server).await.is_empty());
    assert!(!dir.join(format!("{id}.rrd")).exists());
    assert!(!dir.join(format!("{id}.json")).exists());
    let again = c.delete(&url).send().await.unwrap();
    assert_eq!(again.status(), 404);
    let error: Value = again.json().await.unwrap();
    assert_eq!(error["error"]["code"], "not_found");
    let download = c.get(format!("{url}.rrd")).send().await.unwrap();
    assert_eq!(download.status(), 404);

    // Bad input names the field, as for simulate; nothing is stored.
    let (status, error) = create(
        &server,
        &json!({"system": "pendulum", "method": "heun",
        "h": -0.1, "t_end": 10}),
    )
    .await;
    assert_eq!(status, 422);
    assert_eq!(error["error"]["field"], "h");
    assert!(list(&server).await.is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulate_answers_a_recording_with_format_rrd() {
    let dir = data_dir("format");
    let server = start(config(&dir, 1 << 30)).await;
    let c = client();
    let body = spec(5);
    let response = c
        .post(server.url("/api/v1/simulate?format=rrd"))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 200);
    assert_eq!(
        response.headers()["content-type"],
        "application/octet-stream"
    );
    assert!(response.headers()["content-disposition"]
        .to_str()
        .unwrap()
        .starts_with("attachment"));
    let rrd = response.bytes().await.unwrap();
    let decoded = energies(&rrd);
    assert_eq!(decoded["/modin_3s/energy"].len(), 201);
    let expected = json_energies(&server, &body).await;
    assert_eq!(
        serde_json::to_string(&decoded["/heun/energy"]).unwrap(),
        expected[1]
    );
    // Nothing is stored by simulate.
    assert!(list(&server).await.is_empty());

    let response = c
        .post(server.url("/api/v1/simulate?format=xml"))
        .json(&body)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 422);
    let error: Value = response.json().await.unwrap();
    assert_eq!(error["error"]["field"], "format");
}

/// Sends a raw request line (no URL normalisation on the way) and returns the status code.
async fn raw_status(server: &Server, method: &str, target: &str) -> u16 {
    let mut stream = tokio::net::TcpStream::connect(server.addr).await.unwrap();
    let request =
        format!("{method} {target} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n");
    stream.write_all(request.as_bytes()).await.unwrap();
    let mut answer = Vec::new();
    stream.read_to_end(&mut answer).await.unwrap();
    let text = String::from_utf8_lossy(&answer);
    text.split_whitespace().nth(1).unwrap().parse().unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ids_are_strict_and_paths_never_leave_the_directory() {
    let dir = data_dir("ids");
    let server = start(config(&dir, 1 << 30)).await;
    let (_, created) = create(&server, &spec(10)).await;
    let id = created["id"].as_str().unwrap().to_string();
    // A file beside the data directory that a traversal would reach.
    std::fs::write(dir.join("../secret.rrd"), b"secret").unwrap();
    std::fs::write(dir.join("notes.rrd"), b"not a recording").unwrap();

    let upper = id.to_uppercase();
    let short = &id[..31];
    let missing = "0123456789abcdef0123456789abcdef";
    for target in [
        "/api/v1/recordings/..%2F..%2Fetc%2Fpasswd".to_string(),
        "/api/v1/recordings/..%2F..%2Fetc%2Fpasswd.rrd".to_string(),
        "/api/v1/recordings/..%2Fsecret.rrd".to_string(),
        "/api/v1/recordings/../x".to_string(),
        "/api/v1/recordings/notes.rrd".to_string(),
        format!("/api/v1/recordings/{upper}.rrd"),
        format!("/api/v1/recordings/{short}.rrd"),
        format!("/api/v1/recordings/{missing}.rrd"),
        format!("/api/v1/recordings/{missing}"),
        format!("/api/v1/recordings/{id}.json"),
        format!("/api/v1/recordings/{id}.rrd.rrd"),
    ] {
        let status = raw_status(&server, "GET", &target).await;
        assert!(status == 404 || status == 400, "GET {target}: {status}");
        let status = raw_status(&server, "DELETE", &target).await;
        assert!(
            status == 404 || status == 400 || status == 405,
            "DELETE {target}: {status}"
        );
    }
    // Nothing was deleted, and the real id still answers.
    assert_eq!(ids(&list(&server).await), [id.clone()]);
    assert!(dir.join("../secret.rrd").exists());
    assert_eq!(
        raw_status(&server, "GET", &format!("/api/v1/recordings/{id}.rrd")).await,
        200
    );
    let _ = std::fs::remove_file(dir.join("../secret.rrd"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_cap_evicts_the_oldest_and_a_restart_keeps_the_rest() {
    let dir = data_dir("cap");
    // One recording to learn the size of one (they are all alike but for ids and times).
    let server = start(config(&dir, 1 << 30)).await;
    let (_, first) = create(&server, &spec(10)).await;
    let size = first["bytes"].as_u64().unwrap();
    assert!(size > 1000, "{size}");

    // Room for two and a half: the third evicts the first, the fourth the second.
    let cap = size * 5 / 2;
    let server = start(config(&dir, cap)).await;
    assert_eq!(ids(&list(&server).await), [first["id"].as_str().unwrap()]);
    let mut created = vec![first["id"].as_str().unwrap().to_string()];
    for _ in 0..3 {
        let (status, answer) = create(&server, &spec(10)).await;
        assert_eq!(status, 201, "{answer}");
        created.push(answer["id"].as_str().unwrap().to_string());
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let kept = ids(&list(&server).await);
    // Newest first.
    assert_eq!(kept, [created[3].clone(), created[2].clone()]);
    assert!(server.state.recordings.total_bytes() <= cap);
    for old in &created[..2] {
        assert!(!dir.join(format!("{old}.rrd")).exists(), "{old} evicted");
        let status = raw_status(&server, "GET", &format!("/api/v1/recordings/{old}.rrd")).await;
        assert_eq!(status, 404);
    }

    // A recording larger than the whole cap is refused, naming the knob.
    let tiny = start(config(&data_dir("tiny"), size / 2)).await;
    let (status, error) = create(&tiny, &spec(10)).await;
    assert_eq!(status, 507, "{error}");
    assert_eq!(error["error"]["code"], "recording_too_large");
    assert_eq!(error["error"]["field"], "output.every");
    assert!(list(&tiny).await.is_empty());
    assert_eq!(
        std::fs::read_dir(tiny.state.config.data_dir.clone())
            .unwrap()
            .count(),
        0
    );

    // A restart on the same directory keeps the list; torn and foreign files are skipped.
    let torn = "00000000000000000000000000000001";
    std::fs::copy(
        dir.join(format!("{}.json", created[3])),
        dir.join(format!("{torn}.json")),
    )
    .unwrap();
    let sidecar = std::fs::read_to_string(dir.join(format!("{torn}.json"))).unwrap();
    std::fs::write(
        dir.join(format!("{torn}.json")),
        sidecar.replace(&created[3], torn),
    )
    .unwrap();
    let full = std::fs::read(dir.join(format!("{}.rrd", created[3]))).unwrap();
    std::fs::write(dir.join(format!("{torn}.rrd")), &full[..full.len() / 2]).unwrap();
    // The right size but not an RRD stream.
    let foreign = "00000000000000000000000000000002";
    std::fs::write(
        dir.join(format!("{foreign}.json")),
        sidecar.replace(&created[3], foreign),
    )
    .unwrap();
    std::fs::write(dir.join(format!("{foreign}.rrd")), vec![0u8; full.len()]).unwrap();
    std::fs::write(
        dir.join("00000000000000000000000000000003.json"),
        b"{not json",
    )
    .unwrap();
    std::fs::write(dir.join("README.txt"), b"foreign").unwrap();
    std::fs::write(
        dir.join(".tmp-00000000000000000000000000000004.rrd"),
        b"half",
    )
    .unwrap();

    let restarted = start(config(&dir, cap)).await;
    assert_eq!(ids(&list(&restarted).await), kept);
    for skipped in [torn, foreign] {
        let status = raw_status(
            &restarted,
            "GET",
            &format!("/api/v1/recordings/{skipped}.rrd"),
        )
        .await;
        assert_eq!(status, 404, "{skipped}");
        // Skipped, not deleted.
        assert!(dir.join(format!("{skipped}.rrd")).exists());
    }
    assert!(!dir
        .join(".tmp-00000000000000000000000000000004.rrd")
        .exists());
    let rrd = client()
        .get(restarted.url(&format!("/api/v1/recordings/{}.rrd", kept[0])))
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    assert_eq!(energies(&rrd)["/heun/energy"].len(), 101);
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&tiny.state.config.data_dir);
}

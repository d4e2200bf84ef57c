//! Paths and files against the real server loop: paths cannot escape their directories, every
//! answer says nosniff with its own type, the container runs as a user without privileges, and the
//! static files come from memory with validators and follow edits.

use crate::http_reliability::{config, long_run, post, read_answer, small_run};
use crate::server;
use geomint::core::simulation::Limits;
use geomint::http::Config;
use serde_json::{json, Value};
use server::{client, start, Server};
use std::time::{Duration, Instant};
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn short_runs_pass_long_ones_and_long_ones_wait_their_turn() {
    let server = start(Config {
        max_concurrent: 1,
        short_lane: 1,
        long_queue_timeout: Duration::from_millis(600),
        limits: Limits {
            max_steps: 10_000_000_000,
            max_samples: 1_000_000,
        },
        ..config("lanes")
    })
    .await;
    // A long stream holds the only shared slot.
    let holder = client()
        .post(server.url("/api/v1/simulate"))
        .header("accept", "application/x-ndjson")
        .json(&long_run())
        .send()
        .await
        .unwrap();
    assert_eq!(holder.status(), 200);
    while server.state.runs_in_progress() == 0 {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    // Short runs go through the short lane.
    for _ in 0..10 {
        let response = post(&server, &small_run()).await;
        assert_eq!(response.status(), 200);
        let doc: Value = response.json().await.unwrap();
        assert_eq!(doc["runs"][0]["stop"]["reason"], "finished");
    }
    // A long run waits the long queue timeout, then 503 with Retry-After.
    let started = Instant::now();
    let refused = post(&server, &long_run()).await;
    assert_eq!(refused.status(), 503);
    assert_eq!(refused.headers()["retry-after"], "1");
    assert!(started.elapsed() >= Duration::from_millis(600));

    // One long request per client waits; a second one from the same client is refused at once
    // (it answers while the first still waits).
    let waiting = tokio::spawn({
        let url = server.url("/api/v1/simulate");
        async move {
            let body = json!({"system": "pendulum", "method": "modin_3s", "h": 1e-3,
                "t_end": 500, "output": {"every": 100000}});
            client().post(url).json(&body).send().await.unwrap()
        }
    });
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(post(&server, &long_run()).await.status(), 503);
    assert!(!waiting.is_finished(), "the first long request still waits");
    // The holder goes: the waiting long run gets the slot and is served.
    drop(holder);
    let served = waiting.await.unwrap();
    assert_eq!(served.status(), 200);
    let doc: Value = served.json().await.unwrap();
    assert_eq!(doc["runs"][0]["stop"]["reason"], "finished");
}

/// Sends `request_line` (exactly as written, no normalisation) and returns the answer.
async fn raw_get(server: &Server, target: &str) -> (u16, String) {
    let mut stream = TcpStream::connect(server.addr).await.unwrap();
    let request = format!("GET {target} HTTP/1.1\r\nHost: a\r\nConnection: close\r\n\r\n");
    stream.write_all(request.as_bytes()).await.unwrap();
    read_answer(&mut stream, Duration::from_secs(10))
        .await
        .unwrap_or((0, String::new()))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn paths_cannot_escape_their_directories() {
    let cfg = config("paths");
    let root = cfg.data_dir.parent().unwrap().to_path_buf();
    let site = root.join("site");
    std::fs::create_dir_all(&site).unwrap();
    std::fs::write(site.join("index.html"), "<!doctype html><p>page</p>").unwrap();
    std::fs::write(root.join("secret.txt"), "SECRET-MARKER").unwrap();
    std::fs::write(root.join("recordings.rrd"), "SECRET-MARKER").unwrap();
    std::fs::create_dir_all(&cfg.systems_dir).unwrap();
    std::fs::write(root.join("sys-0123456789abcdef.json"), "SECRET-MARKER").unwrap();
    let server = start(Config {
        static_dir: Some(site),
        ..cfg
    })
    .await;
    let (status, page) = raw_get(&server, "/index.html").await;
    assert_eq!(status, 200);
    assert!(page.contains("<p>page</p>"));
    for target in [
        "/../secret.txt",
        "/%2e%2e/secret.txt",
        "/%2E%2E%2Fsecret.txt",
        "/..%2fsecret.txt",
        "/%252e%252e/secret.txt",
        "/%252e%252e%252fsecret.txt",
        "/./../secret.txt",
        "/..%5csecret.txt",
        "/....//secret.txt",
        "//secret.txt",
        "/api/v1/recordings/..%2f..%2frecordings",
        "/api/v1/recordings/..%2frecordings.rrd",
        "/api/v1/recordings/%2e%2e/samples",
        "/api/v1/systems/..%2fsys-0123456789abcdef",
        "/api/v1/systems/..%2f..%2fsys-0123456789abcdef",
    ] {
        let (status, answer) = raw_get(&server, target).await;
        assert!((400..500).contains(&status), "{target}: {status} {answer}");
        assert!(!answer.contains("SECRET-MARKER"), "{target}: {answer}");
    }
    for target in [
        "/api/v1/recordings/..%2f..%2fsecret.txt",
        "/api/v1/systems/..%2f..%2fsys-0123456789abcdef",
    ] {
        let response = client().delete(server.url(target)).send().await.unwrap();
        assert_eq!(response.status(), 404, "{target}");
    }
    assert!(root.join("secret.txt").exists());
    assert!(root.join("sys-0123456789abcdef.json").exists());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_answer_says_nosniff_with_its_own_type() {
    let cfg = config("nosniff");
    let site = cfg.data_dir.parent().unwrap().join("site");
    std::fs::create_dir_all(&site).unwrap();
    std::fs::write(site.join("index.html"), "<!doctype html>").unwrap();
    let server = start(Config {
        static_dir: Some(site),
        ..cfg
    })
    .await;
    let c = client();
    let answers = [
        c.get(server.url("/index.html")).send().await.unwrap(),
        c.get(server.url("/api/v1/systems")).send().await.unwrap(),
        c.get(server.url("/nothing-here")).send().await.unwrap(),
        c.post(server.url("/api/v1/simulate"))
            .json(&small_run())
            .send()
            .await
            .unwrap(),
        c.post(server.url("/api/v1/simulate"))
            .header("accept", "application/x-ndjson")
            .json(&small_run())
            .send()
            .await
            .unwrap(),
        c.post(server.url("/api/v1/simulate?format=rrd"))
            .json(&small_run())
            .send()
            .await
            .unwrap(),
        c.post(server.url("/api/v1/simulate"))
            .body("not json")
            .header("content-type", "text/plain")
            .send()
            .await
            .unwrap(),
    ];
    let expected = [
        "text/html",
        "application/json",
        "application/json",
        "application/json",
        "application/x-ndjson",
        "application/octet-stream",
        "application/json",
    ];
    for (answer, expected) in answers.iter().zip(expected) {
        assert_eq!(
            answer.headers()["x-content-type-options"],
            "nosniff",
            "{}",
            answer.url()
        );
        let content_type = answer.headers()["content-type"].to_str().unwrap();
        assert!(
            content_type.starts_with(expected),
            "{}: {content_type}",
            answer.url()
        );
    }
}

#[test]
fn the_container_runs_as_a_user_without_privileges() {
    let dockerfile =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/Dockerfile")).unwrap();
    let user = dockerfile
        .lines()
        .filter_map(|l| l.trim().strip_prefix("USER "))
        .next_back()
        .expect("the Dockerfile sets a USER");
    let user = user.split(':').next().unwrap().trim();
    assert!(
        !["root", "0", ""].contains(&user),
        "the final stage runs as {user}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn static_files_come_from_memory_with_validators_and_follow_edits() {
    let cfg = config("assets");
    let site = cfg.data_dir.parent().unwrap().join("site");
    std::fs::create_dir_all(site.join("js")).unwrap();
    std::fs::write(site.join("index.html"), "<!doctype html><p>first</p>").unwrap();
    std::fs::write(site.join("js/app.js"), "export const answer = 42;").unwrap();
    // Past the in-memory limit: served from disk, whole.
    let big = vec![b'x'; 3 << 20];
    std::fs::write(site.join("big.bin"), &big).unwrap();
    let server = start(Config {
        static_dir: Some(site.clone()),
        ..cfg
    })
    .await;
    let c = client();
    let get = |path: &str| c.get(server.url(path));

    let page = get("/").send().await.unwrap();
    assert_eq!(page.status(), 200);
    assert_eq!(page.headers()["content-type"], "text/html");
    assert_eq!(page.headers()["cache-control"], "no-cache");
    assert_eq!(page.headers()["x-content-type-options"], "nosniff");
    let etag = page.headers()["etag"].to_str().unwrap().to_string();
    let modified = page.headers()["last-modified"]
        .to_str()
        .unwrap()
        .to_string();
    assert!(etag.starts_with('"') && etag.len() == 34, "{etag}");
    assert_eq!(page.text().await.unwrap(), "<!doctype html><p>first</p>");
    assert_eq!(
        get("/index.html").send().await.unwrap().headers()["etag"],
        etag.as_str()
    );

    // Validators: the same version is 304 without a body; another tag is the file again.
    for (name, value) in [
        ("if-none-match", etag.clone()),
        ("if-none-match", format!("\"other\", W/{etag}")),
        ("if-modified-since", modified.clone()),
    ] {
        let answer = get("/index.html")
            .header(name, &value)
            .send()
            .await
            .unwrap();
        assert_eq!(answer.status(), 304, "{name}: {value}");
        assert_eq!(answer.headers()["etag"], etag.as_str());
        assert!(answer.bytes().await.unwrap().is_empty());
    }
    let other = get("/index.html")
        .header("if-none-match", "\"other\"")
        .header("if-modified-since", &modified)
        .send()
        .await
        .unwrap();
    assert_eq!(
        other.status(),
        200,
        "If-None-Match decides over If-Modified-Since"
    );

    let head = c.head(server.url("/js/app.js")).send().await.unwrap();
    assert_eq!(head.status(), 200);
    assert_eq!(head.headers()["content-type"], "text/javascript");
    assert_eq!(head.headers()["content-length"], "25");
    assert!(head.bytes().await.unwrap().is_empty());
    let from_disk = get("/big.bin").send().await.unwrap();
    assert_eq!(from_disk.status(), 200);
    assert_eq!(from_disk.bytes().await.unwrap().len(), big.len());
    // A directory without its slash is redirected (by ServeDir); this one has no index.html.
    let folder = get("/js").send().await.unwrap();
    assert_eq!(folder.url().path(), "/js/");
    assert_eq!(folder.status(), 404);

    // An edit and a removal are noticed within a second or so.
    std::fs::write(
        site.join("index.html"),
        "<!doctype html><p>second, longer</p>",
    )
    .unwrap();
    std::fs::remove_file(site.join("js/app.js")).unwrap();
    tokio::time::sleep(Duration::from_millis(1200)).await;
    let page = get("/").send().await.unwrap();
    assert_ne!(page.headers()["etag"], etag.as_str());
    assert_eq!(
        page.text().await.unwrap(),
        "<!doctype html><p>second, longer</p>"
    );
    let answer = get("/index.html")
        .header("if-none-match", &etag)
        .send()
        .await
        .unwrap();
    assert_eq!(answer.status(), 200);
    assert_eq!(get("/js/app.js").send().await.unwrap().status(), 404);
}

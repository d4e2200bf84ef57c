//! Misbehaving clients and hostile paths against the real server loop, over raw TCP where a
//! well-behaved client library would not misbehave: connections that send nothing or their head
//! a byte at a time are closed after the header timeout, past the connection limit new ones wait,
//! a body that trickles in is answered 408, 100 MB bodies (with and without a length) are refused
//! with 413 and leave nothing behind, a client gone mid-body holds nothing; short runs are
//! served while long ones hold every shared slot, and long ones wait their turn; static files
//! and ids cannot name paths outside their directory; every answer says `nosniff`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use geomint::core::simulation::Limits;
use geomint::http::Config;
use serde_json::{json, Value};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use crate::server;
use server::{client, start, temporary_files, Server};

fn scratch(name: &str) -> PathBuf {
    let dir = server::scratch_dir(&format!("reliability-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn config(name: &str) -> Config {
    let dir = scratch(name);
    Config {
        data_dir: dir.join("recordings"),
        systems_dir: dir.join("systems"),
        static_dir: None,
        ..Config::default()
    }
}

fn small_run() -> Value {
    json!({"system": "pendulum", "method": "modin_3s", "h": 0.01, "t_end": 10,
        "output": {"every": 100}})
}

/// 10⁹ steps (about 10 s in this build): holds a slot far longer than any test waits, and goes
/// when its client does.
fn long_run() -> Value {
    json!({"system": "pendulum", "method": "modin_3s", "h": 1e-3, "t_end": 1e6,
        "output": {"every": 10000000}})
}

async fn post(server: &Server, body: &Value) -> reqwest::Response {
    client()
        .post(server.url("/api/v1/simulate"))
        .json(body)
        .send()
        .await
        .unwrap()
}

/// Reads an HTTP answer's status line and head, then as much of the body as comes within
/// `wait`; None when the connection closes (or is reset) before a status line.
async fn read_answer(stream: &mut TcpStream, wait: Duration) -> Option<(u16, String)> {
    let mut bytes = Vec::new();
    let mut buf = [0u8; 4096];
    let until = Instant::now() + wait;
    loop {
        let left = until.saturating_duration_since(Instant::now());
        match tokio::time::timeout(left, stream.read(&mut buf)).await {
            Ok(Ok(0)) | Ok(Err(_)) | Err(_) => break,
            Ok(Ok(n)) => bytes.extend_from_slice(&buf[..n]),
        }
        let text = String::from_utf8_lossy(&bytes);
        if let Some(head_end) = text.find("\r\n\r\n") {
            let length = text[..head_end]
                .lines()
                .find_map(|l| {
                    let (name, value) = l.split_once(':')?;
                    name.eq_ignore_ascii_case("content-length")
                        .then(|| value.trim().parse::<usize>().ok())?
                })
                .unwrap_or(0);
            if bytes.len() >= head_end + 4 + length {
                break;
            }
        }
    }
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let status = text.strip_prefix("HTTP/1.1 ")?.get(..3)?.parse().ok()?;
    Some((status, text))
}

/// Whether the server closed `stream` within `wait` (EOF or reset, after any answer).
async fn closed_within(stream: &mut TcpStream, wait: Duration) -> bool {
    let mut buf = [0u8; 1024];
    let until = Instant::now() + wait;
    loop {
        let left = until.saturating_duration_since(Instant::now());
        match tokio::time::timeout(left, stream.read(&mut buf)).await {
            Ok(Ok(0)) | Ok(Err(_)) => return true,
            Ok(Ok(_)) => continue,
            Err(_) => return false,
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn silent_and_slow_heads_are_cut_off_while_runs_go_on() {
    let server = start(Config {
        header_timeout: Duration::from_secs(1),
        ..config("heads")
    })
    .await;
    let mut attackers = Vec::new();
    for i in 0..300 {
        let mut stream = TcpStream::connect(server.addr).await.unwrap();
        if i % 2 == 1 {
            stream
                .write_all(b"POST /api/v1/simulate HTTP/1.1\r\nHost: a\r\nContent-Ty")
                .await
                .unwrap();
        }
        attackers.push(stream);
    }
    // One more sends its head a byte at a time, faster than any per-read timeout would notice.
    let trickler = {
        let mut stream = TcpStream::connect(server.addr).await.unwrap();
        tokio::spawn(async move {
            let head = b"GET /healthz HTTP/1.1\r\nHost: a\r\nX-Padding: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaa\r\n\r\n";
            for byte in head {
                if stream.write_all(&[*byte]).await.is_err() {
                    return true;
                }
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
            closed_within(&mut stream, Duration::from_millis(100)).await
        })
    };
    // Meanwhile other clients' runs are served.
    for _ in 0..20 {
        let response = post(&server, &small_run()).await;
        assert_eq!(response.status(), 200);
    }
    for (i, stream) in attackers.iter_mut().enumerate() {
        assert!(
            closed_within(stream, Duration::from_secs(5)).await,
            "connection {i} is still open"
        );
    }
    assert!(
        trickler.await.unwrap(),
        "a head sent a byte at a time was not cut off"
    );
    assert_eq!(post(&server, &small_run()).await.status(), 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn past_the_connection_limit_new_clients_wait_for_a_free_one() {
    let server = start(Config {
        header_timeout: Duration::from_secs(2),
        max_connections: 8,
        ..config("limit")
    })
    .await;
    let mut idle = Vec::new();
    for _ in 0..8 {
        idle.push(TcpStream::connect(server.addr).await.unwrap());
    }
    let mut waiting = TcpStream::connect(server.addr).await.unwrap();
    waiting
        .write_all(b"GET /healthz HTTP/1.1\r\nHost: a\r\nConnection: close\r\n\r\n")
        .await
        .unwrap();
    // Not served while the eight hold every connection...
    assert!(read_answer(&mut waiting, Duration::from_millis(500))
        .await
        .is_none());
    // ...and served once the header timeout has closed them.
    let (status, _) = read_answer(&mut waiting, Duration::from_secs(10))
        .await
        .expect("an answer after the idle connections were closed");
    assert_eq!(status, 200);
    drop(idle);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_body_that_trickles_in_is_answered_408_and_leaves_nothing() {
    let cfg = Config {
        body_timeout: Duration::from_secs(1),
        ..config("trickle")
    };
    let data_dir = cfg.data_dir.clone();
    let server = start(cfg).await;
    for (path, content_type) in [
        ("/api/v1/simulate", "application/json"),
        ("/api/v1/recordings", "application/octet-stream"),
    ] {
        let mut stream = TcpStream::connect(server.addr).await.unwrap();
        let head = format!(
            "POST {path} HTTP/1.1\r\nHost: a\r\nContent-Type: {content_type}\r\nContent-Length: 1000\r\n\r\n"
        );
        stream.write_all(head.as_bytes()).await.unwrap();
        let (mut reader, mut writer) = stream.into_split();
        let trickle = tokio::spawn(async move {
            for _ in 0..100 {
                if writer.write_all(b" ").await.is_err() {
                    break;
                }
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        });
        let mut bytes = Vec::new();
        let _ = tokio::time::timeout(Duration::from_secs(8), reader.read_to_end(&mut bytes)).await;
        trickle.abort();
        let text = String::from_utf8_lossy(&bytes);
        assert!(text.starts_with("HTTP/1.1 408"), "{path}: {text}");
        let body: Value =
            serde_json::from_str(&text[text.find("\r\n\r\n").unwrap() + 4..]).unwrap();
        assert_eq!(body["error"]["code"], "timeout", "{path}");
    }
    assert!(temporary_files(&data_dir).is_empty());
    assert_eq!(server.state.runs_in_progress(), 0);
    assert_eq!(post(&server, &small_run()).await.status(), 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hundred_megabyte_bodies_are_refused_with_413() {
    let cfg = Config {
        recordings_max_bytes: 10 << 20,
        ..config("large")
    };
    let data_dir = cfg.data_dir.clone();
    let server = start(cfg).await;
    const SIZE: usize = 100 << 20;
    for (path, content_type) in [
        ("/api/v1/simulate", "application/json"),
        ("/api/v1/systems", "application/json"),
        ("/api/v1/recordings", "application/json"),
        ("/api/v1/recordings", "application/octet-stream"),
    ] {
        for declared in [true, false] {
            let mut stream = TcpStream::connect(server.addr).await.unwrap();
            let framing = if declared {
                format!("Content-Length: {SIZE}")
            } else {
                "Transfer-Encoding: chunked".to_string()
            };
            let head = format!(
                "POST {path} HTTP/1.1\r\nHost: a\r\nContent-Type: {content_type}\r\n{framing}\r\n\r\n"
            );
            stream.write_all(head.as_bytes()).await.unwrap();
            let (mut reader, mut writer) = stream.into_split();
            // The body is sent until the server stops reading; the answer is read meanwhile.
            let sender = tokio::spawn(async move {
                let chunk = vec![b'1'; 1 << 16];
                let mut sent = 0;
                while sent < SIZE {
                    let frame = if declared {
                        writer.write_all(&chunk).await
                    } else {
                        let mut framed = format!("{:x}\r\n", chunk.len()).into_bytes();
                        framed.extend_from_slice(&chunk);
                        framed.extend_from_slice(b"\r\n");
                        writer.write_all(&framed).await
                    };
                    if frame.is_err() {
                        break;
                    }
                    sent += chunk.len();
                }
                sent
            });
            let mut head = Vec::new();
            let mut buf = [0u8; 4096];
            while !String::from_utf8_lossy(&head).contains("\r\n\r\n") {
                match tokio::time::timeout(Duration::from_secs(20), reader.read(&mut buf)).await {
                    Ok(Ok(n)) if n > 0 => head.extend_from_slice(&buf[..n]),
                    other => panic!("{path} ({framing}): no answer: {other:?}"),
                }
            }
            let text = String::from_utf8_lossy(&head);
            assert!(
                text.starts_with("HTTP/1.1 413"),
                "{path} ({framing}): {text}"
            );
            drop(reader);
            let sent = sender.await.unwrap();
            assert!(sent < SIZE, "{path} ({framing}): the whole body was read");
        }
    }
    assert!(temporary_files(&data_dir).is_empty());
    assert_eq!(post(&server, &small_run()).await.status(), 200);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_gone_mid_body_holds_nothing() {
    let cfg = config("gone");
    let data_dir = cfg.data_dir.clone();
    let server = start(cfg).await;
    for (path, content_type) in [
        ("/api/v1/simulate", "application/json"),
        ("/api/v1/recordings", "application/octet-stream"),
    ] {
        let mut stream = TcpStream::connect(server.addr).await.unwrap();
        let head = format!(
            "POST {path} HTTP/1.1\r\nHost: a\r\nContent-Type: {content_type}\r\nContent-Length: 100000\r\n\r\n{{\"system\""
        );
        stream.write_all(head.as_bytes()).await.unwrap();
        tokio::time::sleep(Duration::from_millis(200)).await;
        drop(stream);
    }
    let until = Instant::now() + Duration::from_secs(5);
    while !temporary_files(&data_dir).is_empty() {
        assert!(Instant::now() < until, "an upload's temporary file stayed");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert_eq!(server.state.runs_in_progress(), 0);
    assert_eq!(post(&server, &small_run()).await.status(), 200);
}

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

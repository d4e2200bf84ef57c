//! Misbehaving clients and hostile paths against the real server loop, over raw TCP where a
//! well-behaved client library would not misbehave: connections that send nothing or their head
//! a byte at a time are closed after the header timeout, past the connection limit new ones wait,
//! a body that trickles in is answered 408, 100 MB bodies (with and without a length) are refused
//! with 413 and leave nothing behind, a client gone mid-body holds nothing; short runs are
//! served while long ones hold every shared slot, and long ones wait their turn; static files
//! and ids cannot name paths outside their directory; every answer says `nosniff`.

use std::path::PathBuf;
use std::time::{Duration, Instant};

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

pub(crate) fn config(name: &str) -> Config {
    let dir = scratch(name);
    Config {
        data_dir: dir.join("recordings"),
        systems_dir: dir.join("systems"),
        static_dir: None,
        ..Config::default()
    }
}

pub(crate) fn small_run() -> Value {
    json!({"system": "pendulum", "method": "modin_3s", "h": 0.01, "t_end": 10,
        "output": {"every": 100}})
}

/// 10⁹ steps (about 10 s in this build): holds a slot far longer than any test waits, and goes
/// when its client does.
pub(crate) fn long_run() -> Value {
    json!({"system": "pendulum", "method": "modin_3s", "h": 1e-3, "t_end": 1e6,
        "output": {"every": 10000000}})
}

pub(crate) async fn post(server: &Server, body: &Value) -> reqwest::Response {
    client()
        .post(server.url("/api/v1/simulate"))
        .json(body)
        .send()
        .await
        .unwrap()
}

/// Reads an HTTP answer's status line and head, then as much of the body as comes within
/// `wait`; None when the connection closes (or is reset) before a status line.
pub(crate) async fn read_answer(stream: &mut TcpStream, wait: Duration) -> Option<(u16, String)> {
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

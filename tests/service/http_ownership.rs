//! Ownership and quotas over real HTTP: a recording or definition belongs to the token that
//! stored it, and only it or an `admin` token deletes it; one definition stored by two owners is
//! one file with two owners; a client that fills its quota evicts only its own recordings, and
//! another's stay readable; runs in flight and steps per minute answer 429 with `Retry-After`;
//! and all of it holds after the real `geomint serve` is killed with SIGKILL and started again.

use std::path::Path;
use std::process::{Command, Stdio};

use geomint::access::{Anonymous, Quotas};
use reqwest::Method;
use serde_json::{json, Value};

use crate::http_access::{send, start, Body};
use crate::server::{self, spawn_listening, Server, SERVE_LISTENING, SERVE_LOG};

pub(crate) fn definition(k: u64) -> Value {
    json!({"coordinates": ["x"], "momenta": ["p"], "mass": 1, "potential": "k/2*x^2",
        "parameters": {"k": k}, "q0": [1], "p0": [0]})
}

pub(crate) fn run(t_end: u64) -> Value {
    json!({"system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": t_end})
}

pub(crate) async fn json_of(
    server: &Server,
    method: Method,
    path: &str,
    body: Body,
    token: &str,
) -> (u16, Value) {
    let (status, _, bytes) = send(server, method, path, &body, Some(token)).await;
    (
        status,
        serde_json::from_slice(&bytes).unwrap_or(Value::Null),
    )
}

pub(crate) fn ids(list: &Value) -> Vec<String> {
    list.as_array()
        .unwrap()
        .iter()
        .map(|r| r["id"].as_str().unwrap().to_string())
        .collect()
}

pub(crate) fn quota(bytes: u64) -> Quotas {
    Quotas {
        recordings_bytes: Some(bytes),
        ..Quotas::default()
    }
}

/// Only the owner or an admin deletes; listings filter by owner; a shared definition is one
/// file with two owners, gone with the last.
#[tokio::test]
async fn only_owners_and_admins_delete_and_a_shared_definition_has_two_owners() {
    let store = Quotas::default();
    let tokens = [
        ("alice", "read,run,store", store.clone()),
        ("bob", "read,run,store", store.clone()),
        ("ops", "admin", store),
    ];
    let (server, secrets) = start("own-delete", &tokens, Anonymous::None, |_| {}).await;
    let (alice, bob, ops) = (&secrets["alice"], &secrets["bob"], &secrets["ops"]);
    let (status, mine) = json_of(
        &server,
        Method::POST,
        "/api/v1/recordings",
        Body::Json(run(2)),
        alice,
    )
    .await;
    assert_eq!(status, 201);
    let (_, theirs) = json_of(
        &server,
        Method::POST,
        "/api/v1/recordings",
        Body::Json(run(3)),
        bob,
    )
    .await;
    let path = format!("/api/v1/recordings/{}", mine["id"].as_str().unwrap());
    let (status, refused) = json_of(&server, Method::DELETE, &path, Body::None, bob).await;
    assert_eq!(
        (status, refused["error"]["code"].as_str()),
        (403, Some("forbidden"))
    );
    assert!(refused["error"]["message"]
        .as_str()
        .unwrap()
        .contains("belongs to `alice`"));
    let (status, entry) = json_of(&server, Method::GET, &path, Body::None, bob).await;
    assert_eq!(
        (status, entry["owner"].as_str()),
        (200, Some("alice")),
        "bob may read it"
    );
    let (_, listed) = json_of(
        &server,
        Method::GET,
        "/api/v1/recordings?owner=alice",
        Body::None,
        bob,
    )
    .await;
    assert_eq!(ids(&listed), vec![mine["id"].as_str().unwrap()]);
    let (_, listed) = json_of(&server, Method::GET, "/api/v1/recordings", Body::None, bob).await;
    assert_eq!(ids(&listed).len(), 2);
    let deletable: Vec<bool> = listed
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["may_delete"].as_bool().unwrap())
        .collect();
    assert_eq!(
        deletable,
        vec![true, false],
        "bob's own (newest), not alice's"
    );
    assert_eq!(
        json_of(&server, Method::DELETE, &path, Body::None, alice)
            .await
            .0,
        204
    );
    let path = format!("/api/v1/recordings/{}", theirs["id"].as_str().unwrap());
    assert_eq!(
        json_of(&server, Method::DELETE, &path, Body::None, ops)
            .await
            .0,
        204,
        "an admin deletes anyone's"
    );

    // The same definition from two owners: one file, two owners.
    let (status, first) = json_of(
        &server,
        Method::POST,
        "/api/v1/systems",
        Body::Json(definition(5)),
        alice,
    )
    .await;
    assert_eq!(status, 201);
    let (status, second) = json_of(
        &server,
        Method::POST,
        "/api/v1/systems",
        Body::Json(definition(5)),
        bob,
    )
    .await;
    assert_eq!((status, &second["id"]), (200, &first["id"]));
    assert_eq!(second["owners"], json!(["alice", "bob"]));
    let id = first["id"].as_str().unwrap();
    let dir = server.state.config.systems_dir.clone();
    let files = || {
        let mut names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    assert_eq!(files(), vec![format!("{id}.json"), format!("{id}.owners")]);
    let (_, listed) = json_of(
        &server,
        Method::GET,
        "/api/v1/systems?owner=bob",
        Body::None,
        alice,
    )
    .await;
    assert_eq!(ids(&listed), vec![id]);
    let path = format!("/api/v1/systems/{id}");
    assert_eq!(
        json_of(&server, Method::DELETE, &path, Body::None, alice)
            .await
            .0,
        204
    );
    let (status, left) = json_of(&server, Method::GET, &path, Body::None, alice).await;
    assert_eq!(
        (status, &left["owners"]),
        (200, &json!(["bob"])),
        "bob's share stays"
    );
    let (status, _) = json_of(&server, Method::DELETE, &path, Body::None, alice).await;
    assert_eq!(status, 403, "alice gave up her share");
    assert_eq!(
        json_of(&server, Method::DELETE, &path, Body::None, bob)
            .await
            .0,
        204
    );
    assert_eq!(
        json_of(&server, Method::GET, &path, Body::None, bob)
            .await
            .0,
        404
    );
    assert!(files().is_empty(), "{:?}", files());
}

/// A client that fills its quota evicts only its own oldest recordings; another's stay
/// readable; and a store full of others' recordings refuses rather than evict them.
#[tokio::test]
async fn a_full_quota_evicts_only_its_owners_recordings() {
    // Sizes first: one run's recording.
    let (probe, secrets) = start(
        "own-probe",
        &[("p", "admin", Quotas::default())],
        Anonymous::None,
        |_| {},
    )
    .await;
    let (_, made) = json_of(
        &probe,
        Method::POST,
        "/api/v1/recordings",
        Body::Json(run(20)),
        &secrets["p"],
    )
    .await;
    let size = made["bytes"].as_u64().unwrap();
    // alice may keep two and a half of them; the store four and a half.
    let tokens = [
        ("alice", "read,run,store", quota(size * 5 / 2)),
        ("bob", "read,run,store", Quotas::default()),
        ("tiny", "read,run,store", quota(size / 2)),
    ];
    let (server, secrets) = start("own-evict", &tokens, Anonymous::None, |c| {
        c.recordings_max_bytes = size * 9 / 2
    })
    .await;
    let (alice, bob) = (&secrets["alice"], &secrets["bob"]);
    let store = |token: &str| {
        let token = token.to_string();
        let server = &server;
        async move {
            let (status, made) = json_of(
                server,
                Method::POST,
                "/api/v1/recordings",
                Body::Json(run(20)),
                &token,
            )
            .await;
            assert_eq!(status, 201, "{made}");
            made["id"].as_str().unwrap().to_string()
        }
    };
    let b1 = store(bob).await;
    let a1 = store(alice).await;
    let a2 = store(alice).await;
    let b2 = store(bob).await;
    let a3 = store(alice).await; // past alice's quota: her oldest goes
    let (_, listed) = json_of(&server, Method::GET, "/api/v1/recordings", Body::None, bob).await;
    assert_eq!(
        ids(&listed),
        vec![a3.clone(), b2.clone(), a2.clone(), b1.clone()]
    );
    for id in [&b1, &b2] {
        let (status, _, bytes) = send(
            &server,
            Method::GET,
            &format!("/api/v1/recordings/{id}.rrd"),
            &Body::None,
            Some(alice),
        )
        .await;
        assert_eq!(status, 200, "bob's recording stays readable");
        assert!(bytes.starts_with(b"RRF2") && bytes.len() as u64 > size / 2);
    }
    assert_eq!(
        send(
            &server,
            Method::GET,
            &format!("/api/v1/recordings/{a1}"),
            &Body::None,
            Some(alice)
        )
        .await
        .0,
        404
    );
    // bob fills the store's cap: only his own make room (alice's two stay).
    let b3 = store(bob).await;
    let (_, listed) = json_of(
        &server,
        Method::GET,
        "/api/v1/recordings?owner=alice",
        Body::None,
        bob,
    )
    .await;
    assert_eq!(ids(&listed), vec![a3.clone(), a2.clone()]);
    let (_, listed) = json_of(
        &server,
        Method::GET,
        "/api/v1/recordings?owner=bob",
        Body::None,
        bob,
    )
    .await;
    assert_eq!(
        ids(&listed),
        vec![b3.clone(), b2.clone()],
        "bob's oldest made room"
    );
    // A recording larger than its owner's whole quota is refused; nothing goes.
    let (status, refused) = json_of(
        &server,
        Method::POST,
        "/api/v1/recordings",
        Body::Json(run(20)),
        &secrets["tiny"],
    )
    .await;
    assert_eq!(
        (status, refused["error"]["code"].as_str()),
        (403, Some("quota_exceeded")),
        "{refused}"
    );
    let (_, listed) = json_of(&server, Method::GET, "/api/v1/recordings", Body::None, bob).await;
    assert_eq!(ids(&listed).len(), 4);
}

/// Runs in flight and steps per minute past a token's quota answer 429 with `Retry-After`;
/// definitions past its quota 403.
#[tokio::test]
async fn rates_and_counts_past_a_quota_are_refused() {
    let quotas = Quotas {
        steps_per_minute: Some(100),
        systems: Some(2),
        runs: Some(1),
        ..Quotas::default()
    };
    let (server, secrets) = start(
        "own-rate",
        &[("carol", "read,run,store", quotas)],
        Anonymous::None,
        |_| {},
    )
    .await;
    let carol = &secrets["carol"];
    // 20 steps × 2 coordinates = 40 steps: two fit in a minute, not three.
    for expected in [200, 200, 429] {
        let (status, headers, bytes) = send(
            &server,
            Method::POST,
            "/api/v1/simulate",
            &Body::Json(run(2)),
            Some(carol),
        )
        .await;
        assert_eq!(status, expected, "{}", String::from_utf8_lossy(&bytes));
        if status == 429 {
            let wait: u64 = headers["retry-after"].to_str().unwrap().parse().unwrap();
            assert!((1..=60).contains(&wait), "{wait}");
            let error: Value = serde_json::from_slice(&bytes).unwrap();
            assert_eq!(error["error"]["code"], "rate_limited");
        }
    }
    let (status, too_big) = json_of(
        &server,
        Method::POST,
        "/api/v1/simulate",
        Body::Json(run(100)),
        carol,
    )
    .await;
    assert_eq!(
        (status, too_big["error"]["code"].as_str()),
        (403, Some("quota_exceeded"))
    );
    for k in [1, 2] {
        assert_eq!(
            json_of(
                &server,
                Method::POST,
                "/api/v1/systems",
                Body::Json(definition(k)),
                carol
            )
            .await
            .0,
            201
        );
    }
    let (status, refused) = json_of(
        &server,
        Method::POST,
        "/api/v1/systems",
        Body::Json(definition(3)),
        carol,
    )
    .await;
    assert_eq!(
        (status, refused["error"]["code"].as_str()),
        (403, Some("quota_exceeded")),
        "{refused}"
    );
}

/// Runs in flight: a second run while the first streams is 429 `too_many_runs`.
#[tokio::test]
async fn a_second_run_in_flight_past_the_quota_is_429() {
    let quotas = Quotas {
        runs: Some(1),
        ..Quotas::default()
    };
    let (server, secrets) = start(
        "own-runs",
        &[("dan", "read,run", quotas)],
        Anonymous::None,
        |_| {},
    )
    .await;
    let dan = secrets["dan"].clone();
    let long = json!({"system": "pendulum", "methods": ["modin_3s"], "h": 1e-4, "t_end": 1000});
    let response = server::client()
        .post(server.url("/api/v1/simulate?format=ndjson"))
        .bearer_auth(&dan)
        .json(&long)
        .send()
        .await
        .unwrap();
    assert_eq!(response.status().as_u16(), 200);
    let (status, headers, bytes) = send(
        &server,
        Method::POST,
        "/api/v1/simulate",
        &Body::Json(run(2)),
        Some(&dan),
    )
    .await;
    assert_eq!(status, 429, "{}", String::from_utf8_lossy(&bytes));
    assert_eq!(headers["retry-after"], "1");
    assert_eq!(
        serde_json::from_slice::<Value>(&bytes).unwrap()["error"]["code"],
        "too_many_runs"
    );
    drop(response);
    // The run ends once its client is gone; then dan runs again.
    let until = std::time::Instant::now() + std::time::Duration::from_secs(20);
    loop {
        let (status, _, _) = send(
            &server,
            Method::POST,
            "/api/v1/simulate",
            &Body::Json(run(2)),
            Some(&dan),
        )
        .await;
        if status == 200 {
            break;
        }
        assert!(
            std::time::Instant::now() < until,
            "the cancelled run still counts"
        );
        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    }
}

pub(crate) fn serve(dir: &Path, tokens: &Path, cap: u64) -> (server::Process, Server) {
    let mut command = Command::new(env!("CARGO_BIN_EXE_geomint"));
    command
        .env("GEOMINT_LOG", SERVE_LOG)
        .args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--static-dir",
            "no-static-here",
        ])
        .arg("--data-dir")
        .arg(dir.join("recordings"))
        .arg("--systems-dir")
        .arg(dir.join("systems"))
        .arg("--tokens")
        .arg(tokens)
        .args(["--recordings-max-bytes", &cap.to_string()])
        .stdout(Stdio::null());
    let (process, address) = spawn_listening(command, "geomint serve", SERVE_LISTENING);
    let state = geomint::http::AppState::new(geomint::http::Config {
        data_dir: dir.join("unused"),
        systems_dir: dir.join("unused"),
        ..Default::default()
    });
    let addr = address.parse().unwrap();
    (
        process,
        Server {
            base: format!("http://{address}"),
            addr,
            state,
        },
    )
}

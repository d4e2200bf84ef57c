//! Ownership and tokens across restarts and reloads: ownership and quotas survive SIGKILL of the
//! server, the tokens file is reloaded when it changes, and the token command and the policy of an
//! open address.

use crate::http_access::{send, start, tokens_file, Body};
use crate::http_ownership::{definition, ids, json_of, quota, run, serve};
use crate::server::{self};
use geomint::access::{Anonymous, Quotas};
use reqwest::Method;
use serde_json::json;
use std::process::Command;

/// Ownership and quotas survive SIGKILL: after a restart the owners are the same, others still
/// cannot delete, and a quota counts the bytes stored before the kill.
#[tokio::test]
async fn ownership_and_quotas_survive_sigkill() {
    let dir = server::scratch_dir("own-sigkill");
    let (probe, secrets) = start(
        "own-sigkill-probe",
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
    let tokens = [
        ("alice", "read,run,store", quota(size * 5 / 2)),
        ("bob", "read,run,store", Quotas::default()),
    ];
    let (file, secrets) = tokens_file(&dir, &tokens);
    let (alice, bob) = (secrets["alice"].clone(), secrets["bob"].clone());
    let (mut process, server) = serve(&dir, &file, 1 << 30);
    let mut stored = Vec::new();
    for token in [&alice, &bob, &alice] {
        let (status, made) = json_of(
            &server,
            Method::POST,
            "/api/v1/recordings",
            Body::Json(run(20)),
            token,
        )
        .await;
        assert_eq!(status, 201);
        stored.push(made["id"].as_str().unwrap().to_string());
    }
    let (_, system) = json_of(
        &server,
        Method::POST,
        "/api/v1/systems",
        Body::Json(definition(9)),
        &alice,
    )
    .await;
    json_of(
        &server,
        Method::POST,
        "/api/v1/systems",
        Body::Json(definition(9)),
        &bob,
    )
    .await;
    process.0.kill().unwrap();
    process.0.wait().unwrap();

    let (_process, server) = serve(&dir, &file, 1 << 30);
    let (_, listed) = json_of(&server, Method::GET, "/api/v1/recordings", Body::None, &bob).await;
    let owners: Vec<(String, String)> = listed
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r["id"].as_str().unwrap().to_string(),
                r["owner"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let expected: Vec<(String, String)> = stored
        .iter()
        .rev()
        .cloned()
        .zip(["alice", "bob", "alice"].map(String::from))
        .collect();
    assert_eq!(owners, expected);
    let path = format!("/api/v1/recordings/{}", stored[0]);
    assert_eq!(
        json_of(&server, Method::DELETE, &path, Body::None, &bob)
            .await
            .0,
        403
    );
    let path = format!("/api/v1/systems/{}", system["id"].as_str().unwrap());
    let (_, entry) = json_of(&server, Method::GET, &path, Body::None, &bob).await;
    assert_eq!(entry["owners"], json!(["alice", "bob"]));
    // alice has two before the kill: a third evicts her oldest, not bob's.
    let (status, _) = json_of(
        &server,
        Method::POST,
        "/api/v1/recordings",
        Body::Json(run(20)),
        &alice,
    )
    .await;
    assert_eq!(status, 201);
    let (_, listed) = json_of(&server, Method::GET, "/api/v1/recordings", Body::None, &bob).await;
    let left = ids(&listed);
    assert!(
        !left.contains(&stored[0]) && left.contains(&stored[1]) && left.contains(&stored[2]),
        "{left:?}"
    );
}

/// A token removed from the file is refused within a few seconds, without a restart; a file
/// that no longer reads keeps the tokens in force.
#[tokio::test]
async fn tokens_are_reloaded_when_the_file_changes() {
    let dir = server::scratch_dir("own-reload");
    let tokens = [
        ("alice", "read", Quotas::default()),
        ("bob", "read", Quotas::default()),
    ];
    let (file, secrets) = tokens_file(&dir, &tokens);
    let (_process, server) = serve(&dir, &file, 1 << 30);
    let status = |token: String| {
        let server = &server;
        async move {
            send(
                server,
                Method::GET,
                "/api/v1/recordings",
                &Body::None,
                Some(&token),
            )
            .await
            .0
        }
    };
    assert_eq!(status(secrets["alice"].clone()).await, 200);
    let text = std::fs::read_to_string(&file).unwrap();
    // A line that does not read: alice still passes.
    std::fs::write(&file, format!("{text}broken line\n")).unwrap();
    tokio::time::sleep(std::time::Duration::from_secs(5)).await;
    assert_eq!(status(secrets["alice"].clone()).await, 200);
    // alice's line removed: refused once the file is read again.
    let kept: String = text
        .lines()
        .filter(|l| !l.starts_with("alice "))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&file, kept).unwrap();
    let until = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while status(secrets["alice"].clone()).await != 401 {
        assert!(
            std::time::Instant::now() < until,
            "alice's token still passes"
        );
        tokio::time::sleep(std::time::Duration::from_millis(200)).await;
    }
    assert_eq!(status(secrets["bob"].clone()).await, 200);
}

/// `geomint token` prints a secret and the line that admits it; `--append` refuses a name the
/// file has; `serve` on an address other machines reach refuses to start without a policy.
#[test]
fn the_token_command_and_the_policy_of_an_open_address() {
    let dir = server::scratch_dir("own-cli");
    std::fs::create_dir_all(&dir).unwrap();
    let geomint = || Command::new(env!("CARGO_BIN_EXE_geomint"));
    let made = geomint()
        .args(["token", "alice", "--scopes", "read,store", "--runs", "2"])
        .output()
        .unwrap();
    assert!(made.status.success());
    let out = String::from_utf8(made.stdout).unwrap();
    let (secret, line) = out.trim_end().split_once('\n').unwrap();
    assert!(
        line.starts_with("alice read,store sha256:") && line.ends_with(" runs=2"),
        "{line}"
    );
    let file = geomint::access::tokens::TokenFile::parse(line).unwrap();
    assert_eq!(file.verify(secret).map(|e| e.name.as_str()), Some("alice"));
    let tokens = dir.join("tokens");
    let append = |name: &str| {
        geomint()
            .args(["token", name, "--append"])
            .arg(&tokens)
            .output()
            .unwrap()
    };
    let first = append("bob");
    assert!(first.status.success());
    let again = append("bob");
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("used twice"));
    let secret = String::from_utf8(first.stdout).unwrap();
    let file = geomint::access::read_tokens(&tokens).unwrap();
    assert_eq!(
        file.verify(secret.trim()).map(|e| e.name.as_str()),
        Some("bob")
    );
    let open = geomint()
        .env("GEOMINT_LOG", "warn")
        .args([
            "serve",
            "--addr",
            "0.0.0.0:0",
            "--static-dir",
            "no-static-here",
        ])
        .arg("--data-dir")
        .arg(dir.join("recordings"))
        .output()
        .unwrap();
    assert_eq!(open.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&open.stderr).contains("--tokens FILE"),
        "{}",
        String::from_utf8_lossy(&open.stderr)
    );
}

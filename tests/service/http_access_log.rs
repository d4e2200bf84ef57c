//! Access over real HTTP, as documented and logged: the security each operation of the OpenAPI
//! document states, and one access-log line per request.

use crate::http_access::{scoped_tokens, send, start, tokens_file, Body};
use crate::server::{self, client};
use geomint::access::{Anonymous, Quotas};
use reqwest::Method;
use serde_json::{json, Value};

/// The document states the bearer scheme and each operation's scope, with `{}` beside it where
/// a client without a token may call it under the server's policy.
#[tokio::test]
async fn the_document_states_each_operations_scope() {
    for (policy, simulate, store) in [
        (
            Anonymous::None,
            json!([{"bearer": ["run"]}]),
            json!([{"bearer": ["store"]}]),
        ),
        (
            Anonymous::Public,
            json!([{}, {"bearer": ["run"]}]),
            json!([{"bearer": ["store"]}]),
        ),
    ] {
        let (server, _) = start("access-doc", &scoped_tokens(), policy, |_| {}).await;
        let (status, _, bytes) = send(
            &server,
            Method::GET,
            "/api/v1/openapi.json",
            &Body::None,
            None,
        )
        .await;
        assert_eq!(status, 200);
        let doc: Value = serde_json::from_slice(&bytes).unwrap();
        assert_eq!(
            doc["components"]["securitySchemes"]["bearer"]["scheme"],
            "bearer"
        );
        let paths = &doc["paths"];
        assert_eq!(
            paths["/api/v1/simulate"]["post"]["security"], simulate,
            "{policy:?}"
        );
        assert_eq!(
            paths["/api/v1/recordings/{id}"]["delete"]["security"], store,
            "{policy:?}"
        );
        assert_eq!(paths["/healthz"]["get"]["security"], json!([{}]));
        assert!(paths["/api/v1/simulate"]["post"]["responses"]["429"].is_object());
        assert!(paths["/api/v1/systems"]["get"]["responses"]["401"].is_object());
    }
}

/// One access-log line per request, as JSON (`geomint serve --log-format json`, the real
/// process): who (the token's name, or the anonymous address), the route's template, the status
/// and the bytes of the body as sent.
#[tokio::test]
async fn every_request_writes_one_access_line() {
    let dir = server::scratch_dir("access-log");
    let (file, secrets) = tokens_file(&dir, &[("alice", "read", Quotas::default())]);
    let port = server::free_port();
    let log = dir.join("server.log");
    let process = server::Process(
        std::process::Command::new(env!("CARGO_BIN_EXE_geomint"))
            .env("GEOMINT_LOG", "warn,geomint::access=info")
            .args([
                "serve",
                "--log-format",
                "json",
                "--static-dir",
                "no-static-here",
            ])
            .args(["--addr", &format!("127.0.0.1:{port}")])
            .arg("--tokens")
            .arg(&file)
            .arg("--data-dir")
            .arg(dir.join("recordings"))
            .stdout(std::process::Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap(),
    );
    server::wait_for_port(port, "geomint serve");
    let base = format!("http://127.0.0.1:{port}");
    let mut sizes = Vec::new();
    for (path, token) in [
        ("/api/v1/methods/modin_3s", Some(&secrets["alice"])),
        ("/api/v1/systems/pendulum", None),
    ] {
        let mut request = client().get(format!("{base}{path}"));
        if let Some(token) = token {
            request = request.bearer_auth(token);
        }
        sizes.push(request.send().await.unwrap().bytes().await.unwrap().len() as u64);
    }
    // The line is written once the body is sent: give the server a moment, then stop it.
    tokio::time::sleep(std::time::Duration::from_millis(300)).await;
    drop(process);
    let text = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<Value> = text
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|l| l["target"] == "geomint::access")
        .collect();
    assert_eq!(lines.len(), 2, "{text}");
    let fields = |l: &Value| {
        (
            l["caller"].clone(),
            l["route"].clone(),
            l["status"].clone(),
            l["bytes"].clone(),
        )
    };
    assert_eq!(
        fields(&lines[0]),
        (
            json!("alice"),
            json!("/api/v1/methods/{id}"),
            json!(200),
            json!(sizes[0])
        )
    );
    assert_eq!(
        fields(&lines[1]),
        (
            json!("anonymous@127.0.0.1"),
            json!("/api/v1/systems/{id}"),
            json!(401),
            json!(sizes[1])
        )
    );
    assert!(
        lines
            .iter()
            .all(|l| l["duration_ms"].as_f64().is_some_and(|d| d >= 0.0)),
        "{text}"
    );
}

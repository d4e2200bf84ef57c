//! Who may do what, over real HTTP: every route × {no token, a wrong token, a token of each
//! scope} on a server with a tokens file, each answered 2xx, 401 or 403 as its scope says, and a
//! refusal changing nothing stored; the anonymous policies (`public`: reading and small runs);
//! the bearer header's forms; the security the OpenAPI document states; and the access log.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use geomint::access::tokens::generate;
use geomint::access::{AccessConfig, Anonymous, Quotas, Scopes};
use geomint::http::Config;
use reqwest::Method;
use serde_json::{json, Value};

use crate::server::{self, client, Server};

/// Writes a tokens file in `dir` for `tokens` (name, scopes, quotas); the secrets by name.
pub fn tokens_file(
    dir: &Path,
    tokens: &[(&str, &str, Quotas)],
) -> (PathBuf, BTreeMap<String, String>) {
    std::fs::create_dir_all(dir).unwrap();
    let mut lines = String::from("# the tokens of a test\n");
    let mut secrets = BTreeMap::new();
    for (name, scopes, quotas) in tokens {
        let made = generate(name, Scopes::parse(scopes).unwrap(), quotas).unwrap();
        lines.push_str(&made.line);
        lines.push('\n');
        secrets.insert(name.to_string(), made.secret);
    }
    let path = dir.join("tokens");
    std::fs::write(&path, lines).unwrap();
    (path, secrets)
}

/// A server on loopback with `tokens` and the anonymous `policy`.
pub async fn start(
    label: &str,
    tokens: &[(&str, &str, Quotas)],
    policy: Anonymous,
    tune: impl FnOnce(&mut Config),
) -> (Server, BTreeMap<String, String>) {
    let dir = server::scratch_dir(label);
    let (file, secrets) = tokens_file(&dir, tokens);
    let mut config = Config {
        data_dir: dir.join("recordings"),
        systems_dir: dir.join("systems"),
        access: AccessConfig {
            tokens_file: Some(file),
            anonymous: policy,
            anonymous_quotas: Quotas::default(),
        },
        ..Config::default()
    };
    tune(&mut config);
    (server::start(config).await, secrets)
}

/// Sends `method path` with `body` (JSON, or `.rrd` bytes) as `token` (none: no header).
pub async fn send(
    server: &Server,
    method: Method,
    path: &str,
    body: &Body,
    token: Option<&str>,
) -> (u16, reqwest::header::HeaderMap, Vec<u8>) {
    let mut request = client().request(method, server.url(path));
    if let Some(token) = token {
        request = request.bearer_auth(token);
    }
    request = match body {
        Body::None => request,
        Body::Json(value) => request.json(value),
        Body::Rrd(bytes) => request
            .header("content-type", "application/octet-stream")
            .body(bytes.clone()),
    };
    let response = request.send().await.unwrap();
    let status = response.status().as_u16();
    let headers = response.headers().clone();
    (status, headers, response.bytes().await.unwrap().to_vec())
}

/// A request body.
#[derive(Clone, Debug)]
pub enum Body {
    /// None.
    None,
    /// JSON.
    Json(Value),
    /// An `.rrd` upload.
    Rrd(Vec<u8>),
}

const SCOPED: [&str; 4] = ["read", "run", "store", "admin"];

pub(crate) fn scoped_tokens() -> Vec<(&'static str, &'static str, Quotas)> {
    SCOPED.iter().map(|s| (*s, *s, Quotas::default())).collect()
}

fn definition(k: u64) -> Value {
    json!({"coordinates": ["x"], "momenta": ["p"], "mass": 1, "potential": "k/2*x^2",
        "parameters": {"k": k}, "q0": [1], "p0": [0]})
}

fn small_run() -> Value {
    json!({"system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 2})
}

/// What is stored, as the admin sees it: recordings and stored definitions with their owners.
async fn stored(server: &Server, admin: &str) -> (Value, Value) {
    let get = |path: &'static str| async move {
        let (status, _, bytes) = send(server, Method::GET, path, &Body::None, Some(admin)).await;
        assert_eq!(status, 200);
        serde_json::from_slice::<Value>(&bytes).unwrap()
    };
    let recordings = get("/api/v1/recordings").await;
    let systems: Vec<Value> = get("/api/v1/systems")
        .await
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s.get("owners").is_some())
        .map(|s| json!([s["id"], s["owners"]]))
        .collect();
    (recordings, Value::from(systems))
}

/// Every route × every kind of caller: the status its scope says, and nothing changed when
/// refused.
#[tokio::test]
async fn every_route_answers_each_caller_as_its_scope_says() {
    let (server, secrets) = start("access-matrix", &scoped_tokens(), Anonymous::None, |_| {}).await;
    let admin = secrets["admin"].clone();
    let (_, _, rrd) = send(
        &server,
        Method::POST,
        "/api/v1/simulate?format=rrd",
        &Body::Json(small_run()),
        Some(&admin),
    )
    .await;
    let stability = json!({"methods": ["csv1"], "omega": 3.51, "gamma": {"min": 0, "max": 3.5, "n": 4}, "h": {"min": 0.1, "max": 1, "n": 4}});
    let work_precision = json!({"system": "harmonic_oscillator", "params": {"omega": 2, "gamma": 0.1},
        "q0": [1.0], "p0": [0.0], "t_end": 5, "samples": 5, "runs": [{"method": "csv1", "h": [0.1, 0.05]}]});
    let convergence = json!({"system": "harmonic_oscillator", "params": {"omega": 1, "gamma": 0},
        "charts": ["cartesian"], "q0": [1], "p0": [0], "t_end": 2, "methods": ["symplectic_euler"], "h": [0.04, 0.02, 0.01]});
    let sweep = json!({"system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 5, "every": 5,
        "axes": [{"name": "params.gamma", "min": 0.01, "max": 1, "n": 3, "scale": "log"}]});
    // (method, path, body, the scopes it needs — none: open to all)
    let routes: Vec<(Method, &str, Body, &[&str])> = vec![
        (Method::GET, "/healthz", Body::None, &[]),
        (Method::GET, "/api/v1/openapi.json", Body::None, &[]),
        (Method::GET, "/api/v1/systems", Body::None, &["read"]),
        (
            Method::POST,
            "/api/v1/systems",
            Body::Json(definition(7)),
            &["store"],
        ),
        (
            Method::GET,
            "/api/v1/systems/pendulum",
            Body::None,
            &["read"],
        ),
        (
            Method::DELETE,
            "/api/v1/systems/{system}",
            Body::None,
            &["store"],
        ),
        (Method::GET, "/api/v1/methods", Body::None, &["read"]),
        (
            Method::GET,
            "/api/v1/methods/modin_3s",
            Body::None,
            &["read"],
        ),
        (
            Method::POST,
            "/api/v1/simulate",
            Body::Json(small_run()),
            &["run"],
        ),
        (
            Method::POST,
            "/api/v1/simulate/allowed-region",
            Body::Json(
                json!({"system": "henon_heiles", "method": "rk4", "h": 0.1, "t_end": 1,
                "energy": {"value": 0.125, "momentum": "p_x"},
                "plane": {"x": {"name": "y", "min": -0.5, "max": 0.5, "points": 3},
                          "y": {"name": "p_y", "min": -0.5, "max": 0.5, "points": 3}}}),
            ),
            &["run"],
        ),
        (
            Method::POST,
            "/api/v1/stability",
            Body::Json(stability),
            &["run"],
        ),
        (
            Method::POST,
            "/api/v1/stability/point",
            Body::Json(json!({"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": 0.2})),
            &["run"],
        ),
        (
            Method::POST,
            "/api/v1/studies/work-precision",
            Body::Json(work_precision),
            &["run"],
        ),
        (
            Method::POST,
            "/api/v1/studies/energy-map",
            Body::Json(json!({"nx": 3, "ny": 3, "t_max": 20})),
            &["run"],
        ),
        (
            Method::POST,
            "/api/v1/studies/convergence",
            Body::Json(convergence),
            &["run"],
        ),
        (
            Method::POST,
            "/api/v1/studies/sweep",
            Body::Json(sweep),
            &["run"],
        ),
        (
            Method::GET,
            "/api/v1/studies/sweep/presets",
            Body::None,
            &["read"],
        ),
        (Method::GET, "/api/v1/recordings", Body::None, &["read"]),
        (
            Method::POST,
            "/api/v1/recordings",
            Body::Json(small_run()),
            &["store", "run"],
        ),
        (
            Method::POST,
            "/api/v1/recordings",
            Body::Rrd(rrd.clone()),
            &["store"],
        ),
        (
            Method::GET,
            "/api/v1/recordings/{recording}",
            Body::None,
            &["read"],
        ),
        (
            Method::GET,
            "/api/v1/recordings/{recording}.rrd",
            Body::None,
            &["read"],
        ),
        (
            Method::GET,
            "/api/v1/recordings/{recording}/samples",
            Body::None,
            &["read"],
        ),
        (
            Method::DELETE,
            "/api/v1/recordings/{recording}",
            Body::None,
            &["store"],
        ),
    ];
    let callers: Vec<(&str, Option<String>)> = vec![
        ("no token", None),
        ("a wrong token", Some(format!("gmt_{}", "A".repeat(43)))),
    ]
    .into_iter()
    .chain(SCOPED.iter().map(|s| (*s, Some(secrets[*s].clone()))))
    .collect();
    let mut answered = 0;
    for (method, template, body, needs) in &routes {
        for (who, token) in &callers {
            // A target for the routes on one item: the caller's own when it may store, else
            // the admin's.
            let owner = match who {
                &"store" | &"admin" => token.clone().unwrap(),
                _ => admin.clone(),
            };
            let (_, _, made) = send(
                &server,
                Method::POST,
                "/api/v1/recordings",
                &Body::Rrd(rrd.clone()),
                Some(&owner),
            )
            .await;
            let recording: Value = serde_json::from_slice(&made).unwrap();
            let (_, _, made) = send(
                &server,
                Method::POST,
                "/api/v1/systems",
                &Body::Json(definition(100 + answered)),
                Some(&owner),
            )
            .await;
            let system: Value = serde_json::from_slice(&made).unwrap();
            let path = template
                .replace("{recording}", recording["id"].as_str().unwrap())
                .replace("{system}", system["id"].as_str().unwrap());
            let before = stored(&server, &admin).await;
            let (status, headers, bytes) =
                send(&server, method.clone(), &path, body, token.as_deref()).await;
            let text = String::from_utf8_lossy(&bytes[..bytes.len().min(300)]).into_owned();
            let granted = |scope: &&str| *who == "admin" || who == scope;
            let expected = match (who, needs.is_empty()) {
                (&"a wrong token", _) => 401,
                (_, true) => 200,
                (&"no token", false) => 401,
                _ if needs.iter().all(granted) => 200,
                _ => 403,
            };
            let what = format!("{method} {template} as {who}: {status} {text}");
            if expected == 200 {
                assert!((200..300).contains(&status), "{what}");
                continue;
            }
            assert_eq!(status, expected, "{what}");
            let error: Value = serde_json::from_slice(&bytes).expect(&what);
            let code = if expected == 401 {
                "unauthorized"
            } else {
                "forbidden"
            };
            assert_eq!(error["error"]["code"], code, "{what}");
            assert_eq!(error["error"]["field"], "Authorization", "{what}");
            if expected == 401 {
                assert_eq!(
                    headers["www-authenticate"], "Bearer realm=\"geomint\"",
                    "{what}"
                );
            }
            assert_eq!(
                stored(&server, &admin).await,
                before,
                "{what} changed what is stored"
            );
            answered += 1;
        }
    }
    // Every refused case was seen: the 2 open routes answer only the wrong token with 401.
    assert!(answered > 60, "{answered}");
}

/// `--public`: clients without a token read and run small runs; storing, deleting and large
/// runs or studies need a token, and say so.
#[tokio::test]
async fn a_public_server_lets_clients_without_a_token_read_and_run_small_runs() {
    let (server, secrets) = start("access-public", &scoped_tokens(), Anonymous::Public, |c| {
        c.access.anonymous_quotas.runs = Some(2);
    })
    .await;
    let anonymous = |method: Method, path: &'static str, body: Body| {
        let server = &server;
        async move { send(server, method, path, &body, None).await }
    };
    assert_eq!(
        anonymous(Method::GET, "/api/v1/systems", Body::None)
            .await
            .0,
        200
    );
    assert_eq!(
        anonymous(Method::GET, "/api/v1/recordings", Body::None)
            .await
            .0,
        200
    );
    assert_eq!(
        anonymous(Method::POST, "/api/v1/simulate", Body::Json(small_run()))
            .await
            .0,
        200
    );
    let large = json!({"system": "pendulum", "methods": ["modin_3s"], "h": 0.001, "t_end": 200});
    let (status, _, bytes) =
        anonymous(Method::POST, "/api/v1/simulate", Body::Json(large.clone())).await;
    assert_eq!(status, 401, "{}", String::from_utf8_lossy(&bytes));
    assert!(String::from_utf8_lossy(&bytes).contains("more than the 200000"));
    let (status, _, _) = send(
        &server,
        Method::POST,
        "/api/v1/simulate",
        &Body::Json(large),
        Some(&secrets["run"]),
    )
    .await;
    assert_eq!(status, 200, "a token runs it");
    let energy_map = json!({"nx": 3, "ny": 3, "t_max": 20});
    assert_eq!(
        anonymous(
            Method::POST,
            "/api/v1/studies/energy-map",
            Body::Json(energy_map)
        )
        .await
        .0,
        401
    );
    assert_eq!(
        anonymous(Method::POST, "/api/v1/systems", Body::Json(definition(3)))
            .await
            .0,
        401
    );
    assert_eq!(
        anonymous(Method::POST, "/api/v1/recordings", Body::Json(small_run()))
            .await
            .0,
        401
    );
    // A recording an admin stored: listed to everyone, deletable only by its owner.
    let admin = &secrets["admin"];
    send(
        &server,
        Method::POST,
        "/api/v1/recordings",
        &Body::Json(small_run()),
        Some(admin),
    )
    .await;
    let (_, _, listed) = anonymous(Method::GET, "/api/v1/recordings", Body::None).await;
    let listed: Value = serde_json::from_slice(&listed).unwrap();
    assert_eq!(
        (listed[0]["owner"].as_str(), &listed[0]["may_delete"]),
        (Some("admin"), &json!(false))
    );
    let (_, _, listed) = send(
        &server,
        Method::GET,
        "/api/v1/recordings",
        &Body::None,
        Some(admin),
    )
    .await;
    assert_eq!(
        serde_json::from_slice::<Value>(&listed).unwrap()[0]["may_delete"],
        true
    );
}

/// The header's forms: the scheme in any case and a valid token pass; anything else is 401
/// naming the header, whatever the route.
#[tokio::test]
async fn bearer_headers_are_read_strictly() {
    let (server, secrets) =
        start("access-header", &scoped_tokens(), Anonymous::Public, |_| {}).await;
    let read = &secrets["read"];
    let answer = |value: String| {
        let server = &server;
        async move {
            let response = client()
                .get(server.url("/api/v1/recordings"))
                .header("authorization", value)
                .send()
                .await
                .unwrap();
            let status = response.status().as_u16();
            (status, response.json::<Value>().await.unwrap())
        }
    };
    for good in [
        format!("Bearer {read}"),
        format!("bearer {read}"),
        format!("BEARER   {read}"),
    ] {
        let (status, listed) = answer(good.clone()).await;
        assert_eq!((status, listed.is_array()), (200, true), "{good}");
    }
    for bad in [
        format!("Basic {read}"),
        "Bearer".to_string(),
        "Bearer ".to_string(),
        format!("Bearer {read}x"),
        format!("Bearer {}", &read[..read.len() - 1]),
        format!("Bearer {read} {read}"),
        format!("Token {read}"),
        read.to_string(),
        format!("Bearer {}", "a".repeat(10_000)),
    ] {
        let (status, error) = answer(bad.clone()).await;
        assert_eq!(status, 401, "{bad:.40}");
        assert_eq!(error["error"]["field"], "Authorization", "{bad:.40}");
    }
    // Two headers, even two good ones, are refused.
    let response = client()
        .get(server.url("/api/v1/recordings"))
        .header("authorization", format!("Bearer {read}"))
        .header("authorization", format!("Bearer {read}"))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status().as_u16(), 401);
}

//! Every route's outside input, fuzzed through the whole service (`app` in process, every
//! middleware included): request bodies mutated from valid examples (values swapped for odd
//! JSON, keys dropped and added, bytes flipped, cut and spliced, invalid UTF-8), query strings,
//! ids in paths, content types; plus the hostile inputs named outright: JSON nested 10⁵ deep,
//! numbers beyond f64, duplicate keys, non-JSON content types.
//!
//! The property: no panic, never a 5xx (work past the time limit answers with what it finished),
//! and every refusal in the service's error shape with a known code. CI runs proptest's default
//! of 256 cases per target; the long run sets
//! `PROPTEST_CASES` (the README's fuzzing command runs 10⁶ per target in release).

use std::sync::OnceLock;

use axum::body::Body;
use axum::http::Request;
use axum::Router;
use geomint::core::simulation::Limits;
use geomint::http::{app, AppState, Config};
use proptest::prelude::*;
use proptest::test_runner::{Config as RunnerConfig, TestCaseError, TestRunner};
use serde_json::{json, Value};
use tower::ServiceExt;

use crate::server;

/// A service with small limits, so that the valid requests mutation makes stay cheap (its router,
/// built once: building it costs more than most cases).
fn service() -> &'static (Router, tokio::runtime::Runtime) {
    static SERVICE: OnceLock<(Router, tokio::runtime::Runtime)> = OnceLock::new();
    SERVICE.get_or_init(|| {
        // The service is a static, never dropped: the next test process removes this folder.
        let dir = server::scratch_dir("fuzz-routes");
        let state = AppState::new(Config {
            limits: Limits {
                max_steps: 20_000,
                max_samples: 2_000,
            },
            max_concurrent: 2,
            queue_timeout: std::time::Duration::from_secs(30),
            long_queue_timeout: std::time::Duration::from_secs(30),
            // Short, so that the mutated studies that ask for hours of work (up to the map's
            // 2·10¹⁰ steps, or its defaults when a mutation drops every key) come back partial
            // quickly: most of a long run's time goes to the cases that reach this limit.
            request_timeout: std::time::Duration::from_millis(50),
            data_dir: dir.join("recordings"),
            systems_dir: dir.join("systems"),
            max_systems: 100_000,
            ..Config::default()
        });
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .unwrap();
        (app(state), runtime)
    })
}

/// Sends one request to the service; checks the property and returns the status.
fn send(
    method: &str,
    uri: &str,
    content_type: Option<&str>,
    body: Vec<u8>,
) -> Result<u16, TestCaseError> {
    let (router, runtime) = service();
    let mut request = Request::builder().method(method).uri(uri);
    if let Some(ct) = content_type {
        request = request.header("content-type", ct);
    }
    let Ok(request) = request.body(Body::from(body)) else {
        return Ok(400); // not a request hyper would pass on (an invalid URI)
    };
    let (status, content_type, bytes) = runtime.block_on(async {
        let response = router.clone().oneshot(request).await.unwrap();
        let status = response.status();
        let content_type = response
            .headers()
            .get("content-type")
            .and_then(|v| v.to_str().ok())
            .unwrap_or("")
            .to_string();
        let bytes = axum::body::to_bytes(response.into_body(), usize::MAX)
            .await
            .unwrap();
        (status, content_type, bytes)
    });
    prop_assert!(
        !status.is_server_error(),
        "{method} {uri}: {status} {}",
        String::from_utf8_lossy(&bytes)
    );
    if status.is_client_error() {
        prop_assert!(
            content_type.starts_with("application/json"),
            "{uri}: {content_type}"
        );
        let answer: Value = serde_json::from_slice(&bytes)
            .map_err(|e| TestCaseError::fail(format!("{uri}: {status}: not JSON: {e}")))?;
        prop_assert!(answer["error"]["code"].is_string(), "{uri}: {answer}");
        prop_assert!(answer["error"]["message"].is_string(), "{uri}: {answer}");
    }
    Ok(status.as_u16())
}

/// Odd JSON values to put where a valid one was.
fn odd_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        any::<f64>().prop_map(|v| json!(v)),
        prop::sample::select(vec![
            json!(0),
            json!(-1),
            json!(1e308),
            json!(-1e308),
            json!(5e-324),
            json!(1e20),
            json!(u64::MAX),
            json!(0.5),
            json!(401),
            json!(402),
            json!(1e6),
        ]),
        "[a-z_0-9\\[\\]\\.]{0,12}".prop_map(Value::from),
        prop::sample::select(vec![
            "pendulum",
            "modin_3s",
            "csv1",
            "rk4",
            "reference",
            "polar",
            "cartesian",
            "q0[0]",
            "params.gamma",
            "h",
            "log",
            "sys-0123456789abcdef",
            "kahan_li_8",
            "blanes_casas_murua_8",
            "x^2",
            "sin(",
        ])
        .prop_map(Value::from),
    ];
    leaf.prop_recursive(3, 24, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(Value::from),
            prop::collection::btree_map("[a-z_]{1,8}", inner, 0..3)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// Every location (as a path of keys and indices) in `value`.
fn locations(value: &Value, here: &mut Vec<Value>, out: &mut Vec<Vec<Value>>) {
    out.push(here.clone());
    match value {
        Value::Object(map) => {
            for (k, v) in map {
                here.push(Value::from(k.as_str()));
                locations(v, here, out);
                here.pop();
            }
        }
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                here.push(Value::from(i));
                locations(v, here, out);
                here.pop();
            }
        }
        _ => {}
    }
}

fn at<'a>(value: &'a mut Value, path: &[Value]) -> &'a mut Value {
    path.iter().fold(value, |v, key| match key {
        Value::String(k) => &mut v[k.as_str()],
        Value::Number(i) => &mut v[i.as_u64().unwrap() as usize],
        _ => unreachable!(),
    })
}

/// One change to a JSON document.
#[derive(Clone, Debug)]
enum Mutation {
    Replace(usize, Value),
    Remove(usize),
    AddKey(usize, String, Value),
}

fn mutate(seed: &Value, mutations: &[Mutation]) -> Value {
    let mut doc = seed.clone();
    for m in mutations {
        let mut all = Vec::new();
        locations(&doc, &mut Vec::new(), &mut all);
        match m {
            Mutation::Replace(i, v) => *at(&mut doc, &all[i % all.len()]) = v.clone(),
            Mutation::Remove(i) => {
                let path = &all[i % all.len()];
                if let Some((last, parent)) = path.split_last() {
                    match (at(&mut doc, parent), last) {
                        (Value::Object(map), Value::String(k)) => {
                            map.remove(k);
                        }
                        (Value::Array(items), Value::Number(n)) => {
                            items.remove(n.as_u64().unwrap() as usize);
                        }
                        _ => {}
                    }
                }
            }
            Mutation::AddKey(i, k, v) => {
                if let Value::Object(map) = at(&mut doc, &all[i % all.len()]) {
                    map.insert(k.clone(), v.clone());
                }
            }
        }
    }
    doc
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        4 => (any::<usize>(), odd_value()).prop_map(|(i, v)| Mutation::Replace(i, v)),
        1 => any::<usize>().prop_map(Mutation::Remove),
        1 => (any::<usize>(), "[a-z_]{1,10}", odd_value()).prop_map(|(i, k, v)| Mutation::AddKey(i, k, v)),
    ]
}

/// Byte-level damage to a serialised body: flips, cuts, splices, invalid UTF-8.
fn damage(text: &[u8], edits: &[(usize, u8, u8)]) -> Vec<u8> {
    let mut bytes = text.to_vec();
    for &(at, kind, byte) in edits {
        if bytes.is_empty() {
            break;
        }
        let i = at % bytes.len();
        match kind % 4 {
            0 => bytes[i] = byte,
            1 => bytes.insert(i, byte),
            2 => {
                bytes.remove(i);
            }
            _ => bytes.truncate(i),
        }
    }
    bytes
}

/// An input to a route: a body (mutated JSON, or damaged bytes), a query and a content type.
#[derive(Clone, Debug)]
struct Input {
    body: Vec<u8>,
    query: String,
    content_type: Option<&'static str>,
}

fn input(seeds: Vec<Value>) -> impl Strategy<Value = Input> {
    let content_type = prop_oneof![
        8 => Just(Some("application/json")),
        1 => Just(None),
        1 => prop::sample::select(vec![
            Some("text/plain"), Some("application/x-www-form-urlencoded"),
            Some("application/octet-stream"), Some("application/problem+json; charset=utf-8"),
            Some("multipart/form-data; boundary=x"), Some("application/json; charset=latin1"),
        ]),
    ];
    let query = prop_oneof![
        6 => Just(String::new()),
        1 => prop::sample::select(vec!["?format=json", "?format=ndjson", "?format=rrd", "?format=",
            "?format=xml", "?format=rrd&format=json", "?%ff=%fe", "?format=%00"]).prop_map(String::from),
        1 => "\\?[a-z=&%0-9]{0,16}",
    ];
    let body = (
        prop::sample::select(seeds),
        prop::collection::vec(mutation(), 0..4),
        prop::option::weighted(
            0.2,
            prop::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..5),
        ),
    )
        .prop_map(|(seed, mutations, edits)| {
            let text = serde_json::to_vec(&mutate(&seed, &mutations)).unwrap();
            match edits {
                Some(edits) => damage(&text, &edits),
                None => text,
            }
        });
    (body, query, content_type).prop_map(|(body, query, content_type)| Input {
        body,
        query,
        content_type,
    })
}

fn fuzz(path: &str, seeds: Vec<Value>) {
    let mut runner = TestRunner::new(RunnerConfig {
        failure_persistence: None,
        ..RunnerConfig::default()
    });
    let answered: [std::sync::atomic::AtomicU64; 6] = Default::default();
    let result = runner.run(&input(seeds), |input| {
        let uri = format!("{path}{}", input.query);
        let status = send("POST", &uri, input.content_type, input.body)?;
        answered[(status / 100) as usize].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(())
    });
    if let Err(e) = result {
        panic!("{path}: {e}");
    }
    // The mutations must reach past the reader now and then, or this tests only the parser.
    let accepted = answered[2].load(std::sync::atomic::Ordering::Relaxed);
    assert!(accepted > 0, "{path}: no case was accepted: {answered:?}");
}

#[test]
fn simulate() {
    fuzz(
        "/api/v1/simulate",
        vec![
            json!({"system": "pendulum", "methods": ["modin_3s", "heun"], "h": 0.1, "t_end": 20, "output": {"every": 10}}),
            json!({"system": "elastic_pendulum_3d", "method": {"id": "kahan_li_8", "base": "modin_3s"}, "h": 0.05, "t_end": 5, "chart": "cartesian"}),
            json!({"system": "harmonic_oscillator", "params": {"omega": 2, "gamma": 0.1}, "method": "csv1", "q0": [1], "p0": [0], "h": 0.1, "t_end": 10, "compare_to_reference": true}),
        ],
    );
}

#[test]
fn recordings() {
    fuzz(
        "/api/v1/recordings",
        vec![json!({"system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 10})],
    );
}

#[test]
fn allowed_region() {
    fuzz(
        "/api/v1/simulate/allowed-region",
        vec![
            json!({"system": "henon_heiles", "method": "rk4", "h": 0.1, "t_end": 1,
            "q0": [0, 0], "p0": [0, 0], "energy": {"value": 0.125, "momentum": "p_x"},
            "plane": {"x": {"name": "y", "min": -0.5, "max": 0.5, "points": 4},
                      "y": {"name": "p_y", "min": -0.5, "max": 0.5, "points": 3}}}),
        ],
    );
}

#[test]
fn stability() {
    fuzz(
        "/api/v1/stability",
        vec![
            json!({"methods": ["csv1"], "omega": 3.51, "gamma": {"min": 0, "max": 3.5, "n": 8}, "h": {"min": 0, "max": 1, "n": 8}}),
        ],
    );
    fuzz(
        "/api/v1/stability/point",
        vec![json!({"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": 0.2})],
    );
}

#[test]
fn studies_work_precision() {
    fuzz(
        "/api/v1/studies/work-precision",
        vec![json!({
        "system": "harmonic_oscillator", "params": {"omega": 2, "gamma": 0.1},
        "q0": [1.0], "p0": [0.0], "t_end": 5, "samples": 5,
        "runs": [{"method": "csv1", "h": [0.1, 0.05]}, {"method": {"id": "kahan_li_8", "base": "csv1"}, "h": [0.5]}]})],
    );
}

#[test]
fn studies_convergence() {
    fuzz(
        "/api/v1/studies/convergence",
        vec![json!({
        "system": "harmonic_oscillator", "params": {"omega": 1, "gamma": 0},
        "charts": ["cartesian"], "q0": [1], "p0": [0], "t_end": 2,
        "methods": ["symplectic_euler"], "h": [0.04, 0.02, 0.01]})],
    );
}

#[test]
fn studies_energy_map() {
    fuzz(
        "/api/v1/studies/energy-map",
        vec![json!({"nx": 3, "ny": 3, "t_max": 20})],
    );
}

#[test]
fn studies_sweep() {
    fuzz(
        "/api/v1/studies/sweep",
        vec![json!({
        "system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 5, "every": 5,
        "axes": [{"name": "params.gamma", "min": 0.01, "max": 1, "n": 3, "scale": "log"}]})],
    );
}

#[test]
fn systems() {
    fuzz(
        "/api/v1/systems",
        vec![json!({
        "coordinates": ["x", "y"], "momenta": ["px", "py"], "mass": 1,
        "potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*y",
        "parameters": {"k": 1, "l": 1, "m": 1, "g": 0.2},
        "invariants": {"L": "x*py - y*px"}, "q0": [1.2, 0.3], "p0": [0, 0]})],
    );
}

#[test]
fn ids_in_paths() {
    let mut runner = TestRunner::new(RunnerConfig {
        failure_persistence: None,
        ..RunnerConfig::default()
    });
    let id = prop_oneof![
        "[0-9a-f]{32}",
        "sys-[0-9a-f]{16}",
        "(%2e|%2E|\\.|%2f|%5c|%00|%25|/|[a-z0-9])[a-z0-9%./_-]{0,40}",
        prop::collection::vec(any::<u8>(), 0..24)
            .prop_map(|b| { b.iter().map(|c| format!("%{c:02x}")).collect::<String>() }),
    ];
    let route = prop::sample::select(vec![
        ("GET", "/api/v1/recordings/{}"),
        ("GET", "/api/v1/recordings/{}.rrd"),
        ("GET", "/api/v1/recordings/{}/samples"),
        ("DELETE", "/api/v1/recordings/{}"),
        ("GET", "/api/v1/systems/{}"),
        ("DELETE", "/api/v1/systems/{}"),
        ("GET", "/api/v1/methods/{}"),
        ("GET", "/{}"),
    ]);
    runner
        .run(&(route, id), |((method, template), id)| {
            let status = send(method, &template.replace("{}", &id), None, Vec::new())?;
            prop_assert!(
                status != 200 || template == "/{}" || template.contains("methods"),
                "{template} {id}"
            );
            Ok(())
        })
        .unwrap();
}

#[test]
fn hostile_bodies_named_outright() {
    let deep = |n: usize| format!("{}{}", "[".repeat(n), "]".repeat(n)).into_bytes();
    let deep_object = |n: usize| format!("{}1{}", "{\"a\":".repeat(n), "}".repeat(n)).into_bytes();
    let cases: Vec<(Option<&str>, Vec<u8>, u16)> = vec![
        (Some("application/json"), deep(100_000), 400),
        (Some("application/json"), deep_object(100_000), 400),
        (Some("application/json"), br#"{"system": "pendulum", "method": "rk4", "h": 1e999, "t_end": 1}"#.to_vec(), 400),
        (Some("application/json"), br#"{"system": "pendulum", "method": "rk4", "h": 0.1, "t_end": 123456789012345678901234567890}"#.to_vec(), 422),
        (Some("application/json"), br#"{"system": "pendulum", "method": "rk4", "h": 0.1, "h": 0.2, "t_end": 1}"#.to_vec(), 400),
        (Some("application/json"), b"{\"system\": \"pend\xffulum\", \"method\": \"rk4\", \"h\": 0.1, \"t_end\": 1}".to_vec(), 400),
        (Some("application/json"), b"\xef\xbb\xbf{}".to_vec(), 400),
        (Some("application/json"), Vec::new(), 400),
        (Some("text/plain"), br#"{"system": "pendulum", "method": "rk4", "h": 0.1, "t_end": 1}"#.to_vec(), 415),
        (Some("application/x-www-form-urlencoded"), b"system=pendulum".to_vec(), 415),
        (Some("application/json"), vec![b' '; 2 << 20], 413),
    ];
    for path in [
        "/api/v1/simulate",
        "/api/v1/studies/sweep",
        "/api/v1/systems",
        "/api/v1/stability",
    ] {
        for (content_type, body, expected) in &cases {
            let status = send("POST", path, *content_type, body.clone())
                .unwrap_or_else(|e| panic!("{path}: {e}"));
            // Every route reads bodies alike up to the request's own fields.
            if *expected != 422 {
                assert_eq!(
                    status,
                    *expected,
                    "{path}: {}",
                    String::from_utf8_lossy(&body[..body.len().min(80)])
                );
            } else {
                assert!((400..500).contains(&status), "{path}: {status}");
            }
        }
    }
}

/// Found by the studies targets: a t_max/h near u64::MAX overflowed the energy map's work check
/// (a panic in debug builds, a wrapped product that passed the limit in release).
#[test]
fn an_energy_map_of_astronomically_many_steps_is_refused() {
    for t_max in [1e300, 1.8e19, 1e17] {
        let body = json!({"nx": 3, "ny": 3, "t_max": t_max});
        let status = send(
            "POST",
            "/api/v1/studies/energy-map",
            Some("application/json"),
            serde_json::to_vec(&body).unwrap(),
        )
        .unwrap();
        assert_eq!(status, 422, "t_max = {t_max}");
    }
}

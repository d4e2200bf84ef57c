//! Sweeps on NATS JetStream workers, with real processes: a `nats-server` with JetStream in a
//! temporary directory on a loopback port it picks, two `geomint worker`s and a `geomint serve
//! --nats`. The merged document equals the local executor's bit for bit; with one worker killed
//! (SIGKILL) mid-study its shard is handed out again and the document is still the same; a
//! client that goes away leaves no shard in the queue, and takes no other study's with it; a NATS
//! server stopped mid-study fails the study with `executor_unavailable` well within the time
//! limit; `serve --nats` without a server exits non-zero saying so.
//!
//! `nats-server` is a Debian package that the test command installs.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use geomint::api::sweep::SweepRequest;
use geomint::api::system::NoStoredSystems;
use geomint::core::run::Budget;
use geomint::core::simulation::Limits;
use geomint::core::studies::sweep;
use serde_json::{json, Value};

use crate::server;
use server::{client, spawn_listening, Process, SERVE_LISTENING, SERVE_LOG};

pub(crate) fn nats_server_binary() -> PathBuf {
    [
        "/usr/sbin/nats-server",
        "/usr/bin/nats-server",
        "/usr/local/bin/nats-server",
    ]
    .iter()
    .map(PathBuf::from)
    .find(|p| p.exists())
    .expect("nats-server is not installed: `apt-get install nats-server` (scripts/test does)")
}

pub(crate) fn scratch(name: &str) -> PathBuf {
    let dir = server::scratch_dir(&format!("nats-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A NATS server with JetStream storing under `dir`, on a port it picks (`-p -1`).
pub(crate) fn nats_server(dir: &Path) -> (Process, String) {
    let mut command = Command::new(nats_server_binary());
    command
        .args(["-a", "127.0.0.1", "-p", "-1", "-js", "-sd"])
        .arg(dir.join("jetstream"))
        .stdout(Stdio::null());
    let (process, address) = spawn_listening(
        command,
        "nats-server",
        "Listening for client connections on ",
    );
    (process, format!("nats://{address}"))
}

pub(crate) fn geomint() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_geomint"));
    command
        .env_remove("GEOMINT_NATS_URL")
        .env("GEOMINT_LOG", "warn");
    command
}

fn worker(url: &str) -> Process {
    Process(
        geomint()
            .args(["worker", "--nats", url, "--ack-wait-secs", "2"])
            .stdout(Stdio::null())
            .spawn()
            .unwrap(),
    )
}

/// `geomint serve --nats url` on a port of its own, with its data in `dir`.
fn server(url: &str, dir: &Path, time_limit_secs: u32) -> (Process, String) {
    server_with(url, dir, time_limit_secs, &[])
}

/// The same, with `extra` arguments.
pub(crate) fn server_with(
    url: &str,
    dir: &Path,
    time_limit_secs: u32,
    extra: &[&str],
) -> (Process, String) {
    let mut command = geomint();
    command
        .env(
            "GEOMINT_LOG",
            std::env::var("DBG_SERVE_LOG").unwrap_or(SERVE_LOG.into()),
        )
        .args(["serve", "--addr", "127.0.0.1:0", "--nats", url]);
    // An ack wait of 2 s and shards of 4·10⁷ steps unless the test gives its own.
    for (flag, value) in [
        ("--nats-ack-wait-secs", "2"),
        ("--nats-shard-steps", "40000000"),
    ] {
        if !extra.contains(&flag) {
            command.args([flag, value]);
        }
    }
    command
        .args(["--request-timeout-secs", &time_limit_secs.to_string()])
        .arg("--data-dir")
        .arg(dir.join("data"))
        .arg("--systems-dir")
        .arg(dir.join("systems"))
        .arg("--static-dir")
        .arg(dir.join("no-static"))
        .args(extra)
        .stdout(Stdio::null());
    let (process, address) = spawn_listening(command, "geomint serve", SERVE_LISTENING);
    (process, format!("http://{address}"))
}

/// The Fig. 6 sweep on a 12 × 10 grid: 120 cells of 2 × 5·10⁶ steps (several seconds on two
/// cores, four cells at a time in SIMD lanes), in 30 shards of 4·10⁷ steps (four cells each).
fn request() -> Value {
    json!({
        "system": "elastic_pendulum_2d",
        "params": {"g": 0.02},
        "charts": ["cartesian", "polar"],
        "initial_coordinates": "cartesian",
        "p0": [0.0, 0.0],
        "methods": ["symplectic_euler"],
        "h": 0.2,
        "t_end": 1000000,
        "axes": [
            {"name": "q0[0]", "min": -1.5, "max": 1.5, "n": 12},
            {"name": "q0[1]", "min": -1.5, "max": 1.5, "n": 10}
        ]
    })
}

/// The document of the local executor, without its wall time.
fn local() -> Value {
    let job = SweepRequest::from_value(&request())
        .unwrap()
        .to_spec(&NoStoredSystems)
        .unwrap()
        .prepare(&Limits::default())
        .unwrap();
    numbers(
        serde_json::to_value(
            sweep::run(
                &job,
                &geomint::core::studies::engine::Local,
                Budget::default(),
                &|_| true,
            )
            .unwrap(),
        )
        .unwrap(),
    )
}

/// A server's time limit the tests that compare whole documents cannot reach, however loaded the
/// machine (a study past its limit answers 200 with the cells it has, which would differ from the
/// local executor's).
const UNREACHED_LIMIT_SECS: u32 = 600;

/// Asserts the sweep finished (not stopped by the server's time limit), then compares it.
fn same_as_local(doc: Value, expected: &Value, what: &str) {
    assert_eq!(
        doc["stop"], "finished",
        "{what}: unfinished cells {}",
        doc["unfinished_cells"]
    );
    assert!(
        numbers(doc) == *expected,
        "{what}: the document differs from the local one"
    );
}

fn numbers(mut doc: Value) -> Value {
    doc.as_object_mut().unwrap().remove("wall_ms");
    doc
}

async fn post_sweep(base: &str) -> (u16, Value) {
    let response = client()
        .post(format!("{base}/api/v1/studies/sweep"))
        .json(&request())
        .send()
        .await
        .unwrap();
    let status = response.status().as_u16();
    let bytes = response.bytes().await.unwrap();
    (status, geomint::api::json::parse_json(&bytes).unwrap())
}

/// Workers and a server starting at the same moment on a fresh NATS server may each find no
/// stream and create it: every one of them comes up on the one stream and consumer, and a sweep
/// gives the local executor's numbers.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn workers_and_a_server_starting_together_share_one_queue() {
    let dir = scratch("together");
    let (_nats, url) = nats_server(&dir);
    let mut workers: Vec<Process> = (0..4).map(|_| worker(&url)).collect();
    let (_server, base) = server(&url, &dir, UNREACHED_LIMIT_SECS);
    let (status, doc) = post_sweep(&base).await;
    assert_eq!(status, 200, "{}", doc["error"]);
    let expected = tokio::task::spawn_blocking(local).await.unwrap();
    same_as_local(doc, &expected, "workers started with the server");
    for worker in &mut workers {
        assert!(
            worker.0.try_wait().unwrap().is_none(),
            "a worker exited at start-up"
        );
    }
}

/// Shards waiting in the queue.
async fn queued(url: &str) -> u64 {
    let client = async_nats::connect(url).await.unwrap();
    let js = async_nats::jetstream::new(client);
    let mut stream = js.get_stream(geomint::nats::STREAM).await.unwrap();
    stream.info().await.unwrap().state.messages
}

/// Waits until a study's shards are queued and the workers have finished at least one: the
/// study is then under way on the workers, with most of its shards still to do, whatever the
/// machine's speed.
async fn until_a_shard_is_done(url: &str) {
    let until = Instant::now() + Duration::from_secs(20);
    let mut most = 0;
    loop {
        let waiting = queued(url).await;
        if most > 0 && waiting < most {
            return;
        }
        most = most.max(waiting);
        assert!(Instant::now() < until, "no shard was done within 20 s");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sweeps_on_nats_workers_equal_the_local_executor() {
    let dir = scratch("workers");
    let (mut nats, url) = nats_server(&dir);
    let expected = tokio::task::spawn_blocking(local).await.unwrap();
    let mut first = worker(&url);
    let _second = worker(&url);
    let (_server, base) = server(&url, &dir, UNREACHED_LIMIT_SECS);

    // Two workers, nothing goes wrong.
    let started = Instant::now();
    let (status, doc) = post_sweep(&base).await;
    assert_eq!(status, 200, "{}", doc["error"]);
    same_as_local(doc, &expected, "two workers");
    eprintln!("two workers: {:.1} s", started.elapsed().as_secs_f64());

    // One worker killed mid-study: its shard goes to the other after the ack wait (2 s).
    let started = Instant::now();
    let sweep = tokio::spawn({
        let base = base.clone();
        async move { post_sweep(&base).await }
    });
    until_a_shard_is_done(&url).await;
    assert!(
        !sweep.is_finished(),
        "the sweep ended before a worker could be killed"
    );
    first.0.kill().unwrap();
    first.0.wait().unwrap();
    let (status, doc) = sweep.await.unwrap();
    assert_eq!(status, 200, "{}", doc["error"]);
    same_as_local(doc, &expected, "a worker killed mid-study");
    eprintln!(
        "one worker killed: {:.1} s",
        started.elapsed().as_secs_f64()
    );

    // A client that goes away: the shards no worker has started leave the queue.
    let gone = tokio::spawn({
        let base = base.clone();
        async move { post_sweep(&base).await }
    });
    tokio::time::sleep(Duration::from_millis(500)).await;
    gone.abort();
    let until = Instant::now() + Duration::from_secs(10);
    loop {
        let waiting = queued(&url).await;
        if waiting == 0 {
            break;
        }
        assert!(
            Instant::now() < until,
            "{waiting} shards still queued after the client left"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    // A server whose time limit (1 s) passes mid-study: 200 with the cells of the parts received
    // (the local executor's, bit for bit), the others listed as unfinished, the queue emptied.
    let (_hurried, hurried) = server(&url, &dir.join("hurried"), 1);
    let (status, doc) = post_sweep(&hurried).await;
    assert_eq!(status, 200, "{}", doc["error"]);
    assert_eq!(doc["stop"], "time_limit");
    let unfinished: Vec<u64> = doc["unfinished_cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_u64().unwrap())
        .collect();
    assert!(!unfinished.is_empty());
    let cells = expected["cells"].as_u64().unwrap() as usize;
    for (run, want) in doc["runs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(expected["runs"].as_array().unwrap())
    {
        for cell in 0..cells {
            if unfinished.contains(&(cell as u64)) {
                assert_eq!(run["energy_error_l2"][cell], Value::Null);
                assert_eq!(run["steps"][cell], 0);
            } else {
                for column in [
                    "energy_error_l2",
                    "energy_error_max",
                    "diverged_at",
                    "steps",
                ] {
                    assert_eq!(run[column][cell], want[column][cell], "{column}[{cell}]");
                }
            }
        }
    }
    eprintln!(
        "1 s time limit: {} of {cells} cells finished",
        cells - unfinished.len()
    );
    let until = Instant::now() + Duration::from_secs(10);
    while queued(&url).await > 0 {
        assert!(
            Instant::now() < until,
            "shards still queued after the time limit"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }

    // The NATS server stops mid-study: a clear error, long before the 60 s time limit.
    let sweep = tokio::spawn({
        let base = base.clone();
        async move { post_sweep(&base).await }
    });
    until_a_shard_is_done(&url).await;
    assert!(
        !sweep.is_finished(),
        "the sweep ended before the NATS server could be stopped"
    );
    let stopped = Instant::now();
    nats.0.kill().unwrap();
    nats.0.wait().unwrap();
    let (status, error) = sweep.await.unwrap();
    let waited = stopped.elapsed();
    assert_eq!(status, 502, "{}", error["error"]);
    assert_eq!(error["error"]["code"], "executor_unavailable");
    let message = error["error"]["message"].as_str().unwrap();
    assert!(message.contains("NATS server"), "{message}");
    assert!(
        waited < Duration::from_secs(20),
        "the error took {waited:?}"
    );
}

#[test]
fn serve_without_a_nats_server_says_so_and_exits_non_zero() {
    let (_held, port) = server::closed_port();
    let out = geomint()
        .args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--nats",
            &format!("nats://127.0.0.1:{port}"),
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("cannot connect (NATS server nats://127.0.0.1:"),
        "{stderr}"
    );
    let out = geomint()
        .args(["worker", "--nats", &format!("nats://127.0.0.1:{port}")])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
}

/// Messages the shard stream has taken so far (its last sequence number).
async fn shards_published(url: &str) -> u64 {
    let client = async_nats::connect(url).await.unwrap();
    let js = async_nats::jetstream::new(client);
    let mut stream = js.get_stream(geomint::nats::STREAM).await.unwrap();
    stream.info().await.unwrap().state.last_sequence
}

/// `value` without the members that hold wall times, at any depth.
fn untimed(mut value: Value) -> Value {
    fn walk(v: &mut Value) {
        match v {
            Value::Object(map) => {
                map.retain(|k, _| !["wall_ms", "reference_ms"].contains(&k.as_str()));
                map.values_mut().for_each(walk);
            }
            Value::Array(items) => items.iter_mut().for_each(walk),
            _ => {}
        }
    }
    walk(&mut value);
    value
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_study_on_nats_workers_equals_the_local_executor() {
    let dir = scratch("studies");
    let (_nats, url) = nats_server(&dir);
    let _worker = worker(&url);
    let (_server, base) = server(&url, &dir, UNREACHED_LIMIT_SECS);
    let local = server::start(geomint::http::Config::default()).await;
    let studies = [
        // Stability maps: rows of three methods' maps.
        (
            "/api/v1/stability",
            json!({"methods": ["csv1", "cimp", "rk4"], "omega": 3.51,
                "gamma": {"min": 0, "max": 3.5, "n": 41}, "h": {"min": 0.01, "max": 1, "n": 37}}),
        ),
        // A convergence study against a reference run, in two charts.
        (
            "/api/v1/studies/convergence",
            json!({"system": "elastic_pendulum_2d", "charts": ["cartesian", "polar"],
                "initial_coordinates": "cartesian", "q0": [0.3, 1.2], "p0": [0.1, 0.0],
                "t_end": 4, "methods": ["symplectic_euler", "rk4"], "h": [0.1, 0.05, 0.025]}),
        ),
        // An energy map: a sweep of both charts.
        (
            "/api/v1/studies/energy-map",
            json!({"nx": 9, "ny": 7, "t_max": 200}),
        ),
        // A chaos map on the energy surface, its cells stopped by a threshold.
        (
            "/api/v1/studies/sweep",
            json!({"system": "henon_heiles", "methods": ["velocity_verlet"],
                "q0": [0.0, 0.0], "p0": [0.0, 0.0], "h": 0.05, "t_end": 200, "every": 4000,
                "indicators": ["megno", "lyapunov"], "stop_when": {"megno_mean": 4},
                "energy_surface": {"energy": 0.125, "solve_for": "p0[0]"},
                "axes": [{"name": "q0[1]", "min": -0.45, "max": 0.65, "n": 9},
                         {"name": "p0[1]", "min": -0.5, "max": 0.5, "n": 7}]}),
        ),
        // A basin map: Hénon–Heiles's escapes through three exits, each cell stopped as it
        // leaves.
        (
            "/api/v1/studies/basins",
            json!({"system": "henon_heiles", "methods": ["velocity_verlet"],
                "q0": [0.0, 0.0], "p0": [0.0, 0.0], "h": 0.01, "t_end": 100,
                "energy_surface": {"energy": 0.25, "solve_for": "p0[0]"},
                "axes": [{"name": "q0[1]", "min": -0.6, "max": 1.0, "n": 9},
                         {"name": "p0[1]", "min": -0.6, "max": 0.6, "n": 7}],
                "exits": [{"name": "up", "where": "y - 2", "direction": "up"},
                          {"name": "left", "where": "-sqrt(3)/2*x - y/2 - 2", "direction": "up"},
                          {"name": "right", "where": "sqrt(3)/2*x - y/2 - 2", "direction": "up"}]}),
        ),
    ];
    for (path, request) in studies {
        let before = shards_published(&url).await;
        let (status, on_workers) = server::post_json_to(&base, path, &request).await;
        assert_eq!(status, 200, "{path}: {on_workers}");
        assert!(
            shards_published(&url).await > before,
            "{path}: no shard went to the workers"
        );
        let (status, here) = server::post_json(&local, path, &request).await;
        assert_eq!(status, 200, "{path}: {here}");
        assert!(
            untimed(on_workers) == untimed(here),
            "{path}: the workers' document differs from the local one"
        );
    }
    // A work–precision study times its settings on one machine: none goes to the workers.
    let before = shards_published(&url).await;
    let request = json!({"system": "harmonic_oscillator", "t_end": 10,
        "runs": [{"method": "csv1", "h": [0.1, 0.05]}]});
    let (status, doc) =
        server::post_json_to(&base, "/api/v1/studies/work-precision", &request).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(shards_published(&url).await, before);
}

/// POSTs the sweep `body` to the server at `base`: its status and its JSON.
pub(crate) fn post_study(
    base: &str,
    body: Value,
) -> impl std::future::Future<Output = (u16, Value)> + Send + 'static {
    let url = format!("{base}/api/v1/studies/sweep");
    async move {
        let response = client().post(url).json(&body).send().await.unwrap();
        let status = response.status().as_u16();
        (status, response.json::<Value>().await.unwrap())
    }
}

/// A small sweep (4 cells, one shard) whose last γ tells it from the others.
fn small_sweep(gamma_max: f64) -> Value {
    json!({
        "system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 20, "every": 5,
        "axes": [{"name": "params.gamma", "min": 0.001, "max": gamma_max, "n": 4}]
    })
}

async fn until_queued(url: &str, shards: u64) {
    let until = Instant::now() + Duration::from_secs(10);
    while queued(url).await != shards {
        assert!(
            Instant::now() < until,
            "the queue never held {shards} shards"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// A study that leaves the queue (its client gone) takes only its own shards with it: a study
/// queued before it still reaches the workers. Removing a study's shards by a filtered purge of
/// its subject moved the workers' consumer past every earlier message of the stream on the NATS
/// server this runs on (2.9), so the earlier study waited out its time limit with no part.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_study_that_leaves_the_queue_takes_only_its_own_shards() {
    let dir = scratch("leaves");
    let (_nats, url) = nats_server(&dir);
    let (_server, base) = server(&url, &dir, 60);
    let post = |body: Value| post_study(&base, body);
    // No worker yet: the first study's shard waits in the queue, then the second's.
    let first = tokio::spawn(post(small_sweep(0.5)));
    until_queued(&url, 1).await;
    let second = tokio::spawn(post(small_sweep(1.0)));
    until_queued(&url, 2).await;
    second.abort();
    until_queued(&url, 1).await;
    let _worker = worker(&url);
    let (status, doc) = tokio::time::timeout(Duration::from_secs(20), first)
        .await
        .expect("the first study got no part within 20 s of a worker starting")
        .unwrap();
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["stop"], "finished", "{doc}");
    assert!(
        doc["unfinished_cells"].as_array().is_none_or(Vec::is_empty),
        "{doc}"
    );
    assert_eq!(
        doc["runs"][0]["steps"],
        json!([200, 200, 200, 200]),
        "{doc}"
    );
    // The worker acknowledges a shard only once its part is out, so the study can answer a
    // moment before the queue is empty.
    until_queued(&url, 0).await;
}

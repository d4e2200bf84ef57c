//! Poison shards on real NATS workers: a `nats-server` with JetStream, `geomint worker`s made to
//! panic on one study's shard, or to die on it (`GEOMINT_WORKER_PANIC_ON`,
//! `GEOMINT_WORKER_ABORT_ON`, read by workers of debug builds only), and a `geomint serve --nats
//! --nats-max-deliver 3`. The poisoned study fails with `executor_unavailable` after 3
//! deliveries, within a bound, and the studies queued beside it complete.

use std::process::Stdio;
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::nats::{geomint, nats_server, post_study, scratch, server_with};
use crate::server::{client, Process};

/// The marker the worker panics on: a parameter value no other study uses.
const POISON: &str = "0.0123456789";

fn sweep(gamma_max: &str) -> Value {
    let body = format!(
        r#"{{"system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 20, "every": 5,
        "axes": [{{"name": "params.gamma", "min": 0.001, "max": {gamma_max}, "n": 4}}]}}"#
    );
    serde_json::from_str(&body).unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panicking_shard_fails_its_study_after_max_deliver_and_the_others_complete() {
    let dir = scratch("poison");
    let (_nats, url) = nats_server(&dir);
    let _worker = Process(
        geomint()
            .env("GEOMINT_WORKER_PANIC_ON", POISON)
            .args([
                "worker",
                "--nats",
                &url,
                "--ack-wait-secs",
                "2",
                "--nats-max-deliver",
                "3",
            ])
            .stdout(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let (_server, base) = server_with(&url, &dir, 60, &["--nats-max-deliver", "3"]);
    let post = |body: Value| post_study(&base, body);
    // The poisoned study's own time, not that of the join: on a loaded machine the healthy
    // studies beside it may take longer, which is not what the bound is about.
    let poisoned = async {
        let started = Instant::now();
        let answer = post(sweep(POISON)).await;
        (answer, started.elapsed())
    };
    let ((poisoned, elapsed), first, second) =
        tokio::join!(poisoned, post(sweep("0.5")), post(sweep("1")));
    let (status, error) = poisoned;
    assert_eq!(status, 502, "{error}");
    assert_eq!(error["error"]["code"], "executor_unavailable");
    let message = error["error"]["message"].as_str().unwrap();
    assert!(
        message.contains("panicked on each of its 3 deliveries"),
        "{message}"
    );
    // Three attempts, each given back at once: far within the ack waits a lost worker costs.
    assert!(elapsed < Duration::from_secs(30), "{elapsed:?}");
    for (status, doc) in [first, second] {
        assert_eq!(status, 200, "{doc}");
        assert_eq!(doc["cells"], 4, "{doc}");
        assert!(
            doc["unfinished_cells"].as_array().is_none_or(Vec::is_empty),
            "{doc}"
        );
    }
    // Nothing of the poisoned study stays queued.
    let client = async_nats::connect(&url).await.unwrap();
    let js = async_nats::jetstream::new(client);
    let mut stream = js.get_stream(geomint::nats::STREAM).await.unwrap();
    assert_eq!(stream.info().await.unwrap().state.messages, 0);
}

/// A shard that kills every worker that takes it, under a supervisor that starts a dead worker
/// again (as Kubernetes or systemd would): after 3 deliveries (each kills its worker; the next
/// goes out once the 2 s ack wait passes) JetStream publishes its max-deliveries advisory as a
/// worker asks for work again, and the study fails once no worker has spoken of the shard for
/// 3 more ack waits.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_shard_that_kills_its_workers_fails_its_study_after_max_deliver() {
    let dir = scratch("poison-abort");
    let (_nats, url) = nats_server(&dir);
    let start_worker = || {
        Process(
            geomint()
                .env("GEOMINT_WORKER_ABORT_ON", POISON)
                .args([
                    "worker",
                    "--nats",
                    &url,
                    "--ack-wait-secs",
                    "2",
                    "--nats-max-deliver",
                    "3",
                ])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap(),
        )
    };
    let mut workers: Vec<Process> = (0..2).map(|_| start_worker()).collect();
    let (_server, base) = server_with(&url, &dir, 60, &["--nats-max-deliver", "3"]);
    let started = Instant::now();
    let request = client()
        .post(format!("{base}/api/v1/studies/sweep"))
        .json(&sweep(POISON))
        .send();
    let mut request = Box::pin(request);
    let mut deaths = 0;
    let response = loop {
        tokio::select! {
            response = &mut request => break response.unwrap(),
            () = tokio::time::sleep(Duration::from_millis(100)) => {
                for worker in &mut workers {
                    if worker.0.try_wait().unwrap().is_some() {
                        deaths += 1;
                        *worker = start_worker();
                    }
                }
            }
        }
    };
    let status = response.status().as_u16();
    let error: Value = response.json().await.unwrap();
    assert_eq!(status, 502, "{error}");
    let message = error["error"]["message"].as_str().unwrap();
    assert!(
        message.contains("handed to workers 3 times (max_deliver)"),
        "{message}"
    );
    assert_eq!(deaths, 3, "each delivery killed a worker");
    // Three ack waits of 2 s, the advisory and three more ack waits: well within the 60 s time
    // limit.
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "{:?}",
        started.elapsed()
    );
}

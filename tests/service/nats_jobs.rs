//! Jobs and slow workers on real NATS workers (`nats-server` with JetStream, `geomint worker`
//! processes, `geomint serve --nats`): a job's parts run on the workers, not on the server, and
//! end with the synchronous route's document bit for bit; a shard whose every delivery went to a
//! worker that was then stopped (SIGSTOP) for longer than the ack wait is not taken for poison
//! once its workers continue; a job's parts run several at a time, so a stopped worker holds up
//! one part, not the job.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use futures_util::StreamExt;
use serde_json::{json, Value};

use crate::http_jobs::without_timings;
use crate::nats::{geomint, nats_server, nats_server_binary, scratch, server_with};
use crate::server::{free_port, get_json_at as get_json, post_json_to, spawn_listening, Process};

/// A worker with an ack wait of 2 s and 3 deliveries a shard, logging at `info` (each shard it
/// starts) to `log`.
fn worker(url: &str, log: &Path) -> Process {
    worker_with(url, log, &[])
}

/// The same, with more environment variables.
fn worker_with(url: &str, log: &Path, env: &[(&str, &str)]) -> Process {
    worker_waiting(url, log, env, "2")
}

/// The same, with an ack wait of `ack_wait_secs`.
fn worker_waiting(url: &str, log: &Path, env: &[(&str, &str)], ack_wait_secs: &str) -> Process {
    Process(
        geomint()
            .envs(env.iter().copied())
            .env("GEOMINT_LOG", "info")
            .args([
                "worker",
                "--nats",
                url,
                "--ack-wait-secs",
                ack_wait_secs,
                "--nats-max-deliver",
                "3",
            ])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(log).unwrap())
            .spawn()
            .unwrap(),
    )
}

/// A Hénon–Heiles sweep of 120 cells of 4·10⁵ steps: job parts of about 4·10⁶ steps (8, each a
/// whole number of SIMD groups).
fn henon_heiles_sweep() -> Value {
    json!({
        "system": "henon_heiles", "methods": ["velocity_verlet", "rk4"], "h": 0.01, "t_end": 2000,
        "every": 1000, "q0": [0, 0.1], "p0": [0.35, 0],
        "axes": [{"name": "q0[1]", "min": -0.2, "max": 0.2, "n": 12},
                 {"name": "p0[1]", "min": -0.1, "max": 0.1, "n": 10}]
    })
}

/// Submits `sweep` as a job; the URL of its status.
async fn submit_sweep(base: &str, sweep: &Value) -> String {
    let body = json!({"study": "sweep", "request": sweep});
    let (status, job) = post_json_to(base, "/api/v1/jobs", &body).await;
    assert_eq!(status, 202, "{job}");
    format!("{base}/api/v1/jobs/{}", job["id"].as_str().unwrap())
}

/// The job's status once it has ended (within 5 minutes).
async fn until_ended(status_url: &str) -> Value {
    let until = Instant::now() + Duration::from_secs(300);
    loop {
        let job = get_json(status_url.to_string()).await;
        if job["state"] != "running" && job["state"] != "queued" {
            return job;
        }
        assert!(Instant::now() < until, "the job did not end: {job}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// The document of `sweep` on a server without NATS (its data in scratch `label`).
async fn local_sweep(label: &str, sweep: &Value) -> Value {
    let dir = scratch(label);
    let local = crate::server::start(geomint::http::Config {
        data_dir: dir.join("recordings"),
        systems_dir: dir.join("systems"),
        ..geomint::http::Config::default()
    })
    .await;
    let (status, expected) = post_json_to(&local.base, "/api/v1/studies/sweep", sweep).await;
    assert_eq!(status, 200, "{expected}");
    expected
}

/// A job submitted to a server with NATS workers waits for them: with none running, no cell is
/// done on the server; once two start, the job's parts (cut again into shards of their cells)
/// run on them, and the job's document is the synchronous sweep's bit for bit.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_jobs_parts_run_on_the_nats_workers() {
    let dir = scratch("jobs");
    let (_nats, url) = nats_server(&dir);
    let (_server, base) = server_with(
        &url,
        &dir,
        600,
        &[
            "--jobs-dir",
            dir.join("jobs").to_str().unwrap(),
            "--job-part-steps",
            "4000000",
        ],
    );
    let sweep = henon_heiles_sweep();
    let status_url = submit_sweep(&base, &sweep).await;
    // Two seconds without a worker: the job has started, and not one cell was run here.
    let until = Instant::now() + Duration::from_secs(20);
    while get_json(status_url.clone()).await["state"] != "running" {
        assert!(Instant::now() < until, "the job never started");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    let waiting = get_json(status_url.clone()).await;
    assert_eq!(waiting["state"], "running", "{waiting}");
    assert_eq!(waiting["cells_done"], 0, "{waiting}");
    let parts = waiting["parts"].as_u64().unwrap();
    assert!(parts >= 4, "{waiting}");

    let logs: Vec<PathBuf> = (0..2)
        .map(|i| dir.join(format!("worker-{i}.log")))
        .collect();
    let _workers: Vec<Process> = logs.iter().map(|log| worker(&url, log)).collect();
    let done = until_ended(&status_url).await;
    assert_eq!(done["state"], "done", "{done}");
    assert_eq!(done["parts_done"], parts, "{done}");
    // Every part went to the workers as shards of its own cells.
    let started: usize = logs
        .iter()
        .map(|log| {
            std::fs::read_to_string(log)
                .unwrap()
                .matches("shard started")
                .count()
        })
        .sum();
    assert!(
        started as u64 >= parts,
        "{started} shards for {parts} parts"
    );
    let from_job = get_json(format!("{status_url}/result")).await;
    let (status, direct) = post_json_to(&base, "/api/v1/studies/sweep", &sweep).await;
    assert_eq!(status, 200, "{direct}");
    assert_eq!(direct["stop"], "finished", "{direct}");
    assert_eq!(without_timings(&from_job), without_timings(&direct));
}

/// A job's parts on NATS workers run several at a time (`--job-parts-in-flight`, 8 by default):
/// a worker stopped (SIGSTOP) in the middle of a part, with an ack wait of a minute, holds up
/// that part only. The other worker finishes every other part meanwhile, where with one part in
/// flight the job would wait the minute; once the stopped worker continues, the job ends with
/// the synchronous sweep's document bit for bit.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stopped_worker_holds_up_one_part_of_a_job_not_the_job() {
    let dir = scratch("in-flight");
    let (_nats, url) = nats_server(&dir);
    // Parts of one shard each (112 cells of 1.2·10⁶ steps), a second or two of a worker, so
    // that the stop lands in the middle of one; the consumer's ack wait a minute, so that
    // JetStream does not move the stopped worker's shard to the other within the test.
    let (_server, base) = server_with(
        &url,
        &dir,
        600,
        &[
            "--nats-ack-wait-secs",
            "60",
            "--nats-shard-steps",
            "200000000",
            "--jobs-dir",
            dir.join("jobs").to_str().unwrap(),
            "--job-part-steps",
            "120000000",
        ],
    );
    let logs: Vec<PathBuf> = (0..2)
        .map(|i| dir.join(format!("worker-{i}.log")))
        .collect();
    let workers: Vec<Process> = (logs.iter())
        .map(|log| worker_waiting(&url, log, &[], "60"))
        .collect();
    let mut sweep = henon_heiles_sweep();
    sweep["t_end"] = json!(6000);
    sweep["axes"][0]["n"] = json!(20);
    sweep["axes"][1]["n"] = json!(20);
    let status_url = submit_sweep(&base, &sweep).await;

    // The first worker to start a shard is stopped in the middle of it.
    let until = Instant::now() + Duration::from_secs(60);
    let holder = loop {
        if let Some(holder) = started_by_another(&logs, &[]) {
            signal(&workers[holder], "-STOP");
            break holder;
        }
        assert!(Instant::now() < until, "no worker started a shard in 60 s");
        tokio::time::sleep(Duration::from_millis(5)).await;
    };
    // The other worker finishes every other part while it is stopped.
    let until = Instant::now() + Duration::from_secs(40);
    let waiting = loop {
        let job = get_json(status_url.clone()).await;
        let parts = job["parts"].as_u64().unwrap();
        if job["parts_done"].as_u64() == Some(parts - 1) {
            break job;
        }
        assert_ne!(
            job["state"], "done",
            "worker {holder} was stopped after its shard, holding nothing: {job}"
        );
        assert!(
            Instant::now() < until,
            "the job's other parts did not end while worker {holder} was stopped: {job}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert!(waiting["parts"].as_u64().unwrap() >= 4, "{waiting}");
    assert_eq!(waiting["state"], "running", "{waiting}");
    assert!(
        waiting["cells_done"].as_u64() < waiting["cells"].as_u64(),
        "{waiting}"
    );
    signal(&workers[holder], "-CONT");
    let done = until_ended(&status_url).await;
    assert_eq!(done["state"], "done", "{done}");
    let from_job = get_json(format!("{status_url}/result")).await;
    let expected = local_sweep("in-flight-local", &sweep).await;
    assert_eq!(without_timings(&from_job), without_timings(&expected));
}

/// The Fig. 6 sweep on 2 × 2 cells: one shard of 4·10⁷ steps.
fn one_shard_sweep() -> Value {
    json!({
        "system": "elastic_pendulum_2d", "params": {"g": 0.02},
        "charts": ["cartesian", "polar"], "initial_coordinates": "cartesian", "p0": [0.0, 0.0],
        "methods": ["symplectic_euler"], "h": 0.2, "t_end": 1000000,
        "axes": [{"name": "q0[0]", "min": -1.5, "max": 1.5, "n": 2},
                 {"name": "q0[1]", "min": -1.5, "max": 1.5, "n": 2}]
    })
}

/// A worker not yet stopped that has logged starting the shard, if there is one.
fn started_by_another(logs: &[PathBuf], stopped: &[usize]) -> Option<usize> {
    (0..logs.len()).find(|i| {
        !stopped.contains(i)
            && std::fs::read_to_string(&logs[*i]).is_ok_and(|text| text.contains("shard started"))
    })
}

fn signal(process: &Process, name: &str) {
    let status = std::process::Command::new("kill")
        .args([name, &process.0.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
}

/// A shard handed to workers in turn, each stopped (SIGSTOP) as soon as it starts it and kept
/// stopped past the 2 s ack wait, until JetStream has spent the shard's 3 deliveries and published
/// its max-deliveries advisory (watched here too). The workers are then continued: they report
/// progress, the server waits for them rather than failing the study as poisoned, and the sweep
/// ends with the same document as without any stop.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_shard_whose_workers_were_stopped_past_the_ack_wait_is_not_poison() {
    let dir = scratch("stopped");
    let (_nats, url) = nats_server(&dir);
    let logs: Vec<PathBuf> = (0..4)
        .map(|i| dir.join(format!("worker-{i}.log")))
        .collect();
    let workers: Vec<Process> = logs.iter().map(|log| worker(&url, log)).collect();
    let (_server, base) = server_with(&url, &dir, 600, &["--nats-max-deliver", "3"]);
    let watcher = async_nats::connect(url.as_str()).await.unwrap();
    let mut advisories = watcher
        .subscribe(geomint::nats::poison::advisory())
        .await
        .unwrap();
    watcher.flush().await.unwrap();
    let request = one_shard_sweep();
    let posted = tokio::spawn({
        let base = base.clone();
        let request = request.clone();
        async move { post_json_to(&base, "/api/v1/studies/sweep", &request).await }
    });
    // Each worker that starts the shard is stopped, until JetStream says the shard's deliveries
    // are spent. That is usually after three workers; a delivery that reaches a worker's request
    // for work just as it expires is spent too, without a worker starting it.
    let mut stopped = Vec::new();
    let until = Instant::now() + Duration::from_secs(60);
    loop {
        if let Some(holder) = started_by_another(&logs, &stopped) {
            signal(&workers[holder], "-STOP");
            stopped.push(holder);
        }
        let advisory = tokio::time::timeout(Duration::from_millis(10), advisories.next()).await;
        if advisory.is_ok() {
            break;
        }
        assert!(
            Instant::now() < until,
            "no max-deliveries advisory in 60 s; workers stopped: {stopped:?}"
        );
    }
    assert!(!stopped.is_empty() && stopped.len() < 4, "{stopped:?}");
    // The server has heard the advisory too, and waits for the stopped workers.
    tokio::time::sleep(Duration::from_secs(1)).await;
    assert!(
        !posted.is_finished(),
        "the study ended while its workers were stopped"
    );
    for &i in &stopped {
        signal(&workers[i], "-CONT");
    }
    let (status, doc) = tokio::time::timeout(Duration::from_secs(120), posted)
        .await
        .expect("the study ends once its workers continue")
        .unwrap();
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["stop"], "finished", "{doc}");

    // The same sweep on a server without NATS.
    let expected = local_sweep("stopped-local", &request).await;
    assert_eq!(without_timings(&doc), without_timings(&expected));
}

/// A JetStream cluster of three `nats-server`s on loopback (each with its own client and cluster
/// port and store): the processes and their client URLs.
fn nats_cluster(dir: &Path) -> Vec<(Process, String)> {
    let ports: Vec<(u16, u16)> = (0..3).map(|_| (free_port(), free_port())).collect();
    let routes: Vec<String> = (ports.iter())
        .map(|(_, cluster)| format!("nats://127.0.0.1:{cluster}"))
        .collect();
    let routes = routes.join(",");
    ports
        .iter()
        .enumerate()
        .map(|(i, (client, cluster))| {
            let mut command = Command::new(nats_server_binary());
            command
                .args(["-a", "127.0.0.1", "-p", &client.to_string(), "-js", "-sd"])
                .arg(dir.join(format!("node-{i}")))
                .args(["--server_name", &format!("node-{i}")])
                .args(["--cluster_name", "geomint-test"])
                .args(["--cluster", &format!("nats://127.0.0.1:{cluster}")])
                .args(["--routes", &routes])
                .stdout(Stdio::null());
            let (process, address) = spawn_listening(
                command,
                "nats-server",
                "Listening for client connections on ",
            );
            (process, format!("nats://{address}"))
        })
        .collect()
}

/// Waits until the cluster at `url` places a stream on all three servers (its JetStream meta
/// leader elected, every server a peer).
async fn until_the_cluster_places_three_replicas(url: &str) {
    let client = async_nats::connect(url).await.unwrap();
    let js = async_nats::jetstream::new(client);
    let until = Instant::now() + Duration::from_secs(60);
    loop {
        let made = js
            .create_stream(async_nats::jetstream::stream::Config {
                name: "READY".into(),
                subjects: vec!["ready".into()],
                num_replicas: 3,
                ..Default::default()
            })
            .await;
        if made.is_ok() {
            js.delete_stream("READY").await.unwrap();
            return;
        }
        assert!(
            Instant::now() < until,
            "the cluster placed no stream in 60 s: {made:?}"
        );
        tokio::time::sleep(Duration::from_millis(250)).await;
    }
}

/// The shard stream's info, or the error of either call (a cluster electing a leader answers
/// neither for a while).
async fn stream_info(
    js: &async_nats::jetstream::Context,
) -> Result<async_nats::jetstream::stream::Info, String> {
    let mut stream = (js.get_stream(geomint::nats::STREAM).await).map_err(|e| e.to_string())?;
    stream.info().await.cloned().map_err(|e| e.to_string())
}

/// The name of the shard stream's leader, if it has one now.
async fn stream_leader(js: &async_nats::jetstream::Context) -> Result<Option<String>, String> {
    let info = stream_info(js).await?;
    Ok(info.cluster.and_then(|c| c.leader))
}

/// A job on workers of a JetStream cluster of three servers whose shard stream has three copies
/// (`--nats-replicas 3`): the stream's leader is killed (SIGKILL) mid-job; the cluster elects
/// another, the service and the workers connected to the dead server move to the others, and
/// the job ends with the document of a server without NATS.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_outlives_a_killed_server_of_a_three_server_jetstream_cluster() {
    let dir = scratch("cluster");
    let mut nodes = nats_cluster(&dir);
    let urls: Vec<String> = nodes.iter().map(|(_, url)| url.clone()).collect();
    until_the_cluster_places_three_replicas(&urls[0]).await;
    let url = urls.join(",");
    let jobs = dir.join("jobs");
    let (_server, base) = server_with(
        &url,
        &dir,
        600,
        &[
            "--nats-replicas",
            "3",
            "--jobs-dir",
            jobs.to_str().unwrap(),
            "--job-part-steps",
            "4000000",
        ],
    );
    let logs: Vec<PathBuf> = (0..2)
        .map(|i| dir.join(format!("worker-{i}.log")))
        .collect();
    let _workers: Vec<Process> = logs.iter().map(|log| worker(&url, log)).collect();
    let sweep = henon_heiles_sweep();
    let status_url = submit_sweep(&base, &sweep).await;
    let until = Instant::now() + Duration::from_secs(120);
    loop {
        // Queued until the server has looked for jobs to take back in its bucket.
        let job = get_json(status_url.clone()).await;
        let state = job["state"].as_str().unwrap();
        assert!(state == "running" || state == "queued", "{job}");
        if job["parts_done"].as_u64().unwrap() >= 2 {
            break;
        }
        assert!(Instant::now() < until, "no 2 parts in 2 minutes: {job}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    // The stream's leader goes: the cluster must elect another to go on.
    let leader = {
        let client = async_nats::connect(urls[0].as_str()).await.unwrap();
        let js = async_nats::jetstream::new(client);
        let until = Instant::now() + Duration::from_secs(60);
        loop {
            match stream_leader(&js).await {
                Ok(Some(leader)) => break leader,
                Ok(None) => assert!(Instant::now() < until, "no stream leader in 60 s"),
                Err(e) => assert!(Instant::now() < until, "no stream info in 60 s: {e}"),
            }
            tokio::time::sleep(Duration::from_millis(250)).await;
        }
    };
    let index: usize = leader.trim_start_matches("node-").parse().unwrap();
    let (mut killed, _) = nodes.remove(index);
    killed.0.kill().unwrap();
    killed.0.wait().unwrap();
    let alive = &urls[if index == 0 { 1 } else { 0 }];
    let done = until_ended(&status_url).await;
    assert_eq!(done["state"], "done", "{done}");
    let from_job = get_json(format!("{status_url}/result")).await;
    // The stream has its three copies, two of them alive. (The job can end before the cluster
    // has a JetStream meta leader again, which the stream's info waits for.)
    let client = async_nats::connect(alive.as_str()).await.unwrap();
    let js = async_nats::jetstream::new(client);
    let until = Instant::now() + Duration::from_secs(60);
    let replicas = loop {
        match stream_info(&js).await {
            Ok(info) => break info.config.num_replicas,
            Err(e) => assert!(Instant::now() < until, "no stream info in 60 s: {e}"),
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    };
    assert_eq!(replicas, 3);

    let expected = local_sweep("cluster-local", &sweep).await;
    assert_eq!(without_timings(&from_job), without_timings(&expected));
}

/// A part lost on its way to the server: the worker acknowledges its task and the part never
/// arrives (`GEOMINT_WORKER_LOSE_PART_ON`, as a part sent while the server moves to another NATS
/// server would be lost). After an ack wait without a word from the workers the server finds the
/// task gone from the stream, twice in a row, queues it again, and the sweep ends with the
/// document of a server without NATS.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_part_lost_on_its_way_is_queued_again() {
    let dir = scratch("lost-part");
    let (_nats, url) = nats_server(&dir);
    let log = dir.join("worker.log");
    let lose = [("GEOMINT_WORKER_LOSE_PART_ON", "elastic_pendulum_2d")];
    let _worker = worker_with(&url, &log, &lose);
    // A server that never queues the shard again ends the sweep at its 60 s limit, unfinished.
    let (_server, base) = server_with(&url, &dir, 60, &[]);
    let request = one_shard_sweep();
    let (status, doc) = post_json_to(&base, "/api/v1/studies/sweep", &request).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["stop"], "finished", "{doc}");
    let text = std::fs::read_to_string(&log).unwrap();
    assert_eq!(text.matches("a test's part is lost").count(), 1, "{text}");
    assert_eq!(text.matches("shard started").count(), 2, "{text}");

    let expected = local_sweep("lost-part-local", &request).await;
    assert_eq!(without_timings(&doc), without_timings(&expected));
}

/// The names the jobs' bucket `geomint-jobs` keeps on the NATS server at `url`.
async fn bucket_names(url: &str) -> Vec<String> {
    let client = async_nats::connect(url).await.unwrap();
    let bucket = async_nats::jetstream::new(client)
        .get_object_store("geomint-jobs")
        .await
        .unwrap();
    let mut list = bucket.list().await.unwrap();
    let mut names = Vec::new();
    while let Some(info) = list.next().await {
        names.push(info.unwrap().name);
    }
    names
}

/// A server with NATS keeps its jobs' files in a JetStream object store as well as on its disk.
/// Killed (SIGKILL) mid-job, its jobs directory then deleted, it is replaced by a server with an
/// empty jobs directory on the same NATS server: that one takes the job back from the bucket and
/// ends it from the parts kept there (computing only the others), with the synchronous sweep's
/// document bit for bit; a third, on another empty disk, takes it back done, with its result
/// and an event stream that ends. Removing the job takes its files out of the bucket too.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_outlives_its_servers_disk_through_the_jetstream_bucket() {
    let dir = scratch("bucket");
    let (_nats, url) = nats_server(&dir);
    let logs: Vec<PathBuf> = (0..2)
        .map(|i| dir.join(format!("worker-{i}.log")))
        .collect();
    let _workers: Vec<Process> = logs.iter().map(|log| worker(&url, log)).collect();
    let server_on = |jobs: &Path| {
        server_with(
            &url,
            &dir,
            600,
            &[
                "--jobs-dir",
                jobs.to_str().unwrap(),
                "--job-part-steps",
                "4000000",
                "--job-parts-in-flight",
                "1",
            ],
        )
    };
    let first_disk = dir.join("jobs-first");
    let (first, base) = server_on(&first_disk);
    let sweep = henon_heiles_sweep();
    let status_url = submit_sweep(&base, &sweep).await;
    let id = status_url.rsplit('/').next().unwrap().to_string();
    let until = Instant::now() + Duration::from_secs(120);
    let parts = loop {
        let job = get_json(status_url.clone()).await;
        if job["parts_done"].as_u64() >= Some(3) {
            assert_eq!(job["state"], "running", "{job}");
            break job["parts"].as_u64().unwrap();
        }
        assert!(Instant::now() < until, "three parts did not end: {job}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    drop(first);
    std::fs::remove_dir_all(&first_disk).unwrap();

    let names = bucket_names(&url).await;
    assert!(names.contains(&format!("{id}/job.json")), "{names:?}");
    let kept = (names.iter())
        .filter(|n| n.starts_with(&format!("{id}/parts/")))
        .count() as u64;
    assert!(
        kept >= 3 && kept < parts,
        "{kept} of {parts} parts: {names:?}"
    );

    let second_disk = dir.join("jobs-second");
    let (second, base) = server_on(&second_disk);
    let status_url = format!("{base}/api/v1/jobs/{id}");
    let until = Instant::now() + Duration::from_secs(60);
    while get_json(status_url.clone()).await["id"] != id.as_str() {
        assert!(Instant::now() < until, "the job was not taken back");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let done = until_ended(&status_url).await;
    assert_eq!(done["state"], "done", "{done}");
    assert_eq!(done["parts_done"], parts, "{done}");
    // Only the parts the bucket did not keep were computed again.
    let computed = crate::http_jobs::events(&base, &id, 0, None).await;
    let computed = computed.iter().filter(|e| e["event"] == "part").count() as u64;
    assert_eq!(computed, parts - kept);
    let from_job = get_json(format!("{status_url}/result")).await;
    let expected = local_sweep("bucket-local", &sweep).await;
    assert_eq!(without_timings(&from_job), without_timings(&expected));

    // A third server on an empty disk takes the job back done: its event stream ends with
    // `done`, and its result is the same bytes.
    drop(second);
    std::fs::remove_dir_all(&second_disk).unwrap();
    let (_third, base) = server_on(&dir.join("jobs-third"));
    let status_url = format!("{base}/api/v1/jobs/{id}");
    let until = Instant::now() + Duration::from_secs(60);
    while get_json(status_url.clone()).await["state"] != "done" {
        assert!(Instant::now() < until, "the done job was not taken back");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let events = crate::http_jobs::events(&base, &id, 0, None).await;
    assert_eq!(events.last().unwrap()["event"], "done", "{events:?}");
    assert_eq!(get_json(format!("{status_url}/result")).await, from_job);

    let removed = crate::server::client()
        .delete(&status_url)
        .send()
        .await
        .unwrap();
    assert!(removed.status().is_success(), "{:?}", removed.status());
    let left: Vec<String> = (bucket_names(&url).await.into_iter())
        .filter(|n| n.starts_with(&id))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

//! Faults that must lose nothing, on the real `geomint serve` process: SIGKILL while recordings
//! and system definitions are being stored (repeated; after each restart every listed item is
//! whole and readable and no temporary file stays), a full file system under the data directory
//! (507 `storage_full`, what was stored before intact, runs still served, storing again once
//! space is freed), a read-only and a removed data directory (clear errors, no panic), and
//! SIGTERM during long runs and streams (they end with `cancelled` within the grace time and the
//! process exits 0).
//!
//! The full and read-only file systems are a small tmpfs the test mounts (the test command runs
//! as root, as CI does).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use geomint::recording::read::inspect;
use serde_json::{json, Value};

use crate::server;
use server::{
    client, get_json_at as get_json, spawn_listening, temporary_files, Process, SERVE_LISTENING,
    SERVE_LOG,
};

fn scratch(name: &str) -> PathBuf {
    let dir = server::scratch_dir(&format!("faults-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `geomint serve` on a port of its own with its recordings in `data` and definitions in
/// `systems`.
fn serve(data: &Path, systems: &Path, extra: &[&str]) -> (Process, String) {
    let mut command = Command::new(env!("CARGO_BIN_EXE_geomint"));
    command
        .env("GEOMINT_LOG", SERVE_LOG)
        .args(["serve", "--addr", "127.0.0.1:0"])
        .arg("--data-dir")
        .arg(data)
        .arg("--systems-dir")
        .arg(systems)
        .args(["--static-dir", "no-static-here"])
        .args(extra)
        .stdout(Stdio::null());
    let (process, address) = spawn_listening(command, "geomint serve", SERVE_LISTENING);
    (process, format!("http://{address}"))
}

fn recording_request(every: u64) -> Value {
    json!({"system": "elastic_pendulum_2d", "methods": ["modin_3s", "rk4"], "h": 0.01,
        "t_end": 100, "output": {"every": every}})
}

fn definition(k: u64) -> Value {
    json!({
        "coordinates": ["x"], "momenta": ["p"], "mass": 1,
        "potential": "k/2*x^2", "parameters": {"k": k},
        "q0": [1], "p0": [0]
    })
}

async fn post(url: String, body: &Value) -> Result<(u16, Value), reqwest::Error> {
    let response = client().post(url).json(body).send().await?;
    let status = response.status().as_u16();
    Ok((status, response.json().await.unwrap_or(Value::Null)))
}

/// Downloads every listed recording and decodes it with Rerun's decoder; returns their ids.
async fn every_recording_reads(base: &str, scratch: &Path) -> Vec<String> {
    let list = get_json(format!("{base}/api/v1/recordings")).await;
    let mut ids = Vec::new();
    for entry in list.as_array().unwrap() {
        let id = entry["id"].as_str().unwrap().to_string();
        let response = client()
            .get(format!("{base}/api/v1/recordings/{id}.rrd"))
            .send()
            .await
            .unwrap();
        assert_eq!(response.status(), 200, "{id}");
        let bytes = response.bytes().await.unwrap();
        assert_eq!(bytes.len() as u64, entry["bytes"].as_u64().unwrap(), "{id}");
        let file = scratch.join(format!("{id}.rrd"));
        std::fs::write(&file, &bytes).unwrap();
        let inspected = inspect(&file).unwrap_or_else(|e| panic!("{id} does not decode: {e}"));
        assert!(inspected.simulation.is_some(), "{id}");
        std::fs::remove_file(&file).unwrap();
        ids.push(id);
    }
    ids
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigkill_while_storing_loses_nothing_acknowledged() {
    let dir = scratch("sigkill");
    let (data, systems) = (dir.join("recordings"), dir.join("systems"));
    let mut acknowledged_recordings = Vec::new();
    let mut acknowledged_systems = Vec::new();
    let mut next_k = 1;
    for round in 0..4u64 {
        let (mut process, base) = serve(&data, &systems, &[]);
        // Four writers store recordings and definitions until the process dies under them.
        let mut writers = Vec::new();
        for w in 0..4u64 {
            let base = base.clone();
            let first_k = next_k + w * 1000;
            writers.push(tokio::spawn(async move {
                let mut recordings = Vec::new();
                let mut systems = Vec::new();
                for i in 0.. {
                    let stored = if (i + w) % 2 == 0 {
                        post(
                            format!("{base}/api/v1/recordings"),
                            &recording_request(1 + i % 7),
                        )
                        .await
                    } else {
                        post(format!("{base}/api/v1/systems"), &definition(first_k + i)).await
                    };
                    match stored {
                        Ok((201, answer)) => {
                            let id = answer["id"].as_str().unwrap().to_string();
                            if id.starts_with("sys-") {
                                systems.push(id)
                            } else {
                                recordings.push(id)
                            }
                        }
                        // A busy machine answers 503 with Retry-After: a client retries.
                        Ok((503, _)) => tokio::time::sleep(Duration::from_millis(50)).await,
                        Ok((status, answer)) => panic!("{status}: {answer}"),
                        Err(_) => break,
                    }
                }
                (recordings, systems)
            }));
        }
        next_k += 10_000;
        tokio::time::sleep(Duration::from_millis(400 + 300 * round)).await;
        process.0.kill().unwrap();
        process.0.wait().unwrap();
        for writer in writers {
            let (recordings, systems) = writer.await.unwrap();
            acknowledged_recordings.extend(recordings);
            acknowledged_systems.extend(systems);
        }
        // After a restart everything acknowledged is listed and reads; nothing else is listed.
        let (_process, base) = serve(&data, &systems, &[]);
        let listed = every_recording_reads(&base, &dir).await;
        for id in &acknowledged_recordings {
            assert!(
                listed.contains(id),
                "round {round}: recording {id} was lost"
            );
        }
        let stored = get_json(format!("{base}/api/v1/systems")).await;
        for id in &acknowledged_systems {
            let found = stored["systems"]
                .as_array()
                .or(stored.as_array())
                .unwrap()
                .iter()
                .any(|s| s["id"] == id.as_str());
            assert!(found, "round {round}: system {id} was lost");
            let one = client()
                .get(format!("{base}/api/v1/systems/{id}"))
                .send()
                .await
                .unwrap();
            assert_eq!(one.status(), 200, "{id}");
        }
        // A restarted store removes the temporary files of the killed writes.
        assert!(
            temporary_files(&data).is_empty(),
            "{:?}",
            temporary_files(&data)
        );
        assert!(temporary_files(&systems).is_empty());
    }
    assert!(
        acknowledged_recordings.len() >= 4 && acknowledged_systems.len() >= 4,
        "too few writes to test: {} recordings, {} systems",
        acknowledged_recordings.len(),
        acknowledged_systems.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A tmpfs of `size` mounted at `dir`, unmounted when dropped.
struct Tmpfs(PathBuf);

impl Tmpfs {
    fn mount(dir: &Path, size: &str) -> Tmpfs {
        std::fs::create_dir_all(dir).unwrap();
        let status = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir)
            .status()
            .expect("mount runs");
        assert!(
            status.success(),
            "cannot mount a tmpfs at {} (the fault tests run as root)",
            dir.display()
        );
        Tmpfs(dir.to_path_buf())
    }

    fn remount(&self, options: &str) {
        let status = Command::new("mount")
            .args(["-o", &format!("remount,{options}")])
            .arg(&self.0)
            .status()
            .unwrap();
        assert!(status.success());
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_is_507_and_loses_nothing_stored_before() {
    let dir = scratch("full");
    let disk = Tmpfs::mount(&dir.join("disk"), "5m");
    let (data, systems) = (dir.join("disk/recordings"), dir.join("disk/systems"));
    let (_process, base) = serve(&data, &systems, &[]);
    let mut stored = Vec::new();
    let full = loop {
        let (status, answer) = post(format!("{base}/api/v1/recordings"), &recording_request(4))
            .await
            .unwrap();
        match status {
            201 => stored.push(answer["id"].as_str().unwrap().to_string()),
            _ => break (status, answer),
        }
        assert!(stored.len() < 100, "the disk never filled");
    };
    assert_eq!(full.0, 507, "{}", full.1);
    assert_eq!(full.1["error"]["code"], "storage_full");
    assert!(full.1["error"]["message"]
        .as_str()
        .unwrap()
        .contains("disk is full"));
    assert!(!stored.is_empty());
    // Runs are still served, and what was stored before still reads.
    let (status, _) = post(format!("{base}/api/v1/simulate"), &recording_request(100))
        .await
        .unwrap();
    assert_eq!(status, 200);
    assert_eq!(every_recording_reads(&base, &dir).await, {
        let mut s = stored.clone();
        s.reverse();
        s
    });
    assert!(temporary_files(&data).is_empty());
    // A definition cannot be stored either once the last bytes are taken.
    let filler = data.join("filler");
    {
        use std::io::Write;
        let mut file = std::fs::File::create(&filler).unwrap();
        while file.write_all(&[0u8; 4096]).is_ok() {}
    }
    let (status, answer) = post(format!("{base}/api/v1/systems"), &definition(7))
        .await
        .unwrap();
    assert_eq!(status, 507, "{answer}");
    assert_eq!(answer["error"]["code"], "storage_full");
    // Space freed: storing works again.
    std::fs::remove_file(&filler).unwrap();
    for id in &stored[..2] {
        let response = client()
            .delete(format!("{base}/api/v1/recordings/{id}"))
            .send()
            .await
            .unwrap();
        assert_eq!(response.status(), 204);
    }
    let (status, _) = post(format!("{base}/api/v1/recordings"), &recording_request(4))
        .await
        .unwrap();
    assert_eq!(status, 201);
    let (status, _) = post(format!("{base}/api/v1/systems"), &definition(7))
        .await
        .unwrap();
    assert_eq!(status, 201);
    drop(_process);
    drop(disk);
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_read_only_or_removed_data_directory_gives_clear_errors() {
    let dir = scratch("readonly");
    let disk = Tmpfs::mount(&dir.join("disk"), "8m");
    let (data, systems) = (dir.join("disk/recordings"), dir.join("disk/systems"));
    let (mut process, base) = serve(&data, &systems, &[]);
    let (status, first) = post(format!("{base}/api/v1/recordings"), &recording_request(10))
        .await
        .unwrap();
    assert_eq!(status, 201);
    disk.remount("ro");
    for (path, body) in [
        ("/api/v1/recordings", recording_request(10)),
        ("/api/v1/systems", definition(3)),
    ] {
        let (status, answer) = post(format!("{base}{path}"), &body).await.unwrap();
        assert_eq!(status, 500, "{path}: {answer}");
        assert_eq!(answer["error"]["code"], "storage_unavailable", "{path}");
        assert!(
            answer["error"]["message"]
                .as_str()
                .unwrap()
                .contains("cannot be written"),
            "{answer}"
        );
    }
    let upload = client()
        .post(format!("{base}/api/v1/recordings"))
        .header("content-type", "application/octet-stream")
        .body(vec![0u8; 100])
        .send()
        .await
        .unwrap();
    assert_eq!(upload.status(), 500);
    // Reading and running go on.
    assert_eq!(
        every_recording_reads(&base, &dir).await,
        vec![first["id"].as_str().unwrap().to_string()]
    );
    let (status, _) = post(format!("{base}/api/v1/simulate"), &recording_request(100))
        .await
        .unwrap();
    assert_eq!(status, 200);
    disk.remount("rw");
    drop(disk);
    // The data directory removed under the server: the store makes it again.
    let _ = std::fs::remove_dir_all(dir.join("disk"));
    let (status, answer) = post(format!("{base}/api/v1/recordings"), &recording_request(10))
        .await
        .unwrap();
    assert_eq!(status, 201, "{answer}");
    assert!(process.0.try_wait().unwrap().is_none(), "the server exited");
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_ends_runs_and_streams_with_their_stop_reason_and_exits_0() {
    let dir = scratch("sigterm");
    let (mut process, base) = serve(
        &dir.join("recordings"),
        &dir.join("systems"),
        &[
            "--shutdown-grace-secs",
            "1",
            "--max-concurrent",
            "2",
            "--max-steps",
            "1e10",
        ],
    );
    // 10⁹ steps each, about 10 s: still running when the 1 s grace period ends.
    let long = json!({"system": "pendulum", "method": "modin_3s", "h": 1e-3, "t_end": 1e6,
        "output": {"every": 10000000}});
    let stream = client()
        .post(format!("{base}/api/v1/simulate"))
        .header("accept", "application/x-ndjson")
        .json(&long)
        .send()
        .await
        .unwrap();
    assert_eq!(stream.status(), 200);
    let json_run = tokio::spawn({
        let (url, long) = (format!("{base}/api/v1/simulate"), long.clone());
        async move { post(url, &long).await.unwrap() }
    });
    let until = Instant::now() + Duration::from_secs(10);
    while get_json(format!("{base}/healthz")).await["runs_in_progress"] != 2 {
        assert!(Instant::now() < until, "the runs did not start");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let signalled = Instant::now();
    let pid = process.0.id().to_string();
    assert!(Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .unwrap()
        .success());
    let text = stream.text().await.unwrap();
    let lines: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let summary = lines.iter().find(|l| l["type"] == "summary").expect(&text);
    assert_eq!(summary["stop"]["reason"], "cancelled", "{summary}");
    assert_eq!(lines.last().unwrap()["type"], "end");
    let (status, doc) = json_run.await.unwrap();
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["runs"][0]["stop"]["reason"], "cancelled");
    let exit = loop {
        if let Some(exit) = process.0.try_wait().unwrap() {
            break exit;
        }
        assert!(
            signalled.elapsed() < Duration::from_secs(20),
            "the server did not exit"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(exit.success(), "{exit}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A job whose jobs directory fills while it runs: it fails with `storage_full` naming the part
/// that was not stored; the parts stored before read back whole and no temporary file stays; the
/// server goes on serving; and once space is freed the same study as a new job ends with the
/// synchronous route's document.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_on_a_full_disk_fails_with_storage_full_and_keeps_its_stored_parts() {
    let dir = scratch("jobs-full");
    let disk = Tmpfs::mount(&dir.join("disk"), "1m");
    let jobs = dir.join("disk/jobs");
    let (_process, base) = serve(
        &dir.join("recordings"),
        &dir.join("systems"),
        &[
            "--jobs-dir",
            jobs.to_str().unwrap(),
            "--job-part-steps",
            "4000000",
        ],
    );
    // 8 parts of about 10 kB: room for the job's record and two or three of them.
    let filler = dir.join("disk/filler");
    {
        use std::io::Write;
        let mut file = std::fs::File::create(&filler).unwrap();
        while file.write_all(&[0u8; 4096]).is_ok() {}
    }
    std::fs::write(
        &filler,
        vec![0u8; std::fs::metadata(&filler).unwrap().len() as usize - 40960],
    )
    .unwrap();
    let sweep = json!({
        "system": "henon_heiles", "methods": ["velocity_verlet", "rk4"], "h": 0.01, "t_end": 2000,
        "every": 1000, "q0": [0, 0.1], "p0": [0.35, 0],
        "axes": [{"name": "q0[1]", "min": -0.2, "max": 0.2, "n": 12},
                 {"name": "p0[1]", "min": -0.1, "max": 0.1, "n": 10}]});
    let submit = json!({"study": "sweep", "request": sweep});
    let run_job = |base: String, submit: Value| async move {
        let (status, job) = post(format!("{base}/api/v1/jobs"), &submit).await.unwrap();
        assert_eq!(status, 202, "{job}");
        let url = format!("{base}/api/v1/jobs/{}", job["id"].as_str().unwrap());
        let until = Instant::now() + Duration::from_secs(120);
        loop {
            let job = get_json(url.clone()).await;
            if job["state"] != "queued" && job["state"] != "running" {
                return (url, job);
            }
            assert!(Instant::now() < until, "the job did not end: {job}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    };
    let (_, failed) = run_job(base.clone(), submit.clone()).await;
    assert_eq!(failed["state"], "failed", "{failed}");
    assert_eq!(failed["error"]["code"], "storage_full", "{failed}");
    let message = failed["error"]["message"].as_str().unwrap();
    assert!(
        message.contains("disk is full: the part of cells"),
        "{message}"
    );
    let stored = failed["parts_done"].as_u64().unwrap();
    assert!(stored < failed["parts"].as_u64().unwrap(), "{failed}");
    // What was stored reads back whole, and nothing half-written stays.
    let id = failed["id"].as_str().unwrap();
    let parts: Vec<PathBuf> = std::fs::read_dir(jobs.join(id).join("parts"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(parts.len() as u64, stored, "{parts:?}");
    for part in &parts {
        let value: Value = serde_json::from_slice(&std::fs::read(part).unwrap()).unwrap();
        assert!(
            value["cells"].as_array().is_some_and(|c| !c.is_empty()),
            "{part:?}"
        );
    }
    assert!(
        temporary_files(&jobs).is_empty(),
        "{:?}",
        temporary_files(&jobs)
    );
    let (status, _) = post(format!("{base}/api/v1/simulate"), &recording_request(100))
        .await
        .unwrap();
    assert_eq!(status, 200);
    // Space freed: the study as a new job gives the synchronous document.
    std::fs::remove_file(&filler).unwrap();
    let (url, done) = run_job(base.clone(), submit).await;
    assert_eq!(done["state"], "done", "{done}");
    let from_job = get_json(format!("{url}/result")).await;
    let (status, direct) = post(format!("{base}/api/v1/studies/sweep"), &sweep)
        .await
        .unwrap();
    assert_eq!(status, 200, "{direct}");
    let numbers = |mut doc: Value| {
        doc.as_object_mut().unwrap().remove("wall_ms");
        doc
    };
    assert_eq!(numbers(from_job), numbers(direct));
    drop(_process);
    drop(disk);
    let _ = std::fs::remove_dir_all(&dir);
}

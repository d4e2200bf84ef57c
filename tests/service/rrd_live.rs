//! `geomint run --rerun-addr` streaming a run live to a Rerun gRPC receiver: the `rerun` command
//! of the Python SDK (`rerun-sdk` 0.33.x, next to `GEOMINT_PYTHON` in its venv's `bin`) saves what
//! it receives with `--save`, and the file is read back with Rerun's own decoder. Runs when
//! `GEOMINT_PYTHON` is set; otherwise it prints a notice and passes. Unix only (the receiver is
//! stopped through its process group).

use std::collections::BTreeSet;
use std::fs::File;
use std::net::TcpStream;
use std::os::unix::process::CommandExt as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use geomint::api::system::NoStoredSystems;
use geomint::api::SimulateRequest;
use geomint::core::run::Budget;
use geomint::core::simulation::stream::CHUNK_SAMPLES;
use geomint::core::simulation::Limits;
use geomint::core::simulation::SimulationDocument;
use geomint::recording::{path_blocks, sample_steps, APPLICATION_ID};
use serde_json::json;

use crate::decoded;
use crate::server;
use decoded::Decoded;
use server::free_port;

/// A child process in a process group of its own, killed with its group unless it has ended.
struct Process {
    child: Child,
    name: &'static str,
}

impl Process {
    fn spawn(name: &'static str, command: &mut Command) -> Process {
        let child = command
            .process_group(0)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {name}: {e}"));
        Process { child, name }
    }

    /// Sends `signal` (as `kill` names it) to the process group.
    fn signal(&self, signal: &str) {
        let _ = Command::new("kill")
            .args([signal, "--", &format!("-{}", self.child.id())])
            .stderr(Stdio::null())
            .status();
    }

    /// Waits up to `timeout` for the process to end.
    fn wait(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let started = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                return Some(status);
            }
            if started.elapsed() > timeout {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Whether the process has ended.
    fn ended(&mut self) -> bool {
        self.child.try_wait().expect("try_wait").is_some()
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        if !self.ended() {
            eprintln!("killing {}", self.name);
            self.signal("-KILL");
            let _ = self.child.wait();
        }
    }
}

/// Polls `f` every 50 ms until it gives a value, for up to `timeout`.
fn poll<T>(timeout: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let started = Instant::now();
    loop {
        if let Some(v) = f() {
            return Some(v);
        }
        if started.elapsed() > timeout {
            return None;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn log_of(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_default()
}

#[test]
fn run_streams_live_to_a_rerun_viewer() {
    let Some(python) = std::env::var_os("GEOMINT_PYTHON") else {
        println!(
            "notice: GEOMINT_PYTHON is not set; skipping the live streaming test \
             (set it to the Python of a venv with `pip install 'rerun-sdk==0.33.*'`)"
        );
        return;
    };
    let rerun = Path::new(&python).with_file_name("rerun");
    assert!(
        rerun.exists(),
        "GEOMINT_PYTHON is set but there is no `rerun` command beside it at {}",
        rerun.display()
    );
    let dir = server::scratch_dir("rrd-live");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();

    // The receiver: a gRPC server on a free local port that saves what it receives.
    let port = free_port();
    let received = dir.join("received.rrd");
    let receiver_log = dir.join("receiver.log");
    let mut receiver = Process::spawn(
        "the rerun receiver",
        Command::new(&rerun)
            .args(["--bind", "127.0.0.1", "--port", &port.to_string(), "--save"])
            .arg(&received)
            .stdin(Stdio::null())
            .stdout(File::create(&receiver_log).unwrap())
            .stderr(File::create(dir.join("receiver.err")).unwrap()),
    );
    let listening = poll(Duration::from_secs(60), || {
        assert!(
            !receiver.ended(),
            "the receiver ended: {}",
            log_of(&dir.join("receiver.err"))
        );
        TcpStream::connect(("127.0.0.1", port)).ok()
    });
    assert!(
        listening.is_some(),
        "the receiver does not listen on {port}"
    );

    // Two methods (one label not a plain entity name), 80000/0.01 = 8·10⁶ steps sampled every
    // 4000: 2001 samples each, so at least eight chunks of ≤ 256 samples per method, more when
    // the 50 ms flush interval cuts them.
    let body = json!({"system": "pendulum", "params": {"epsilon": 0.01},
        "methods": ["modin_3s", {"id": "modin_rks", "inner": "rk4"}],
        "h": 0.01, "t_end": 80000, "q0": [2.5], "p0": [0.0], "output": {"every": 4000}});
    let answer: SimulationDocument = {
        let spec = SimulateRequest::from_value(&body).unwrap();
        let sim = spec.prepare(&Limits::default(), &NoStoredSystems).unwrap();
        sim.simulate(2, Budget::default()).unwrap()
    };
    let schedule = answer.schedule;
    let samples = schedule.samples_per_method as usize;
    assert_eq!(samples, 2001);
    let methods = ["modin_3s", "modin_rks_rk4"];
    let energy_rows = |d: &Decoded| -> Vec<usize> {
        methods
            .iter()
            .map(|m| {
                let path = format!("/{m}/energy");
                if d.chunks.contains_key(&path) {
                    d.rows(&path)
                } else {
                    0
                }
            })
            .collect()
    };
    let spec_path = dir.join("spec.json");
    std::fs::write(&spec_path, serde_json::to_vec(&body).unwrap()).unwrap();
    let answer_path = dir.join("answer.json");
    let started = Instant::now();
    let mut geomint = Process::spawn(
        "geomint",
        Command::new(env!("CARGO_BIN_EXE_geomint"))
            .arg("run")
            .arg(&spec_path)
            .args(["--rerun-addr", &format!("127.0.0.1:{port}"), "-o"])
            .arg(&answer_path)
            .env_remove("GEOMINT_MAX_STEPS")
            .env_remove("GEOMINT_MAX_SAMPLES")
            .stdin(Stdio::null())
            .stderr(File::create(dir.join("geomint.err")).unwrap()),
    );
    let status = geomint
        .wait(Duration::from_secs(120))
        .expect("geomint ends within 120 s");
    let elapsed = started.elapsed();
    let geomint_err = log_of(&dir.join("geomint.err"));
    assert!(status.success(), "geomint failed: {geomint_err}");
    assert!(
        geomint_err.contains("streamed the run live"),
        "{geomint_err}"
    );

    // The JSON the run wrote holds the same columns as computed here, as text.
    let written = std::fs::read_to_string(&answer_path).unwrap();
    for run in &answer.runs {
        let columns = serde_json::to_string(&run.columns).unwrap();
        let fields = &columns[1..columns.len() - 1];
        assert!(written.contains(fields), "{} columns as JSON", run.method);
    }

    // The receiver writes what it gets as it comes: wait until everything is there (both
    // methods' energies complete, and their force evaluations, logged last), then stop it.
    let complete = |d: &Decoded| {
        energy_rows(d).iter().all(|&n| n == samples)
            && methods.iter().all(|m| {
                let path = format!("/{m}/force_evaluations");
                d.chunks.contains_key(&path) && d.rows(&path) == 1
            })
    };
    let arrived = poll(Duration::from_secs(30), || {
        let bytes = std::fs::read(&received).ok()?;
        Decoded::try_of(&bytes).ok().filter(complete).map(|_| ())
    });
    receiver.signal("-INT");
    if receiver.wait(Duration::from_secs(10)).is_none() {
        receiver.signal("-KILL");
    }
    assert!(
        arrived.is_some(),
        "the receiver did not save the whole run within 30 s; geomint said: {geomint_err}\n\
         receiver: {}",
        log_of(&dir.join("receiver.err"))
    );
    let bytes = std::fs::read(&received).unwrap();
    let d = Decoded::of(&bytes);

    assert_eq!(
        d.application_ids,
        BTreeSet::from([APPLICATION_ID.to_string()])
    );
    assert_eq!(d.recording_stores.len(), 1);
    assert_eq!(d.entity_paths(), decoded::simulation_entities(&methods));
    let labels: Vec<&str> = answer.runs.iter().map(|r| r.method.as_str()).collect();
    assert_eq!(
        d.recording_name(),
        format!("pendulum: {}", labels.join(", "))
    );

    let steps = sample_steps(samples, schedule.every, schedule.steps);
    let mut chunk_counts = Vec::new();
    for (i, m) in methods.iter().enumerate() {
        let run = &answer.runs[i];
        assert_eq!(run.columns.energy.len(), samples);
        let path = format!("/{m}/energy");
        let decoded = d.scalars(&path);
        assert_eq!(decoded.len(), samples, "{path}");
        let got_steps: Vec<i64> = decoded.iter().map(|r| r.0).collect();
        assert_eq!(got_steps, steps, "{path}");
        for (k, (got, want)) in decoded.iter().zip(&run.columns.energy).enumerate() {
            assert_eq!(got.1.to_bits(), want.to_bits(), "{path}[{k}]");
        }
        // Logged as computed: one chunk per chunk of the stream, none larger.
        let rows: Vec<usize> = d.chunks[&path]
            .iter()
            .filter(|c| !c.is_static())
            .map(|c| c.num_rows())
            .collect();
        assert!(
            rows.len() >= samples.div_ceil(CHUNK_SAMPLES),
            "{path}: chunks of {rows:?} rows"
        );
        assert!(rows.iter().all(|&n| n <= CHUNK_SAMPLES), "{path}: {rows:?}");
        chunk_counts.push(rows.len());
        for e in ["phase/0/point", "world/bodies"] {
            assert_eq!(d.rows(&format!("/{m}/{e}")), samples, "/{m}/{e}");
        }
        for e in ["phase/0/path", "world/path"] {
            assert_eq!(
                d.rows(&format!("/{m}/{e}")),
                path_blocks(samples).len(),
                "/{m}/{e}"
            );
        }
        assert_eq!(
            d.scalars(&format!("/{m}/force_evaluations")),
            [(
                schedule.steps as i64,
                run.outcome.stats.force_evaluations as f64
            )]
        );
    }
    // The blueprint came first, with the data.
    assert_eq!(d.blueprint_stores.len(), 1);
    assert_eq!(d.activations, 1);
    println!(
        "streamed {samples} samples × 2 methods of {} steps live in {:.2} s (geomint run, end to \
         end); energy chunks per method: {chunk_counts:?}; received {} bytes",
        schedule.steps,
        elapsed.as_secs_f64(),
        bytes.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A viewer that is not there: a clear error and exit code 1, not a hang.
#[test]
fn run_without_a_viewer_fails_with_exit_code_1() {
    let dir = server::scratch_dir("rrd-noviewer");
    std::fs::create_dir_all(&dir).unwrap();
    let spec_path: PathBuf = dir.join("spec.json");
    std::fs::write(
        &spec_path,
        serde_json::to_vec(&json!({"system": "harmonic_oscillator", "method": "csv1",
            "h": 0.1, "t_end": 1}))
        .unwrap(),
    )
    .unwrap();
    let output = dir.join("out.json");
    let (_held, port) = server::closed_port();
    let started = Instant::now();
    let mut geomint = Process::spawn(
        "geomint",
        Command::new(env!("CARGO_BIN_EXE_geomint"))
            .arg("run")
            .arg(&spec_path)
            .args(["--rerun-addr", &format!("127.0.0.1:{port}"), "-o"])
            .arg(&output)
            .stdin(Stdio::null())
            .stderr(File::create(dir.join("geomint.err")).unwrap()),
    );
    let status = geomint
        .wait(Duration::from_secs(60))
        .expect("geomint gives up within 60 s");
    let err = log_of(&dir.join("geomint.err"));
    println!(
        "no viewer: exit {status} after {:.1} s: {err}",
        started.elapsed().as_secs_f64()
    );
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains("cannot stream to the Rerun viewer"), "{err}");
    assert!(!output.exists(), "no output without a viewer");
    let _ = std::fs::remove_dir_all(&dir);
}

//! Jobs through the service: every study submitted as a job ends with its route's document bit
//! for bit; a job whose server is SIGKILLed mid-way goes on under the next one from its stored
//! parts, computing none of them twice, to the same document; cancelling and removing; the event
//! stream resumed with `?after=`; owners' jobs taking turns part by part and hidden from each
//! other; refusals naming their field.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use geomint::access::{Anonymous, Quotas};
use geomint::http::Config;
use geomint::jobs::JobsConfig;
use serde_json::{json, Value};

use crate::server::{self, client, post_json_to, spawn_listening, SERVE_LISTENING, SERVE_LOG};

const JOBS: &str = "/api/v1/jobs";

fn jobs_config(label: &str, part_steps: u64) -> Config {
    let dir = server::scratch_dir(label);
    Config {
        request_timeout: Duration::from_secs(120),
        data_dir: dir.join("recordings"),
        systems_dir: dir.join("systems"),
        jobs: Some(JobsConfig {
            dir: dir.join("jobs"),
            max_per_owner: 1000,
            part_steps,
            time_limit: Duration::from_secs(600),
            parts_in_flight: 1,
        }),
        ..Config::default()
    }
}

/// `method path` on the server at `base` with an optional JSON body and token: status and body.
async fn call(
    base: &str,
    method: reqwest::Method,
    path: &str,
    body: Option<&Value>,
    token: Option<&str>,
) -> (u16, Vec<u8>) {
    let mut request = client().request(method, format!("{base}{path}"));
    if let Some(token) = token {
        request = request.bearer_auth(token);
    }
    if let Some(body) = body {
        request = request.json(body);
    }
    let response = request.send().await.unwrap();
    let status = response.status().as_u16();
    (status, response.bytes().await.unwrap().to_vec())
}

async fn call_json(
    base: &str,
    method: reqwest::Method,
    path: &str,
    body: Option<&Value>,
    token: Option<&str>,
) -> (u16, Value) {
    let (status, bytes) = call(base, method, path, body, token).await;
    let value = serde_json::from_slice(&bytes).unwrap_or(Value::Null);
    (status, value)
}

/// Submits `study` with `request` as `token`; the job's id.
async fn submit(base: &str, study: &str, request: &Value, token: Option<&str>) -> String {
    let body = json!({"study": study, "request": request});
    let (status, job) = call_json(base, reqwest::Method::POST, JOBS, Some(&body), token).await;
    assert_eq!(status, 202, "{job}");
    assert!(
        job["state"] == "queued" || job["state"] == "running",
        "{job}"
    );
    job["id"].as_str().unwrap().to_string()
}

/// The job's event stream from after `after` to its last event.
pub(crate) async fn events(base: &str, id: &str, after: usize, token: Option<&str>) -> Vec<Value> {
    let path = format!("{JOBS}/{id}/events?after={after}");
    let (status, bytes) = tokio::time::timeout(
        Duration::from_secs(300),
        call(base, reqwest::Method::GET, &path, None, token),
    )
    .await
    .expect("the job ends within 5 minutes");
    assert_eq!(status, 200);
    String::from_utf8(bytes)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// A document without its timings (wall times differ from run to run; every number else is
/// compared bit for bit).
pub(crate) fn without_timings(value: &Value) -> Value {
    match value {
        Value::Object(map) => Value::Object(
            map.iter()
                .filter(|(k, _)| !k.ends_with("_ms") && !k.starts_with("wall_") && *k != "fits")
                .map(|(k, v)| (k.clone(), without_timings(v)))
                .collect(),
        ),
        Value::Array(items) => Value::Array(items.iter().map(without_timings).collect()),
        other => other.clone(),
    }
}

fn small_studies() -> Vec<(&'static str, &'static str, Value)> {
    vec![
        (
            "sweep",
            "/api/v1/studies/sweep",
            json!({"system": "pendulum", "methods": ["modin_3s", "heun"], "h": 0.1, "t_end": 20,
                   "axes": [{"name": "params.gamma", "min": 0.01, "max": 1, "n": 5, "scale": "log"},
                            {"name": "q0[0]", "min": 0.5, "max": 2.5, "n": 7}]}),
        ),
        (
            "basins",
            "/api/v1/studies/basins",
            json!({"system": {"name": "double well", "coordinates": ["x"], "mass": 1,
                              "potential": "-x^2/2 + x^4/4", "damping": {"gamma": "gamma"},
                              "parameters": {"gamma": 0.125}},
                   "methods": ["csv2"], "h": 0.05, "t_end": 200,
                   "axes": [{"name": "q0[0]", "min": -2, "max": 2, "n": 9},
                            {"name": "p0[0]", "min": -2, "max": 2, "n": 9}]}),
        ),
        (
            "energy-map",
            "/api/v1/studies/energy-map",
            json!({"nx": 5, "ny": 4, "t_max": 100}),
        ),
        (
            "stability",
            "/api/v1/stability",
            json!({"methods": ["csv1", "rk4"], "omega": 3.51,
                   "gamma": {"min": 0, "max": 4, "n": 9}, "h": {"min": 0.05, "max": 1, "n": 7}}),
        ),
        (
            "convergence",
            "/api/v1/studies/convergence",
            json!({"system": "harmonic_oscillator", "params": {"omega": 1, "gamma": 0.1},
                   "q0": [1], "p0": [0], "t_end": 10, "methods": ["rk4", "csv1"],
                   "h": [0.1, 0.05, 0.025]}),
        ),
        (
            "work-precision",
            "/api/v1/studies/work-precision",
            json!({"system": "pendulum", "t_end": 20, "samples": 10,
                   "runs": [{"method": "modin_3s", "h": [0.1, 0.05]}, {"method": "csv1", "h": [0.1]}]}),
        ),
    ]
}

/// Every study as a job, in parts of a few cells, ends `done` with the document its route
/// answers, bit for bit but for wall times; its events count 1, 2, … and a part event per part;
/// `?after=` resumes the stream; the recording comes where the study has one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_study_as_a_job_gives_its_routes_document() {
    let server = server::start(jobs_config("jobs-each", 1000)).await;
    let base = server.base.clone();
    for (study, route, request) in small_studies() {
        let (status, direct) = post_json_to(&base, route, &request).await;
        assert_eq!(status, 200, "{study}: {direct}");
        let id = submit(&base, study, &request, None).await;
        let seen = events(&base, &id, 0, None).await;
        let seqs: Vec<u64> = seen.iter().map(|e| e["seq"].as_u64().unwrap()).collect();
        assert_eq!(seqs, (1..=seen.len() as u64).collect::<Vec<_>>(), "{study}");
        assert_eq!(seen[0]["event"], "submitted");
        assert_eq!(seen[1]["event"], "started");
        let last = seen.last().unwrap();
        assert_eq!(last["event"], "done", "{study}: {last}");
        let parts = last["parts"].as_u64().unwrap();
        let part_events = seen.iter().filter(|e| e["event"] == "part").count() as u64;
        assert_eq!(part_events, parts, "{study}: each part computed once");
        assert_eq!(last["cells_done"], last["cells"], "{study}");
        if study != "work-precision" {
            assert!(parts > 1, "{study}: the study ran in {parts} part(s)");
        }

        let resumed = events(&base, &id, 2, None).await;
        assert_eq!(resumed, seen[2..].to_vec(), "{study}: ?after=2");
        let again = events(&base, &id, seen.len(), None).await;
        assert_eq!(
            again,
            [last.clone()],
            "{study}: after the last event, the last event again"
        );
        let path = format!("{JOBS}/{id}/events?after={}", seen.len() + 1);
        let (status, err) = call_json(&base, reqwest::Method::GET, &path, None, None).await;
        assert_eq!(
            (status, &err["error"]["field"]),
            (422, &json!("after")),
            "{err}"
        );

        let path = format!("{JOBS}/{id}/request");
        let (status, submitted) = call_json(&base, reqwest::Method::GET, &path, None, None).await;
        assert_eq!(status, 200, "{study}: {submitted}");
        let expected = json!({"study": study, "request": request, "priority": 0});
        assert_eq!(submitted, expected, "{study}: the submission read back");

        let path = format!("{JOBS}/{id}/result");
        let (status, from_job) = call_json(&base, reqwest::Method::GET, &path, None, None).await;
        assert_eq!(status, 200, "{study}: {from_job}");
        assert_eq!(
            without_timings(&from_job),
            without_timings(&direct),
            "{study}: the job's document differs from the route's"
        );
        let (rrd_status, rrd) = call(
            &base,
            reqwest::Method::GET,
            &format!("{path}?format=rrd"),
            None,
            None,
        )
        .await;
        let (status, job) = call_json(
            &base,
            reqwest::Method::GET,
            &format!("{JOBS}/{id}"),
            None,
            None,
        )
        .await;
        assert_eq!(status, 200);
        assert_eq!(job["state"], "done");
        assert_eq!(job["parts_done"], job["parts"]);
        match study {
            "convergence" => {
                assert_eq!(rrd_status, 422);
                assert_eq!(job["recording"], Value::Null, "{study}: {job}");
            }
            _ => {
                assert_eq!(rrd_status, 200, "{study}");
                assert!(rrd.starts_with(b"RRF2"), "{study}: not a recording");
                // The same recording in the recordings library, said to be this job's.
                let kept = job["recording"].as_str().expect("the library's id");
                let entry_path = format!("/api/v1/recordings/{kept}");
                let (status, entry) =
                    call_json(&base, reqwest::Method::GET, &entry_path, None, None).await;
                assert_eq!(status, 200, "{study}: {entry}");
                assert_eq!(entry["origin"], "job", "{entry}");
                assert_eq!(entry["job"], json!({"id": id, "study": study}), "{entry}");
                assert_eq!(entry["bytes"], rrd.len(), "{entry}");
                let rrd_path = format!("{entry_path}.rrd");
                let (status, library) =
                    call(&base, reqwest::Method::GET, &rrd_path, None, None).await;
                assert_eq!(status, 200, "{study}");
                assert!(library == rrd, "{study}: the library's copy differs");
            }
        }
    }
    let (status, listed) = call_json(&base, reqwest::Method::GET, JOBS, None, None).await;
    assert_eq!(status, 200);
    assert_eq!(listed.as_array().unwrap().len(), small_studies().len());
}

/// A sweep of many parts whose server is SIGKILLed mid-job: the next server takes it up from
/// its stored parts (`resumed`), computes only the parts that were not stored, and ends with the
/// document of the uninterrupted sweep bit for bit.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_survives_sigkill_of_its_server() {
    let dir = server::scratch_dir("jobs-sigkill");
    let serve = || {
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
            .arg("--jobs-dir")
            .arg(dir.join("jobs"))
            .args(["--job-part-steps", "4000000"])
            .stdout(Stdio::null());
        let (process, address) = spawn_listening(command, "geomint serve", SERVE_LISTENING);
        (process, format!("http://{address}"))
    };
    let sweep = json!({
        "system": "henon_heiles", "methods": ["velocity_verlet", "rk4"], "h": 0.01, "t_end": 2000,
        "every": 1000,
        "q0": [0, 0.1], "p0": [0.35, 0],
        "axes": [{"name": "q0[1]", "min": -0.2, "max": 0.2, "n": 12},
                 {"name": "p0[1]", "min": -0.1, "max": 0.1, "n": 10}]});
    let (mut first, base) = serve();
    let id = submit(&base, "sweep", &sweep, None).await;
    let status_path = format!("{JOBS}/{id}");
    let started = Instant::now();
    let parts = loop {
        let (_, job) = call_json(&base, reqwest::Method::GET, &status_path, None, None).await;
        let (done, parts) = (
            job["parts_done"].as_u64().unwrap(),
            job["parts"].as_u64().unwrap(),
        );
        assert!(
            job["state"] != "done",
            "the job ended before it could be killed: {job}"
        );
        if done >= 3 {
            assert!(parts >= done + 3, "{job}");
            break parts;
        }
        assert!(started.elapsed() < Duration::from_secs(120), "{job}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    first.0.kill().unwrap();
    first.0.wait().unwrap();

    let (_second, base) = serve();
    let seen = events(&base, &id, 0, None).await;
    let kinds: Vec<&str> = seen.iter().map(|e| e["event"].as_str().unwrap()).collect();
    let resumed = kinds
        .iter()
        .position(|k| *k == "resumed")
        .expect("a resumed event");
    assert_eq!(*kinds.last().unwrap(), "done", "{kinds:?}");
    let before = kinds[..resumed].iter().filter(|k| **k == "part").count() as u64;
    let after = kinds[resumed..].iter().filter(|k| **k == "part").count() as u64;
    assert!(before >= 3, "{kinds:?}");
    // A part stored just before the kill, its event not yet written, is read back, not run.
    assert!(
        before + after == parts || before + after + 1 == parts,
        "{before} parts before the kill and {after} after, of {parts}"
    );
    let (status, from_job) = call_json(
        &base,
        reqwest::Method::GET,
        &format!("{status_path}/result"),
        None,
        None,
    )
    .await;
    assert_eq!(status, 200);
    let (status, direct) = post_json_to(&base, "/api/v1/studies/sweep", &sweep).await;
    assert_eq!(status, 200, "{direct}");
    assert_eq!(without_timings(&from_job), without_timings(&direct));
}

/// A running job is not removed (409) but cancelled between steps, keeping its record; its result
/// is then 409; once ended, DELETE removes it and its files; its id is then unknown.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_is_cancelled_then_removed() {
    let server = server::start(jobs_config("jobs-cancel", 200_000)).await;
    let base = server.base.clone();
    let long = json!({"system": "pendulum", "methods": ["rk4"], "h": 0.001, "t_end": 2000, "every": 1000,
                      "axes": [{"name": "q0[0]", "min": 0.1, "max": 3, "n": 200}]});
    let id = submit(&base, "sweep", &long, None).await;
    let path = format!("{JOBS}/{id}");
    let started = Instant::now();
    while call_json(&base, reqwest::Method::GET, &path, None, None)
        .await
        .1["parts_done"]
        == 0
    {
        assert!(started.elapsed() < Duration::from_secs(60));
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let (status, refused) = call_json(&base, reqwest::Method::DELETE, &path, None, None).await;
    assert_eq!(
        (status, &refused["error"]["code"]),
        (409, &json!("job_not_done"))
    );
    let cancel = format!("{path}/cancel");
    let (status, job) = call_json(&base, reqwest::Method::POST, &cancel, None, None).await;
    assert_eq!(status, 200, "{job}");
    let seen = events(&base, &id, 0, None).await;
    assert_eq!(seen.last().unwrap()["event"], "cancelled");
    let (_, job) = call_json(&base, reqwest::Method::GET, &path, None, None).await;
    assert_eq!(job["state"], "cancelled");
    assert!(job["parts_done"].as_u64().unwrap() < job["parts"].as_u64().unwrap());
    let (status, refused) = call_json(
        &base,
        reqwest::Method::GET,
        &format!("{path}/result"),
        None,
        None,
    )
    .await;
    assert_eq!(status, 409);
    assert_eq!(refused["error"]["code"], "job_not_done");
    // Cancelling an ended job leaves it as it is.
    let (status, again) = call_json(&base, reqwest::Method::POST, &cancel, None, None).await;
    assert_eq!((status, &again["state"]), (200, &json!("cancelled")));
    let (status, _) = call(&base, reqwest::Method::DELETE, &path, None, None).await;
    assert_eq!(status, 204);
    let (status, _) = call(&base, reqwest::Method::GET, &path, None, None).await;
    assert_eq!(status, 404);
    // Nothing of it is left on disk.
    let dir = server.state.config.jobs.as_ref().unwrap().dir.join(&id);
    assert!(!dir.exists(), "{}", dir.display());
}

/// Refusals name their field: the study, a field inside the request (as its route names it,
/// under `request.`), the priority, an unknown field; unknown ids are 404.
#[tokio::test]
async fn job_refusals_name_their_field() {
    let server = server::start(jobs_config("jobs-refusals", 1_000_000)).await;
    let base = server.base.clone();
    let sweep = small_studies().remove(0).2;
    let mut bad_axis = sweep.clone();
    bad_axis["axes"][1]["name"] = json!("q9[0]");
    let cases = [
        (
            json!({"study": "sweeps", "request": sweep}),
            "study",
            "invalid_value",
        ),
        (json!({"study": "sweep"}), "request", "missing_field"),
        (
            json!({"study": "sweep", "request": bad_axis}),
            "request.axes[1].name",
            "",
        ),
        (
            json!({"study": "sweep", "request": sweep, "priority": 5000}),
            "priority",
            "invalid_value",
        ),
        (
            json!({"study": "sweep", "request": sweep, "when": 1}),
            "when",
            "unknown_field",
        ),
        (
            json!({"study": "sweep", "request": {"system": "pendulum"}}),
            "request.methods",
            "missing_field",
        ),
    ];
    for (body, field, code) in cases {
        let (status, err) = call_json(&base, reqwest::Method::POST, JOBS, Some(&body), None).await;
        assert_eq!(status, 422, "{body}: {err}");
        assert_eq!(err["error"]["field"], field, "{body}: {err}");
        if !code.is_empty() {
            assert_eq!(err["error"]["code"], code, "{err}");
        }
    }
    for path in [
        "/api/v1/jobs/nothing",
        "/api/v1/jobs/0123456789abcdef0123456789abcdef/result",
    ] {
        let (status, err) = call_json(&base, reqwest::Method::GET, path, None, None).await;
        assert_eq!(status, 404, "{path}: {err}");
    }
    let (status, listed) = call_json(&base, reqwest::Method::GET, JOBS, None, None).await;
    assert_eq!((status, listed), (200, json!([])));
}

/// Two owners: alice's large job and then bob's small one take turns part by part, so bob's ends
/// while alice's still has most of its parts to run; neither sees the other's job, `admin` sees
/// both, and a client without the `run` scope cannot submit.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn owners_take_turns_and_see_only_their_jobs() {
    let (server, secrets) = crate::http_access::start(
        "jobs-owners",
        &[
            ("alice", "read,run", Quotas::default()),
            ("bob", "read,run", Quotas::default()),
            ("reader", "read", Quotas::default()),
            ("root", "admin", Quotas::default()),
        ],
        Anonymous::None,
        |config| {
            let jobs = jobs_config("jobs-owners-dir", 4_000_000);
            config.jobs = jobs.jobs;
        },
    )
    .await;
    let base = server.base.clone();
    let (alice, bob) = (
        Some(secrets["alice"].as_str()),
        Some(secrets["bob"].as_str()),
    );
    let cells = |n: u64| {
        json!({"system": "pendulum", "methods": ["rk4"], "h": 0.001, "t_end": 2000, "every": 1000,
               "axes": [{"name": "q0[0]", "min": 0.1, "max": 3, "n": n}]})
    };
    // Each cell is 2·10⁶ steps: two cells a part.
    let large = submit(&base, "sweep", &cells(120), alice).await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let small = submit(&base, "sweep", &cells(6), bob).await;
    let seen = events(&base, &small, 0, bob).await;
    assert_eq!(seen.last().unwrap()["event"], "done");
    let (_, large_now) = call_json(
        &base,
        reqwest::Method::GET,
        &format!("{JOBS}/{large}"),
        None,
        alice,
    )
    .await;
    let (done, parts) = (
        large_now["parts_done"].as_u64().unwrap(),
        large_now["parts"].as_u64().unwrap(),
    );
    assert_eq!(parts, 60, "{large_now}");
    assert!(
        done < parts / 2,
        "bob's 3 parts waited for {done} of alice's {parts}"
    );

    for (token, other) in [(alice, &small), (bob, &large)] {
        let (status, _) = call_json(
            &base,
            reqwest::Method::GET,
            &format!("{JOBS}/{other}"),
            None,
            token,
        )
        .await;
        assert_eq!(status, 404);
        for (method, path) in [
            (reqwest::Method::DELETE, format!("{JOBS}/{other}")),
            (reqwest::Method::POST, format!("{JOBS}/{other}/cancel")),
        ] {
            let (status, _) = call_json(&base, method, &path, None, token).await;
            assert_eq!(status, 404);
        }
    }
    let (_, mine) = call_json(&base, reqwest::Method::GET, JOBS, None, bob).await;
    let ids: Vec<&str> = mine
        .as_array()
        .unwrap()
        .iter()
        .map(|j| j["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, [small.as_str()]);
    let root = Some(secrets["root"].as_str());
    let (_, all) = call_json(&base, reqwest::Method::GET, JOBS, None, root).await;
    assert_eq!(all.as_array().unwrap().len(), 2);
    let body = json!({"study": "sweep", "request": cells(2)});
    let reader = Some(secrets["reader"].as_str());
    let (status, _) = call_json(&base, reqwest::Method::POST, JOBS, Some(&body), reader).await;
    assert_eq!(status, 403);
    let (status, _) = call_json(
        &base,
        reqwest::Method::POST,
        &format!("{JOBS}/{large}/cancel"),
        None,
        root,
    )
    .await;
    assert_eq!(status, 200);
}

/// A job that runs past its time limit fails with `timeout`, keeping the parts it finished.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_past_its_time_limit_fails_keeping_its_parts() {
    let mut config = jobs_config("jobs-time-limit", 200_000);
    if let Some(jobs) = config.jobs.as_mut() {
        jobs.time_limit = Duration::from_secs(2);
    }
    let server = server::start(config).await;
    let base = server.base.clone();
    // Parts of one cell of 2·10⁶ steps, some tens of milliseconds each: 16 s of work in all.
    let long = json!({"system": "pendulum", "methods": ["rk4"], "h": 0.001, "t_end": 2000, "every": 1000,
                      "energy_reference": "initial",
                      "axes": [{"name": "q0[0]", "min": 0.1, "max": 3, "n": 400}]});
    let id = submit(&base, "sweep", &long, None).await;
    let seen = events(&base, &id, 0, None).await;
    let last = seen.last().unwrap();
    assert_eq!(last["event"], "failed", "{last}");
    assert_eq!(last["error"]["code"], "timeout", "{last}");
    let stored = seen.iter().filter(|e| e["event"] == "part").count() as u64;
    assert!(
        stored > 0 && stored < last["parts"].as_u64().unwrap(),
        "{last}"
    );
    let (_, job) = call_json(
        &base,
        reqwest::Method::GET,
        &format!("{JOBS}/{id}"),
        None,
        None,
    )
    .await;
    assert_eq!(job["state"], "failed");
    assert_eq!(job["error"]["code"], "timeout");
}

/// `geomint job` against a server: submit a spec file, watch it to its end (exit 0), fetch the
/// document (equal to the route's) and the recording, read its status, remove it; a refused
/// spec exits 2 naming the field.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_command_line_submits_watches_and_fetches() {
    let server = server::start(jobs_config("jobs-cli", 1000)).await;
    let base = server.base.clone();
    let dir = server::scratch_dir("jobs-cli-files");
    std::fs::create_dir_all(&dir).unwrap();
    let (_, _, request) = small_studies().remove(0);
    let spec = dir.join("sweep.json");
    std::fs::write(&spec, request.to_string()).unwrap();
    let (status, direct) = post_json_to(&base, "/api/v1/studies/sweep", &request).await;
    assert_eq!(status, 200);
    let geomint = |args: Vec<String>| {
        let base = base.clone();
        async move {
            tokio::task::spawn_blocking(move || {
                Command::new(env!("CARGO_BIN_EXE_geomint"))
                    .arg("job")
                    .args(&args)
                    .args(["--server", &base])
                    .output()
                    .unwrap()
            })
            .await
            .unwrap()
        }
    };
    let path = |p: &std::path::Path| p.display().to_string();
    let submitted = geomint(vec!["submit".into(), "sweep".into(), path(&spec)]).await;
    assert!(
        submitted.status.success(),
        "{}",
        String::from_utf8_lossy(&submitted.stderr)
    );
    let job: Value = serde_json::from_slice(&submitted.stdout).unwrap();
    let id = job["id"].as_str().unwrap().to_string();
    let watched = geomint(vec!["watch".into(), id.clone()]).await;
    let log = String::from_utf8_lossy(&watched.stderr);
    assert!(watched.status.success(), "{log}");
    assert!(log.lines().last().unwrap().contains(" done: "), "{log}");
    let out = dir.join("map.json");
    let fetched = geomint(vec!["fetch".into(), id.clone(), "-o".into(), path(&out)]).await;
    assert!(fetched.status.success());
    let from_job: Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(without_timings(&from_job), without_timings(&direct));
    let rrd = dir.join("map.rrd");
    let fetched = geomint(vec!["fetch".into(), id.clone(), "-o".into(), path(&rrd)]).await;
    assert!(fetched.status.success());
    assert!(std::fs::read(&rrd).unwrap().starts_with(b"RRF2"));
    let status = geomint(vec!["status".into(), id.clone()]).await;
    let status: Value = serde_json::from_slice(&status.stdout).unwrap();
    assert_eq!(status["state"], "done");
    let cancelled = geomint(vec!["cancel".into(), id.clone()]).await;
    let cancelled: Value = serde_json::from_slice(&cancelled.stdout).unwrap();
    assert_eq!(
        cancelled["state"], "done",
        "cancelling a done job leaves it done"
    );
    let removed = geomint(vec!["remove".into(), id.clone()]).await;
    assert!(removed.status.success());
    let gone = geomint(vec!["status".into(), id]).await;
    assert_eq!(gone.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&gone.stderr).contains("404 not_found"));

    let mut bad = request.clone();
    bad["t_end"] = json!(-1);
    std::fs::write(&spec, bad.to_string()).unwrap();
    let refused = geomint(vec!["submit".into(), "sweep".into(), path(&spec)]).await;
    assert_eq!(refused.status.code(), Some(2));
    let message = String::from_utf8_lossy(&refused.stderr);
    assert!(message.contains("(request.t_end)"), "{message}");
}

/// A job's files count against its owner's quota of stored bytes (`recordings_bytes`), with its
/// recordings: a 30 kB quota holds the job's record and a few of its 8 parts of about 10 kB, and
/// the job then fails with `quota_exceeded`, keeping the parts it stored; a new job is refused
/// at once (403) while the owner has no room; another owner is not touched; once the failed job
/// is removed, the owner submits again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_jobs_files_count_against_its_owners_quota() {
    let small = Quotas {
        recordings_bytes: Some(30_000),
        ..Quotas::default()
    };
    let (server, secrets) = crate::http_access::start(
        "jobs-quota",
        &[
            ("carol", "read,run", small),
            ("dave", "read,run", Quotas::default()),
        ],
        Anonymous::None,
        |config| {
            let jobs = jobs_config("jobs-quota-dir", 4_000_000);
            config.jobs = jobs.jobs;
        },
    )
    .await;
    let base = server.base.clone();
    let (carol, dave) = (
        Some(secrets["carol"].as_str()),
        Some(secrets["dave"].as_str()),
    );
    let sweep = json!({
        "system": "henon_heiles", "methods": ["velocity_verlet", "rk4"], "h": 0.01, "t_end": 2000,
        "every": 1000, "q0": [0, 0.1], "p0": [0.35, 0],
        "axes": [{"name": "q0[1]", "min": -0.2, "max": 0.2, "n": 12},
                 {"name": "p0[1]", "min": -0.1, "max": 0.1, "n": 10}]});
    let id = submit(&base, "sweep", &sweep, carol).await;
    let seen = events(&base, &id, 0, carol).await;
    let last = seen.last().unwrap();
    assert_eq!(last["event"], "failed", "{last}");
    let path = format!("{JOBS}/{id}");
    let (_, failed) = call_json(&base, reqwest::Method::GET, &path, None, carol).await;
    assert_eq!(failed["error"]["code"], "quota_exceeded", "{failed}");
    let message = failed["error"]["message"].as_str().unwrap();
    assert!(message.contains("`carol` keeps"), "{message}");
    assert!(message.contains("its quota of 30000 bytes"), "{message}");
    let stored = failed["parts_done"].as_u64().unwrap();
    assert!(
        (1..failed["parts"].as_u64().unwrap()).contains(&stored),
        "{failed}"
    );
    // No room: refused at once, naming the quota.
    let body = json!({"study": "sweep", "request": sweep});
    let (status, refused) = call_json(&base, reqwest::Method::POST, JOBS, Some(&body), carol).await;
    assert_eq!(status, 403, "{refused}");
    assert_eq!(refused["error"]["code"], "quota_exceeded", "{refused}");
    // Another owner's job runs to its end.
    let other = submit(&base, "sweep", &sweep, dave).await;
    assert_eq!(
        events(&base, &other, 0, dave).await.last().unwrap()["event"],
        "done"
    );
    // The failed job removed, there is room again.
    let (status, _) = call(&base, reqwest::Method::DELETE, &path, None, carol).await;
    assert_eq!(status, 204);
    let small_sweep = json!({"system": "pendulum", "methods": ["rk4"], "h": 0.01, "t_end": 10,
                             "axes": [{"name": "q0[0]", "min": 0.1, "max": 3, "n": 4}]});
    let again = submit(&base, "sweep", &small_sweep, carol).await;
    assert_eq!(
        events(&base, &again, 0, carol).await.last().unwrap()["event"],
        "done"
    );
}

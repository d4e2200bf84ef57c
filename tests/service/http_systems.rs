//! User-defined systems over real HTTP: definitions inline in simulations and studies, stored
//! under `/api/v1/systems` (the same definition, the same id), run by their id bit for bit like
//! the inline definition, kept across a restart, deleted; files in the store that are not
//! definitions skipped with a log line; every wrong definition a 422 naming its field and, in an
//! expression, the character.

use std::io::Write;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::server;

use geomint::api::system::SystemDefinition;
use geomint::http::Config;
use geomint::store::systems::{StoredSystem, SystemStore};
use serde_json::{json, Value};
use server::{client, post_json, start, Server};

/// A scratch systems directory of this test process.
fn systems_dir(name: &str) -> PathBuf {
    let dir = server::scratch_dir(&format!("systems-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn config(dir: &PathBuf) -> Config {
    Config {
        request_timeout: Duration::from_secs(30),
        data_dir: dir.join("recordings"),
        systems_dir: dir.clone(),
        ..Config::default()
    }
}

/// The elastic pendulum of the definition language's example.
fn elastic() -> Value {
    json!({
        "coordinates": ["x", "y"], "momenta": ["px", "py"],
        "mass": 1,
        "potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*y",
        "damping": {"epsilon": 0.1, "matrix": [
            ["x^2/(x^2+y^2)", "x*y/(x^2+y^2)"], ["x*y/(x^2+y^2)", "y^2/(x^2+y^2)"]]},
        "parameters": {"k": 1, "l": 1, "m": 1, "g": 0.2},
        "invariants": {"L": "x*py - y*px"},
        "positions": [["x", "-y"]],
        "q0": [1.2, 0.3], "p0": [0, 0]
    })
}

async fn get(server: &Server, path: &str) -> (u16, Value) {
    let response = client().get(server.url(path)).send().await.unwrap();
    let status = response.status().as_u16();
    (status, response.json().await.unwrap_or(Value::Null))
}

async fn delete(server: &Server, path: &str) -> u16 {
    client()
        .delete(server.url(path))
        .send()
        .await
        .unwrap()
        .status()
        .as_u16()
}

/// The numbers of a simulation answer's runs, without their timings.
fn numbers(answer: &Value) -> Value {
    let mut runs = answer["runs"].clone();
    for run in runs.as_array_mut().unwrap() {
        run.as_object_mut().unwrap().remove("stats");
    }
    runs
}

fn run_of(system: Value) -> Value {
    json!({"system": system, "params": {"g": 0.5}, "methods": ["modin_3s", "rk4"],
        "h": 0.05, "t_end": 20, "output": {"every": 10}})
}

#[tokio::test]
async fn a_stored_definition_has_one_id_runs_like_the_inline_one_and_survives_a_restart() {
    let dir = systems_dir("store");
    let server = start(config(&dir)).await;

    let (status, stored) = post_json(&server, "/api/v1/systems", &elastic()).await;
    assert_eq!(status, 201, "{stored}");
    let id = stored["id"].as_str().unwrap().to_string();
    assert!(id.starts_with("sys-") && id.len() == 20, "{id}");
    assert_eq!(stored["facts"]["dimension"], 2);
    assert_eq!(stored["facts"]["separable"], true);
    let methods: Vec<&str> = stored["facts"]["methods"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    assert!(
        methods.contains(&"modin_3s") && methods.contains(&"rk4"),
        "{methods:?}"
    );
    assert!(
        !methods.contains(&"csv1"),
        "Rayleigh damping is not conformal: {methods:?}"
    );
    assert_eq!(stored["invariants"], json!(["L"]));

    // The same definition, written with other key order and `1.0` for `1`: the same id, 200.
    let mut again = elastic();
    again["mass"] = json!(1.0);
    let reordered: Value =
        serde_json::from_str(&serde_json::to_string_pretty(&again).unwrap()).unwrap();
    let (status, second) = post_json(&server, "/api/v1/systems", &reordered).await;
    assert_eq!(status, 200);
    assert_eq!(second["id"], stored["id"]);
    // A different definition: a different id.
    let mut other = elastic();
    other["parameters"]["k"] = json!(2);
    let (status, third) = post_json(&server, "/api/v1/systems", &other).await;
    assert_eq!(status, 201);
    assert_ne!(third["id"], stored["id"]);

    // Listed after the built-in systems; one of them by id.
    let (_, list) = get(&server, "/api/v1/systems").await;
    let ids: Vec<&str> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids[0], "harmonic_oscillator");
    assert!(
        ids.contains(&"pendulum") && ids.contains(&id.as_str()),
        "{ids:?}"
    );
    let (status, one) = get(&server, &format!("/api/v1/systems/{id}")).await;
    assert_eq!(status, 200);
    assert_eq!(one["definition"]["potential"], elastic()["potential"]);
    assert_eq!(one["facts"], stored["facts"]);

    // Run by id and inline: the same numbers, bit for bit.
    let (status, by_id) = post_json(&server, "/api/v1/simulate", &run_of(json!(id))).await;
    assert_eq!(status, 200, "{by_id}");
    let (status, inline) = post_json(&server, "/api/v1/simulate", &run_of(elastic())).await;
    assert_eq!(status, 200, "{inline}");
    assert!(
        numbers(&by_id) == numbers(&inline),
        "by id and inline differ"
    );
    assert_eq!(by_id["system"]["id"], json!(id));
    let samples = by_id["runs"][0]["t"].as_array().unwrap().len();
    assert_eq!(samples, 41);
    // The damping dissipates energy; J = x p_y − y p_x is not conserved (gravity has a torque).
    let energy = by_id["runs"][0]["energy"].as_array().unwrap();
    assert!(energy.last().unwrap().as_f64().unwrap() < energy[0].as_f64().unwrap());

    // A convergence study on the stored system, by id.
    let study = json!({"system": id, "methods": ["modin_3s"], "h": [0.04, 0.02, 0.01], "t_end": 2});
    let (status, answer) = post_json(&server, "/api/v1/studies/convergence", &study).await;
    assert_eq!(status, 200, "{answer}");
    let order = answer["series"][0]["state"]["order"]
        .as_f64()
        .unwrap_or(f64::NAN);
    assert!(
        (order - 2.0).abs() < 0.2,
        "observed order {order}: {answer}"
    );

    // A restart on the same directory keeps both definitions.
    let restarted = start(config(&dir)).await;
    let (status, kept) = get(&restarted, &format!("/api/v1/systems/{id}")).await;
    assert_eq!(status, 200);
    assert_eq!(kept["definition"], one["definition"]);
    assert_eq!(
        kept["created_unix_ms"].as_u64().unwrap() / 1000,
        one["created_unix_ms"].as_u64().unwrap() / 1000
    );
    let (status, rerun) = post_json(&restarted, "/api/v1/simulate", &run_of(json!(id))).await;
    assert_eq!(status, 200);
    assert!(
        numbers(&rerun) == numbers(&by_id),
        "the restarted server differs"
    );

    // Deleting: built-in systems stay; a stored one goes, and its id no longer runs.
    assert_eq!(delete(&restarted, "/api/v1/systems/pendulum").await, 409);
    assert_eq!(
        delete(&restarted, &format!("/api/v1/systems/{id}")).await,
        204
    );
    assert_eq!(
        delete(&restarted, &format!("/api/v1/systems/{id}")).await,
        404
    );
    assert_eq!(
        get(&restarted, &format!("/api/v1/systems/{id}")).await.0,
        404
    );
    let (status, refused) = post_json(&restarted, "/api/v1/simulate", &run_of(json!(id))).await;
    assert_eq!(status, 422);
    assert_eq!(refused["error"]["code"], "unknown_system");
    assert!(!dir.join(format!("{id}.json")).exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test]
async fn the_store_holds_at_most_its_cap() {
    let dir = systems_dir("cap");
    let server = start(Config {
        max_systems: 2,
        ..config(&dir)
    })
    .await;
    for k in 1..=2 {
        let mut d = elastic();
        d["parameters"]["k"] = json!(k);
        assert_eq!(post_json(&server, "/api/v1/systems", &d).await.0, 201);
    }
    let mut d = elastic();
    d["parameters"]["k"] = json!(3);
    let (status, answer) = post_json(&server, "/api/v1/systems", &d).await;
    assert_eq!(status, 507);
    assert_eq!(answer["error"]["code"], "too_many_systems");
    // Storing one already there still answers it.
    let mut d = elastic();
    d["parameters"]["k"] = json!(1);
    assert_eq!(post_json(&server, "/api/v1/systems", &d).await.0, 200);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A log writer into a shared buffer.
#[derive(Clone, Default)]
struct Captured(Arc<Mutex<Vec<u8>>>);

impl Write for Captured {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(bytes);
        Ok(bytes.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn files_that_are_not_definitions_are_skipped_with_a_log_line_and_left_in_place() {
    let dir = systems_dir("corrupt");
    std::fs::create_dir_all(&dir).unwrap();
    // A good definition, stored by the store itself.
    let good = {
        let store = SystemStore::open(&dir, 10);
        let definition = SystemDefinition::read(&elastic(), &Default::default()).unwrap();
        let stored = StoredSystem::new(definition, 0).unwrap();
        let owner = geomint::store::systems::DefinitionOwner {
            name: "alice".into(),
            quota: None,
        };
        let (stored, new) = store.insert(stored, &owner).unwrap();
        assert!(new);
        stored.info.id.to_string()
    };
    let torn = dir.join("sys-0123456789abcdef.json");
    std::fs::write(&torn, br#"{"coordinates": ["x"], "potential": "x^"#).unwrap();
    let misnamed = dir.join("sys-fedcba9876543210.json");
    std::fs::copy(dir.join(format!("{good}.json")), &misnamed).unwrap();
    // A definition that reads but does not check (`y` is not declared), under its own id.
    let unchecked = json!({"coordinates": ["x"], "potential": "x^2 + y"});
    let id = SystemDefinition::read(&unchecked, &Default::default())
        .unwrap()
        .id();
    let wrong = dir.join(format!("{id}.json"));
    std::fs::write(&wrong, unchecked.to_string()).unwrap();
    let foreign = dir.join("notes.txt");
    std::fs::write(&foreign, b"not a definition").unwrap();

    let log = Captured::default();
    let writer = log.clone();
    let subscriber = tracing_subscriber::fmt()
        .with_writer(move || writer.clone())
        .with_ansi(false)
        .finish();
    let store = tracing::subscriber::with_default(subscriber, || SystemStore::open(&dir, 10));
    let ids: Vec<String> = store.list().iter().map(|s| s.info.id.to_string()).collect();
    assert_eq!(ids, vec![good.clone()]);
    let log = String::from_utf8(log.0.lock().unwrap().clone()).unwrap();
    for (file, reason) in [
        (&torn, "not a definition"),
        (&misnamed, "not its file name"),
        (&wrong, "does not check at `potential`"),
        (&foreign, "not a stored definition's file name"),
    ] {
        let name = file.file_name().unwrap().to_string_lossy().into_owned();
        let line = log
            .lines()
            .find(|l| l.contains(&name))
            .unwrap_or_else(|| panic!("no log line for {name}:\n{log}"));
        assert!(
            line.contains("skipping a stored system") && line.contains(reason),
            "{line}"
        );
        assert!(file.exists(), "{name} is left for a person to look at");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test]
async fn wrong_definitions_are_refused_at_their_field_and_character() {
    let dir = systems_dir("refusals");
    let server = start(config(&dir)).await;
    let with = |patch: Value| {
        let mut d = elastic();
        for (k, v) in patch.as_object().unwrap() {
            if v.is_null() {
                d.as_object_mut().unwrap().remove(k);
            } else {
                d[k] = v.clone();
            }
        }
        d
    };
    let cases = [
        (
            json!({"potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*"}),
            "system.potential",
            "invalid_expression",
            Some(34),
        ),
        (
            json!({"potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*z"}),
            "system.potential",
            "invalid_expression",
            Some(34),
        ),
        (
            json!({"invariants": {"L": "x*py - y*px + foo(x)"}}),
            "system.invariants.L",
            "invalid_expression",
            Some(14),
        ),
        (
            json!({"mass": [[1, 2], [2, 1]]}),
            "system.mass",
            "invalid_value",
            None,
        ),
        (
            json!({"mass": [[1, 0], [0.5, 1]]}),
            "system.mass[1][0]",
            "invalid_value",
            None,
        ),
        (
            json!({"mass": "x"}),
            "system.mass",
            "invalid_expression",
            Some(0),
        ),
        (
            json!({"damping": {"epsilon": 0.1, "matrix": [["x^2", "x*y"], ["x", "y^2"]]}}),
            "system.damping.matrix[1][0]",
            "invalid_value",
            None,
        ),
        (
            json!({"damping": {"epsilon": 0.1, "matrix": [["1", "0"]]}}),
            "system.damping.matrix",
            "invalid_value",
            None,
        ),
        (
            json!({"momenta": ["px", "x"]}),
            "system.momenta[1]",
            "invalid_value",
            None,
        ),
        (
            json!({"coordinates": []}),
            "system.coordinates",
            "invalid_value",
            None,
        ),
        (
            json!({"hamiltonian": "px^2/2"}),
            "system.hamiltonian",
            "invalid_value",
            None,
        ),
        (json!({"q0": [1]}), "system.q0", "invalid_value", None),
        (
            json!({"colour": "red"}),
            "system.colour",
            "unknown_field",
            None,
        ),
    ];
    for (patch, field, code, position) in cases {
        let (status, answer) =
            post_json(&server, "/api/v1/simulate", &run_of(with(patch.clone()))).await;
        assert_eq!(status, 422, "{patch}: {answer}");
        let error = &answer["error"];
        assert_eq!(error["field"], field, "{patch}: {answer}");
        assert_eq!(error["code"], code, "{patch}: {answer}");
        match position {
            Some(at) => assert_eq!(error["position"], at, "{patch}: {answer}"),
            None => assert!(error.get("position").is_none(), "{patch}: {answer}"),
        }
    }
    // The same definition stored: the same field without the `system.` prefix.
    let (status, answer) = post_json(
        &server,
        "/api/v1/systems",
        &with(json!({"potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*"})),
    )
    .await;
    assert_eq!(status, 422);
    assert_eq!(answer["error"]["field"], "potential");
    assert_eq!(answer["error"]["position"], 34);
    // A method the system does not qualify for names the requirement.
    let mut body = run_of(elastic());
    body["methods"] = json!(["csv1"]);
    let (status, answer) = post_json(&server, "/api/v1/simulate", &body).await;
    assert_eq!(status, 422);
    assert_eq!(answer["error"]["code"], "unmet_requirement");
    assert_eq!(answer["error"]["field"], "methods[0]");
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test]
async fn a_definition_is_recorded_and_its_samples_read_back() {
    let dir = systems_dir("recording");
    let server = start(config(&dir)).await;
    let pendulum = json!({
        "coordinates": ["a", "b"],
        "hamiltonian": "(p_a^2 + 2*p_b^2 - 2*p_a*p_b*cos(a - b)) / (2*(1 + sin(a - b)^2)) - 2*g*cos(a) - g*cos(b)",
        "parameters": {"g": 9.81},
        "positions": [["sin(a)", "-cos(a)"], ["sin(a) + sin(b)", "-cos(a) - cos(b)"]],
        "q0": [1, 0.5]
    });
    let body = json!({"system": pendulum, "methods": ["implicit_midpoint"], "h": 0.01,
        "t_end": 2, "output": {"every": 10}});
    let (status, created) = post_json(&server, "/api/v1/recordings", &body).await;
    assert_eq!(status, 201, "{created}");
    let id = created["id"].as_str().unwrap();
    let (status, read) = get(&server, &format!("/api/v1/recordings/{id}/samples")).await;
    assert_eq!(status, 200, "{read}");
    let (_, direct) = post_json(&server, "/api/v1/simulate", &body).await;
    // The recording keeps single-precision positions: the samples read back agree to 1e-6.
    let recorded = read["runs"][0]["q"].as_array().unwrap();
    let computed = direct["runs"][0]["q"].as_array().unwrap();
    assert_eq!(recorded.len(), computed.len());
    assert_eq!(recorded.len(), 21);
    for (r, c) in recorded.iter().zip(computed) {
        for (x, y) in r.as_array().unwrap().iter().zip(c.as_array().unwrap()) {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!((x - y).abs() < 1e-6 * (1.0 + y.abs()), "{x} against {y}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs the `geomint` command line with `args`, its stored systems read from `dir`.
fn geomint_with_systems(dir: &std::path::Path, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_geomint"))
        .args(args)
        .env("GEOMINT_SYSTEMS_DIR", dir)
        .env_remove("GEOMINT_MAX_STEPS")
        .output()
        .unwrap()
}

#[tokio::test]
async fn the_command_line_names_stored_systems_like_the_server() {
    let dir = systems_dir("cli");
    let server = start(config(&dir)).await;
    let (status, stored) = post_json(&server, "/api/v1/systems", &elastic()).await;
    assert_eq!(status, 201, "{stored}");
    let id = stored["id"].as_str().unwrap().to_string();
    let scratch = server::scratch_dir("systems-cli-specs");
    std::fs::create_dir_all(&scratch).unwrap();

    // A run: the same numbers as the server's for the stored id.
    let request = run_of(json!(id));
    let (status, served) = post_json(&server, "/api/v1/simulate", &request).await;
    assert_eq!(status, 200, "{served}");
    let spec = scratch.join("run.json");
    std::fs::write(&spec, serde_json::to_vec(&request).unwrap()).unwrap();
    let out = geomint_with_systems(&dir, &["run", spec.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ran = geomint::api::json::parse_json(&out.stdout).unwrap();
    assert_eq!(numbers(&ran), numbers(&served));

    // A sweep: the same document, digest included (the stored definition inlined), as the
    // server's; without the directory the id is unknown, named at `system`.
    let sweep = json!({"system": id, "methods": ["modin_3s"], "h": 0.1, "t_end": 5,
        "axes": [{"name": "params.g", "min": 0.1, "max": 0.5, "n": 3}]});
    let (status, served) = post_json(&server, "/api/v1/studies/sweep", &sweep).await;
    assert_eq!(status, 200, "{served}");
    let spec = scratch.join("sweep.json");
    std::fs::write(&spec, serde_json::to_vec(&sweep).unwrap()).unwrap();
    let out = geomint_with_systems(&dir, &["study", "sweep", spec.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut swept = geomint::api::json::parse_json(&out.stdout).unwrap();
    let mut served = served;
    for doc in [&mut swept, &mut served] {
        doc.as_object_mut().unwrap().remove("wall_ms");
    }
    assert_eq!(swept, served);
    let nowhere = scratch.join("no-systems-here");
    let out = geomint_with_systems(&nowhere, &["study", "sweep", spec.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let message = String::from_utf8_lossy(&out.stderr);
    assert!(
        message.contains("system") && message.contains(&id),
        "{message}"
    );
}

//! Pins what the service answers, bit for bit: the JSON of a set of runs, studies, catalogues and
//! refused requests, each compared with its snapshot in `tests/snapshots/` (insta). Wall times
//! are the only numbers that differ between two computations, so they are redacted; every other
//! number — states, energies, errors, spectral radii, fitted orders — and every error code,
//! field and message must stay exactly as recorded. A change that moves code without changing
//! behaviour keeps this test green; a change of behaviour shows up here as a diff to review.
//!
//! Floats are compared through their shortest round-trip decimal form, which identifies the bits.

use crate::server;

use geomint::http::Config;
use insta::assert_json_snapshot;
use serde_json::{json, Value};
use server::{post_json, start};

/// Fields that hold wall times, at any depth.
const TIMED: &[&str] = &["wall_time_ms", "wall_ms", "timings_ms", "reference_ms"];

/// `value` with every timed number replaced by a marker: wall times, and the work–precision
/// fits (objects with a `slope`), which regress wall time on error. Convergence fits (`order`
/// and `intercept` of errors against h) are not timed and stay.
fn redact(mut value: Value) -> Value {
    fn walk(v: &mut Value) {
        match v {
            Value::Object(map) => {
                let timed_fit = map.contains_key("slope");
                for (key, child) in map.iter_mut() {
                    let fitted = timed_fit && (key == "slope" || key == "intercept");
                    if fitted || TIMED.contains(&key.as_str()) {
                        *child = Value::String("[timed]".into());
                    } else {
                        walk(child);
                    }
                }
            }
            Value::Array(items) => items.iter_mut().for_each(walk),
            _ => {}
        }
    }
    walk(&mut value);
    value
}

async fn pin(server: &server::Server, path: &str, body: Value) -> Value {
    let (status, answer) = post_json(server, path, &body).await;
    redact(json!({"status": status, "answer": answer}))
}

async fn get(server: &server::Server, path: &str) -> Value {
    let response = server::client().get(server.url(path)).send().await.unwrap();
    let status = response.status().as_u16();
    let bytes = response.bytes().await.unwrap();
    let answer: Value = serde_json::from_slice(&bytes).unwrap();
    json!({"status": status, "answer": answer})
}

fn config() -> Config {
    Config {
        max_concurrent: 4,
        request_timeout: std::time::Duration::from_secs(120),
        queue_timeout: std::time::Duration::from_secs(60),
        long_queue_timeout: std::time::Duration::from_secs(60),
        ..Config::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn simulations_are_pinned() {
    let s = start(config()).await;
    let sim = "/api/v1/simulate";
    assert_json_snapshot!(
        "pendulum_every_splitting_and_baseline",
        pin(&s, sim, json!({"system": "pendulum", "params": {"epsilon": 0.01},
            "methods": ["modin_3s", "modin_2s", {"id": "modin_rks", "inner": "rk4"}, "csv1", "csv2",
                "cimp", "heun", "rk3", "rk4", "explicit_euler", "position_verlet", "velocity_verlet",
                "symplectic_euler", "symplectic_euler_adjoint", "implicit_midpoint"],
            "h": 0.1, "t_end": 20, "output": {"every": 25}, "compare_to_reference": true}))
        .await
    );
    assert_json_snapshot!(
        "oscillator_compositions_exact_solution",
        pin(&s, sim, json!({"system": "harmonic_oscillator", "params": {"omega": 2, "gamma": 0.3},
            "methods": [{"id": "triple_jump", "base": "csv2"}, {"id": "suzuki_4", "base": "cimp"},
                {"id": "yoshida_6", "base": "modin_2s"}, {"id": "kahan_li_6", "base": "velocity_verlet"},
                {"id": "kahan_li_8", "base": "modin_3s"}, {"id": "reference", "tolerance": 1e-9},
                {"id": "modin_rks", "inner": "implicit_midpoint"}],
            "h": 0.05, "t_end": 4, "output": {"every": 8}}))
        .await
    );
    assert_json_snapshot!(
        "processed_compositions",
        pin(
            &s,
            sim,
            json!({"system": "elastic_pendulum_3d", "params": {"epsilon": 0.001},
            "methods": [{"id": "blanes_casas_murua_8", "base": "modin_3s"},
                {"id": "blanes_casas_murua_8", "base": "modin_2s"},
                {"id": "blanes_casas_murua_8", "base": "implicit_midpoint"}],
            "h": 0.2, "t_end": 8, "output": {"every": 10}})
        )
        .await
    );
    assert_json_snapshot!(
        "oscillator_jacobian_defect",
        pin(
            &s,
            sim,
            json!({"system": "harmonic_oscillator", "params": {"omega": 3.51, "gamma": 0.4},
            "methods": ["csv1", "csv2", "cimp", "modin_3s", "rk4"], "h": 0.3, "t_end": 3,
            "jacobian_defect": true})
        )
        .await
    );
    assert_json_snapshot!(
        "rowlands_processors",
        pin(&s, sim, json!({"system": "elastic_pendulum_2d",
            "methods": [{"id": "rowlands", "processor": "none"}, {"id": "rowlands", "processor": "original"},
                "rowlands", "velocity_verlet"], "h": 0.1, "t_end": 4, "output": {"every": 10}}))
        .await
    );
    assert_json_snapshot!(
        "elastic_pendulum_3d_charts",
        pin(
            &s,
            sim,
            json!({"system": "elastic_pendulum_3d", "params": {"epsilon": 0.1},
            "methods": ["modin_3s", "rk4", "symplectic_euler"], "h": 0.1, "t_end": 10,
            "output": {"every": 20}})
        )
        .await
    );
    assert_json_snapshot!(
        "elastic_pendulum_3d_cylindrical",
        pin(
            &s,
            sim,
            json!({"system": "elastic_pendulum_3d", "chart": "cylindrical",
            "methods": ["symplectic_euler", "symplectic_euler_adjoint", "implicit_midpoint", "rk4"],
            "h": 0.1, "t_end": 10, "output": {"every": 20}})
        )
        .await
    );
    assert_json_snapshot!(
        "planar_polar_from_cartesian",
        pin(
            &s,
            sim,
            json!({"system": "elastic_pendulum_2d", "chart": "polar",
            "initial_coordinates": "cartesian", "q0": [0.7, 1.1], "p0": [0.1, -0.2],
            "methods": ["symplectic_euler", "symplectic_euler_adjoint", "rk4"], "h": 0.05,
            "t_end": 5, "output": {"every": 20}, "compare_to_reference": true})
        )
        .await
    );
    assert_json_snapshot!(
        "free_particle_polar",
        pin(
            &s,
            sim,
            json!({"system": "free_particle_2d", "chart": "polar",
            "methods": ["symplectic_euler", "implicit_midpoint"], "h": 0.02, "t_end": 2,
            "output": {"every": 20}})
        )
        .await
    );
    assert_json_snapshot!(
        "nbody_figure_eight",
        pin(
            &s,
            sim,
            json!({"system": "nbody", "params": {"gamma": 0.05},
            "methods": ["csv1", {"id": "kahan_li_8", "base": "modin_3s"}, "rk4"], "h": 0.01,
            "t_end": 2, "output": {"every": 40}})
        )
        .await
    );
    assert_json_snapshot!(
        "undamped_velocity_verlet_compositions",
        pin(
            &s,
            sim,
            json!({"system": "henon_heiles", "q0": [-0.2, 0.0], "p0": [0.1, 0.45],
            "methods": [{"id": "triple_jump", "base": "velocity_verlet"},
                {"id": "kahan_li_8", "base": "velocity_verlet"},
                {"id": "blanes_casas_murua_8", "base": "velocity_verlet"}],
            "h": 0.1, "t_end": 20, "output": {"every": 40}})
        )
        .await
    );
    assert_json_snapshot!(
        "nbody_lennard_jones",
        pin(
            &s,
            sim,
            json!({"system": "nbody", "params": {"masses": [1, 2], "potential": "lennard_jones",
            "lj_sigma": 1.1}, "q0": [0, 0, 0, 1.2, 0, 0], "p0": [0, 0.1, 0, 0, -0.05, 0],
            "method": "modin_2s", "h": 0.01, "t_end": 1, "output": {"every": 20}})
        )
        .await
    );
    assert_json_snapshot!(
        "first_order_charts",
        pin(
            &s,
            sim,
            json!({"system": "gompertz", "chart": "transformed", "q0": [3],
            "methods": ["explicit_euler", "rk4"], "h": 0.9, "t_end": 9})
        )
        .await
    );
    assert_json_snapshot!(
        "compensating_chart",
        pin(
            &s,
            sim,
            json!({"system": "harmonic_oscillator", "chart": "compensating",
            "params": {"gamma": 0}, "methods": ["symplectic_euler", "rk4"], "h": 0.04,
            "t_end": 4, "output": {"every": 10}})
        )
        .await
    );
    assert_json_snapshot!(
        "exponential_decay_original",
        pin(
            &s,
            sim,
            json!({"system": "exponential_decay", "methods": ["explicit_euler", "heun"],
            "h": 0.3, "t_end": 3})
        )
        .await
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn studies_are_pinned() {
    let s = start(config()).await;
    assert_json_snapshot!(
        "stability_map",
        pin(
            &s,
            "/api/v1/stability",
            json!({"methods": ["csv1", "csv2", "cimp",
            {"id": "triple_jump", "base": "csv1"}, "rk4", "modin_2s"], "omega": 3.51,
            "gamma": {"min": 0, "max": 3.5, "n": 8}, "h": {"min": 0, "max": 1, "n": 9}})
        )
        .await
    );
    assert_json_snapshot!(
        "stability_point",
        pin(
            &s,
            "/api/v1/stability/point",
            json!({"method": "csv2", "omega": 3.51,
            "gamma": 0.5, "h": 0.2})
        )
        .await
    );
    assert_json_snapshot!(
        "convergence_fig9",
        pin(
            &s,
            "/api/v1/studies/convergence",
            json!({"system": "harmonic_oscillator",
            "params": {"omega": 1, "gamma": 0}, "charts": ["cartesian", "compensating"],
            "q0": [1], "p0": [0], "t_end": 10, "methods": ["symplectic_euler", "rk4"],
            "h": [0.04, 0.02, 0.01]})
        )
        .await
    );
    assert_json_snapshot!(
        "convergence_against_reference",
        pin(
            &s,
            "/api/v1/studies/convergence",
            json!({"system": "elastic_pendulum_2d",
            "chart": "polar", "t_end": 2, "methods": ["implicit_midpoint"], "h": [0.1, 0.05],
            "samples": 4})
        )
        .await
    );
    assert_json_snapshot!(
        "work_precision",
        pin(
            &s,
            "/api/v1/studies/work-precision",
            json!({"system": "elastic_pendulum_3d",
            "params": {"epsilon": 0.001}, "t_end": 20, "samples": 10,
            "runs": [{"method": {"id": "kahan_li_8", "base": "modin_3s"}, "h": [0.4, 0.2]},
                {"method": "rk4", "h": [0.1]}, {"method": "reference", "tolerance": [1e-8]}],
            "reference": {"method": {"id": "kahan_li_8", "base": "modin_3s"}, "h": 0.05}})
        )
        .await
    );
    assert_json_snapshot!(
        "work_precision_exact",
        pin(
            &s,
            "/api/v1/studies/work-precision",
            json!({"system": "harmonic_oscillator",
            "t_end": 10, "runs": [{"method": "csv1", "h": [0.1, 0.05]}]})
        )
        .await
    );
    assert_json_snapshot!(
        "energy_map",
        pin(
            &s,
            "/api/v1/studies/energy-map",
            json!({"nx": 5, "ny": 4, "t_max": 40,
            "h": 0.2})
        )
        .await
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sweeps_are_pinned() {
    let s = start(config()).await;
    // Over a parameter and the step, against the exact solution (csv1's divergence map).
    assert_json_snapshot!(
        "sweep_gamma_h",
        pin(
            &s,
            "/api/v1/studies/sweep",
            json!({"system": "harmonic_oscillator", "methods": ["csv1", "rk4"], "t_end": 20,
            "every": 10, "axes": [{"name": "params.gamma", "min": 0.0, "max": 2.0, "n": 4},
            {"name": "h", "min": 0.1, "max": 3.0, "n": 3}]})
        )
        .await
    );
    // Over the initial state in two charts, against H₀: the energy map's kind, run in lanes,
    // with the pivot outside the polar chart.
    assert_json_snapshot!(
        "sweep_energy_map_kind",
        pin(
            &s,
            "/api/v1/studies/sweep",
            json!({"system": "elastic_pendulum_2d", "params": {"g": 0.02},
            "charts": ["cartesian", "polar"], "initial_coordinates": "cartesian", "p0": [0, 0],
            "methods": ["symplectic_euler"], "h": 0.2, "t_end": 40, "energy_reference": "initial",
            "axes": [{"name": "q0[0]", "min": -1.3, "max": 1.1, "n": 5},
            {"name": "q0[1]", "min": 0.0, "max": 1.7, "n": 3}]})
        )
        .await
    );
    // Damped without an exact solution: against a reference run; a log axis.
    assert_json_snapshot!(
        "sweep_against_reference",
        pin(
            &s,
            "/api/v1/studies/sweep",
            json!({"system": "pendulum", "params": {"epsilon": 0.05},
            "methods": ["modin_3s", "heun"], "h": 0.1, "t_end": 5, "every": 5,
            "axes": [{"name": "params.epsilon", "min": 0.01, "max": 0.3, "n": 3, "scale": "log"}]})
        )
        .await
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn catalogues_are_pinned() {
    let s = start(config()).await;
    assert_json_snapshot!("systems", get(&s, "/api/v1/systems").await);
    assert_json_snapshot!("methods", get(&s, "/api/v1/methods").await);
    assert_json_snapshot!("system_nbody", get(&s, "/api/v1/systems/nbody").await);
    assert_json_snapshot!("method_unknown", get(&s, "/api/v1/methods/nope").await);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refusals_are_pinned() {
    let s = start(config()).await;
    let ok = json!({"system": "pendulum", "methods": ["modin_3s"], "h": 0.1, "t_end": 1});
    let with = |key: &str, v: Value| {
        let mut body = ok.clone();
        body[key] = v;
        body
    };
    let sim = "/api/v1/simulate";
    let cases: Vec<(&str, Value)> = vec![
        (sim, with("system", json!("nope"))),
        (sim, with("system", json!(""))),
        (sim, with("system", json!(3))),
        (sim, with("h", json!(-0.1))),
        (sim, with("h", json!(null))),
        (sim, with("t_end", json!(1e12))),
        (sim, with("x", json!(1))),
        (sim, with("methods", json!([]))),
        (sim, with("methods", json!(["nope"]))),
        (
            sim,
            with("methods", json!([{"id": "modin_3s", "inner": "rk4"}])),
        ),
        (
            sim,
            with("methods", json!([{"id": "modin_rks", "inner": "csv1"}])),
        ),
        (
            sim,
            with("methods", json!([{"id": "modin_rks", "inner": "rk9"}])),
        ),
        (
            sim,
            with("methods", json!([{"id": "triple_jump", "base": "heun"}])),
        ),
        (
            sim,
            with("methods", json!([{"id": "rowlands", "processor": "x"}])),
        ),
        (
            sim,
            with("methods", json!([{"id": "reference", "tolerance": 1}])),
        ),
        (sim, with("methods", json!(["rowlands"]))),
        (
            sim,
            with(
                "methods",
                json!([
                    "modin_3s", "heun", "rk4", "rk3", "csv1", "csv2", "cimp", "heun", "rk4", "rk3",
                    "csv1", "csv2", "cimp", "heun", "rk4", "rk3", "csv1"
                ]),
            ),
        ),
        (sim, with("method", json!("heun"))),
        (sim, with("params", json!({"gamma": -1}))),
        (sim, with("params", json!({"gamma": 1, "epsilon": 2}))),
        (sim, with("params", json!({"omega": 1}))),
        (sim, with("params", json!({"gamma": "x"}))),
        (sim, with("q0", json!([1, 2]))),
        (sim, with("q0", json!([1, "a"]))),
        (sim, with("output", json!({"every": 0}))),
        (sim, with("output", json!({"every": -1}))),
        (sim, with("chart", json!("polar"))),
        (sim, with("initial_coordinates", json!("polar"))),
        (
            sim,
            json!({"system": "elastic_pendulum_3d", "methods": ["modin_3s"], "h": 0.1,
            "t_end": 1, "jacobian_defect": true}),
        ),
        (
            sim,
            json!({"system": "pendulum", "methods": ["modin_3s", "reference"], "h": 0.1,
            "t_end": 1, "jacobian_defect": true}),
        ),
        (
            sim,
            json!({"system": "elastic_pendulum_2d", "chart": "polar", "methods": ["modin_3s"],
            "h": 0.1, "t_end": 1}),
        ),
        (
            sim,
            json!({"system": "elastic_pendulum_2d", "chart": "polar", "q0": [0, 0],
            "initial_coordinates": "cartesian", "methods": ["rk4"], "h": 0.1, "t_end": 1}),
        ),
        (
            sim,
            json!({"system": "nbody", "params": {"masses": [1, 2]}, "methods": ["rk4"],
            "h": 0.1, "t_end": 1}),
        ),
        (
            sim,
            json!({"system": "nbody", "params": {"potential": "yukawa"}, "methods": ["rk4"],
            "h": 0.1, "t_end": 1}),
        ),
        (
            sim,
            json!({"system": "harmonic_oscillator", "params": {"gamma": 2},
            "methods": ["csv2"], "h": 1, "t_end": 1}),
        ),
        (
            sim,
            json!({"system": "pendulum", "method": {"id": "modin_rks", "inner": "rk9"},
            "h": 0.1, "t_end": 1}),
        ),
        (sim, json!({"system": "pendulum", "h": 0.1, "t_end": 1})),
        (
            sim,
            json!({"system": "pendulum", "methods": ["heun"], "h": 1e-4, "t_end": 200,
            "output": {"every": 1}}),
        ),
        (
            "/api/v1/stability",
            json!({"methods": ["csv1", "reference"], "omega": 1,
            "gamma": {"min": 0, "max": 1, "n": 3}, "h": {"min": 0, "max": 1, "n": 3}}),
        ),
        (
            "/api/v1/stability",
            json!({"methods": ["csv1", "rk4"], "omega": 1,
            "gamma": {"min": 0, "max": 1, "n": 1000}, "h": {"min": 0, "max": 1, "n": 1000}}),
        ),
        (
            "/api/v1/stability",
            json!({"methods": ["rowlands"], "omega": 1,
            "gamma": {"min": 0, "max": 1, "n": 3}, "h": {"min": 0, "max": 1, "n": 3}}),
        ),
        (
            "/api/v1/stability/point",
            json!({"method": "csv2", "omega": 1, "gamma": 2, "h": 1}),
        ),
        (
            "/api/v1/stability/point",
            json!({"method": "csv2", "omega": 1, "gamma": -2, "h": 1}),
        ),
        (
            "/api/v1/studies/convergence",
            json!({"system": "harmonic_oscillator", "t_end": 1,
            "methods": ["rk4"], "h": [0.1, 0.3]}),
        ),
        (
            "/api/v1/studies/convergence",
            json!({"system": "harmonic_oscillator", "t_end": 1,
            "charts": ["cartesian", "polar"], "methods": ["rk4"], "h": [0.1]}),
        ),
        (
            "/api/v1/studies/convergence",
            json!({"system": "nope", "t_end": 1,
            "methods": ["rk4"], "h": [0.1]}),
        ),
        (
            "/api/v1/studies/convergence",
            json!({"system": "elastic_pendulum_2d", "chart": "polar",
            "t_end": 1, "methods": ["modin_3s"], "h": [0.1]}),
        ),
        (
            "/api/v1/studies/work-precision",
            json!({"system": "pendulum", "t_end": 10,
            "runs": [{"method": "rk4", "h": [0.3]}]}),
        ),
        (
            "/api/v1/studies/work-precision",
            json!({"system": "pendulum", "t_end": 10,
            "runs": [{"method": "reference", "h": [0.1]}]}),
        ),
        (
            "/api/v1/studies/work-precision",
            json!({"system": "pendulum", "t_end": 10,
            "runs": [{"method": "rk4", "h": [1e-7]}]}),
        ),
        ("/api/v1/studies/energy-map", json!({"method": "modin_3s"})),
        ("/api/v1/studies/energy-map", json!({"nx": 0})),
        (
            "/api/v1/studies/energy-map",
            json!({"nx": 401, "ny": 401, "t_max": 1e6}),
        ),
        ("/api/v1/studies/energy-map", json!({"params": {"m": -1}})),
    ];
    let mut answers = Vec::new();
    for (path, body) in cases {
        let (status, answer) = post_json(&s, path, &body).await;
        answers.push(json!({"path": path, "request": body, "status": status, "answer": answer}));
    }
    // Malformed bodies, read by the body extractor.
    for text in [
        "{\"h\": 1e999}",
        "{\"system\": \"pendulum\",",
        "",
        "[1, 2]",
        "{\"system\": \"pendulum\", \"q0\": [1, -1e999]}",
    ] {
        let response = server::client()
            .post(s.url(sim))
            .header("content-type", "application/json")
            .body(text)
            .send()
            .await
            .unwrap();
        let status = response.status().as_u16();
        let answer: Value = serde_json::from_slice(&response.bytes().await.unwrap()).unwrap();
        answers.push(json!({"path": sim, "text": text, "status": status, "answer": answer}));
    }
    assert_json_snapshot!("refusals", redact(Value::Array(answers)));
}

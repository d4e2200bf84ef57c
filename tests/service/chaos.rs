//! Chaos indicators through the wire layer: typed-in systems (the page's examples) against finite
//! differences of every method's step, the conformal pairing on a typed-in damped system, a
//! published Lyapunov exponent reproduced, and the requests' fields read and refused by name.

use crate::common;

use geomint::api::crossings::StopWhenRequest;
use geomint::api::system::NoStoredSystems;
use geomint::api::system::SystemDefinition;
use geomint::api::SimulateRequest;
use geomint::core::chaos::{ChaosSpec, Indicator};
use geomint::core::error::Field;
use geomint::core::methods::{self, Method, MethodId};
use geomint::core::run::{Budget, Stepper};
use geomint::core::simulation::{Limits, Simulation, SimulationSpec};
use geomint::core::system::{MechanicalSystem, State};
use geomint::core::systems::SystemRef;
use geomint::core::tangent::Tangent;
use geomint::core::with_system;
use serde_json::{json, Value};

/// A server's settings with scratch folders of its own.
fn config() -> geomint::http::Config {
    geomint::http::Config {
        data_dir: crate::server::scratch_dir("chaos"),
        systems_dir: crate::server::scratch_dir("chaos-systems"),
        ..geomint::http::Config::default()
    }
}

/// The system of a definition written as JSON.
fn defined(definition: Value) -> SystemRef {
    SystemDefinition::read(&definition, &Field::new("system"))
        .expect("the definition reads")
        .define(&Field::new("system"))
        .expect("the definition checks")
}

/// The page's five examples (static/js/examples.js), as definitions.
fn examples() -> Vec<(&'static str, Value)> {
    vec![
        (
            "duffing",
            json!({
            "coordinates": ["x"], "mass": 1, "potential": "alpha*x^2/2 + beta*x^4/4",
            "damping": {"gamma": "gamma"}, "parameters": {"alpha": -1, "beta": 1, "gamma": 0.05},
            "q0": [1.5], "p0": [0]}),
        ),
        (
            "henon-heiles",
            json!({
            "coordinates": ["x", "y"], "mass": 1, "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3",
            "damping": {"epsilon": "eps", "matrix": [[1, 0], [0, 1]]}, "parameters": {"eps": 0.002},
            "q0": [0, 0.1], "p0": [0.49, 0]}),
        ),
        (
            "double-pendulum",
            json!({
            "coordinates": ["a", "b"], "momenta": ["p1", "p2"],
            "hamiltonian": "(p1^2 + 2*p2^2 - 2*p1*p2*cos(a-b)) / (2*(1 + sin(a-b)^2)) - 2*g*cos(a) - g*cos(b)",
            "parameters": {"g": 9.81}, "q0": [1.8, 2.4], "p0": [0, 0]}),
        ),
        (
            "kepler",
            json!({
            "coordinates": ["x", "y"], "mass": 1, "potential": "-k/sqrt(x^2 + y^2)",
            "damping": {"epsilon": "eps", "matrix": [["x^2/(x^2 + y^2)", "x*y/(x^2 + y^2)"], ["x*y/(x^2 + y^2)", "y^2/(x^2 + y^2)"]]},
            "parameters": {"k": 1, "eps": 0.05}, "q0": [1, 0], "p0": [0, 1.2]}),
        ),
        (
            "spring-chain",
            json!({
            "coordinates": ["x1", "x2", "x3"], "mass": "m",
            "potential": "k/2*(x1^2 + (x2 - x1)^2 + (x3 - x2)^2 + x3^2)",
            "damping": {"epsilon": "c", "matrix": [[0, 0, 0], [0, 1, 0], [0, 0, 0]]},
            "parameters": {"m": 1, "k": 1, "c": 0.2}, "q0": [0.3, 0, 0], "p0": [0.1, 0, -0.2]}),
        ),
    ]
}

#[test]
fn tangent_maps_of_typed_in_systems_equal_differences_of_the_step() {
    let mut checked = 0;
    let mut failures = Vec::new();
    for (name, definition) in examples() {
        let spec = SimulationSpec::new(
            defined(definition),
            &[Method::Plain(MethodId::Rk4)],
            0.01,
            1.0,
        );
        let sim = Simulation::prepare(&spec, &Limits::default()).expect("a valid system");
        for choice in common::every_fixed_step_choice() {
            if choice.no_step_jacobian().is_some() {
                continue;
            }
            let h = 0.01;
            with_system!(&sim.system, sys => {
                let Ok(mut stepper) = methods::build(&choice, sys, name, h) else {
                    continue;
                };
                let z0 = State::from_slices(sys.dim(), &sim.q0, &sim.p0);
                let mut tangent = Tangent::new(sys, &z0);
                let mut z = z0.clone();
                stepper.step_tangent(sys, &mut z, h, &mut tangent).expect("a tangent step");
                let reference = common::step_jacobian_by_differences(sys, &choice, &z0, h);
                let diff = (&tangent.jac - &reference).amax() / reference.amax().max(1.0);
                if !(diff < 1e-7) {
                    failures.push(format!("{} on {name}: differs by {diff:e}", choice.label()));
                }
                checked += 1;
            });
        }
    }
    eprintln!("typed-in systems: {checked} tangent maps checked");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(checked > 60, "{checked}");
}

#[test]
fn conformal_methods_pair_the_exponents_of_a_typed_in_system() {
    // Hénon–Heiles typed in with conformal damping γ = 0.1 (n = 2, four exponents).
    let system = defined(json!({
        "coordinates": ["x", "y"], "mass": 1, "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3",
        "damping": {"gamma": "gamma"}, "parameters": {"gamma": 0.1},
        "q0": [0, -0.25], "p0": [0.42, 0]}));
    let chaos = ChaosSpec::new(&[Indicator::Lyapunov]);
    for id in [MethodId::Csv1, MethodId::Csv2, MethodId::Cimp] {
        let spec = SimulationSpec {
            every: Some(200),
            ..SimulationSpec::new(system.clone(), &[Method::Plain(id)], 0.05, 200.0)
        };
        let sim = Simulation::prepare(&spec, &Limits::default())
            .and_then(|s| s.with_chaos(&chaos))
            .unwrap();
        let (c, _) = common::run_to_columns(&sim, 0, None, Budget::default()).unwrap();
        let mut worst = 0.0f64;
        for spectrum in c.lyapunov.as_ref().unwrap().iter().skip(1) {
            worst = worst.max((spectrum[0] + spectrum[3] + 0.2).abs());
            worst = worst.max((spectrum[1] + spectrum[2] + 0.2).abs());
        }
        eprintln!("{id}: typed-in Hénon–Heiles pairs miss −2γ by {worst:e}");
        assert!(worst < 1e-10, "{id}: {worst:e}");
    }
}

#[test]
fn the_lorenz_system_through_its_cotangent_lift_has_its_published_largest_exponent() {
    // y' = f(y) enters as H = p·f(y); with p = 0 the positions' deviations follow f's own
    // variational equation, and the first deviation vector (every coordinate alike, no momentum)
    // stays there. Sprott, "Chaos and Time-Series Analysis" (Oxford University Press, 2003),
    // Appendix A, gives the Lorenz system (σ = 10, r = 28, b = 8/3) the exponents
    // (0.9056, 0, −14.5723).
    let system = defined(json!({
        "coordinates": ["x", "y", "z"], "momenta": ["px", "py", "pz"],
        "hamiltonian": "px*s*(y - x) + py*(x*(r - z) - y) + pz*(x*y - b*z)",
        "parameters": {"s": 10, "r": 28, "b": 2.6666666666666665},
        "q0": [-8.0, -8.0, 27.0], "p0": [0, 0, 0]}));
    let chaos = ChaosSpec {
        deviations: Some(1),
        ..ChaosSpec::new(&[Indicator::Lyapunov])
    };
    let spec = SimulationSpec {
        every: Some(1_000_000),
        ..SimulationSpec::new(system, &[Method::Plain(MethodId::Rk4)], 0.01, 1e5)
    };
    let sim = Simulation::prepare(&spec, &Limits::default())
        .and_then(|s| s.with_chaos(&chaos))
        .unwrap();
    let (c, _) = common::run_to_columns(&sim, 0, None, Budget::default()).unwrap();
    let lambda = c.lyapunov.as_ref().unwrap().last().unwrap()[0];
    // Measured 0.905657 at T = 10⁵ (0.905484 at T = 10⁴): the finite-time estimate itself
    // fluctuates by about 10⁻⁴ at this length, so the published value's last digit is matched
    // within one unit.
    eprintln!("Lorenz λ₁ at T = 10⁵: {lambda}");
    assert!((lambda - 0.9056).abs() < 1e-4, "{lambda}");
}

#[test]
fn requests_name_the_fields_of_indicators_they_cannot_serve() {
    let field = |body: Value| {
        SimulateRequest::from_value(&body)
            .and_then(|r| r.prepare(&Limits::default(), &NoStoredSystems).map(|_| ()))
            .unwrap_err()
            .field
    };
    let base = json!({"system": "henon_heiles", "methods": ["velocity_verlet", "rk4"], "h": 0.05, "t_end": 1});
    let with = |extra: Value| {
        let mut body = base.clone();
        body.as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        body
    };
    for (extra, expected) in [
        (
            json!({"indicators": ["megno", "lyapunovv"]}),
            "indicators[1]",
        ),
        (
            json!({"indicators": ["megno"], "deviations": 5}),
            "deviations",
        ),
        (
            json!({"indicators": ["sali"], "deviations": 1}),
            "deviations",
        ),
        (
            json!({"indicators": ["megno"], "stop_when": {"fli": 3}}),
            "stop_when.fli",
        ),
        (
            json!({"indicators": ["megno"], "stop_when": {"megno_max": 3}}),
            "stop_when.megno_max",
        ),
        (json!({"deviations": 2}), "deviations"),
        // One `stop_when` for events and thresholds: a threshold needs its indicator, an
        // event's direction and count need its surface, and an empty object says what it lacks.
        (
            json!({"stop_when": {"megno_mean": 8}}),
            "stop_when.megno_mean",
        ),
        (json!({"stop_when": {"count": 2}}), "stop_when.where"),
        (json!({"stop_when": {}}), "stop_when.where"),
        (json!({"indicators": ["megno"], "qr_every": 0}), "qr_every"),
        (
            json!({"indicators": ["megno"], "methods": ["rk4", "reference"]}),
            "methods[1]",
        ),
        (
            json!({"indicators": ["megno"], "methods": ["rowlands"]}),
            "methods[0]",
        ),
    ] {
        assert_eq!(
            field(with(extra.clone())).as_deref(),
            Some(expected),
            "{extra}"
        );
    }
    // A request reads back what it was given.
    let req = SimulateRequest::from_value(&with(
        json!({"indicators": ["megno", "lyapunov"], "deviations": 2,
        "qr_every": 5, "stop_when": {"megno_mean": 8}}),
    ))
    .unwrap();
    assert_eq!(
        req.stop_when,
        Some(StopWhenRequest {
            megno_mean: Some(8.0),
            ..Default::default()
        })
    );
    let again = SimulateRequest::from_value(&serde_json::to_value(&req).unwrap()).unwrap();
    assert_eq!(again, req);
}

#[tokio::test]
async fn simulate_answers_carry_the_indicators_in_json_and_ndjson() {
    use crate::server::{post_json, post_ndjson, start};
    let server = start(config()).await;
    let body = json!({
        "system": "henon_heiles", "params": {"lambda": 1}, "q0": [0, -0.25], "p0": [0.5103, 0],
        "methods": [{"id": "triple_jump", "base": "velocity_verlet"}, "csv1"], "h": 0.05, "t_end": 400,
        "output": {"every": 100}, "indicators": ["megno", "lyapunov", "sali", "gali"],
        "stop_when": {"megno_mean": 4}, "compare_to_reference": true});
    let (status, doc) = post_json(&server, "/api/v1/simulate", &body).await;
    assert_eq!(status, 200);
    // The reference run (for the energy errors) tracks nothing and stops at the end.
    for run in doc["runs"].as_array().unwrap() {
        let n = run["t"].as_array().unwrap().len();
        assert_eq!(run["energy_error"].as_array().unwrap().len(), n);
        for name in ["megno", "megno_mean", "sali", "gali", "lyapunov"] {
            assert_eq!(run[name].as_array().unwrap().len(), n, "{name}");
        }
        assert_eq!(run["lyapunov"][0].as_array().unwrap().len(), 4);
        assert!(run.get("fli").is_none());
        // The summary has the last sample's values under the same names.
        assert_eq!(run["indicators"]["megno_mean"], run["megno_mean"][n - 1]);
        assert_eq!(run["indicators"]["lyapunov"], run["lyapunov"][n - 1]);
    }
    // The chaotic orbit (H ≈ 1/6) passes ⟨Y⟩ = 4 before t = 400: its runs stop there, said so.
    let stop = &doc["runs"][0]["stop"];
    assert_eq!(stop["reason"], "indicator");
    assert_eq!(stop["indicator"], "megno_mean");
    assert!(stop["value"].as_f64().unwrap() >= 4.0);
    // The stream: the header names the indicators, the summaries hold them.
    let (status, _, lines) =
        post_ndjson(&server, "/api/v1/simulate", "application/x-ndjson", &body).await;
    assert_eq!(status, 200);
    assert_eq!(
        lines[0]["indicators"],
        json!(["lyapunov", "megno", "sali", "gali"])
    );
    assert_eq!(lines[0]["deviations"], 4);
    let summaries: Vec<&Value> = lines.iter().filter(|l| l["type"] == "summary").collect();
    assert_eq!(summaries.len(), 2);
    for s in summaries {
        let run = &doc["runs"][s["method"].as_u64().unwrap() as usize];
        assert_eq!(s["indicators"], run["indicators"]);
    }
    // Without indicators, none of these fields.
    let plain = json!({"system": "henon_heiles", "methods": ["csv1"], "h": 0.05, "t_end": 1});
    let (_, doc) = post_json(&server, "/api/v1/simulate", &plain).await;
    for name in ["megno", "lyapunov", "indicators"] {
        assert!(doc["runs"][0].get(name).is_none(), "{name}");
    }
    // A refusal is a 422 naming the field.
    let mut bad = body.clone();
    bad["deviations"] = json!(9);
    let (status, error) = post_json(&server, "/api/v1/simulate", &bad).await;
    assert_eq!(
        (status, error["error"]["field"].as_str()),
        (422, Some("deviations"))
    );
}

#[tokio::test]
async fn the_chaos_presets_run_and_mark_the_cells_off_the_energy_surface() {
    use crate::server::{get_json, post_json, start};
    let server = start(config()).await;
    let presets = get_json(&server, "/api/v1/studies/sweep/presets").await;
    let preset = |id: &str| {
        presets
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["id"] == id)
            .unwrap()["request"]
            .clone()
    };
    // The Hénon–Heiles map, coarser and shorter.
    let mut hh = preset("henon_heiles_megno");
    hh["axes"][0]["n"] = json!(9);
    hh["axes"][1]["n"] = json!(9);
    hh["t_end"] = json!(100);
    hh["every"] = json!(2000);
    let (status, doc) = post_json(&server, "/api/v1/studies/sweep", &hh).await;
    assert_eq!(status, 200, "{doc}");
    let run = &doc["runs"][0];
    let megno = run["megno_mean"].as_array().unwrap();
    assert_eq!(megno.len(), 81);
    for (cell, m) in megno.iter().enumerate() {
        let off = run["errors"][cell]
            .as_str()
            .is_some_and(|e| e.contains("energy_surface.energy"));
        assert_eq!(m.is_null(), off, "cell {cell}");
    }
    assert!(megno.iter().any(Value::is_null) && megno.iter().any(Value::is_number));
    // The elastic pendulum in both charts.
    let mut elastic = preset("elastic_pendulum_chaos");
    elastic["axes"][0]["n"] = json!(3);
    elastic["axes"][1]["n"] = json!(3);
    elastic["t_end"] = json!(5);
    elastic["every"] = json!(500);
    let (status, doc) = post_json(&server, "/api/v1/studies/sweep", &elastic).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(doc["runs"].as_array().unwrap().len(), 2);
    assert!(doc["runs"][1]["megno_mean"]
        .as_array()
        .unwrap()
        .iter()
        .any(Value::is_number));
    // A surface no cell reaches.
    hh["energy_surface"]["energy"] = json!(-1);
    let (status, error) = post_json(&server, "/api/v1/studies/sweep", &hh).await;
    assert_eq!(
        (status, error["error"]["field"].as_str()),
        (422, Some("energy_surface.energy"))
    );
}

/// One `stop_when` holds an event and thresholds together, and whichever comes first ends the
/// run: on the chaotic orbit ⟨Y⟩ passes 4 long before the 1000th upward crossing of y = 0, and
/// the second crossing comes before ⟨Y⟩ reaches 4; the threshold's stop is the one a run with
/// the threshold alone makes, step for step.
#[tokio::test]
async fn an_event_and_a_threshold_in_one_stop_when_end_a_run_at_whichever_comes_first() {
    use crate::server::{post_json, start};
    let server = start(config()).await;
    let run = |stop_when: Value| {
        json!({"system": "henon_heiles", "params": {"lambda": 1}, "q0": [0, -0.25], "p0": [0.5103, 0],
            "method": "velocity_verlet", "h": 0.05, "t_end": 2000, "output": {"every": 100},
            "indicators": ["megno"], "stop_when": stop_when})
    };
    let stop_of = |doc: &Value| doc["runs"][0]["stop"].clone();
    let (status, alone) =
        post_json(&server, "/api/v1/simulate", &run(json!({"megno_mean": 4}))).await;
    assert_eq!(status, 200, "{alone}");
    let threshold = stop_of(&alone);
    assert_eq!(threshold["reason"], "indicator", "{threshold}");
    let both = json!({"where": "y", "direction": "up", "count": 1000, "megno_mean": 4});
    let (status, doc) = post_json(&server, "/api/v1/simulate", &run(both)).await;
    assert_eq!(status, 200, "{doc}");
    assert_eq!(stop_of(&doc), threshold);
    let early = json!({"where": "y", "direction": "up", "count": 2, "megno_mean": 4});
    let (status, doc) = post_json(&server, "/api/v1/simulate", &run(early)).await;
    assert_eq!(status, 200, "{doc}");
    let event = stop_of(&doc);
    assert_eq!(event["reason"], "event", "{event}");
    assert!(
        event["t"].as_f64().unwrap() < threshold["t"].as_f64().unwrap(),
        "{event} {threshold}"
    );
    assert_eq!(
        doc["runs"][0]["events"]["t"].as_array().map(Vec::len),
        Some(2),
        "{doc}"
    );
}

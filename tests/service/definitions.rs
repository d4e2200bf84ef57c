//! User-defined systems against the built-in ones they restate: each built-in system that the
//! definition language can write (the oscillator, the pendulum, the elastic 3-D pendulum, the
//! planar elastic pendulum in Cartesian coordinates and in polar ones as a general H(q, p), three
//! bodies) runs every method that applies to the built-in one, and the runs agree to 1e-12
//! relative over 10⁴ steps; the same methods are refused on both. Then the structure a user's
//! system keeps: Hénon–Heiles' bounded energy error, csv1's conformal Jacobian, a conserved
//! user invariant, and a general H(q, p) on which only the methods for it run.

use crate::common;

use common::{every_fixed_step_choice, method, params, run_to_columns};
use geomint::api::system::SystemDefinition;
use geomint::core::error::{CoreError, Field};
use geomint::core::run::Budget;
use geomint::core::simulation::{Columns, EnergyReference, Limits, Simulation, SimulationSpec};
use geomint::core::systems::{HarmonicOscillator, SystemRef};
use serde_json::{json, Value};

/// The system of a definition written as JSON.
pub(crate) fn defined(definition: Value) -> SystemRef {
    SystemDefinition::read(&definition, &Field::new("system"))
        .expect("the definition reads")
        .define(&Field::new("system"))
        .expect("the definition checks")
}

/// A built-in system and its restatement as a definition, run from the same state.
struct Twin {
    name: &'static str,
    built_in: &'static str,
    params: Value,
    chart: Option<&'static str>,
    definition: Value,
    h: f64,
    /// For a system whose round-off errors grow too fast for 1e-12 in q and p over 10⁴ steps
    /// (three bodies: the figure eight's period depends on its energy, so a change in the last
    /// bit becomes a phase error that grows with time), a map of the positions that moves the
    /// motion along unchanged but rounds the built-in arithmetic differently; the tolerance in q
    /// and p is then ten times the difference it makes to the built-in run itself. The energy
    /// must agree to 1e-12 regardless. The map and its inverse.
    relabel: Option<(Relabel, Relabel)>,
}

fn twins() -> Vec<Twin> {
    vec![
        Twin {
            name: "oscillator",
            built_in: "harmonic_oscillator",
            params: json!({"omega": 1.3, "gamma": 0.05}),
            chart: None,
            definition: json!({
                "coordinates": ["q"], "momenta": ["p"],
                "potential": "omega^2*q^2/2",
                "damping": {"gamma": "gamma"},
                "parameters": {"omega": 1.3, "gamma": 0.05},
            }),
            h: 0.01,
            relabel: None,
        },
        Twin {
            name: "pendulum",
            built_in: "pendulum",
            params: json!({"gamma": 0.005}),
            chart: None,
            definition: json!({
                "coordinates": ["q"], "momenta": ["p"],
                "potential": "1 - cos(q)",
                "damping": {"gamma": "gamma"},
                "parameters": {"gamma": 0.005},
            }),
            h: 0.01,
            relabel: None,
        },
        Twin {
            name: "elastic 3-D pendulum",
            built_in: "elastic_pendulum_3d",
            params: json!({"epsilon": 0.1, "m": 1.5, "k": 2, "l": 1, "g": 1}),
            chart: None,
            definition: json!({
                "coordinates": ["x", "y", "z"], "momenta": ["px", "py", "pz"],
                "mass": "m",
                "potential": "k/2*(sqrt(x^2 + y^2 + z^2) - l)^2 + m*g*z",
                "damping": {"epsilon": "epsilon", "matrix": [
                    ["x^2/(x^2+y^2+z^2)", "x*y/(x^2+y^2+z^2)", "x*z/(x^2+y^2+z^2)"],
                    ["x*y/(x^2+y^2+z^2)", "y^2/(x^2+y^2+z^2)", "y*z/(x^2+y^2+z^2)"],
                    ["x*z/(x^2+y^2+z^2)", "y*z/(x^2+y^2+z^2)", "z^2/(x^2+y^2+z^2)"]]},
                "parameters": {"epsilon": 0.1, "m": 1.5, "k": 2, "l": 1, "g": 1},
                "invariants": {"J3": "x*py - y*px"},
            }),
            h: 0.01,
            relabel: None,
        },
        Twin {
            name: "planar elastic pendulum, Cartesian",
            built_in: "elastic_pendulum_2d",
            params: json!({"m": 1, "k": 1, "l": 1, "g": 0.2}),
            chart: Some("cartesian"),
            definition: json!({
                "coordinates": ["x", "y"], "momenta": ["px", "py"],
                "mass": "m",
                "potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*y",
                "parameters": {"m": 1, "k": 1, "l": 1, "g": 0.2},
            }),
            h: 0.01,
            relabel: None,
        },
        Twin {
            name: "planar elastic pendulum, polar, as a general H",
            built_in: "elastic_pendulum_2d",
            params: json!({"m": 1, "k": 1, "l": 1, "g": 0.2}),
            chart: Some("polar"),
            definition: json!({
                "coordinates": ["r", "theta"], "momenta": ["pr", "ptheta"],
                "hamiltonian": "(pr^2 + ptheta^2/r^2)/(2*m) + k/2*(r - l)^2 - m*g*r*cos(theta)",
                "parameters": {"m": 1, "k": 1, "l": 1, "g": 0.2},
            }),
            h: 0.01,
            relabel: None,
        },
        // Undamped: with damping the figure eight leaves its choreography for chaotic motion, in
        // which no two orders of the same arithmetic agree at t = 100 (with γ = 0.01 the
        // definition's modin_3s run differs from the built-in one by 2e-14 relative after 10³
        // steps, 2e-13 after 3·10³ and 1e-9 after 10⁴); the conformal methods run all the same.
        Twin {
            name: "three bodies",
            built_in: "nbody",
            params: json!({"gamma": 0.0}),
            chart: None,
            definition: json!({
                "coordinates": ["x1", "y1", "z1", "x2", "y2", "z2", "x3", "y3", "z3"],
                "mass": 1,
                "potential": "-G/sqrt((x1-x2)^2 + (y1-y2)^2 + (z1-z2)^2) \
                              - G/sqrt((x1-x3)^2 + (y1-y3)^2 + (z1-z3)^2) \
                              - G/sqrt((x2-x3)^2 + (y2-y3)^2 + (z2-z3)^2)",
                "damping": {"gamma": "gamma"},
                "parameters": {"G": 1, "gamma": 0.0},
            }),
            h: 0.01,
            relabel: Some((shift_x, unshift_x)),
        },
    ]
}

const STEPS: u64 = 10_000;

/// A map of positions.
type Relabel = fn(&[f64]) -> Vec<f64>;

/// The state moved by 3/8 along x (exact in binary, but every position rounds differently),
/// and back. The figure eight's total momentum is zero, so the motion moves with it.
fn shift_x(x: &[f64]) -> Vec<f64> {
    shifted(x, 0.375)
}
fn unshift_x(x: &[f64]) -> Vec<f64> {
    shifted(x, -0.375)
}
fn shifted(x: &[f64], by: f64) -> Vec<f64> {
    x.iter()
        .enumerate()
        .map(|(i, v)| if i % 3 == 0 { v + by } else { *v })
        .collect()
}

/// How much moving the positions changes the built-in run `plain` of `spec` (moved back):
/// the size of the run's own round-off, relative, in q, p and H.
fn round_off_sensitivity(
    spec: &SimulationSpec,
    (relabel, back): (Relabel, Relabel),
    plain: &Columns,
) -> f64 {
    let relabelled = SimulationSpec {
        q0: spec.q0.as_deref().map(relabel),
        ..spec.clone()
    };
    let c = run(&relabelled).expect("the relabelled run");
    let back = |xs: &[Vec<f64>]| -> Vec<Vec<f64>> { xs.iter().map(|x| back(x)).collect() };
    let dq = relative_difference(&plain.q, &back(&c.q));
    let dp = relative_difference(&plain.p, &c.p);
    let de = relative_difference(&[plain.energy.clone()], &[c.energy.clone()]);
    // A relabelling that changes nothing in the arithmetic would make a zero tolerance: at
    // least the 1e-12 of the other systems.
    dq.max(dp).max(de).max(1e-12)
}

/// One method's run of a prepared spec, or the refusal.
pub(crate) fn run(spec: &SimulationSpec) -> Result<Columns, CoreError> {
    let sim = Simulation::prepare(spec, &Limits::default())?;
    Ok(run_to_columns(&sim, 0, None, Budget::default())?.0)
}

/// The largest difference between two sample lists, relative to the largest value.
fn relative_difference(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    let scale = a
        .iter()
        .flatten()
        .fold(0.0_f64, |m, x| m.max(x.abs()))
        .max(f64::MIN_POSITIVE);
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0_f64, f64::max)
        / scale
}

#[test]
fn built_in_systems_written_as_definitions_reproduce_their_runs() {
    let mut compared = 0;
    for twin in twins() {
        let custom = defined(twin.definition.clone());
        let t_end = twin.h * STEPS as f64;
        // The built-in run's first sample is its initial state in the chart's coordinates.
        let start = {
            let mut spec = SimulationSpec::new(twin.built_in, &[method("rk4")], twin.h, twin.h);
            spec.params = params(twin.params.clone());
            spec.chart = twin.chart.map(str::to_string);
            let columns = run(&spec).expect("the built-in system runs");
            (columns.q[0].clone(), columns.p[0].clone())
        };
        for choice in every_fixed_step_choice() {
            let spec_of = |system: SystemRef, chart: Option<&str>, params: Value| SimulationSpec {
                params: common::params(params),
                chart: chart.map(str::to_string),
                q0: Some(start.0.clone()),
                p0: Some(start.1.clone()),
                every: Some(100),
                ..SimulationSpec::new(system, &[choice], twin.h, t_end)
            };
            let built_in = run(&spec_of(
                SystemRef::from(twin.built_in),
                twin.chart,
                twin.params.clone(),
            ));
            let theirs = run(&spec_of(custom.clone(), None, json!({})));
            let label = format!("{} with {}", twin.name, choice.label());
            match (built_in, theirs) {
                (Ok(a), Ok(b)) => {
                    let dq = relative_difference(&a.q, &b.q);
                    let dp = relative_difference(&a.p, &b.p);
                    let de = relative_difference(&[a.energy.clone()], &[b.energy.clone()]);
                    let tolerance = match twin.relabel {
                        None => 1e-12,
                        Some(relabel) => {
                            10.0 * round_off_sensitivity(
                                &spec_of(
                                    SystemRef::from(twin.built_in),
                                    twin.chart,
                                    twin.params.clone(),
                                ),
                                relabel,
                                &a,
                            )
                        }
                    };
                    assert!(
                        dq < tolerance && dp < tolerance && de < 1e-12,
                        "{label}: relative differences q {dq:.1e}, p {dp:.1e}, H {de:.1e} \
                         (tolerance {tolerance:.1e})"
                    );
                    assert_eq!(a.t.len(), b.t.len(), "{label}");
                    compared += 1;
                }
                (Err(a), Err(b)) => {
                    assert_eq!(
                        geomint::core::error::ErrorDetail::from(a).code,
                        geomint::core::error::ErrorDetail::from(b).code,
                        "{label}: refused for different reasons"
                    );
                }
                (a, b) => panic!(
                    "{label}: the built-in {} but the definition {}",
                    if a.is_ok() { "runs" } else { "is refused" },
                    if b.is_ok() { "runs" } else { "is refused" },
                ),
            }
        }
    }
    // Six systems, each with at least the Runge–Kutta methods and symplectic Euler.
    assert!(compared >= 6 * 5, "only {compared} runs compared");
}

#[test]
fn the_oscillator_as_a_definition_meets_the_exact_solution_at_second_order() {
    let custom = defined(twins().remove(0).definition);
    let exact = HarmonicOscillator {
        omega: 1.3,
        gamma: 0.05,
    };
    let (q0, p0) = (1.0, 0.0);
    let t_end = 10.0;
    let (qe, pe) = exact.solution(t_end, q0, p0);
    let errors: Vec<f64> = [0.02, 0.01, 0.005]
        .iter()
        .map(|&h| {
            let spec = SimulationSpec {
                q0: Some(vec![q0]),
                p0: Some(vec![p0]),
                ..SimulationSpec::new(custom.clone(), &[method("csv2")], h, t_end)
            };
            let c = run(&spec).expect("csv2 runs");
            let (q, p) = (c.q.last().unwrap()[0], c.p.last().unwrap()[0]);
            ((q - qe).powi(2) + (p - pe).powi(2)).sqrt()
        })
        .collect();
    for pair in errors.windows(2) {
        let order = (pair[0] / pair[1]).log2();
        assert!(
            (order - 2.0).abs() < 0.05,
            "order {order:.3} from {errors:?}"
        );
    }
    assert!(errors[2] < 1e-4, "{errors:?}");
}

/// The largest |H − H₀| over the first half of the samples and over the second.
pub(crate) fn energy_error_by_halves(energy: &[f64]) -> (f64, f64) {
    let errors: Vec<f64> = energy.iter().map(|e| (e - energy[0]).abs()).collect();
    let half = errors.len() / 2;
    let largest = |part: &[f64]| part.iter().cloned().fold(0.0, f64::max);
    (largest(&errors[..half]), largest(&errors[half..]))
}

/// Hénon–Heiles, V = (x² + y²)/2 + x²y − y³/3, at energy 1/8 (a bounded orbit).
fn henon_heiles(damping: Option<Value>) -> SystemRef {
    let mut definition = json!({
        "coordinates": ["x", "y"], "momenta": ["px", "py"],
        "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3",
        "q0": [0.0, 0.1], "p0": [0.48, 0.0],
    });
    if let Some(d) = damping {
        definition["damping"] = d;
        definition["parameters"] = json!({"gamma": 0.05});
    }
    defined(definition)
}

/// An undamped system without an exact solution measures its energy error against H₀, which
/// its exact flow keeps; a damped one has no reference unless the reference run is asked for.
#[test]
fn an_undamped_definition_measures_its_energy_error_against_the_initial_energy() {
    let document = |system: SystemRef| {
        let spec = SimulationSpec {
            every: Some(100),
            ..SimulationSpec::new(system, &[method("modin_3s")], 0.05, 50.0)
        };
        let sim = Simulation::prepare(&spec, &Limits::default()).expect("valid");
        let reference = sim.energy_reference();
        (reference, sim.simulate(1, Budget::default()).expect("runs"))
    };
    let (reference, doc) = document(henon_heiles(None));
    assert_eq!(reference, Some(EnergyReference::Initial));
    assert_eq!(doc.energy_reference, Some(EnergyReference::Initial));
    let c = &doc.runs[0].columns;
    let errors = c.energy_error.as_ref().expect("an energy error against H0");
    assert_eq!(errors.len(), c.energy.len());
    assert_eq!(errors[0], 0.0);
    for (e, h) in errors.iter().zip(&c.energy) {
        assert_eq!(*e, h - c.energy[0], "H - H0 exactly");
    }
    // Second order at h = 0.05 on a bounded orbit: small, and not zero.
    let largest = errors.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    assert!(largest > 1e-12 && largest < 1e-3, "{largest:e}");

    let (reference, doc) = document(henon_heiles(Some(json!({"gamma": "gamma"}))));
    assert_eq!(reference, None);
    assert!(doc.runs[0].columns.energy_error.is_none());
}

#[test]
fn henon_heiles_keeps_its_energy_error_bounded_under_modin_3s_while_rk4_drifts() {
    let system = henon_heiles(None);
    let (h, steps) = (0.1, 1_000_000u64);
    let energy_error = |id: &str| -> (f64, f64) {
        let spec = SimulationSpec {
            every: Some(10_000),
            ..SimulationSpec::new(system.clone(), &[method(id)], h, h * steps as f64)
        };
        let c = run(&spec).expect("runs");
        energy_error_by_halves(&c.energy)
    };
    let (first, second) = energy_error("modin_3s");
    // A band: the error of the second half of the run is no larger than that of the first
    // (beyond sampling noise) and small.
    assert!(
        second < 1e-3 && second < 1.5 * first,
        "modin_3s: {first:.2e}, {second:.2e}"
    );
    let (rk_first, rk_second) = energy_error("rk4");
    // rk4's error grows linearly in time: the second half's is about twice the first's.
    assert!(
        rk_second > 1.8 * rk_first,
        "rk4: {rk_first:.2e}, {rk_second:.2e}"
    );
    assert!(
        rk_second > 10.0 * second,
        "rk4 {rk_second:.2e} against modin_3s {second:.2e}"
    );
}

#[test]
fn csv1_on_a_conformally_damped_definition_contracts_volume_by_exp_minus_2_gamma_h() {
    let system = henon_heiles(Some(json!({"gamma": "gamma"})));
    let spec = SimulationSpec {
        jacobian_defect: true,
        ..SimulationSpec::new(system, &[method("csv1")], 0.05, 20.0)
    };
    let c = run(&spec).expect("csv1 runs");
    let defects = c.jacobian_defect.expect("the Jacobian defect is reported");
    assert!(defects.len() > 300);
    let worst = defects.iter().cloned().fold(0.0, f64::max);
    assert!(worst < 1e-12, "|det − e^(−2γh)| up to {worst:.2e}");
}

#[test]
fn a_user_invariant_the_system_conserves_stays_at_round_off() {
    // A central potential with damping along the radius keeps L = x p_y − y p_x.
    let system = defined(json!({
        "coordinates": ["x", "y"], "momenta": ["px", "py"],
        "potential": "-1/sqrt(x^2 + y^2) + (x^2 + y^2)/20",
        "damping": {"epsilon": 0.2, "matrix": [
            ["x^2/(x^2+y^2)", "x*y/(x^2+y^2)"],
            ["x*y/(x^2+y^2)", "y^2/(x^2+y^2)"]]},
        "invariants": {"L": "x*py - y*px"},
        "q0": [1.0, 0.0], "p0": [0.1, 0.9],
    }));
    let spec = SimulationSpec {
        every: Some(100),
        ..SimulationSpec::new(system, &[method("modin_3s")], 0.01, 100.0)
    };
    let c = run(&spec).expect("modin_3s runs");
    let l = &c.invariants["L"];
    let drift = l.iter().map(|x| (x - l[0]).abs()).fold(0.0, f64::max);
    assert!(drift < 1e-13, "L drifts by {drift:.2e}");
    // The energy does fall: the damping acts.
    assert!(c.energy.last().unwrap() < &(c.energy[0] - 1e-3));
}

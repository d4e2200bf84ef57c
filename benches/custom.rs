//! User-defined systems against the built-in ones they restate: ns per step of modin_3s and rk4
//! on P1 (the damped pendulum) and P2 (the elastic 3-D pendulum) of `steps`, each written as a
//! definition, measured with the same loop and interleaved with the built-in run; then the time
//! to read, check and differentiate a definition, and to compile it.

use std::time::Instant;

use geomint::api::system::SystemDefinition;
use geomint::core::error::Field;
use geomint::core::methods::runge_kutta::RK4;
use geomint::core::methods::splitting::compiled::{StretchPlan, COMPILE_AFTER};
use geomint::core::methods::splitting::MODIN_3S;
use geomint::core::methods::{Method, MethodId};
use geomint::core::system::MechanicalSystem;
use geomint::core::system::State;
use geomint::core::systems::{params, AnySystem, ElasticPendulum3d, Pendulum, SystemInfo};
use serde_json::{json, Value};
use std::sync::Arc;

mod common;
use common::measure;

fn p1_definition() -> Value {
    json!({
        "coordinates": ["q"], "momenta": ["p"],
        "potential": "1 - cos(q)",
        "damping": {"gamma": "gamma"},
        "parameters": {"gamma": 0.005},
    })
}

fn p2_definition() -> Value {
    json!({
        "coordinates": ["x", "y", "z"], "momenta": ["px", "py", "pz"],
        "mass": "m",
        "potential": "k/2*(sqrt(x^2 + y^2 + z^2) - l)^2 + m*g*z",
        "damping": {"epsilon": "epsilon", "matrix": [
            ["x^2/(x^2+y^2+z^2)", "x*y/(x^2+y^2+z^2)", "x*z/(x^2+y^2+z^2)"],
            ["x*y/(x^2+y^2+z^2)", "y^2/(x^2+y^2+z^2)", "y*z/(x^2+y^2+z^2)"],
            ["x*z/(x^2+y^2+z^2)", "y*z/(x^2+y^2+z^2)", "z^2/(x^2+y^2+z^2)"]]},
        "parameters": {"m": 1, "k": 1, "l": 1, "g": 1, "epsilon": 0.1},
    })
}

/// Reads and checks a definition (parse, names, shapes, symbolic derivatives, the checks at
/// sample points).
fn check(definition: &Value) -> Arc<SystemInfo> {
    SystemDefinition::read(definition, &Field::new("system"))
        .expect("reads")
        .check(&Field::new("system"))
        .expect("checks")
}

/// Compiles a checked definition with its default parameters.
fn compile(info: &SystemInfo) -> AnySystem {
    let values = params::resolve(info, &Default::default(), &Field::new("params")).expect("params");
    info.build(&values, &info.charts[0], common::H)
        .expect("builds")
}

/// Median milliseconds of `work` over 21 runs after one warm-up.
fn median_ms(mut work: impl FnMut()) -> f64 {
    work();
    let mut times: Vec<f64> = (0..21)
        .map(|_| {
            let began = Instant::now();
            work();
            began.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[10]
}

fn main() {
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let wanted = |name: &str| filter.is_empty() || filter.iter().any(|f| name.contains(f.as_str()));
    let choices = [Method::new(MethodId::Modin3s), Method::new(MethodId::Rk4)];

    println!("| problem | method | built-in ns/step | definition ns/step | ratio |");
    println!("|---|---|---|---|---|");
    let p1 = Pendulum { gamma: 0.005 };
    let p1_custom = compile(&check(&p1_definition()));
    let p1_start = State::from_slices(nalgebra::U1, &[0.9 * std::f64::consts::PI], &[0.0]);
    for c in &choices {
        if !wanted(&format!("P1 {}", c.label())) {
            continue;
        }
        let (built_in, sum) = measure(&p1, c, &p1_start);
        let AnySystem::Custom1(custom) = &p1_custom else {
            panic!("P1 compiles to a one-degree-of-freedom system")
        };
        let (defined, custom_sum) = measure(custom, c, &p1_start);
        assert!(
            (sum - custom_sum).abs() <= 1e-9 * sum.abs(),
            "{sum} against {custom_sum}"
        );
        println!(
            "| P1 pendulum | {} | {built_in:.1} | {defined:.1} | {:.2} |",
            c.label(),
            defined / built_in
        );
    }
    let p2 = ElasticPendulum3d {
        m: 1.0,
        k: 1.0,
        l: 1.0,
        g: 1.0,
        epsilon: 0.1,
    };
    let p2_custom = compile(&check(&p2_definition()));
    let p2_start = State::from_slices(
        nalgebra::U3,
        &[0.0, 1.558_845_73, -0.6],
        &[1.341_640_79, 0.0, 0.0],
    );
    for c in &choices {
        if !wanted(&format!("P2 {}", c.label())) {
            continue;
        }
        let (built_in, sum) = measure(&p2, c, &p2_start);
        let AnySystem::Custom3(custom) = &p2_custom else {
            panic!("P2 compiles to a three-degree-of-freedom system")
        };
        let (defined, custom_sum) = measure(custom, c, &p2_start);
        assert!(
            (sum - custom_sum).abs() <= 1e-6 * sum.abs(),
            "{sum} against {custom_sum}"
        );
        println!(
            "| P2 elastic pendulum | {} | {built_in:.1} | {defined:.1} | {:.2} |",
            c.label(),
            defined / built_in
        );
    }

    if wanted("define") {
        println!(
            "\n| definition | read, check, differentiate (ms) | compile (ms) | compile a modin_3s \
             stretch and rk4 steps (ms) |"
        );
        println!("|---|---|---|---|");
        for (name, definition) in [("P1", p1_definition()), ("P2", p2_definition())] {
            let checking = median_ms(|| {
                std::hint::black_box(check(&definition));
            });
            // A fresh model each time: a model keeps its last compilation, which a second
            // compile of the same one would only look up.
            let both = median_ms(|| {
                std::hint::black_box(compile(&check(&definition)));
            });
            let compiling = both - checking;
            let all = median_ms(|| {
                let sys = compile(&check(&definition));
                assert_eq!(compiled_steps(&sys), 2, "both compiled");
            });
            let steps = all - both;
            println!("| {name} | {checking:.2} | {compiling:.2} | {steps:.2} |");
        }
    }
}

/// Compiles a modin_3s stretch and rk4 steps for the typed-in system `sys`, as its first long
/// runs would, and says how many it compiled.
fn compiled_steps(sys: &AnySystem) -> usize {
    let plan = StretchPlan {
        flows: MODIN_3S,
        coefficients: &[(1e-3, 0.0); 5],
        h: common::H,
        seam: Some((common::H, (1e-3, 0.0))),
    };
    geomint::core::with_system!(sys, s => {
        s.compiled_forces().map_or(0, |forces| {
            usize::from(forces.stretch(&plan, COMPILE_AFTER).is_some())
                + usize::from(forces.steps(&RK4, common::H, COMPILE_AFTER).is_some())
        })
    })
}

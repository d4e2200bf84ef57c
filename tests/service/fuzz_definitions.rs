//! Random and mutated system definitions through the whole path a request takes (read, check,
//! compile, run a few steps): never a panic, and every refusal a client error (4xx), never a
//! server error. CI runs a bounded number of cases (proptest's default, 256 per property); the
//! long run sets `PROPTEST_CASES` (see the README).

use std::panic::{catch_unwind, AssertUnwindSafe};

use geomint::api::system::NoStoredSystems;
use geomint::api::SimulateRequest;
use geomint::core::run::Budget;
use geomint::core::simulation::Limits;
use geomint::http::error::status_for;
use proptest::prelude::*;
use serde_json::{json, Value};

/// Definitions that check, to mutate.
fn seeds() -> Vec<Value> {
    vec![
        json!({
            "coordinates": ["x", "y"], "momenta": ["px", "py"], "mass": 1,
            "potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*y",
            "damping": {"epsilon": 0.1, "matrix": [
                ["x^2/(x^2+y^2)", "x*y/(x^2+y^2)"], ["x*y/(x^2+y^2)", "y^2/(x^2+y^2)"]]},
            "parameters": {"k": 1, "l": 1, "m": 1, "g": 0.2},
            "invariants": {"L": "x*py - y*px"}, "positions": [["x", "-y"]],
            "q0": [1.2, 0.3], "p0": [0, 0]
        }),
        json!({
            "coordinates": ["a", "b"],
            "hamiltonian": "(p_a^2 + 2*p_b^2 - 2*p_a*p_b*cos(a - b)) / (2*(1 + sin(a - b)^2)) - 2*g*cos(a) - g*cos(b)",
            "parameters": {"g": 9.81},
            "positions": [["sin(a)", "-cos(a)"], ["sin(a) + sin(b)", "-cos(a) - cos(b)"]],
            "q0": [1, 0.5]
        }),
        json!({
            "coordinates": ["u1", "u2", "u3"], "mass": [1, "m2", 1],
            "potential": "k/2*(u1^2 + (u2 - u1)^2 + (u3 - u2)^2 + u3^2)",
            "damping": {"gamma": "gamma"},
            "parameters": {"k": 1, "m2": 2, "gamma": 0.1}, "q0": [0.1, 0, -0.1]
        }),
    ]
}

const NAMES: &[&str] = &[
    "x", "y", "px", "py", "a", "b", "p_a", "k", "l", "m", "g", "gamma", "zz",
];
const FUNCTIONS: &[&str] = &[
    "sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log", "sqrt",
    "abs", "nosuch",
];

/// Expressions from a loose grammar: mostly well formed, with unknown names and functions,
/// extreme numbers and divisions by zero mixed in.
fn expression() -> impl Strategy<Value = String> {
    let leaf = prop_oneof![
        proptest::sample::select(NAMES).prop_map(str::to_string),
        proptest::sample::select(&["0", "1", "2.5", "1e308", "1e-320", "pi", "-0"][..])
            .prop_map(str::to_string),
        (-1e3..1e3f64).prop_map(|v| format!("{v}")),
    ];
    leaf.prop_recursive(5, 40, 3, |inner| {
        prop_oneof![
            (
                inner.clone(),
                proptest::sample::select(&["+", "-", "*", "/", "^"][..]),
                inner.clone()
            )
                .prop_map(|(a, op, b)| format!("({a}){op}({b})")),
            (proptest::sample::select(FUNCTIONS), inner.clone())
                .prop_map(|(f, a)| format!("{f}({a})")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("atan2({a}, {b})")),
            inner.prop_map(|a| format!("-{a}")),
        ]
    })
}

/// Any JSON value of small size.
fn value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::from),
        any::<f64>()
            .prop_filter("finite", |v| v.is_finite())
            .prop_map(Value::from),
        expression().prop_map(Value::from),
        "\\PC{0,12}".prop_map(Value::from),
    ];
    leaf.prop_recursive(3, 24, 4, |inner| {
        prop_oneof![
            proptest::collection::vec(inner.clone(), 0..4).prop_map(Value::from),
            proptest::collection::btree_map("[a-z_]{1,6}", inner, 0..4)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// One change to a definition.
#[derive(Clone, Debug)]
enum Mutation {
    /// Replace the value at a path (keys and indices picked by position) by another value.
    Replace(Vec<usize>, Value),
    /// Replace a string at a path by an expression.
    Rewrite(Vec<usize>, String),
    /// Edit one character of a string at a path.
    Poke(Vec<usize>, usize, char),
    /// Remove what is at a path.
    Remove(Vec<usize>),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let path = proptest::collection::vec(0..16usize, 1..4);
    prop_oneof![
        (path.clone(), value()).prop_map(|(p, v)| Mutation::Replace(p, v)),
        (path.clone(), expression()).prop_map(|(p, e)| Mutation::Rewrite(p, e)),
        (path.clone(), 0..64usize, proptest::char::range(' ', '~'))
            .prop_map(|(p, i, c)| Mutation::Poke(p, i, c)),
        path.prop_map(Mutation::Remove),
    ]
}

/// The JSON pointer of the value a path picks (each step a key or an item by position, modulo
/// the size, stopping at a leaf), split into its parent's pointer and its last token.
fn locate(v: &Value, path: &[usize]) -> Option<(String, String)> {
    let mut parent = String::new();
    let mut node = v;
    let mut last = None;
    for &step in path {
        let (token, child) = match node {
            Value::Object(m) if !m.is_empty() => {
                let (k, child) = m.iter().nth(step % m.len())?;
                (k.replace('~', "~0").replace('/', "~1"), child)
            }
            Value::Array(a) if !a.is_empty() => ((step % a.len()).to_string(), &a[step % a.len()]),
            _ => break,
        };
        if let Some(previous) = last.replace(token) {
            parent = format!("{parent}/{previous}");
        }
        node = child;
    }
    last.map(|token| (parent, token))
}

fn apply(definition: &mut Value, mutation: &Mutation) {
    let path = match mutation {
        Mutation::Replace(p, _)
        | Mutation::Rewrite(p, _)
        | Mutation::Poke(p, _, _)
        | Mutation::Remove(p) => p,
    };
    let Some((parent, token)) = locate(definition, path) else {
        return;
    };
    let Some(container) = definition.pointer_mut(&parent) else {
        return;
    };
    if let Mutation::Remove(_) = mutation {
        match container {
            Value::Object(m) => {
                m.remove(&token.replace("~1", "/").replace("~0", "~"));
            }
            Value::Array(a) => {
                if let Ok(i) = token.parse::<usize>() {
                    a.remove(i);
                }
            }
            _ => {}
        }
        return;
    }
    let Some(slot) = container.pointer_mut(&format!("/{token}")) else {
        return;
    };
    match mutation {
        Mutation::Replace(_, v) => *slot = v.clone(),
        Mutation::Rewrite(_, e) => *slot = Value::from(e.clone()),
        Mutation::Poke(_, i, c) => {
            if let Value::String(s) = slot {
                let mut chars: Vec<char> = s.chars().collect();
                if chars.is_empty() {
                    chars.push(*c);
                } else {
                    let i = i % chars.len();
                    chars[i] = *c;
                }
                *s = chars.into_iter().collect();
            }
        }
        Mutation::Remove(_) => {}
    }
}

/// Runs a simulation request of `system` the way the service does, a few steps per method, and
/// fails the property on a panic or on a refusal that would be a server error.
fn exercise(system: Value, methods: &[&str]) -> Result<(), TestCaseError> {
    let body = json!({"system": system, "methods": methods, "h": 0.1, "t_end": 2,
        "output": {"every": 5}});
    let outcome = catch_unwind(AssertUnwindSafe(
        || -> Result<(), geomint::api::ErrorDetail> {
            let request = SimulateRequest::from_value(&body)?;
            let sim = request.prepare(&Limits::default(), &NoStoredSystems)?;
            for i in 0..sim.methods.len() {
                let mut sink = geomint::core::simulation::ColumnSink::new(sim.invariant_names());
                sim.run_method(i, None, Budget::default(), &mut sink)?;
            }
            Ok(())
        },
    ));
    match outcome {
        Err(_) => Err(TestCaseError::fail(format!("panicked on {body}"))),
        Ok(Err(detail)) => {
            let status = status_for(detail.code);
            prop_assert!(
                status.is_client_error(),
                "{} ({}) for {body}",
                status,
                detail.message
            );
            Ok(())
        }
        Ok(Ok(())) => Ok(()),
    }
}

const METHODS: &[&str] = &[
    "modin_3s",
    "rk4",
    "csv1",
    "implicit_midpoint",
    "symplectic_euler",
    "heun",
];

proptest! {
    #[test]
    fn mutated_definitions_never_panic_nor_fail_as_the_server(
        seed in 0..3usize,
        mutations in proptest::collection::vec(mutation(), 1..4),
        method in proptest::sample::select(METHODS),
    ) {
        let mut definition = seeds().swap_remove(seed);
        for m in &mutations {
            apply(&mut definition, m);
        }
        exercise(definition, &[method])?;
    }

    #[test]
    fn random_definitions_never_panic_nor_fail_as_the_server(
        potential in expression(),
        damping in proptest::option::of(expression()),
        invariant in expression(),
        general in any::<bool>(),
        method in proptest::sample::select(METHODS),
    ) {
        let mut definition = json!({
            "coordinates": ["x", "y"], "momenta": ["px", "py"],
            "parameters": {"k": 1.5, "l": 1, "m": 2, "g": 9.81, "gamma": 0.1},
            "invariants": {"I": invariant},
            "q0": [0.3, -0.2], "p0": [0.1, 0.4],
        });
        definition[if general { "hamiltonian" } else { "potential" }] = Value::from(potential);
        if let Some(d) = damping {
            definition["damping"] = json!({"epsilon": 0.1, "matrix": [[d.clone(), 0], [0, d]]});
        }
        exercise(definition, &[method])?;
    }
}

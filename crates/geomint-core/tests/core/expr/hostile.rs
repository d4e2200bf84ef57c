//! Hostile input: random and mutated text never panics, errors point inside the input,
//! and pathological sizes fail quickly with the right error.

use std::time::{Duration, Instant};

use super::common::EXAMPLES;
use geomint_core::expr::{
    parse, parse_with_limits, Backend, CompileOptions, CompiledFunction, ExprError, ExprLimits,
    Graph, NameScope,
};
use proptest::prelude::*;

fn scope() -> NameScope {
    NameScope::with_names(&[
        "x", "y", "z", "k", "l", "m", "g", "q", "t1", "t2", "p1", "p2", "a", "b",
    ])
    .unwrap()
    .restricted_to(&[])
    .clone()
}

fn full_scope() -> NameScope {
    NameScope::with_names(&[
        "x", "y", "z", "k", "l", "m", "g", "q", "t1", "t2", "p1", "p2", "a", "b",
    ])
    .unwrap()
}

/// Parses, and on success runs everything else the engine does with an expression;
/// checks that any error points inside the input (or just past its end).
fn exercise(text: &str, scope: &NameScope) {
    let length = text.chars().count();
    match parse(text, scope) {
        Err(error) => {
            let position = error.position().expect("parse errors have a position");
            assert!(
                position <= length,
                "{error:?} for {text:?} ({length} chars)"
            );
            assert!(!error.to_string().is_empty());
        }
        Ok(parsed) => {
            let mut g = Graph::new();
            let f = g.add_parsed(&parsed);
            let vars: Vec<_> = scope.vars().collect();
            let Ok(hessian) = g.hessian(f, &vars[..2]) else {
                return;
            };
            let mut outputs = vec![f];
            outputs.extend(hessian.iter().flatten());
            let options = CompileOptions {
                backend: Backend::Interpreter,
                ..CompileOptions::with_layout(vars.clone())
            };
            let compiled = CompiledFunction::new(&g, &outputs, &options).unwrap();
            let mut out = vec![0.0; outputs.len()];
            compiled.eval(&vec![0.5; vars.len()], &mut out);
        }
    }
}

/// Characters that make up expressions, plus some that do not, plus multi-byte ones.
const ALPHABET: &[char] = &[
    'x', 'y', 'z', 'k', 'q', '1', '2', '0', '9', '.', 'e', 'E', '+', '-', '*', '/', '^', '(', ')',
    ',', ' ', 's', 'i', 'n', 'p', 'a', 't', '_', 'θ', '€', '$', '\n', '\u{301}', '\0',
];

#[derive(Debug, Clone)]
enum Edit {
    Insert(usize, char),
    Delete(usize),
    Replace(usize, char),
}

fn apply(text: &str, edits: &[Edit]) -> String {
    let mut chars: Vec<char> = text.chars().collect();
    for edit in edits {
        let len = chars.len();
        match *edit {
            Edit::Insert(at, c) => chars.insert(at % (len + 1), c),
            Edit::Delete(at) if len > 0 => {
                chars.remove(at % len);
            }
            Edit::Replace(at, c) if len > 0 => chars[at % len] = c,
            _ => {}
        }
    }
    chars.into_iter().collect()
}

fn edit() -> impl Strategy<Value = Edit> {
    let c = proptest::sample::select(ALPHABET);
    prop_oneof![
        (any::<usize>(), c.clone()).prop_map(|(i, c)| Edit::Insert(i, c)),
        any::<usize>().prop_map(Edit::Delete),
        (any::<usize>(), c).prop_map(|(i, c)| Edit::Replace(i, c)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_strings_never_panic(text in "\\PC{0,80}") {
        exercise(&text, &full_scope());
        exercise(&text, &scope());
    }

    #[test]
    fn strings_of_expression_characters_never_panic(
        chars in proptest::collection::vec(proptest::sample::select(ALPHABET), 0..60)
    ) {
        let text: String = chars.into_iter().collect();
        exercise(&text, &full_scope());
    }

    #[test]
    fn mutated_examples_never_panic(
        index in 0..EXAMPLES.len(),
        edits in proptest::collection::vec(edit(), 1..6),
    ) {
        let text = apply(EXAMPLES[index].text, &edits);
        exercise(&text, &full_scope());
    }
}

fn quickly<T>(limit: Duration, work: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let result = work();
    assert!(start.elapsed() < limit, "took {:?}", start.elapsed());
    result
}

#[test]
fn deep_parentheses_fail_cleanly() {
    let deep = "(".repeat(100_000);
    let error = quickly(Duration::from_millis(500), || {
        parse(&deep, &full_scope()).unwrap_err()
    });
    assert_eq!(
        error,
        ExprError::TooLong {
            position: 4096,
            limit: 4096
        }
    );
    // With the length limit lifted, the nesting limit stops it at the 65th parenthesis.
    let limits = ExprLimits {
        max_chars: usize::MAX,
        ..ExprLimits::default()
    };
    let error = quickly(Duration::from_millis(500), || {
        parse_with_limits(&deep, &full_scope(), &limits).unwrap_err()
    });
    assert_eq!(
        error,
        ExprError::TooDeep {
            position: 64,
            limit: 64
        }
    );
    let calls = "sin(".repeat(100_000) + "x" + &")".repeat(100_000);
    let error = parse_with_limits(&calls, &full_scope(), &limits).unwrap_err();
    assert_eq!(
        error,
        ExprError::TooDeep {
            position: 259,
            limit: 64
        }
    );
    // Signs and powers are read in loops, not recursion: long chains are fine.
    let signs = "-".repeat(1000) + "x";
    assert!(parse(&signs, &full_scope()).is_ok());
    let tower = vec!["x"; 500].join("^");
    assert!(parse(&tower, &full_scope()).is_ok());
}

#[test]
fn huge_inputs_fail_quickly() {
    let huge = "x+".repeat(500_000);
    let error = quickly(Duration::from_millis(500), || {
        parse(&huge, &full_scope()).unwrap_err()
    });
    assert_eq!(
        error,
        ExprError::TooLong {
            position: 4096,
            limit: 4096
        }
    );
    // Without the length limit, the node limit stops a long sum early.
    let limits = ExprLimits {
        max_chars: usize::MAX,
        ..ExprLimits::default()
    };
    let error = quickly(Duration::from_millis(500), || {
        parse_with_limits(&huge, &full_scope(), &limits).unwrap_err()
    });
    assert_eq!(
        error,
        ExprError::TooManyNodes {
            position: 1999,
            limit: 2000
        }
    );
    // A long number literal is parsed in linear time.
    let number = "9".repeat(4000);
    let error = quickly(Duration::from_millis(500), || {
        parse(&number, &full_scope()).unwrap_err()
    });
    assert!(matches!(
        error,
        ExprError::NonFiniteConstant { position: 0, .. }
    ));
    let small = format!("0.{}1", "0".repeat(4000));
    assert_eq!(parse(&small, &full_scope()).unwrap().eval(&[]), 0.0);
    // The largest accepted expression parses fast.
    let longest = "12345.6*x + ".repeat(341) + "x";
    assert_eq!(longest.chars().count(), 4093);
    quickly(Duration::from_millis(500), || {
        parse(&longest, &full_scope()).unwrap()
    });
}

#[test]
fn exploding_derivatives_are_refused() {
    let scope = full_scope();
    let x = scope.lookup("x").unwrap();
    // A tower x^x^...^x: every derivative multiplies the size.
    let tower = vec!["x"; 40].join("^");
    let mut g = Graph::new();
    let mut f = g.parse(&tower, &scope).unwrap();
    let start = Instant::now();
    let mut refused = false;
    for _ in 0..10 {
        let before = g.len();
        match g.derivative(f, x) {
            Ok(d) => f = d,
            Err(error) => {
                assert_eq!(error, ExprError::DerivativeTooLarge { limit: 20_000 });
                // Nothing of the failed attempt is left behind.
                assert_eq!(g.len(), before);
                refused = true;
                break;
            }
        }
    }
    assert!(refused, "the tower's derivatives should outgrow the limit");
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "took {:?}",
        start.elapsed()
    );

    // A nested product: the Hessian of (x*y*z*...)^k with a small limit.
    let small = ExprLimits {
        max_derivative_nodes: 50,
        ..ExprLimits::default()
    };
    let mut g = Graph::with_limits(small);
    let f = g
        .parse("(x*y*z*k*l*m*g*q)^7 * sin(x*y*z*k*l*m*g*q)", &scope)
        .unwrap();
    let vars: Vec<_> = scope.vars().take(8).collect();
    let before = g.len();
    assert_eq!(
        g.hessian(f, &vars).unwrap_err(),
        ExprError::DerivativeTooLarge { limit: 50 }
    );
    assert_eq!(g.len(), before);
    // The graph is still usable afterwards.
    assert!(g.gradient(f, &vars[..1]).is_ok());
}

#[test]
fn oversized_programs_are_refused() {
    let scope = full_scope();
    let limits = ExprLimits {
        max_program_len: 10,
        ..ExprLimits::default()
    };
    let mut g = Graph::with_limits(limits);
    let f = g
        .parse(
            "sin(x) + cos(y) + exp(z) + log(k) + sqrt(l) + m + g",
            &scope,
        )
        .unwrap();
    let error =
        CompiledFunction::new(&g, &[f], &CompileOptions::with_layout(scope.vars())).unwrap_err();
    assert_eq!(error, ExprError::ProgramTooLarge { limit: 10 });
}

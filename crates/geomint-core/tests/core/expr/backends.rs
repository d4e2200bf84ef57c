//! The JIT, the interpreter and a plain recursive evaluation of the parsed tree agree
//! bit for bit; the compiled object is safe to share and to misuse.

use super::common::{same_value, Rng, EXAMPLES};
use geomint_core::expr::{
    parse, AstId, AstNode, Backend, CompileOptions, CompiledFunction, ExprError, Graph, NameScope,
    ParsedExpr, Var,
};

/// The straightforward recursive evaluator: the same operations as the engine, applied
/// to the tree exactly as written.
fn eval_tree(parsed: &ParsedExpr, id: AstId, values: &[f64]) -> f64 {
    match parsed.nodes()[id] {
        AstNode::Number(v) => v,
        AstNode::Var(var) => values[var.index()],
        AstNode::Unary(op, a) => op.apply(eval_tree(parsed, a, values)),
        AstNode::Binary(op, a, b) => {
            op.apply(eval_tree(parsed, a, values), eval_tree(parsed, b, values))
        }
    }
}

const EXTRA: &[&str] = &[
    "x^y",
    "x^-3",
    "x^17",
    "x^16",
    "x^-16",
    "x^15 * y^7",
    "y^0.5",
    "x^2.5",
    "2^3^2*x",
    "-x^2",
    "pi*x",
    "sqrt(x) + abs(y) - (-x)",
    "exp(x)/log(y)",
    "atan2(x, y)",
    "x*0 + y",
    "x/y/x",
    "(x+y)^3 - (x+y)^2",
    "1/(1 + x^2) - sinh(y)*cosh(x)*tanh(x-y)",
    "asin(x) + acos(y) + atan(x/y)",
    "tan(x)^-1",
    // The sine and cosine of one value come from one call in the JIT (`sincos`); not those of
    // two values that held one register in turn.
    "sin(x)*cos(x) - cos(x*y)/sin(x*y)",
    "-0.1*x*cos(y) + 0.1*sin(y)",
    "cos(x) + sin(y)",
    "sin(x) + cos(x*x)",
    "cos(y) * sin(x*y) + sin(y) - cos(y*y) + cos(x)*sin(x*x)",
    "x",
    "3",
    "-y",
];

fn expressions() -> Vec<(NameScope, String)> {
    let mut all: Vec<(NameScope, String)> = EXAMPLES
        .iter()
        .map(|e| (NameScope::with_names(e.names).unwrap(), e.text.to_string()))
        .collect();
    for text in EXTRA {
        all.push((
            NameScope::with_names(&["x", "y"]).unwrap(),
            text.to_string(),
        ));
    }
    all
}

fn compile(
    g: &Graph,
    outputs: &[geomint_core::expr::NodeId],
    scope: &NameScope,
    backend: Backend,
) -> CompiledFunction {
    let options = CompileOptions {
        backend,
        ..CompileOptions::with_layout(scope.vars())
    };
    CompiledFunction::new(g, outputs, &options).unwrap()
}

/// Random inputs, including zeros, negatives (NaN from sqrt/log), and large values.
fn random_input(rng: &mut Rng, n: usize) -> Vec<f64> {
    (0..n)
        .map(|_| match rng.below(10) {
            0 => 0.0,
            1 => rng.uniform(-100.0, 100.0),
            2 => rng.uniform(-1e-3, 1e-3),
            _ => rng.uniform(-3.0, 3.0),
        })
        .collect()
}

#[test]
fn jit_interpreter_and_tree_agree_bit_for_bit() {
    let mut rng = Rng(7);
    for (scope, text) in expressions() {
        let parsed = parse(&text, &scope).unwrap();
        let mut g = Graph::new();
        let f = g.add_parsed(&parsed);
        let vars: Vec<Var> = scope.vars().collect();
        let gradient = g.gradient(f, &vars).unwrap();
        let hessian = g.hessian(f, &vars).unwrap();
        let mut outputs = vec![f];
        outputs.extend(&gradient);
        outputs.extend(hessian.iter().flatten());

        let jit = compile(&g, &outputs, &scope, Backend::Jit);
        let interpreter = compile(&g, &outputs, &scope, Backend::Interpreter);
        assert!(jit.is_jit() && !interpreter.is_jit());
        let (mut a, mut b) = (vec![0.0; outputs.len()], vec![0.0; outputs.len()]);
        for _ in 0..2000 {
            let input = random_input(&mut rng, vars.len());
            jit.eval(&input, &mut a);
            interpreter.eval(&input, &mut b);
            for k in 0..outputs.len() {
                assert_eq!(
                    a[k].to_bits(),
                    b[k].to_bits(),
                    "{text} output {k} at {input:?}"
                );
            }
            // The value against the tree as written: equal up to the documented
            // simplifications (the sign of a zero, 0*x = 0).
            let reference = eval_tree(&parsed, parsed.root(), &input);
            assert!(
                same_value(a[0], reference),
                "{text} at {input:?}: {} vs {reference}",
                a[0]
            );
            // And the graph's own evaluator.
            let direct = g.eval(&outputs, &input);
            for k in 0..outputs.len() {
                assert!(same_value(direct[k], b[k]), "{text} output {k}");
            }
        }
    }
}

#[test]
fn baked_parameters_fold_and_agree() {
    let example = &EXAMPLES[1]; // elastic pendulum
    let scope = NameScope::with_names(example.names).unwrap();
    let vars: Vec<Var> = scope.vars().collect();
    let mut g = Graph::new();
    let v = g.parse(example.text, &scope).unwrap();
    let gradient = g.gradient(v, &vars[..3]).unwrap();
    let params = [10.0, 1.5, 2.0, 9.81];
    let general =
        CompiledFunction::new(&g, &gradient, &CompileOptions::with_layout(vars.clone())).unwrap();
    let mut options = CompileOptions::with_layout(vars[..3].iter().copied());
    options.constants = vars[3..].iter().copied().zip(params).collect();
    let baked = CompiledFunction::new(&g, &gradient, &options).unwrap();
    assert_eq!(baked.input_count(), 3);
    // Folding k/2 and m*g removes work.
    assert!(baked.program().operation_count() < general.program().operation_count());
    let mut rng = Rng(3);
    let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
    for _ in 0..1000 {
        let q: Vec<f64> = (0..3).map(|_| rng.uniform(-2.0, 2.0)).collect();
        let mut full = q.clone();
        full.extend(params);
        general.eval(&full, &mut a);
        baked.eval(&q, &mut b);
        for k in 0..3 {
            assert_eq!(a[k].to_bits(), b[k].to_bits(), "component {k} at {q:?}");
        }
    }
}

#[test]
fn powers_use_exactly_the_documented_multiplications() {
    let scope = NameScope::with_names(&["x"]).unwrap();
    let mut g = Graph::new();
    let cases = [
        (2, 1),
        (3, 2),
        (4, 2),
        (5, 3),
        (15, 6),
        (16, 4),
        (-1, 2),
        (-16, 6),
    ];
    for (n, operations) in cases {
        let f = g.parse(&format!("x^{n}"), &scope).unwrap();
        let compiled = compile(&g, &[f], &scope, Backend::Jit);
        // One load, the multiplications, and for negative n a constant and a division.
        assert_eq!(
            compiled.program().operation_count(),
            1 + operations,
            "x^{n}"
        );
        let mut out = [0.0];
        for x in [0.7, -1.3, 1.0000001, 3.0] {
            compiled.eval(&[x], &mut out);
            assert_eq!(
                out[0].to_bits(),
                geomint_core::expr::ops::powi(x, n).to_bits()
            );
            assert_eq!(
                out[0].to_bits(),
                geomint_core::expr::ops::pow(x, f64::from(n)).to_bits()
            );
        }
    }
    assert_eq!(geomint_core::expr::ops::powi(3.0, 2), 9.0);
    assert_eq!(geomint_core::expr::ops::powi(f64::NAN, 0), 1.0);
    assert_eq!(geomint_core::expr::ops::pow(2.0, 0.5), 2f64.sqrt());
}

#[test]
fn outputs_may_be_inputs_constants_or_repeated() {
    let scope = NameScope::with_names(&["x", "y"]).unwrap();
    let mut g = Graph::new();
    let x = g.parse("x", &scope).unwrap();
    let c = g.parse("2*3", &scope).unwrap();
    let s = g.parse("x*y", &scope).unwrap();
    for backend in [Backend::Jit, Backend::Interpreter] {
        let f = compile(&g, &[x, c, s, x, s], &scope, backend);
        let mut out = [0.0; 5];
        f.eval(&[4.0, 0.5], &mut out);
        assert_eq!(out, [4.0, 6.0, 2.0, 4.0, 2.0]);
        let none = compile(&g, &[], &scope, backend);
        none.eval(&[1.0, 2.0], &mut []);
    }
}

#[test]
fn compiled_functions_are_shared_across_threads() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<CompiledFunction>();
    assert_send_sync::<Graph>();

    let (mut g, scope, f) = super::common::build(&EXAMPLES[3]); // double pendulum
    let vars: Vec<Var> = scope.vars().collect();
    let gradient = g.gradient(f, &vars).unwrap();
    let compiled = compile(&g, &gradient, &scope, Backend::Auto);
    let input = [0.3, -0.2, 0.5, 0.1];
    let mut expected = [0.0; 4];
    compiled.eval_interpreted(&input, &mut expected);
    std::thread::scope(|s| {
        for _ in 0..4 {
            s.spawn(|| {
                let mut out = [0.0; 4];
                for _ in 0..10_000 {
                    compiled.eval(&input, &mut out);
                    assert_eq!(out, expected);
                }
            });
        }
    });
}

#[test]
fn many_functions_can_be_compiled_and_dropped() {
    let scope = NameScope::with_names(&["x"]).unwrap();
    for i in 0..200 {
        let mut g = Graph::new();
        let f = g.parse(&format!("sin(x) * {i}"), &scope).unwrap();
        let compiled = compile(&g, &[f], &scope, Backend::Jit);
        let mut out = [0.0];
        compiled.eval(&[1.0], &mut out);
        assert_eq!(out[0], 1f64.sin() * f64::from(i));
    }
}

#[test]
fn bad_slices_and_bindings_are_errors() {
    let scope = NameScope::with_names(&["x", "y"]).unwrap();
    let (x, y) = (scope.lookup("x").unwrap(), scope.lookup("y").unwrap());
    let mut g = Graph::new();
    let f = g.parse("x + y", &scope).unwrap();
    let compiled = compile(&g, &[f], &scope, Backend::Auto);
    assert_eq!(
        compiled.try_eval(&[1.0], &mut [0.0]),
        Err(ExprError::WrongSliceLength {
            which: "inputs",
            expected: 2,
            found: 1
        })
    );
    assert_eq!(
        compiled.try_eval(&[1.0, 2.0], &mut []),
        Err(ExprError::WrongSliceLength {
            which: "outputs",
            expected: 1,
            found: 0
        })
    );
    let result = std::panic::catch_unwind(|| compiled.eval(&[1.0, 2.0, 3.0], &mut [0.0]));
    assert!(result.is_err());

    let only_x = CompileOptions::with_layout([x]);
    assert_eq!(
        CompiledFunction::new(&g, &[f], &only_x).unwrap_err(),
        ExprError::UnboundVariable { var: 1 }
    );
    let twice = CompileOptions {
        constants: vec![(y, 1.0), (x, 2.0)],
        ..CompileOptions::with_layout([x])
    };
    assert_eq!(
        CompiledFunction::new(&g, &[f], &twice).unwrap_err(),
        ExprError::DuplicateBinding { var: 0 }
    );
}

/// The JIT takes the sine and cosine of one value from one call (`sincos`); the interpreter
/// calls `sin` and `cos`. Bit for bit the same over the whole range of magnitudes, the huge
/// arguments whose reduction modulo π/2 takes the slow path included.
#[test]
fn sine_and_cosine_of_one_value_agree_at_every_magnitude() {
    let scope = NameScope::with_names(&["x"]).unwrap();
    let mut g = Graph::new();
    let parsed = parse("sin(x) - 2*cos(x)", &scope).unwrap();
    let f = g.add_parsed(&parsed);
    let x = scope.vars().next().unwrap();
    let outputs = vec![f, g.gradient(f, &[x]).unwrap()[0]];
    let jit = compile(&g, &outputs, &scope, Backend::Jit);
    let interpreter = compile(&g, &outputs, &scope, Backend::Interpreter);
    let mut rng = Rng(11);
    let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
    let mut checked = 0;
    for exponent in -320..=308 {
        for _ in 0..20 {
            let x = rng.uniform(-1.0, 1.0) * 10f64.powi(exponent);
            jit.eval(&[x], &mut a);
            interpreter.eval(&[x], &mut b);
            for k in 0..2 {
                assert_eq!(a[k].to_bits(), b[k].to_bits(), "output {k} at x = {x:e}");
            }
            checked += 1;
        }
    }
    for x in [
        0.0,
        -0.0,
        f64::INFINITY,
        f64::NAN,
        f64::MAX,
        f64::MIN_POSITIVE,
    ] {
        jit.eval(&[x], &mut a);
        interpreter.eval(&[x], &mut b);
        assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "at x = {x:e}");
    }
    assert_eq!(checked, 629 * 20);
}

/// Registers are reused once their value is dead, so one register can hold a value whose sine
/// the program takes and later another value whose cosine it takes: the JIT must not take them
/// for one value's pair. Only the expression is compiled here (its derivatives would keep the
/// values alive, and their registers apart).
#[test]
fn a_sine_and_a_cosine_of_two_values_in_one_register_stay_apart() {
    let scope = NameScope::with_names(&["x", "y"]).unwrap();
    let mut rng = Rng(13);
    for text in [
        "sin(x) + cos(x*x)",
        "cos(x) * sin(x*y)",
        "sin(x + y) - cos((x + y)*(x + y))",
    ] {
        let mut g = Graph::new();
        let f = g.add_parsed(&parse(text, &scope).unwrap());
        let jit = compile(&g, &[f], &scope, Backend::Jit);
        let interpreter = compile(&g, &[f], &scope, Backend::Interpreter);
        let (mut a, mut b) = ([0.0], [0.0]);
        for _ in 0..200 {
            let input = random_input(&mut rng, 2);
            jit.eval(&input, &mut a);
            interpreter.eval(&input, &mut b);
            assert_eq!(a[0].to_bits(), b[0].to_bits(), "{text} at {input:?}");
        }
    }
}

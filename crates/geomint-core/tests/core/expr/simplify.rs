//! Simplification: the DAG built for derivatives and folded expressions is the small
//! one, checked structurally (node identity) and by node counts.

use super::common::{build, vars, EXAMPLES};
use geomint_core::expr::{Graph, NameScope, Node};

fn setup() -> (Graph, NameScope) {
    (Graph::new(), NameScope::with_names(&["x", "y"]).unwrap())
}

#[test]
fn derivative_of_square_is_two_x() {
    let (mut g, scope) = setup();
    let x = scope.lookup("x").unwrap();
    let f = g.parse("x^2", &scope).unwrap();
    let d = g.derivative(f, x).unwrap();
    let two_x = g.parse("2*x", &scope).unwrap();
    assert_eq!(d, two_x);
    assert_eq!(g.count_nodes(&[d]), 3);
    assert_eq!(g.to_infix(d, &scope, 100).unwrap(), "2 * x");
    // Reverse mode gives the same node.
    assert_eq!(g.gradient(f, &[x]).unwrap(), vec![two_x]);
    // And the cube: 3*x^2, not exp(3*log(x))*...
    let cube = g.parse("x^3", &scope).unwrap();
    let d = g.derivative(cube, x).unwrap();
    assert_eq!(d, g.parse("3*x^2", &scope).unwrap());
    let d2 = g.derivative(d, x).unwrap();
    assert_eq!(d2, g.parse("3*(2*x)", &scope).unwrap());
}

#[test]
fn derivatives_of_constants_and_other_variables_are_zero() {
    let (mut g, scope) = setup();
    let x = scope.lookup("x").unwrap();
    let zero = g.constant(0.0);
    for text in ["5", "pi^2", "y", "sin(y)*exp(y)", "atan2(y, 2)"] {
        let f = g.parse(text, &scope).unwrap();
        assert_eq!(g.derivative(f, x).unwrap(), zero, "{text}");
        assert_eq!(g.gradient(f, &[x]).unwrap(), vec![zero], "{text}");
    }
    let f = g.parse("x", &scope).unwrap();
    let d = g.derivative(f, x).unwrap();
    assert_eq!(g.as_const(d), Some(1.0));
}

#[test]
fn builders_fold_and_simplify() {
    let (mut g, scope) = setup();
    let x = g.parse("x", &scope).unwrap();
    let cases = [
        ("2*3 + 1", "7"),
        ("x*1", "x"),
        ("1*x", "x"),
        ("x*0", "0"),
        ("0*x", "0"),
        ("0/x", "0"),
        ("x + 0", "x"),
        ("0 + x", "x"),
        ("x - 0", "x"),
        ("0 - x", "-x"),
        ("x/1", "x"),
        ("x^1", "x"),
        ("x^0", "1"),
        ("y^(3-3)", "1"),
        ("-(-x)", "x"),
        ("-(0)", "-0"),
        ("x + -y", "x - y"),
        ("-x + y", "y - x"),
        ("x - -y", "x + y"),
        ("-x * y", "-(x * y)"),
        ("x * -y", "-(x * y)"),
        ("-x / -y", "x / y"),
        ("x * -1", "-x"),
        ("abs(-x)", "abs(x)"),
        ("y*x", "x * y"),
        ("x^(1+1)", "x^2"),
        ("2^10", "1024"),
        ("sqrt(4)", "2"),
        ("x^-2", "x^-2"),
        ("x^20", "x^20"),
    ];
    for (text, simplified) in cases {
        let id = g.parse(text, &scope).unwrap();
        assert_eq!(g.to_infix(id, &scope, 100).unwrap(), simplified, "{text}");
    }
    let square = g.parse("x^2", &scope).unwrap();
    assert!(matches!(g.node(square), Node::PowI(_, 2)));
    assert_eq!(g.parse("(x)", &scope).unwrap(), x);
}

#[test]
fn equal_subexpressions_are_one_node() {
    let (mut g, scope) = setup();
    let f = g.parse("x*y + y*x", &scope).unwrap();
    // x, y, x*y and the sum.
    assert_eq!(g.count_nodes(&[f]), 4);
    let a = g.parse("sin(x+y)^2 + cos(x+y)^2", &scope).unwrap();
    // x, y, x+y, sin, cos, two squares, the sum.
    assert_eq!(g.count_nodes(&[a]), 8);
    let before = g.len();
    let again = g.parse("sin(x + y)^2 + cos(y + x)^2", &scope).unwrap();
    assert_eq!((again, g.len()), (a, before));
}

#[test]
fn elastic_pendulum_gradient_and_hessian_stay_small() {
    let (mut g, scope, v) = build(&EXAMPLES[1]);
    let all = vars(&scope);
    let q = &all[..3];
    assert_eq!(g.count_nodes(&[v]), 21);
    let gradient = g.gradient(v, q).unwrap();
    // V itself is 21 nodes; the whole gradient, sharing with V, is at most 30.
    assert!(
        g.count_nodes(&gradient) <= 30,
        "{}",
        g.count_nodes(&gradient)
    );
    let hessian = g.hessian(v, q).unwrap();
    let mut all_outputs = gradient.clone();
    all_outputs.extend(hessian.iter().flatten());
    // Gradient and Hessian together: at most 64 nodes.
    assert!(
        g.count_nodes(&all_outputs) <= 64,
        "{}",
        g.count_nodes(&all_outputs)
    );
    // Symmetric entries are the same node.
    assert_eq!(hessian[0][2], hessian[2][0]);
    // The components share everything but the last multiplication, as by hand:
    // dV/dx = x * (shared factor) adds one node to what the other components need.
    let without_x = g.count_nodes(&gradient[1..]);
    assert_eq!(g.count_nodes(&gradient) - without_x, 1);
}

#[test]
fn printed_expressions_parse_back_to_the_same_node() {
    for example in EXAMPLES.iter().filter(|e| !e.text.contains("abs")) {
        let (mut g, scope, f) = build(example);
        let gradient = g.gradient(f, &vars(&scope)).unwrap();
        for id in std::iter::once(f).chain(gradient) {
            let text = g.to_infix(id, &scope, 10_000).unwrap();
            assert_eq!(
                g.parse(&text, &scope).unwrap(),
                id,
                "{}: {text}",
                example.name
            );
        }
    }
}

#[test]
fn printing_refuses_exponential_trees() {
    let (mut g, scope) = setup();
    let mut f = g.parse("x", &scope).unwrap();
    for _ in 0..40 {
        f = g.mul(f, f); // 2^40 leaves as a tree, 41 nodes as a DAG
        f = g.add(f, f);
    }
    assert_eq!(g.count_nodes(&[f]), 81);
    assert!(g.to_infix(f, &scope, 1000).is_none());
}

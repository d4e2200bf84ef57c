//! The parser: precedence, associativity, numbers, and every error with its position.

use geomint_core::expr::ops::{BinaryOp, UnaryOp};
use geomint_core::expr::{
    parse, parse_with_limits, AstNode, Expected, ExprError, ExprLimits, NameScope,
};

fn scope() -> NameScope {
    NameScope::with_names(&["x", "y", "k", "θ"]).unwrap()
}

fn value(text: &str) -> f64 {
    parse(text, &scope()).unwrap().eval(&[2.0, 3.0, 5.0, 0.5])
}

/// Prints the tree fully parenthesised, to check its shape.
fn shape(text: &str) -> String {
    let parsed = parse(text, &scope()).unwrap();
    let mut out: Vec<String> = Vec::new();
    for node in parsed.nodes() {
        let s = match *node {
            AstNode::Number(v) => format!("{v}"),
            AstNode::Var(v) => ["x", "y", "k", "θ"][v.index()].to_string(),
            AstNode::Unary(UnaryOp::Neg, a) => format!("(-{})", out[a]),
            AstNode::Unary(op, a) => format!("{}({})", op.name(), out[a]),
            AstNode::Binary(BinaryOp::Atan2, a, b) => format!("atan2({}, {})", out[a], out[b]),
            AstNode::Binary(op, a, b) => format!("({} {} {})", out[a], op.name(), out[b]),
        };
        out.push(s);
    }
    out.pop().unwrap()
}

fn error(text: &str) -> ExprError {
    parse(text, &scope()).unwrap_err()
}

#[test]
fn precedence_and_associativity() {
    assert_eq!(shape("x + y * k"), "(x + (y * k))");
    assert_eq!(shape("x - y - k"), "((x - y) - k)");
    assert_eq!(shape("x / y / k"), "((x / y) / k)");
    assert_eq!(shape("x * y / k * x"), "(((x * y) / k) * x)");
    assert_eq!(shape("2^3^2"), "(2 ^ (3 ^ 2))");
    assert_eq!(shape("-x^2"), "(-(x ^ 2))");
    assert_eq!(shape("x^-y^2"), "(x ^ (-(y ^ 2)))");
    assert_eq!(shape("-x * y"), "((-x) * y)");
    assert_eq!(shape("x * -y"), "(x * (-y))");
    assert_eq!(shape("--x"), "(-(-x))");
    assert_eq!(shape("+x"), "x");
    assert_eq!(shape("(x + y) * k"), "((x + y) * k)");
    assert_eq!(shape("x - -y"), "(x - (-y))");
    assert_eq!(
        shape("atan2(y, x) + sin(x)^2"),
        "(atan2(y, x) + (sin(x) ^ 2))"
    );
    assert_eq!(shape("2 * x ^ k ^ y * 3"), "((2 * (x ^ (k ^ y))) * 3)");

    assert_eq!(value("2^3^2"), 512.0);
    assert_eq!(value("-2^2"), -4.0);
    assert_eq!(value("(-2)^2"), 4.0);
    assert_eq!(value("x - y - k"), -6.0);
    assert_eq!(value("k / y / x"), 5.0 / 3.0 / 2.0);
    assert_eq!(value("2^-1"), 0.5);
    assert_eq!(value("1 + 2 * 3 ^ 2 / 6"), 4.0);
    assert_eq!(value("pi"), std::f64::consts::PI);
    assert_eq!(value(" \t x\n*\ry "), 6.0);
    assert_eq!(value("θ*4"), 2.0);
}

#[test]
fn numbers() {
    assert_eq!(value("1"), 1.0);
    assert_eq!(value("0.5"), 0.5);
    assert_eq!(value(".5"), 0.5);
    assert_eq!(value("1."), 1.0);
    assert_eq!(value("1e-3"), 1e-3);
    assert_eq!(value("2.5E+4"), 2.5e4);
    assert_eq!(value("0.1"), 0.1);
    assert_eq!(value("1e-400"), 0.0); // underflows to zero: finite, accepted
    assert_eq!(value("12345678901234567890"), 12345678901234567890.0);
}

#[test]
fn syntax_errors_with_positions() {
    assert_eq!(
        error("x + * y"),
        ExprError::UnexpectedToken {
            expected: Expected::Operand,
            found: "*".into(),
            position: 4
        }
    );
    assert_eq!(
        error("sin(x"),
        ExprError::UnexpectedEnd {
            expected: Expected::OperatorOrCloseParen,
            position: 5
        }
    );
    assert_eq!(
        error("atan2(y x)"),
        ExprError::UnexpectedToken {
            expected: Expected::OperatorOrComma,
            found: "x".into(),
            position: 8
        }
    );
    assert_eq!(
        error("(x + y"),
        ExprError::UnexpectedEnd {
            expected: Expected::OperatorOrCloseParen,
            position: 6
        }
    );
    assert_eq!(
        error("x + y)"),
        ExprError::UnexpectedToken {
            expected: Expected::OperatorOrEnd,
            found: ")".into(),
            position: 5
        }
    );
    assert_eq!(
        error("sin x"),
        ExprError::UnexpectedToken {
            expected: Expected::OpenParen,
            found: "x".into(),
            position: 4
        }
    );
    assert_eq!(
        error(""),
        ExprError::UnexpectedEnd {
            expected: Expected::Operand,
            position: 0
        }
    );
    assert_eq!(
        error("   "),
        ExprError::UnexpectedEnd {
            expected: Expected::Operand,
            position: 3
        }
    );
    assert_eq!(
        error("-"),
        ExprError::UnexpectedEnd {
            expected: Expected::Operand,
            position: 1
        }
    );
    assert_eq!(
        error("x y"),
        ExprError::UnexpectedToken {
            expected: Expected::OperatorOrEnd,
            found: "y".into(),
            position: 2
        }
    );
    assert_eq!(
        error("2x"),
        ExprError::UnexpectedToken {
            expected: Expected::OperatorOrEnd,
            found: "x".into(),
            position: 1
        }
    );
    assert_eq!(
        error("x ** 2"),
        ExprError::UnexpectedToken {
            expected: Expected::Operand,
            found: "*".into(),
            position: 3
        }
    );
    assert_eq!(
        error("x + ."),
        ExprError::UnexpectedEnd {
            expected: Expected::Digit,
            position: 5
        }
    );
    assert_eq!(
        error("1e+x"),
        ExprError::UnexpectedToken {
            expected: Expected::Digit,
            found: "x".into(),
            position: 3
        }
    );
    assert_eq!(
        error("1.2.3"),
        ExprError::UnexpectedToken {
            expected: Expected::OperatorOrEnd,
            found: ".3".into(),
            position: 3
        }
    );
    assert_eq!(
        error("sin(x,)"),
        ExprError::UnexpectedToken {
            expected: Expected::Operand,
            found: ")".into(),
            position: 6
        }
    );
    assert_eq!(
        error("x $ y"),
        ExprError::UnexpectedCharacter {
            character: '$',
            position: 2
        }
    );
    assert_eq!(
        error("x = 1"),
        ExprError::UnexpectedCharacter {
            character: '=',
            position: 2
        }
    );
}

#[test]
fn name_and_call_errors() {
    assert_eq!(
        error("foo(x)"),
        ExprError::UnknownFunction {
            name: "foo".into(),
            position: 0
        }
    );
    assert_eq!(
        error("x + z*2"),
        ExprError::UnknownName {
            name: "z".into(),
            position: 4,
            known: vec!["x".into(), "y".into(), "k".into(), "θ".into()]
        }
    );
    assert_eq!(
        error("1 + atan2(x)"),
        ExprError::WrongArgumentCount {
            function: "atan2",
            position: 4,
            expected: 2,
            found: 1
        }
    );
    assert_eq!(
        error("sin(x, y)"),
        ExprError::WrongArgumentCount {
            function: "sin",
            position: 0,
            expected: 1,
            found: 2
        }
    );
    assert_eq!(
        error("cos()"),
        ExprError::WrongArgumentCount {
            function: "cos",
            position: 0,
            expected: 1,
            found: 0
        }
    );
    // A declared name used as a function: the "(" cannot follow an operand.
    assert_eq!(
        error("x(2)"),
        ExprError::UnexpectedToken {
            expected: Expected::OperatorOrEnd,
            found: "(".into(),
            position: 1
        }
    );
    assert_eq!(
        error("1e999"),
        ExprError::NonFiniteConstant {
            text: "1e999".into(),
            position: 0
        }
    );
    assert_eq!(
        error("2 * 1e999"),
        ExprError::NonFiniteConstant {
            text: "1e999".into(),
            position: 4
        }
    );
}

#[test]
fn names_not_allowed_are_refused_where_they_stand() {
    let full = scope();
    let params_only = full.restricted_to(&[full.lookup("k").unwrap()]);
    assert_eq!(
        parse("2*k", &params_only)
            .unwrap()
            .eval(&[0.0, 0.0, 4.0, 0.0]),
        8.0
    );
    let err = parse("k * (1 + y)", &params_only).unwrap_err();
    assert_eq!(
        err,
        ExprError::NameNotAllowed {
            name: "y".into(),
            position: 9,
            allowed: vec!["k".into()]
        }
    );
    assert_eq!(
        err.to_string(),
        "\"y\" cannot be used in this expression (at character 9); names that may be used here: k"
    );
}

#[test]
fn positions_count_characters_not_bytes() {
    // "θ" and "é" take two bytes each; positions are character indices.
    assert_eq!(
        error("θ + é"),
        ExprError::UnknownName {
            name: "é".into(),
            position: 4,
            known: vec!["x".into(), "y".into(), "k".into(), "θ".into()]
        }
    );
    assert_eq!(
        error("θ*θ € 2"),
        ExprError::UnexpectedCharacter {
            character: '€',
            position: 4
        }
    );
    assert_eq!(
        error("θθ + ("),
        ExprError::UnknownName {
            name: "θθ".into(),
            position: 0,
            known: vec!["x".into(), "y".into(), "k".into(), "θ".into()]
        }
    );
    assert_eq!(
        error("(θ + 1"),
        ExprError::UnexpectedEnd {
            expected: Expected::OperatorOrCloseParen,
            position: 6
        }
    );
}

#[test]
fn messages_are_precise() {
    assert_eq!(
        error("x + ) ").to_string(),
        r#"expected an operand (a number, a name, a function call or "("), found ")" at character 4"#
    );
    assert_eq!(
        error("sin(x").to_string(),
        r#"expected an operator (+ - * / ^) or ")", found the end of the expression at character 5"#
    );
    assert_eq!(
        error("foo(1)").to_string(),
        "unknown function \"foo\" at character 0; the functions are sin, cos, tan, asin, acos, \
         atan, sinh, cosh, tanh, exp, log, sqrt, abs, atan2"
    );
    assert_eq!(
        error("atan2(x)").to_string(),
        "atan2 takes 2 arguments, but 1 was given at character 0"
    );
    assert_eq!(
        error("1e999").to_string(),
        "the number 1e999 at character 0 is too large to represent"
    );
    let long_number = format!("1{}", "0".repeat(400));
    let message = error(&long_number).to_string();
    assert!(
        message.len() < 100,
        "long literals are shortened: {message}"
    );
}

#[test]
fn size_limits_have_positions() {
    let limits = ExprLimits {
        max_chars: 10,
        ..ExprLimits::default()
    };
    assert_eq!(
        parse_with_limits("x + y + k + x", &scope(), &limits).unwrap_err(),
        ExprError::TooLong {
            position: 10,
            limit: 10
        }
    );
    let limits = ExprLimits {
        max_depth: 3,
        ..ExprLimits::default()
    };
    assert!(parse_with_limits("((sin(x)))", &scope(), &limits).is_ok());
    assert_eq!(
        parse_with_limits("(((sin(x))))", &scope(), &limits).unwrap_err(),
        ExprError::TooDeep {
            position: 6,
            limit: 3
        }
    );
    let limits = ExprLimits {
        max_parse_nodes: 5,
        ..ExprLimits::default()
    };
    assert!(parse_with_limits("x + y + k", &scope(), &limits).is_ok());
    assert_eq!(
        parse_with_limits("x + y + k * y", &scope(), &limits).unwrap_err(),
        ExprError::TooManyNodes {
            position: 10,
            limit: 5
        }
    );
}

#[test]
fn declarations_are_checked() {
    let mut scope = NameScope::new();
    assert!(scope.declare("q_1").is_ok());
    for bad in ["", "1x", "x y", "sin", "pi", "q_1", "a-b"] {
        assert!(
            matches!(
                scope.declare(bad),
                Err(ExprError::InvalidDeclaration { .. })
            ),
            "{bad:?} should be refused"
        );
    }
}

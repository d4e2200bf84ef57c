//! The expression engine's operations, as the interpreter inlines them.

use geomint_core::expr::ops;
use geomint_core::expr::ops::*;

/// The interpreter's inlined cases must be the same IEEE operations as `BinaryOp::apply` and
/// `UnaryOp::apply`.
#[test]
fn inlined_cases_match_apply() {
    let (x, y) = (0.1, 0.7);
    assert_eq!(BinaryOp::Add.apply(x, y), x + y);
    assert_eq!(BinaryOp::Mul.apply(x, y), x * y);
    assert_eq!(ops::powi(x, 3), x * (x * x));
    assert_eq!(UnaryOp::Sqrt.apply(x), x.sqrt());
    assert_eq!(UnaryOp::Neg.apply(x), -x);
}

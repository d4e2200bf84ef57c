//! The expression engine behind user-defined mechanical systems: parse a formula, take
//! exact simplified derivatives, and compile any set of them to native code.
//!
//! ```
//! use geomint_core::expr::{CompileOptions, CompiledFunction, ExprError, Graph, NameScope};
//!
//! let scope = NameScope::with_names(&["x", "y", "k", "l", "m", "g"])?;
//! let [x, y] = [0, 1].map(|i| scope.vars().nth(i).unwrap());
//! let mut graph = Graph::new();
//! let potential = graph.parse("k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*y", &scope)?;
//! let gradient = graph.gradient(potential, &[x, y])?;
//! let f = CompiledFunction::new(&graph, &gradient, &CompileOptions::with_layout(scope.vars()))?;
//! let mut force = [0.0; 2];
//! f.eval(&[3.0, 4.0, 2.0, 1.0, 1.0, 9.81], &mut force);
//! assert!((force[0] - 2.0 * (5.0 - 1.0) * 3.0 / 5.0).abs() < 1e-12);
//! # Ok::<(), ExprError>(())
//! ```
//!
//! # The language
//! * numbers: `1`, `0.5`, `.5`, `1.`, `1e-3`, `2.5E+4` (decimal; a literal that overflows
//!   to infinity, such as `1e999`, is an error);
//! * binary `+ - * /` and `^`; `^` groups from the right and binds tighter than a sign,
//!   so `-x^2 = -(x^2)`, `2^3^2 = 2^9` and `x^-2 = x^(-2)`;
//! * signs `-x` and `+x`; parentheses;
//! * the functions `sin cos tan asin acos atan sinh cosh tanh exp log sqrt abs` of one
//!   argument and `atan2(y, x)`; `log` is the natural logarithm;
//! * the constant `pi`, and the names declared in the [`NameScope`];
//! * whitespace anywhere between tokens. Nothing else: no implicit multiplication, no
//!   user functions.
//!
//! `x^n` for an integer `n` with `|n| <= 16` is computed by multiplications (see
//! [`ops::powi`]), otherwise with `powf`; the rule depends only on the exponent's value
//! ([`ops::pow`]).
//!
//! # Errors
//! Errors about the text carry the 0-based index of the offending **character**
//! (Unicode scalar value, not byte); the end of the input is the number of characters.
//!
//! # Limits
//! Hostile input is bounded by [`ExprLimits`] (defaults in parentheses): the length of an
//! expression (4096 characters), the nesting of parentheses and calls (64), the nodes of
//! one parsed expression (2000), the nodes one derivative, gradient or Hessian may add
//! (20 000) and the instructions of a compiled program (20 000). Parsing is linear in the
//! input and never recurses more than the nesting limit; no input makes it panic.
//!
//! # Pieces
//! [`parse`](mod@parse) reads text into a [`ParsedExpr`]; a [`Graph`] holds expressions as a
//! hash-consed DAG and simplifies as it builds; its derivative methods are in `diff`;
//! [`program`] lowers outputs to a register program and interprets it; the JIT
//! translates that program with Cranelift; [`CompiledFunction`] ties them together.

mod compile;
mod diff;
mod display;
mod error;
mod graph;
pub(crate) mod jit;
mod lex;
pub mod ops;
pub mod parse;
pub mod program;
pub mod trace;

pub use compile::{Backend, CompileOptions, CompiledFunction};
pub use error::{Expected, ExprError};
pub use graph::{Graph, Node, NodeId};
pub use parse::{parse, parse_with_limits, AstId, AstNode, NameScope, ParsedExpr};

/// A variable slot: the index of a name in its [`NameScope`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Var(pub u32);

impl Var {
    /// The slot index.
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// Bounds that keep hostile or accidental input cheap.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExprLimits {
    /// The longest expression accepted, in characters.
    pub max_chars: usize,
    /// The deepest nesting of parentheses and function calls.
    pub max_depth: usize,
    /// The most nodes (numbers, names, operations) one parsed expression may have.
    pub max_parse_nodes: usize,
    /// The most new graph nodes one call of `derivative`, `gradient`, `jacobian` or
    /// `hessian` may add.
    pub max_derivative_nodes: usize,
    /// The most instructions (loads, constants, operations) of one compiled program.
    pub max_program_len: usize,
}

impl ExprLimits {
    /// The default limits.
    pub const DEFAULT: ExprLimits = ExprLimits {
        max_chars: 4096,
        max_depth: 64,
        max_parse_nodes: 2000,
        max_derivative_nodes: 20_000,
        max_program_len: 20_000,
    };
}

impl Default for ExprLimits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

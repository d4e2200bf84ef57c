//! The error type shared by the whole engine.
//!
//! Every error that is about the text of an expression carries a `position`: the 0-based
//! index of the offending **character** (a Unicode scalar value, as `str::chars` counts
//! them), not a byte offset. A position equal to the number of characters in the input
//! means "at the end". Errors raised later (differentiation, compilation, evaluation)
//! are not about a place in the text and carry no position.

use std::fmt;

/// What the parser would have accepted at the place where it stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Expected {
    /// The start of an operand: a number, a name, a function call, `-`, `+` or `(`.
    Operand,
    /// A binary operator, or the end of the whole expression.
    OperatorOrEnd,
    /// A binary operator, or the `)` closing a parenthesis or a call.
    OperatorOrCloseParen,
    /// A binary operator, or the `,` before the next argument of a call.
    OperatorOrComma,
    /// The `(` that must follow a function name.
    OpenParen,
    /// A digit: after a lone `.`, or in the exponent of a number such as `1e-3`.
    Digit,
}

impl fmt::Display for Expected {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Expected::Operand => r#"an operand (a number, a name, a function call or "(")"#,
            Expected::OperatorOrEnd => "an operator (+ - * / ^) or the end of the expression",
            Expected::OperatorOrCloseParen => r#"an operator (+ - * / ^) or ")""#,
            Expected::OperatorOrComma => {
                r#"an operator (+ - * / ^) or "," before the next argument"#
            }
            Expected::OpenParen => r#""(" after the function name"#,
            Expected::Digit => "a digit",
        })
    }
}

/// Everything that can go wrong while parsing, differentiating, compiling or evaluating.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ExprError {
    /// A character that no token of the language starts with (e.g. `$`, `=`, `[`).
    #[error("unexpected character '{character}' at character {position}")]
    UnexpectedCharacter {
        /// The character, as written.
        character: char,
        /// Its 0-based character index.
        position: usize,
    },
    /// A well-formed token in a place where the grammar does not allow it.
    #[error("expected {expected}, found \"{found}\" at character {position}")]
    UnexpectedToken {
        /// What would have been accepted there.
        expected: Expected,
        /// The token's text as written (shortened if very long).
        found: String,
        /// The 0-based character index where the token starts.
        position: usize,
    },
    /// The input ended where more was required.
    #[error("expected {expected}, found the end of the expression at character {position}")]
    UnexpectedEnd {
        /// What would have been accepted there.
        expected: Expected,
        /// The number of characters in the input.
        position: usize,
    },
    /// A name that is neither declared, a function, nor `pi`.
    #[error(
        "unknown name \"{name}\" at character {position}; {}",
        list_names(known)
    )]
    UnknownName {
        /// The name as written.
        name: String,
        /// Where it starts.
        position: usize,
        /// The names that would have been accepted in this expression.
        known: Vec<String>,
    },
    /// A call of a function the language does not have.
    #[error(
        "unknown function \"{name}\" at character {position}; the functions are {}",
        crate::expr::ops::function_names()
    )]
    UnknownFunction {
        /// The name as written.
        name: String,
        /// Where it starts.
        position: usize,
    },
    /// A known function called with the wrong number of arguments.
    #[error("{function} takes {expected} argument{}, but {found} {} given at character {position}",
        if *expected == 1 { "" } else { "s" }, if *found == 1 { "was" } else { "were" })]
    WrongArgumentCount {
        /// The function's name.
        function: &'static str,
        /// Where the function name starts.
        position: usize,
        /// How many arguments it takes.
        expected: usize,
        /// How many were given.
        found: usize,
    },
    /// A declared name that the caller does not allow in this expression (e.g. a
    /// coordinate in an expression that may only depend on parameters).
    #[error(
        "\"{name}\" cannot be used in this expression (at character {position}); {}",
        list_names(allowed)
    )]
    NameNotAllowed {
        /// The name as written.
        name: String,
        /// Where it starts.
        position: usize,
        /// The names that would have been accepted.
        allowed: Vec<String>,
    },
    /// The input is longer than the limit; `position` is the first character past it.
    #[error("the expression is too long: at most {limit} characters are allowed")]
    TooLong {
        /// The first character index past the limit (equal to `limit`).
        position: usize,
        /// The limit in characters.
        limit: usize,
    },
    /// Parentheses and function calls nested deeper than the limit.
    #[error(
        "the expression is nested too deeply at character {position}: at most {limit} levels of parentheses and function calls are allowed"
    )]
    TooDeep {
        /// Where the level past the limit opens.
        position: usize,
        /// The limit in levels.
        limit: usize,
    },
    /// The parsed expression has more nodes than the limit.
    #[error(
        "the expression is too large at character {position}: at most {limit} operations and operands are allowed"
    )]
    TooManyNodes {
        /// Where the node past the limit starts.
        position: usize,
        /// The limit in nodes.
        limit: usize,
    },
    /// A number literal that does not fit in an `f64` (e.g. `1e999`).
    #[error("the number {text} at character {position} is too large to represent")]
    NonFiniteConstant {
        /// The literal as written (shortened if very long).
        text: String,
        /// Where it starts.
        position: usize,
    },
    /// A derivative would need more new nodes than the limit.
    #[error("the derivative is too large: it would need more than {limit} new operations")]
    DerivativeTooLarge {
        /// The limit in new graph nodes per derivative, gradient or Hessian.
        limit: usize,
    },
    /// The compiled program would have more instructions than the limit.
    #[error("the compiled program is too large: more than {limit} instructions")]
    ProgramTooLarge {
        /// The limit in instructions.
        limit: usize,
    },
    /// A name declared twice, or a name that is not an identifier, or that is reserved
    /// (a function name or `pi`).
    #[error("cannot declare \"{name}\": {reason}")]
    InvalidDeclaration {
        /// The offending name.
        name: String,
        /// Why it was refused.
        reason: &'static str,
    },
    /// An output depends on a variable that is neither an input nor given a constant value.
    #[error("variable {var} is used but is neither an input nor given a constant value")]
    UnboundVariable {
        /// The variable's slot index.
        var: u32,
    },
    /// A variable appears twice in the input layout or the constants, or in both.
    #[error("variable {var} is bound twice (in the input layout or the constants)")]
    DuplicateBinding {
        /// The variable's slot index.
        var: u32,
    },
    /// The JIT was requested but is not available on this platform.
    #[error("the JIT compiler is not available: {reason}")]
    JitUnavailable {
        /// The reason given by the code generator.
        reason: String,
    },
    /// An input or output slice of the wrong length was passed to `eval`.
    #[error("expected {expected} {which}, got {found}")]
    WrongSliceLength {
        /// `"inputs"` or `"outputs"`.
        which: &'static str,
        /// The length the function was compiled for.
        expected: usize,
        /// The length passed.
        found: usize,
    },
}

impl ExprError {
    /// The 0-based character index this error refers to, for errors about the text.
    pub fn position(&self) -> Option<usize> {
        match self {
            ExprError::UnexpectedCharacter { position, .. }
            | ExprError::UnexpectedToken { position, .. }
            | ExprError::UnexpectedEnd { position, .. }
            | ExprError::UnknownName { position, .. }
            | ExprError::UnknownFunction { position, .. }
            | ExprError::WrongArgumentCount { position, .. }
            | ExprError::NameNotAllowed { position, .. }
            | ExprError::TooLong { position, .. }
            | ExprError::TooDeep { position, .. }
            | ExprError::TooManyNodes { position, .. }
            | ExprError::NonFiniteConstant { position, .. } => Some(*position),
            _ => None,
        }
    }
}

fn list_names(names: &[String]) -> String {
    if names.is_empty() {
        "no names may be used here".to_string()
    } else {
        format!("names that may be used here: {}", names.join(", "))
    }
}

/// Shortens a token's text for an error message, so that a 4000-digit number does not
/// flood the message.
pub(crate) fn shorten(text: &str) -> String {
    const MAX: usize = 24;
    let mut chars = text.chars();
    let head: String = chars.by_ref().take(MAX).collect();
    if chars.next().is_some() {
        format!("{head}…")
    } else {
        head
    }
}

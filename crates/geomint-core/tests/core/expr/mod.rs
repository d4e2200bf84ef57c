//! The expression engine of user-defined systems: the parser and its errors, symbolic
//! derivatives against central differences, simplification, the JIT against the interpreter
//! bit for bit, and hostile input.

#[allow(dead_code)]
mod common;

mod backends;
mod derivatives;
mod hostile;
mod parse;
mod simplify;

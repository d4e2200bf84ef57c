//! The integrator core's integration tests, in one binary that links the core only: methods
//! against exact solutions and the papers' experiments, the geometric properties they keep,
//! charts, stability, the adaptive reference and the expression engine.

#[allow(dead_code)]
mod common;

mod chaos;
mod chaos_map;
mod charts;
mod compositions;
mod energy_map;
mod expr;
mod orders;
mod reference;
mod stability;
mod structure;

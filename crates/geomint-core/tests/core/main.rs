//! The integrator core's integration tests, in one binary that links the core only: methods
//! against exact solutions and the papers' experiments, the geometric properties they keep,
//! charts, stability, the adaptive reference, the expression engine, Poincaré sections and
//! events, and driven systems.

#[allow(dead_code)]
mod common;

mod blanes_moan;
mod chaos;
mod chaos_map;
mod charts;
mod compositions;
mod driven;
mod energy_map;
mod expr;
mod order_conditions;
mod orders;
mod reference;
mod sections;
mod stability;
mod structure;

//! The integrator core's integration tests, in one binary that links the core only: methods
//! against exact solutions and the papers' experiments, the geometric properties they keep,
//! charts, stability, the adaptive reference, the expression engine, Poincaré sections and
//! events, driven systems, chaos indicators, every method's order conditions, and the building
//! blocks one at a time (the library's own unit tests are these: its lib builds no test target,
//! which would compile the whole core a second time).

#[allow(dead_code)]
mod common;

mod basins;
mod blanes_moan;
mod blocks;
mod chaos;
mod chaos_map;
mod charts;
mod compiled_stretch;
mod compositions;
mod driven;
mod energy_map;
mod expr;
mod indicators;
mod layers;
mod names;
mod order_conditions;
mod orders;
mod reference;
mod sections;
mod stability;
mod steps;
mod structure;
mod sweep_lanes;
mod workspace;

//! Batched steppers: runs of one method side by side, with the state of the runs in arrays of
//! one value per run that the compiler packs into SIMD registers (f64×2 on any x86-64, f64×4
//! where the CPU has AVX2, f64×8 where it has AVX-512; chosen when the run starts). Studies
//! whose cells share a method, a system and a schedule run their cells a group at a time
//! through them.
//!
//! Every lane does exactly the arithmetic of the one-run path, operation for operation and in
//! the same order, and IEEE addition, multiplication, division and square root round the same in
//! a SIMD lane as in a scalar register, so a run in a lane is bit for bit the run of the generic
//! stepper. No fused multiply-add is used, which would round once where the one-run path rounds
//! twice: rustc never contracts a·b + c into one (only `mul_add` does), whatever the target
//! features.
//!
//! - [`pendulum`]: symplectic Euler and its adjoint on the planar elastic pendulum in either
//!   chart, with the energy error at every step (paper 001's Fig. 6 map); four runs.
//! - [`tangent`]: any composition of kicks and drifts on a separable system that evaluates its
//!   forces and their Hessian in lanes ([`LaneForces`]: built-in systems with their formulas,
//!   typed-in ones through their compiled functions), with deviation vectors advanced by the
//!   method's own tangent map (chaos maps); sixteen runs, so that a step's chain of dependent
//!   operations (drift, force, kick) has several registers of independent work to overlap.

pub mod pendulum;
pub mod tangent;

pub use pendulum::{Chart, LaneKernel, Order, Start, Tally};
pub use tangent::{LaneForces, TangentLanes};

/// Steps between two looks at the budget (the one-cell path's interval).
pub const CHECK_EVERY: u64 = 1024;

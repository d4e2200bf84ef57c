//! Batched steppers: four runs of one method side by side, with the state of [`LANES`] runs in
//! arrays the compiler packs into SIMD registers (f64×2 on any x86-64, f64×4 where the CPU has
//! AVX2, chosen when the run starts). Studies whose cells share a method, a system and a
//! schedule run their cells four at a time through them.
//!
//! Every lane does exactly the arithmetic of the one-run path, operation for operation and in
//! the same order, and IEEE addition, multiplication, division and square root round the same in
//! a SIMD lane as in a scalar register, so a run in a lane is bit for bit the run of the generic
//! stepper. No fused multiply-add is used, which would round once where the one-run path rounds
//! twice: rustc never contracts a·b + c into one (only `mul_add` does), whatever the target
//! features.
//!
//! - [`pendulum`]: symplectic Euler and its adjoint on the planar elastic pendulum in either
//!   chart, with the energy error at every step (paper 001's Fig. 6 map).
//! - [`tangent`]: any composition of kicks and drifts on a separable system that evaluates its
//!   forces and their Hessian in lanes ([`LaneForces`]), with deviation vectors advanced by the
//!   method's own tangent map (chaos maps).

pub mod pendulum;
pub mod tangent;

pub use pendulum::{Chart, LaneKernel, Order, Start, Tally};
pub use tangent::{LaneForces, TangentLanes};

/// Cells integrated side by side.
pub const LANES: usize = 4;
/// One value per lane.
pub type Lane = [f64; LANES];
/// Steps between two looks at the budget (the one-cell path's interval).
pub const CHECK_EVERY: u64 = 1024;

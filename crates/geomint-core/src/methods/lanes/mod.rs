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
//! - [`tangent`]: any composition of kicks and drifts on a separable system that evaluates its
//!   forces and their Hessian in lanes ([`LaneForces`]: built-in systems with their formulas,
//!   typed-in ones through their compiled functions), with deviation vectors advanced by the
//!   method's own tangent map (chaos maps); sixteen runs, so that a step's chain of dependent
//!   operations (drift, force, kick) has several registers of independent work to overlap.
//! - [`runs`]: plain runs (no deviation vectors) of compositions of kicks, drifts and exact
//!   damping flows, sixteen side by side, as the one-run stepper takes its stretches; with one
//!   system per lane (`system::lanes::EachLane`) for sweeps over parameters and the step. A
//!   system with compiled steps runs its stretches through code compiled for the lanes instead
//!   (f64×2 vectors, whatever the CPU), with the same bits.

pub mod runs;
pub mod tangent;

pub use tangent::{LaneForces, TangentLanes};

/// The instruction set a batched stepper's code is built for. Lanes start with the widest the
/// CPU has ([`Isa::detect`]); another one the CPU has may be chosen (`with_isa`), e.g.
/// `Portable` to compute what a CPU without AVX2 computes: the numbers are the same bits in
/// every one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// What every CPU of the target has (f64×2 on x86-64).
    Portable,
    /// f64×4 registers.
    Avx2,
    /// f64×8 registers.
    Avx512,
}

impl Isa {
    /// The widest instruction set this CPU has.
    pub fn detect() -> Self {
        [Isa::Avx512, Isa::Avx2]
            .into_iter()
            .find(|isa| isa.available())
            .unwrap_or(Isa::Portable)
    }

    /// Whether this CPU runs code built for this instruction set.
    pub fn available(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            match self {
                Isa::Portable => true,
                Isa::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
                // Code built with AVX-512F may also use AVX2 and FMA instructions (rustc enables
                // the features it implies), so all three must be there.
                Isa::Avx512 => {
                    std::arch::is_x86_feature_detected!("avx512f")
                        && std::arch::is_x86_feature_detected!("avx2")
                        && std::arch::is_x86_feature_detected!("fma")
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self == Isa::Portable
        }
    }
}

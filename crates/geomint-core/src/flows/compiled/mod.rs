//! Stretches of steps compiled to native code for the system that runs them: the splitting
//! composer's fused stretch between two samples (see `Splitting::advance`), or a Runge–Kutta
//! method's steps, as one function with the system's forces written into the step rather than
//! called through a pointer. The methods build them (`codegen`), for one run and for the plain
//! runs' lanes (`methods::lanes::runs`), from what a system gives
//! (`MechanicalSystem::compiled_forces`): its forces as programs ([`ForcePrograms`]) and the
//! cache its code is kept in ([`CompiledSteps`]). A typed-in system gives the programs it was
//! compiled from; the built-in Hénon–Heiles system its force traced into a program
//! (`expr::trace`). The other built-in systems run the generic steps, compiled with the program.
//!
//! The compiled code does the stepper's arithmetic operation for operation (each `axpy` as a
//! product and a sum, no fused multiply-add, the force cache and its count), so it gives the
//! same bits. A splitting stretch whose state stops being finite is reported, and the composer
//! runs it again step by step as it would have; Runge–Kutta steps stop after the first such step,
//! as the stepper's do.

use std::sync::Arc;

use super::SubFlow;
use super::LANES;
use crate::expr::jit::OwnedModule;

mod cache;
mod codegen;

pub use cache::{CompiledForces, CompiledSteps};
pub use codegen::ForcePrograms;

/// What a stretch does: the flows of one step with their fractions of h, the per-flow
/// coefficients for h (the damping's c = 1 − e^{−rτ}, and d), and the seam that fuses the last
/// flow of a step with the first of the next (its time and coefficients), if they fuse.
#[derive(Clone, Copy, Debug)]
pub struct StretchPlan<'a> {
    /// The flows of one step and their fractions of h.
    pub flows: &'a [(SubFlow, f64)],
    /// Per flow, its coefficients for this h.
    pub coefficients: &'a [(f64, f64)],
    /// The step.
    pub h: f64,
    /// The fused seam's time and coefficients; `None` for a method whose last and first flows
    /// do not fuse (velocity Verlet's θ-kicks, of a damped system), whose steps are taken whole.
    pub seam: Option<(f64, (f64, f64))>,
}

/// `stretch(q, p, grad, counters, n)`: n ≥ 1 steps from (q, p) in place, with the force cache
/// `grad` and `counters` = [whether `grad` holds ∇V(q) (0 or 1), force evaluations so far],
/// both updated. Returns the steps taken: a splitting stretch n, or 0 if the state did not sum
/// to a finite number after some step (the arrays then hold no meaningful state); Runge–Kutta
/// steps up to and including the first whose state does not. Code for lanes returns instead the
/// mask of its lanes whose state did not (see [`CompiledStretch::run_lanes`]).
pub type StretchFn = unsafe extern "C" fn(*mut f64, *mut f64, *mut f64, *mut u64, u64) -> u64;

/// Native code for a system's stretches of one plan.
#[derive(Debug)]
pub struct CompiledStretch {
    code: StretchFn,
    dimension: usize,
    /// Runs one call takes: 1, or a group of lanes of arrays of [`LANES`] (a divisor of it).
    lanes: usize,
    /// Owns the code's memory.
    _module: OwnedModule,
}

impl CompiledStretch {
    /// Code built for states of `dimension` components, owned by `module`.
    ///
    /// # Safety
    /// `code` must be a function of [`StretchFn`]'s contract that reads and writes `dimension`
    /// components of its arrays, and live as long as `module`.
    pub(crate) unsafe fn new(
        code: StretchFn,
        dimension: usize,
        lanes: usize,
        module: OwnedModule,
    ) -> Self {
        CompiledStretch {
            code,
            dimension,
            lanes,
            _module: module,
        }
    }

    /// Runs up to `n ≥ 1` steps in place and returns the steps taken ([`StretchFn`]). One step
    /// of a splitting's stretch is a whole step, its last flow unfused, as the stepper's `step`
    /// takes it: a run that watches every step takes them here too.
    pub fn run(
        &self,
        q: &mut [f64],
        p: &mut [f64],
        grad: &mut [f64],
        grad_valid: &mut bool,
        force_evaluations: &mut u64,
        n: u64,
    ) -> u64 {
        let d = self.dimension;
        assert!(q.len() == d && p.len() == d && grad.len() == d && n >= 1);
        assert_eq!(self.lanes, 1, "code for one run");
        let mut counters = [u64::from(*grad_valid), *force_evaluations];
        // SAFETY: the arrays have the dimension the code was built for (checked above).
        let taken = unsafe { self.call([q, p, grad], 0, &mut counters, n) };
        *grad_valid = counters[0] != 0;
        *force_evaluations = counters[1];
        taken
    }

    /// Calls the code on q, p and the force cache from component `start` on.
    ///
    /// # Safety
    /// The code must read and write only components of the arrays from `start` on.
    unsafe fn call(
        &self,
        [q, p, grad]: [&mut [f64]; 3],
        start: usize,
        counters: &mut [u64; 2],
        n: u64,
    ) -> u64 {
        // SAFETY: the caller keeps the code within the arrays, and `self` keeps it alive.
        unsafe {
            (self.code)(
                q.as_mut_ptr().add(start),
                p.as_mut_ptr().add(start),
                grad.as_mut_ptr().add(start),
                counters.as_mut_ptr(),
                n,
            )
        }
    }

    /// Runs `n ≥ 1` steps of [`LANES`] runs side by side in place (code built for lanes: the
    /// arrays hold component i of lane l at i·LANES + l) and says per lane whether its state
    /// failed to sum to a finite number after some step. Every lane takes all n steps.
    pub fn run_lanes(
        &self,
        q: &mut [f64],
        p: &mut [f64],
        grad: &mut [f64],
        grad_valid: &mut bool,
        force_evaluations: &mut u64,
        n: u64,
    ) -> [bool; LANES] {
        let d = self.dimension;
        assert!(q.len() == d && p.len() == d && grad.len() == d && n >= 1);
        let group_lanes = self.lanes;
        assert!(group_lanes > 1 && LANES.is_multiple_of(group_lanes) && d.is_multiple_of(LANES));
        let mut counters = [0; 2];
        let mut left = [false; LANES];
        for group in (0..LANES).step_by(group_lanes) {
            // Each group starts from the same cache and count; all end with the same.
            counters = [u64::from(*grad_valid), *force_evaluations];
            // SAFETY: the code reads and writes the group's lanes, `group` to `group` +
            // group_lanes − 1, of arrays of LANES lanes and `dimension` components (checked
            // above).
            let mask =
                unsafe { self.call([&mut *q, &mut *p, &mut *grad], group, &mut counters, n) };
            for l in 0..group_lanes {
                left[group + l] = mask & (1 << l) != 0;
            }
        }
        *grad_valid = counters[0] != 0;
        *force_evaluations = counters[1];
        left
    }
}

/// A compiled stretch shared by the runs of one system and plan.
pub type SharedStretch = Arc<CompiledStretch>;

/// Steps a system's runs take on the generic path before its compiled code is built: a build
/// takes 0.25–0.75 ms per stepper (the `custom` bench), about what 2·10⁴ generic steps cost, so
/// short work never pays for one. The code gives the generic path's bits, so a run may switch
/// at any stretch.
pub const COMPILE_AFTER: u64 = 20_000;

/// How often a run without compiled code reports its generic steps to the system (and so asks
/// again): rarely enough to cost nothing, often enough for short runs (a sweep's cells) to add
/// up to [`COMPILE_AFTER`].
const ASK_EVERY: u64 = 2_048;

/// A run's compiled code, asked for as the run goes: at its first stretch (another run of the
/// same system, a sweep's earlier cell, may have had it built), then every [`ASK_EVERY`] steps
/// taken without it, until the system has it.
#[derive(Clone, Debug, Default)]
pub struct LazyCode {
    code: Option<SharedStretch>,
    asked: bool,
    pending: u64,
}

impl LazyCode {
    /// Forgets the code (the step size changed).
    pub fn reset(&mut self) {
        *self = LazyCode::default();
    }

    /// The code for a stretch of `n` steps, or `None`, in which case the generic path takes them.
    /// `ask(steps)` asks the system, telling it the generic steps taken since the last ask, this
    /// stretch's included.
    pub fn get(
        &mut self,
        n: u64,
        ask: impl FnOnce(u64) -> Option<SharedStretch>,
    ) -> Option<&SharedStretch> {
        if self.code.is_none() {
            // This stretch counts as generic when the system is asked before it: a run shorter
            // than ASK_EVERY then still reports its first stretch.
            self.pending = self.pending.saturating_add(n);
            if !self.asked || self.pending >= ASK_EVERY {
                self.code = ask(self.pending);
                self.asked = true;
                self.pending = 0;
            }
        }
        // Borrowed, not cloned: a run that watches every step asks at every step.
        self.code.as_ref()
    }
}

//! Which compiled steps a system has: the code built from its [`ForcePrograms`] for a
//! splitting's stretches and for Runge–Kutta steps, kept per system for the plan last asked for
//! ([`CompiledSteps`]), and built once the system's runs have taken [`COMPILE_AFTER`] steps
//! without it. A method asks through [`CompiledForces`], what the system gives it
//! (`MechanicalSystem::compiled_forces`): its programs and its cache.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use super::codegen::{self, ForcePrograms};
use super::{CompiledStretch, SharedStretch, StretchPlan, COMPILE_AFTER};
use crate::flows::{SubFlow, Tableau};

/// A system's forces as programs, and the cache of the code methods build from them. The cache
/// is keyed by the plan or tableau only: a system gives the same programs with its cache every
/// time (a system's programs are fixed when it is made).
pub struct CompiledForces<'a> {
    /// The programs and constants the code is built from.
    pub programs: ForcePrograms<'a>,
    /// Where the system keeps its code.
    pub code: &'a CompiledSteps,
}

impl CompiledForces<'_> {
    /// The compiled stretch of the splitting `plan` for one run, once the system's runs have
    /// taken `steps` more steps without it (see [`CompiledSteps`]).
    pub fn stretch(&self, plan: &StretchPlan, steps: u64) -> Option<SharedStretch> {
        let key = || plan_key(plan);
        self.code.cached(&self.code.stretch, key, steps, || {
            codegen::compile(plan, &self.programs)
        })
    }

    /// The compiled stretch of `plan` over the plain runs' lanes (`methods::lanes::runs`).
    pub fn lanes_stretch(&self, plan: &StretchPlan, steps: u64) -> Option<SharedStretch> {
        let key = || plan_key(plan);
        self.code.cached(&self.code.lanes_stretch, key, steps, || {
            codegen::compile_lanes(plan, &self.programs)
        })
    }

    /// The compiled steps of the explicit Runge–Kutta method `tableau` at step `h`.
    pub fn steps(&self, tableau: &Tableau, h: f64, steps: u64) -> Option<SharedStretch> {
        let key = || {
            std::iter::once(0)
                .chain(
                    tableau
                        .a
                        .iter()
                        .flat_map(|row| row.iter().map(|a| a.to_bits())),
                )
                .chain(tableau.b.iter().map(|b| b.to_bits()))
                .chain([h.to_bits()])
        };
        self.code.cached(&self.code.stretch, key, steps, || {
            codegen::compile_runge_kutta(tableau, h, &self.programs)
        })
    }
}

/// What a splitting's code is built from: its flows and fractions, the coefficients, h and the
/// seam (only its τ and c enter the code).
fn plan_key<'a>(plan: &'a StretchPlan<'a>) -> impl Iterator<Item = u64> + 'a {
    plan.flows
        .iter()
        .flat_map(|&(flow, fraction)| [flow_code(flow), fraction.to_bits()])
        .chain(plan.coefficients.iter().map(|&(c, _)| c.to_bits()))
        .chain([plan.h.to_bits()])
        .chain(match plan.seam {
            Some((tau, (c, _))) => [1, tau.to_bits(), c.to_bits()],
            None => [0; 3],
        })
}

/// The last code compiled for a system, and what it was compiled for.
type Slot = Mutex<Option<(Vec<u64>, Option<SharedStretch>)>>;

/// A system's compiled steps: the code last built for a plan (the cells of a sweep share it),
/// for one run and for the plain runs' lanes, and the steps its runs took on the generic path
/// while the code was missing.
#[derive(Default)]
pub struct CompiledSteps {
    stretch: Slot,
    lanes_stretch: Slot,
    generic_steps: AtomicU64,
}

impl std::fmt::Debug for CompiledSteps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CompiledSteps")
            .field("generic_steps", &self.generic_steps)
            .finish_non_exhaustive()
    }
}

impl CompiledSteps {
    /// Whether one run's code was built for the plan last asked for.
    pub fn stretch_built(&self) -> bool {
        built(&self.stretch)
    }

    /// Whether the lanes' code was built for the plan last asked for.
    pub fn lanes_built(&self) -> bool {
        built(&self.lanes_stretch)
    }

    /// The code `compile` builds, kept for `key` until another key asks (the cells of a sweep
    /// share it). Without it, `steps` more steps were run on the generic path, and the code is
    /// built once the system's runs have taken [`COMPILE_AFTER`] such steps. `None` until then,
    /// and when the code cannot be built (a flow it does not take). A lookup allocates nothing.
    fn cached<K: Iterator<Item = u64>>(
        &self,
        slot: &Slot,
        key: impl Fn() -> K,
        steps: u64,
        compile: impl FnOnce() -> Result<CompiledStretch, String>,
    ) -> Option<SharedStretch> {
        if let Ok(last) = slot.lock() {
            if let Some((_, code)) = last.as_ref().filter(|(k, _)| k.iter().copied().eq(key())) {
                return code.clone();
            }
        }
        let waited = self.generic_steps.fetch_add(steps, Ordering::Relaxed) + steps;
        if waited < COMPILE_AFTER {
            return None;
        }
        let code = compile().ok().map(Arc::new);
        if let Ok(mut last) = slot.lock() {
            *last = Some((key().collect(), code.clone()));
        }
        code
    }
}

/// Whether `slot` holds code.
fn built(slot: &Slot) -> bool {
    slot.lock()
        .is_ok_and(|last| last.as_ref().is_some_and(|(_, code)| code.is_some()))
}

/// A flow's kind as a number, for the stretch's key.
fn flow_code(flow: SubFlow) -> u64 {
    match flow {
        SubFlow::Drift => 1,
        SubFlow::Kick => 2,
        SubFlow::Damp => 3,
        SubFlow::KickDamp => 4,
        SubFlow::MomentumRk => 5,
        SubFlow::DampedKick(theta) => 6 + theta.value().to_bits(),
    }
}

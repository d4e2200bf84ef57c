//! Which compiled steps a system has: its code for a splitting's stretches and for Runge–Kutta
//! steps (`stretch/` builds it), kept per system for the plan last asked for ([`CompiledSteps`]),
//! and built once the system's runs have taken
//! [`COMPILE_AFTER`](crate::flows::compiled::COMPILE_AFTER) steps without it. A typed-in system
//! compiles its programs; a built-in one ([`BuiltInSteps`]) the program of its force, traced from
//! the Rust code that computes its `f64` force (`expr::trace`), so that both give the same bits.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use super::mass::InverseMass;
use super::stretch;
use super::system::{Compiled, DampingModel, EnergyModel};
use crate::expr::program::Program;
use crate::flows::compiled::{CompiledStretch, SharedStretch, StretchPlan, COMPILE_AFTER};
use crate::flows::SubFlow;
use crate::flows::Tableau;

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
    /// The compiled stretch of `plan` for the system of `parts` (see [`Self::cached`]).
    pub(super) fn stretch<'p>(
        &self,
        plan: &StretchPlan,
        steps: u64,
        parts: impl FnOnce() -> Option<stretch::Parts<'p>>,
    ) -> Option<SharedStretch> {
        let key = || plan_key(plan);
        self.cached(&self.stretch, key, steps, parts, |parts| {
            stretch::compile(plan, parts)
        })
    }

    /// The compiled stretch of `plan` over the plain runs' lanes (see [`Self::cached`]).
    pub(super) fn lanes_stretch<'p>(
        &self,
        plan: &StretchPlan,
        steps: u64,
        parts: impl FnOnce() -> Option<stretch::Parts<'p>>,
    ) -> Option<SharedStretch> {
        let key = || plan_key(plan);
        self.cached(&self.lanes_stretch, key, steps, parts, |parts| {
            stretch::compile_lanes(plan, parts)
        })
    }

    /// The compiled steps of `tableau` at step `h` (see [`Self::cached`]).
    pub(super) fn steps<'p>(
        &self,
        tableau: &Tableau,
        h: f64,
        steps: u64,
        parts: impl FnOnce() -> Option<stretch::Parts<'p>>,
    ) -> Option<SharedStretch> {
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
        self.cached(&self.stretch, key, steps, parts, |parts| {
            stretch::compile_runge_kutta(tableau, h, parts)
        })
    }

    /// Whether one run's code was built for the plan last asked for.
    pub fn stretch_built(&self) -> bool {
        built(&self.stretch)
    }

    /// Whether the lanes' code was built for the plan last asked for.
    pub fn lanes_built(&self) -> bool {
        built(&self.lanes_stretch)
    }

    /// The code `compile` builds for the system's `parts`, kept for `key` until another key asks
    /// (the cells of a sweep share it). Without it, `steps` more steps were run on the generic
    /// path, and the code is built once the system's runs have taken
    /// [`COMPILE_AFTER`](crate::flows::compiled::COMPILE_AFTER) such steps. `None`
    /// until then, and when the system is one the compiled steps do not take (`parts` gives
    /// none: a general H or damping, a driven system's projector damping or Runge–Kutta steps)
    /// or the code cannot be built. A lookup allocates nothing.
    fn cached<'p, K: Iterator<Item = u64>>(
        &self,
        slot: &Slot,
        key: impl Fn() -> K,
        steps: u64,
        parts: impl FnOnce() -> Option<stretch::Parts<'p>>,
        compile: impl FnOnce(&stretch::Parts) -> Result<CompiledStretch, String>,
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
        let code = parts().and_then(|parts| compile(&parts).ok().map(Arc::new));
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

/// A built-in separable system's compiled steps: its force as a program of q, traced from the
/// code of its `f64` force, with M = I and conformal damping at `rate` (or none).
#[derive(Debug)]
pub struct BuiltInSteps {
    /// The coordinates.
    n: usize,
    /// ∇V; `None` where the system's code was not traced (see `expr::trace`).
    gradient: Option<Program>,
    inverse_mass: InverseMass,
    rate: f64,
    code: CompiledSteps,
}

impl BuiltInSteps {
    /// The steps of a system of `n` coordinates with unit mass, force `gradient` and conformal
    /// damping at `rate` (0: undamped).
    pub(in crate::systems) fn new(n: usize, gradient: Option<Program>, rate: f64) -> Self {
        BuiltInSteps {
            n,
            gradient,
            inverse_mass: InverseMass::Unit,
            rate,
            code: CompiledSteps::default(),
        }
    }

    /// The compiled stretch of `plan` (see [`CompiledSteps::stretch`]).
    pub(in crate::systems) fn stretch(
        &self,
        plan: &StretchPlan,
        steps: u64,
    ) -> Option<SharedStretch> {
        self.code.stretch(plan, steps, || self.parts())
    }

    /// The compiled steps of `tableau` at step `h` (see [`CompiledSteps::steps`]).
    pub(in crate::systems) fn steps(
        &self,
        tableau: &Tableau,
        h: f64,
        steps: u64,
    ) -> Option<SharedStretch> {
        self.code.steps(tableau, h, steps, || self.parts())
    }

    /// Whether code was built for the plan last asked for.
    pub(in crate::systems) fn built(&self) -> bool {
        self.code.stretch_built()
    }

    fn parts(&self) -> Option<stretch::Parts<'_>> {
        Some(stretch::Parts {
            n: self.n,
            clock: None,
            gradient: self.gradient.as_ref()?,
            inverse_mass: &self.inverse_mass,
            projector: None,
            rate: self.rate,
        })
    }
}

impl Compiled {
    /// The compiled stretch of `plan` (see [`CompiledSteps::stretch`]).
    pub(super) fn stretch(&self, plan: &StretchPlan, steps: u64) -> Option<SharedStretch> {
        self.compiled_steps.stretch(plan, steps, || self.parts())
    }

    /// The compiled stretch of `plan` over the plain runs' lanes.
    pub(super) fn lanes_stretch(&self, plan: &StretchPlan, steps: u64) -> Option<SharedStretch> {
        self.compiled_steps
            .lanes_stretch(plan, steps, || self.parts())
    }

    /// The compiled steps of `tableau` at step `h`.
    pub(super) fn steps(&self, tableau: &Tableau, h: f64, steps: u64) -> Option<SharedStretch> {
        self.compiled_steps
            .steps(tableau, h, steps, || self.parts())
    }

    /// What compiled steps need of the system, if it is one they take.
    fn parts(&self) -> Option<stretch::Parts<'_>> {
        let EnergyModel::Separable {
            gradient,
            inverse_mass,
            ..
        } = &self.energy
        else {
            return None;
        };
        let projector = match (&self.damping, &self.damping_matrix) {
            (DampingModel::None | DampingModel::Conformal { .. }, _) => None,
            // A driven system's projector is left to the generic path.
            (DampingModel::Projector { .. }, Some(matrix)) if self.clock.is_none() => {
                Some(matrix.program())
            }
            _ => return None,
        };
        Some(stretch::Parts {
            n: self.n,
            clock: self.clock,
            gradient: gradient.program(),
            inverse_mass,
            projector,
            rate: self.damping.rate(),
        })
    }
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

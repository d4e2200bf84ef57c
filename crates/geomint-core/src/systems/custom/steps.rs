//! Which compiled steps a typed-in system has: its code for a splitting's stretches and for
//! Runge–Kutta steps (`stretch/` builds it), kept per system for the plan last asked for, and
//! built once the system's runs have taken
//! [`COMPILE_AFTER`](crate::flows::compiled::COMPILE_AFTER) steps without it.

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};

use super::stretch;
use super::system::{Compiled, DampingModel, EnergyModel};
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

impl Compiled {
    /// The compiled stretch of `plan` (see [`Self::cached`]).
    pub(super) fn stretch(&self, plan: &StretchPlan, steps: u64) -> Option<SharedStretch> {
        let key = || plan_key(plan);
        self.cached(&self.stretch, key, steps, |parts| {
            stretch::compile(plan, parts)
        })
    }

    /// The compiled stretch of `plan` over the plain runs' lanes (see [`Self::cached`]).
    pub(super) fn lanes_stretch(&self, plan: &StretchPlan, steps: u64) -> Option<SharedStretch> {
        let key = || plan_key(plan);
        self.cached(&self.lanes_stretch, key, steps, |parts| {
            stretch::compile_lanes(plan, parts)
        })
    }

    /// The compiled steps of `tableau` at step `h` (see [`Self::cached`]).
    pub(super) fn steps(&self, tableau: &Tableau, h: f64, steps: u64) -> Option<SharedStretch> {
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
        self.cached(&self.stretch, key, steps, |parts| {
            stretch::compile_runge_kutta(tableau, h, parts)
        })
    }

    /// The code `compile` builds for the system's parts, kept for `key` until another key asks
    /// (the cells of a sweep share it). Without it, `steps` more steps were run on the generic
    /// path, and the code is built once the system's runs have taken
    /// [`COMPILE_AFTER`](crate::flows::compiled::COMPILE_AFTER) such steps. `None`
    /// until then, and when the system is one the compiled steps do not take (a general H or
    /// damping, a driven system's projector damping or Runge–Kutta steps) or the code cannot be
    /// built. A lookup allocates nothing.
    fn cached<K: Iterator<Item = u64>>(
        &self,
        slot: &Mutex<Option<(Vec<u64>, Option<SharedStretch>)>>,
        key: impl Fn() -> K,
        steps: u64,
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
        let code = self
            .parts()
            .and_then(|parts| compile(&parts).ok().map(Arc::new));
        if let Ok(mut last) = slot.lock() {
            *last = Some((key().collect(), code.clone()));
        }
        code
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

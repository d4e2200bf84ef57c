//! What a system gives the methods' compiled steps (`flows::compiled`): its forces as programs
//! and the cache of the code built from them. A typed-in system gives the programs it was
//! compiled from; a built-in one ([`BuiltInSteps`]) the program of its force, traced from the
//! Rust code that computes its `f64` force (`expr::trace`), so that both give the same bits.

use super::mass::InverseMass;
use super::system::{Compiled, DampingModel, EnergyModel};
use crate::expr::program::Program;
use crate::flows::compiled::{CompiledForces, CompiledSteps, ForcePrograms};

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

    /// Its force's program and its code, when its force was traced.
    pub(in crate::systems) fn forces(&self) -> Option<CompiledForces<'_>> {
        Some(CompiledForces {
            programs: ForcePrograms {
                n: self.n,
                clock: None,
                gradient: self.gradient.as_ref()?,
                inverse_mass: &self.inverse_mass,
                projector: None,
                rate: self.rate,
            },
            code: &self.code,
        })
    }

    /// Whether code was built for the plan last asked for.
    pub(in crate::systems) fn built(&self) -> bool {
        self.code.stretch_built()
    }
}

impl Compiled {
    /// Its programs and its code, if it is a system compiled steps take (a separable H, and no
    /// damping, conformal damping or an autonomous system's projector damping).
    pub(super) fn compiled_forces(&self) -> Option<CompiledForces<'_>> {
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
        Some(CompiledForces {
            programs: ForcePrograms {
                n: self.n,
                clock: self.clock,
                gradient: gradient.program(),
                inverse_mass,
                projector,
                rate: self.damping.rate(),
            },
            code: &self.compiled_steps,
        })
    }
}

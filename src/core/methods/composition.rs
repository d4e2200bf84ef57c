//! Symmetric compositions that raise the order of a symmetric second-order method.
//!
//! The triple jump Φ_{w₁h} ∘ Φ_{w₀h} ∘ Φ_{w₁h} with w₁ = 1/(2 − 2^{1/3}), w₀ = 1 − 2w₁ is of
//! order 4 (Creutz & Gocksch 1989, Yoshida 1990; Hairer–Lubich–Wanner, Geometric Numerical
//! Integration, II.4 eq. (4.4)). The middle weight is negative; the damping sub-flows then run
//! backwards in time exactly, so the composition stays conformal symplectic.
//!
//! Splitting bases are composed as data (`splitting::compose`, which also fuses adjacent flows);
//! other bases (cimp, csv2, implicit_midpoint) are wrapped by [`Composed`].

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

use crate::core::error::StepError;
use crate::core::flows::Tangent;
use crate::core::run::Stepper;
use crate::core::system::{MechanicalSystem, State};

/// The triple-jump weights (w₁, w₀, w₁).
pub fn triple_jump_weights() -> [f64; 3] {
    let w1 = 1.0 / (2.0 - 2f64.cbrt());
    [w1, 1.0 - 2.0 * w1, w1]
}

/// A base stepper applied with sub-steps w_k h.
pub struct Composed<M> {
    base: M,
    weights: Vec<f64>,
}

impl<M> Composed<M> {
    /// Composes `base` with `weights` (which should sum to one).
    pub fn new(base: M, weights: Vec<f64>) -> Self {
        Self { base, weights }
    }
}

impl<S: MechanicalSystem, M: Stepper<S>> Stepper<S> for Composed<M>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        for &w in &self.weights {
            self.base.step(sys, z, w * h)?;
        }
        Ok(())
    }

    fn force_evaluations(&self) -> u64 {
        self.base.force_evaluations()
    }

    fn check_interval(&self) -> u64 {
        self.base.check_interval()
    }

    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        tangent: &mut Tangent,
    ) -> Result<(), StepError> {
        for &w in &self.weights {
            self.base.step_tangent(sys, z, w * h, tangent)?;
        }
        Ok(())
    }
}

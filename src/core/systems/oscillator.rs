//! The damped harmonic oscillator q'' + 2γq' + ω²q = 0 (paper 003 eq. 2.5): T = p²/2,
//! V = ω²q²/2, p' = −ω²q − 2γp, with its exact solution in all three damping regimes.

use nalgebra::{DMatrix, U1};

use crate::core::system::{MechanicalSystem, State, Structure, Vector};

/// The damped harmonic oscillator.
#[derive(Clone, Debug, PartialEq)]
pub struct HarmonicOscillator {
    /// Angular frequency ω.
    pub omega: f64,
    /// Damping coefficient γ (ε = 2γ).
    pub gamma: f64,
}

impl HarmonicOscillator {
    /// The exact (q, p) at time t from (q0, p0). With a = q0, b = (p0 + γq0) the solution is
    /// e^{−γt}(a C(t) + b S(t)) where C, S are cos βt and sin(βt)/β (under-damped, β² = ω² − γ²),
    /// 1 and t (critical), cosh κt and sinh(κt)/κ (over-damped, κ² = γ² − ω²).
    pub fn solution(&self, t: f64, q0: f64, p0: f64) -> (f64, f64) {
        let g = self.gamma;
        let d = self.omega * self.omega - g * g;
        // e^{−γt}·(C, S, C', S'); in the over-damped case from the two real exponents
        // λ± = γ ± κ (λ₋ = ω²/(γ + κ) without cancellation), so that e^{−γt} cosh κt does not
        // overflow for large κt.
        let (c, s, c_dot, s_dot) = if d > 0.0 {
            let beta = d.sqrt();
            let decay = (-g * t).exp();
            let (sn, cs) = (beta * t).sin_cos();
            (
                decay * cs,
                decay * sn / beta,
                -decay * beta * sn,
                decay * cs,
            )
        } else if d < 0.0 {
            let kappa = (-d).sqrt();
            let slow = (-(self.omega * self.omega / (g + kappa)) * t).exp();
            let fast = (-(g + kappa) * t).exp();
            let ch = 0.5 * (slow + fast);
            let sh = 0.5 * (slow - fast);
            (ch, sh / kappa, kappa * sh, ch)
        } else {
            let decay = (-g * t).exp();
            (decay, decay * t, 0.0, decay)
        };
        let (a, b) = (q0, p0 + g * q0);
        let q = a * c + b * s;
        let p = a * c_dot + b * s_dot - g * q;
        (q, p)
    }
}

impl MechanicalSystem for HarmonicOscillator {
    type Dim = U1;
    fn dim(&self) -> U1 {
        U1
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: true,
            conformal_damping: true,
        }
    }
    fn kinetic(&self, _q: &Vector<U1>, p: &Vector<U1>) -> f64 {
        0.5 * p[0] * p[0]
    }
    fn potential(&self, q: &Vector<U1>) -> f64 {
        0.5 * self.omega * self.omega * q[0] * q[0]
    }
    #[inline]
    fn grad_potential(&self, q: &Vector<U1>, out: &mut Vector<U1>) {
        out[0] = self.omega * self.omega * q[0];
    }
    #[inline]
    fn velocity(&self, _q: &Vector<U1>, p: &Vector<U1>, out: &mut Vector<U1>) {
        out[0] = p[0];
    }
    fn damping_rate(&self) -> f64 {
        2.0 * self.gamma
    }
    fn hess_potential(&self, _q: &Vector<U1>, out: &mut DMatrix<f64>) -> u64 {
        out[(0, 0)] = self.omega * self.omega;
        0
    }
    fn exact(&self, t: f64, start: &State<U1>) -> Option<State<U1>> {
        let (q, p) = self.solution(t, start.q[0], start.p[0]);
        Some(State::from_slices(U1, &[q], &[p]))
    }
}

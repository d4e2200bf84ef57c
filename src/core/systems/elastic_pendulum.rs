//! The elastic 3-D pendulum with damping along the spring (paper 000 Sec. 6.2, eq. 16): a mass m on
//! a spring of stiffness k and rest length l, gravity (0, 0, −g),
//! V = k/2 (l − |q|)² + m g q_z, M = m I, D(q) = q qᵀ/|q|².
//!
//! Only the radial momentum is damped, at the rate ε/m; D is singular (rank one). Both gravity
//! and the spring are invariant under rotations about the z axis, and so is D, so
//! J₃ = (q × p)_z is conserved for every ε.

use nalgebra::{DMatrix, U3};

use crate::core::system::{MechanicalSystem, Structure, Vector};

/// The damped elastic 3-D pendulum.
#[derive(Clone, Debug, PartialEq)]
pub struct ElasticPendulum3d {
    /// Mass.
    pub m: f64,
    /// Spring stiffness.
    pub k: f64,
    /// Spring rest length.
    pub l: f64,
    /// Gravitational acceleration (acting along −z).
    pub g: f64,
    /// Damping strength ε of the radial dissipation.
    pub epsilon: f64,
}

impl MechanicalSystem for ElasticPendulum3d {
    type Dim = U3;
    fn dim(&self) -> U3 {
        U3
    }
    fn structure(&self) -> Structure {
        Structure {
            separable_constant_mass: true,
            conformal_damping: false,
        }
    }
    fn kinetic(&self, _q: &Vector<U3>, p: &Vector<U3>) -> f64 {
        0.5 * p.norm_squared() / self.m
    }
    fn potential(&self, q: &Vector<U3>) -> f64 {
        let stretch = self.l - q.norm();
        0.5 * self.k * stretch * stretch + self.m * self.g * q[2]
    }
    #[inline]
    fn grad_potential(&self, q: &Vector<U3>, out: &mut Vector<U3>) {
        let r = q.norm();
        let c = self.k * (1.0 - self.l / r);
        out[0] = c * q[0];
        out[1] = c * q[1];
        out[2] = c * q[2] + self.m * self.g;
    }
    #[inline]
    fn velocity(&self, _q: &Vector<U3>, p: &Vector<U3>, out: &mut Vector<U3>) {
        let inv_m = 1.0 / self.m;
        out[0] = p[0] * inv_m;
        out[1] = p[1] * inv_m;
        out[2] = p[2] * inv_m;
    }
    fn damping_rate(&self) -> f64 {
        self.epsilon / self.m
    }
    #[inline]
    fn project_damped(&self, q: &Vector<U3>, v: &Vector<U3>, out: &mut Vector<U3>) {
        let c = q.dot(v) / q.norm_squared();
        out[0] = c * q[0];
        out[1] = c * q[1];
        out[2] = c * q[2];
    }
    fn hess_potential(&self, q: &Vector<U3>, out: &mut DMatrix<f64>) -> u64 {
        // ∇V = k(1 − l/r) q + m g e_z, so ∇²V = k(1 − l/r) I + k l q qᵀ / r³.
        let r = q.norm();
        let a = self.k * (1.0 - self.l / r);
        let b = self.k * self.l / (r * r * r);
        for i in 0..3 {
            for j in 0..3 {
                out[(i, j)] = b * q[i] * q[j] + if i == j { a } else { 0.0 };
            }
        }
        0
    }
    fn invariant_names(&self) -> &'static [&'static str] {
        &["J3"]
    }
    fn invariants(&self, _t: f64, q: &Vector<U3>, p: &Vector<U3>, out: &mut [f64]) {
        out[0] = q[0] * p[1] - q[1] * p[0];
    }
}

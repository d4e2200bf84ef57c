//! Typed-in separable systems in the chaos maps' SIMD lanes: ∇V and ∇²V are the programs of the
//! system's one-run functions compiled over all the lanes at once ([`LaneCode`]), each lane's
//! arithmetic the scalar code's, so every lane's numbers are that path's; where that code cannot
//! be built, each lane calls the one-run functions. M⁻¹ is the one-run path's arithmetic. The
//! rest of the step (the drifts, the kicks and the deviation vectors' tangent maps) is the
//! lanes' own, vectorised. One, two and three degrees of freedom, the dimensions a typed-in
//! system runs on the stack with, the clock of a driven system counted among them (its velocity
//! is 1 and its momentum damped or not as on the one-run path).

// Lanes and components are indexed side by side.
#![allow(clippy::needless_range_loop)]

use std::sync::OnceLock;

use nalgebra::{U1, U2, U3};

use super::system::{CustomSystem, DampingModel, EnergyModel, InverseMass};
use crate::expr::jit::{self, JitFunction};
use crate::expr::program::Program;
use crate::flows::compiled::CompiledForces;
use crate::system::lanes::{damp_each_lane, damp_point, PointForces};
use crate::system::{Lane, LaneForces, MechanicalSystem, LANES};

macro_rules! lane_forces {
    ($($dim:ty => $n:literal),*) => {$(
        impl LaneForces<$n> for CustomSystem<$dim> {
            fn in_lanes(&self) -> bool {
                matches!(self.model().energy, EnergyModel::Separable { .. })
            }

            fn compiled_forces_in_lanes(&self) -> Option<CompiledForces<'_>> {
                self.compiled_forces()
            }

            #[inline(always)]
            fn velocity_lanes(&self, p: &[Lane; $n], v: &mut [Lane; $n]) {
                let EnergyModel::Separable { inverse_mass, .. } = &self.model().energy else {
                    return;
                };
                // `InverseMass::apply`'s arithmetic on the degrees of freedom, vectorised where
                // it is one division; a driven system's clock moves at velocity ∂H̃/∂p_t = 1, as
                // on its one-run path.
                let n = self.dof($n);
                match inverse_mass {
                    InverseMass::Unit => v[..n].copy_from_slice(&p[..n]),
                    InverseMass::Scalar(m) => {
                        for i in 0..n {
                            for l in 0..LANES {
                                v[i][l] = p[i][l] / m;
                            }
                        }
                    }
                    InverseMass::Diagonal(d) => {
                        for i in 0..n {
                            for l in 0..LANES {
                                v[i][l] = p[i][l] / d[i];
                            }
                        }
                    }
                    InverseMass::Full(_) => each_lane(p, v, |x, out| {
                        inverse_mass.apply(&x[..n], &mut out[..n])
                    }),
                }
                if n < $n {
                    v[n] = [1.0; LANES];
                }
            }

            #[inline(always)]
            fn grad_lanes(&self, q: &[Lane; $n], g: &mut [Lane; $n]) {
                let model = self.model();
                let EnergyModel::Separable { gradient, hessian, .. } = &model.energy else {
                    return;
                };
                match model.lane_forces.functions($n, gradient.program(), hessian.program()) {
                    // SAFETY: the function reads $n inputs and writes $n outputs of LANES lanes
                    // each (checked when it was built), the sizes of `q` and `g`.
                    Some(code) => unsafe {
                        let (inputs, outputs) = (q.as_flattened(), g.as_flattened_mut());
                        (code.gradient.code())(inputs.as_ptr(), outputs.as_mut_ptr())
                    },
                    None => each_lane(q, g, |x, out| gradient.eval(x, out)),
                }
            }

            #[inline(always)]
            fn hessian_lanes(&self, q: &[Lane; $n], hess: &mut [[Lane; $n]; $n]) {
                let model = self.model();
                let EnergyModel::Separable { gradient, hessian, .. } = &model.energy else {
                    return;
                };
                // The one-run path reads the n² outputs as a column-major matrix: entry (i, j)
                // is output j·n + i, here out[j][i].
                let mut out = [[[0.0; LANES]; $n]; $n];
                match model.lane_forces.functions($n, gradient.program(), hessian.program()) {
                    // SAFETY: the function reads $n inputs and writes $n² outputs of LANES
                    // lanes each (checked when it was built), the sizes of `q` and `out`.
                    Some(code) => unsafe {
                        (code.hessian.code())(
                            q.as_flattened().as_ptr(),
                            out.as_flattened_mut().as_flattened_mut().as_mut_ptr(),
                        )
                    },
                    None => {
                        let mut x = [0.0; $n];
                        let mut one = [[0.0; $n]; $n];
                        for l in 0..LANES {
                            for i in 0..$n {
                                x[i] = q[i][l];
                            }
                            hessian.eval(&x, one.as_flattened_mut());
                            for j in 0..$n {
                                for i in 0..$n {
                                    out[j][i][l] = one[j][i];
                                }
                            }
                        }
                    }
                }
                for i in 0..$n {
                    for j in 0..$n {
                        hess[i][j] = out[j][i];
                    }
                }
            }

            #[inline(always)]
            fn damp_lanes(&self, q: &[Lane; $n], p: &mut [Lane; $n], tau: f64, c: &Lane) {
                if !matches!(self.model().damping, DampingModel::Conformal { .. }) {
                    damp_each_lane(|_| self, q, p, tau, c);
                    return;
                }
                // Conformal damping projects onto every momentum (P = I): the one-run path's
                // p ← −c·P p + p, operation for operation, in every lane its c leaves moving.
                for l in 0..LANES {
                    if c[l] == 0.0 {
                        continue;
                    }
                    let minus_c = -c[l];
                    for i in 0..$n {
                        p[i][l] = minus_c * p[i][l] + p[i][l];
                    }
                }
            }
        }

        impl PointForces<$n> for CustomSystem<$dim> {
            #[inline(always)]
            fn velocity_at(&self, p: [f64; $n]) -> [f64; $n] {
                let mut v = [0.0; $n];
                if let EnergyModel::Separable { inverse_mass, .. } = &self.model().energy {
                    // A driven system's clock moves at velocity 1, as on its one-run path.
                    let n = self.dof($n);
                    inverse_mass.apply(&p[..n], &mut v[..n]);
                    if n < $n {
                        v[n] = 1.0;
                    }
                }
                v
            }

            #[inline(always)]
            fn grad_at(&self, q: [f64; $n]) -> [f64; $n] {
                let mut g = [0.0; $n];
                if let EnergyModel::Separable { gradient, .. } = &self.model().energy {
                    gradient.eval(&q, &mut g);
                }
                g
            }

            #[inline(always)]
            fn damp_at(&self, q: [f64; $n], p: [f64; $n], tau: f64, c: f64) -> [f64; $n] {
                damp_point(self, q, p, tau, c)
            }
        }
    )*};
}

lane_forces!(U1 => 1, U2 => 2, U3 => 3);

/// `f` from `inputs` to `outputs` lane by lane, through arrays of one lane's components.
#[inline(always)]
fn each_lane<const N: usize>(
    inputs: &[Lane; N],
    outputs: &mut [Lane; N],
    f: impl Fn(&[f64], &mut [f64]),
) {
    let (mut x, mut y) = ([0.0; N], [0.0; N]);
    for l in 0..LANES {
        for i in 0..N {
            x[i] = inputs[i][l];
        }
        f(&x, &mut y);
        for i in 0..N {
            outputs[i][l] = y[i];
        }
    }
}

/// ∇V and ∇²V compiled over the [`LANES`] lanes ([`jit::compile_lanes`]), built at the lanes'
/// first call on the system; `None` where they could not be, and the lanes then call the one-run
/// functions lane by lane.
#[derive(Debug, Default)]
pub struct LaneCode(OnceLock<Option<LaneFunctions>>);

/// The functions of [`LaneCode`].
#[derive(Debug)]
struct LaneFunctions {
    gradient: JitFunction,
    hessian: JitFunction,
}

/// Programs longer than this keep the calls lane by lane: the lanes' function writes a program
/// once per vector of lanes, and the time to build it grows with that.
const MOST_OPERATIONS: usize = 4_000;

impl LaneCode {
    /// Whether the lanes' functions were built (else the lanes call the one-run functions).
    pub fn built(&self) -> bool {
        matches!(self.0.get(), Some(Some(_)))
    }

    /// The functions for `gradient` and `hessian` of `n` coordinates, built on the first call;
    /// later calls return them as built (a system's programs and dimension do not change).
    fn functions(&self, n: usize, gradient: &Program, hessian: &Program) -> Option<&LaneFunctions> {
        self.0
            .get_or_init(|| {
                let fits = gradient.inputs() == n
                    && gradient.outputs() == n
                    && hessian.inputs() == n
                    && hessian.outputs() == n * n
                    && gradient.operation_count() + hessian.operation_count() <= MOST_OPERATIONS;
                let compile = |program| jit::compile_lanes(program, LANES, jit::VECTOR_WIDTH).ok();
                fits.then(|| {
                    Some(LaneFunctions {
                        gradient: compile(gradient)?,
                        hessian: compile(hessian)?,
                    })
                })
                .flatten()
            })
            .as_ref()
    }
}

//! A composition of kicks and drifts (velocity Verlet and its compositions, the triple jump,
//! Blanes–Moan's RKN splitting, symplectic Euler, …) on a separable system with constant mass,
//! [`LANES`] runs side by side, each with deviation vectors advanced by the method's own tangent
//! map: the step of a chaos map's cells.
//!
//! Each flow does what the composer's `step_tangent` does, in its order, with the kernel's
//! tangent maps (`flows::drift_tangent`, `flows::kick_tangent`) on packs of lanes: a drift's
//! tangent map δq ← δq + Σⱼ (τM⁻¹)ᵢⱼ δpⱼ and then the drift; a kick's δp ← 1·δp + Σⱼ (−τ∇²V)ᵢⱼ δqⱼ
//! with ∇²V at q, and then the kick with the force, which is evaluated again only after a drift (the
//! composer's force cache, so the evaluations count the same). The products by the zero
//! entries of M⁻¹ are kept: they are what the one-run path computes. A step leaves the lanes to
//! the caller when one of them needs a look: its state is no longer finite, or a deviation
//! vector left the range the chaos frame keeps it in (see `chaos::frame`).

// Lanes, components and columns are indexed side by side: loops over lane numbers are the form
// the compiler vectorises.
#![allow(clippy::needless_range_loop)]

use nalgebra::DMatrix;

use crate::chaos::frame;
use crate::flows::SubFlow;
use crate::flows::{self, Pack};

use super::Isa;

pub use crate::system::{Lane, LaneForces, LANES};

/// The most degrees of freedom a lane system may have (a bound for the guard's scratch column).
pub const MAX_DIMENSION: usize = 16;

/// One deviation vector in every lane.
#[derive(Clone, Copy, Debug)]
pub struct Column<const N: usize> {
    /// δq.
    pub q: [Lane; N],
    /// δp.
    pub p: [Lane; N],
}

/// ∇²V at the lanes' positions, while they stay (consecutive kicks).
struct Hessian<const N: usize> {
    at_q: [[Lane; N]; N],
    valid: bool,
}

impl<const N: usize> Hessian<N> {
    #[inline(always)]
    fn new() -> Self {
        Hessian {
            at_q: [[[0.0; LANES]; N]; N],
            valid: false,
        }
    }
}

/// A flow of the sequence with its time τ = fraction · h.
#[derive(Clone, Copy, Debug)]
enum TangentFlow {
    Drift(f64),
    Kick(f64),
}

/// What ended an [`TangentLanes::advance`]: the steps taken and, for the last of them, the
/// lanes whose state is not finite (its components do not sum to a finite number, the one-run
/// path's test) and those with a deviation vector out of range.
#[derive(Clone, Copy, Debug)]
pub struct TangentEnded {
    /// Steps taken.
    pub steps: u64,
    /// Per lane: the state's components do not sum to a finite number.
    pub not_finite: [bool; LANES],
    /// Per lane: a deviation vector's squared norm left [2⁻⁶⁰⁰, 2⁶⁰⁰].
    pub out_of_range: [bool; LANES],
}

/// The runs of [`LANES`] cells and their deviation vectors.
#[derive(Clone, Debug)]
pub struct TangentLanes<const N: usize> {
    flows: Vec<TangentFlow>,
    minv: [[f64; N]; N],
    /// Positions.
    pub q: [Lane; N],
    /// Momenta.
    pub p: [Lane; N],
    /// The deviation vectors.
    pub columns: Vec<Column<N>>,
    grad: [Lane; N],
    grad_valid: bool,
    force_evaluations: u64,
    isa: Isa,
}

impl<const N: usize> TangentLanes<N> {
    /// The lanes of the splitting `flows` at step `h` with `k` deviation vectors, all zero, on
    /// a system of damping rate `r`; the inverse mass matrix `minv` as the one-run path's
    /// tangent map reads it. `None` unless every flow is a kick or a drift: without damping
    /// (r = 0) a θ-kick is one too, to the bit (its state update is the kick's, and its tangent
    /// coefficients (1 − (1−θ)rτ)/(1 + θrτ) and τ/(1 + θrτ) are exactly 1 and τ).
    pub fn new(
        flows: &[(SubFlow, f64)],
        r: f64,
        h: f64,
        minv: [[f64; N]; N],
        k: usize,
    ) -> Option<Self> {
        if N > MAX_DIMENSION {
            return None;
        }
        let flows = flows
            .iter()
            .map(|&(flow, fraction)| match flow {
                SubFlow::Drift => Some(TangentFlow::Drift(fraction * h)),
                SubFlow::Kick => Some(TangentFlow::Kick(fraction * h)),
                SubFlow::DampedKick(_) if r == 0.0 => Some(TangentFlow::Kick(fraction * h)),
                _ => None,
            })
            .collect::<Option<Vec<_>>>()?;
        let zero = [[0.0; LANES]; N];
        Some(TangentLanes {
            flows,
            minv,
            q: zero,
            p: zero,
            columns: vec![Column { q: zero, p: zero }; k],
            grad: zero,
            grad_valid: false,
            force_evaluations: 0,
            isa: Isa::detect(),
        })
    }

    /// The same lanes run by code built for `isa`, if this CPU has it (the numbers are the same
    /// bits).
    pub fn with_isa(mut self, isa: Isa) -> Option<Self> {
        isa.available().then(|| {
            self.isa = isa;
            self
        })
    }

    /// Force evaluations so far (every lane has taken the same).
    pub fn force_evaluations(&self) -> u64 {
        self.force_evaluations
    }

    /// Up to `steps` steps of every lane; stops early after a step that leaves a `watched` lane
    /// not finite or with a deviation vector out of range.
    pub fn advance<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        steps: u64,
        watched: &[bool; LANES],
    ) -> TangentEnded {
        match self.isa {
            // SAFETY: the CPU supports AVX-512F, detected when the lanes were made.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => unsafe { self.advance_avx512(sys, steps, watched) },
            // SAFETY: the CPU supports AVX2, detected when the lanes were made.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => unsafe { self.advance_avx2(sys, steps, watched) },
            _ => self.advance_portable(sys, steps, watched),
        }
    }

    /// [`Self::advance_portable`] compiled with AVX-512 (f64×8 registers).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn advance_avx512<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        steps: u64,
        watched: &[bool; LANES],
    ) -> TangentEnded {
        self.advance_portable(sys, steps, watched)
    }

    /// [`Self::advance_portable`] compiled with AVX2 (f64×4 registers).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn advance_avx2<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        steps: u64,
        watched: &[bool; LANES],
    ) -> TangentEnded {
        self.advance_portable(sys, steps, watched)
    }

    #[inline(always)]
    fn advance_portable<S: LaneForces<N>>(
        &mut self,
        sys: &S,
        steps: u64,
        watched: &[bool; LANES],
    ) -> TangentEnded {
        let mut done = 0;
        while done < steps {
            self.step(sys);
            done += 1;
            let (not_finite, out_of_range) = self.look();
            let flagged = (0..LANES).any(|i| watched[i] & (not_finite[i] | out_of_range[i]));
            if flagged || done == steps {
                return TangentEnded {
                    steps: done,
                    not_finite,
                    out_of_range,
                };
            }
        }
        TangentEnded {
            steps: 0,
            not_finite: [false; LANES],
            out_of_range: [false; LANES],
        }
    }

    /// One step of every lane.
    #[inline(always)]
    fn step<S: LaneForces<N>>(&mut self, sys: &S) {
        let mut hessian = Hessian::new();
        for f in 0..self.flows.len() {
            self.apply(sys, self.flows[f], &mut hessian);
        }
    }

    /// One flow of every lane, its deviation vectors first.
    #[inline(always)]
    fn apply<S: LaneForces<N>>(&mut self, sys: &S, flow: TangentFlow, hessian: &mut Hessian<N>) {
        match flow {
            TangentFlow::Drift(tau) => {
                let mut scaled = [[0.0; N]; N];
                for i in 0..N {
                    for j in 0..N {
                        scaled[i][j] = tau * self.minv[i][j];
                    }
                }
                for c in self.columns.iter_mut() {
                    flows::drift_tangent(Pack::of_mut(&mut c.q), Pack::of(&c.p), |i, j| {
                        Pack::splat(scaled[i][j])
                    });
                }
                let mut v = [[0.0; LANES]; N];
                sys.velocity_lanes(&self.p, &mut v);
                flows::drift(Pack::of_mut(&mut self.q), Pack::of(&v), Pack::splat(tau));
                self.grad_valid = false;
                hessian.valid = false;
            }
            TangentFlow::Kick(tau) => {
                if !self.columns.is_empty() {
                    // ∇²V at q, kept while q is (consecutive kicks): the same bits as
                    // evaluating it again.
                    if !hessian.valid {
                        sys.hessian_lanes(&self.q, &mut hessian.at_q);
                        hessian.valid = true;
                    }
                    let minus_tau = Pack::splat(-tau);
                    let mut scaled = [[Pack::splat(0.0); N]; N];
                    for i in 0..N {
                        for j in 0..N {
                            scaled[i][j] = minus_tau * Pack(hessian.at_q[i][j]);
                        }
                    }
                    for c in self.columns.iter_mut() {
                        flows::kick_tangent(
                            Pack::of_mut(&mut c.p),
                            Pack::of(&c.q),
                            Pack::splat(1.0),
                            |i, j| scaled[i][j],
                        );
                    }
                }
                if !self.grad_valid {
                    sys.grad_lanes(&self.q, &mut self.grad);
                    self.force_evaluations += 1;
                    self.grad_valid = true;
                }
                flows::kick(
                    Pack::of_mut(&mut self.p),
                    Pack::of(&self.grad),
                    Pack::splat(tau),
                );
            }
        }
    }

    /// Per lane: whether the state's components fail to sum to a finite number (summed as the
    /// one-run path sums them, positions then momenta), and whether a deviation vector's
    /// squared norm is out of range.
    #[inline(always)]
    fn look(&self) -> ([bool; LANES], [bool; LANES]) {
        let mut not_finite = [false; LANES];
        let mut out_of_range = [false; LANES];
        for l in 0..LANES {
            let (mut sq, mut sp) = (0.0, 0.0);
            for i in 0..N {
                sq += self.q[i][l];
                sp += self.p[i][l];
            }
            not_finite[l] = !(sq + sp).is_finite();
        }
        for c in &self.columns {
            for l in 0..LANES {
                let mut n2 = 0.0;
                for i in 0..N {
                    n2 += c.q[i][l] * c.q[i][l];
                }
                for i in 0..N {
                    n2 += c.p[i][l] * c.p[i][l];
                }
                out_of_range[l] |= !frame::in_range(n2);
            }
        }
        (not_finite, out_of_range)
    }

    /// Whether every component of lane `l`'s state is finite.
    pub fn finite(&self, l: usize) -> bool {
        (0..N).all(|i| self.q[i][l].is_finite() && self.p[i][l].is_finite())
    }

    /// Brings lane `l`'s deviation vectors back in range as `chaos::frame::guard` does, adding
    /// the powers of two taken out to `exponents` (one per vector).
    pub fn guard(&mut self, l: usize, exponents: &mut [i32]) {
        let mut buffer = [0.0; 2 * MAX_DIMENSION];
        let column = &mut buffer[..2 * N];
        for (c, e) in self.columns.iter_mut().zip(exponents) {
            for i in 0..N {
                column[i] = c.q[i][l];
                column[N + i] = c.p[i][l];
            }
            let n2 = column.iter().fold(0.0, |acc, x| acc + x * x);
            if !frame::in_range(n2) {
                *e += frame::rescale(column);
                for i in 0..N {
                    c.q[i][l] = column[i];
                    c.p[i][l] = column[N + i];
                }
            }
        }
    }

    /// Normalises the first deviation vector of each lane in `due` as `frame::orthonormalise`
    /// normalises a first column, and returns the norms (R₁₁) and which lanes it normalised; a
    /// vector whose norm is zero or not finite is left alone (`frame::orthonormalise` replaces
    /// it).
    pub fn normalise_first(&mut self, due: &[bool; LANES]) -> (Lane, [bool; LANES]) {
        let c = &mut self.columns[0];
        let mut n2 = [0.0; LANES];
        for i in 0..N {
            for l in 0..LANES {
                n2[l] += c.q[i][l] * c.q[i][l];
            }
        }
        for i in 0..N {
            for l in 0..LANES {
                n2[l] += c.p[i][l] * c.p[i][l];
            }
        }
        let norm = n2.map(f64::sqrt);
        let scale: [bool; LANES] =
            std::array::from_fn(|l| due[l] && norm[l] > 0.0 && norm[l].is_finite());
        for i in 0..N {
            for l in 0..LANES {
                if scale[l] {
                    c.q[i][l] /= norm[l];
                }
            }
        }
        for i in 0..N {
            for l in 0..LANES {
                if scale[l] {
                    c.p[i][l] /= norm[l];
                }
            }
        }
        (norm, scale)
    }

    /// Lane `l`'s deviation vectors into the columns of `jac` (2n × k, δq rows first).
    pub fn store(&self, l: usize, jac: &mut DMatrix<f64>) {
        for (col, c) in self.columns.iter().enumerate() {
            for i in 0..N {
                jac[(i, col)] = c.q[i][l];
                jac[(N + i, col)] = c.p[i][l];
            }
        }
    }

    /// Lane `l`'s deviation vectors from the columns of `jac`.
    pub fn load(&mut self, l: usize, jac: &DMatrix<f64>) {
        for (col, c) in self.columns.iter_mut().enumerate() {
            for i in 0..N {
                c.q[i][l] = jac[(i, col)];
                c.p[i][l] = jac[(N + i, col)];
            }
        }
    }
}

//! Hénon's step (see the [module docs](super)): from a state (z₀, t₀) with surface value s₀,
//! integrate dz/ds = f(z)/σ, dt/ds = 1/σ (σ = ∇S·f + ∂S/∂t) in the surface value s up to a
//! level, with the eighth-order Dormand–Prince tableau of DOP853 (Hairer, Nørsett, Wanner I,
//! Sec. II.10): one step of size level − s₀, split into m equal sub-steps when its embedded
//! error estimate (HNW's combination of the fifth- and third-order estimates, as the adaptive
//! reference uses it) exceeds [`TOLERANCE`], then one more step of size −(S(z*) − level) that
//! leaves the surface's residue at round-off: an Euler step, since that residue is the first
//! step's error (about TOLERANCE · |level − s₀|) and Euler's error its square, unless the residue
//! is above 1e-10 · |level − s₀|. Buffers are allocated once per run.

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim};

use super::surface::Surface;
use crate::methods::dop853::{StageVector, DOP853};
use crate::system::{MechanicalSystem, State, Vector};

/// The error measure a (sub-)step must meet: relative and absolute, per component.
pub const TOLERANCE: f64 = 1e-14;
/// Most sub-steps a located point may take (a crossing this close to tangent is refused).
pub const MAX_SUBSTEPS: usize = 1024;
const STAGES: usize = 12;
/// The largest residue, relative to the step in s, that an Euler step removes (module docs).
const EULER_RESIDUE: f64 = 1e-10;

/// A point of extended phase space with its time: (z, t).
struct Point<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    z: State<D>,
    t: f64,
}

impl<D: Dim> Point<D>
where
    DefaultAllocator: Allocator<D>,
{
    fn zeros(dim: D) -> Self {
        let v = Vector::<D>::zeros_generic(dim, nalgebra::U1);
        Point {
            z: State { q: v.clone(), p: v },
            t: 0.0,
        }
    }

    fn components(&self) -> impl Iterator<Item = f64> + '_ {
        self.z
            .q
            .iter()
            .chain(self.z.p.iter())
            .copied()
            .chain([self.t])
    }
}

impl<D: Dim> StageVector for Point<D>
where
    DefaultAllocator: Allocator<D>,
{
    fn assign(&mut self, other: &Self) {
        copy(&mut self.z, &other.z);
        self.t = other.t;
    }

    /// self += c·x.
    fn add_scaled(&mut self, x: &Self, c: f64) {
        self.z.q.axpy(c, &x.z.q, 1.0);
        self.z.p.axpy(c, &x.z.p, 1.0);
        self.t += c * x.t;
    }

    /// self ← c·x.
    fn assign_scaled(&mut self, x: &Self, c: f64) {
        self.assign(x);
        self.z.q *= c;
        self.z.p *= c;
        self.t *= c;
    }
}

/// The surface's and the vector field's evaluation: their buffers and count.
struct Evaluator<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// Degrees of freedom (the clock of a driven system excluded).
    n: usize,
    scratch: Vector<D>,
    inputs: Vec<f64>,
    outputs: Vec<f64>,
    evaluations: u64,
}

impl<D: Dim> Evaluator<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// S at (z, t).
    fn value(&mut self, surface: &Surface, z: &State<D>, t: f64) -> f64 {
        let n = self.n;
        surface.value(
            &z.q.as_slice()[..n],
            &z.p.as_slice()[..n],
            t,
            &mut self.inputs,
        )
    }

    /// S and σ at `at`, with the vector field f(z) left in `out` (unscaled).
    fn sigma<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        surface: &Surface,
        at: &Point<D>,
        out: &mut Point<D>,
    ) -> (f64, f64) {
        sys.vector_field(
            &at.z.q,
            &at.z.p,
            &mut out.z.q,
            &mut out.z.p,
            &mut self.scratch,
        );
        self.evaluations += 1;
        let n = self.n;
        surface.rate(
            (&at.z.q.as_slice()[..n], &at.z.p.as_slice()[..n], at.t),
            (&out.z.q.as_slice()[..n], &out.z.p.as_slice()[..n]),
            &mut self.inputs,
            &mut self.outputs,
        )
    }

    /// The Hénon field at `at` into `out`: (f, 1)/σ; false where σ vanishes or is not finite.
    #[inline]
    fn field<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        surface: &Surface,
        at: &Point<D>,
        out: &mut Point<D>,
    ) -> bool {
        let (_, sigma) = self.sigma(sys, surface, at, out);
        // Division, not a reciprocal times f: for S = q_j the j-th component is then exactly 1.
        for x in out.z.q.iter_mut().chain(out.z.p.iter_mut()) {
            *x /= sigma;
        }
        out.t = 1.0 / sigma;
        sigma != 0.0 && sigma.is_finite()
    }
}

/// Hénon's step for one run: its stage buffers and the surface's evaluation buffers.
pub struct Henon<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    eval: Evaluator<D>,
    k: Vec<Point<D>>,
    stage: Point<D>,
    y: Point<D>,
    step_start: Point<D>,
    slope: Point<D>,
    err5: Point<D>,
    err3: Point<D>,
}

/// Why a point could not be located.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Unlocated {
    /// σ vanished or the state left the finite numbers: s is no clock here.
    Singular,
    /// Even [`MAX_SUBSTEPS`] sub-steps did not meet the tolerance.
    Tangent,
    /// The point reached moves across the surface against the direction the step crossed it
    /// in: near a tangency, the method's steps crossed where the exact flow from either end of
    /// the step turns back, and what was reached is the crossing on the way back.
    Reversed,
}

impl<D: Dim> Henon<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// Buffers for a system of state dimension `dim` and `n` degrees of freedom.
    pub fn new(dim: D, n: usize) -> Self {
        let (inputs, outputs) = Surface::buffers(n);
        Henon {
            eval: Evaluator {
                n,
                scratch: Vector::<D>::zeros_generic(dim, nalgebra::U1),
                inputs,
                outputs,
                evaluations: 0,
            },
            k: (0..STAGES).map(|_| Point::zeros(dim)).collect(),
            stage: Point::zeros(dim),
            y: Point::zeros(dim),
            step_start: Point::zeros(dim),
            slope: Point::zeros(dim),
            err5: Point::zeros(dim),
            err3: Point::zeros(dim),
        }
    }

    /// Vector-field evaluations so far.
    pub fn evaluations(&self) -> u64 {
        self.eval.evaluations
    }

    /// S at (z, t).
    pub fn value(&mut self, surface: &Surface, z: &State<D>, t: f64) -> f64 {
        self.eval.value(surface, z, t)
    }

    /// σ at (z, t): the rate at which the surface value changes there.
    pub fn rate<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        surface: &Surface,
        z: &State<D>,
        t: f64,
    ) -> f64 {
        copy(&mut self.y.z, z);
        self.y.t = t;
        self.eval.sigma(sys, surface, &self.y, &mut self.stage).1
    }

    /// One step of size `ds` from `self.y`, which it advances; returns the error measure
    /// (≤ 1: within [`TOLERANCE`]), or `None` where σ vanished or a value is not finite.
    fn step<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        surface: &Surface,
        ds: f64,
    ) -> Option<f64> {
        let t = &DOP853;
        let mut ok = self.eval.field(sys, surface, &self.y, &mut self.k[0]);
        let eval = &mut self.eval;
        t.stages(&self.y, ds, &mut self.k, &mut self.stage, |x, out| {
            ok &= eval.field(sys, surface, x, out);
        });
        // The slope and the two embedded error estimates; err₅'s weights e₂ … e₅ vanish.
        t.slope(&self.k, &mut self.slope);
        self.err5.assign_scaled(&self.k[0], t.e[0]);
        for i in 5..STAGES {
            self.err5.add_scaled(&self.k[i], t.e[i]);
        }
        t.third_order_error(&self.k, &self.slope, &mut self.err3);
        self.step_start.assign(&self.y);
        self.y.add_scaled(&self.slope, ds);
        let (mut e5, mut e3, mut count) = (0.0, 0.0, 0.0);
        for ((a, b), (x5, x3)) in self
            .step_start
            .components()
            .zip(self.y.components())
            .zip(self.err5.components().zip(self.err3.components()))
        {
            let sc = TOLERANCE * (1.0 + a.abs().max(b.abs()));
            e5 += (x5 / sc) * (x5 / sc);
            e3 += (x3 / sc) * (x3 / sc);
            count += 1.0;
        }
        if !ok || !self.y.components().all(f64::is_finite) {
            return None;
        }
        let denominator = if e5 + 0.01 * e3 > 0.0 {
            e5 + 0.01 * e3
        } else {
            1.0
        };
        Some(ds.abs() * e5 * (1.0 / (denominator * count)).sqrt())
    }

    /// One Euler step of size `ds` from `self.y`, which it advances; `None` where σ vanished
    /// or a value is not finite.
    fn euler<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        surface: &Surface,
        ds: f64,
    ) -> Option<()> {
        let ok = self.eval.field(sys, surface, &self.y, &mut self.k[0]);
        self.y.add_scaled(&self.k[0], ds);
        (ok && self.y.components().all(f64::is_finite)).then_some(())
    }

    /// Integrates from (z₀, t₀), whose surface value is `s0`, to the surface value `level`;
    /// writes the point reached into `out` and returns its time.
    pub fn locate<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        surface: &Surface,
        (z0, t0, s0): (&State<D>, f64, f64),
        level: f64,
        out: &mut State<D>,
    ) -> Result<f64, Unlocated> {
        let ds = level - s0;
        let mut m = 1usize;
        loop {
            copy(&mut self.y.z, z0);
            self.y.t = t0;
            let mut worst = 0.0f64;
            for _ in 0..m {
                match self.step(sys, surface, ds / m as f64) {
                    Some(err) => worst = worst.max(err),
                    None => return Err(Unlocated::Singular),
                }
            }
            if worst <= 1.0 {
                break;
            }
            if m >= MAX_SUBSTEPS {
                return Err(Unlocated::Tangent);
            }
            // The error of an eighth-order step scales as its size⁸.
            let more = (1.25 * worst.powf(0.125)).ceil().max(2.0) as usize;
            m = (m * more).min(MAX_SUBSTEPS);
        }
        // The step's residue on the surface, removed by one more step. The residue is the
        // step's error, about TOLERANCE relative to ds: an Euler step then errs by the
        // residue's square (relative to the step's own scale, about 1e-28), below round-off,
        // at one evaluation of the field; a residue that is not that small takes an eighth-order
        // step, whose error is of its ninth power.
        let residue = self.eval.value(surface, &self.y.z, self.y.t) - level;
        if residue != 0.0 && residue.is_finite() {
            if residue.abs() <= EULER_RESIDUE * ds.abs() {
                self.euler(sys, surface, -residue)
                    .ok_or(Unlocated::Singular)?;
            } else {
                self.step(sys, surface, -residue)
                    .ok_or(Unlocated::Singular)?;
            }
        }
        copy(out, &self.y.z);
        Ok(self.y.t)
    }
}

/// to ← from, in place (no allocation for dynamic dimensions either).
pub fn copy<D: Dim>(to: &mut State<D>, from: &State<D>)
where
    DefaultAllocator: Allocator<D>,
{
    to.q.copy_from(&from.q);
    to.p.copy_from(&from.p);
}

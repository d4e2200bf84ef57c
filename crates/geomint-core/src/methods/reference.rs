//! The reference integrator: the adaptive embedded Runge–Kutta method DOP853 (Hairer–Nørsett–
//! Wanner, Solving ODEs I, Sec. II.10; tableau in [`dop853`](super::dop853)), run at a tight
//! tolerance and used as the "exact" solution where no closed form exists.
//!
//! Each fixed step h of the driver is one segment [0, h] integrated from scratch: an initial
//! step guess (HNW's `hinit`), then accepted and rejected steps under the standard DOP853
//! controller (exponent 1/8, no PI term, safety 0.9, step ratio within [0.333, 6], steps at most h)
//! until the segment's end, which is always a step endpoint. The error of a step combines the
//! fifth- and third-order estimates as HNW's code does: with E₅ = Σᵢ (err₅ᵢ/scᵢ)², E₃ likewise and
//! scᵢ = atol + rtol·max(|y₀ᵢ|, |y₁ᵢ|) over the N = 2n components, err = |h| E₅ / √(N (E₅ + 0.01 E₃)).
//!
//! The arithmetic is that of the `ode_solvers` crate's `Dop853` 0.6.2 (which geomint used before):
//! the same operations in the same order, zero coefficients included, so every state, and every
//! study built on the reference, is the same to the bit (`tests/core/reference.rs` compares the
//! two). Unlike that crate it works on the system's own fixed-size state (q, p) with buffers
//! allocated once per run, so a step allocates nothing, and it does not store the steps of a
//! segment. Its stiffness test never fired with the settings used here, so it is left out.

use std::time::Instant;

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim};

use super::dop853::{EmbeddedTableau, StageVector, DOP853};
use super::sources::*;
use super::{Citation, Group, Kind, MethodInfo, MethodOption, Steps};
use crate::error::StepError;
use crate::run::Stepper;
use crate::system::{MechanicalSystem, State, Vector};

/// Most adaptive steps inside one fixed step h.
const MAX_STEPS_PER_SEGMENT: u32 = 200_000;
/// Adaptive steps between two looks at the deadline inside a fixed step (the driver looks only
/// between fixed steps, and one can take [`MAX_STEPS_PER_SEGMENT`] adaptive steps: about a second
/// in an optimised build, twenty in a debug one). A look costs a clock read; 256 steps of 12
/// stages take tens of microseconds.
const DEADLINE_CHECK_STEPS: u32 = 256;

/// Default relative and absolute tolerance of the reference runs.
pub const DEFAULT_TOLERANCE: f64 = 1e-12;

/// The step-size controller (HNW's defaults for DOP853): the next step is h/fac with
/// fac = err^ALPHA/SAFETY clamped to [1/FAC_MAX, 1/FAC_MIN], so a step grows at most FAC_MAX-fold
/// and shrinks at most to FAC_MIN of itself.
const SAFETY: f64 = 0.9;
/// Exponent of the error in the step-size factor (1/8; no PI term).
const ALPHA: f64 = 0.125;
/// Smallest ratio of two successive steps.
const FAC_MIN: f64 = 0.333;
/// Largest ratio of two successive steps.
const FAC_MAX: f64 = 6.0;
/// Stages of a step.
const STAGES: usize = 12;

/// DOP853 at a fixed tolerance, advancing over each requested interval.
pub struct Reference<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    tolerance: f64,
    force_evaluations: u64,
    /// The stage derivatives k₁ … k₁₂, as (q', p').
    k: [State<D>; STAGES],
    /// The state a stage is evaluated at.
    stage: State<D>,
    /// Σ bᵢ kᵢ of the current step.
    slope: State<D>,
    /// The proposed end of the step, y₀ + h Σ bᵢ kᵢ.
    proposed: State<D>,
    /// The fifth- and third-order error estimates (without the factor h).
    err5: State<D>,
    err3: State<D>,
    scratch: Vector<D>,
    /// The state at the start of the current fixed step, restored when the deadline passes.
    start: State<D>,
    /// Given up inside a fixed step once this instant passes.
    deadline: Option<Instant>,
}

impl<D: Dim> Reference<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// A reference integrator with relative and absolute tolerance `tolerance` for systems of
    /// dimension `dim`.
    pub fn new(tolerance: f64, dim: D) -> Self {
        let zero = Vector::<D>::zeros_generic(dim, nalgebra::U1);
        let state = || State {
            q: zero.clone(),
            p: zero.clone(),
        };
        Self {
            tolerance,
            force_evaluations: 0,
            k: std::array::from_fn(|_| state()),
            stage: state(),
            slope: state(),
            proposed: state(),
            err5: state(),
            err3: state(),
            scratch: zero.clone(),
            start: state(),
            deadline: None,
        }
    }
}

/// y ← y + x·c, component by component.
#[inline(always)]
fn add_scaled<D: Dim>(y: &mut State<D>, x: &State<D>, c: f64)
where
    DefaultAllocator: Allocator<D>,
{
    for (y, x) in y.q.iter_mut().zip(x.q.iter()) {
        *y += *x * c;
    }
    for (y, x) in y.p.iter_mut().zip(x.p.iter()) {
        *y += *x * c;
    }
}

/// y ← x in place (`clone_from` would allocate a fresh vector for a run-time dimension).
#[inline(always)]
fn copy<D: Dim>(y: &mut State<D>, x: &State<D>)
where
    DefaultAllocator: Allocator<D>,
{
    y.q.copy_from(&x.q);
    y.p.copy_from(&x.p);
}

/// The components of (q, p) in the order y = (q, p) lists them.
#[inline(always)]
fn components<D: Dim>(z: &State<D>) -> impl Iterator<Item = f64> + '_
where
    DefaultAllocator: Allocator<D>,
{
    z.q.iter().chain(z.p.iter()).copied()
}

/// f(y) = (q', p') into `out`.
#[inline(always)]
fn field<S: MechanicalSystem>(
    sys: &S,
    y: &State<S::Dim>,
    out: &mut State<S::Dim>,
    scratch: &mut Vector<S::Dim>,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys.vector_field(&y.q, &y.p, &mut out.q, &mut out.p, scratch);
}

/// `a` with the sign of `b` (Fortran's SIGN), as the initial-step guess uses it.
fn with_sign_of(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a.abs()
    } else {
        -a.abs()
    }
}

/// Why a segment could not be completed.
enum SegmentFailure {
    /// More than `MAX_STEPS_PER_SEGMENT` steps.
    TooManySteps { x: f64, steps: u32 },
    /// The step size fell below round-off relative to x.
    Underflow { x: f64 },
    /// The deadline passed.
    Deadline,
}

impl From<SegmentFailure> for StepError {
    fn from(f: SegmentFailure) -> Self {
        let message = match f {
            SegmentFailure::TooManySteps { x, steps } => {
                format!("Stopped at x = {x}. Need more than {steps} steps.")
            }
            SegmentFailure::Underflow { x } => format!("Stopped at x = {x}. Step size underflow."),
            SegmentFailure::Deadline => return StepError::DeadlinePassed,
        };
        StepError::AdaptiveFailed { message }
    }
}

impl<D: Dim> Reference<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// HNW's initial step guess for the segment [0, `length`] from `y` (two evaluations): an
    /// explicit Euler step of size 0.01·‖y‖/‖f‖, then the step for which the estimated local
    /// error of order 8 is 0.01, at most 100 times the first guess and `length`.
    fn initial_step<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        y: &State<D>,
        length: f64,
    ) -> f64 {
        let tol = self.tolerance;
        let [f0, .., f1] = &mut self.k;
        field(sys, y, f0, &mut self.scratch);
        let (mut d0, mut d1) = (0.0, 0.0);
        for (yi, fi) in components(y).zip(components(f0)) {
            let sc = tol + yi.abs() * tol;
            d0 += (yi / sc) * (yi / sc);
            d1 += (fi / sc) * (fi / sc);
        }
        let mut h0 = if d0 < 1e-10 || d1 < 1e-10 {
            1e-6
        } else {
            0.01 * (d0 / d1).sqrt()
        };
        h0 = with_sign_of(h0.min(length.abs()), length);
        // One Euler step, and the change of f along it.
        copy(&mut self.stage, y);
        add_scaled(&mut self.stage, f0, h0);
        field(sys, &self.stage, f1, &mut self.scratch);
        let mut d2 = 0.0;
        for ((yi, fa), fb) in components(y).zip(components(f0)).zip(components(f1)) {
            let sc = tol + yi.abs() * tol;
            d2 += ((fb - fa) / sc) * ((fb - fa) / sc);
        }
        d2 = d2.sqrt() / h0;
        let h1 = if d1.sqrt().max(d2.abs()) <= 1e-15 {
            1e-6_f64.max(h0.abs() * 1e-3)
        } else {
            (0.01 / d1.sqrt().max(d2)).powf(0.125)
        };
        with_sign_of((100.0 * h0.abs()).min(h1.min(length.abs())), length)
    }

    /// Integrates y' = f(y) over [0, `length`], replacing `y` by the end state; returns the
    /// number of evaluations of f.
    fn segment<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        y: &mut State<D>,
        length: f64,
    ) -> Result<u64, SegmentFailure> {
        let t: &EmbeddedTableau = &DOP853;
        let direction = with_sign_of(1.0, length);
        let h_max = length.abs();
        copy(&mut self.start, y);
        let mut h = self.initial_step(sys, y, length);
        field(sys, y, &mut self.k[0], &mut self.scratch);
        let mut evaluations = 3u64;
        // The controller's memory: whether the last step was rejected.
        let mut rejected = false;
        let mut x = 0.0f64;
        let mut steps = 0u32;
        loop {
            if steps >= MAX_STEPS_PER_SEGMENT {
                return Err(SegmentFailure::TooManySteps { x, steps });
            }
            if steps > 0
                && steps.is_multiple_of(DEADLINE_CHECK_STEPS)
                && self.deadline.is_some_and(|d| Instant::now() >= d)
            {
                copy(y, &self.start);
                return Err(SegmentFailure::Deadline);
            }
            if 0.1 * h.abs() <= f64::EPSILON * x.abs() {
                return Err(SegmentFailure::Underflow { x });
            }
            let last = (x + 1.01 * h - length) * direction > 0.0;
            if last {
                h = length - x;
            }
            steps += 1;
            self.attempt(sys, y, h, t);
            evaluations += 11;
            let err = self.error(y, h, t);
            // The step-size factor: err^(1/8)/safety, kept within [1/FAC_MAX, 1/FAC_MIN].
            let fac11 = err.powf(ALPHA);
            let fac = (1.0 / FAC_MAX).max((1.0 / FAC_MIN).min(fac11 / SAFETY));
            let mut h_new = h / fac;
            if err <= 1.0 {
                if h_new.abs() > h_max {
                    h_new = direction * h_max;
                }
                if rejected {
                    h_new = direction * h_new.abs().min(h.abs());
                }
                rejected = false;
                // The derivative at the new point is the next step's k₁ (FSAL).
                field(sys, &self.proposed, &mut self.k[0], &mut self.scratch);
                evaluations += 1;
                std::mem::swap(y, &mut self.proposed);
                x += h;
                if last {
                    return Ok(evaluations);
                }
            } else {
                h_new = h / (1.0 / FAC_MIN).min(fac11 / SAFETY);
                rejected = true;
            }
            h = h_new;
        }
    }

    /// The stages k₂ … k₁₂ of a step of size `h` from `y` (k₁ is known), the slope Σ bᵢ kᵢ and the
    /// proposed end y + h Σ bᵢ kᵢ.
    #[inline(always)]
    fn attempt<S: MechanicalSystem<Dim = D>>(
        &mut self,
        sys: &S,
        y: &State<D>,
        h: f64,
        t: &EmbeddedTableau,
    ) {
        let scratch = &mut self.scratch;
        t.stages(y, h, &mut self.k, &mut self.stage, |x, out| {
            field(sys, x, out, scratch)
        });
        t.slope(&self.k, &mut self.slope);
        copy(&mut self.proposed, y);
        add_scaled(&mut self.proposed, &self.slope, h);
    }

    /// The step's error measure (≤ 1: accept) from the two embedded estimates.
    #[inline(always)]
    fn error(&mut self, y: &State<D>, h: f64, t: &EmbeddedTableau) -> f64 {
        let tol = self.tolerance;
        // err₅ = Σ eᵢ kᵢ from zero, left to right. The zero weights e₂ … e₅ are applied to k₁₁,
        // k₁₂, the slope and the proposed state, as the earlier implementation did, so that a
        // non-finite value among them rejects the step exactly as it did there.
        self.err5.q.fill(0.0);
        self.err5.p.fill(0.0);
        add_scaled(&mut self.err5, &self.k[0], t.e[0]);
        add_scaled(&mut self.err5, &self.k[10], t.e[1]);
        add_scaled(&mut self.err5, &self.k[11], t.e[2]);
        add_scaled(&mut self.err5, &self.slope, t.e[3]);
        add_scaled(&mut self.err5, &self.proposed, t.e[4]);
        for i in 5..STAGES {
            add_scaled(&mut self.err5, &self.k[i], t.e[i]);
        }
        t.third_order_error(&self.k, &self.slope, &mut self.err3);
        let (mut e5, mut e3) = (0.0, 0.0);
        let scales = components(y)
            .zip(components(&self.proposed))
            .map(|(a, b)| tol + a.abs().max(b.abs()) * tol);
        for ((sc, a), b) in scales
            .zip(components(&self.err5))
            .zip(components(&self.err3))
        {
            e5 += (a / sc) * (a / sc);
            e3 += (b / sc) * (b / sc);
        }
        let mut denominator = e5 + 0.01 * e3;
        if denominator <= 0.0 {
            denominator = 1.0;
        }
        let n = (2 * y.q.len()) as f64;
        h.abs() * e5 * (1.0 / (denominator * n)).sqrt()
    }
}

impl<D: Dim> StageVector for State<D>
where
    DefaultAllocator: Allocator<D>,
{
    #[inline(always)]
    fn assign(&mut self, x: &Self) {
        copy(self, x);
    }

    #[inline(always)]
    fn add_scaled(&mut self, x: &Self, c: f64) {
        add_scaled(self, x, c);
    }

    /// y ← x·c, component by component.
    #[inline(always)]
    fn assign_scaled(&mut self, x: &Self, c: f64) {
        for (y, x) in self.q.iter_mut().zip(x.q.iter()) {
            *y = *x * c;
        }
        for (y, x) in self.p.iter_mut().zip(x.p.iter()) {
            *y = *x * c;
        }
    }
}

impl<S: MechanicalSystem> Stepper<S> for Reference<S::Dim>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        self.force_evaluations += self.segment(sys, z, h)?;
        Ok(())
    }

    fn force_evaluations(&self) -> u64 {
        self.force_evaluations
    }

    fn check_interval(&self) -> u64 {
        1
    }

    fn set_deadline(&mut self, deadline: Option<Instant>) {
        self.deadline = deadline;
    }
}

/// Catalogue entry of `reference`.
pub const REFERENCE_INFO: MethodInfo = MethodInfo {
    id: "reference",
    name: "Reference: adaptive DOP853",
    order: 8,
    kind: Kind::Adaptive,
    symplectic: false,
    conformal_symplectic: false,
    symmetric: false,
    requirements: &[],
    reference: Citation {
        paper: HNW,
        equation: "Sec. II.10",
    },
    group: Group::Baseline,
    options: &[MethodOption::Tolerance],
    no_step_jacobian: Some("the adaptive reference has"),
    steps: Steps::Own,
};

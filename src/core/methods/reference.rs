//! The reference integrator: the adaptive embedded Runge–Kutta method DOP853 (Hairer–Nørsett–
//! Wanner, Solving ODEs I, Sec. II.10) from the `ode_solvers` crate, run at a tight tolerance and
//! used as the "exact" solution where no closed form exists.
//!
//! It is driven segment by segment with sparse output (a fresh solver per segment, started from
//! the previous end state), so every reported state is a step endpoint: `ode_solvers` 0.6.2's
//! dense output extrapolates wrongly when the end time lies on the output grid.

use nalgebra::allocator::Allocator;
use nalgebra::{DVector, DefaultAllocator};
use ode_solvers::{Dop853, OutputType};

use super::sources::*;
use super::{Citation, Group, Kind, MethodInfo, MethodOption};
use crate::core::error::StepError;
use crate::core::run::Stepper;
use crate::core::system::{MechanicalSystem, State, Vector};

/// Most adaptive steps inside one fixed step h. The driver checks deadlines and cancellation only
/// between fixed steps, so this bounds the work a single call can do (about a second).
const MAX_STEPS_PER_SEGMENT: u32 = 200_000;

/// Default relative and absolute tolerance of the reference runs.
pub const DEFAULT_TOLERANCE: f64 = 1e-12;

/// Adapts a mechanical system to `ode_solvers`' first-order form y = (q, p).
struct FirstOrder<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys: &'a S,
    work: std::cell::RefCell<(
        State<S::Dim>,
        Vector<S::Dim>,
        Vector<S::Dim>,
        Vector<S::Dim>,
    )>,
}

impl<S: MechanicalSystem> ode_solvers::System<f64, DVector<f64>> for FirstOrder<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn system(&self, _t: f64, y: &DVector<f64>, dy: &mut DVector<f64>) {
        let mut work = self.work.borrow_mut();
        let (z, dq, dp, scratch) = &mut *work;
        let n = z.q.len();
        for i in 0..n {
            z.q[i] = y[i];
            z.p[i] = y[n + i];
        }
        self.sys.vector_field(&z.q, &z.p, dq, dp, scratch);
        for i in 0..n {
            dy[i] = dq[i];
            dy[n + i] = dp[i];
        }
    }
}

/// DOP853 at a fixed tolerance, advancing over each requested interval.
pub struct Reference {
    tolerance: f64,
    force_evaluations: u64,
}

impl Reference {
    /// A reference integrator with relative and absolute tolerance `tolerance`.
    pub fn new(tolerance: f64) -> Self {
        Self {
            tolerance,
            force_evaluations: 0,
        }
    }
}

impl<S: MechanicalSystem> Stepper<S> for Reference
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        let n = z.q.len();
        let mut y = DVector::<f64>::zeros(2 * n);
        for i in 0..n {
            y[i] = z.q[i];
            y[n + i] = z.p[i];
        }
        let zero = Vector::<S::Dim>::zeros_generic(sys.dim(), nalgebra::U1);
        let f = FirstOrder {
            sys,
            work: std::cell::RefCell::new((z.clone(), zero.clone(), zero.clone(), zero)),
        };
        let (end, evaluations) = dop853(f, y, h, self.tolerance)?;
        self.force_evaluations += evaluations;
        for i in 0..n {
            z.q[i] = end[i];
            z.p[i] = end[n + i];
        }
        Ok(())
    }

    fn force_evaluations(&self) -> u64 {
        self.force_evaluations
    }

    fn check_interval(&self) -> u64 {
        1
    }
}

/// Integrates y' = f(y) over [0, h] with DOP853 at tolerance `tol`; returns the end state and
/// the number of right-hand-side evaluations. Kept free of the system's generic bounds so that
/// nalgebra's dynamic vector types infer cleanly.
fn dop853<F: ode_solvers::System<f64, DVector<f64>>>(
    f: F,
    y: DVector<f64>,
    h: f64,
    tol: f64,
) -> Result<(DVector<f64>, u64), StepError> {
    let mut solver = Dop853::from_param(
        f,
        0.0,
        h,
        h,
        y,
        tol,
        tol,
        0.9,
        0.0,
        0.333,
        6.0,
        h,
        0.0,
        MAX_STEPS_PER_SEGMENT,
        u32::MAX,
        OutputType::Sparse,
    );
    let stats = solver.integrate().map_err(|e| StepError::AdaptiveFailed {
        message: e.to_string(),
    })?;
    let end = solver
        .y_out()
        .last()
        .cloned()
        .ok_or(StepError::AdaptiveFailed {
            message: "the integrator produced no output".into(),
        })?;
    Ok((end, u64::from(stats.num_eval)))
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
};

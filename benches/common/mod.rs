//! The timing loop shared by the step benchmarks: h = 0.1, one timed run = 5000 repetitions of
//! a [0, 200] integration (2000 steps each, state reset each time so that the amplitude never
//! reaches subnormal numbers), one warm-up, then the median of 7 runs.

use std::hint::black_box;
use std::time::Instant;

use geomint::core::error::StepError;
use geomint::core::methods::{self, Method};
use geomint::core::run::{integrate, Budget, Observer, Schedule, Stepper};
use geomint::core::system::{MechanicalSystem, State};
use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;

/// The sum of q₀ over the final states: keeps the work observable.
struct Checksum(f64);

impl<D: nalgebra::Dim> Observer<D> for Checksum
where
    DefaultAllocator: Allocator<D>,
{
    fn on_sample(&mut self, step: u64, _t: f64, z: &State<D>) {
        if step > 0 {
            self.0 += z.q[0];
        }
    }
}

/// Integrations per timed run.
pub const REPETITIONS: u64 = 5000;
/// Integrations per run with `GEOMINT_BENCH_PROFILE` set: one short run for instruction counts
/// under callgrind (`valgrind --tool=callgrind`), where wall time means nothing.
pub const PROFILE_REPETITIONS: u64 = 50;
/// Steps per integration.
pub const STEPS: u64 = 2000;
/// The step size.
pub const H: f64 = 0.1;

/// A stepper seen through `step` alone: the driver's stretches between samples run as single
/// steps, so a splitting's end flows are not fused. The step-by-step form, for comparison.
struct StepByStep<'a, M>(&'a mut M);

impl<S: MechanicalSystem, M: Stepper<S>> Stepper<S> for StepByStep<'_, M>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    #[inline(always)]
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        self.0.step(sys, z, h)
    }
    fn force_evaluations(&self) -> u64 {
        self.0.force_evaluations()
    }
}

/// Median ns per step and the checksum of the final states, as the service runs: the driver
/// monomorphised for the concrete stepper, stretches of steps between samples (splittings fuse
/// their end flows).
pub fn measure<S: MechanicalSystem>(sys: &S, choice: &Method, start: &State<S::Dim>) -> (f64, f64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    measure_with(sys, choice, start, false)
}

/// [`measure`] with every step taken on its own (no fusion).
#[allow(dead_code)] // not every bench compares the two forms
pub fn measure_step_by_step<S: MechanicalSystem>(
    sys: &S,
    choice: &Method,
    start: &State<S::Dim>,
) -> (f64, f64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    measure_with(sys, choice, start, true)
}

fn measure_with<S: MechanicalSystem>(
    sys: &S,
    choice: &Method,
    start: &State<S::Dim>,
    step_by_step: bool,
) -> (f64, f64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let schedule = Schedule {
        h: H,
        steps: STEPS,
        every: u64::MAX,
    };
    let profiling = std::env::var_os("GEOMINT_BENCH_PROFILE").is_some();
    let repetitions = if profiling {
        PROFILE_REPETITIONS
    } else {
        REPETITIONS
    };
    let one_run = || {
        let mut sum = Checksum(0.0);
        let began = Instant::now();
        for _ in 0..repetitions {
            let mut stepper =
                methods::build(choice, sys, "bench", black_box(H)).expect("method builds");
            let mut z = black_box(start.clone());
            let budget = Budget::default();
            if step_by_step {
                geomint::core::with_stepper!(&mut stepper, st => integrate(
                    sys, &mut StepByStep(st), &mut z, schedule, budget, &mut sum
                ))
            } else {
                geomint::core::with_stepper!(&mut stepper, st => integrate(
                    sys, st, &mut z, schedule, budget, &mut sum
                ))
            }
            .expect("run");
        }
        (
            began.elapsed().as_secs_f64() * 1e9 / (repetitions * STEPS) as f64,
            sum.0,
        )
    };
    if profiling {
        return one_run();
    }
    one_run();
    let mut runs: Vec<(f64, f64)> = (0..7).map(|_| one_run()).collect();
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    runs[3]
}

//! The timing loop shared by the step benchmarks: h = 0.1, one timed run = 5000 repetitions of
//! a [0, 200] integration (2000 steps each, state reset each time so that the amplitude never
//! reaches subnormal numbers), one warm-up, then the median of 7 runs.

use std::hint::black_box;
use std::time::Instant;

use geomint::core::methods::{self, Method};
use geomint::core::run::{integrate, Budget, Observer, Schedule};
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
/// Steps per integration.
pub const STEPS: u64 = 2000;
/// The step size.
pub const H: f64 = 0.1;

/// Median ns per step and the checksum of the final states.
pub fn measure<S: MechanicalSystem>(sys: &S, choice: &Method, start: &State<S::Dim>) -> (f64, f64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let schedule = Schedule {
        h: H,
        steps: STEPS,
        every: u64::MAX,
    };
    let one_run = || {
        let mut sum = Checksum(0.0);
        let began = Instant::now();
        for _ in 0..REPETITIONS {
            let mut stepper =
                methods::build(choice, sys, "bench", black_box(H)).expect("method builds");
            let mut z = black_box(start.clone());
            integrate(
                sys,
                &mut stepper,
                &mut z,
                schedule,
                Budget::default(),
                false,
                &mut sum,
            )
            .expect("run");
        }
        (
            began.elapsed().as_secs_f64() * 1e9 / (REPETITIONS * STEPS) as f64,
            sum.0,
        )
    };
    one_run();
    let mut runs: Vec<(f64, f64)> = (0..7).map(|_| one_run()).collect();
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    runs[3]
}

//! The adaptive reference against the `ode_solvers` crate's Dop853 it reproduces, timed on the
//! same problems: with its fixed-size state, and with the dynamic one geomint used to pass.

use std::hint::black_box;
use std::time::Instant;

use geomint::core::methods::{self, Method};
use geomint::core::run::{integrate, Budget, Observer, RunEnd, Schedule};
use geomint::core::system::{MechanicalSystem, State};
use nalgebra::allocator::Allocator;
use nalgebra::{DVector, DefaultAllocator, SVector};
use ode_solvers::{Dop853, OutputType};

use super::{median, SAMPLES};

/// Ignores the samples of a run.
struct Unobserved;

impl<D: nalgebra::Dim> Observer<D> for Unobserved
where
    DefaultAllocator: Allocator<D>,
{
    fn on_sample(&mut self, _: u64, _: f64, _: &State<D>) {}
}

/// A mechanical system as `ode_solvers` sees it, y = (q, p) in one vector of N = 2n components:
/// a fixed-size one (`SVector<f64, N>`) or the dynamic one geomint used to pass (`DVector`).
struct FirstOrder<'a, S> {
    sys: &'a S,
}

impl<S> Clone for FirstOrder<'_, S> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<S> Copy for FirstOrder<'_, S> {}

impl<S: MechanicalSystem> FirstOrder<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn eval(&self, y: &[f64], dy: &mut [f64]) {
        let n = y.len() / 2;
        let z = State::from_slices(self.sys.dim(), &y[..n], &y[n..]);
        let (mut dq, mut dp, mut scratch) = (z.q.clone(), z.q.clone(), z.q.clone());
        self.sys
            .vector_field(&z.q, &z.p, &mut dq, &mut dp, &mut scratch);
        dy[..n].copy_from_slice(dq.as_slice());
        dy[n..].copy_from_slice(dp.as_slice());
    }
}

impl<S: MechanicalSystem, const N: usize> ode_solvers::System<f64, SVector<f64, N>>
    for FirstOrder<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn system(&self, _t: f64, y: &SVector<f64, N>, dy: &mut SVector<f64, N>) {
        self.eval(y.as_slice(), dy.as_mut_slice());
    }
}

impl<S: MechanicalSystem> ode_solvers::System<f64, DVector<f64>> for FirstOrder<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn system(&self, _t: f64, y: &DVector<f64>, dy: &mut DVector<f64>) {
        self.eval(y.as_slice(), dy.as_mut_slice());
    }
}

/// `segments` segments of length `h` through the crate's Dop853 with the reference's settings,
/// from `y`: the end state and the accepted steps.
fn crate_run<D, F>(
    f: F,
    mut y: nalgebra::OVector<f64, D>,
    h: f64,
    segments: u64,
    tol: f64,
) -> (Vec<f64>, u64)
where
    D: nalgebra::Dim,
    DefaultAllocator: Allocator<D>,
    F: ode_solvers::System<f64, nalgebra::OVector<f64, D>> + Copy,
{
    let mut accepted = 0u64;
    for _ in 0..segments {
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
            200_000,
            u32::MAX,
            OutputType::Sparse,
        );
        let stats = solver.integrate().expect("the crate's run");
        accepted += u64::from(stats.accepted_steps);
        y = solver.y_out().last().expect("an end state").clone();
    }
    (y.iter().copied().collect(), accepted)
}

/// Times the reference against the crate's Dop853 on one problem.
pub fn against_crate<S: MechanicalSystem, const N: usize>(
    name: &str,
    sys: &S,
    start: &State<S::Dim>,
    t_end: f64,
) where
    DefaultAllocator: Allocator<S::Dim>,
{
    let f = FirstOrder { sys };
    let y0: Vec<f64> = start.q.iter().chain(start.p.iter()).copied().collect();
    for segment in [t_end / SAMPLES as f64, 0.1] {
        let segments = (t_end / segment).round() as u64;
        for tol in [1e-8, 1e-10, 1e-12] {
            let ours = || {
                let choice = Method::Reference { tolerance: tol };
                let mut stepper = methods::build(&choice, sys, "bench", segment).expect("builds");
                let mut z = black_box(start).clone();
                let schedule = Schedule {
                    h: segment,
                    steps: segments,
                    every: segments,
                };
                let (stop, _) = integrate(
                    sys,
                    &mut stepper,
                    &mut z,
                    schedule,
                    Budget::default(),
                    &mut Unobserved,
                )
                .expect("the run");
                assert_eq!(stop, RunEnd::Finished);
                z.q.iter().chain(z.p.iter()).copied().collect::<Vec<f64>>()
            };
            let fixed = || {
                let y: [f64; N] = black_box(&y0[..]).try_into().expect("2n components");
                crate_run::<nalgebra::Const<N>, _>(f, SVector::from(y), segment, segments, tol)
            };
            let dynamic = || {
                let y = DVector::from_column_slice(black_box(&y0));
                crate_run::<nalgebra::Dyn, _>(f, y, segment, segments, tol)
            };
            let (end, accepted) = fixed();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&ours()),
                bits(&end),
                "{name} tol {tol:e}: reference against Dop853"
            );
            assert_eq!(
                bits(&dynamic().0),
                bits(&end),
                "{name} tol {tol:e}: DVector"
            );
            let time = |run: &dyn Fn()| {
                median(
                    (0..5)
                        .map(|_| {
                            let began = Instant::now();
                            run();
                            began.elapsed().as_secs_f64() * 1e3
                        })
                        .collect(),
                )
            };
            let t_ours = time(&|| {
                black_box(ours());
            });
            let t_fixed = time(&|| {
                black_box(fixed());
            });
            let t_dynamic = time(&|| {
                black_box(dynamic());
            });
            let ns = |ms: f64| ms * 1e6 / accepted as f64;
            println!(
                "| {name} | {segment} | {tol:e} | {accepted} | {:.1} | {:.1} | {:.1} | {:.2} | {:.2} |",
                ns(t_ours),
                ns(t_fixed),
                ns(t_dynamic),
                t_ours / t_fixed,
                t_ours / t_dynamic
            );
        }
    }
}

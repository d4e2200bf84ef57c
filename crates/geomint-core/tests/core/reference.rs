//! The adaptive reference (DOP853): its tableau meets the order conditions it should, and its
//! results are bit for bit those of the `ode_solvers` crate's Dop853 0.6.2 driven as geomint drove
//! it before (a fresh solver per fixed step, sparse output, the same controller settings) — on a
//! 1-, 2-, 3- and 9-dimensional system, damped and not, at loose and tight tolerances, with
//! segments short enough to be one step and long enough to need hundreds.

use crate::common;

use common::Discard;
use geomint_core::methods::dop853::DOP853;
use geomint_core::methods::{self, Method};
use geomint_core::run::{integrate, Budget, RunEnd, Schedule};
use geomint_core::system::{MechanicalSystem, State, Vector};
use geomint_core::systems::{
    ElasticPendulum3d, NBody, PairPotential, Pendulum, PlanarKind, PlanarPolar, PlanarSpring,
};
use nalgebra::allocator::Allocator;
use nalgebra::{DVector, DefaultAllocator};
use ode_solvers::{Dop853, OutputType};

/// A mechanical system as `ode_solvers` sees it: y = (q, p) in one dynamic vector.
struct FirstOrder<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys: &'a S,
    start: &'a State<S::Dim>,
}

impl<S: MechanicalSystem> ode_solvers::System<f64, DVector<f64>> for FirstOrder<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn system(&self, _t: f64, y: &DVector<f64>, dy: &mut DVector<f64>) {
        let n = self.start.q.len();
        let mut z = self.start.clone();
        for i in 0..n {
            z.q[i] = y[i];
            z.p[i] = y[n + i];
        }
        let (mut dq, mut dp, mut scratch) = (z.q.clone(), z.q.clone(), z.q.clone());
        self.sys
            .vector_field(&z.q, &z.p, &mut dq, &mut dp, &mut scratch);
        for i in 0..n {
            dy[i] = dq[i];
            dy[n + i] = dp[i];
        }
    }
}

/// `steps` segments of length `h` through the crate's Dop853 with geomint's former settings:
/// the end state and the evaluations counted.
fn crate_run<S: MechanicalSystem>(
    sys: &S,
    start: &State<S::Dim>,
    h: f64,
    steps: u64,
    tol: f64,
) -> (State<S::Dim>, u64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let n = start.q.len();
    let mut z = start.clone();
    let mut evaluations = 0u64;
    for _ in 0..steps {
        let y = DVector::from_iterator(2 * n, z.q.iter().chain(z.p.iter()).copied());
        let (end, evals) = crate_segment(FirstOrder { sys, start }, y, h, tol);
        evaluations += evals;
        for i in 0..n {
            z.q[i] = end[i];
            z.p[i] = end[n + i];
        }
    }
    (z, evaluations)
}

/// One segment [0, h] through the crate's Dop853 (free of the system's bounds, so that the
/// dynamic vector type infers).
fn crate_segment<F: ode_solvers::System<f64, DVector<f64>>>(
    f: F,
    y: DVector<f64>,
    h: f64,
    tol: f64,
) -> (DVector<f64>, u64) {
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
    let end = solver.y_out().last().expect("an end state").clone();
    (end, u64::from(stats.num_eval))
}

/// The same run through geomint's reference stepper.
fn geomint_run<S: MechanicalSystem>(
    sys: &S,
    start: &State<S::Dim>,
    h: f64,
    steps: u64,
    tol: f64,
) -> (State<S::Dim>, u64)
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let choice = Method::Reference { tolerance: tol };
    let schedule = Schedule {
        h,
        steps,
        every: steps,
    };
    let (z, stop, force_evaluations) = common::run_schedule(sys, &choice, start, schedule);
    assert_eq!(stop, RunEnd::Finished);
    (z, force_evaluations)
}

fn bits<D: nalgebra::Dim>(v: &Vector<D>) -> Vec<u64>
where
    DefaultAllocator: Allocator<D>,
{
    v.iter().map(|x| x.to_bits()).collect()
}

/// Compares the two implementations over several tolerances and segment lengths.
fn same_bits<S: MechanicalSystem>(name: &str, sys: &S, start: &State<S::Dim>, t_end: f64) -> u64
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let mut compared = 0;
    for tol in [1e-6, 1e-10, 1e-13] {
        for h in [0.05, 1.0, t_end / 3.0] {
            let steps = (t_end / h).round() as u64;
            let (ours, our_evals) = geomint_run(sys, start, h, steps, tol);
            let (theirs, their_evals) = crate_run(sys, start, h, steps, tol);
            assert_eq!(
                (bits(&ours.q), bits(&ours.p)),
                (bits(&theirs.q), bits(&theirs.p)),
                "{name}, tol {tol:e}, h {h}: {ours:?} against {theirs:?}"
            );
            assert_eq!(our_evals, their_evals, "{name}, tol {tol:e}, h {h}");
            compared += our_evals;
        }
    }
    compared
}

#[test]
fn the_reference_reproduces_the_crate_bit_for_bit() {
    let pendulum = Pendulum { gamma: 0.005 };
    let start = State::from_slices(nalgebra::U1, &[0.9 * std::f64::consts::PI], &[0.0]);
    let mut evaluations = same_bits("pendulum", &pendulum, &start, 30.0);

    let elastic = ElasticPendulum3d {
        m: 1.0,
        k: 1.0,
        l: 1.0,
        g: 1.0,
        epsilon: 0.1,
    };
    let start = State::from_slices(
        nalgebra::U3,
        &[0.0, 1.558_845_73, -0.6],
        &[1.341_640_79, 0.0, 0.0],
    );
    evaluations += same_bits("elastic_pendulum_3d", &elastic, &start, 30.0);

    // A non-separable chart (the mass matrix depends on r).
    let polar = PlanarPolar(PlanarSpring {
        m: 1.0,
        k: 1.0,
        l: 1.0,
        g: 0.2,
        kind: PlanarKind::Pendulum,
    });
    let start = State::from_slices(nalgebra::U2, &[1.3, 0.7], &[0.0, 0.1]);
    evaluations += same_bits("elastic_pendulum_2d polar", &polar, &start, 20.0);

    // Three bodies on the figure-eight choreography, damped: a run-time dimension.
    let bodies = NBody {
        masses: vec![1.0, 1.0, 1.0],
        potential: PairPotential::Gravity {
            g: 1.0,
            softening: 0.0,
        },
        gamma: 0.01,
    };
    let (x, y) = (0.970_004_36, -0.243_087_53);
    let (vx, vy) = (0.466_203_685, 0.432_365_73);
    let q = [x, y, 0.0, -x, -y, 0.0, 0.0, 0.0, 0.0];
    let p = [vx, vy, 0.0, vx, vy, 0.0, -2.0 * vx, -2.0 * vy, 0.0];
    let start = State::from_slices(nalgebra::Dyn(9), &q, &p);
    evaluations += same_bits("nbody", &bodies, &start, 6.0);
    // The comparison covered many adaptive steps, not a handful.
    assert!(evaluations > 100_000, "{evaluations} evaluations compared");
}

#[test]
fn the_tableau_meets_its_order_conditions() {
    let t = &DOP853;
    // Row sums are the nodes: c_i = Σ_j a_ij (to the 30 digits published).
    for (i, row) in t.a.iter().enumerate() {
        let sum: f64 = row.iter().sum();
        assert!(
            (sum - t.c[i]).abs() < 1e-14,
            "row {i}: Σa = {sum}, c = {}",
            t.c[i]
        );
    }
    // The quadrature conditions of order 8, Σ bᵢ cᵢ^{k−1} = 1/k, k = 1 … 8.
    for k in 1..=8 {
        let sum: f64 = t.b.iter().zip(&t.c).map(|(b, c)| b * c.powi(k - 1)).sum();
        assert!((sum - 1.0 / f64::from(k)).abs() < 1e-14, "k = {k}: {sum}");
    }
    // …and a condition of order 9 they do not meet, so the check can fail.
    let ninth: f64 = t.b.iter().zip(&t.c).map(|(b, c)| b * c.powi(8)).sum();
    assert!((ninth - 1.0 / 9.0).abs() > 1e-6, "Σ b c⁸ = {ninth}");
    // Trees of orders 3 to 5 with inner stage sums: Σ bᵢ aᵢⱼ cⱼ^{m} = 1/((m+1)(m+2)).
    for m in 0..=3 {
        let sum: f64 = (1..12)
            .map(|i| t.b[i] * (0..i).map(|j| t.a[i][j] * t.c[j].powi(m)).sum::<f64>())
            .sum();
        let exact = 1.0 / f64::from((m + 1) * (m + 2));
        assert!(
            (sum - exact).abs() < 1e-14,
            "Σ b a c^{m} = {sum}, exact {exact}"
        );
    }
    // The error estimators are differences of two solutions: their weights sum to zero, and the
    // third-order one's weights (on k₁, k₉, k₁₂) to one.
    let e: f64 = t.e.iter().sum();
    assert!(e.abs() < 1e-14, "Σe = {e}");
    let bhh: f64 = t.bhh.iter().sum();
    assert!((bhh - 1.0).abs() < 1e-14, "Σbhh = {bhh}");
}

/// One fixed step of the reference can take up to 2·10⁵ adaptive steps: the deadline is looked
/// at inside it too. Past the deadline the run stops at once with `time_limit` at step 0, the
/// state as it was; without one, the same step finishes, as the driver's own check alone would
/// let it (and bit for bit as before, see above).
#[test]
fn a_deadline_stops_the_reference_inside_a_long_step() {
    let pendulum = Pendulum { gamma: 0.0 };
    let start = State::from_slices(nalgebra::U1, &[2.0], &[0.0]);
    // One fixed step over t = 2000 at tolerance 1e-13: thousands of adaptive steps.
    let (h, tol) = (2000.0, 1e-13);
    let schedule = Schedule {
        h,
        steps: 1,
        every: 1,
    };
    let run = |deadline| {
        let choice = Method::Reference { tolerance: tol };
        let mut stepper = methods::build(&choice, &pendulum, "test", h).expect("builds");
        let mut z = start.clone();
        let budget = Budget {
            cancel: None,
            deadline,
        };
        let (stop, stats) = integrate(
            &pendulum,
            &mut stepper,
            &mut z,
            schedule,
            budget,
            &mut Discard,
        )
        .expect("the run");
        (stop, stats, z)
    };
    let (stop, stats, z) = run(None);
    assert_eq!(stop, RunEnd::Finished);
    assert!(
        stats.force_evaluations > 100_000,
        "{} evaluations",
        stats.force_evaluations
    );
    assert_ne!(bits(&z.q), bits(&start.q));

    // A deadline in the past: the driver's check before the first step stops it.
    let (stop, stats, z) = run(Some(std::time::Instant::now()));
    assert_eq!(stop, RunEnd::TimeLimit { step: 0 });
    assert_eq!(stats.force_evaluations, 0);
    assert_eq!((bits(&z.q), bits(&z.p)), (bits(&start.q), bits(&start.p)));

    // A deadline that passes during the step: the stepper's own check stops it there.
    let mut stepper = methods::build(&Method::Reference { tolerance: tol }, &pendulum, "test", h)
        .expect("builds");
    let mut z = start.clone();
    geomint_core::run::Stepper::set_deadline(&mut stepper, Some(std::time::Instant::now()));
    let error = geomint_core::run::Stepper::step(&mut stepper, &pendulum, &mut z, h).unwrap_err();
    assert_eq!(error, geomint_core::error::StepError::DeadlinePassed);
    assert_eq!((bits(&z.q), bits(&z.p)), (bits(&start.q), bits(&start.p)));
    let evaluations = geomint_core::run::Stepper::force_evaluations(&stepper);
    assert!(
        evaluations < 10_000,
        "{evaluations} evaluations before giving up"
    );
}

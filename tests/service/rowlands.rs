//! Rowlands time stepping (paper 001 Sec. 3.3): measured orders of the processed method, of its
//! kernel and of Störmer–Verlet, the coefficient of the original processor (h²/12, not the printed
//! h²/24), force-evaluation counts, the driver's processing contract, the requirements and the
//! `processor` option.
//!
//! The order measurements run over [`CASES`]; a system joins them with one line there.

use crate::common;

use geomint::core::diagnostics::log_log_slope;
use geomint::core::error::Field;
use geomint::core::methods::rowlands::{Processor, Rowlands};
use geomint::core::methods::{self, AnyStepper, Method, MethodId};
use geomint::core::run::{integrate, Budget, Observer, RunEnd, Schedule, Stepper};
use geomint::core::system::{MechanicalSystem, State};
use geomint::core::systems::{self, Pendulum};
use geomint_core::with_system;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, U1};

/// One system for the order measurements: its catalogue id, parameters (JSON, undamped), the
/// horizon and the step sizes. The chart and the initial state are the catalogue's defaults.
pub(crate) struct Case {
    system: &'static str,
    params: &'static str,
    t_end: f64,
    hs: [f64; 4],
}

const HS: [f64; 4] = [0.1, 0.05, 0.025, 0.0125];

/// The systems the orders are measured on, the paper's Fig. 4 first.
const CASES: &[Case] = &[
    // 001 Fig. 4: the planar elastic pendulum in Cartesian coordinates, l = m = k = 1, g = 0.2
    // (the catalogue's defaults), t_max = 4: slopes 2 for Störmer–Verlet and 4 for Rowlands, in
    // the energy and in the ℓ² state error.
    Case {
        system: "elastic_pendulum_2d",
        params: r#"{"m": 1, "k": 1, "l": 1, "g": 0.2}"#,
        t_end: 4.0,
        hs: HS,
    },
    Case {
        system: "harmonic_oscillator",
        params: r#"{"omega": 2, "gamma": 0}"#,
        t_end: 4.0,
        hs: HS,
    },
    Case {
        system: "pendulum",
        params: r#"{"gamma": 0}"#,
        t_end: 4.0,
        hs: HS,
    },
    Case {
        system: "elastic_pendulum_3d",
        params: r#"{"epsilon": 0}"#,
        t_end: 4.0,
        hs: HS,
    },
    // No analytic Hessian: the product U_qq w is a difference of gradients.
    Case {
        system: "nbody",
        params: r#"{"gamma": 0}"#,
        t_end: 2.0,
        hs: [0.04, 0.02, 0.01, 0.005],
    },
];

pub(crate) fn case_of(system: &str) -> &'static Case {
    CASES.iter().find(|c| c.system == system).expect("a case")
}

/// What is run: a method choice, or rowlands with the paper's printed coefficient h²/24 in the
/// original processor (eqs. 32–33).
#[derive(Clone, Debug)]
pub(crate) enum Variant {
    Choice(Method),
    Printed,
}

impl Variant {
    pub(crate) fn label(&self) -> String {
        match self {
            Variant::Choice(c) => c.label(),
            Variant::Printed => "rowlands(original, printed h²/24)".into(),
        }
    }

    fn stepper<S: MechanicalSystem>(&self, sys: &S, h: f64) -> AnyStepper<S>
    where
        DefaultAllocator: Allocator<S::Dim>,
    {
        match self {
            Variant::Choice(c) => methods::build(c, sys, "test", h).expect("method builds"),
            Variant::Printed => AnyStepper::Rowlands(
                Rowlands::new(sys, Processor::Original).with_original_coefficient(1.0 / 24.0),
            ),
        }
    }
}

/// Records the first sample, the largest energy drift |H_k − H_0| and the sample count.
struct Record<'a, S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    sys: &'a S,
    first: Option<State<S::Dim>>,
    last: Option<State<S::Dim>>,
    energy0: f64,
    drift: f64,
    samples: u64,
}

impl<S: MechanicalSystem> Observer<S::Dim> for Record<'_, S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn on_sample(&mut self, _step: u64, _t: f64, z: &State<S::Dim>) {
        let e = self.sys.energy(&z.q, &z.p);
        if self.first.is_none() {
            self.first = Some(z.clone());
            self.energy0 = e;
        }
        self.drift = self.drift.max((e - self.energy0).abs());
        self.last = Some(z.clone());
        self.samples += 1;
    }
}

/// One run's results.
#[derive(Debug)]
pub(crate) struct Measured {
    /// The end state, q then p.
    pub(crate) end: Vec<f64>,
    /// max_k |H(z_k) − H(z_0)| over the samples.
    pub(crate) energy_drift: f64,
    pub(crate) force_evaluations: u64,
    pub(crate) samples: u64,
}

fn flat<D: nalgebra::Dim>(z: &State<D>) -> Vec<f64>
where
    DefaultAllocator: Allocator<D>,
{
    z.q.iter().chain(z.p.iter()).copied().collect()
}

pub(crate) fn run<S: MechanicalSystem, M: Stepper<S>>(
    sys: &S,
    stepper: &mut M,
    start: &State<S::Dim>,
    schedule: Schedule,
) -> Measured
where
    DefaultAllocator: Allocator<S::Dim>,
{
    let mut record = Record {
        sys,
        first: None,
        last: None,
        energy0: 0.0,
        drift: 0.0,
        samples: 0,
    };
    let mut z = start.clone();
    let (stop, stats) = integrate(
        sys,
        stepper,
        &mut z,
        schedule,
        Budget::default(),
        &mut record,
    )
    .expect("run succeeds");
    assert_eq!(stop, RunEnd::Finished);
    // The driver's contract: the first sample is the caller's state, the last one the state it
    // leaves in z.
    assert_eq!(record.first.as_ref(), Some(start));
    assert_eq!(record.last.as_ref(), Some(&z));
    Measured {
        end: flat(&z),
        energy_drift: record.drift,
        force_evaluations: stats.force_evaluations,
        samples: record.samples,
    }
}

/// The system of `case` (in its default chart, for step h) and its default initial state.
fn system_of(case: &Case, h: f64) -> (systems::AnySystem, Vec<f64>, Vec<f64>) {
    let info = common::info(case.system);
    let params = common::params(serde_json::from_str(case.params).expect("params JSON"));
    let resolved =
        systems::params::resolve(&info, &params, &Field::new("params")).expect("valid params");
    let system = info
        .build(&resolved, &info.charts[0], h)
        .expect("a catalogue system builds");
    (system, info.q0.clone(), info.p0.clone())
}

/// The end state of `variant` on `case` with step h (sampling every `every` steps), and the
/// reference end state (the exact solution, or DOP853 at tolerance 1e-14).
pub(crate) fn measure(case: &Case, variant: &Variant, h: f64, every: u64) -> (Measured, Vec<f64>) {
    let (system, q0, p0) = system_of(case, h);
    with_system!(&system, sys => {
        let start = State::from_slices(sys.dim(), &q0, &p0);
        let mut stepper = variant.stepper(sys, h);
        let measured = run(sys, &mut stepper, &start, Schedule::new(h, case.t_end, every));
        let reference = match sys.exact(case.t_end, &start) {
            Some(z) => flat(&z),
            None => {
                let choice = Method::Reference { tolerance: 1e-14 };
                let mut st = methods::build(&choice, sys, "test", case.t_end / 8.0).unwrap();
                let sched = Schedule::new(case.t_end / 8.0, case.t_end, u64::MAX);
                run(sys, &mut st, &start, sched).end
            }
        };
        (measured, reference)
    })
}

pub(crate) fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Observed orders (ℓ² state error at t_end, largest energy drift) of `variant` on `case`.
fn orders(case: &Case, variant: &Variant) -> (f64, f64, Vec<f64>, Vec<f64>) {
    let (state, energy): (Vec<f64>, Vec<f64>) = case
        .hs
        .iter()
        .map(|&h| {
            let (m, reference) = measure(case, variant, h, 1);
            (distance(&m.end, &reference), m.energy_drift)
        })
        .unzip();
    (
        log_log_slope(&case.hs, &state),
        log_log_slope(&case.hs, &energy),
        state,
        energy,
    )
}

fn choice(id: MethodId, processor: Option<Processor>) -> Variant {
    Variant::Choice(match processor {
        Some(p) => Method::Rowlands { processor: p },
        None => Method::new(id),
    })
}

/// Expected (state, energy) orders; None where the test only reports the figure.
fn expectations() -> Vec<(Variant, Option<f64>, Option<f64>)> {
    vec![
        (
            choice(MethodId::Rowlands, Some(Processor::Cheap)),
            Some(4.0),
            Some(4.0),
        ),
        (
            choice(MethodId::Rowlands, Some(Processor::Original)),
            Some(4.0),
            Some(4.0),
        ),
        (
            choice(MethodId::Rowlands, Some(Processor::None)),
            Some(2.0),
            None,
        ),
        (Variant::Printed, Some(2.0), Some(2.0)),
        (choice(MethodId::VelocityVerlet, None), Some(2.0), Some(2.0)),
    ]
}

#[test]
fn processed_rowlands_is_fourth_order_and_its_kernel_and_the_printed_coefficient_second() {
    let mut report = Vec::new();
    let mut failures = Vec::new();
    for case in CASES {
        for (variant, state_order, energy_order) in expectations() {
            let (s, e, state, energy) = orders(case, &variant);
            report.push(format!(
                "{:22} {:36} state {s:5.2}  energy {e:5.2}   (errors at h = {:e}: state {:.2e}, energy {:.2e})",
                case.system,
                variant.label(),
                case.hs[3],
                state[3],
                energy[3]
            ));
            for (what, observed, expected) in
                [("state", s, state_order), ("energy", e, energy_order)]
            {
                if let Some(x) = expected {
                    if (observed - x).abs() > 0.25 {
                        failures.push(format!(
                            "{} on {}: {what} order {observed:.3}, expected {x}",
                            variant.label(),
                            case.system
                        ));
                    }
                }
            }
        }
    }
    println!("{}", report.join("\n"));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn forward_and_backward_neighbours_make_the_cheap_postprocessor_match_the_original_to_fourth_order()
{
    // Both post-processors invert the same kernel state: they agree up to O(h⁴).
    let case = case_of("elastic_pendulum_3d");
    let diffs: Vec<f64> = case
        .hs
        .iter()
        .map(|&h| {
            let (system, q0, p0) = system_of(case, h);
            with_system!(&system, sys => {
                let start = State::from_slices(sys.dim(), &q0, &p0);
                let mut kernel = Rowlands::new(sys, Processor::None);
                let mut z = start.clone();
                for _ in 0..10 {
                    kernel.step(sys, &mut z, h).unwrap();
                }
                let mut a = z.clone();
                let mut b = z.clone();
                assert!(Rowlands::new(sys, Processor::Cheap).post_process(sys, &z, h, &mut a).unwrap());
                assert!(Rowlands::new(sys, Processor::Original).post_process(sys, &z, h, &mut b).unwrap());
                assert!(!Rowlands::new(sys, Processor::None).post_process(sys, &z, h, &mut b.clone()).unwrap());
                distance(&flat(&a), &flat(&b))
            })
        })
        .collect();
    let order = log_log_slope(&case.hs, &diffs);
    assert!((order - 4.0).abs() < 0.3, "order {order:.3}: {diffs:?}");
}

#[test]
fn force_evaluations_are_counted_per_gradient() {
    // 40 steps, samples at 0, 10, 20, 30, 40. With an analytic Hessian (counted as none): the
    // kernel costs one gradient per step plus one for the first ∇Û; cheap pre-processing two, its
    // post-processing two per sample after the first (one ∇Û for each neighbour); the original
    // processor one gradient each way.
    let steps = 40;
    let pendulum = Pendulum { gamma: 0.0 };
    let start = State::from_slices(U1, &[2.0], &[0.3]);
    let count = |v: &Variant| {
        let mut st = v.stepper(&pendulum, 0.1);
        let m = run(&pendulum, &mut st, &start, Schedule::new(0.1, 4.0, 10));
        assert_eq!(m.samples, 5);
        m.force_evaluations
    };
    let samples_after_first = 4;
    let cases = [
        (Processor::None, 1 + steps),
        (Processor::Original, 1 + 1 + steps + samples_after_first),
        (Processor::Cheap, 2 + 1 + steps + 2 * samples_after_first),
    ];
    for (p, expected) in cases {
        let v = Variant::Choice(Method::Rowlands { processor: p });
        assert_eq!(count(&v), expected, "{}", v.label());
    }
    assert_eq!(
        count(&Variant::Choice(Method::new(MethodId::VelocityVerlet))),
        1 + steps
    );

    // Without an analytic Hessian (N bodies, n = 9): the first Hessian is the system's difference
    // Hessian (2n = 18 gradients), every later product a difference along one direction (2).
    let bodies = geomint::core::systems::NBody {
        masses: vec![1.0, 2.0, 0.5],
        potential: geomint::core::systems::PairPotential::Gravity {
            g: 1.0,
            softening: 0.3,
        },
        gamma: 0.0,
    };
    let z9 = State::from_slices(
        nalgebra::Dyn(9),
        &[1.0, 0.0, 0.0, -0.5, 0.8, 0.1, -0.5, -0.8, -0.1],
        &[0.0, 0.5, 0.1, -0.4, -0.25, 0.0, 0.4, -0.25, -0.1],
    );
    let count = |p: Processor| {
        let mut st = Rowlands::new(&bodies, p);
        run(&bodies, &mut st, &z9, Schedule::new(0.1, 4.0, 10)).force_evaluations
    };
    let first_modified = 1 + 18;
    let modified = 1 + 2;
    assert_eq!(count(Processor::None), first_modified + steps * modified);
    assert_eq!(
        count(Processor::Cheap),
        2 + first_modified + steps * modified + 2 * samples_after_first * modified
    );
    // The original pre-processor asks for the first Hessian.
    assert_eq!(
        count(Processor::Original),
        (18 + 1) + modified + steps * modified + samples_after_first * modified
    );
}

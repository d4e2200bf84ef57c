//! The symmetric compositions of orders 4, 6 and 8: their weights meet the order conditions,
//! every scheme reaches its order on the damped oscillator with every kind of base, and the
//! compositions keep what their bases keep exactly (det ∂Ψ/∂z = e^{−2γh}, the elastic
//! pendulum's J₃) at s force evaluations per step. The processed one (blanes_casas_murua_8):
//! its kernel alone is of order 4, processed of order 8, every processed sample is accurate,
//! and a processor that fails is a clean error.

use crate::common;

use common::{final_state, request, run_all, run_stepper, run_to_columns, Discard};
use geomint_core::diagnostics::log_log_slope;
use geomint_core::error::{Field, StepError};
use geomint_core::methods::composition::{inverse, Processed, Scheme};
use geomint_core::methods::splitting::{self, Composition, Splitting};
use geomint_core::methods::{self, Base, Method, MethodId};
use geomint_core::run::{integrate, Budget, RunEnd, Schedule, Stepper};
use geomint_core::simulation::{Limits, MethodAt, Simulation, SimulationSpec};
use geomint_core::system::{MechanicalSystem, State};
use geomint_core::systems::{HarmonicOscillator, Pendulum};
use nalgebra::U1;
use serde_json::json;

/// Every composition of the catalogue: a new one is checked by every test here without being
/// named.
fn compositions() -> Vec<MethodId> {
    Scheme::all().map(Scheme::id).collect()
}

fn scheme(id: MethodId) -> Scheme {
    Scheme::of(id).expect("a composition")
}

/// Σ γᵏ.
fn power_sum(weights: &[f64], k: i32) -> f64 {
    weights.iter().map(|w| w.powi(k)).sum()
}

#[test]
fn weights_meet_the_order_conditions_of_symmetric_compositions() {
    // For a symmetric composition of a symmetric second-order method, order p needs (among
    // others) Σγ = 1 and Σγ^k = 0 for the odd k = 3, …, p − 1 (Hairer–Lubich–Wanner V.3); the
    // tables are given to 26 digits (Blanes–Casas–Murua's to 15), so these hold to round-off.
    for id in compositions() {
        let s = scheme(id);
        // A processed scheme's kernel too: the processor can remove the other terms of the
        // kernel's error, not these (Blanes, Casas & Murua 2006).
        let w = s.weights();
        let label = id.as_str();
        assert!(
            w.iter().zip(w.iter().rev()).all(|(a, b)| a == b),
            "{label}: not palindromic"
        );
        assert!(
            (power_sum(&w, 1) - 1.0).abs() < 4e-16 * w.len() as f64,
            "{label}: Σγ − 1 = {:e}",
            power_sum(&w, 1) - 1.0
        );
        for k in [3, 5, 7] {
            let sum = power_sum(&w, k);
            if (k as u32) < s.order() {
                assert!(sum.abs() < 1e-14, "{label}: Σγ^{k} = {sum:e}");
            } else {
                // The first condition past the order fails: the test can tell (Suzuki's 25
                // small weights give the smallest, 1.3e-4, far above round-off).
                assert!(sum.abs() > 1e-5, "{label}: Σγ^{k} = {sum:e} vanishes too");
                break;
            }
        }
        assert_eq!(id.info().order, s.order(), "{label}");
    }
    assert_eq!(Scheme::of(MethodId::KahanLi8).unwrap().weights().len(), 17);
    assert_eq!(Scheme::of(MethodId::KahanLi6).unwrap().weights().len(), 9);
    assert_eq!(Scheme::of(MethodId::Yoshida6).unwrap().weights().len(), 7);
    assert_eq!(Scheme::of(MethodId::Suzuki4).unwrap().weights().len(), 5);
    assert_eq!(Scheme::of(MethodId::McLachlan4).unwrap().weights().len(), 5);
    assert_eq!(Scheme::of(MethodId::Suzuki6).unwrap().weights().len(), 25);
}

#[test]
fn every_composition_reaches_its_order_on_the_damped_oscillator() {
    let sys = HarmonicOscillator {
        omega: 2.0,
        gamma: 0.3,
    };
    let start = State::from_slices(U1, &[1.0], &[0.5]);
    let t_end = 4.0;
    let exact = sys.exact(t_end, &start).unwrap();
    // Step sizes where the error is far above round-off and in the asymptotic range. Suzuki's
    // 25 stages of order 6 err about 100 times less than the 7 and 9 of Yoshida and Kahan–Li at
    // the same h (3e-9 at h = 0.2 on cimp), and reach round-off at h = 0.025: they take the
    // longer steps of the eighth-order methods.
    let steps = |scheme: Scheme| -> [f64; 4] {
        match (scheme.order(), scheme.weights().len()) {
            (4, _) => [0.1, 0.05, 0.025, 0.0125],
            (6, stages) if stages <= 9 => [0.2, 0.1, 0.05, 0.025],
            _ => [0.4, 0.2, 0.1, 0.05],
        }
    };
    let bases = [
        MethodId::Modin3s,
        MethodId::Modin2s,
        MethodId::Csv1,
        MethodId::Csv2,
        MethodId::Cimp,
        MethodId::PositionVerlet,
        MethodId::VelocityVerlet,
        MethodId::ImplicitMidpoint,
    ];
    let mut report = Vec::new();
    for id in compositions() {
        let nominal = f64::from(scheme(id).order());
        for base in bases {
            let choice = Method::composition(scheme(id), Base::of(base).unwrap());
            let hs = steps(scheme(id));
            let errors: Vec<f64> = hs
                .iter()
                .map(|&h| {
                    let z = final_state(&sys, &choice, &start, h, t_end);
                    (z.q[0] - exact.q[0]).hypot(z.p[0] - exact.p[0])
                })
                .collect();
            let order = log_log_slope(&hs, &errors);
            report.push(format!(
                "{:32} observed {order:.3} (errors {:.2e} … {:.2e})",
                choice.label(),
                errors[0],
                errors[3]
            ));
            assert!(
                (order - nominal).abs() <= 0.3,
                "{} observed order {order:.3}, nominal {nominal}: errors {errors:?}",
                choice.label()
            );
        }
    }
    println!("{}", report.join("\n"));
}

#[test]
fn mclachlans_five_stages_err_less_than_the_triple_jumps_three_at_equal_cost() {
    // McLachlan (1995) spends two more stages than the triple jump on a smaller error constant
    // (his free weight γ₁ = 0.28). At equal force evaluations (h = 0.1 against 0.06, 300 stages
    // each over t = 6) the damped oscillator measures what that buys, on two kinds of base.
    let sys = HarmonicOscillator {
        omega: 2.0,
        gamma: 0.3,
    };
    let start = State::from_slices(U1, &[1.0], &[0.5]);
    let t_end = 6.0;
    let exact = sys.exact(t_end, &start).unwrap();
    for base in [Base::Modin3s, Base::VelocityVerlet] {
        let error = |id: MethodId, h: f64| {
            let choice = Method::composition(scheme(id), base);
            let (z, end, forces) =
                common::run_schedule(&sys, &choice, &start, Schedule::new(h, t_end, u64::MAX));
            assert_eq!(end, RunEnd::Finished);
            ((z.q[0] - exact.q[0]).hypot(z.p[0] - exact.p[0]), forces)
        };
        let (mclachlan, mclachlan_forces) = error(MethodId::McLachlan4, 0.1);
        let (triple_jump, triple_jump_forces) = error(MethodId::TripleJump, 0.06);
        assert_eq!(mclachlan_forces, triple_jump_forces, "{base:?}");
        let gain = triple_jump / mclachlan;
        println!("{base:?}: triple jump {triple_jump:.3e}, McLachlan {mclachlan:.3e}: {gain:.1}×");
        assert!(
            gain > 3.0,
            "{base:?}: only {gain:.2}× ({triple_jump:e} / {mclachlan:e})"
        );
    }
}

#[test]
fn compositions_of_conformal_bases_stay_conformal_symplectic() {
    // det ∂Ψ/∂z = e^{−2γh} per step, with negative sub-steps running the damping backwards. (A
    // processed method's step Jacobian is its kernel's conjugated by the processor's: the same
    // determinant.)
    for schemes in compositions().chunks(3) {
        conformal_symplectic(schemes);
    }
}

/// The Jacobian defect of each of `schemes` over three bases, on a linear and a nonlinear system.
fn conformal_symplectic(schemes: &[MethodId]) {
    let methods: Vec<MethodAt> = schemes
        .iter()
        .flat_map(|&id| {
            [Base::Modin3s, Base::Csv1, Base::Csv2]
                .map(|base| Method::composition(scheme(id), base))
        })
        .enumerate()
        .map(|(i, method)| MethodAt {
            method,
            field: Field::new("methods").index(i),
        })
        .collect();
    for (system, params, q0) in [
        (
            "harmonic_oscillator",
            json!({"omega": 3.51, "gamma": 0.4}),
            1.0,
        ),
        ("pendulum", json!({"gamma": 0.3}), 2.8),
    ] {
        let req = SimulationSpec {
            methods: methods.clone(),
            jacobian_defect: true,
            q0: Some(vec![q0]),
            p0: Some(vec![0.1]),
            ..request(system, params, &[], 0.2, 20.0)
        };
        let (sim, runs) = run_all(&req);
        for (choice, run) in sim.methods.iter().zip(&runs) {
            let defects = run.jacobian_defect.as_ref().expect("defect requested");
            let worst = defects.iter().cloned().fold(0.0, f64::max);
            assert!(
                worst < 1e-12,
                "{system} {}: det defect {worst:e}",
                choice.label()
            );
        }
    }
}

#[test]
fn compositions_keep_j3_and_cost_one_force_evaluation_per_stage() {
    // The elastic pendulum of paper 000 Sec. 6.2 with weak damping: J₃ = (q × p)_z is conserved
    // by every sub-flow of 3S, so by any composition of it, negative sub-steps included.
    let methods: Vec<&str> = compositions().iter().map(|id| id.as_str()).collect();
    let req = request(
        "elastic_pendulum_3d",
        json!({"epsilon": 0.001}),
        &methods,
        0.2,
        200.0,
    );
    let sim = Simulation::prepare(&req, &Limits::default()).unwrap();
    for (i, choice) in sim.methods.iter().enumerate() {
        let (run, outcome) = run_to_columns(&sim, i, None, Default::default()).unwrap();
        let j3 = &run.invariants["J3"];
        let drift = j3.iter().map(|v| (v - j3[0]).abs()).fold(0.0, f64::max);
        assert!(drift < 1e-13, "{}: J3 drift {drift:e}", choice.label());
        // 1000 steps of s stages, each one kick; the fused damping and drift flows cost nothing.
        // A processor's stages cost one kick each too, once before the first step and once per
        // output after step 0.
        let stages = scheme(choice.id()).weights().len() as u64;
        let processing = scheme(choice.id())
            .processor()
            .map_or(0, |p| p.len() as u64);
        let outputs = run.t.len() as u64 - 1;
        assert_eq!(
            outcome.stats.force_evaluations,
            1000 * stages + processing * (1 + outputs),
            "{}",
            choice.label()
        );
    }
}

/// The error at t_end of `stepper` (a fresh one per step size) on the damped oscillator from
/// (1, 0.5), against the exact solution, for each h.
fn oscillator_errors<M: Stepper<HarmonicOscillator>>(
    hs: &[f64],
    mut stepper: impl FnMut(&HarmonicOscillator) -> M,
) -> Vec<f64> {
    let sys = HarmonicOscillator {
        omega: 2.0,
        gamma: 0.3,
    };
    let start = State::from_slices(U1, &[1.0], &[0.5]);
    let t_end = 4.0;
    let exact = sys.exact(t_end, &start).unwrap();
    hs.iter()
        .map(|&h| {
            let (z, stop, _) = run_stepper(
                &sys,
                &mut stepper(&sys),
                &start,
                Schedule::new(h, t_end, 10),
            );
            assert_eq!(stop, RunEnd::Finished);
            (z.q[0] - exact.q[0]).hypot(z.p[0] - exact.p[0])
        })
        .collect()
}

#[test]
fn the_processed_kernel_is_fourth_order_alone_and_eighth_order_processed() {
    // Blanes–Casas–Murua's kernel weights meet Σγ^k = 0 for k = 3, 5, 7 (the test above) but
    // not the other conditions of order 6: alone, the kernel is a fourth-order method. Its
    // processor's weights sum to zero (π is near the identity), the output map is π's exact
    // inverse, and the processed method π⁻¹ ∘ Kⁿ ∘ π is of order 8.
    let s = Scheme::of(MethodId::BlanesCasasMurua8).unwrap();
    let kernel = s.weights();
    let processor = s.processor().expect("a processed scheme");
    assert_eq!((kernel.len(), processor.len()), (13, 20));
    assert!(kernel.iter().zip(kernel.iter().rev()).all(|(a, b)| a == b));
    assert!((power_sum(&kernel, 1) - 1.0).abs() < 1e-15);
    assert!(power_sum(&processor, 1).abs() < 1e-15);
    let back = inverse(&processor);
    assert!(back
        .iter()
        .zip(processor.iter().rev())
        .all(|(a, b)| *a == -*b));

    let hs = [0.4, 0.2, 0.1, 0.05];
    let composition = |weights: &[f64]| {
        let weights = weights.to_vec();
        move |sys: &HarmonicOscillator| {
            Splitting::new(sys, Composition::new(splitting::MODIN_3S, &weights), None)
        }
    };
    let alone = oscillator_errors(&hs, composition(&kernel));
    let (pre, post) = (composition(&processor), composition(&back));
    let kern = composition(&kernel);
    let processed = oscillator_errors(&hs, |sys| Processed::new(kern(sys), pre(sys), post(sys)));
    // Read the other way (π⁻¹ first, π at the outputs), the processor does not help: order 4.
    let (pre, post) = (composition(&processor), composition(&back));
    let swapped = oscillator_errors(&hs, |sys| Processed::new(kern(sys), post(sys), pre(sys)));
    let order = |errors: &[f64]| log_log_slope(&hs, errors);
    println!(
        "kernel alone: order {:.3} ({:.2e} … {:.2e}); processed: order {:.3} ({:.2e} … {:.2e}); \
         processor swapped: order {:.3}",
        order(&alone),
        alone[0],
        alone[3],
        order(&processed),
        processed[0],
        processed[3],
        order(&swapped)
    );
    assert!((order(&alone) - 4.0).abs() < 0.3, "kernel {alone:?}");
    assert!(
        (order(&processed) - 8.0).abs() < 0.3,
        "processed {processed:?}"
    );
    assert!((order(&swapped) - 4.0).abs() < 0.3, "swapped {swapped:?}");
}

#[test]
fn every_processed_sample_is_accurate_whatever_the_base() {
    // π⁻¹ runs at every sample (here every step) from a kernel state it has not seen, so it must
    // not reuse a force from its previous call: with velocity Verlet, csv1 or csv2 as the base,
    // whose first flow is a kick, a stale force would put every sample off by O(h).
    let sys = HarmonicOscillator {
        omega: 2.0,
        gamma: 0.3,
    };
    let start = State::from_slices(U1, &[1.0], &[0.5]);
    let bases = [
        Base::VelocityVerlet,
        Base::Csv1,
        Base::Csv2,
        Base::Modin3s,
        Base::Cimp,
    ];
    let methods: Vec<MethodAt> = bases
        .iter()
        .enumerate()
        .map(|(i, &base)| MethodAt {
            method: Method::composition(Scheme::of(MethodId::BlanesCasasMurua8).unwrap(), base),
            field: Field::new("methods").index(i),
        })
        .collect();
    let req = SimulationSpec {
        methods,
        q0: Some(vec![1.0]),
        p0: Some(vec![0.5]),
        ..request(
            "harmonic_oscillator",
            json!({"omega": 2, "gamma": 0.3}),
            &[],
            0.1,
            4.0,
        )
    };
    let (sim, runs) = run_all(&req);
    for (choice, run) in sim.methods.iter().zip(&runs) {
        assert_eq!(run.t.len(), 41, "{}", choice.label());
        let worst = run
            .t
            .iter()
            .zip(run.q.iter().zip(&run.p))
            .map(|(&t, (q, p))| {
                let exact = sys.exact(t, &start).unwrap();
                (q[0] - exact.q[0]).hypot(p[0] - exact.p[0])
            })
            .fold(0.0, f64::max);
        println!("{}: worst sample error {worst:.2e}", choice.label());
        assert!(
            worst < 1e-9,
            "{}: worst sample error {worst:e}",
            choice.label()
        );
    }
}

#[test]
fn a_processor_that_fails_is_an_error_of_the_first_step_and_leaves_the_state() {
    // With an implicit base, π's sub-steps solve Newton problems; at h = 5 on the pendulum from
    // (3, 3) the first one does not converge. The run is refused at step 1, t = 0, and the
    // state the processor was given is left as it was.
    let sys = Pendulum { gamma: 0.3 };
    let method = Method::composition(
        Scheme::of(MethodId::BlanesCasasMurua8).unwrap(),
        Base::ImplicitMidpoint,
    );
    let start = State::from_slices(U1, &[3.0], &[3.0]);
    let h = 5.0;
    let mut stepper = methods::build(&method, &sys, "pendulum", h).unwrap();
    let mut z = start.clone();
    let err = stepper.pre_process(&sys, &mut z, h).unwrap_err();
    assert!(matches!(err, StepError::NewtonFailed { .. }), "{err:?}");
    assert_eq!((z.q[0], z.p[0]), (3.0, 3.0));

    let methods = vec![MethodAt {
        method,
        field: Field::new("methods").index(0),
    }];
    let req = SimulationSpec {
        methods,
        q0: Some(vec![3.0]),
        p0: Some(vec![3.0]),
        ..request("pendulum", json!({"gamma": 0.3}), &[], h, 50.0)
    };
    let sim = Simulation::prepare(&req, &Limits::default()).unwrap();
    let err = run_to_columns(&sim, 0, None, Default::default()).unwrap_err();
    let message = err.to_string();
    assert!(
        message.starts_with("step 1 (t = 0): Newton iteration did not converge"),
        "{message}"
    );
}

#[test]
fn a_processed_run_stopped_before_its_first_step_leaves_the_state_as_given() {
    // The processor runs with the first step: a run the budget stops before it (cancelled, or
    // started after its deadline) hands back the caller's state, not π(z₀), and costs nothing.
    let sys = HarmonicOscillator {
        omega: 2.0,
        gamma: 0.3,
    };
    let method = Method::composition(Scheme::of(MethodId::BlanesCasasMurua8).unwrap(), Base::Cimp);
    let cancelled = std::sync::atomic::AtomicBool::new(true);
    let budgets = [
        Budget {
            cancel: Some(&cancelled),
            deadline: None,
        },
        Budget {
            cancel: None,
            deadline: Some(std::time::Instant::now()),
        },
    ];
    for budget in budgets {
        let mut stepper = methods::build(&method, &sys, "oscillator", 0.1).unwrap();
        let mut z = State::from_slices(U1, &[1.0], &[0.5]);
        let (stop, stats) = integrate(
            &sys,
            &mut stepper,
            &mut z,
            Schedule::new(0.1, 4.0, 10),
            budget,
            &mut Discard,
        )
        .unwrap();
        assert!(
            matches!(
                stop,
                RunEnd::Cancelled { step: 0 } | RunEnd::TimeLimit { step: 0 }
            ),
            "{stop:?}"
        );
        assert_eq!((z.q[0], z.p[0], stats.force_evaluations), (1.0, 0.5, 0));
    }
}

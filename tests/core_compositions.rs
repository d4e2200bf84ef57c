//! The symmetric compositions of orders 4, 6 and 8: their weights meet the order conditions,
//! every scheme reaches its order on the damped oscillator with every kind of base, and the
//! compositions keep what their bases keep exactly (det ∂Ψ/∂z = e^{−2γh}, the elastic
//! pendulum's J₃) at s force evaluations per step.

mod common;

use common::{final_state, request, run_all, run_to_columns};
use geomint::core::diagnostics::log_log_slope;
use geomint::core::error::Field;
use geomint::core::methods::composition::Scheme;
use geomint::core::methods::{Base, Method, MethodId};
use geomint::core::simulation::{Limits, MethodAt, Simulation, SimulationSpec};
use geomint::core::system::{MechanicalSystem, State};
use geomint::core::systems::HarmonicOscillator;
use nalgebra::U1;
use serde_json::json;

const COMPOSITIONS: [MethodId; 5] = [
    MethodId::TripleJump,
    MethodId::Suzuki4,
    MethodId::Yoshida6,
    MethodId::KahanLi6,
    MethodId::KahanLi8,
];

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
    // tables are given to 26 digits, so these hold to round-off.
    for id in COMPOSITIONS {
        let s = scheme(id);
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
                // The first condition past the order fails: the test can tell.
                assert!(sum.abs() > 1e-3, "{label}: Σγ^{k} = {sum:e} vanishes too");
                break;
            }
        }
        assert_eq!(id.info().order, s.order(), "{label}");
    }
    assert_eq!(Scheme::KahanLi8.weights().len(), 17);
    assert_eq!(Scheme::KahanLi6.weights().len(), 9);
    assert_eq!(Scheme::Yoshida6.weights().len(), 7);
    assert_eq!(Scheme::Suzuki4.weights().len(), 5);
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
    // Step sizes where the error is far above round-off and in the asymptotic range.
    let steps = |order: u32| -> [f64; 4] {
        match order {
            4 => [0.1, 0.05, 0.025, 0.0125],
            6 => [0.2, 0.1, 0.05, 0.025],
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
    for id in COMPOSITIONS {
        let nominal = f64::from(scheme(id).order());
        for base in bases {
            let choice = Method::composition(scheme(id), Base::of(base).unwrap());
            let hs = steps(scheme(id).order());
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
fn compositions_of_conformal_bases_stay_conformal_symplectic() {
    // det ∂Ψ/∂z = e^{−2γh} per step, with negative sub-steps running the damping backwards.
    let methods: Vec<MethodAt> = COMPOSITIONS
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
    let methods: Vec<&str> = COMPOSITIONS.iter().map(|id| id.as_str()).collect();
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
        let stages = scheme(choice.id()).weights().len() as u64;
        assert_eq!(
            outcome.stats.force_evaluations,
            1000 * stages,
            "{}",
            choice.label()
        );
    }
}

//! Observed orders of every method against the damped oscillator's exact solution, and the
//! symmetry of the methods that claim it.

use crate::common;

use common::{conservative_only, every_fixed_step_choice as every_choice, final_state};
use geomint_core::diagnostics::log_log_slope;
use geomint_core::methods::{Method, MethodId};
use geomint_core::system::{MechanicalSystem, State};
use geomint_core::systems::HarmonicOscillator;
use nalgebra::U1;

fn nominal_order(c: &Method) -> f64 {
    f64::from(c.order())
}

#[test]
fn every_method_converges_with_its_nominal_order_on_the_damped_oscillator() {
    let damped = HarmonicOscillator {
        omega: 2.0,
        gamma: 0.3,
    };
    // rowlands is derived for conservative systems only: it runs undamped (tests/core_rowlands.rs
    // measures it further).
    let undamped = HarmonicOscillator {
        omega: 2.0,
        gamma: 0.0,
    };
    let start = State::from_slices(U1, &[1.0], &[0.5]);
    let t_end = 4.0;
    let hs = [0.04, 0.02, 0.01, 0.005];
    let mut report = Vec::new();
    // At these steps orders 6 and 8 reach round-off; tests/core_compositions.rs measures them
    // at larger steps.
    for choice in every_choice().into_iter().filter(|c| c.order() <= 4) {
        let sys = if conservative_only(&choice) {
            &undamped
        } else {
            &damped
        };
        let exact = sys.exact(t_end, &start).unwrap();
        let errors: Vec<f64> = hs
            .iter()
            .map(|&h| {
                let z = final_state(sys, &choice, &start, h, t_end);
                ((z.q[0] - exact.q[0]).powi(2) + (z.p[0] - exact.p[0]).powi(2)).sqrt()
            })
            .collect();
        let order = log_log_slope(&hs, &errors);
        report.push(format!("{:32} observed {order:.3}", choice.label()));
        assert!(
            (order - nominal_order(&choice)).abs() <= 0.2,
            "{} observed order {order:.3}, nominal {}: errors {errors:?}",
            choice.label(),
            nominal_order(&choice)
        );
    }
    println!("{}", report.join("\n"));
}

#[test]
fn reference_matches_the_exact_solution_to_its_tolerance() {
    for gamma in [0.3, 2.0, 3.0] {
        // under-, critically and over-damped
        let sys = HarmonicOscillator { omega: 2.0, gamma };
        let start = State::from_slices(U1, &[1.0], &[0.5]);
        let exact = sys.exact(10.0, &start).unwrap();
        let z = final_state(&sys, &Method::new(MethodId::Reference), &start, 0.5, 10.0);
        let err = (z.q[0] - exact.q[0]).abs() + (z.p[0] - exact.p[0]).abs();
        assert!(err < 1e-11, "gamma {gamma}: reference error {err:e}");
    }
}

#[test]
fn exact_solution_satisfies_the_equation_in_all_three_regimes() {
    // Checks q' = p and p' = −ω²q − 2γp by central differences of the closed form.
    for gamma in [0.5, 2.0, 3.5] {
        let sys = HarmonicOscillator { omega: 2.0, gamma };
        let d = 1e-5;
        for t in [0.3, 1.7, 4.0] {
            let (q, p) = sys.solution(t, 0.7, -0.2);
            let (qa, pa) = sys.solution(t + d, 0.7, -0.2);
            let (qb, pb) = sys.solution(t - d, 0.7, -0.2);
            let dq = (qa - qb) / (2.0 * d);
            let dp = (pa - pb) / (2.0 * d);
            assert!(
                (dq - p).abs() < 1e-8,
                "q' = p fails at gamma {gamma}, t {t}"
            );
            assert!(
                (dp + 4.0 * q + 2.0 * gamma * p).abs() < 1e-8,
                "p' fails at gamma {gamma}, t {t}"
            );
        }
    }
}

#[test]
fn symmetric_methods_are_their_own_adjoint() {
    // Φ₋ₕ ∘ Φₕ = id to round-off for every method marked symmetric, on the nonlinear pendulum
    // (undamped for rowlands, whose symmetric part is its kernel: one step each way, without the
    // processing a run adds).
    let damped = geomint_core::systems::Pendulum { gamma: 0.2 };
    let undamped = geomint_core::systems::Pendulum { gamma: 0.0 };
    let start = State::from_slices(U1, &[2.0], &[0.3]);
    for choice in every_choice().into_iter().filter(|c| c.info().symmetric) {
        let sys = if conservative_only(&choice) {
            &undamped
        } else {
            &damped
        };
        let mut stepper = geomint_core::methods::build(&choice, sys, "pendulum", 0.1).unwrap();
        let mut z = start.clone();
        geomint_core::run::Stepper::step(&mut stepper, sys, &mut z, 0.1).unwrap();
        let mut stepper = geomint_core::methods::build(&choice, sys, "pendulum", 0.1).unwrap();
        geomint_core::run::Stepper::step(&mut stepper, sys, &mut z, -0.1).unwrap();
        let err = (z.q[0] - start.q[0]).abs() + (z.p[0] - start.p[0]).abs();
        assert!(
            err < 1e-13,
            "{}: Φ₋ₕ∘Φₕ differs from the identity by {err:e}",
            choice.label()
        );
    }
    // And Heun, which is not symmetric, is not.
    let heun = Method::new(MethodId::Heun);
    let forward = final_state(&damped, &heun, &start, 0.1, 0.1);
    let mut stepper = geomint_core::methods::build(&heun, &damped, "pendulum", 0.1).unwrap();
    let mut z = forward;
    geomint_core::run::Stepper::step(&mut stepper, &damped, &mut z, -0.1).unwrap();
    assert!((z.q[0] - start.q[0]).abs() + (z.p[0] - start.p[0]).abs() > 1e-6);
}

#[test]
fn strongly_over_damped_exact_solution_stays_finite_and_decays_at_the_slow_rate() {
    // ω = 1, γ = 10: κt passes 710 (where cosh overflows) near t = 71.
    let sys = HarmonicOscillator {
        omega: 1.0,
        gamma: 10.0,
    };
    let kappa = (99.0f64).sqrt();
    let slow = 1.0 / (10.0 + kappa); // λ₋ = ω²/(γ + κ)
    let (q100, _) = sys.solution(100.0, 1.0, 0.0);
    let (q200, p200) = sys.solution(200.0, 1.0, 0.0);
    assert!(q200.is_finite() && p200.is_finite());
    // Past the fast transient q decays exactly as e^{−λ₋ t}.
    assert!(((q200 / q100).ln() / 100.0 + slow).abs() < 1e-12);
}

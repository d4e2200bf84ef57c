//! Driven systems: a typed-in potential with the time t, run in extended phase space. Every
//! method that takes time converges with its nominal order on the driven damped Duffing
//! oscillator against the adaptive reference; the methods that cannot are refused.

use crate::common::{conservative_only, every_fixed_step_choice, final_state};
use crate::sections::duffing;
use geomint_core::diagnostics::log_log_slope;
use geomint_core::methods::build::no_time;
use geomint_core::methods::{Method, MethodId};
use geomint_core::system::{MechanicalSystem, State};
use geomint_core::systems::AnySystem;
use geomint_core::with_system;

/// The steps at which a method of order p is measured: errors well above round-off and in the
/// asymptotic range.
fn steps(order: u32) -> &'static [f64] {
    match order {
        1 | 2 => &[0.02, 0.01, 0.005, 0.0025],
        3 | 4 => &[0.1, 0.05, 0.025, 0.0125],
        5 | 6 => &[0.4, 0.2, 0.1, 0.05],
        _ => &[0.4, 0.2, 0.1],
    }
}

#[test]
fn every_method_that_takes_time_has_its_order_on_the_driven_duffing_oscillator() {
    let info = duffing(0.3, 0.5, 1.2);
    let t_end = 4.0;
    let build =
        |h: f64| -> AnySystem { info.build(&Default::default(), &info.charts[0], h).unwrap() };
    let system = build(0.1);
    let reference = with_system!(&system, sys => {
        let start = State::at_time(sys, 0.0, &[1.0], &[0.0]);
        let z = final_state(sys, &Method::Reference { tolerance: 1e-14 }, &start, 0.5, t_end);
        // The clock reached t_end with the rest.
        assert!((z.q[1] - t_end).abs() <= 1e-13, "clock {}", z.q[1]);
        (z.q[0], z.p[0])
    });
    let rate = with_system!(&system, sys => sys.damping_rate());
    let mut report = Vec::new();
    let mut refused = Vec::new();
    for method in every_fixed_step_choice() {
        if no_time(&method, rate).is_some() {
            refused.push(method.label());
            continue;
        }
        // Derived for conservative systems only (blanes_moan_srkn11): not for a damped one.
        if rate != 0.0 && conservative_only(&method) {
            continue;
        }
        let hs = steps(method.order());
        let errors: Vec<f64> = hs
            .iter()
            .map(|&h| {
                with_system!(&system, sys => {
                    let start = State::at_time(sys, 0.0, &[1.0], &[0.0]);
                    let z = final_state(sys, &method, &start, h, t_end);
                    (z.q[0] - reference.0).hypot(z.p[0] - reference.1)
                })
            })
            .collect();
        let order = log_log_slope(hs, &errors);
        report.push(format!("{} {order:.2}", method.label()));
        let nominal = f64::from(method.order());
        assert!(
            (order - nominal).abs() <= 0.3,
            "{}: observed {order:.2}, nominal {nominal}: {errors:?}",
            method.label()
        );
    }
    println!(
        "driven damped Duffing, observed orders: {}",
        report.join(", ")
    );
    println!("refused: {}", refused.join(", "));
    assert_eq!(
        refused,
        [
            "csv2",
            "cimp",
            "rowlands(none)",
            "rowlands(original)",
            "rowlands(cheap)",
            "triple_jump(csv2)",
            "triple_jump(cimp)"
        ]
    );
    let _ = MethodId::Csv1;
}

#[test]
fn chaos_indicators_run_on_a_driven_system_in_extended_phase_space() {
    use geomint_core::chaos::{ChaosSpec, Indicator};
    use geomint_core::run::{Budget, RunEnd};
    use geomint_core::simulation::{Limits, Simulation, SimulationSpec};
    // The damped driven Duffing oscillator: its state carries the clock t (a request for
    // indicators once panicked building the start state without it).
    let mut spec = SimulationSpec::new(
        duffing(0.3, 0.5, 1.2),
        &[Method::new(MethodId::Csv1)],
        0.05,
        200.0,
    );
    spec.q0 = Some(vec![1.0]);
    spec.p0 = Some(vec![0.0]);
    let sim = Simulation::prepare(&spec, &Limits::default())
        .and_then(|s| s.with_chaos(&ChaosSpec::new(&[Indicator::Lyapunov])))
        .expect("indicators are taken on a driven system");
    let (columns, outcome) =
        crate::common::run_to_columns(&sim, 0, None, Budget::default()).expect("the run succeeds");
    assert_eq!(outcome.stop, RunEnd::Finished);
    let spectrum = columns
        .lyapunov
        .as_ref()
        .and_then(|l| l.last())
        .expect("a spectrum at the last sample");
    // Two exponents (the default for one degree of freedom), finite and largest first; at
    // δ = 0.3, A = 0.5, ω = 1.2 the forced two-well oscillator is on its chaotic attractor (the
    // parameters of the classic strange-attractor pictures of this equation), so the largest
    // is positive.
    assert_eq!(spectrum.len(), 2, "{spectrum:?}");
    assert!(spectrum.iter().all(|l| l.is_finite()), "{spectrum:?}");
    assert!(spectrum[0] >= spectrum[1], "{spectrum:?}");
    assert!(spectrum[0] > 0.05, "λ_max = {}: {spectrum:?}", spectrum[0]);
}

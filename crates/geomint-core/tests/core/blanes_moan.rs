//! Blanes & Moan's optimized splittings (J. Comput. Appl. Math. 142 (2002) 313–330), each one
//! sequence and one catalogue entry: S₆ reaches order 4 on the damped (Rayleigh) pendulum, where
//! its B-flow is the exact kick-and-damp, and SRKN₁₁ᵇ order 6 on the undamped one, against the
//! adaptive reference; both sequences are consistent and palindromic.

use crate::common;

use common::final_state;
use geomint_core::diagnostics::log_log_slope;
use geomint_core::methods::composition::Scheme;
use geomint_core::methods::splitting::{self, SubFlow};
use geomint_core::methods::{Method, MethodId};
use geomint_core::system::State;
use geomint_core::systems::Pendulum;
use nalgebra::U1;

/// The distance of `choice`'s end state from the reference's, per step size.
fn errors(sys: &Pendulum, choice: Method, hs: &[f64], t_end: f64) -> Vec<f64> {
    let start = State::from_slices(U1, &[1.2], &[0.3]);
    let truth = final_state(
        sys,
        &Method::Reference { tolerance: 1e-14 },
        &start,
        0.5,
        t_end,
    );
    hs.iter()
        .map(|&h| {
            let z = final_state(sys, &choice, &start, h, t_end);
            ((z.q[0] - truth.q[0]).powi(2) + (z.p[0] - truth.p[0]).powi(2)).sqrt()
        })
        .collect()
}

#[test]
fn s6_is_of_order_4_on_the_damped_pendulum_and_srkn11_of_order_6_undamped() {
    let t_end = 8.0;
    let hs = [0.4, 0.2, 0.1, 0.05];
    let s6 = errors(
        &Pendulum { gamma: 0.2 },
        Method::new(MethodId::BlanesMoanS6),
        &hs,
        t_end,
    );
    let order = log_log_slope(&hs, &s6);
    println!("S6 on the damped pendulum: observed order {order:.3}, errors {s6:?}");
    assert!(
        (order - 4.0).abs() < 0.15,
        "S6 observed order {order:.3}: {s6:?}"
    );
    // Larger steps for order 6, whose error at h = 0.05 already nears the reference's.
    let hs = [0.8, 0.4, 0.2];
    let srkn = errors(
        &Pendulum { gamma: 0.0 },
        Method::new(MethodId::BlanesMoanSrkn11),
        &hs,
        t_end,
    );
    let order = log_log_slope(&hs, &srkn);
    println!("SRKN11b on the pendulum: observed order {order:.3}, errors {srkn:?}");
    assert!(
        (order - 6.0).abs() < 0.3,
        "SRKN11b observed order {order:.3}: {srkn:?}"
    );
    // What the optimisation buys: at h = 0.2 (40 steps of 11 force evaluations) it is far more
    // accurate than the sixth-order composition of velocity Verlet at the same cost (63 steps
    // of 7).
    let yoshida = errors(
        &Pendulum { gamma: 0.0 },
        Method::Composition {
            scheme: Scheme::of(MethodId::Yoshida6).unwrap(),
            base: geomint_core::methods::Base::VelocityVerlet,
        },
        &[t_end / 63.0],
        t_end,
    );
    println!(
        "at equal force evaluations: SRKN11b {:e}, yoshida_6(velocity_verlet) {:e}",
        srkn[2], yoshida[0]
    );
    assert!(
        srkn[2] < yoshida[0] / 10.0,
        "SRKN11b {:e} against yoshida_6 {:e}",
        srkn[2],
        yoshida[0]
    );
}

#[test]
fn the_sequences_are_consistent_and_symmetric() {
    for (name, seq) in [
        ("blanes_moan_s6", splitting::BLANES_MOAN_S6),
        ("blanes_moan_srkn11", splitting::BLANES_MOAN_SRKN11),
    ] {
        let total = |kinds: &[SubFlow]| -> f64 {
            seq.iter()
                .filter(|(f, _)| kinds.contains(f))
                .map(|(_, w)| w)
                .sum()
        };
        assert!(
            (total(&[SubFlow::Drift]) - 1.0).abs() < 1e-15,
            "{name}: drifts"
        );
        let kicks = total(&[SubFlow::Kick, SubFlow::KickDamp]);
        assert!((kicks - 1.0).abs() < 1e-15, "{name}: kicks {kicks}");
        assert!(
            seq.iter().zip(seq.iter().rev()).all(|(a, b)| a == b),
            "{name}: not palindromic"
        );
    }
    assert_eq!(
        splitting::BLANES_MOAN_SRKN11
            .iter()
            .filter(|(f, _)| *f == SubFlow::Kick)
            .count(),
        12
    );
}

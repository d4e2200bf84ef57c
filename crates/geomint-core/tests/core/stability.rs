//! Linear stability analysis on the damped oscillator (paper 003 Ch. 3) for every method.

use geomint_core::methods::{Method, MethodId};
use geomint_core::stability::{self, Relation, StabilityAxis};

fn conformal() -> Vec<Method> {
    [
        MethodId::Cimp,
        MethodId::Csv1,
        MethodId::Csv2,
        MethodId::Modin3s,
        MethodId::Modin2s,
    ]
    .into_iter()
    .map(Method::new)
    .collect()
}

#[test]
fn conformal_methods_have_det_e_minus_2_gamma_h() {
    for choice in conformal() {
        for omega in [0.5, 1.0, 3.51, 10.0] {
            for gamma in [0.0, 0.1, 0.7, 2.0] {
                for h in [0.01, 0.1, 0.3, 0.9] {
                    let a = stability::analyse(&choice, omega, gamma, h).unwrap();
                    let expected = (-2.0 * gamma * h).exp();
                    // The determinant of a matrix with large entries carries their round-off.
                    let scale = a
                        .method
                        .matrix
                        .iter()
                        .flatten()
                        .fold(1.0f64, |m, x| m.max(x.abs()));
                    assert!(
                        (a.method.det - expected).abs() < 1e-13 * scale * scale,
                        "{} ω={omega} γ={gamma} h={h}: det {}",
                        choice.label(),
                        a.method.det
                    );
                    assert!((a.exact.det - expected).abs() < 1e-13);
                }
            }
        }
    }
}

#[test]
fn runge_kutta_methods_do_not_have_the_conformal_determinant() {
    for id in [MethodId::Heun, MethodId::Rk3, MethodId::Rk4] {
        let choice = Method::new(id);
        let a = stability::analyse(&choice, 3.51, 0.5, 0.2).unwrap();
        let miss = (a.method.det - (-0.2f64).exp()).abs();
        assert!(miss > 1e-6, "{id:?}: det misses e^(-2γh) by only {miss:e}");
        let m = stability::map(
            &choice,
            3.51,
            StabilityAxis {
                min: 0.0,
                max: 3.5,
                n: 20,
            },
            StabilityAxis {
                min: 0.0,
                max: 1.0,
                n: 20,
            },
        )
        .unwrap();
        assert!(
            m.stable.iter().any(|&s| s) && m.stable.iter().any(|&s| !s),
            "{id:?} map is all one colour"
        );
    }
}

#[test]
fn the_exact_half_trace_matches_eq_3_6() {
    let (omega, gamma, h) = (3.51f64, 0.8f64, 0.3f64);
    let beta = (omega * omega - gamma * gamma).sqrt();
    let a = stability::analyse(&Method::new(MethodId::Csv1), omega, gamma, h).unwrap();
    assert!((0.5 * a.exact.trace - (-gamma * h).exp() * (beta * h).cos()).abs() < 1e-14);
}

#[test]
fn half_traces_of_the_thesis_match_our_methods() {
    // eqs. (3.10), (3.15), (3.20)
    for (gamma, h) in [(0.3, 0.1), (1.5, 0.4), (3.0, 0.6)] {
        let omega = 3.51f64;
        let ht = |id| {
            0.5 * stability::analyse(&Method::new(id), omega, gamma, h)
                .unwrap()
                .method
                .trace
        };
        let b = 0.25f64 * h * h * (omega * omega - gamma * gamma);
        let cimp = (-gamma * h).exp() * (1.0 - b) / (1.0 + b);
        let csv1 = (-gamma * h).exp() * (1.0 - 0.5 * h * h * omega * omega) * (gamma * h).cosh();
        assert!((ht(MethodId::Cimp) - cimp).abs() < 1e-13);
        assert!((ht(MethodId::Csv1) - csv1).abs() < 1e-13);
        assert!((ht(MethodId::Csv2) - stability::csv2_half_trace(omega, gamma, h)).abs() < 1e-13);
    }
}

#[test]
fn cimp_is_stable_wherever_omega_exceeds_gamma() {
    let m = stability::map(
        &Method::new(MethodId::Cimp),
        3.51,
        StabilityAxis {
            min: 0.0,
            max: 3.5,
            n: 100,
        },
        StabilityAxis {
            min: 0.0,
            max: 1.0,
            n: 100,
        },
    )
    .unwrap();
    assert!(
        m.stable.iter().all(|&s| s),
        "unstable cells: {}",
        m.stable.iter().filter(|s| !**s).count()
    );
    assert_eq!(m.disagreements, 0);
}

#[test]
fn numerical_maps_agree_with_the_corrected_relations_not_the_printed_ones() {
    let gamma = StabilityAxis {
        min: 0.0,
        max: 3.5,
        n: 100,
    };
    let h = StabilityAxis {
        min: 0.0,
        max: 1.0,
        n: 100,
    };
    for id in [MethodId::Csv1, MethodId::Csv2] {
        let m = stability::map(&Method::new(id), 3.51, gamma, h).unwrap();
        let unstable = m.stable.iter().filter(|s| !**s).count();
        println!("{id:?}: {unstable} unstable cells, corrected relation disagrees off the boundary in {}, printed in {}", m.disagreements, m.printed_disagreements);
        assert!(
            unstable > 100,
            "{id:?}: the map should have an unstable region"
        );
        assert_eq!(m.disagreements, 0, "{id:?}");
        assert!(
            m.printed_disagreements > 100,
            "{id:?}: printed relation disagrees in only {}",
            m.printed_disagreements
        );
    }
    // Spot checks of the corrected csv1 relation hω ≤ 2 independent of γ.
    for gamma in [0.0, 1.0, 3.0] {
        assert_eq!(
            stability::analytic_stable(MethodId::Csv1, Relation::Corrected, 3.51, gamma, 0.56),
            Some(true)
        );
        assert_eq!(
            stability::analytic_stable(MethodId::Csv1, Relation::Corrected, 3.51, gamma, 0.58),
            Some(false)
        );
    }
}

#[test]
fn half_trace_error_orders() {
    // ½tr error against the exact flow: the thesis finds O(Δt⁴) for all three (after 3.13, 3.18,
    // 3.23): the one-step error of a second-order method in the trace, whose O(h³) terms cancel.
    let hs = [0.08, 0.04, 0.02, 0.01];
    for id in [MethodId::Cimp, MethodId::Csv1, MethodId::Csv2] {
        let (_, order) = stability::half_trace_error(&Method::new(id), 3.51, 0.5, &hs).unwrap();
        println!("{id:?}: ½tr error order {order:.3}");
        assert!((order - 4.0).abs() < 0.15, "{id:?}: observed order {order}");
    }
}

#[test]
fn maps_reject_bad_grids() {
    let c = Method::new(MethodId::Csv1);
    let ok = StabilityAxis {
        min: 0.0,
        max: 1.0,
        n: 10,
    };
    assert!(stability::map(&c, 3.51, StabilityAxis { n: 1, ..ok }, ok).is_err());
    assert!(stability::map(
        &c,
        3.51,
        ok,
        StabilityAxis {
            min: 1.0,
            max: 0.0,
            n: 10
        }
    )
    .is_err());
    assert!(stability::map(&c, -1.0, ok, ok).is_err());
    assert!(stability::map(&c, 3.51, StabilityAxis { n: 100_000, ..ok }, ok).is_err());
}

//! The fits behind observed orders and work–precision slopes.

use geomint_core::diagnostics::*;

#[test]
fn the_fit_recovers_a_power_law() {
    // ms = 3·error^(−1/4)
    let points: Vec<(f64, f64)> = [1e-2, 1e-4, 1e-6, 1e-8]
        .iter()
        .map(|&e: &f64| (e, 3.0 * e.powf(-0.25)))
        .collect();
    let (slope, intercept) = fit_log_log(&points).unwrap();
    assert!((slope + 0.25).abs() < 1e-12);
    assert!((intercept - 3f64.log10()).abs() < 1e-12);
    assert_eq!(fit_log_log(&points[..1]), None);
    assert_eq!(fit_line(&[1.0, 1.0], &[2.0, 3.0]), None);
}

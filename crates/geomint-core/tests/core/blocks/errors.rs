//! The error types: ranges and their messages, fields by variant.
use geomint_core::error::*;

#[test]
fn ranges_check_and_show_their_bounds() {
    let h = Field::new("h");
    assert!(Range::POSITIVE.check(0.1, &h).is_ok());
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(Range::POSITIVE.check(bad, &h).is_err());
    }
    assert_eq!(
        Range::POSITIVE.check(-0.1, &h).unwrap_err().to_string(),
        "h: must be finite and > 0, got -0.1"
    );
    let tolerance = Range::closed(1e-14, false, 1e-2);
    assert_eq!(
        tolerance
            .check(1.0, &Field::new("methods").index(0).key("tolerance"))
            .unwrap_err()
            .to_string(),
        "methods[0].tolerance: 1 is outside the valid range [1e-14, 0.01]"
    );
    assert_eq!(show(1e6), "1000000");
    assert_eq!(show(2.5e-7), "2.5e-7");
}

#[test]
fn fields_build_paths() {
    let runs = Field::new("runs");
    assert_eq!(runs.index(1).key("h").index(2).as_str(), "runs[1].h[2]");
    assert_eq!(Field::default().key("h").as_str(), "h");
}

//! The symplectic frame of the chaos indicators: orthonormal, Lagrangian, kept in range.

use geomint_core::chaos::frame::*;
use nalgebra::DMatrix;

#[test]
fn the_frame_is_orthonormal_and_a_lagrangian_flag() {
    for n in 1..=5 {
        let v = start(n, 2 * n);
        let gram = v.transpose() * &v;
        assert!(
            (gram - DMatrix::<f64>::identity(2 * n, 2 * n)).amax() < 1e-15,
            "n = {n}"
        );
        // Ω⁻¹ v_{2n−1−j} = −v_j for j < n (0-based), so the flags are nested.
        for j in 0..n {
            let partner = v.column(2 * n - 1 - j);
            for l in 0..n {
                // Ω⁻¹(a; b) = (−b; a).
                assert!((partner[n + l] - v[(l, j)]).abs() < 1e-15);
                assert!((partner[l] + v[(n + l, j)]).abs() < 1e-15);
            }
        }
    }
}

#[test]
fn orthonormalising_gives_a_triangular_factor_of_the_columns() {
    let a = DMatrix::from_row_slice(
        4,
        3,
        &[1.0, 2.0, 0.5, 1e-3, 1.0, 2.0, 3.0, -1.0, 1.0, 0.0, 4.0, 1e8],
    );
    let mut q = a.clone();
    let mut r = DMatrix::zeros(3, 3);
    orthonormalise(&mut q, &mut r);
    assert!((&q * &r - &a).amax() < 1e-7 * a.amax());
    assert!((q.transpose() * &q - DMatrix::<f64>::identity(3, 3)).amax() < 1e-15);
    // Dependent and zero columns: the log-growth stays finite, the basis orthonormal.
    let mut d = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 1.0, 0.0]);
    let mut r2 = DMatrix::zeros(2, 2);
    orthonormalise(&mut d, &mut r2);
    assert_eq!(r2[(1, 1)], 0.0);
    assert!((d.transpose() * &d - DMatrix::<f64>::identity(2, 2)).amax() < 1e-15);
    assert!(log_growth(0.0, 0).is_finite());
}

#[test]
fn the_guard_keeps_columns_in_range_exactly() {
    let mut w = DMatrix::from_row_slice(2, 2, &[1e200, 1e-200, 3e200, 2e-200]);
    let before = w.clone();
    let mut e = [0, 0];
    guard(&mut w, &mut e);
    for col in 0..2 {
        let back = power_of_two(e[col]);
        for row in 0..2 {
            assert_eq!(w[(row, col)] * back, before[(row, col)]);
        }
        assert!((1.0..4.0).contains(&w.column(col).norm()));
    }
}

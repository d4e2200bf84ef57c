//! The exact damping flows of typed-in systems with a mass and a damping matrix.

use geomint_core::systems::custom::damping::*;

/// A x for row-major A.
fn mul(a: &[f64], x: &[f64], n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (0..n).map(|k| a[i * n + k] * x[k]).sum())
        .collect()
}

#[test]
fn the_flows_solve_their_linear_equations() {
    // M = [[2, 0.5], [0.5, 1]], D = [[1, 0.3], [0.3, 0.2]] (positive definite), ε = 0.7.
    let n = 2;
    let m = [2.0, 0.5, 0.5, 1.0];
    let d = [1.0, 0.3, 0.3, 0.2];
    let eps = 0.7;
    let factor = MassFactor::new(&m, n).unwrap();
    let flows = DampingFlows::new(&factor);
    // A = ε D M⁻¹; M⁻¹ = [[1, −0.5], [−0.5, 2]] / 1.75.
    let minv = [1.0 / 1.75, -0.5 / 1.75, -0.5 / 1.75, 2.0 / 1.75];
    let a: Vec<f64> = (0..4)
        .map(|k| {
            let (i, j) = (k / 2, k % 2);
            eps * (0..2).map(|l| d[i * 2 + l] * minv[l * 2 + j]).sum::<f64>()
        })
        .collect();
    // (I + cA) x = p.
    let p = [0.4, -1.3];
    let mut x = p;
    flows.solve(eps, &d, &mut x, 0.6);
    let ax = mul(&a, &x, n);
    for i in 0..n {
        assert!((x[i] + 0.6 * ax[i] - p[i]).abs() < 1e-14);
    }
    // The decay against many small forward-Euler... rather: e^{−τA} e^{τA} = I and
    // d/dτ e^{−τA}p = −A e^{−τA}p by central differences.
    let tau = 0.8;
    let (mut plus, mut minus, mut mid) = (p, p, p);
    flows.decay(eps, &d, &mut plus, tau + 1e-6);
    flows.decay(eps, &d, &mut minus, tau - 1e-6);
    flows.decay(eps, &d, &mut mid, tau);
    let amid = mul(&a, &mid, n);
    for i in 0..n {
        let derivative = (plus[i] - minus[i]) / 2e-6;
        assert!(
            (derivative + amid[i]).abs() < 1e-8,
            "{derivative} vs {}",
            -amid[i]
        );
    }
    // The kick-and-damp solves p' = −g − A p: check the derivative too.
    let g = [0.3, 0.9];
    let (mut plus, mut minus, mut mid) = (p, p, p);
    flows.kick_decay(eps, &d, &mut plus, &g, tau + 1e-6);
    flows.kick_decay(eps, &d, &mut minus, &g, tau - 1e-6);
    flows.kick_decay(eps, &d, &mut mid, &g, tau);
    let amid = mul(&a, &mid, n);
    for i in 0..n {
        let derivative = (plus[i] - minus[i]) / 2e-6;
        assert!((derivative + g[i] + amid[i]).abs() < 1e-8);
    }
    // A singular D (rank one, kernel (1, −1)): along the kernel the kick enters undamped,
    // so the same equation holds with A of rank one.
    let d1 = [1.0, 1.0, 1.0, 1.0];
    let a1: Vec<f64> = (0..4)
        .map(|k| {
            let (i, j) = (k / 2, k % 2);
            eps * (0..2).map(|l| d1[i * 2 + l] * minv[l * 2 + j]).sum::<f64>()
        })
        .collect();
    let (mut plus, mut minus, mut mid) = (p, p, p);
    flows.kick_decay(eps, &d1, &mut plus, &g, tau + 1e-6);
    flows.kick_decay(eps, &d1, &mut minus, &g, tau - 1e-6);
    flows.kick_decay(eps, &d1, &mut mid, &g, tau);
    let amid = mul(&a1, &mid, n);
    for i in 0..n {
        let derivative = (plus[i] - minus[i]) / 2e-6;
        assert!((derivative + g[i] + amid[i]).abs() < 1e-8);
    }
    // No time, no change (to round-off of the eigenvector basis).
    let mut same = p;
    flows.kick_decay(eps, &d1, &mut same, &g, 0.0);
    for i in 0..n {
        assert!((same[i] - p[i]).abs() < 1e-14 * p[i].abs());
    }
}

#[test]
fn a_matrix_that_is_not_positive_definite_has_no_factor() {
    assert!(MassFactor::new(&[1.0, 2.0, 2.0, 1.0], 2).is_none());
    assert!(MassFactor::new(&[f64::NAN], 1).is_none());
}

//! A typed-in system's constant mass matrix in the form its steps use ([`InverseMass`], whose
//! arithmetic `flows::mass` holds): which form represents M⁻¹ exactly, and ½ vᵀ M⁻¹ v.

use super::damping::MassFactor;
pub use crate::flows::InverseMass;

impl InverseMass {
    /// M⁻¹ of the symmetric positive definite `m` (row-major n×n, factor `factor`).
    pub(super) fn new(m: &[f64], factor: &MassFactor, n: usize) -> Self {
        let off_diagonal_zero = (0..n * n).all(|k| k / n == k % n || m[k] == 0.0);
        let diagonal: Vec<f64> = (0..n).map(|i| m[i * n + i]).collect();
        if off_diagonal_zero && diagonal.iter().all(|&d| d == 1.0) {
            InverseMass::Unit
        } else if off_diagonal_zero && diagonal.iter().all(|&d| d == diagonal[0]) {
            InverseMass::Scalar(diagonal[0])
        } else if off_diagonal_zero {
            InverseMass::Diagonal(diagonal)
        } else {
            InverseMass::Full(factor.inverse())
        }
    }

    /// ½ vᵀ M⁻¹ v.
    #[inline]
    pub(super) fn half_quadratic(&self, v: &[f64]) -> f64 {
        match self {
            // (0.5 Σ x²) / 1 is 0.5 Σ x², to the bit.
            InverseMass::Unit => 0.5 * v.iter().map(|x| x * x).sum::<f64>(),
            InverseMass::Scalar(m) => 0.5 * v.iter().map(|x| x * x).sum::<f64>() / m,
            InverseMass::Diagonal(d) => 0.5 * v.iter().zip(d).map(|(x, m)| x * x / m).sum::<f64>(),
            InverseMass::Full(inverse) => {
                let n = v.len();
                let quadratic: f64 = (0..n)
                    .map(|i| {
                        let row: f64 = (0..n).map(|j| inverse[i * n + j] * v[j]).sum();
                        v[i] * row
                    })
                    .sum();
                0.5 * quadratic
            }
        }
    }
}

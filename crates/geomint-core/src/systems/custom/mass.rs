//! M⁻¹ of a typed-in system's constant mass matrix ([`InverseMass`]).

use super::damping::MassFactor;

/// M⁻¹ of a constant mass matrix, in the cheapest form that represents it exactly.
#[derive(Debug)]
pub enum InverseMass {
    /// M = I: M⁻¹p = p (the same bits as p / 1, without a division in the step's chain).
    Unit,
    /// M = m I: M⁻¹p = p / m.
    Scalar(f64),
    /// A diagonal M: M⁻¹p = p_i / m_i.
    Diagonal(Vec<f64>),
    /// A full M: M⁻¹, row-major.
    Full(Vec<f64>),
}

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

    /// out = M⁻¹ v.
    #[inline]
    pub(crate) fn apply(&self, v: &[f64], out: &mut [f64]) {
        match self {
            InverseMass::Unit => out.copy_from_slice(v),
            InverseMass::Scalar(m) => {
                for (o, x) in out.iter_mut().zip(v) {
                    *o = x / m;
                }
            }
            InverseMass::Diagonal(d) => {
                for ((o, x), m) in out.iter_mut().zip(v).zip(d) {
                    *o = x / m;
                }
            }
            InverseMass::Full(inverse) => {
                let n = v.len();
                for (i, o) in out.iter_mut().enumerate() {
                    *o = inverse[i * n..(i + 1) * n]
                        .iter()
                        .zip(v)
                        .map(|(a, x)| a * x)
                        .sum();
                }
            }
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

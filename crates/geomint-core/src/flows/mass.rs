//! M⁻¹ of a constant mass matrix ([`InverseMass`]), in the form the drift's velocity is
//! computed in on every path: the one run of a typed-in system, its lanes and compiled steps.

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
}

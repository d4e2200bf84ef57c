//! The deviation vectors' frame: where they start, how they are re-orthonormalised, and how
//! their growth is kept in range between re-orthonormalisations.
//!
//! **Start.** The k vectors are the first k columns of V = S·Π, where Π orders the unit vectors
//! as (q₁, …, qₙ, pₙ, …, p₁) and S = [[X, −Y], [Y, X]] is the orthogonal symplectic matrix of the
//! unitary U = X + iY = F/√n (F the discrete Fourier matrix, F_lj = e^{2πi lj/n}). So v₁ moves
//! every coordinate alike and no momentum, v₂… mix the coordinates, and with k = 2n the frame is
//! a Lagrangian flag: Ω⁻¹v_{2n+1−j} lies in span(v₁, …, v_j) (Ω⁻¹ commutes with S, and
//! Ω⁻¹p_j = −q_j). For a tangent map A with AᵀΩA = c²Ω that makes the QR estimates pair exactly
//! at every finite time, not only in the limit: the k-volume of A v₁…v_k and the (2n−k)-volume
//! of A applied to the rest are related through A⁻ᵀ = c⁻²ΩAΩ⁻¹, so
//! Σ_{i≤2n−k} ln R̃_ii = Σ_{i≤k} ln R̃_ii + (2n − 2k) ln c and λ_i + λ_{2n+1−i} = 2 ln c/t, with
//! c² = e^{−2γt}: −2γ for a conformal symplectic method, 0 for a symplectic one. (A frame of
//! generic orthonormal vectors pairs only as t → ∞, with an O(1/t) error.)
//!
//! **QR.** Benettin, Galgani, Giorgilli & Strelcyn (Meccanica 15, 1980): the vectors are
//! orthonormalised every `qr_every` steps by Gram–Schmidt (each column twice against the earlier
//! ones, which keeps the basis orthogonal to round-off however close the vectors have come), and
//! ln R_ii is summed: Σ ln R_ii/t → λ_i. The product of the R's is the R̃ of A·V = Q R̃, so extra
//! re-orthonormalisations change nothing but round-off.
//!
//! **Range.** Between re-orthonormalisations a vector grows or shrinks like e^{λt}; a column
//! whose squared norm leaves [2⁻⁶⁰⁰, 2⁶⁰⁰] is scaled by a power of two (exact) and the exponent
//! kept after every step, so a finite run never overflows whatever the interval (a single step
//! would have to grow a vector by 2⁷⁰⁰). A column that collapses to zero
//! (a singular tangent map) is counted as a contraction by the smallest normal number,
//! e^{−708.4}, and replaced by a unit vector orthogonal to the others.

use nalgebra::DMatrix;

/// Squared norms outside [2⁻⁶⁰⁰, 2⁶⁰⁰] are brought back to about 1.
const GUARD_EXPONENT: i32 = 600;

/// The first k columns of the frame of the module docs, for n degrees of freedom.
pub fn start(n: usize, k: usize) -> DMatrix<f64> {
    let mut v = DMatrix::zeros(2 * n, k);
    let scale = 1.0 / (n as f64).sqrt();
    let angle = |l: usize, j: usize| 2.0 * std::f64::consts::PI * ((l * j) % n) as f64 / n as f64;
    for col in 0..k {
        for l in 0..n {
            let (re, im) = if col < n {
                let a = angle(l, col);
                (a.cos() * scale, a.sin() * scale)
            } else {
                let a = angle(l, 2 * n - 1 - col);
                (a.cos() * scale, a.sin() * scale)
            };
            if col < n {
                v[(l, col)] = re;
                v[(n + l, col)] = im;
            } else {
                v[(l, col)] = -im;
                v[(n + l, col)] = re;
            }
        }
    }
    v
}

/// 2^e for |e| ≤ 1022, exactly.
#[inline(always)]
pub const fn power_of_two(e: i32) -> f64 {
    f64::from_bits(((1023 + e) as u64) << 52)
}

/// Keeps each column of `w` within range: a column whose squared norm is outside
/// [2⁻⁶⁰⁰, 2⁶⁰⁰] (or under- or overflows) is multiplied by 2^{−e}, 2^e about its largest entry,
/// and e added to `exponents`.
#[inline]
pub fn guard(w: &mut DMatrix<f64>, exponents: &mut [i32]) {
    let rows = w.nrows();
    for (col, e) in exponents.iter_mut().enumerate() {
        let column = &mut w.as_mut_slice()[col * rows..(col + 1) * rows];
        let mut n2 = 0.0;
        for x in column.iter() {
            n2 += x * x;
        }
        if !in_range(n2) {
            *e += rescale(column);
        }
    }
}

/// Whether a column's squared norm `n2` is within [2⁻⁶⁰⁰, 2⁶⁰⁰] (false for NaN).
#[inline(always)]
pub fn in_range(n2: f64) -> bool {
    n2 <= power_of_two(GUARD_EXPONENT) && n2 >= power_of_two(-GUARD_EXPONENT)
}

/// The binary exponent of a positive finite x (−1023 for subnormal numbers).
fn binary_exponent(x: f64) -> i32 {
    ((x.to_bits() >> 52) & 0x7ff) as i32 - 1023
}

/// Scales `column` by 2^{−e} with 2^e ≤ its largest entry < 2^{e+1} (e within ±1022); returns
/// e, or 0 for a column that is zero or not finite.
pub fn rescale(column: &mut [f64]) -> i32 {
    let largest = column.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    if !largest.is_finite() || largest == 0.0 {
        return 0;
    }
    let e = binary_exponent(largest).clamp(-1022, 1022);
    let factor = power_of_two(-e);
    for x in column.iter_mut() {
        *x *= factor;
    }
    e
}

/// Orthonormalises the columns of `w` in place (it becomes Q) and writes R (k × k, upper
/// triangular, R_ii ≥ 0) into `r`. Each column is orthogonalised twice against the earlier
/// ones; a column left with no norm is replaced by a unit vector orthogonal to them (its R_ii
/// is 0).
pub fn orthonormalise(w: &mut DMatrix<f64>, r: &mut DMatrix<f64>) {
    let (rows, k) = w.shape();
    r.fill(0.0);
    for j in 0..k {
        for _pass in 0..2 {
            for i in 0..j {
                let mut dot = 0.0;
                for l in 0..rows {
                    dot += w[(l, i)] * w[(l, j)];
                }
                for l in 0..rows {
                    w[(l, j)] -= dot * w[(l, i)];
                }
                r[(i, j)] += dot;
            }
        }
        let mut n2 = 0.0;
        for l in 0..rows {
            n2 += w[(l, j)] * w[(l, j)];
        }
        let norm = n2.sqrt();
        if norm > 0.0 && norm.is_finite() {
            r[(j, j)] = norm;
            for l in 0..rows {
                w[(l, j)] /= norm;
            }
        } else {
            r[(j, j)] = 0.0;
            replace_collapsed(w, j);
        }
    }
}

/// Column `j` of `w` becomes the first unit vector e_m that keeps more than half its length
/// after Gram–Schmidt against columns 0..j (one always does, as j < 2n), normalised.
fn replace_collapsed(w: &mut DMatrix<f64>, j: usize) {
    let rows = w.nrows();
    for m in 0..rows {
        for l in 0..rows {
            w[(l, j)] = if l == m { 1.0 } else { 0.0 };
        }
        for i in 0..j {
            let dot = w[(m, i)];
            for l in 0..rows {
                w[(l, j)] -= dot * w[(l, i)];
            }
        }
        let n2: f64 = (0..rows).map(|l| w[(l, j)] * w[(l, j)]).sum();
        if n2 > 0.25 {
            let norm = n2.sqrt();
            for l in 0..rows {
                w[(l, j)] /= norm;
            }
            return;
        }
    }
}

/// ln R_ii + e_i ln 2, the log-growth of column i over the interval, with a zero R_ii counted as
/// the smallest normal number.
#[inline]
pub fn log_growth(r_ii: f64, exponent: i32) -> f64 {
    r_ii.max(f64::MIN_POSITIVE).ln() + f64::from(exponent) * std::f64::consts::LN_2
}

/// The directions of the vectors evolved without orthonormalisation, A v_j, in the current Q
/// basis: the columns of the accumulated R̃, each normalised (C). One interval with R and the
/// guard exponents e maps C to the normalised columns of R·diag(2^e)·C; the row scaling is done
/// relative to the largest e so that nothing overflows. A column that would have no length keeps
/// its old direction.
pub fn advance_directions(
    c: &mut DMatrix<f64>,
    r: &DMatrix<f64>,
    exponents: &[i32],
    work: &mut DMatrix<f64>,
) {
    let k = c.nrows();
    let top = exponents.iter().copied().max().unwrap_or(0);
    for j in 0..k {
        for i in 0..k {
            let mut acc = 0.0;
            for l in i..k {
                let scaled = c[(l, j)] * power_of_two((exponents[l] - top).max(-1022));
                acc += r[(i, l)] * scaled;
            }
            work[(i, j)] = acc;
        }
        let n2: f64 = (0..k).map(|i| work[(i, j)] * work[(i, j)]).sum();
        let norm = n2.sqrt();
        if norm > 0.0 && norm.is_finite() {
            for i in 0..k {
                c[(i, j)] = work[(i, j)] / norm;
            }
        }
    }
}

/// SALI = min(‖ŵ₁ + ŵ₂‖, ‖ŵ₁ − ŵ₂‖) = √(2(1 − |cos θ|)) of the first two directions, written
/// as √2 |sin θ|/√(1 + |cos θ|) with cos θ = C₁₂ and sin θ = C₂₂ (C₁ = ±e₁), which keeps its
/// relative accuracy as the vectors align (Skokos, J. Phys. A 34 (2001) 10029).
pub fn sali(c: &DMatrix<f64>) -> f64 {
    std::f64::consts::SQRT_2 * c[(1, 1)].abs() / (1.0 + c[(0, 1)].abs()).sqrt()
}

/// GALI_k = ‖ŵ₁ ∧ … ∧ ŵ_k‖ = |det C| = Π|C_ii| for the upper triangular C of unit columns
/// (Skokos, Bountis & Antonopoulos, Physica D 231 (2007) 30).
pub fn gali(c: &DMatrix<f64>) -> f64 {
    (0..c.nrows()).map(|i| c[(i, i)].abs()).product()
}

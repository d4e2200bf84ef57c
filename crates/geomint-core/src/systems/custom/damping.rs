//! The exact damping flows of a general Rayleigh damping: with q frozen, p' = −A p with
//! A = ε D(q) M⁻¹, D symmetric positive semidefinite and M constant, symmetric positive definite.
//!
//! With M = L Lᵀ (Cholesky), L⁻¹ A L = ε L⁻¹ D L⁻ᵀ =: S is symmetric positive semidefinite, so
//! with S = Q Λ Qᵀ every function of A is L Q f(Λ) Qᵀ L⁻¹:
//! - the decay e^{−τA} p,
//! - the kick-and-damp e^{−τA} p − τ φ₁(−τA) g, φ₁(z) = (e^z − 1)/z (paper 000's linear flow),
//! - the θ-method solve (I + aA)⁻¹ p.
//!
//! S is diagonalised by cyclic Jacobi rotations in place (n ≤ 32, a few sweeps), in buffers kept
//! per thread, so a step allocates nothing after the first.

use std::cell::RefCell;

/// Work space of one thread: S (then Q's eigenvalues on its diagonal), Q, and two vectors.
#[derive(Default)]
struct Scratch {
    s: Vec<f64>,
    q: Vec<f64>,
    u: Vec<f64>,
    v: Vec<f64>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// The constant mass factor of a general damping: L with M = L Lᵀ (row-major, lower).
#[derive(Clone, Debug, PartialEq)]
pub struct MassFactor {
    n: usize,
    l: Vec<f64>,
}

impl MassFactor {
    /// The Cholesky factor of the symmetric matrix `m` (row-major n×n), or `None` when `m` is
    /// not positive definite.
    pub fn new(m: &[f64], n: usize) -> Option<Self> {
        let mut l = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..=i {
                let mut sum = m[i * n + j];
                for k in 0..j {
                    sum -= l[i * n + k] * l[j * n + k];
                }
                if i == j {
                    if !(sum > 0.0) || !sum.is_finite() {
                        return None;
                    }
                    l[i * n + i] = sum.sqrt();
                } else {
                    l[i * n + j] = sum / l[j * n + j];
                }
            }
        }
        Some(MassFactor { n, l })
    }

    /// x ← L⁻¹ x (forward substitution).
    fn solve_lower(&self, x: &mut [f64]) {
        let n = self.n;
        for i in 0..n {
            let mut sum = x[i];
            for k in 0..i {
                sum -= self.l[i * n + k] * x[k];
            }
            x[i] = sum / self.l[i * n + i];
        }
    }

    /// x ← L x.
    fn mul_lower(&self, x: &mut [f64]) {
        let n = self.n;
        for i in (0..n).rev() {
            let mut sum = 0.0;
            for k in 0..=i {
                sum += self.l[i * n + k] * x[k];
            }
            x[i] = sum;
        }
    }

    /// x ← Lᵀ⁻¹ x (back substitution with the transpose).
    fn solve_upper(&self, x: &mut [f64]) {
        let n = self.n;
        for i in (0..n).rev() {
            let mut sum = x[i];
            for k in i + 1..n {
                sum -= self.l[k * n + i] * x[k];
            }
            x[i] = sum / self.l[i * n + i];
        }
    }

    /// x ← M⁻¹ x.
    pub fn solve(&self, x: &mut [f64]) {
        self.solve_lower(x);
        self.solve_upper(x);
    }

    /// M⁻¹, row-major.
    pub fn inverse(&self) -> Vec<f64> {
        let n = self.n;
        let mut inverse = vec![0.0; n * n];
        let mut column = vec![0.0; n];
        for j in 0..n {
            column.fill(0.0);
            column[j] = 1.0;
            self.solve(&mut column);
            for i in 0..n {
                inverse[i * n + j] = column[i];
            }
        }
        // M⁻¹ is symmetric; the two triangles of the solve differ by round-off.
        for i in 0..n {
            for j in 0..i {
                let mean = 0.5 * (inverse[i * n + j] + inverse[j * n + i]);
                inverse[i * n + j] = mean;
                inverse[j * n + i] = mean;
            }
        }
        inverse
    }

    /// S = ε L⁻¹ D L⁻ᵀ into `s` (row-major), from D (row-major).
    fn similar(&self, epsilon: f64, d: &[f64], s: &mut [f64]) {
        let n = self.n;
        s[..n * n].copy_from_slice(&d[..n * n]);
        // Columns: S ← L⁻¹ S, then rows: S ← S L⁻ᵀ, i.e. (L⁻¹ Sᵀ)ᵀ; S stays symmetric.
        let mut column = [0.0; 32];
        for j in 0..n {
            for i in 0..n {
                column[i] = s[i * n + j];
            }
            self.solve_lower(&mut column[..n]);
            for i in 0..n {
                s[i * n + j] = column[i];
            }
        }
        for i in 0..n {
            self.solve_lower(&mut s[i * n..i * n + n]);
        }
        for x in &mut s[..n * n] {
            *x *= epsilon;
        }
    }
}

/// Diagonalises the symmetric `s` (row-major n×n) in place by cyclic Jacobi rotations: on
/// return its diagonal holds the eigenvalues and `q` (row-major) the eigenvectors as columns.
fn jacobi(s: &mut [f64], q: &mut [f64], n: usize) {
    q[..n * n].fill(0.0);
    for i in 0..n {
        q[i * n + i] = 1.0;
    }
    for _sweep in 0..64 {
        let mut off = 0.0;
        let mut scale = 0.0;
        for i in 0..n {
            scale += s[i * n + i] * s[i * n + i];
            for j in i + 1..n {
                off += s[i * n + j] * s[i * n + j];
            }
        }
        if off <= 1e-32 * scale || off == 0.0 {
            return;
        }
        for p in 0..n {
            for r in p + 1..n {
                let apr = s[p * n + r];
                if apr == 0.0 {
                    continue;
                }
                let (app, arr) = (s[p * n + p], s[r * n + r]);
                let theta = (arr - app) / (2.0 * apr);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let sn = t * c;
                for k in 0..n {
                    let (skp, skr) = (s[k * n + p], s[k * n + r]);
                    s[k * n + p] = c * skp - sn * skr;
                    s[k * n + r] = sn * skp + c * skr;
                }
                for k in 0..n {
                    let (spk, srk) = (s[p * n + k], s[r * n + k]);
                    s[p * n + k] = c * spk - sn * srk;
                    s[r * n + k] = sn * spk + c * srk;
                }
                for k in 0..n {
                    let (qkp, qkr) = (q[k * n + p], q[k * n + r]);
                    q[k * n + p] = c * qkp - sn * qkr;
                    q[k * n + r] = sn * qkp + c * qkr;
                }
            }
        }
    }
}

/// The flows of A = ε D M⁻¹ at one q.
pub struct DampingFlows<'a> {
    factor: &'a MassFactor,
}

impl<'a> DampingFlows<'a> {
    /// The flows of the damping with mass factor `factor`.
    pub fn new(factor: &'a MassFactor) -> Self {
        DampingFlows { factor }
    }

    /// Applies L Q f(Λ) Qᵀ L⁻¹ to `x`, with `weight(λ)` giving f, and adds `scale` times the same
    /// operator with `weight2` applied to `y` when given; S = ε L⁻¹ D L⁻ᵀ from `d`.
    fn apply(
        &self,
        epsilon: f64,
        d: &[f64],
        x: &mut [f64],
        weight: impl Fn(f64) -> f64,
        second: Option<(&[f64], f64, &dyn Fn(f64) -> f64)>,
    ) {
        let n = self.factor.n;
        SCRATCH.with(|scratch| {
            let mut guard = scratch.borrow_mut();
            let Scratch { s, q, u, v } = &mut *guard;
            for buffer in [&mut *s, &mut *q] {
                if buffer.len() < n * n {
                    buffer.resize(n * n, 0.0);
                }
            }
            for buffer in [&mut *u, &mut *v] {
                if buffer.len() < n {
                    buffer.resize(n, 0.0);
                }
            }
            self.factor.similar(epsilon, d, s);
            jacobi(s, q, n);
            // u = Qᵀ L⁻¹ x, weighted by f(λ); plus the second term.
            u[..n].copy_from_slice(x);
            self.factor.solve_lower(&mut u[..n]);
            let project = |w: &[f64], out: &mut [f64]| {
                for (k, slot) in out[..n].iter_mut().enumerate() {
                    *slot = (0..n).map(|i| q[i * n + k] * w[i]).sum();
                }
            };
            let mut coefficients = [0.0; 32];
            project(&u[..n], &mut coefficients);
            for (k, c) in coefficients[..n].iter_mut().enumerate() {
                *c *= weight(s[k * n + k]);
            }
            if let Some((y, scale, weight2)) = second {
                v[..n].copy_from_slice(y);
                self.factor.solve_lower(&mut v[..n]);
                let mut other = [0.0; 32];
                project(&v[..n], &mut other);
                for (k, c) in coefficients[..n].iter_mut().enumerate() {
                    *c += scale * other[k] * weight2(s[k * n + k]);
                }
            }
            for (i, slot) in x.iter_mut().enumerate() {
                *slot = (0..n).map(|k| q[i * n + k] * coefficients[k]).sum();
            }
            self.factor.mul_lower(x);
        });
    }

    /// p ← e^{−τA} p.
    pub fn decay(&self, epsilon: f64, d: &[f64], p: &mut [f64], tau: f64) {
        self.apply(epsilon, d, p, |l| (-tau * l).exp(), None);
    }

    /// p ← e^{−τA} p − τ φ₁(−τA) g.
    pub fn kick_decay(&self, epsilon: f64, d: &[f64], p: &mut [f64], g: &[f64], tau: f64) {
        let phi1 = move |l: f64| {
            let x = tau * l;
            if x.abs() < 1e-8 {
                1.0 - 0.5 * x
            } else {
                -(-x).exp_m1() / x
            }
        };
        self.apply(epsilon, d, p, |l| (-tau * l).exp(), Some((g, -tau, &phi1)));
    }

    /// p ← (I + aA)⁻¹ p.
    pub fn solve(&self, epsilon: f64, d: &[f64], p: &mut [f64], a: f64) {
        self.apply(epsilon, d, p, |l| 1.0 / (1.0 + a * l), None);
    }
}

//! Linear stability analysis on the damped oscillator q'' + 2γq' + ω²q = 0 (paper 003 Ch. 3),
//! for every method.
//!
//! On this linear problem one step of any method is a linear map z ↦ M z; M is found by stepping
//! the unit initial states (1, 0) and (0, 1) (Newton converges to round-off for the implicit
//! methods). The exact flow has det M = e^{−2γh} and ½ tr M = e^{−γh} cos βh, β² = ω² − γ²
//! (eqs. 3.5–3.7).
//!
//! **Stability.** The method is stable when both eigenvalues lie in the closed unit disk. For a
//! 2×2 real matrix with 0 < det M ≤ 1 that holds iff |tr M| ≤ 1 + det M (the Jury/Schur–Cohn
//! condition: complex eigenvalues have |λ|² = det M ≤ 1; real ones are both in [−1, 1] iff
//! p(±1) = 1 ∓ tr M + det M ≥ 0). For the conformal methods det M = e^{−2γh}, so the condition is
//! |½ tr M| ≤ e^{−γh} cosh(γh).
//!
//! The thesis instead requires |½ tr M| < e^{−γh} (the text after eqs. 3.11, 3.16 and 3.21): that
//! is the condition for *complex* eigenvalues, not for stability, since real eigenvalues with
//! product e^{−2γh} can both lie inside the disk. Its printed relations (3.17) for csv1 and (3.22)
//! for csv2 therefore mark stable cells as unstable; the corrected relations below follow from the
//! same ½ tr M with the Jury condition and agree with the numerical maps (tested):
//! - cimp, ½ tr M = e^{−γh} (1 − b)/(1 + b), b = h²(ω² − γ²)/4 (eq. 3.10):
//!   stable iff |1 − b| ≤ cosh(γh) |1 + b|, always true for ω ≥ γ (as (3.12) says);
//! - csv1, ½ tr M = e^{−γh} (1 − h²ω²/2) cosh(γh) (eq. 3.15): stable iff hω ≤ 2, for every γ
//!   (printed (3.17): 1 − sech γh < h²ω²/2 < 1 + sech γh);
//! - csv2, ½ tr M = e^{−γh} [(4 + γ²h²) − 2h²ω² cosh(γh/2)]/(4 − γ²h²) (eq. 3.20, which our csv2
//!   reproduces to round-off, tested): stable iff that bracket's modulus is ≤ cosh(γh) (printed
//!   (3.22): (γ²h²/2) sech(γh/2) < h²ω²/2 < 2 sech(γh/2)).

use nalgebra::{Complex, Matrix2, U1};
use rayon::prelude::*;
use serde::Serialize;

use super::error::{CoreError, Field, Range};
use super::methods::{self, Method, MethodId};
use super::run::Stepper;
use super::system::{MechanicalSystem, State};
use super::systems::HarmonicOscillator;

/// A complex eigenvalue.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Eigenvalue {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
}

/// A propagation matrix and its spectral data.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Spectrum {
    /// The matrix, row-major: [[∂q⁺/∂q, ∂q⁺/∂p], [∂p⁺/∂q, ∂p⁺/∂p]].
    pub matrix: [[f64; 2]; 2],
    /// Trace.
    pub trace: f64,
    /// Determinant.
    pub det: f64,
    /// The two eigenvalues.
    pub eigenvalues: [Eigenvalue; 2],
    /// Largest eigenvalue modulus.
    pub spectral_radius: f64,
}

impl Spectrum {
    /// The spectral data of `m`, with eigenvalues from ½tr ± √((½tr)² − det) (eq. 3.4).
    pub fn of(m: &Matrix2<f64>) -> Self {
        let trace = m.trace();
        let det = m.determinant();
        let half = 0.5 * trace;
        let disc = Complex::new(half * half - det, 0.0).sqrt();
        let l1 = Complex::new(half, 0.0) + disc;
        let l2 = Complex::new(half, 0.0) - disc;
        Spectrum {
            matrix: [[m[(0, 0)], m[(0, 1)]], [m[(1, 0)], m[(1, 1)]]],
            trace,
            det,
            eigenvalues: [
                Eigenvalue {
                    re: l1.re,
                    im: l1.im,
                },
                Eigenvalue {
                    re: l2.re,
                    im: l2.im,
                },
            ],
            spectral_radius: l1.norm().max(l2.norm()),
        }
    }
}

/// One (ω, γ, h) point: the method's propagation matrix and the exact one.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PointAnalysis {
    /// The method's one-step matrix.
    pub method: Spectrum,
    /// The exact flow's matrix over one step.
    pub exact: Spectrum,
    /// |½ tr M_exact − ½ tr M_method|.
    pub half_trace_error: f64,
    /// Whether the method is stable here (both eigenvalues in the closed unit disk).
    pub stable: bool,
}

fn check_point(omega: f64, gamma: f64, h: f64) -> Result<(), CoreError> {
    Range::POSITIVE.check(omega, &Field::new("omega"))?;
    Range::NON_NEGATIVE.check(gamma, &Field::new("gamma"))?;
    Range::POSITIVE.check(h, &Field::new("h"))?;
    Ok(())
}

/// The one-step propagation matrix of `choice` on the damped oscillator.
pub fn propagation_matrix(
    choice: &Method,
    omega: f64,
    gamma: f64,
    h: f64,
) -> Result<Matrix2<f64>, CoreError> {
    check_point(omega, gamma, h)?;
    if choice.id() == MethodId::Reference {
        return Err(CoreError::Unsupported {
            field: Field::new("method"),
            reason: "the adaptive reference has no fixed-step propagation matrix",
        });
    }
    let sys = HarmonicOscillator { omega, gamma };
    let mut m = Matrix2::zeros();
    for column in 0..2 {
        let mut stepper = methods::build(choice, &sys, "harmonic_oscillator", h)?;
        let mut z = State::from_slices(U1, &[f64::from(column == 0)], &[f64::from(column == 1)]);
        stepper
            .step(&sys, &mut z, h)
            .map_err(|source| CoreError::Step {
                field: None,
                run: None,
                step: 1,
                t: 0.0,
                source,
            })?;
        m[(0, column)] = z.q[0];
        m[(1, column)] = z.p[0];
    }
    Ok(m)
}

/// The exact flow's matrix over time h (eq. 3.5's matrix at t = h).
pub fn exact_matrix(omega: f64, gamma: f64, h: f64) -> Matrix2<f64> {
    let sys = HarmonicOscillator { omega, gamma };
    let (q1, p1) = sys.solution(h, 1.0, 0.0);
    let (q2, p2) = sys.solution(h, 0.0, 1.0);
    Matrix2::new(q1, q2, p1, p2)
}

/// Stability from a spectrum: spectral radius ≤ 1 up to round-off.
fn is_stable(s: &Spectrum) -> bool {
    s.spectral_radius <= 1.0 + 1e-12
}

/// The method and exact spectra at (ω, γ, h).
pub fn analyse(
    choice: &Method,
    omega: f64,
    gamma: f64,
    h: f64,
) -> Result<PointAnalysis, CoreError> {
    let method = Spectrum::of(&propagation_matrix(choice, omega, gamma, h)?);
    let exact = Spectrum::of(&exact_matrix(omega, gamma, h));
    Ok(PointAnalysis {
        half_trace_error: (0.5 * exact.trace - 0.5 * method.trace).abs(),
        stable: is_stable(&method),
        method,
        exact,
    })
}

/// An evenly spaced axis of `n` points from `min` to `max`, the k-th being
/// min + (max − min)·k/(n − 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
#[cfg_attr(feature = "openapi", schema(as = AxisSpec))]
pub struct StabilityAxis {
    /// First value (≥ 0).
    #[cfg_attr(feature = "openapi", schema(example = 0.0, minimum = 0.0))]
    pub min: f64,
    /// Last value (≥ min).
    #[cfg_attr(feature = "openapi", schema(example = 1.0, minimum = 0.0))]
    pub max: f64,
    /// Number of points, 2 to 1000.
    #[cfg_attr(feature = "openapi", schema(example = 41, minimum = 2, maximum = 1000))]
    pub n: usize,
}

impl StabilityAxis {
    /// The k-th value.
    pub fn at(&self, k: usize) -> f64 {
        self.min + (self.max - self.min) * k as f64 / (self.n - 1) as f64
    }

    /// Checks the axis: finite, 0 ≤ min ≤ max, 2 to `max_n` points; errors name `field.min`,
    /// `field.max` or `field.n`.
    pub fn check(&self, field: &Field, max_n: usize) -> Result<(), CoreError> {
        Range::NON_NEGATIVE.check(self.min, &field.key("min"))?;
        Range::above(self.min, false).check(self.max, &field.key("max"))?;
        if self.n < 2 || self.n > max_n {
            return Err(CoreError::Count {
                field: field.key("n"),
                got: self.n as u64,
                min: 2,
                max: max_n as u64,
                what: "points",
            });
        }
        Ok(())
    }
}

/// An analytic stability relation for a conformal method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Relation {
    /// As printed in the thesis: (3.12), (3.17), (3.22).
    Printed,
    /// Derived with the Jury condition |½ tr M| ≤ e^{−γh} cosh γh (see the module docs).
    Corrected,
}

/// The analytic stability verdict at (ω, γ, h), for cimp, csv1 and csv2; `None` for the others.
pub fn analytic_stable(
    id: MethodId,
    relation: Relation,
    omega: f64,
    gamma: f64,
    h: f64,
) -> Option<bool> {
    let x = 0.5 * h * h * omega * omega;
    let gh = gamma * h;
    Some(match (id, relation) {
        (MethodId::Cimp, Relation::Printed) => x > 0.5 * gh * gh,
        (MethodId::Cimp, Relation::Corrected) => {
            let b = 0.25 * h * h * (omega * omega - gamma * gamma);
            (1.0 - b).abs() <= gh.cosh() * (1.0 + b).abs()
        }
        (MethodId::Csv1, Relation::Printed) => {
            let sech = 1.0 / gh.cosh();
            1.0 - sech < x && x < 1.0 + sech
        }
        (MethodId::Csv1, Relation::Corrected) => x <= 2.0,
        (MethodId::Csv2, Relation::Printed) => {
            let sech = 1.0 / (0.5 * gh).cosh();
            0.5 * gh * gh * sech < x && x < 2.0 * sech
        }
        (MethodId::Csv2, Relation::Corrected) => {
            let phi = ((4.0 + gh * gh) - 2.0 * h * h * omega * omega * (0.5 * gh).cosh())
                / (4.0 - gh * gh);
            phi.abs() <= gh.cosh()
        }
        _ => return None,
    })
}

/// The ½ tr M of eq. (3.20) for csv2, as printed.
pub fn csv2_half_trace(omega: f64, gamma: f64, h: f64) -> f64 {
    let gh = gamma * h;
    (-gh).exp()
        * ((4.0 + gh * gh) / (4.0 - gh * gh)
            - 2.0 * h * h * omega * omega / (4.0 - gh * gh) * (0.5 * gh).cosh())
}

/// A stability map over a (γ, h) grid at fixed ω.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StabilityMap {
    /// The method's label.
    pub method: String,
    /// ω.
    pub omega: f64,
    /// The γ axis (columns).
    pub gamma: StabilityAxis,
    /// The h axis (rows).
    pub h: StabilityAxis,
    /// Spectral radius per cell, row-major (h rows × γ columns); NaN where the step fails.
    pub spectral_radius: Vec<f64>,
    /// Numerical stability per cell.
    pub stable: Vec<bool>,
    /// The corrected analytic verdict per cell (cimp, csv1, csv2).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub analytic: Option<Vec<bool>>,
    /// The printed relation's verdict per cell (cimp, csv1, csv2).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub printed: Option<Vec<bool>>,
    /// Cells where `stable` and `analytic` disagree and no neighbour is on the other side of
    /// the numerical boundary.
    pub disagreements: usize,
    /// The same count for the printed relation.
    pub printed_disagreements: usize,
}

/// Most points per axis of a map.
pub const MAX_AXIS_POINTS: usize = 1000;

/// The stability map of `choice` over the grid, computed in parallel over rows.
pub fn map(
    choice: &Method,
    omega: f64,
    gamma: StabilityAxis,
    h: StabilityAxis,
) -> Result<StabilityMap, CoreError> {
    check_map(choice, omega, gamma, h)?;
    let radius: Vec<f64> = (0..h.n)
        .into_par_iter()
        .flat_map_iter(|row| map_row(choice, omega, gamma, h.at(row)))
        .collect();
    Ok(map_of_rows(choice, omega, gamma, h, radius))
}

/// Checks a map's axes, ω, and the method against the most damped oscillator of the map.
pub fn check_map(
    choice: &Method,
    omega: f64,
    gamma: StabilityAxis,
    h: StabilityAxis,
) -> Result<(), CoreError> {
    gamma.check(&Field::new("gamma"), MAX_AXIS_POINTS)?;
    h.check(&Field::new("h"), MAX_AXIS_POINTS)?;
    check_point(omega, 0.0, 1.0)?;
    // A method that refuses damping (rowlands) would be refused in every damped cell: say so once.
    let widest = HarmonicOscillator {
        omega,
        gamma: gamma.max,
    };
    choice.check(
        &Field::new("method"),
        "harmonic_oscillator",
        widest.structure(),
        widest.damping_rate(),
    )
}

/// One row of a map: the spectral radius at each γ of the axis for the step `hv`; NaN where the
/// step fails. A zero step is the identity: stable, without stepping.
pub fn map_row(choice: &Method, omega: f64, gamma: StabilityAxis, hv: f64) -> Vec<f64> {
    (0..gamma.n)
        .map(|col| {
            if hv == 0.0 {
                return 1.0;
            }
            propagation_matrix(choice, omega, gamma.at(col), hv)
                .map(|m| Spectrum::of(&m).spectral_radius)
                .unwrap_or(f64::NAN)
        })
        .collect()
}

/// The map from its spectral radii (rows of [`map_row`], in order): the verdicts, analytic and
/// numerical, and their disagreements.
pub fn map_of_rows(
    choice: &Method,
    omega: f64,
    gamma: StabilityAxis,
    h: StabilityAxis,
    radius: Vec<f64>,
) -> StabilityMap {
    let stable: Vec<bool> = radius.iter().map(|&r| r <= 1.0 + 1e-12).collect();
    let verdicts = |relation| -> Option<Vec<bool>> {
        (0..h.n * gamma.n)
            .map(|k| {
                analytic_stable(
                    choice.id(),
                    relation,
                    omega,
                    gamma.at(k % gamma.n),
                    h.at(k / gamma.n).max(1e-300),
                )
            })
            .collect()
    };
    let analytic = verdicts(Relation::Corrected);
    let printed = verdicts(Relation::Printed);
    let count = |other: &Option<Vec<bool>>| {
        other
            .as_ref()
            .map_or(0, |o| disagreements_off_boundary(&stable, o, h.n, gamma.n))
    };
    StabilityMap {
        method: choice.label(),
        omega,
        gamma,
        h,
        disagreements: count(&analytic),
        printed_disagreements: count(&printed),
        spectral_radius: radius,
        stable,
        analytic,
        printed,
    }
}

/// Cells where `a` and `b` disagree, not counting cells that have a neighbour (8-connected) on the
/// other side of `a`'s boundary.
fn disagreements_off_boundary(a: &[bool], b: &[bool], rows: usize, cols: usize) -> usize {
    let at = |r: usize, c: usize| a[r * cols + c];
    let mut count = 0;
    for r in 0..rows {
        for c in 0..cols {
            if a[r * cols + c] == b[r * cols + c] {
                continue;
            }
            let mut near_boundary = false;
            for dr in -1i64..=1 {
                for dc in -1i64..=1 {
                    let (rr, cc) = (r as i64 + dr, c as i64 + dc);
                    if rr >= 0
                        && cc >= 0
                        && (rr as usize) < rows
                        && (cc as usize) < cols
                        && at(rr as usize, cc as usize) != at(r, c)
                    {
                        near_boundary = true;
                    }
                }
            }
            if !near_boundary {
                count += 1;
            }
        }
    }
    count
}

/// The ½ tr error |½tr M_exact − ½tr M_method| at each h, and its observed order (the slope of
/// log error against log h).
pub fn half_trace_error(
    choice: &Method,
    omega: f64,
    gamma: f64,
    hs: &[f64],
) -> Result<(Vec<f64>, f64), CoreError> {
    let errors = hs
        .iter()
        .map(|&h| analyse(choice, omega, gamma, h).map(|a| a.half_trace_error))
        .collect::<Result<Vec<f64>, _>>()?;
    let order = super::diagnostics::log_log_slope(hs, &errors);
    Ok((errors, order))
}

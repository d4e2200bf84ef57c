//! Diagnostics computed from sampled runs: the dissipation drift of paper 003 eq. (4.4),
//! least-squares slopes for observed orders, and the test of divergence.

use serde::Serialize;

/// A run whose energy leaves H₀ by more than this many times 1 + |H₀| has diverged (the test of
/// the energy-error map, in the sweeps' metrics and in the energy-map lanes alike).
pub const DIVERGENCE: f64 = 100.0;

/// One point of the dissipation drift d = ln(max |q| over a half-oscillation) + γ t* (paper 003
/// eq. 4.4): constant for the exact flow, so a trend shows a wrong dissipation rate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DriftPoint {
    /// Time t* of the amplitude peak.
    pub t: f64,
    /// d(t*).
    pub d: f64,
}

/// The dissipation drift of a 1-DOF run (paper 003 eq. 4.4): the samples are cut at the sign
/// changes of q; in each complete half-oscillation the peak |q| at t* gives
/// d = ln|q(t*)| + γ t*. For the exact flow of the damped oscillator d is constant, so a trend
/// in d is a wrong dissipation rate. Resolution is that of the sampling.
pub fn dissipation_drift(t: &[f64], q: &[f64], gamma: f64) -> Vec<DriftPoint> {
    let mut out = Vec::new();
    let mut segment_start: Option<usize> = None;
    for i in 1..q.len() {
        let crossed = q[i - 1].signum() != q[i].signum() && q[i - 1] != 0.0;
        if crossed {
            if let Some(start) = segment_start {
                let (peak, &value) = q[start..i]
                    .iter()
                    .enumerate()
                    .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
                    .expect("segment is not empty");
                if value != 0.0 {
                    let tp = t[start + peak];
                    out.push(DriftPoint {
                        t: tp,
                        d: value.abs().ln() + gamma * tp,
                    });
                }
            }
            segment_start = Some(i);
        }
    }
    out
}

/// The least-squares line y ≈ intercept + slope·x: (slope, intercept), or `None` when the x
/// values do not spread (fewer than two distinct).
pub fn fit_line(x: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let count = n as f64;
    let mx = x.iter().sum::<f64>() / count;
    let my = y.iter().sum::<f64>() / count;
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    if n < 2 || !(sxx > 0.0) {
        return None;
    }
    let slope = sxy / sxx;
    Some((slope, my - slope * mx))
}

/// The least-squares line through (log₁₀ x, log₁₀ y) of `points` (x, y): (slope, intercept) —
/// an observed order, or a cost-versus-error exponent.
pub fn fit_log_log(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let x: Vec<f64> = points.iter().map(|p| p.0.log10()).collect();
    let y: Vec<f64> = points.iter().map(|p| p.1.log10()).collect();
    fit_line(&x, &y)
}

/// Least-squares slope of log(y) against log(x): an observed order of convergence.
pub fn log_log_slope(x: &[f64], y: &[f64]) -> f64 {
    let lx: Vec<f64> = x.iter().map(|v| v.ln()).collect();
    let ly: Vec<f64> = y.iter().map(|v| v.ln()).collect();
    least_squares_slope(&lx, &ly)
}

/// Least-squares slope of y against x (for the trend of the dissipation drift); NaN when the
/// x values do not spread.
pub fn least_squares_slope(x: &[f64], y: &[f64]) -> f64 {
    fit_line(x, y).map_or(f64::NAN, |(slope, _)| slope)
}

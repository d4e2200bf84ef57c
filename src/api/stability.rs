//! Linear stability analysis as users ask for it — the bodies of `POST /api/v1/stability` and
//! `POST /api/v1/stability/point` — their strict parsers, and the answers built from
//! [`core::stability`](crate::core::stability).
//!
//! Parsing follows [`request`](super::request): every problem names the field at fault
//! (`methods[1].base`, `gamma.n`, `omega`). Methods take the same forms as in a simulation
//! request; the adaptive `reference` has no propagation matrix and is refused.
//!
//! Maps are laid out as the core computes them, one row per h value and one column per γ value;
//! a spectral radius that is not finite (the method is undefined there, e.g. csv2 at γh = 2, or
//! overflows) is `null`, since JSON has no NaN.

use std::sync::atomic::Ordering;
use std::time::Instant;

use serde::Serialize;
use serde_json::{Map, Value};
use utoipa::ToSchema;

use super::error::{codes, ErrorDetail};
use super::request::{
    check_fields, method, missing, number, object, present, wrong_type, MethodSpec,
};
use crate::core::error::CoreError;
use crate::core::methods::{MethodChoice, MethodId};
use crate::core::run::Budget;
use crate::core::stability::{
    self, Axis, Eigenvalue, PointAnalysis, Relation, Spectrum, StabilityMap, MAX_AXIS_POINTS,
};
use crate::core::system::MechanicalSystem;
use crate::core::systems::HarmonicOscillator;

/// Most methods in one map request.
pub const MAX_MAP_METHODS: usize = 16;

/// Most cells (methods × γ points × h points) in one map request.
pub const MAX_MAP_CELLS: usize = 1_000_000;

/// The fields of [`StabilityRequest`], as the parser accepts them.
pub const MAP_FIELDS: &[&str] = &["methods", "omega", "gamma", "h"];

/// The fields of [`PointRequest`], as the parser accepts them.
pub const POINT_FIELDS: &[&str] = &["method", "omega", "gamma", "h"];

/// The fields of an [`AxisSpec`].
pub const AXIS_FIELDS: &[&str] = &["min", "max", "n"];

/// An evenly spaced axis: `n` points from `min` to `max`, the k-th being
/// min + (max − min)·k/(n − 1).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AxisSpec {
    /// First value (≥ 0).
    #[schema(example = 0.0)]
    pub min: f64,
    /// Last value (≥ min).
    #[schema(example = 1.0)]
    pub max: f64,
    /// Number of points, 2 to 1000.
    #[schema(example = 41, minimum = 2, maximum = 1000)]
    pub n: usize,
}

impl From<AxisSpec> for Axis {
    fn from(a: AxisSpec) -> Self {
        Axis {
            min: a.min,
            max: a.max,
            n: a.n,
        }
    }
}

impl From<Axis> for AxisSpec {
    fn from(a: Axis) -> Self {
        AxisSpec {
            min: a.min,
            max: a.max,
            n: a.n,
        }
    }
}

/// A request for stability maps of the damped oscillator q'' + 2γq' + ω²q = 0 over a (γ, h)
/// grid at fixed ω.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({
    "methods": ["csv1", {"id": "triple_jump", "base": "csv1"}],
    "omega": 3.51,
    "gamma": {"min": 0, "max": 3.5, "n": 141},
    "h": {"min": 0, "max": 1, "n": 41}
}))]
pub struct StabilityRequest {
    /// Fixed-step methods to map, in this order (1 to 16; not `reference`). Each map has
    /// gamma.n × h.n cells, and all maps together at most 10⁶ (an answer of about 30 MB).
    pub methods: Vec<MethodSpec>,
    /// The undamped frequency ω (finite, > 0).
    #[schema(example = 3.51)]
    pub omega: f64,
    /// The damping rates γ: the columns of each map.
    pub gamma: AxisSpec,
    /// The step sizes h: the rows of each map.
    pub h: AxisSpec,
}

/// A request for the stability analysis of one method at one (ω, γ, h).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": 0.2}))]
pub struct PointRequest {
    /// A fixed-step method (not `reference`).
    pub method: MethodSpec,
    /// The undamped frequency ω (finite, > 0).
    #[schema(example = 3.51)]
    pub omega: f64,
    /// The damping rate γ (finite, ≥ 0).
    #[schema(example = 0.5)]
    pub gamma: f64,
    /// The step size h (finite, > 0).
    #[schema(example = 0.2)]
    pub h: f64,
}

/// A validated map request, ready to compute.
#[derive(Clone, Debug, PartialEq)]
pub struct MapJob {
    /// The methods, in the order asked.
    pub choices: Vec<MethodChoice>,
    /// ω.
    pub omega: f64,
    /// The γ axis (columns).
    pub gamma: Axis,
    /// The h axis (rows).
    pub h: Axis,
}

impl MapJob {
    /// Cells over all maps.
    pub fn cells(&self) -> usize {
        self.choices.len() * self.gamma.n * self.h.n
    }
}

/// A validated point request, ready to compute.
#[derive(Clone, Debug, PartialEq)]
pub struct PointJob {
    /// The method.
    pub choice: MethodChoice,
    /// ω.
    pub omega: f64,
    /// γ.
    pub gamma: f64,
    /// h.
    pub h: f64,
}

/// The answer to a map request.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct StabilityDocument {
    /// ω.
    pub omega: f64,
    /// The γ axis: the columns of every map.
    pub gamma: AxisSpec,
    /// The h axis: the rows of every map.
    pub h: AxisSpec,
    /// One map per method, in the order asked.
    pub maps: Vec<MapDocument>,
}

/// The stability map of one method: every grid is h.n rows (h values) × gamma.n columns
/// (γ values).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct MapDocument {
    /// The method's label, e.g. `triple_jump(csv1)`.
    #[schema(example = "csv1")]
    pub method: String,
    /// Largest eigenvalue modulus of the one-step matrix; `null` where it is not finite (the
    /// method is undefined there, e.g. csv2 at γh = 2, or overflows). At h = 0 it is 1.
    pub spectral_radius: Vec<Vec<Option<f64>>>,
    /// Whether both eigenvalues lie in the closed unit disk (spectral radius ≤ 1 + 1e-12).
    pub stable: Vec<Vec<bool>>,
    /// The corrected analytic relation's verdict (cimp, csv1, csv2; `null` for the others).
    pub analytic: Option<Vec<Vec<bool>>>,
    /// The verdict of the relation as printed in the thesis, eqs. (3.12), (3.17), (3.22)
    /// (cimp, csv1, csv2; `null` for the others).
    pub printed: Option<Vec<Vec<bool>>>,
    /// Cells where `stable` and `analytic` disagree, not counting cells next to the numerical
    /// boundary; `null` without an analytic relation.
    pub disagreements: Option<usize>,
    /// The same count for `printed`.
    pub printed_disagreements: Option<usize>,
}

/// A complex eigenvalue.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
pub struct EigenvalueDocument {
    /// Real part (`null` when not finite).
    pub re: Option<f64>,
    /// Imaginary part (`null` when not finite).
    pub im: Option<f64>,
}

/// A 2×2 one-step matrix and its spectral data; numbers that are not finite (overflow at
/// extreme ω, γ, h) are `null`.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct SpectrumDocument {
    /// The matrix, row-major: [[∂q⁺/∂q, ∂q⁺/∂p], [∂p⁺/∂q, ∂p⁺/∂p]].
    pub matrix: [[Option<f64>; 2]; 2],
    /// Trace.
    pub trace: Option<f64>,
    /// Determinant.
    pub det: Option<f64>,
    /// The two eigenvalues ½tr ± √((½tr)² − det).
    pub eigenvalues: [EigenvalueDocument; 2],
    /// Largest eigenvalue modulus.
    pub spectral_radius: Option<f64>,
}

/// The core's analysis at one point: the method's one-step matrix and the exact flow's.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct PointAnalysisDocument {
    /// The method's one-step matrix.
    pub method: SpectrumDocument,
    /// The exact flow's matrix over one step (det = e^{−2γh}, ½tr = e^{−γh} cos βh).
    pub exact: SpectrumDocument,
    /// |½ tr M_exact − ½ tr M_method|.
    pub half_trace_error: Option<f64>,
    /// Whether the method is stable here (spectral radius ≤ 1 + 1e-12).
    pub stable: bool,
}

/// The analytic stability verdicts of cimp, csv1 and csv2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, ToSchema)]
pub struct AnalyticVerdicts {
    /// The relation derived with the Jury condition |½ tr M| ≤ e^{−γh} cosh γh.
    pub corrected: bool,
    /// The relation as printed in the thesis, eqs. (3.12), (3.17), (3.22).
    pub printed: bool,
}

/// The answer to a point request.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct PointDocument {
    /// The method's label.
    #[schema(example = "csv1")]
    pub method: String,
    /// ω.
    pub omega: f64,
    /// γ.
    pub gamma: f64,
    /// h.
    pub h: f64,
    /// The method's and the exact one-step matrices, the ½-trace error and the verdict.
    pub analysis: PointAnalysisDocument,
    /// The analytic verdicts (cimp, csv1, csv2; `null` for the others).
    pub analytic: Option<AnalyticVerdicts>,
}

/// `x` when finite.
fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl From<&Spectrum> for SpectrumDocument {
    fn from(s: &Spectrum) -> Self {
        let eigen = |e: &Eigenvalue| EigenvalueDocument {
            re: finite(e.re),
            im: finite(e.im),
        };
        SpectrumDocument {
            matrix: s.matrix.map(|row| row.map(finite)),
            trace: finite(s.trace),
            det: finite(s.det),
            eigenvalues: [eigen(&s.eigenvalues[0]), eigen(&s.eigenvalues[1])],
            spectral_radius: finite(s.spectral_radius),
        }
    }
}

impl From<&PointAnalysis> for PointAnalysisDocument {
    fn from(a: &PointAnalysis) -> Self {
        PointAnalysisDocument {
            method: (&a.method).into(),
            exact: (&a.exact).into(),
            half_trace_error: finite(a.half_trace_error),
            stable: a.stable,
        }
    }
}

/// `cells` (row-major, `cols` per row) as rows.
fn rows<T: Copy, U>(cells: &[T], cols: usize, f: impl Fn(T) -> U) -> Vec<Vec<U>> {
    cells
        .chunks(cols)
        .map(|row| row.iter().map(|&x| f(x)).collect())
        .collect()
}

impl From<&StabilityMap> for MapDocument {
    fn from(m: &StabilityMap) -> Self {
        let cols = m.gamma.n;
        MapDocument {
            method: m.method.clone(),
            spectral_radius: rows(&m.spectral_radius, cols, finite),
            stable: rows(&m.stable, cols, |s| s),
            analytic: m.analytic.as_deref().map(|a| rows(a, cols, |s| s)),
            printed: m.printed.as_deref().map(|p| rows(p, cols, |s| s)),
            disagreements: m.analytic.as_ref().map(|_| m.disagreements),
            printed_disagreements: m.printed.as_ref().map(|_| m.printed_disagreements),
        }
    }
}

/// A core error as the error shape.
fn core_detail(error: &CoreError) -> ErrorDetail {
    ErrorDetail::core(error)
}

/// Refuses `choice` on the oscillator damped at rate γ (rowlands needs γ = 0), naming `field`.
fn check_damping(choice: &MethodChoice, gamma: f64, field: &str) -> Result<(), ErrorDetail> {
    let sys = HarmonicOscillator { omega: 1.0, gamma };
    choice
        .check("harmonic_oscillator", sys.structure(), sys.damping_rate())
        .map_err(|e| ErrorDetail {
            field: Some(field.to_string()),
            ..core_detail(&e)
        })
}

fn invalid(field: &str, message: impl std::fmt::Display) -> ErrorDetail {
    ErrorDetail::at(codes::INVALID_VALUE, field, format!("{field}: {message}"))
}

/// The required number `key` of `obj`, named `field` in errors.
fn required_number(
    obj: &Map<String, Value>,
    key: &str,
    field: &str,
    what: &str,
) -> Result<f64, ErrorDetail> {
    match present(obj, key) {
        Some(v) => number(v, field),
        None => Err(missing(field, what)),
    }
}

/// Parses the axis `name` of `obj`.
fn axis(obj: &Map<String, Value>, name: &str) -> Result<AxisSpec, ErrorDetail> {
    let v = present(obj, name).ok_or_else(|| {
        missing(
            name,
            &format!("the {name} axis, e.g. {{\"min\": 0, \"max\": 1, \"n\": 41}}"),
        )
    })?;
    let o = object(v, Some(name))?;
    check_fields(o, AXIS_FIELDS, &format!("{name}."))?;
    let field = |k: &str| format!("{name}.{k}");
    let min = required_number(o, "min", &field("min"), "the first value")?;
    let max = required_number(o, "max", &field("max"), "the last value")?;
    let n = match present(o, "n") {
        Some(v) => v.as_u64().ok_or_else(|| {
            wrong_type(
                &field("n"),
                &format!("a whole number of points (2 to {MAX_AXIS_POINTS})"),
                v,
            )
        })?,
        None => return Err(missing(&field("n"), "the number of points")),
    };
    Ok(AxisSpec {
        min,
        max,
        n: usize::try_from(n).unwrap_or(usize::MAX),
    })
}

/// Checks an axis the way [`stability::map`] does, naming `name.min`, `name.max` or `name.n`.
fn check_axis(a: &AxisSpec, name: &str) -> Result<(), ErrorDetail> {
    if !(a.min.is_finite() && a.min >= 0.0) {
        return Err(invalid(
            &format!("{name}.min"),
            format!("must be finite and ≥ 0, got {}", a.min),
        ));
    }
    if !(a.max.is_finite() && a.max >= a.min) {
        return Err(invalid(
            &format!("{name}.max"),
            format!("must be finite and ≥ {name}.min = {}, got {}", a.min, a.max),
        ));
    }
    if !(2..=MAX_AXIS_POINTS).contains(&a.n) {
        return Err(invalid(
            &format!("{name}.n"),
            format!("needs 2 to {MAX_AXIS_POINTS} points, got {}", a.n),
        ));
    }
    Ok(())
}

fn check_positive(x: f64, field: &str) -> Result<(), ErrorDetail> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(invalid(field, format!("must be finite and > 0, got {x}")))
    }
}

/// The method `spec` (named `field`) as a fixed-step choice: `reference` is refused.
fn fixed_step_choice(spec: &MethodSpec, field: &str) -> Result<MethodChoice, ErrorDetail> {
    let (id, at) = match spec {
        MethodSpec::Id(id) => (id.as_str(), field.to_string()),
        MethodSpec::Options(o) => (o.id.as_str(), format!("{field}.id")),
    };
    if MethodId::parse(id) == Some(MethodId::Reference) {
        return Err(invalid(
            &at,
            "the adaptive `reference` integrator has no fixed step and so no propagation \
             matrix; choose a fixed-step method (see GET /api/v1/methods)",
        ));
    }
    MethodChoice::parse(&spec.to_input(), field).map_err(|e| core_detail(&e))
}

impl StabilityRequest {
    /// Parses a request from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&super::request::parse_json(bytes)?)
    }

    /// Parses a request from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = object(value, None)?;
        check_fields(obj, MAP_FIELDS, "")?;
        let methods = match present(obj, "methods") {
            Some(v) => super::request::methods(v)?,
            None => {
                return Err(missing(
                    "methods",
                    "the methods to map, e.g. [\"csv1\", {\"id\": \"triple_jump\", \"base\": \"csv1\"}]",
                ))
            }
        };
        Ok(StabilityRequest {
            methods,
            omega: required_number(obj, "omega", "omega", "the undamped frequency ω")?,
            gamma: axis(obj, "gamma")?,
            h: axis(obj, "h")?,
        })
    }

    /// Validates the request (cheap: nothing is computed): the methods, ω, the axes and the
    /// size of the work.
    pub fn prepare(&self) -> Result<MapJob, ErrorDetail> {
        if self.methods.is_empty() {
            return Err(invalid("methods", "give at least one method"));
        }
        if self.methods.len() > MAX_MAP_METHODS {
            return Err(invalid(
                "methods",
                format!(
                    "at most {MAX_MAP_METHODS} methods per request, got {}",
                    self.methods.len()
                ),
            ));
        }
        let choices = self
            .methods
            .iter()
            .enumerate()
            .map(|(i, m)| fixed_step_choice(m, &format!("methods[{i}]")))
            .collect::<Result<Vec<_>, _>>()?;
        check_positive(self.omega, "omega")?;
        check_axis(&self.gamma, "gamma")?;
        check_axis(&self.h, "h")?;
        for (i, choice) in choices.iter().enumerate() {
            check_damping(choice, self.gamma.max, &format!("methods[{i}]"))?;
        }
        let job = MapJob {
            choices,
            omega: self.omega,
            gamma: self.gamma.into(),
            h: self.h.into(),
        };
        let cells = job.cells();
        if cells > MAX_MAP_CELLS {
            return Err(ErrorDetail::at(
                codes::TOO_MANY_CELLS,
                "methods",
                format!(
                    "methods: {} methods × {} γ values × {} h values = {cells} cells exceeds the \
                     limit of {MAX_MAP_CELLS} per request; ask for fewer methods or coarser axes",
                    job.choices.len(),
                    job.gamma.n,
                    job.h.n
                ),
            ));
        }
        Ok(job)
    }
}

impl PointRequest {
    /// Parses a request from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&super::request::parse_json(bytes)?)
    }

    /// Parses a request from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = object(value, None)?;
        check_fields(obj, POINT_FIELDS, "")?;
        let method = match present(obj, "method") {
            Some(v) => method(v, "method")?,
            None => return Err(missing("method", "the method, e.g. \"csv1\"")),
        };
        Ok(PointRequest {
            method,
            omega: required_number(obj, "omega", "omega", "the undamped frequency ω")?,
            gamma: required_number(obj, "gamma", "gamma", "the damping rate γ")?,
            h: required_number(obj, "h", "h", "the step size")?,
        })
    }

    /// Validates the request (cheap: nothing is computed).
    pub fn prepare(&self) -> Result<PointJob, ErrorDetail> {
        let choice = fixed_step_choice(&self.method, "method")?;
        check_positive(self.omega, "omega")?;
        if !(self.gamma.is_finite() && self.gamma >= 0.0) {
            return Err(invalid(
                "gamma",
                format!("must be finite and ≥ 0, got {}", self.gamma),
            ));
        }
        check_positive(self.h, "h")?;
        check_damping(&choice, self.gamma, "method")?;
        Ok(PointJob {
            choice,
            omega: self.omega,
            gamma: self.gamma,
            h: self.h,
        })
    }
}

/// Computes the maps of `job`, one method after another (each in parallel over its rows).
/// Between methods it gives up when `budget`'s deadline has passed (`timeout`) or its flag is
/// set (`overloaded`: the server is shutting down or the client went away).
pub fn maps(job: &MapJob, budget: Budget) -> Result<StabilityDocument, ErrorDetail> {
    let mut maps = Vec::with_capacity(job.choices.len());
    for (i, choice) in job.choices.iter().enumerate() {
        if budget.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(ErrorDetail::new(
                codes::OVERLOADED,
                "the stability maps were cancelled (the server is shutting down)",
            ));
        }
        if budget.deadline.is_some_and(|d| Instant::now() >= d) {
            return Err(ErrorDetail::new(
                codes::TIMEOUT,
                format!(
                    "the stability maps took longer than the time limit ({i} of {} done); ask \
                     for fewer methods or coarser axes",
                    job.choices.len()
                ),
            ));
        }
        let map = stability::map(choice, job.omega, job.gamma, job.h).map_err(|e| {
            let detail = core_detail(&e);
            // The core names `methods` for method problems; say which.
            match detail.field.as_deref() {
                Some("methods") => ErrorDetail {
                    field: Some(format!("methods[{i}]")),
                    ..detail
                },
                _ => detail,
            }
        })?;
        maps.push(MapDocument::from(&map));
    }
    Ok(StabilityDocument {
        omega: job.omega,
        gamma: job.gamma.into(),
        h: job.h.into(),
        maps,
    })
}

/// The analysis of `job`: the core's [`PointAnalysis`] and, for cimp, csv1 and csv2, the
/// analytic verdicts.
pub fn point(job: &PointJob) -> Result<PointDocument, ErrorDetail> {
    let PointJob {
        choice,
        omega,
        gamma,
        h,
    } = job;
    let analysis = stability::analyse(choice, *omega, *gamma, *h).map_err(|e| {
        let detail = core_detail(&e);
        match detail.field.as_deref() {
            Some("methods") => ErrorDetail {
                field: Some("method".to_string()),
                ..detail
            },
            _ => detail,
        }
    })?;
    let verdict = |relation| stability::analytic_stable(choice.id, relation, *omega, *gamma, *h);
    let analytic = match (verdict(Relation::Corrected), verdict(Relation::Printed)) {
        (Some(corrected), Some(printed)) => Some(AnalyticVerdicts { corrected, printed }),
        _ => None,
    };
    Ok(PointDocument {
        method: choice.label(),
        omega: *omega,
        gamma: *gamma,
        h: *h,
        analysis: (&analysis).into(),
        analytic,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field_of_map(text: &str) -> Option<String> {
        StabilityRequest::from_slice(text.as_bytes())
            .and_then(|r| r.prepare().map(|_| ()))
            .unwrap_err()
            .field
    }

    #[test]
    fn map_fields_are_named() {
        let axes =
            r#""gamma": {"min": 0, "max": 3.5, "n": 10}, "h": {"min": 0, "max": 1, "n": 10}"#;
        for (body, field) in [
            (format!(r#"{{"methods": ["csv1"], "omega": 1, {axes}, "x": 1}}"#), "x"),
            (format!(r#"{{"methods": ["csv1", "reference"], "omega": 1, {axes}}}"#), "methods[1]"),
            (
                format!(r#"{{"methods": [{{"id": "reference"}}], "omega": 1, {axes}}}"#),
                "methods[0].id",
            ),
            (
                format!(r#"{{"methods": [{{"id": "triple_jump", "base": "heun"}}], "omega": 1, {axes}}}"#),
                "methods[0].base",
            ),
            (format!(r#"{{"methods": ["csv1"], "omega": 0, {axes}}}"#), "omega"),
            (
                r#"{"methods": ["csv1"], "omega": 1, "gamma": {"min": 0, "max": 1, "n": 1}, "h": {"min": 0, "max": 1, "n": 2}}"#.to_string(),
                "gamma.n",
            ),
            (
                r#"{"methods": ["csv1"], "omega": 1, "gamma": {"min": 0, "max": 1, "n": 2}, "h": {"min": 1, "max": 0.5, "n": 2}}"#.to_string(),
                "h.max",
            ),
            (
                r#"{"methods": ["csv1"], "omega": 1, "gamma": {"min": 0, "max": 1, "n": 2, "k": 1}, "h": {"min": 0, "max": 1, "n": 2}}"#.to_string(),
                "gamma.k",
            ),
        ] {
            assert_eq!(field_of_map(&body).as_deref(), Some(field), "{body}");
        }
    }

    #[test]
    fn rowlands_is_refused_on_a_damped_axis_or_point() {
        let h = r#""h": {"min": 0, "max": 1, "n": 10}"#;
        let damped = format!(
            r#"{{"methods": ["csv1", "rowlands"], "omega": 1, "gamma": {{"min": 0, "max": 1, "n": 10}}, {h}}}"#
        );
        let error = StabilityRequest::from_slice(damped.as_bytes())
            .unwrap()
            .prepare()
            .unwrap_err();
        assert_eq!(
            (error.code.as_str(), error.field.as_deref()),
            (codes::UNMET_REQUIREMENT, Some("methods[1]"))
        );
        assert!(error.message.contains("no damping"), "{}", error.message);
        let undamped = format!(
            r#"{{"methods": ["rowlands"], "omega": 1, "gamma": {{"min": 0, "max": 0, "n": 2}}, {h}}}"#
        );
        let job = StabilityRequest::from_slice(undamped.as_bytes())
            .unwrap()
            .prepare()
            .unwrap();
        assert!(maps(&job, Budget::default()).is_ok());
        let point = |gamma: f64| {
            PointRequest::from_value(&serde_json::json!({
                "method": {"id": "rowlands", "processor": "none"}, "omega": 1, "gamma": gamma, "h": 0.1
            }))
            .unwrap()
            .prepare()
        };
        let error = point(0.1).unwrap_err();
        assert_eq!(
            (error.code.as_str(), error.field.as_deref()),
            (codes::UNMET_REQUIREMENT, Some("method"))
        );
        assert!(point(0.0).is_ok());
    }

    #[test]
    fn the_cell_limit_counts_every_method() {
        let axes =
            r#""gamma": {"min": 0, "max": 1, "n": 1000}, "h": {"min": 0, "max": 1, "n": 1000}"#;
        let one = format!(r#"{{"methods": ["csv1"], "omega": 1, {axes}}}"#);
        let job = StabilityRequest::from_slice(one.as_bytes())
            .unwrap()
            .prepare()
            .unwrap();
        assert_eq!(job.cells(), MAX_MAP_CELLS);
        let two = one.replace("\"csv1\"", "\"csv1\", \"rk4\"");
        let error = StabilityRequest::from_slice(two.as_bytes())
            .unwrap()
            .prepare()
            .unwrap_err();
        assert_eq!(
            (error.code.as_str(), error.field.as_deref()),
            (codes::TOO_MANY_CELLS, Some("methods"))
        );
    }
}

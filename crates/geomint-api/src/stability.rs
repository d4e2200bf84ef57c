//! Linear stability requests as users write them — the bodies of `POST /api/v1/stability` and
//! `POST /api/v1/stability/point` — and their strict readers into the core's specs
//! ([`crate::core::studies::stability`]). Methods take the same forms as in a simulation
//! request; every problem names its field (`methods[1].base`, `gamma.n`, `omega`).

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::json::{self, count, missing, Obj};
use super::method::{read_method, read_methods, MethodSpec};
use crate::core::error::{CoreError, ErrorDetail, Field};
use crate::core::methods::MethodId;
use crate::core::simulation::MethodAt;
use crate::core::stability::{StabilityAxis, MAX_AXIS_POINTS};
use crate::core::studies::stability::{PointSpec, StabilitySpec, NO_PROPAGATION_MATRIX};

/// The fields of [`StabilityRequest`], as the reader accepts them.
pub const MAP_FIELDS: &[&str] = &["methods", "omega", "gamma", "h"];
/// The fields of [`PointRequest`], as the reader accepts them.
pub const POINT_FIELDS: &[&str] = &["method", "omega", "gamma", "h"];
/// The fields of an axis.
pub const AXIS_FIELDS: &[&str] = &["min", "max", "n"];

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
    #[schema(min_items = 1, max_items = 16)]
    pub methods: Vec<MethodSpec>,
    /// The undamped frequency ω (finite, > 0).
    #[schema(example = 3.51, exclusive_minimum = 0.0)]
    pub omega: f64,
    /// The damping rates γ: the columns of each map.
    pub gamma: StabilityAxis,
    /// The step sizes h: the rows of each map.
    pub h: StabilityAxis,
}

/// A request for the stability analysis of one method at one (ω, γ, h).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"method": "csv1", "omega": 3.51, "gamma": 0.5, "h": 0.2}))]
pub struct PointRequest {
    /// A fixed-step method (not `reference`).
    pub method: MethodSpec,
    /// The undamped frequency ω (finite, > 0).
    #[schema(example = 3.51, exclusive_minimum = 0.0)]
    pub omega: f64,
    /// The damping rate γ (finite, ≥ 0).
    #[schema(example = 0.5, minimum = 0.0)]
    pub gamma: f64,
    /// The step size h (finite, > 0).
    #[schema(example = 0.2, exclusive_minimum = 0.0)]
    pub h: f64,
}

/// The method `spec` at `field` as a fixed-step method: the adaptive `reference` is refused,
/// naming the id where the request gave an object.
fn fixed_step(spec: &MethodSpec, field: &Field) -> Result<MethodAt, ErrorDetail> {
    if spec.id() == MethodId::Reference.as_str() {
        let at = match spec {
            MethodSpec::Id(_) => field.clone(),
            MethodSpec::Options(_) => field.key("id"),
        };
        return Err(CoreError::Unsupported {
            field: at,
            reason: NO_PROPAGATION_MATRIX,
        }
        .into());
    }
    Ok(spec.at(field)?)
}

/// Reads the axis `field`.
fn axis(v: &Value, field: &Field) -> Result<StabilityAxis, ErrorDetail> {
    let o = Obj::new(v, field.clone(), AXIS_FIELDS)?;
    let min = o.required("min", "the first value", json::number)?;
    let max = o.required("max", "the last value", json::number)?;
    let n = o.required("n", "the number of points", |v, at| {
        count(
            v,
            at,
            &format!("a whole number of points (2 to {MAX_AXIS_POINTS})"),
        )
    })?;
    Ok(StabilityAxis {
        min,
        max,
        n: usize::try_from(n).unwrap_or(usize::MAX),
    })
}

/// Reads the axis `name` of `obj`.
fn required_axis(obj: &Obj<'_>, name: &str) -> Result<StabilityAxis, ErrorDetail> {
    match obj.get(name) {
        Some(v) => axis(v, &obj.field(name)),
        None => Err(missing(
            &obj.field(name),
            &format!("the {name} axis, e.g. {{\"min\": 0, \"max\": 1, \"n\": 41}}"),
        )),
    }
}

impl StabilityRequest {
    /// Reads a request from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&json::parse_json(bytes)?)
    }

    /// Reads a request from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = Obj::new(value, Field::default(), MAP_FIELDS)?;
        Ok(StabilityRequest {
            methods: obj.required(
                "methods",
                "the methods to map, e.g. [\"csv1\", {\"id\": \"triple_jump\", \"base\": \"csv1\"}]",
                read_methods,
            )?,
            omega: obj.required("omega", "the undamped frequency ω", json::number)?,
            gamma: required_axis(&obj, "gamma")?,
            h: required_axis(&obj, "h")?,
        })
    }

    /// The request in core terms.
    pub fn to_spec(&self) -> Result<StabilitySpec, ErrorDetail> {
        let methods = Field::new("methods");
        Ok(StabilitySpec {
            methods: self
                .methods
                .iter()
                .enumerate()
                .map(|(i, m)| fixed_step(m, &methods.index(i)))
                .collect::<Result<_, _>>()?,
            omega: self.omega,
            gamma: self.gamma,
            h: self.h,
        })
    }
}

impl PointRequest {
    /// Reads a request from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&json::parse_json(bytes)?)
    }

    /// Reads a request from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = Obj::new(value, Field::default(), POINT_FIELDS)?;
        Ok(PointRequest {
            method: obj.required("method", "the method, e.g. \"csv1\"", read_method)?,
            omega: obj.required("omega", "the undamped frequency ω", json::number)?,
            gamma: obj.required("gamma", "the damping rate γ", json::number)?,
            h: obj.required("h", "the step size", json::number)?,
        })
    }

    /// The request in core terms.
    pub fn to_spec(&self) -> Result<PointSpec, ErrorDetail> {
        Ok(PointSpec {
            method: fixed_step(&self.method, &Field::new("method"))?,
            omega: self.omega,
            gamma: self.gamma,
            h: self.h,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::error::ErrorCode;
    use crate::core::run::Budget;
    use crate::core::studies::engine::Local;
    use crate::core::studies::stability::{maps, MAX_MAP_CELLS};

    fn field_of_map(text: &str) -> Option<String> {
        StabilityRequest::from_slice(text.as_bytes())
            .and_then(|r| Ok(r.to_spec()?.prepare().map(|_| ())?))
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
        let error = ErrorDetail::from(
            StabilityRequest::from_slice(damped.as_bytes())
                .unwrap()
                .to_spec()
                .unwrap()
                .prepare()
                .unwrap_err(),
        );
        assert_eq!(
            (error.code, error.field.as_deref()),
            (ErrorCode::UnmetRequirement, Some("methods[1]"))
        );
        assert!(error.message.contains("no damping"), "{}", error.message);
        let undamped = format!(
            r#"{{"methods": ["rowlands"], "omega": 1, "gamma": {{"min": 0, "max": 0, "n": 2}}, {h}}}"#
        );
        let job = StabilityRequest::from_slice(undamped.as_bytes())
            .unwrap()
            .to_spec()
            .unwrap()
            .prepare()
            .unwrap();
        assert!(maps(&job, &Local, Budget::default()).is_ok());
        let point = |gamma: f64| {
            PointRequest::from_value(&serde_json::json!({
                "method": {"id": "rowlands", "processor": "none"}, "omega": 1, "gamma": gamma, "h": 0.1
            }))
            .unwrap()
            .to_spec()
            .unwrap()
            .prepare()
        };
        let error = ErrorDetail::from(point(0.1).unwrap_err());
        assert_eq!(
            (error.code, error.field.as_deref()),
            (ErrorCode::UnmetRequirement, Some("method"))
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
            .to_spec()
            .unwrap()
            .prepare()
            .unwrap();
        assert_eq!(job.points(), MAX_MAP_CELLS);
        let two = one.replace("\"csv1\"", "\"csv1\", \"rk4\"");
        let error = ErrorDetail::from(
            StabilityRequest::from_slice(two.as_bytes())
                .unwrap()
                .to_spec()
                .unwrap()
                .prepare()
                .unwrap_err(),
        );
        assert_eq!(
            (error.code, error.field.as_deref()),
            (ErrorCode::TooManyCells, Some("methods"))
        );
    }
}

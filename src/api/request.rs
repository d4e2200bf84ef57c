//! The simulation request as users write it — the body of `POST /api/v1/simulate` and the spec
//! file of `geomint run` — and its strict parser.
//!
//! Parsing goes through a JSON value first, then field by field, so that every problem is
//! reported with the path of the field at fault: unknown fields (at any depth, including method
//! objects), wrong types, unknown method ids. Numbers JSON cannot hold (`1e999`) fail the first
//! stage with the path of the number.

use serde::Serialize;
use serde_json::{Map, Value};
use utoipa::ToSchema;

use super::error::{codes, ErrorDetail};
use crate::core::methods::{MethodId, MethodInput};
use crate::core::simulate::{Limits, Request, Simulation};

/// A simulation request.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({
    "system": "pendulum",
    "params": {"epsilon": 0.01},
    "methods": ["modin_3s", "heun"],
    "h": 0.1,
    "t_end": 200,
    "q0": [2.827433],
    "p0": [0.0],
    "output": {"every": 10},
    "compare_to_reference": false
}))]
pub struct SimulateRequest {
    /// System id (see `GET /api/v1/systems`).
    pub system: String,
    /// System parameters by name; omitted ones take their defaults. Conformally damped systems
    /// accept `epsilon` (= 2γ) instead of `gamma`.
    #[serde(default, skip_serializing_if = "Map::is_empty")]
    #[schema(value_type = Object)]
    pub params: Map<String, Value>,
    /// Coordinate chart (see the system's `charts`; default: its first, Cartesian one). Runs in
    /// a non-Cartesian chart also report their state transformed to Cartesian coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(example = "polar")]
    pub chart: Option<String>,
    /// The coordinates `q0` and `p0` are given in: `chart` (default) or `cartesian` (transformed
    /// into the chart by its point transformation and cotangent lift). Omitted `q0`/`p0` are
    /// always the catalogue's Cartesian defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_coordinates: Option<InitialCoordinates>,
    /// Methods to run, in this order, on the same system and initial state (at most 16).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub methods: Vec<MethodSpec>,
    /// A single method, instead of `methods`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<MethodSpec>,
    /// Step size (finite, > 0).
    pub h: f64,
    /// Final time (finite, > 0); the run takes ceil(t_end/h) steps of size h.
    pub t_end: f64,
    /// Initial positions (default: the system's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default: the system's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p0: Option<Vec<f64>>,
    /// Sampling.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output: Option<OutputOptions>,
    /// Measure energy errors against the adaptive reference integrator.
    #[serde(default)]
    pub compare_to_reference: bool,
    /// Report |det ∂Φ/∂z − e^{−2γ h n}| of each sampled step (conformally damped systems only).
    #[serde(default)]
    pub jacobian_defect: bool,
}

/// The coordinates an initial state is given in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum InitialCoordinates {
    /// The chart's own generalized coordinates and momenta.
    Chart,
    /// Cartesian coordinates and momenta (for a first-order ODE: the original variable).
    Cartesian,
}

/// Sampling options.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputOptions {
    /// Sample every this many steps (≥ 1; default: about 1000 samples per method). The first
    /// and the last step are always sampled.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub every: Option<u64>,
}

/// A method: a bare id, or an object with options.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(untagged)]
pub enum MethodSpec {
    /// A method id such as `modin_3s`.
    Id(String),
    /// A method with options.
    Options(MethodOptions),
}

/// A method with options.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MethodOptions {
    /// The method id.
    pub id: String,
    /// Inner Runge–Kutta method of `modin_rks` (default `heun`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inner: Option<String>,
    /// Symmetric second-order base of a composition (`triple_jump`, `suzuki_4`, `yoshida_6`,
    /// `kahan_li_6`, `kahan_li_8`; default `modin_3s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<String>,
    /// Relative tolerance of `reference` (in [1e-14, 1e-2]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Processor of `rowlands`: `none` (the second-order kernel alone), `original` (eqs. 32–33
    /// with h²/12) or `cheap` (eqs. 34–37; default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub processor: Option<String>,
}

/// The fields of [`SimulateRequest`], as the parser accepts them.
pub const REQUEST_FIELDS: &[&str] = &[
    "system",
    "params",
    "chart",
    "initial_coordinates",
    "methods",
    "method",
    "h",
    "t_end",
    "q0",
    "p0",
    "output",
    "compare_to_reference",
    "jacobian_defect",
];
const OUTPUT_FIELDS: &[&str] = &["every"];
const METHOD_FIELDS: &[&str] = &["id", "inner", "base", "tolerance", "processor"];

impl MethodSpec {
    /// The method id.
    pub fn id(&self) -> &str {
        match self {
            MethodSpec::Id(id) => id,
            MethodSpec::Options(o) => &o.id,
        }
    }

    /// The core's form of this method.
    pub fn to_input(&self) -> MethodInput {
        match self {
            MethodSpec::Id(id) => MethodInput::Id(id.clone()),
            MethodSpec::Options(o) => MethodInput::Object {
                id: o.id.clone(),
                inner: o.inner.clone(),
                base: o.base.clone(),
                tolerance: o.tolerance,
                processor: o.processor.clone(),
            },
        }
    }
}

impl SimulateRequest {
    /// Parses a request from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&parse_json(bytes)?)
    }

    /// Parses a request from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = object(value, None)?;
        check_fields(obj, REQUEST_FIELDS, "")?;
        let mut req = SimulateRequest {
            system: match present(obj, "system") {
                Some(v) => string(v, "system")?,
                None => return Err(missing("system", "the system id, e.g. \"pendulum\"")),
            },
            ..Default::default()
        };
        if let Some(v) = present(obj, "params") {
            req.params = object(v, Some("params"))?.clone();
        }
        if let Some(v) = present(obj, "chart") {
            req.chart = Some(string(v, "chart")?);
        }
        if let Some(v) = present(obj, "initial_coordinates") {
            req.initial_coordinates = Some(initial_coordinates(v)?);
        }
        match (present(obj, "methods"), present(obj, "method")) {
            (Some(_), Some(_)) => {
                return Err(ErrorDetail::at(
                    codes::INVALID_VALUE,
                    "method",
                    "give either `methods` (a list) or `method` (one), not both",
                ))
            }
            (Some(v), None) => req.methods = methods(v)?,
            (None, Some(v)) => req.method = Some(method(v, "method")?),
            (None, None) => {
                return Err(missing(
                    "methods",
                    "the methods to run, e.g. [\"modin_3s\", \"heun\"] (or one `method`)",
                ))
            }
        }
        req.h = match present(obj, "h") {
            Some(v) => number(v, "h")?,
            None => return Err(missing("h", "the step size")),
        };
        req.t_end = match present(obj, "t_end") {
            Some(v) => number(v, "t_end")?,
            None => return Err(missing("t_end", "the final time")),
        };
        if let Some(v) = present(obj, "q0") {
            req.q0 = Some(numbers(v, "q0")?);
        }
        if let Some(v) = present(obj, "p0") {
            req.p0 = Some(numbers(v, "p0")?);
        }
        if let Some(v) = present(obj, "output") {
            let o = object(v, Some("output"))?;
            check_fields(o, OUTPUT_FIELDS, "output.")?;
            let every =
                match present(o, "every") {
                    Some(v) => Some(v.as_u64().ok_or_else(|| {
                        wrong_type("output.every", "a whole number of steps ≥ 1", v)
                    })?),
                    None => None,
                };
            req.output = Some(OutputOptions { every });
        }
        if let Some(v) = present(obj, "compare_to_reference") {
            req.compare_to_reference = boolean(v, "compare_to_reference")?;
        }
        if let Some(v) = present(obj, "jacobian_defect") {
            req.jacobian_defect = boolean(v, "jacobian_defect")?;
        }
        Ok(req)
    }

    /// Whether the request gave a single `method` rather than `methods`.
    pub fn is_single_method(&self) -> bool {
        self.method.is_some()
    }

    /// The request in core terms.
    pub fn to_core(&self) -> Request {
        let methods = match &self.method {
            Some(m) => vec![m.to_input()],
            None => self.methods.iter().map(MethodSpec::to_input).collect(),
        };
        Request {
            system: self.system.clone(),
            params: self.params.clone(),
            chart: self.chart.clone(),
            initial_cartesian: self.initial_coordinates == Some(InitialCoordinates::Cartesian),
            methods,
            h: self.h,
            t_end: self.t_end,
            q0: self.q0.clone(),
            p0: self.p0.clone(),
            every: self.output.as_ref().and_then(|o| o.every),
            compare_to_reference: self.compare_to_reference,
            jacobian_defect: self.jacobian_defect,
        }
    }

    /// Validates the request against the catalogues and `limits` (cheap: no integration).
    pub fn prepare(&self, limits: &Limits) -> Result<Simulation, ErrorDetail> {
        let req = self.to_core();
        Simulation::prepare(&req, limits).map_err(|e| {
            let detail = ErrorDetail::from_core(&e, &req, limits);
            if self.is_single_method() {
                detail.singular_method()
            } else {
                detail
            }
        })
    }
}

/// Parses JSON text into a value; errors are `malformed_json` with line and column, and for a
/// number beyond the range of f64 also the path of that number.
pub fn parse_json(bytes: &[u8]) -> Result<Value, ErrorDetail> {
    let mut value = serde_json::from_slice(bytes).map_err(|e| malformed(bytes, &e))?;
    exact_floats(bytes, &mut value);
    Ok(value)
}

/// Deserializes JSON text into any type; syntax errors are `malformed_json` (see
/// [`parse_json`]), type errors `invalid_type`, unknown fields `unknown_field`.
pub fn from_json<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, ErrorDetail> {
    let value = parse_json(bytes)?;
    serde_json::from_value(value).map_err(|e| {
        let message = e.to_string();
        let field = message
            .strip_prefix("unknown field `")
            .and_then(|rest| rest.split('`').next())
            .map(str::to_string);
        match field {
            Some(f) => ErrorDetail::at(codes::UNKNOWN_FIELD, f, message),
            None => ErrorDetail::new(codes::INVALID_TYPE, message),
        }
    })
}

fn malformed(bytes: &[u8], e: &serde_json::Error) -> ErrorDetail {
    let text = e.to_string();
    if text.starts_with("number out of range") {
        let path = byte_offset(bytes, e.line(), e.column()).and_then(|at| path_at(&bytes[..at]));
        let message = format!(
            "{text}: JSON numbers must lie within ±1.8e308 (NaN and Infinity cannot be written in JSON)"
        );
        return ErrorDetail {
            code: codes::MALFORMED_JSON.to_string(),
            message: match &path {
                Some(p) => format!("{p}: {message}"),
                None => message,
            },
            field: path,
        };
    }
    let message = if e.is_eof() && bytes.iter().all(u8::is_ascii_whitespace) {
        "the input is empty; expected a JSON object".to_string()
    } else {
        format!("malformed JSON: {text}")
    };
    ErrorDetail::new(codes::MALFORMED_JSON, message)
}

/// The byte offset of a 1-based line and column as serde_json reports them.
fn byte_offset(bytes: &[u8], line: usize, column: usize) -> Option<usize> {
    let mut start = 0;
    for _ in 1..line {
        start += bytes[start..].iter().position(|&b| b == b'\n')? + 1;
    }
    Some((start + column).min(bytes.len()))
}

/// Where a JSON scanner stands: the containers around the current value.
enum Frame {
    Object {
        key: Option<String>,
        reading_key: bool,
    },
    Array {
        index: usize,
    },
}

/// Scans JSON text that is well-formed up to its end, calling `on_number` with the containers
/// around each number and the number's text; returns the containers open at the end.
fn scan(text: &str, mut on_number: impl FnMut(&[Frame], &str)) -> Vec<Frame> {
    let mut stack: Vec<Frame> = Vec::new();
    let bytes = text.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'"' => {
                let start = i;
                i += 1;
                while i < bytes.len() && bytes[i] != b'"' {
                    i += if bytes[i] == b'\\' { 2 } else { 1 };
                }
                if let (
                    Some(raw),
                    Some(Frame::Object {
                        key,
                        reading_key: true,
                    }),
                ) = (text.get(start..=i.min(bytes.len() - 1)), stack.last_mut())
                {
                    *key = Some(
                        serde_json::from_str::<String>(raw).unwrap_or_else(|_| raw.to_string()),
                    );
                }
            }
            b'-' | b'0'..=b'9' => {
                let start = i;
                while i + 1 < bytes.len()
                    && matches!(bytes[i + 1], b'0'..=b'9' | b'+' | b'-' | b'.' | b'e' | b'E')
                {
                    i += 1;
                }
                on_number(&stack, &text[start..=i]);
            }
            b'{' => stack.push(Frame::Object {
                key: None,
                reading_key: true,
            }),
            b'[' => stack.push(Frame::Array { index: 0 }),
            b'}' | b']' => {
                stack.pop();
            }
            b':' => {
                if let Some(Frame::Object { reading_key, .. }) = stack.last_mut() {
                    *reading_key = false;
                }
            }
            b',' => match stack.last_mut() {
                Some(Frame::Object { reading_key, .. }) => *reading_key = true,
                Some(Frame::Array { index }) => *index += 1,
                None => {}
            },
            _ => {}
        }
        i += 1;
    }
    stack
}

/// The path (`params.omega`, `q0[1]`) of the value being read at the end of `prefix`, a prefix of
/// a JSON document that was well-formed up to there.
fn path_at(prefix: &[u8]) -> Option<String> {
    let stack = scan(std::str::from_utf8(prefix).ok()?, |_, _| {});
    let mut path = String::new();
    for frame in &stack {
        match frame {
            Frame::Object { key: Some(k), .. } => {
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(k);
            }
            Frame::Object { key: None, .. } => return None,
            Frame::Array { index } => path.push_str(&format!("[{index}]")),
        }
    }
    (!path.is_empty()).then_some(path)
}

/// Re-reads every floating-point number of `value` from its text in `bytes` with a correctly
/// rounded conversion, so that a number sent in the shortest form that round-trips (as this
/// service writes them) arrives with exactly the same bits. (serde_json's default float parser
/// may be one unit in the last place off.)
fn exact_floats(bytes: &[u8], value: &mut Value) {
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    scan(text, |stack, token| {
        let mut target = Some(&mut *value);
        for frame in stack {
            target = match (target, frame) {
                (Some(v), Frame::Object { key: Some(k), .. }) => v.get_mut(k.as_str()),
                (Some(v), Frame::Array { index }) => v.get_mut(*index),
                _ => None,
            };
        }
        if let Some(v) = target.filter(|v| v.is_f64()) {
            if let Some(n) = token
                .parse::<f64>()
                .ok()
                .and_then(serde_json::Number::from_f64)
            {
                *v = Value::Number(n);
            }
        }
    });
}

/// A field's value, treating an explicit `null` as absent.
pub(crate) fn present<'a>(obj: &'a Map<String, Value>, key: &str) -> Option<&'a Value> {
    obj.get(key).filter(|v| !v.is_null())
}

/// Refuses the first key of `obj` not in `allowed` (`unknown_field`, named with `prefix`).
pub(crate) fn check_fields(
    obj: &Map<String, Value>,
    allowed: &[&str],
    prefix: &str,
) -> Result<(), ErrorDetail> {
    match obj.keys().find(|k| !allowed.contains(&k.as_str())) {
        None => Ok(()),
        Some(k) => Err(ErrorDetail::at(
            codes::UNKNOWN_FIELD,
            format!("{prefix}{k}"),
            format!(
                "unknown field `{prefix}{k}`; expected one of: {}",
                allowed.join(", ")
            ),
        )),
    }
}

fn describe(v: &Value) -> String {
    match v {
        Value::Null => "null".to_string(),
        Value::Bool(b) => format!("the boolean {b}"),
        Value::Number(n) => format!("the number {n}"),
        Value::String(s) if s.len() <= 40 => format!("the string \"{s}\""),
        Value::String(_) => "a string".to_string(),
        Value::Array(_) => "a list".to_string(),
        Value::Object(_) => "an object".to_string(),
    }
}

/// An `invalid_type` error: `field` should have been `expected`.
pub(crate) fn wrong_type(field: &str, expected: &str, v: &Value) -> ErrorDetail {
    ErrorDetail::at(
        codes::INVALID_TYPE,
        field,
        format!("{field}: expected {expected}, got {}", describe(v)),
    )
}

/// A `missing_field` error for `field`, explaining `what` it is.
pub(crate) fn missing(field: &str, what: &str) -> ErrorDetail {
    ErrorDetail::at(
        codes::MISSING_FIELD,
        field,
        format!("missing field `{field}`: {what}"),
    )
}

/// `v` as an object; `field` names it (`None` for the request itself).
pub(crate) fn object<'a>(
    v: &'a Value,
    field: Option<&str>,
) -> Result<&'a Map<String, Value>, ErrorDetail> {
    v.as_object().ok_or_else(|| match field {
        Some(f) => wrong_type(f, "an object", v),
        None => ErrorDetail::new(
            codes::INVALID_TYPE,
            format!("the request must be a JSON object, got {}", describe(v)),
        ),
    })
}

/// `v` as a string.
pub(crate) fn string(v: &Value, field: &str) -> Result<String, ErrorDetail> {
    v.as_str()
        .map(str::to_string)
        .ok_or_else(|| wrong_type(field, "a string", v))
}

/// `v` as a number.
pub(crate) fn number(v: &Value, field: &str) -> Result<f64, ErrorDetail> {
    v.as_f64().ok_or_else(|| wrong_type(field, "a number", v))
}

/// `initial_coordinates`: `chart` or `cartesian`.
pub(crate) fn initial_coordinates(v: &Value) -> Result<InitialCoordinates, ErrorDetail> {
    match string(v, "initial_coordinates")?.as_str() {
        "chart" => Ok(InitialCoordinates::Chart),
        "cartesian" => Ok(InitialCoordinates::Cartesian),
        other => Err(ErrorDetail::at(
            codes::INVALID_VALUE,
            "initial_coordinates",
            format!("`{other}` is not one of chart, cartesian"),
        )),
    }
}

fn boolean(v: &Value, field: &str) -> Result<bool, ErrorDetail> {
    v.as_bool()
        .ok_or_else(|| wrong_type(field, "true or false", v))
}

/// A list of numbers, each named `field[i]` in errors.
pub(crate) fn numbers(v: &Value, field: &str) -> Result<Vec<f64>, ErrorDetail> {
    let list = v
        .as_array()
        .ok_or_else(|| wrong_type(field, "a list of numbers", v))?;
    list.iter()
        .enumerate()
        .map(|(i, x)| number(x, &format!("{field}[{i}]")))
        .collect()
}

fn method_id(v: &Value, field: &str) -> Result<String, ErrorDetail> {
    let id = string(v, field)?;
    if MethodId::parse(&id).is_none() {
        let known: Vec<&str> = MethodId::ALL.iter().map(|m| m.as_str()).collect();
        return Err(ErrorDetail::at(
            codes::UNKNOWN_METHOD,
            field,
            format!(
                "{field}: unknown method `{id}`; known: {}",
                known.join(", ")
            ),
        ));
    }
    Ok(id)
}

/// `methods`: a list of methods, each named `methods[i]` in errors.
pub(crate) fn methods(v: &Value) -> Result<Vec<MethodSpec>, ErrorDetail> {
    v.as_array()
        .ok_or_else(|| wrong_type("methods", "a list of methods", v))?
        .iter()
        .enumerate()
        .map(|(i, m)| method(m, &format!("methods[{i}]")))
        .collect()
}

/// A method: an id or an object with options, with unknown ids and fields named.
pub(crate) fn method(v: &Value, field: &str) -> Result<MethodSpec, ErrorDetail> {
    match v {
        Value::String(_) => Ok(MethodSpec::Id(method_id(v, field)?)),
        Value::Object(o) => {
            check_fields(o, METHOD_FIELDS, &format!("{field}."))?;
            let id = match present(o, "id") {
                Some(v) => method_id(v, &format!("{field}.id"))?,
                None => return Err(missing(&format!("{field}.id"), "the method id")),
            };
            let option = |name: &str| -> Result<Option<String>, ErrorDetail> {
                present(o, name)
                    .map(|v| method_id(v, &format!("{field}.{name}")))
                    .transpose()
            };
            Ok(MethodSpec::Options(MethodOptions {
                id,
                inner: option("inner")?,
                base: option("base")?,
                tolerance: present(o, "tolerance")
                    .map(|v| number(v, &format!("{field}.tolerance")))
                    .transpose()?,
                processor: present(o, "processor")
                    .map(|v| {
                        v.as_str().map(str::to_string).ok_or_else(|| {
                            wrong_type(
                                &format!("{field}.processor"),
                                "a processor name: none, original or cheap",
                                v,
                            )
                        })
                    })
                    .transpose()?,
            }))
        }
        other => Err(wrong_type(
            field,
            "a method id or an object such as {\"id\": \"modin_rks\", \"inner\": \"rk4\"}",
            other,
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn field_of(text: &str) -> Option<String> {
        SimulateRequest::from_slice(text.as_bytes())
            .unwrap_err()
            .field
    }

    #[test]
    fn out_of_range_numbers_are_located() {
        assert_eq!(field_of(r#"{"h": 1e999}"#).as_deref(), Some("h"));
        assert_eq!(
            field_of(r#"{"system": "x", "q0": [1, 2, -1e999]}"#).as_deref(),
            Some("q0[2]")
        );
        assert_eq!(
            field_of("{\"params\": {\"a\": [1], \"omega\":\n 1e400}}").as_deref(),
            Some("params.omega")
        );
        assert_eq!(field_of(r#"{"a\"b": 1e999}"#).as_deref(), Some("a\"b"));
    }

    #[test]
    fn fields_are_named() {
        let base = r#""system": "pendulum", "h": 0.1, "t_end": 1"#;
        assert_eq!(
            field_of(&format!(r#"{{{base}, "methods": ["heun"], "x": 1}}"#)).as_deref(),
            Some("x")
        );
        assert_eq!(
            field_of(&format!(
                r#"{{{base}, "methods": ["heun", {{"id": "rk4", "y": 1}}]}}"#
            ))
            .as_deref(),
            Some("methods[1].y")
        );
        assert_eq!(
            field_of(&format!(
                r#"{{{base}, "methods": ["heun"], "output": {{"every": -1}}}}"#
            ))
            .as_deref(),
            Some("output.every")
        );
        assert_eq!(
            field_of(&format!(
                r#"{{{base}, "method": {{"id": "modin_rks", "inner": "rk9"}}}}"#
            ))
            .as_deref(),
            Some("method.inner")
        );
        assert_eq!(
            field_of(&format!(
                r#"{{{base}, "methods": ["heun"], "q0": [1, "a"]}}"#
            ))
            .as_deref(),
            Some("q0[1]")
        );
    }

    #[test]
    fn floats_arrive_with_their_exact_bits() {
        let xs: Vec<f64> = (0..2000)
            .map(|i| 1.0 + 0.1 * i as f64)
            .chain([3.8000000000000003, -2.2250738585072014e-308, 0.1 + 0.2])
            .collect();
        let text =
            serde_json::to_string(&json!({"a": {"b": [xs.clone()]}, "c\\\"": xs[5], "n": 10}))
                .unwrap();
        let v = parse_json(text.as_bytes()).unwrap();
        let back: Vec<f64> = serde_json::from_value(v["a"]["b"][0].clone()).unwrap();
        assert!(xs
            .iter()
            .zip(&back)
            .all(|(x, y)| x.to_bits() == y.to_bits()));
        assert_eq!(v["c\\\""].as_f64().unwrap().to_bits(), xs[5].to_bits());
        assert_eq!(v["n"].as_u64(), Some(10));
    }

    #[test]
    fn a_full_request_parses() {
        let req = SimulateRequest::from_slice(
            br#"{"system": "pendulum", "params": {"epsilon": 0.01}, "methods": ["modin_3s", {"id": "triple_jump", "base": "csv1"}],
                "h": 0.1, "t_end": 200, "q0": [2.5], "p0": null, "output": {"every": 10}, "compare_to_reference": true}"#,
        )
        .unwrap();
        assert_eq!(req.methods.len(), 2);
        assert_eq!(req.p0, None);
        let core = req.to_core();
        assert_eq!(core.every, Some(10));
        assert!(core.compare_to_reference);
        assert_eq!(
            core.methods[1],
            MethodInput::Object {
                id: "triple_jump".into(),
                inner: None,
                base: Some("csv1".into()),
                tolerance: None,
                processor: None
            }
        );
        // Serializing gives back what was parsed.
        let again = SimulateRequest::from_value(&serde_json::to_value(&req).unwrap()).unwrap();
        assert_eq!(again, req);
    }
}

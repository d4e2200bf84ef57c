//! The simulation request as users write it — the body of `POST /api/v1/simulate` and
//! `POST /api/v1/recordings`, and the spec file of `geomint run` — its strict reader, and its
//! validation into the core's [`Simulation`].

use std::collections::BTreeMap;

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::chaos;
use super::crossings::{
    read_energy, read_section, read_stop_when, watching, EnergyRequest, SectionRequest,
    StopWhenRequest, DEFAULT_MAX_POINTS,
};
use super::json::{self, boolean, count, numbers, string, Obj};
use super::method::{read_method, read_methods, MethodSpec};
use super::system::StoredSystems;
use super::system::{read_system, SystemRequest};
use crate::core::chaos::{ChaosSpec, Indicator};
use crate::core::error::{CoreError, ErrorCode, ErrorDetail, Field};
use crate::core::run::Budget;
use crate::core::simulation::{
    InitialCoordinates, InputFields, Limits, MethodAt, Simulation, SimulationSpec,
};
use crate::core::systems::{ChartId, ParamValue};

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
    /// The system: a built-in or stored system's id (see `GET /api/v1/systems`), or a
    /// definition of its own.
    pub system: SystemRequest,
    /// System parameters by name; omitted ones take their defaults. Conformally damped systems
    /// accept `epsilon` (= 2γ) instead of `gamma`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    #[schema(value_type = Object)]
    pub params: BTreeMap<String, ParamValue>,
    /// Coordinate chart (see the system's `charts`; default: its first, Cartesian one). Runs in
    /// a non-Cartesian chart also report their state transformed to Cartesian coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<ChartId>, example = "polar")]
    pub chart: Option<String>,
    /// The coordinates `q0` and `p0` are given in: `chart` (default) or `cartesian` (transformed
    /// into the chart by its point transformation and cotangent lift). Omitted `q0`/`p0` are
    /// always the catalogue's Cartesian defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_coordinates: Option<InitialCoordinates>,
    /// Methods to run, in this order, on the same system and initial state (1 to 16; or give
    /// one `method` instead).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schema(min_items = 1, max_items = 16)]
    pub methods: Vec<MethodSpec>,
    /// A single method, instead of `methods`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub method: Option<MethodSpec>,
    /// Step size (finite, > 0).
    #[schema(exclusive_minimum = 0.0)]
    pub h: f64,
    /// Final time (finite, > 0); the run takes ceil(t_end/h) steps of size h.
    #[schema(exclusive_minimum = 0.0)]
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
    /// A Poincaré section of each run: its crossings of a surface located to round-off by
    /// Hénon's trick, each with its t, q, p and H (`section` per run; `crossings` lines when
    /// streamed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub section: Option<SectionRequest>,
    /// What ends each run before `t_end`: an event (the n-th crossing of a surface), an
    /// indicator's threshold, or both.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_when: Option<StopWhenRequest>,
    /// An energy level: one initial momentum solved for so that H(q0, p0) is the energy.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy: Option<EnergyRequest>,
    /// Chaos indicators each run reports, per sample and in its summary, from deviation vectors
    /// advanced by the method's own tangent map: `lyapunov` (the finite-time spectrum, largest
    /// first), `megno` (Y and its mean ⟨Y⟩ as `megno` and `megno_mean`), `fli`, `sali`, `gali`.
    /// Every method needs a step Jacobian (not `reference`, `rowlands`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schema(example = json!(["megno", "lyapunov"]))]
    pub indicators: Vec<Indicator>,
    /// Deviation vectors k, 1 to 2n (default: 2n with `lyapunov` or `gali`, else 2 with `sali`,
    /// else 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1)]
    pub deviations: Option<u64>,
    /// Steps between re-orthonormalisations of the deviation vectors, which are also the steps
    /// the indicators are updated on (default 10).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1)]
    pub qr_every: Option<u64>,
}

/// Sampling options.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputOptions {
    /// Sample every this many steps (≥ 1; default: about 1000 samples per method). The first
    /// and the last step are always sampled.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1)]
    pub every: Option<u64>,
}

/// The fields of [`SimulateRequest`], as the reader accepts them.
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
    "section",
    "stop_when",
    "energy",
    "indicators",
    "deviations",
    "qr_every",
];
const OUTPUT_FIELDS: &[&str] = &["every"];

/// `initial_coordinates`: `chart` or `cartesian`.
pub fn initial_coordinates(v: &Value, field: &Field) -> Result<InitialCoordinates, ErrorDetail> {
    match string(v, field)?.as_str() {
        "chart" => Ok(InitialCoordinates::Chart),
        "cartesian" => Ok(InitialCoordinates::Cartesian),
        other => Err(ErrorDetail::at(
            ErrorCode::InvalidValue,
            field,
            format!("{field}: `{other}` is not one of chart, cartesian"),
        )),
    }
}

impl SimulateRequest {
    /// Reads a request from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&json::parse_json(bytes)?)
    }

    /// Reads a request from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = Obj::new(value, Field::default(), REQUEST_FIELDS)?;
        let mut req = SimulateRequest {
            system: obj.required(
                "system",
                "the system id, e.g. \"pendulum\", or a system definition",
                read_system,
            )?,
            params: obj.optional("params", json::params)?.unwrap_or_default(),
            chart: obj.optional("chart", string)?,
            initial_coordinates: obj.optional("initial_coordinates", initial_coordinates)?,
            ..Default::default()
        };
        match (obj.has("methods"), obj.has("method")) {
            (true, true) => {
                return Err(ErrorDetail::at(
                    ErrorCode::InvalidValue,
                    "method",
                    "method: give either `methods` (a list) or `method` (one), not both",
                ))
            }
            (true, false) => {
                req.methods = obj.optional("methods", read_methods)?.unwrap_or_default()
            }
            (false, true) => req.method = obj.optional("method", read_method)?,
            (false, false) => {
                return Err(json::missing(
                    &Field::new("methods"),
                    "the methods to run, e.g. [\"modin_3s\", \"heun\"] (or one `method`)",
                ))
            }
        }
        req.h = obj.required("h", "the step size", json::number)?;
        req.t_end = obj.required("t_end", "the final time", json::number)?;
        req.q0 = obj.optional("q0", numbers)?;
        req.p0 = obj.optional("p0", numbers)?;
        req.output = obj.optional("output", |v, at| {
            let o = Obj::new(v, at.clone(), OUTPUT_FIELDS)?;
            Ok(OutputOptions {
                every: o.optional("every", |v, at| count(v, at, "a whole number of steps ≥ 1"))?,
            })
        })?;
        req.compare_to_reference = obj
            .optional("compare_to_reference", boolean)?
            .unwrap_or(false);
        req.jacobian_defect = obj.optional("jacobian_defect", boolean)?.unwrap_or(false);
        req.section = obj.optional("section", read_section)?;
        req.stop_when = obj.optional("stop_when", read_stop_when)?;
        req.energy = obj.optional("energy", read_energy)?;
        let chaos = chaos::read(&obj)?;
        req.indicators = chaos.indicators;
        req.deviations = chaos.deviations;
        req.qr_every = chaos.qr_every;
        Ok(req)
    }

    /// The methods with the fields they were given at: `methods[i]`, or `method`.
    fn methods_at(&self) -> Vec<(&MethodSpec, Field)> {
        match &self.method {
            Some(m) => vec![(m, Field::new("method"))],
            None => self
                .methods
                .iter()
                .enumerate()
                .map(|(i, m)| (m, Field::new("methods").index(i)))
                .collect(),
        }
    }

    /// The request with a stored system's id replaced by its definition, as recordings keep it
    /// (so that a recording reads back wherever it goes).
    pub fn inlined(&self, stored: &dyn StoredSystems) -> SimulateRequest {
        SimulateRequest {
            system: self.system.inlined(stored),
            ..self.clone()
        }
    }

    /// The request in core terms.
    pub fn to_spec(&self, stored: &dyn StoredSystems) -> Result<SimulationSpec, CoreError> {
        let methods = self
            .methods_at()
            .into_iter()
            .map(|(m, field)| m.at(&field))
            .collect::<Result<Vec<MethodAt>, _>>()?;
        let fields = InputFields {
            methods: if self.method.is_some() {
                Field::new("method")
            } else {
                Field::new("methods")
            },
            ..InputFields::default()
        };
        Ok(SimulationSpec {
            system: self.system.to_ref(&Field::new("system"), stored)?,
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
            fields,
        })
    }

    /// The chaos indicators asked for, in core terms (`None`: none).
    pub fn chaos_spec(&self) -> Result<Option<ChaosSpec>, CoreError> {
        chaos::chaos_spec(
            &self.indicators,
            self.deviations,
            self.qr_every,
            self.stop_when.as_ref(),
        )
    }

    /// Validates the request against the catalogues and `limits` (cheap: no integration): the
    /// simulation, its indicators, then what its runs watch (section points count against the
    /// samples).
    pub fn prepare(
        &self,
        limits: &Limits,
        stored: &dyn StoredSystems,
    ) -> Result<Simulation, ErrorDetail> {
        let spec = self.to_spec(stored)?;
        let chaos = self.chaos_spec()?;
        let mut sim = Simulation::prepare(&spec, limits)?;
        if let Some(chaos) = chaos {
            sim = sim.with_chaos(&chaos)?;
        }
        if let Some(section) = &self.section {
            let points = section
                .max_points
                .unwrap_or(DEFAULT_MAX_POINTS)
                .saturating_mul(sim.methods.len() as u64);
            if points > limits.max_samples {
                return Err(CoreError::TooManySamples {
                    field: Field::new("section").key("max_points"),
                    samples: points,
                    limit: limits.max_samples,
                }
                .into());
            }
        }
        let watching = watching(
            self.section.as_ref(),
            self.stop_when.as_ref(),
            self.energy.as_ref(),
        );
        Ok(sim.watching(&watching)?)
    }
}

/// Reads the simulation `request` (JSON text), checks it against `limits` and runs it with up to
/// `workers` methods at once, without stored systems: its document as the service writes it
/// (JSON text), or the error it would answer. What `geomint.local` runs in a Python process.
pub fn simulate_to_json(
    request: &[u8],
    limits: &Limits,
    workers: usize,
) -> Result<String, ErrorDetail> {
    let request = SimulateRequest::from_slice(request)?;
    let sim = request.prepare(limits, &crate::system::NoStoredSystems)?;
    let document = sim.simulate(workers.clamp(1, sim.methods.len()), Budget::default())?;
    serde_json::to_string(&document)
        .map_err(|e| ErrorDetail::new(ErrorCode::Internal, format!("the document: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system::NoStoredSystems;
    use serde_json::json;

    fn field_of(text: &str) -> Option<String> {
        SimulateRequest::from_slice(text.as_bytes())
            .and_then(|r| r.prepare(&Limits::default(), &NoStoredSystems).map(|_| r))
            .unwrap_err()
            .field
    }

    #[test]
    fn fields_are_named() {
        let base = r#""system": "pendulum", "h": 0.1, "t_end": 1"#;
        for (body, field) in [
            (format!(r#"{{{base}, "methods": ["heun"], "x": 1}}"#), "x"),
            (
                format!(r#"{{{base}, "methods": ["heun", {{"id": "rk4", "y": 1}}]}}"#),
                "methods[1].y",
            ),
            (
                format!(r#"{{{base}, "methods": ["heun"], "output": {{"every": -1}}}}"#),
                "output.every",
            ),
            (
                format!(r#"{{{base}, "method": {{"id": "modin_rks", "inner": "rk9"}}}}"#),
                "method.inner",
            ),
            (
                format!(r#"{{{base}, "methods": ["heun"], "q0": [1, "a"]}}"#),
                "q0[1]",
            ),
            (format!(r#"{{{base}, "method": "rowlands"}}"#), "method"),
        ] {
            assert_eq!(field_of(&body).as_deref(), Some(field), "{body}");
        }
    }

    #[test]
    fn a_full_request_reads_and_writes_back() {
        let req = SimulateRequest::from_slice(
            br#"{"system": "pendulum", "params": {"epsilon": 0.01}, "methods": ["modin_3s", {"id": "triple_jump", "base": "csv1"}],
                "h": 0.1, "t_end": 200, "q0": [2.5], "p0": null, "output": {"every": 10}, "compare_to_reference": true}"#,
        )
        .unwrap();
        assert_eq!(req.methods.len(), 2);
        assert_eq!(req.p0, None);
        let spec = req.to_spec(&NoStoredSystems).unwrap();
        assert_eq!(spec.every, Some(10));
        assert!(spec.compare_to_reference);
        assert_eq!(spec.methods[1].method.label(), "triple_jump(csv1)");
        assert_eq!(spec.methods[1].field.as_str(), "methods[1]");
        // Writing gives back what was read.
        let again = SimulateRequest::from_value(&serde_json::to_value(&req).unwrap()).unwrap();
        assert_eq!(again, req);
        let _ = json!({});
    }
}

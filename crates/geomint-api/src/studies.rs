//! Study requests as users write them — the bodies of `POST /api/v1/studies/convergence`,
//! `/work-precision` and `/energy-map`, and the spec files of `geomint study` — and their strict
//! readers into the core's specs ([`crate::core::studies`]). Every problem names its field
//! (`runs[1].h[2]`, `charts[1]`, `x[0]`).

use std::collections::BTreeMap;

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::json::{self, count, list, numbers, string, wrong_type, Obj};
use super::method::{read_method, read_methods, MethodSpec};
use super::simulate::initial_coordinates;
use super::system::StoredSystems;
use super::system::{read_system, SystemRequest};
use crate::core::error::{ErrorDetail, Field};
use crate::core::simulation::{InitialCoordinates, MethodAt};
use crate::core::studies::convergence::ConvergenceSpec;
use crate::core::studies::energy_map::EnergyMapSpec;
use crate::core::studies::settings::{RunSpec, MAX_SAMPLES};
use crate::core::studies::work_precision::{WorkPrecisionSpec, DEFAULT_SAMPLES};
use crate::core::systems::{ChartId, ParamValue};

/// The fields of one `{method, h | tolerance}` entry (a work–precision run, a reference).
pub const RUN_FIELDS: &[&str] = &["method", "h", "tolerance"];

/// A method with its settings.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(as = RunSpec)]
pub struct RunRequest {
    /// The method.
    pub method: MethodSpec,
    /// Step sizes (fixed-step methods), each dividing t_end/samples.
    #[serde(default)]
    #[schema(min_items = 1)]
    pub h: Vec<f64>,
    /// Tolerances (the adaptive `reference` only), in [1e-14, 1e-2].
    #[serde(default)]
    #[schema(min_items = 1)]
    pub tolerance: Vec<f64>,
}

/// The schema of a study's reference run: a method with one step size or one tolerance.
#[derive(ToSchema)]
#[allow(dead_code)] // only its schema is used; the reader builds a `RunRequest`
pub struct ReferenceRun {
    /// The method.
    method: MethodSpec,
    /// The step size (a fixed-step method).
    #[schema(exclusive_minimum = 0.0)]
    h: Option<f64>,
    /// The tolerance (the adaptive `reference`), in [1e-14, 1e-2].
    #[schema(minimum = 1e-14, maximum = 1e-2)]
    tolerance: Option<f64>,
}

/// Reads a `{"method", "h" | "tolerance"}` entry; `single` asks for one number instead of a
/// list.
fn run_request(v: &Value, field: &Field, single: bool) -> Result<RunRequest, ErrorDetail> {
    let o = Obj::new(v, field.clone(), RUN_FIELDS)?;
    let method = o.required(
        "method",
        "the method, e.g. \"rk4\" or {\"id\": \"kahan_li_8\", \"base\": \"modin_3s\"}",
        read_method,
    )?;
    let values = |name: &str| -> Result<Vec<f64>, ErrorDetail> {
        let read = |v: &Value, at: &Field| match single {
            true => json::number(v, at).map(|x| vec![x]),
            false => numbers(v, at),
        };
        Ok(o.optional(name, read)?.unwrap_or_default())
    };
    Ok(RunRequest {
        method,
        h: values("h")?,
        tolerance: values("tolerance")?,
    })
}

impl RunRequest {
    /// The run in core terms; `field` names it (`runs[1]`, `reference`).
    fn to_spec(&self, field: &Field) -> Result<RunSpec, ErrorDetail> {
        Ok(RunSpec {
            method: self.method.at(&field.key("method"))?,
            h: self.h.clone(),
            tolerance: self.tolerance.clone(),
            field: field.clone(),
        })
    }
}

/// The fields every study has.
struct Common {
    system: SystemRequest,
    params: BTreeMap<String, ParamValue>,
    q0: Option<Vec<f64>>,
    p0: Option<Vec<f64>>,
    t_end: f64,
    samples: Option<u64>,
    reference: Option<RunRequest>,
}

impl Common {
    /// Reads the common fields of the study object `obj` (whose other fields the caller reads).
    fn read(obj: &Obj<'_>) -> Result<Self, ErrorDetail> {
        Ok(Common {
            system: obj.required(
                "system",
                "the system id, e.g. \"pendulum\", or a system definition",
                read_system,
            )?,
            params: obj.optional("params", json::params)?.unwrap_or_default(),
            t_end: obj.required("t_end", "the final time", json::number)?,
            samples: obj.optional("samples", |v, at| {
                count(v, at, &format!("a whole number from 1 to {MAX_SAMPLES}"))
            })?,
            q0: obj.optional("q0", numbers)?,
            p0: obj.optional("p0", numbers)?,
            reference: obj.optional("reference", |v, at| run_request(v, at, true))?,
        })
    }
}

/// The fields of a convergence study.
pub const CONVERGENCE_FIELDS: &[&str] = &[
    "system",
    "params",
    "chart",
    "charts",
    "initial_coordinates",
    "q0",
    "p0",
    "t_end",
    "methods",
    "h",
    "samples",
    "reference",
];

/// A convergence study.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({
    "system": "harmonic_oscillator",
    "params": {"omega": 1, "gamma": 0},
    "charts": ["cartesian", "compensating"],
    "q0": [1], "p0": [0],
    "t_end": 10,
    "methods": ["symplectic_euler"],
    "h": [0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125]
}))]
pub struct ConvergenceRequest {
    /// The system: a built-in or stored system's id, or a definition of its own.
    pub system: SystemRequest,
    /// System parameters (as for a simulation).
    #[serde(default)]
    #[schema(value_type = Object)]
    pub params: BTreeMap<String, ParamValue>,
    /// One coordinate chart (default: the system's first, Cartesian one).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<ChartId>)]
    pub chart: Option<String>,
    /// Several charts, instead of `chart`: every method runs in each, from the same physical
    /// initial state.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    #[schema(value_type = Vec<ChartId>, min_items = 1)]
    pub charts: Vec<String>,
    /// The coordinates `q0` and `p0` are given in: `chart` (the default with one chart) or
    /// `cartesian` (the default, and the only choice, with several charts). Omitted `q0`/`p0`
    /// are the catalogue's Cartesian defaults.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub initial_coordinates: Option<InitialCoordinates>,
    /// Initial positions (default: the system's).
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default: the system's).
    pub p0: Option<Vec<f64>>,
    /// Final time (finite, > 0).
    #[schema(exclusive_minimum = 0.0)]
    pub t_end: f64,
    /// The methods, as in a simulation (ids, or objects with options).
    #[schema(min_items = 1)]
    pub methods: Vec<MethodSpec>,
    /// Step sizes, each dividing t_end into a whole number of steps.
    #[schema(min_items = 1)]
    pub h: Vec<f64>,
    /// Evenly spaced sample times t_k = k·t_end/samples, k = 1…samples, over which the largest
    /// energy error is taken (1 to 1000; every step size must divide t_end/samples). Default:
    /// the largest number up to 1000 that divides every setting's step count.
    #[schema(minimum = 1, maximum = 1000)]
    pub samples: Option<u64>,
    /// The run the errors are measured against where the system has no exact solution
    /// (default: `reference` at tolerance 1e-13), in the system's Cartesian chart. Give one step
    /// size or tolerance.
    #[schema(value_type = Option<ReferenceRun>)]
    pub reference: Option<RunRequest>,
}

impl ConvergenceRequest {
    /// Reads a study from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&json::parse_json(bytes)?)
    }

    /// Reads a study from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = Obj::new(value, Field::default(), CONVERGENCE_FIELDS)?;
        let common = Common::read(&obj)?;
        let charts = obj.optional("charts", |v, at| list(v, at, "a list of chart ids", string))?;
        if charts.as_ref().is_some_and(Vec::is_empty) {
            return Err(crate::core::error::CoreError::Empty {
                field: Field::new("charts"),
                what: "chart",
            }
            .into());
        }
        Ok(ConvergenceRequest {
            system: common.system,
            params: common.params,
            chart: obj.optional("chart", string)?,
            charts: charts.unwrap_or_default(),
            initial_coordinates: obj.optional("initial_coordinates", initial_coordinates)?,
            q0: common.q0,
            p0: common.p0,
            t_end: common.t_end,
            methods: obj.required(
                "methods",
                "the methods, e.g. [\"symplectic_euler\", \"rk4\"]",
                read_methods,
            )?,
            h: obj.required(
                "h",
                "the step sizes, e.g. [0.04, 0.02, 0.01, 0.005]",
                numbers,
            )?,
            samples: common.samples,
            reference: common.reference,
        })
    }

    /// The study in core terms.
    pub fn to_spec(&self, stored: &dyn StoredSystems) -> Result<ConvergenceSpec, ErrorDetail> {
        let methods = Field::new("methods");
        Ok(ConvergenceSpec {
            system: self.system.to_ref(&Field::new("system"), stored)?,
            params: self.params.clone(),
            chart: self.chart.clone(),
            charts: self.charts.clone(),
            initial_coordinates: self.initial_coordinates,
            q0: self.q0.clone(),
            p0: self.p0.clone(),
            t_end: self.t_end,
            methods: self
                .methods
                .iter()
                .enumerate()
                .map(|(i, m)| m.at(&methods.index(i)))
                .collect::<Result<Vec<MethodAt>, _>>()?,
            h: self.h.clone(),
            samples: self.samples,
            reference: self
                .reference
                .as_ref()
                .map(|r| r.to_spec(&Field::new("reference")))
                .transpose()?,
        })
    }
}

/// The fields of a work–precision study.
pub const STUDY_FIELDS: &[&str] = &[
    "system",
    "params",
    "q0",
    "p0",
    "t_end",
    "samples",
    "runs",
    "reference",
    "repeats",
];

/// A work–precision study.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({
    "system": "elastic_pendulum_3d",
    "params": {"epsilon": 0.0001},
    "t_end": 1000,
    "runs": [
        {"method": {"id": "kahan_li_8", "base": "modin_3s"}, "h": [0.8, 0.4, 0.2]},
        {"method": "rk4", "h": [0.05, 0.025]},
        {"method": "reference", "tolerance": [1e-8, 1e-10]}
    ]
}))]
pub struct WorkPrecisionRequest {
    /// The system: a built-in or stored system's id, or a definition of its own.
    pub system: SystemRequest,
    /// System parameters (as for a simulation).
    #[serde(default)]
    #[schema(value_type = Object)]
    pub params: BTreeMap<String, ParamValue>,
    /// Initial positions (default: the system's).
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default: the system's).
    pub p0: Option<Vec<f64>>,
    /// Final time (finite, > 0).
    #[schema(exclusive_minimum = 0.0)]
    pub t_end: f64,
    /// Evenly spaced sample times t_k = k·t_end/samples, k = 1…samples (default 50, 1 to 1000),
    /// over which the largest energy error is taken.
    #[serde(default)]
    #[schema(minimum = 1, maximum = 1000)]
    pub samples: u64,
    /// The methods, each with its step sizes (or for `reference` its tolerances).
    #[schema(min_items = 1)]
    pub runs: Vec<RunRequest>,
    /// The run the errors are measured against where the system has no exact solution
    /// (default: `reference` at tolerance 1e-13). Give one step size or tolerance.
    #[schema(value_type = Option<ReferenceRun>)]
    pub reference: Option<RunRequest>,
    /// Timings per setting, 1 to 20 (default 1; a run under 20 ms is always timed 5 times): a
    /// point's `wall_ms` is their median and `timings_ms` lists them, so that a busy machine
    /// shows as spread rather than as a wrong slope.
    #[serde(skip_serializing_if = "is_one")]
    #[schema(minimum = 1, maximum = 20, default = 1)]
    pub repeats: u64,
}

fn is_one(n: &u64) -> bool {
    *n == 1
}

impl WorkPrecisionRequest {
    /// Reads a study from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&json::parse_json(bytes)?)
    }

    /// Reads a study from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = Obj::new(value, Field::default(), STUDY_FIELDS)?;
        let common = Common::read(&obj)?;
        let runs = obj.required(
            "runs",
            "the methods with their step sizes, e.g. [{\"method\": \"rk4\", \"h\": [0.1, 0.05]}]",
            |v, at| {
                list(v, at, "a list of {method, h} objects", |r, at| {
                    run_request(r, at, false)
                })
            },
        )?;
        Ok(WorkPrecisionRequest {
            system: common.system,
            params: common.params,
            q0: common.q0,
            p0: common.p0,
            t_end: common.t_end,
            samples: common.samples.unwrap_or(DEFAULT_SAMPLES),
            runs,
            reference: common.reference,
            repeats: obj
                .optional("repeats", |v, at| {
                    count(v, at, "a whole number from 1 to 20")
                })?
                .unwrap_or(1),
        })
    }

    /// The request with a stored system's id replaced by its definition, as recordings keep it.
    pub fn inlined(&self, stored: &dyn StoredSystems) -> WorkPrecisionRequest {
        WorkPrecisionRequest {
            system: self.system.inlined(stored),
            ..self.clone()
        }
    }

    /// The study in core terms.
    pub fn to_spec(&self, stored: &dyn StoredSystems) -> Result<WorkPrecisionSpec, ErrorDetail> {
        let runs = Field::new("runs");
        Ok(WorkPrecisionSpec {
            system: self.system.to_ref(&Field::new("system"), stored)?,
            params: self.params.clone(),
            q0: self.q0.clone(),
            p0: self.p0.clone(),
            t_end: self.t_end,
            samples: self.samples,
            runs: self
                .runs
                .iter()
                .enumerate()
                .map(|(i, r)| r.to_spec(&runs.index(i)))
                .collect::<Result<_, _>>()?,
            reference: self
                .reference
                .as_ref()
                .map(|r| r.to_spec(&Field::new("reference")))
                .transpose()?,
            repeats: self.repeats,
        })
    }
}

/// The fields of an energy-map request.
pub const MAP_FIELDS: &[&str] = &["method", "params", "h", "t_max", "nx", "ny", "x", "y"];
/// Default step and horizon (Fig. 6 uses t_max = 50 000; the default is a quick look).
const DEFAULT_H: f64 = 0.2;
const DEFAULT_T_MAX: f64 = 2000.0;
const DEFAULT_N: usize = 41;

/// An energy-error map of the planar elastic pendulum (001 Fig. 6).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({"method": "symplectic_euler", "h": 0.2, "t_max": 2000, "nx": 41, "ny": 41}))]
pub struct EnergyMapRequest {
    /// The method, run in both charts (default `symplectic_euler`); it must run on the polar
    /// chart's non-separable Hamiltonian (symplectic Euler and its adjoint, implicit midpoint,
    /// the Runge–Kutta methods).
    #[serde(default)]
    pub method: MethodSpec,
    /// `m`, `k`, `l`, `g` of `elastic_pendulum_2d` (default 1, 1, 1 and g = 0.02 as in Fig. 6).
    #[serde(default)]
    #[schema(value_type = Object)]
    pub params: BTreeMap<String, ParamValue>,
    /// Step size (default 0.2).
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub h: f64,
    /// Final time (default 2000; Fig. 6 uses 50 000).
    #[serde(default)]
    #[schema(exclusive_minimum = 0.0)]
    pub t_max: f64,
    /// Grid points along x (default 41, at most 401).
    #[serde(default)]
    #[schema(minimum = 1, maximum = 401)]
    pub nx: usize,
    /// Grid points along y (default 41, at most 401).
    #[serde(default)]
    #[schema(minimum = 1, maximum = 401)]
    pub ny: usize,
    /// Range [min, max] of x₀ (default [−1.5, 1.5]).
    #[serde(default)]
    #[schema(min_items = 2, max_items = 2)]
    pub x: [f64; 2],
    /// Range [min, max] of y₀, y pointing down along gravity (default [−1.5, 1.5]).
    #[serde(default)]
    #[schema(min_items = 2, max_items = 2)]
    pub y: [f64; 2],
}

fn range(v: &Value, field: &Field) -> Result<[f64; 2], ErrorDetail> {
    let pair = v
        .as_array()
        .filter(|a| a.len() == 2)
        .ok_or_else(|| wrong_type(field, "a range [min, max]", v))?;
    Ok([
        json::number(&pair[0], &field.index(0))?,
        json::number(&pair[1], &field.index(1))?,
    ])
}

fn grid_points(v: &Value, field: &Field) -> Result<usize, ErrorDetail> {
    count(v, field, "a whole number of grid points")
        .map(|n| usize::try_from(n).unwrap_or(usize::MAX))
}

impl EnergyMapRequest {
    /// Reads a map request from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = Obj::new(value, Field::default(), MAP_FIELDS)?;
        let number = |name: &str, default: f64| -> Result<f64, ErrorDetail> {
            Ok(obj.optional(name, json::number)?.unwrap_or(default))
        };
        Ok(EnergyMapRequest {
            method: obj
                .optional("method", read_method)?
                .unwrap_or_else(|| MethodSpec::Id("symplectic_euler".into())),
            params: obj.optional("params", json::params)?.unwrap_or_default(),
            h: number("h", DEFAULT_H)?,
            t_max: number("t_max", DEFAULT_T_MAX)?,
            nx: obj.optional("nx", grid_points)?.unwrap_or(DEFAULT_N),
            ny: obj.optional("ny", grid_points)?.unwrap_or(DEFAULT_N),
            x: obj.optional("x", range)?.unwrap_or([-1.5, 1.5]),
            y: obj.optional("y", range)?.unwrap_or([-1.5, 1.5]),
        })
    }

    /// The map in core terms.
    pub fn to_spec(&self) -> Result<EnergyMapSpec, ErrorDetail> {
        Ok(EnergyMapSpec {
            method: self.method.at(&Field::new("method"))?,
            params: self.params.clone(),
            h: self.h,
            t_max: self.t_max,
            nx: self.nx,
            ny: self.ny,
            x: self.x,
            y: self.y,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::simulation::Limits;
    use crate::system::NoStoredSystems;
    use serde_json::json;

    fn field_of(body: Value) -> Option<String> {
        ConvergenceRequest::from_value(&body)
            .and_then(|r| Ok(r.to_spec(&NoStoredSystems)?.prepare(&Limits::default())?))
            .unwrap_err()
            .field
    }

    #[test]
    fn default_samples_divide_every_step_count() {
        let req = ConvergenceRequest::from_value(&json!({
            "system": "harmonic_oscillator", "t_end": 9, "methods": ["rk4"], "h": [0.3, 0.45]}))
        .unwrap();
        let job = req
            .to_spec(&NoStoredSystems)
            .unwrap()
            .prepare(&Limits::default())
            .unwrap();
        assert_eq!(job.samples, 10);
    }

    #[test]
    fn fields_are_named() {
        let ok = json!({"system": "harmonic_oscillator", "t_end": 1, "methods": ["rk4"],
            "h": [0.1, 0.05]});
        let with = |key: &str, v: Value| {
            let mut body = ok.clone();
            body[key] = v;
            body
        };
        assert_eq!(
            field_of(with("h", json!([0.1, 0.3]))).as_deref(),
            Some("h[1]")
        );
        assert_eq!(field_of(with("h", json!([]))).as_deref(), Some("h"));
        assert_eq!(
            field_of(with("methods", json!([]))).as_deref(),
            Some("methods")
        );
        assert_eq!(
            field_of(with("chart", json!("polar"))).as_deref(),
            Some("chart")
        );
        assert_eq!(
            field_of(with("charts", json!(["cartesian", "cartesian"]))).as_deref(),
            Some("charts[1]")
        );
        let mut both = with("charts", json!(["cartesian", "compensating"]));
        both["chart"] = json!("cartesian");
        assert_eq!(field_of(both).as_deref(), Some("charts"));
        let mut in_chart = with("charts", json!(["cartesian", "compensating"]));
        in_chart["q0"] = json!([0.5]);
        in_chart["initial_coordinates"] = json!("chart");
        assert_eq!(field_of(in_chart).as_deref(), Some("initial_coordinates"));
        assert_eq!(field_of(with("samples", json!(3))).as_deref(), Some("h[0]"));
        assert_eq!(
            field_of(with(
                "methods",
                json!(["rk4", {"id": "kahan_li_8", "base": "heun"}])
            ))
            .as_deref(),
            Some("methods[1].base")
        );
    }
}

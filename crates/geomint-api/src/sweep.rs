//! Sweep requests as users write them — the body of `POST /api/v1/studies/sweep` and the spec
//! file of `geomint study sweep` — their strict reader into the core's
//! [`SweepSpec`](crate::core::studies::sweep::SweepSpec), the request's digest (the identity that
//! shards carry), and the presets: the energy-error map of paper 001 Fig. 6 and the numerical
//! stability map of paper 003 Ch. 3.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::Serialize;
use serde_json::{json, Value};
use sha2::{Digest, Sha256};
use utoipa::ToSchema;

use super::chaos::{self, EnergySurfaceRequest};
use super::crossings::{read_section, read_stop_when, watching, SectionRequest, StopWhenRequest};
use super::json::{self, count, list, numbers, string, Obj};
use super::method::{read_methods, MethodSpec};
use super::simulate::initial_coordinates;
use super::studies::EnergyMapRequest;
use super::system::StoredSystems;
use super::system::{read_system, SystemRequest};
use crate::core::chaos::Indicator;
use crate::core::error::{CoreError, ErrorCode, ErrorDetail, Field};
use crate::core::simulation::InitialCoordinates;
use crate::core::studies::energy_map::FIG6_G;
use crate::core::studies::sweep::{Axis, EnergyReference, Scale, SweepSpec, Target};
use crate::core::systems::{ChartId, ParamValue};

/// The fields of a sweep.
pub const SWEEP_FIELDS: &[&str] = &[
    "system",
    "params",
    "chart",
    "charts",
    "initial_coordinates",
    "q0",
    "p0",
    "methods",
    "h",
    "t_end",
    "every",
    "energy_reference",
    "axes",
    "indicators",
    "deviations",
    "qr_every",
    "stop_when",
    "energy_surface",
    "section",
];

/// The fields of an axis.
pub const AXIS_FIELDS: &[&str] = &["name", "min", "max", "n", "scale"];

/// One axis of a sweep.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct AxisRequest {
    /// What it varies: `params.<name>` (a number parameter, e.g. `params.gamma`), `h`, `q0[i]`
    /// or `p0[i]` (a component of the initial state, in the coordinates `initial_coordinates`
    /// names).
    #[schema(example = "params.gamma")]
    pub name: String,
    /// The first value.
    pub min: f64,
    /// The last value.
    pub max: f64,
    /// Points (1 to 401).
    #[schema(minimum = 1, maximum = 401)]
    pub n: u64,
    /// `linear` (default) or `log` (min > 0).
    #[schema(required = false)]
    pub scale: Scale,
}

/// A sweep: one system, one or more methods in one or more charts, over a grid of one or two
/// axes.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({
    "system": "harmonic_oscillator",
    "methods": ["csv1"],
    "t_end": 50,
    "every": 10,
    "axes": [
        {"name": "params.gamma", "min": 0.05, "max": 2, "n": 20},
        {"name": "h", "min": 0.1, "max": 3, "n": 30}
    ]
}))]
pub struct SweepRequest {
    /// The system: a built-in or stored system's id, or a definition of its own.
    pub system: SystemRequest,
    /// Parameters fixed for the whole sweep (an axis overrides its own).
    #[serde(default)]
    #[schema(value_type = Object)]
    pub params: BTreeMap<String, ParamValue>,
    /// Several charts: every method runs in each, from the same physical state.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    #[serde(default)]
    #[schema(value_type = Vec<ChartId>, min_items = 1)]
    pub charts: Vec<String>,
    /// The coordinates of `q0`, `p0` and the initial-state axes: `chart` (the default with one
    /// chart) or `cartesian` (the default with several).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub initial_coordinates: Option<InitialCoordinates>,
    /// Initial positions (default: the system's).
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default: the system's).
    pub p0: Option<Vec<f64>>,
    /// The methods, as in a simulation.
    #[schema(min_items = 1)]
    pub methods: Vec<MethodSpec>,
    /// Step size, unless an axis varies `h`.
    pub h: Option<f64>,
    /// Final time.
    #[schema(exclusive_minimum = 0.0)]
    pub t_end: f64,
    /// Sample every this many steps (default 1: the ℓ² error sums every step, as eq. 50).
    #[schema(minimum = 1)]
    pub every: Option<u64>,
    /// What energy errors are measured against: `exact`, `initial` (H₀) or `reference` (an
    /// adaptive DOP853 run per cell at tolerance 1e-13). Default: the exact solution where the
    /// system has one, else H₀ when nothing is damped, else the reference.
    pub energy_reference: Option<EnergyReference>,
    /// One or two axes; cells are row-major, the first axis running fastest.
    #[schema(min_items = 1, max_items = 2)]
    pub axes: Vec<AxisRequest>,
    /// Chaos indicators each run reports, as in a simulation; their last values are the sweep's
    /// chaos maps (`lyapunov_max`, `megno`, `megno_mean`, `fli`, `sali`, `gali`, and
    /// `stopped_at` where a threshold stopped a cell).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub indicators: Vec<Indicator>,
    /// Deviation vectors, as in a simulation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1)]
    pub deviations: Option<u64>,
    /// Steps between re-orthonormalisations, as in a simulation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1)]
    pub qr_every: Option<u64>,
    /// Thresholds that stop a cell's run, as in a simulation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stop_when: Option<StopWhenRequest>,
    /// Initial states on the energy surface H = E: per cell, one momentum solved from the
    /// energy while the axes vary other components (a Poincaré section).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy_surface: Option<EnergySurfaceRequest>,
    /// A Poincaré section each run collects, as in a simulation: each cell's points (up to
    /// `max_points` per run; all cells' points together count against the sample limit) in the
    /// runs' `sections`, so that a grid of orbits exports as one document.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub section: Option<SectionRequest>,
}

fn axis(v: &Value, at: &Field) -> Result<AxisRequest, ErrorDetail> {
    let o = Obj::new(v, at.clone(), AXIS_FIELDS)?;
    let name = o.required(
        "name",
        "what the axis varies: params.<name>, h, q0[i] or p0[i]",
        string,
    )?;
    let scale = match o.optional("scale", string)?.as_deref() {
        None | Some("linear") => Scale::Linear,
        Some("log") => Scale::Log,
        Some(other) => {
            let field = at.key("scale");
            return Err(ErrorDetail::at(
                ErrorCode::InvalidValue,
                &field,
                format!("{field}: `{other}` is not one of linear, log"),
            ));
        }
    };
    Ok(AxisRequest {
        name,
        min: o.required("min", "the axis's first value", json::number)?,
        max: o.required("max", "the axis's last value", json::number)?,
        // The most points depend on the study (a sweep's 401, a basin map's 1024): the core
        // checks them.
        n: o.required("n", "the number of points", |v, at| {
            count(v, at, "a whole number of points")
        })?,
        scale,
    })
}

fn energy_reference(v: &Value, field: &Field) -> Result<EnergyReference, ErrorDetail> {
    match string(v, field)?.as_str() {
        "exact" => Ok(EnergyReference::Exact),
        "initial" => Ok(EnergyReference::Initial),
        "reference" => Ok(EnergyReference::Reference),
        other => Err(ErrorDetail::at(
            ErrorCode::InvalidValue,
            field,
            format!("{field}: `{other}` is not one of exact, initial, reference"),
        )),
    }
}

impl SweepRequest {
    /// Reads a sweep from JSON text.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::from_value(&json::parse_json(bytes)?)
    }

    /// Reads a sweep from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let obj = Obj::new(value, Field::default(), SWEEP_FIELDS)?;
        let mut charts = obj
            .optional("charts", |v, at| list(v, at, "a list of chart ids", string))?
            .unwrap_or_default();
        if let Some(chart) = obj.optional("chart", string)? {
            if !charts.is_empty() {
                return Err(crate::core::error::CoreError::Either {
                    field: Field::new("chart"),
                    first: "`chart`",
                    second: "`charts`",
                }
                .into());
            }
            charts.push(chart);
        }
        if obj.has("charts") && charts.is_empty() {
            return Err(crate::core::error::CoreError::Empty {
                field: Field::new("charts"),
                what: "chart",
            }
            .into());
        }
        let chaos = chaos::read(&obj)?;
        Ok(SweepRequest {
            system: obj.required(
                "system",
                "the system id, e.g. \"pendulum\", or a system definition",
                read_system,
            )?,
            params: obj.optional("params", json::params)?.unwrap_or_default(),
            charts,
            initial_coordinates: obj.optional("initial_coordinates", initial_coordinates)?,
            q0: obj.optional("q0", numbers)?,
            p0: obj.optional("p0", numbers)?,
            methods: obj.required(
                "methods",
                "the methods, e.g. [\"symplectic_euler\", \"rk4\"]",
                read_methods,
            )?,
            h: obj.optional("h", json::number)?,
            t_end: obj.required("t_end", "the final time", json::number)?,
            every: obj.optional("every", |v, at| count(v, at, "a whole number of steps ≥ 1"))?,
            energy_reference: obj.optional("energy_reference", energy_reference)?,
            axes: obj.required(
                "axes",
                "one or two axes, e.g. [{\"name\": \"h\", \"min\": 0.01, \"max\": 1, \"n\": 20}]",
                |v, at| list(v, at, "a list of axes", axis),
            )?,
            indicators: chaos.indicators,
            deviations: chaos.deviations,
            qr_every: chaos.qr_every,
            stop_when: obj.optional("stop_when", read_thresholds)?,
            energy_surface: obj.optional("energy_surface", chaos::read_surface)?,
            section: obj.optional("section", read_section)?,
        })
    }

    /// The request with a stored system's id replaced by its definition: what identifies the
    /// sweep, whether the definition was named or sent.
    fn inlined(&self, stored: &dyn StoredSystems) -> SweepRequest {
        SweepRequest {
            system: self.system.inlined(stored),
            ..self.clone()
        }
    }

    /// The request as canonical JSON, a stored system inlined (what parts of the sweep carry,
    /// and what NATS workers receive).
    pub fn canonical(&self, stored: &dyn StoredSystems) -> Value {
        serde_json::to_value(self.inlined(stored)).unwrap_or(Value::Null)
    }

    /// The request's identity: the SHA-256 of its canonical JSON (keys in a fixed order, numbers
    /// as they read back, a stored system inlined), in hex. Parts of a sweep carry it.
    pub fn digest(&self, stored: &dyn StoredSystems) -> String {
        let canonical = serde_json::to_vec(&self.inlined(stored)).unwrap_or_default();
        let mut hex = String::with_capacity(64);
        for byte in Sha256::digest(&canonical) {
            let _ = write!(hex, "{byte:02x}");
        }
        hex
    }

    /// The sweep in core terms.
    pub fn to_spec(&self, stored: &dyn StoredSystems) -> Result<SweepSpec, ErrorDetail> {
        let methods = Field::new("methods");
        let charts = Field::new("charts");
        let axes = Field::new("axes");
        Ok(SweepSpec {
            system: self.system.to_ref(&Field::new("system"), stored)?,
            params: self.params.clone(),
            charts: self
                .charts
                .iter()
                .enumerate()
                .map(|(i, c)| (Some(c.clone()), charts.index(i)))
                .collect(),
            initial_coordinates: self.initial_coordinates,
            q0: self.q0.clone(),
            p0: self.p0.clone(),
            methods: self
                .methods
                .iter()
                .enumerate()
                .map(|(i, m)| m.at(&methods.index(i)))
                .collect::<Result<_, _>>()?,
            h: self.h,
            t_end: self.t_end,
            every: self.every,
            energy_reference: self.energy_reference,
            axes: self
                .axes
                .iter()
                .enumerate()
                .map(|(i, a)| {
                    let field = axes.index(i);
                    let target = Target::parse(&a.name).ok_or_else(|| {
                        let at = field.key("name");
                        ErrorDetail::at(
                            ErrorCode::InvalidValue,
                            &at,
                            format!(
                                "{at}: `{}` is not an axis; give params.<name>, h, q0[i] or p0[i]",
                                a.name
                            ),
                        )
                    })?;
                    Ok(Axis {
                        target,
                        min: a.min,
                        max: a.max,
                        n: usize::try_from(a.n).unwrap_or(usize::MAX),
                        scale: a.scale,
                        field,
                    })
                })
                .collect::<Result<_, ErrorDetail>>()?,
            chaos: chaos::chaos_spec(
                &self.indicators,
                self.deviations,
                self.qr_every,
                self.stop_when.as_ref(),
            )?,
            energy_surface: self
                .energy_surface
                .as_ref()
                .map(EnergySurfaceRequest::to_core)
                .transpose()?,
            section: watching(self.section.as_ref(), None, None).section,
            digest: self.digest(stored),
        })
    }
}

/// A ready-made sweep.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct Preset {
    /// Its id.
    pub id: &'static str,
    /// What it shows.
    pub title: &'static str,
    /// The request.
    #[schema(value_type = Object)]
    pub request: Value,
}

/// The sweep that computes the energy-error map `map` (paper 001 Fig. 6): the planar elastic
/// pendulum released at rest from each (x₀, y₀), run in Cartesian and polar coordinates. Its
/// `energy_error_l2` and `diverged_at` equal the map's ε and divergence times bit for bit.
pub fn energy_map_preset(map: &EnergyMapRequest) -> Value {
    let mut params = map.params.clone();
    params
        .entry("g".to_string())
        .or_insert(ParamValue::Number(FIG6_G));
    let axis = |name: &str, range: [f64; 2], n: usize| json!({"name": name, "min": range[0], "max": range[1], "n": n});
    json!({
        "system": "elastic_pendulum_2d",
        "params": params,
        "charts": ["cartesian", "polar"],
        "initial_coordinates": "cartesian",
        "p0": [0.0, 0.0],
        "methods": [map.method],
        "h": map.h,
        "t_end": map.t_max,
        "energy_reference": "initial",
        "axes": [axis("q0[0]", map.x, map.nx), axis("q0[1]", map.y, map.ny)],
    })
}

/// The presets offered to clients.
pub fn presets() -> Vec<Preset> {
    let fig6 = EnergyMapRequest::from_value(&json!({"nx": 21, "ny": 21, "t_max": 2000}))
        .map(|m| energy_map_preset(&m))
        .unwrap_or(Value::Null);
    vec![
        Preset {
            id: "fig6_energy_map",
            title: "Paper 001 Fig. 6: ℓ² energy error of symplectic Euler on the planar elastic \
                    pendulum released at rest, Cartesian against polar coordinates (coarse grid)",
            request: fig6,
        },
        Preset {
            id: "henon_heiles_megno",
            title:
                "Hénon–Heiles at E = 1/8: MEGNO ⟨Y⟩ over the (y, p_y) section at x = 0, p_x ≥ 0 \
                    from the energy (⟨Y⟩ ≈ 2 on tori, growing as λt/2 in the chaotic sea; cells \
                    outside the energy surface are marked)",
            request: json!({
                "system": "henon_heiles",
                "methods": [{"id": "triple_jump", "base": "velocity_verlet"}],
                "q0": [0.0, 0.0],
                "p0": [0.0, 0.0],
                "h": 0.05,
                "t_end": 1000,
                "every": 20000,
                "indicators": ["megno"],
                "energy_surface": {"energy": 0.125, "solve_for": "p0[0]"},
                "axes": [
                    {"name": "q0[1]", "min": -0.45, "max": 0.65, "n": 51},
                    {"name": "p0[1]", "min": -0.5, "max": 0.5, "n": 51}
                ]
            }),
        },
        Preset {
            id: "elastic_pendulum_chaos",
            title: "Paper 001's question asked of chaos: MEGNO ⟨Y⟩ of the planar elastic pendulum \
                    released at rest, symplectic Euler in Cartesian against polar coordinates",
            request: json!({
                "system": "elastic_pendulum_2d",
                "charts": ["cartesian", "polar"],
                "initial_coordinates": "cartesian",
                "p0": [0.0, 0.0],
                "methods": ["symplectic_euler"],
                "h": 0.01,
                "t_end": 100,
                "every": 10000,
                "indicators": ["megno"],
                "axes": [
                    {"name": "q0[0]", "min": -1.5, "max": 1.5, "n": 21},
                    {"name": "q0[1]", "min": -1.5, "max": 1.5, "n": 21}
                ]
            }),
        },
        Preset {
            id: "csv1_stability",
            title: "Paper 003 Ch. 3: where csv1 diverges on the damped oscillator, over γ and h \
                    (compare with the linear stability map)",
            request: json!({
                "system": "harmonic_oscillator",
                "methods": ["csv1"],
                "t_end": 200,
                "every": 100,
                "axes": [
                    {"name": "params.gamma", "min": 0.0, "max": 2.0, "n": 21},
                    {"name": "h", "min": 0.1, "max": 3.0, "n": 30}
                ]
            }),
        },
    ]
}

/// A sweep's `stop_when`: thresholds of its indicators only (a sweep's runs watch no surface).
fn read_thresholds(v: &Value, at: &Field) -> Result<StopWhenRequest, ErrorDetail> {
    let stop = read_stop_when(v, at)?;
    if stop.surface.is_some() {
        return Err(CoreError::Unsupported {
            field: at.key("where"),
            reason: "a sweep's runs stop at indicator thresholds only, not at events",
        }
        .into());
    }
    Ok(stop)
}

//! Basin-map requests — the body of `POST /api/v1/studies/basins`: a sweep's grid, system and
//! methods over initial-state axes, with the exits of an open system and the settings that
//! recognise attractors; read strictly into the core's
//! [`BasinsSpec`](crate::core::studies::basins::BasinsSpec); and the presets that reproduce
//! published pictures.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::Serialize;
use serde_json::{json, Value};
use sha2::{Digest, Sha256};
use utoipa::ToSchema;

use super::chaos::EnergySurfaceRequest;
use super::crossings::direction;
use super::json::{self, count, list, string, Obj};
use super::method::MethodSpec;
use super::simulate::initial_coordinates;
use super::sweep::{AxisRequest, Preset, SweepRequest, SWEEP_FIELDS};
use super::system::{StoredSystems, SystemRequest};
use crate::core::error::{ErrorDetail, Field};
use crate::core::sections::Direction;
use crate::core::simulation::InitialCoordinates;
use crate::core::studies::basins::{BasinsSpec, ExitSpec, GivenAttractor, Recognition};
use crate::core::studies::sweep::Scale;
use crate::core::systems::{ChartId, ParamValue};

/// The sweep's fields a basin map does not take: it samples no energies, tracks no indicators
/// and collects no section.
const NOT_FOR_BASINS: &[&str] = &[
    "every",
    "energy_reference",
    "indicators",
    "deviations",
    "qr_every",
    "stop_when",
    "section",
];
const EXIT_FIELDS: &[&str] = &["name", "where", "direction"];
const RECOGNITION_FIELDS: &[&str] = &[
    "period",
    "max_period",
    "tolerance",
    "escape_radius",
    "angles",
];
const ATTRACTOR_FIELDS: &[&str] = &["name", "points", "radius"];

/// An exit of an open system: a surface S(q, p, t) = 0 in the section language, crossed in
/// `direction`.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({"name": "up", "where": "y - 2", "direction": "up"}))]
pub struct ExitRequest {
    /// Its name (unique), which the map's legend shows.
    pub name: String,
    /// S, an expression in the coordinates, momenta, parameters and t.
    #[serde(rename = "where")]
    pub surface: String,
    /// `up` (S from negative to non-negative), `down` or `both` (default).
    #[schema(required = false, pattern = "^(up|down|both)$")]
    pub direction: String,
}

/// How attractors are recognised.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
pub struct RecognitionRequest {
    /// A driven system's driving period T: its attractors are found on the stroboscopic map
    /// t = kT, and T must be a whole number of steps. Required for a driven system, refused for
    /// one nothing drives.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub period: Option<f64>,
    /// The longest period of the stroboscopic map looked for, in driving periods (1 to 64,
    /// default 8).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1, maximum = 64)]
    pub max_period: Option<u64>,
    /// How close, in every component, stroboscopic points one period apart must be (default
    /// 1e-6).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub tolerance: Option<f64>,
    /// A component beyond this has escaped to infinity (default 1e6).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub escape_radius: Option<f64>,
    /// The coordinates that are angles, by name (a pendulum's `theta`): compared modulo 2π on
    /// the stroboscopic map and against given attractors, reported in (−π, π], and never taken
    /// to have escaped — so a rotating orbit, whose angle gains 2π a period, is a periodic one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angles: Option<Vec<String>>,
}

/// An attractor the request names: an orbit (a driven system's stroboscopic point) that comes
/// within `radius` of one of its points, in every component, ends up there; an equilibrium or
/// periodic orbit found on the fly within `radius` of its points takes its label too.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({"name": "left well", "points": [[-1, 0]], "radius": 0.05}))]
pub struct AttractorRequest {
    /// Its name (unique), which the map's legend shows.
    pub name: String,
    /// Its points (1 to 256), each q then p (without a driven system's clock).
    #[schema(min_items = 1, max_items = 256)]
    pub points: Vec<Vec<f64>>,
    /// How close counts, in every component (angles modulo 2π).
    #[schema(exclusive_minimum = 0.0)]
    pub radius: f64,
}

/// A basin map: which attractor or exit each initial state of a grid ends up at.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({
    "system": "henon_heiles",
    "methods": ["yoshida6"],
    "h": 0.01,
    "t_end": 100,
    "q0": [0, 0], "p0": [0, 0],
    "energy_surface": {"energy": 0.25, "solve_for": "p0[0]"},
    "axes": [
        {"name": "q0[1]", "min": -0.6, "max": 1.0, "n": 100},
        {"name": "p0[1]", "min": -0.6, "max": 0.6, "n": 100}
    ],
    "exits": [
        {"name": "up", "where": "y - 2", "direction": "up"},
        {"name": "left", "where": "-sqrt(3)/2*x - y/2 - 2", "direction": "up"},
        {"name": "right", "where": "sqrt(3)/2*x - y/2 - 2", "direction": "up"}
    ]
}))]
pub struct BasinsRequest {
    /// The system: a built-in or stored system's id, or a definition of its own.
    #[schema(value_type = SystemRequest)]
    pub system: Value,
    /// Parameters.
    #[serde(default)]
    #[schema(value_type = Object)]
    pub params: BTreeMap<String, ParamValue>,
    /// The chart the map runs in (one).
    #[schema(value_type = Option<ChartId>)]
    pub chart: Option<String>,
    /// The coordinates of `q0`, `p0` and the axes: `chart` (default) or `cartesian`.
    pub initial_coordinates: Option<InitialCoordinates>,
    /// Initial positions (default: the system's); the axes vary some of them.
    pub q0: Option<Vec<f64>>,
    /// Initial momenta (default: the system's).
    pub p0: Option<Vec<f64>>,
    /// The methods: one map each, with the same labels for the same outcomes.
    #[schema(min_items = 1)]
    pub methods: Vec<MethodSpec>,
    /// Step size.
    #[schema(exclusive_minimum = 0.0)]
    pub h: f64,
    /// The longest time a cell runs; most stop as soon as their outcome is decided.
    #[schema(exclusive_minimum = 0.0)]
    pub t_end: f64,
    /// One or two axes over `q0[i]` or `p0[i]`; cells are row-major, the first axis fastest.
    #[schema(min_items = 1, max_items = 2, value_type = Vec<MapAxis>)]
    pub axes: Vec<AxisRequest>,
    /// Initial states on the energy surface H = E, one momentum solved per cell.
    pub energy_surface: Option<EnergySurfaceRequest>,
    /// The exits of an open system (up to 16).
    #[serde(default)]
    #[schema(max_items = 16)]
    pub exits: Vec<ExitRequest>,
    /// How attractors are recognised.
    pub recognition: Option<RecognitionRequest>,
    /// Attractors known in advance (up to 64): they take the first labels, in this order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schema(max_items = 64)]
    pub attractors: Vec<AttractorRequest>,
}

/// One axis of a basin map, as the schema shows it: a sweep's axis (read by the sweep's reader)
/// over `q0[i]` or `p0[i]`, with up to
/// [`MAX_MAP_POINTS`](crate::core::studies::basins::MAX_MAP_POINTS) points.
#[derive(ToSchema)]
#[allow(dead_code)]
struct MapAxis {
    /// `q0[i]` or `p0[i]`: a component of the initial state, in the coordinates
    /// `initial_coordinates` names.
    #[schema(example = "q0[0]")]
    name: String,
    /// The first value.
    min: f64,
    /// The last value.
    max: f64,
    /// Points (1 to 1024).
    #[schema(minimum = 1, maximum = 1024)]
    n: u64,
    /// `linear` (default) or `log` (min > 0).
    #[schema(required = false)]
    scale: Scale,
}

/// The fields of a basin map: a sweep's, less [`NOT_FOR_BASINS`] and `charts`, with its own.
fn basins_fields() -> Vec<&'static str> {
    SWEEP_FIELDS
        .iter()
        .copied()
        .filter(|f| !NOT_FOR_BASINS.contains(f) && *f != "charts")
        .chain(["exits", "recognition", "attractors"])
        .collect()
}

fn exit(v: &Value, at: &Field) -> Result<ExitRequest, ErrorDetail> {
    let o = Obj::new(v, at.clone(), EXIT_FIELDS)?;
    Ok(ExitRequest {
        name: o.required("name", "the exit's name, e.g. \"up\"", string)?,
        surface: o.required("where", "the exit surface S, e.g. \"y - 2\"", string)?,
        direction: o
            .optional("direction", direction)?
            .unwrap_or_else(|| "both".into()),
    })
}

fn attractor(v: &Value, at: &Field) -> Result<AttractorRequest, ErrorDetail> {
    let o = Obj::new(v, at.clone(), ATTRACTOR_FIELDS)?;
    let point = |v: &Value, at: &Field| list(v, at, "a point: q then p", json::number);
    Ok(AttractorRequest {
        name: o.required("name", "the attractor's name, e.g. \"left well\"", string)?,
        points: o.required("points", "its points, e.g. [[-1, 0]]", |v, at| {
            list(v, at, "a list of points, each q then p", point)
        })?,
        radius: o.required("radius", "how close counts, e.g. 0.05", json::number)?,
    })
}

fn recognition(v: &Value, at: &Field) -> Result<RecognitionRequest, ErrorDetail> {
    let o = Obj::new(v, at.clone(), RECOGNITION_FIELDS)?;
    Ok(RecognitionRequest {
        period: o.optional("period", json::number)?,
        max_period: o.optional("max_period", |v, at| {
            count(v, at, "a whole number of driving periods from 1 to 64")
        })?,
        tolerance: o.optional("tolerance", json::number)?,
        escape_radius: o.optional("escape_radius", json::number)?,
        // No angles is no `angles`: the same map, the same identity.
        angles: o
            .optional("angles", |v, at| {
                list(v, at, "a list of coordinate names", string)
            })?
            .filter(|angles| !angles.is_empty()),
    })
}

impl BasinsRequest {
    /// Reads a basin map from a JSON value, naming the field at fault in every error.
    pub fn from_value(value: &Value) -> Result<(Self, SweepRequest), ErrorDetail> {
        let obj = Obj::new(value, Field::default(), &basins_fields())?;
        let exits = obj
            .optional("exits", |v, at| list(v, at, "a list of exits", exit))?
            .unwrap_or_default();
        let recognition = obj.optional("recognition", recognition)?;
        let attractors = obj
            .optional("attractors", |v, at| {
                list(v, at, "a list of attractors", attractor)
            })?
            .unwrap_or_default();
        // The rest is a sweep's body, read by the sweep's reader.
        let mut rest = value.clone();
        if let Some(map) = rest.as_object_mut() {
            map.remove("exits");
            map.remove("recognition");
            map.remove("attractors");
        }
        let sweep = SweepRequest::from_value(&rest)?;
        let h = obj.required("h", "the step size", json::number)?;
        let request = BasinsRequest {
            system: obj.get("system").cloned().unwrap_or(Value::Null),
            params: sweep.params.clone(),
            chart: sweep.charts.first().cloned(),
            initial_coordinates: obj.optional("initial_coordinates", initial_coordinates)?,
            q0: sweep.q0.clone(),
            p0: sweep.p0.clone(),
            methods: sweep.methods.clone(),
            h,
            t_end: sweep.t_end,
            axes: sweep.axes.clone(),
            energy_surface: sweep.energy_surface.clone(),
            exits,
            recognition,
            attractors,
        };
        Ok((request, sweep))
    }

    /// The map in core terms; `sweep` is the body as the sweep's reader read it.
    pub fn to_spec(
        &self,
        sweep: &SweepRequest,
        stored: &dyn StoredSystems,
    ) -> Result<BasinsSpec, ErrorDetail> {
        let mut spec = sweep.to_spec(stored)?;
        // The map's identity: the sweep's, with the exits and the recognition settings.
        let own = serde_json::to_vec(&(&self.exits, &self.recognition)).unwrap_or_default();
        let mut hasher = Sha256::new();
        hasher.update(spec.digest.as_bytes());
        hasher.update(&own);
        // Given attractors join the identity only when there are some, so that a map without
        // them keeps the identity it had before they could be given.
        if !self.attractors.is_empty() {
            hasher.update(serde_json::to_vec(&self.attractors).unwrap_or_default());
        }
        let mut hex = String::with_capacity(64);
        for byte in hasher.finalize() {
            let _ = write!(hex, "{byte:02x}");
        }
        spec.digest = hex;
        let exits = Field::new("exits");
        let defaults = Recognition::default();
        let given = self.recognition.clone().unwrap_or_default();
        Ok(BasinsSpec {
            sweep: spec,
            exits: self
                .exits
                .iter()
                .enumerate()
                .map(|(i, e)| ExitSpec {
                    name: e.name.clone(),
                    text: e.surface.clone(),
                    direction: Direction::parse(&e.direction).unwrap_or(Direction::Both),
                    field: exits.index(i),
                })
                .collect(),
            recognition: Recognition {
                period: given.period,
                max_period: given.max_period.map_or(defaults.max_period, |m| {
                    usize::try_from(m).unwrap_or(usize::MAX)
                }),
                tolerance: given.tolerance.unwrap_or(defaults.tolerance),
                escape_radius: given.escape_radius.unwrap_or(defaults.escape_radius),
                angles: given.angles.unwrap_or_default(),
                field: defaults.field,
            },
            attractors: self
                .attractors
                .iter()
                .enumerate()
                .map(|(i, a)| GivenAttractor {
                    name: a.name.clone(),
                    points: a.points.clone(),
                    radius: a.radius,
                    field: Field::new("attractors").index(i),
                })
                .collect(),
        })
    }
}

/// The exits of Hénon–Heiles: two units out along its three channels, beyond the saddles at
/// 90°, 210° and 330° (Aguirre, Vallejo & Sanjuán, Phys. Rev. E 64 (2001) 066208).
fn henon_heiles_exits() -> Value {
    json!([
        {"name": "up", "where": "y - 2", "direction": "up"},
        {"name": "left", "where": "-sqrt(3)/2*x - y/2 - 2", "direction": "up"},
        {"name": "right", "where": "sqrt(3)/2*x - y/2 - 2", "direction": "up"}
    ])
}

/// The (y, p_y) plane of Hénon–Heiles at x = 0, p_x ≥ 0 from the energy E.
fn henon_heiles_plane(energy: f64) -> (Value, Value) {
    (
        json!({"energy": energy, "solve_for": "p0[0]"}),
        json!([
            {"name": "q0[1]", "min": -0.6, "max": 1.0, "n": 101},
            {"name": "p0[1]", "min": -0.6, "max": 0.6, "n": 101}
        ]),
    )
}

/// Ready-made basin maps that reproduce published pictures.
pub fn presets() -> Vec<Preset> {
    let (surface, plane) = henon_heiles_plane(0.25);
    vec![
        Preset {
            id: "double_well",
            title: "The damped double well x″ + δx′ − x + x³ = 0 (δ = 0.25): two interleaved \
                    spiral basins, every cell decided by the energy argument",
            request: json!({
                "system": {"name": "damped double well", "coordinates": ["x"], "mass": 1,
                           "potential": "-x^2/2 + x^4/4", "damping": {"gamma": "delta/2"},
                           "parameters": {"delta": 0.25}},
                "methods": ["csv2"], "h": 0.05, "t_end": 500,
                "axes": [{"name": "q0[0]", "min": -2, "max": 2, "n": 101},
                         {"name": "p0[0]", "min": -2, "max": 2, "n": 101}]
            }),
        },
        Preset {
            id: "forced_duffing",
            title: "The forced damped Duffing oscillator x″ + 0.5x′ − x + x³ = 0.1 cos t: a \
                    period-1 orbit in each well, found on the stroboscopic map",
            request: json!({
                "system": {"name": "forced damped Duffing", "coordinates": ["x"], "mass": 1,
                           "potential": "-x^2/2 + x^4/4 - A*x*cos(omega*t)",
                           "damping": {"gamma": "delta/2"},
                           "parameters": {"delta": 0.5, "A": 0.1, "omega": 1}},
                "methods": ["csv1"], "h": std::f64::consts::TAU / 64.0,
                "t_end": 200.0 * std::f64::consts::TAU,
                "recognition": {"period": std::f64::consts::TAU},
                "axes": [{"name": "q0[0]", "min": -1.8, "max": 1.8, "n": 61},
                         {"name": "p0[0]", "min": -1.0, "max": 1.0, "n": 61}]
            }),
        },
        Preset {
            id: "forced_pendulum",
            title: "The forced damped pendulum θ″ + 0.1θ′ + sin θ = 2 cos t: two rotating \
                    orbits, one each way round, with interleaved basins and a fractal boundary \
                    (the system of Grebogi, Ott & Yorke's fractal basin boundaries, Science 238 \
                    (1987) 632); θ is an angle, so a turn a period is a period-1 orbit",
            request: json!({
                "system": {"name": "forced damped pendulum", "coordinates": ["theta"],
                           "mass": 1, "potential": "-cos(theta) - F*theta*cos(omega*t)",
                           "damping": {"gamma": "nu/2"},
                           "parameters": {"nu": 0.1, "F": 2, "omega": 1}},
                "methods": ["csv1"], "h": std::f64::consts::TAU / 64.0,
                "t_end": 200.0 * std::f64::consts::TAU,
                "recognition": {"period": std::f64::consts::TAU, "angles": ["theta"]},
                "axes": [{"name": "q0[0]", "min": -std::f64::consts::PI,
                          "max": std::f64::consts::PI, "n": 101},
                         {"name": "p0[0]", "min": -4.0, "max": 4.0, "n": 101}]
            }),
        },
        Preset {
            id: "henon_heiles_escapes",
            title: "Hénon–Heiles at E = 0.25, above the escape energy 1/6: which of the three \
                    exits each orbit of the (y, p_y) section leaves through (Wada basins)",
            request: json!({
                "system": "henon_heiles",
                "methods": [{"id": "triple_jump", "base": "velocity_verlet"}],
                "h": 0.01, "t_end": 200, "q0": [0.0, 0.0], "p0": [0.0, 0.0],
                "energy_surface": surface, "axes": plane, "exits": henon_heiles_exits()
            }),
        },
        Preset {
            id: "henon_heiles_escapes_damped",
            title:
                "The same with weak conformal damping (γ = 0.01): some orbits lose their energy \
                    before they find an exit and settle at the origin (Blesa, Seoane, Barrio & \
                    Sanjuán 2012)",
            request: json!({
                "system": {"name": "damped Hénon–Heiles", "coordinates": ["x", "y"], "mass": 1,
                           "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3",
                           "damping": {"gamma": "gamma"}, "parameters": {"gamma": 0.01}},
                "methods": ["csv2"], "h": 0.01, "t_end": 500, "q0": [0.0, 0.0], "p0": [0.0, 0.0],
                "energy_surface": surface, "axes": plane, "exits": henon_heiles_exits()
            }),
        },
    ]
}

//! The allowed-region request: a simulation request with an energy level — the request an orbit
//! launched on a section's plane would send — and the plane to sample (`plane`), read strictly
//! and turned into the core's [`Plane`] and the prepared [`Simulation`] whose initial state the
//! grid points start from.

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::json::{count, missing, number, string, Obj};
use super::simulate::SimulateRequest;
use super::system::StoredSystems;
use crate::core::error::{ErrorDetail, Field};
use crate::core::sections::EnergyLevel;
use crate::core::simulation::{Limits, Plane, PlaneAxis, Simulation};

/// One axis of the plane.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PlaneAxisRequest {
    /// A coordinate or momentum of the system, e.g. `x` or `p_x` (not the solved momentum).
    pub name: String,
    /// The first value (finite).
    pub min: f64,
    /// The last value (finite, > min).
    pub max: f64,
    /// How many evenly spaced values, `min` and `max` included (2 to 200; default 101).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 2, maximum = 200)]
    pub points: Option<u64>,
}

/// The plane: two of the system's coordinates or momenta.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PlaneRequest {
    /// Across.
    pub x: PlaneAxisRequest,
    /// Up.
    pub y: PlaneAxisRequest,
}

/// A simulation request with `energy` (see `POST /api/v1/simulate`), and `plane`: which grid
/// points of the plane can start an orbit at that energy. The simulation's method, step and
/// section are checked as for a run but nothing is integrated.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[schema(example = json!({
    "system": {"name": "Hénon–Heiles", "coordinates": ["x", "y"],
        "potential": "(x^2 + y^2)/2 + x^2*y - y^3/3"},
    "method": "velocity_verlet", "h": 0.08, "t_end": 100,
    "q0": [0, 0], "p0": [0, 0],
    "energy": {"value": 0.125, "momentum": "p_y"},
    "plane": {"x": {"name": "x", "min": -0.6, "max": 0.8, "points": 71},
        "y": {"name": "p_x", "min": -0.5, "max": 0.5, "points": 51}}
}))]
pub struct AllowedRegionRequest {
    /// The simulation an orbit from a point of the plane would run; `energy` is required.
    #[serde(flatten)]
    pub simulation: SimulateRequest,
    /// The plane to sample.
    pub plane: PlaneRequest,
}

/// Default grid points per axis.
pub const DEFAULT_PLANE_POINTS: u64 = 101;

fn read_axis(v: &Value, field: &Field) -> Result<PlaneAxisRequest, ErrorDetail> {
    let o = Obj::new(v, field.clone(), &["name", "min", "max", "points"])?;
    Ok(PlaneAxisRequest {
        name: o.required("name", "a coordinate or momentum, e.g. \"x\"", string)?,
        min: o.required("min", "the first value", number)?,
        max: o.required("max", "the last value", number)?,
        points: o.optional("points", |v, f| {
            count(v, f, "a whole number of grid points")
        })?,
    })
}

fn read_plane(v: &Value, field: &Field) -> Result<PlaneRequest, ErrorDetail> {
    let o = Obj::new(v, field.clone(), &["x", "y"])?;
    Ok(PlaneRequest {
        x: o.required("x", "the axis across: {name, min, max}", read_axis)?,
        y: o.required("y", "the axis up: {name, min, max}", read_axis)?,
    })
}

impl AllowedRegionRequest {
    /// Reads a request from a JSON value: `plane`, and the rest as a simulation request whose
    /// errors name its fields as `POST /api/v1/simulate` does.
    pub fn from_value(value: &Value) -> Result<Self, ErrorDetail> {
        let mut rest = value.clone();
        let plane = match rest.as_object_mut() {
            Some(map) => map.remove("plane"),
            None => None,
        };
        let simulation = SimulateRequest::from_value(&rest)?;
        if simulation.energy.is_none() {
            return Err(missing(
                &Field::new("energy"),
                "the energy level: {\"value\": E, \"momentum\": \"p_y\"}",
            ));
        }
        let plane = match plane.filter(|v| !v.is_null()) {
            Some(v) => read_plane(&v, &Field::new("plane"))?,
            None => {
                return Err(missing(
                    &Field::new("plane"),
                    "the plane: {\"x\": {name, min, max}, \"y\": {name, min, max}}",
                ))
            }
        };
        Ok(AllowedRegionRequest { simulation, plane })
    }

    /// The prepared simulation (without its energy level: the grid points are where it is
    /// solved), the level, and the plane.
    pub fn prepare(
        &self,
        limits: &Limits,
        stored: &dyn StoredSystems,
    ) -> Result<(Simulation, EnergyLevel, Plane), ErrorDetail> {
        let energy = self.simulation.energy.clone().unwrap_or_default();
        let mut request = self.simulation.clone();
        request.energy = None;
        let sim = request.prepare(limits, stored)?;
        let level = EnergyLevel {
            energy: energy.value,
            momentum: energy.momentum,
            field: Field::new("energy"),
        };
        let axis = |a: &PlaneAxisRequest, key: &str| PlaneAxis {
            name: a.name.clone(),
            min: a.min,
            max: a.max,
            points: a.points.unwrap_or(DEFAULT_PLANE_POINTS),
            field: Field::new("plane").key(key),
        };
        let plane = Plane {
            x: axis(&self.plane.x, "x"),
            y: axis(&self.plane.y, "y"),
        };
        Ok((sim, level, plane))
    }
}

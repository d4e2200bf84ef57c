//! The members of a simulation request that watch its runs — `section` (a Poincaré section:
//! a surface and a direction, or a stroboscopic period and phase), `stop_when` (what ends a run
//! early: an event, the n-th crossing of a surface) and `energy` (an initial momentum solved
//! from an energy level) — read strictly and turned into the core's [`Watching`].
//!
//! `stop_when` is one object for every kind of early stop: an event is its members `where`,
//! `direction` and `count`; other kinds (indicator thresholds) are members of their own beside
//! them.

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::json::{count, number, string, Obj};
use crate::core::error::{CoreError, ErrorCode, ErrorDetail, Field};
use crate::core::sections::{Direction, EnergyLevel, EventSpec, SectionSpec, SurfaceSpec};
use crate::core::simulation::Watching;

/// The most points a section collects per run when `max_points` is not given.
pub const DEFAULT_MAX_POINTS: u64 = 10_000;

/// A Poincaré section of each run: `where` (an expression S in the coordinates, momenta,
/// parameters and the time `t`) with `direction`, or a stroboscopic section `period` with
/// `phase`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"where": "y", "direction": "up", "max_points": 10000}))]
pub struct SectionRequest {
    /// The surface S = 0, e.g. `y` or `x^2 + y^2 - 1`; the names are the system's coordinates,
    /// its momenta (`p_<coordinate>` unless the definition names them), its parameters and `t`.
    #[serde(rename = "where", default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<String>,
    /// Which crossings count: `up` (S from negative to non-negative; default), `down`, `both`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Direction>)]
    pub direction: Option<String>,
    /// A stroboscopic section instead: the state at the times t ≡ `phase` (mod `period`) in
    /// (0, t_end] (> 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(exclusive_minimum = 0.0)]
    pub period: Option<f64>,
    /// The stroboscopic phase, a time (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase: Option<f64>,
    /// Most points per run (1 to 10⁶; default 10⁴); later crossings are not collected.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1, maximum = 1000000)]
    pub max_points: Option<u64>,
}

/// What ends each run before `t_end`: the `count`-th crossing of the surface `where` in
/// `direction` (an event; the run's `stop` is then `event`, at the crossing's time).
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"where": "y", "direction": "up", "count": 3}))]
pub struct StopWhenRequest {
    /// The event's surface S = 0, named as a section's.
    #[serde(rename = "where")]
    pub surface: String,
    /// Which crossings count: `up`, `down`, `both` (default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Direction>)]
    pub direction: Option<String>,
    /// The crossing that ends the run (1 to 10⁶; default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1, maximum = 1000000)]
    pub count: Option<u64>,
}

/// An energy level for the initial state: `momentum` (one of the system's momenta) is replaced
/// by the non-negative value for which H(q0, p0) = `value`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"value": 0.125, "momentum": "p_y"}))]
pub struct EnergyRequest {
    /// The energy E.
    pub value: f64,
    /// The momentum solved for.
    pub momentum: String,
}

const SECTION_FIELDS: &[&str] = &["where", "direction", "period", "phase", "max_points"];
/// The members of `stop_when`.
pub const STOP_FIELDS: &[&str] = &["where", "direction", "count"];
const ENERGY_FIELDS: &[&str] = &["value", "momentum"];

/// `up`, `down` or `both`.
fn direction(v: &Value, field: &Field) -> Result<String, ErrorDetail> {
    let name = string(v, field)?;
    match Direction::parse(&name) {
        Some(_) => Ok(name),
        None => Err(ErrorDetail::at(
            ErrorCode::InvalidValue,
            field,
            format!("{field}: `{name}` is not one of up, down, both"),
        )),
    }
}

/// Reads `section`.
pub fn read_section(v: &Value, field: &Field) -> Result<SectionRequest, ErrorDetail> {
    let o = Obj::new(v, field.clone(), SECTION_FIELDS)?;
    let section = SectionRequest {
        surface: o.optional("where", string)?,
        direction: o.optional("direction", direction)?,
        period: o.optional("period", number)?,
        phase: o.optional("phase", number)?,
        max_points: o.optional("max_points", |v, at| count(v, at, "a whole number ≥ 1"))?,
    };
    let either = |first, second| {
        ErrorDetail::from(CoreError::Either {
            field: field.clone(),
            first,
            second,
        })
    };
    match (&section.surface, section.period) {
        (Some(_), Some(_)) => Err(either("`where`", "`period`")),
        (None, None) => Err(super::json::missing(
            &o.field("where"),
            "the surface, e.g. \"y\" (or a stroboscopic `period`)",
        )),
        (Some(_), None) if section.phase.is_some() => Err(either("`where`", "`phase`")),
        (None, Some(_)) if section.direction.is_some() => Err(either("`period`", "`direction`")),
        _ => Ok(section),
    }
}

/// Reads `stop_when`.
pub fn read_stop_when(v: &Value, field: &Field) -> Result<StopWhenRequest, ErrorDetail> {
    let o = Obj::new(v, field.clone(), STOP_FIELDS)?;
    Ok(StopWhenRequest {
        surface: o.required(
            "where",
            "the surface whose crossing ends the run, e.g. \"y\"",
            string,
        )?,
        direction: o.optional("direction", direction)?,
        count: o.optional("count", |v, at| count(v, at, "a whole number ≥ 1"))?,
    })
}

/// Reads `energy`.
pub fn read_energy(v: &Value, field: &Field) -> Result<EnergyRequest, ErrorDetail> {
    let o = Obj::new(v, field.clone(), ENERGY_FIELDS)?;
    Ok(EnergyRequest {
        value: o.required("value", "the energy E", number)?,
        momentum: o.required("momentum", "the momentum to solve for, e.g. \"p_y\"", string)?,
    })
}

/// The core's [`Watching`] of the three members.
pub fn watching(
    section: Option<&SectionRequest>,
    stop_when: Option<&StopWhenRequest>,
    energy: Option<&EnergyRequest>,
) -> Watching {
    let parse = |d: &Option<String>, default| {
        d.as_deref()
            .and_then(Direction::parse)
            .unwrap_or(default)
    };
    Watching {
        section: section.map(|s| SectionSpec {
            surface: match (&s.surface, s.period) {
                (Some(text), _) => SurfaceSpec::Where {
                    text: text.clone(),
                    direction: parse(&s.direction, Direction::Up),
                },
                (None, period) => SurfaceSpec::Stroboscopic {
                    period: period.unwrap_or(f64::NAN),
                    phase: s.phase.unwrap_or(0.0),
                },
            },
            max_points: s.max_points.unwrap_or(DEFAULT_MAX_POINTS),
            field: Field::new("section"),
        }),
        stop_when: stop_when.map(|s| EventSpec {
            text: s.surface.clone(),
            direction: parse(&s.direction, Direction::Both),
            count: s.count.unwrap_or(1),
            field: Field::new("stop_when"),
        }),
        energy: energy.map(|e| EnergyLevel {
            energy: e.value,
            momentum: e.momentum.clone(),
            field: Field::new("energy"),
        }),
    }
}

//! The members of a simulation request that watch its runs — `section` (a Poincaré section:
//! a surface and a direction, or a stroboscopic period and phase), `stop_when` (what ends a run
//! early: an event, the n-th crossing of a surface) and `energy` (an initial momentum solved
//! from an energy level) — read strictly and turned into the core's [`Watching`].
//!
//! `stop_when` is one object for every kind of early stop: an event is its members `where`,
//! `direction` and `count`; the chaos indicators' thresholds are members of their own beside
//! them (and go to the core's [`ChaosSpec`](crate::core::chaos::ChaosSpec)).

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::json::{count, number, string, Obj};
use crate::core::chaos::Statistic;
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

/// What ends each run before `t_end`: an event, the `count`-th crossing of the surface `where`
/// in `direction` (the run's `stop` is then `event`, at the crossing's time), or a chaos
/// indicator reaching its threshold (`stop` is then `indicator`; the indicator must be among the
/// request's `indicators`). Give a surface, thresholds, or both: whichever comes first ends the
/// run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({"where": "y", "direction": "up", "count": 3}))]
pub struct StopWhenRequest {
    /// The event's surface S = 0, named as a section's.
    #[serde(rename = "where", default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<String>,
    /// Which crossings count: `up`, `down`, `both` (default); with `where` only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Direction>)]
    pub direction: Option<String>,
    /// The crossing that ends the run (1 to 10⁶; default 1); with `where` only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1, maximum = 1000000)]
    pub count: Option<u64>,
    /// The largest finite-time Lyapunov exponent reaching this value from below.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lyapunov_max: Option<f64>,
    /// MEGNO Y(t) reaching this value from below.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub megno: Option<f64>,
    /// MEGNO's running mean ⟨Y⟩(t) reaching this value from below.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(example = 8.0)]
    pub megno_mean: Option<f64>,
    /// The fast Lyapunov indicator reaching this value from below.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fli: Option<f64>,
    /// SALI falling to this value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sali: Option<f64>,
    /// GALI_k falling to this value.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gali: Option<f64>,
}

impl StopWhenRequest {
    fn threshold(&mut self, statistic: Statistic) -> &mut Option<f64> {
        match statistic {
            Statistic::LyapunovMax => &mut self.lyapunov_max,
            Statistic::Megno => &mut self.megno,
            Statistic::MegnoMean => &mut self.megno_mean,
            Statistic::Fli => &mut self.fli,
            Statistic::Sali => &mut self.sali,
            Statistic::Gali => &mut self.gali,
        }
    }

    /// The indicator thresholds given, in [`Statistic::ALL`]'s order.
    pub fn thresholds(&self) -> Vec<(Statistic, f64)> {
        let mut copy = self.clone();
        Statistic::ALL
            .into_iter()
            .filter_map(|s| copy.threshold(s).map(|v| (s, v)))
            .collect()
    }
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
/// The members of `stop_when`: an event's, then the indicator thresholds (named as the
/// statistics, [`Statistic::as_str`]).
pub const STOP_FIELDS: &[&str] = &[
    "where",
    "direction",
    "count",
    "lyapunov_max",
    "megno",
    "megno_mean",
    "fli",
    "sali",
    "gali",
];
const ENERGY_FIELDS: &[&str] = &["value", "momentum"];

/// `up`, `down` or `both`.
pub(crate) fn direction(v: &Value, field: &Field) -> Result<String, ErrorDetail> {
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

/// Reads `stop_when`: a surface (`where`, with `direction` and `count`), thresholds, or both.
pub fn read_stop_when(v: &Value, field: &Field) -> Result<StopWhenRequest, ErrorDetail> {
    let o = Obj::new(v, field.clone(), STOP_FIELDS)?;
    let mut stop = StopWhenRequest {
        surface: o.optional("where", string)?,
        direction: o.optional("direction", direction)?,
        count: o.optional("count", |v, at| count(v, at, "a whole number ≥ 1"))?,
        ..StopWhenRequest::default()
    };
    for statistic in Statistic::ALL {
        *stop.threshold(statistic) = o.optional(statistic.as_str(), number)?;
    }
    if stop.surface.is_none() {
        let why = if stop.direction.is_some() || stop.count.is_some() {
            "the surface that `direction` and `count` are of, e.g. \"y\""
        } else if stop.thresholds().is_empty() {
            "the surface whose crossing ends the run, e.g. \"y\", or an indicator's threshold \
             such as `megno_mean`"
        } else {
            return Ok(stop);
        };
        return Err(super::json::missing(&o.field("where"), why));
    }
    Ok(stop)
}

/// Reads `energy`.
pub fn read_energy(v: &Value, field: &Field) -> Result<EnergyRequest, ErrorDetail> {
    let o = Obj::new(v, field.clone(), ENERGY_FIELDS)?;
    Ok(EnergyRequest {
        value: o.required("value", "the energy E", number)?,
        momentum: o.required(
            "momentum",
            "the momentum to solve for, e.g. \"p_y\"",
            string,
        )?,
    })
}

/// The core's [`Watching`] of the three members.
pub fn watching(
    section: Option<&SectionRequest>,
    stop_when: Option<&StopWhenRequest>,
    energy: Option<&EnergyRequest>,
) -> Watching {
    let parse =
        |d: &Option<String>, default| d.as_deref().and_then(Direction::parse).unwrap_or(default);
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
        stop_when: stop_when.and_then(|s| {
            Some(EventSpec {
                text: s.surface.clone()?,
                direction: parse(&s.direction, Direction::Both),
                count: s.count.unwrap_or(1),
                field: Field::new("stop_when"),
            })
        }),
        energy: energy.map(|e| EnergyLevel {
            energy: e.value,
            momentum: e.momentum.clone(),
            field: Field::new("energy"),
        }),
    }
}

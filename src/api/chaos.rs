//! The chaos indicators as requests write them — `indicators`, `deviations`, `qr_every` and
//! `stop_when` in a simulation or a sweep, and a sweep's `energy_surface` — read field by field
//! into the core's [`ChaosSpec`] and [`EnergySurface`].

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::json::{count, list, number, string, Obj};
use crate::core::chaos::{ChaosFields, ChaosSpec, Indicator, Statistic};
use crate::core::error::{CoreError, ErrorCode, ErrorDetail, Field};
use crate::core::simulation::EnergySurface;
use crate::core::studies::sweep::Target;

/// The indicators' fields of a request, as the readers accept them.
pub const CHAOS_FIELDS: &[&str] = &["indicators", "deviations", "qr_every", "stop_when"];

/// Thresholds that stop a run (`stop_when`): a growing statistic stops it when it reaches its
/// threshold from below, SALI and GALI when they fall to theirs. Each needs its indicator in
/// `indicators` (`lyapunov_max` needs `lyapunov`, `megno` and `megno_mean` need `megno`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Thresholds {
    /// The largest finite-time Lyapunov exponent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lyapunov_max: Option<f64>,
    /// MEGNO Y(t).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub megno: Option<f64>,
    /// MEGNO's running mean ⟨Y⟩(t).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(example = 8.0)]
    pub megno_mean: Option<f64>,
    /// The fast Lyapunov indicator.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fli: Option<f64>,
    /// SALI (stops when it falls to the threshold).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sali: Option<f64>,
    /// GALI_k (stops when it falls to the threshold).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gali: Option<f64>,
}

impl Thresholds {
    fn slot(&mut self, statistic: Statistic) -> &mut Option<f64> {
        match statistic {
            Statistic::LyapunovMax => &mut self.lyapunov_max,
            Statistic::Megno => &mut self.megno,
            Statistic::MegnoMean => &mut self.megno_mean,
            Statistic::Fli => &mut self.fli,
            Statistic::Sali => &mut self.sali,
            Statistic::Gali => &mut self.gali,
        }
    }

    /// The thresholds given, in [`Statistic::ALL`]'s order.
    pub fn entries(&self) -> Vec<(Statistic, f64)> {
        let mut copy = self.clone();
        Statistic::ALL
            .into_iter()
            .filter_map(|s| copy.slot(s).map(|v| (s, v)))
            .collect()
    }
}

/// `indicators`: a list of indicator names.
pub fn read_indicators(v: &Value, at: &Field) -> Result<Vec<Indicator>, ErrorDetail> {
    list(v, at, "a list of indicators", |v, at| {
        let name = string(v, at)?;
        Indicator::parse(&name).ok_or_else(|| {
            CoreError::UnknownName {
                field: at.clone(),
                what: "indicator".into(),
                value: name,
                known: Indicator::ALL.iter().map(|i| i.as_str().to_string()).collect(),
            }
            .into()
        })
    })
}

/// `stop_when`: an object of thresholds.
pub fn read_thresholds(v: &Value, at: &Field) -> Result<Thresholds, ErrorDetail> {
    let names: Vec<&str> = Statistic::ALL.iter().map(|s| s.as_str()).collect();
    let o = Obj::new(v, at.clone(), &names)?;
    let mut thresholds = Thresholds::default();
    for statistic in Statistic::ALL {
        *thresholds.slot(statistic) = o.optional(statistic.as_str(), number)?;
    }
    Ok(thresholds)
}

/// The indicators' four fields of a request object.
pub struct ChaosFieldsRead {
    /// `indicators` (empty: none asked for).
    pub indicators: Vec<Indicator>,
    /// `deviations`.
    pub deviations: Option<u64>,
    /// `qr_every`.
    pub qr_every: Option<u64>,
    /// `stop_when`.
    pub stop_when: Option<Thresholds>,
}

/// Reads the indicators' fields of `obj`.
pub fn read(obj: &Obj<'_>) -> Result<ChaosFieldsRead, ErrorDetail> {
    Ok(ChaosFieldsRead {
        indicators: obj
            .optional("indicators", read_indicators)?
            .unwrap_or_default(),
        deviations: obj.optional("deviations", |v, at| {
            count(v, at, "a whole number of deviation vectors")
        })?,
        qr_every: obj.optional("qr_every", |v, at| count(v, at, "a whole number of steps ≥ 1"))?,
        stop_when: obj.optional("stop_when", read_thresholds)?,
    })
}

/// The core's spec of the indicators, or `None` when none are asked for; the options without
/// `indicators` are an error naming them.
pub fn chaos_spec(
    indicators: &[Indicator],
    deviations: Option<u64>,
    qr_every: Option<u64>,
    stop_when: Option<&Thresholds>,
) -> Result<Option<ChaosSpec>, CoreError> {
    if indicators.is_empty() {
        let stray = [
            (deviations.is_some(), "deviations"),
            (qr_every.is_some(), "qr_every"),
            (stop_when.is_some(), "stop_when"),
        ];
        if let Some((_, name)) = stray.iter().find(|(given, _)| *given) {
            return Err(CoreError::Unsupported {
                field: Field::new(*name),
                reason: "it applies to chaos indicators: give `indicators` too",
            });
        }
        return Ok(None);
    }
    Ok(Some(ChaosSpec {
        indicators: indicators.to_vec(),
        deviations: deviations.map(|k| usize::try_from(k).unwrap_or(usize::MAX)),
        qr_every,
        stop_when: stop_when.map(Thresholds::entries).unwrap_or_default(),
        fields: ChaosFields::default(),
    }))
}

/// A sweep's initial states on an energy surface.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EnergySurfaceRequest {
    /// The energy E.
    #[schema(example = 0.125)]
    pub energy: f64,
    /// The initial momentum solved from H = E, `p0[i]` (the larger root; for a diagonal mass
    /// the non-negative one). The state must be given where H = ½pᵀM⁻¹p + V(q); an axis may not
    /// vary it. Cells where the rest of the state alone has more energy are marked as such.
    #[schema(example = "p0[0]")]
    pub solve_for: String,
}

/// `energy_surface`.
pub fn read_surface(v: &Value, at: &Field) -> Result<EnergySurfaceRequest, ErrorDetail> {
    let o = Obj::new(v, at.clone(), &["energy", "solve_for"])?;
    Ok(EnergySurfaceRequest {
        energy: o.required("energy", "the energy E of the surface", number)?,
        solve_for: o.required("solve_for", "the momentum solved from H = E, e.g. \"p0[0]\"", string)?,
    })
}

impl EnergySurfaceRequest {
    /// The surface in core terms.
    pub fn to_core(&self) -> Result<EnergySurface, ErrorDetail> {
        let field = Field::new("energy_surface");
        match Target::parse(&self.solve_for) {
            Some(Target::P0(momentum)) => Ok(EnergySurface {
                energy: self.energy,
                momentum,
                field,
            }),
            _ => {
                let at = field.key("solve_for");
                Err(ErrorDetail::at(
                    ErrorCode::InvalidValue,
                    &at,
                    format!("{at}: `{}` is not an initial momentum p0[i]", self.solve_for),
                ))
            }
        }
    }
}

//! The chaos indicators as requests write them — `indicators`, `deviations` and `qr_every` in a
//! simulation or a sweep, with the thresholds of `stop_when` ([`StopWhenRequest`]), and a
//! sweep's `energy_surface` — read field by field into the core's [`ChaosSpec`] and
//! [`EnergySurface`].

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::crossings::StopWhenRequest;
use super::json::{count, list, number, string, Obj};
use crate::core::chaos::{ChaosFields, ChaosSpec, Indicator};
use crate::core::error::{CoreError, ErrorCode, ErrorDetail, Field};
use crate::core::simulation::EnergySurface;
use crate::core::studies::sweep::Target;

/// The indicators' fields of a request, as the readers accept them.
pub const CHAOS_FIELDS: &[&str] = &["indicators", "deviations", "qr_every"];

/// `indicators`: a list of indicator names.
pub fn read_indicators(v: &Value, at: &Field) -> Result<Vec<Indicator>, ErrorDetail> {
    list(v, at, "a list of indicators", |v, at| {
        let name = string(v, at)?;
        Indicator::parse(&name).ok_or_else(|| {
            CoreError::UnknownName {
                field: at.clone(),
                what: "indicator".into(),
                value: name,
                known: Indicator::ALL
                    .iter()
                    .map(|i| i.as_str().to_string())
                    .collect(),
            }
            .into()
        })
    })
}

/// The indicators' fields of a request object (their thresholds are in `stop_when`).
pub struct ChaosFieldsRead {
    /// `indicators` (empty: none asked for).
    pub indicators: Vec<Indicator>,
    /// `deviations`.
    pub deviations: Option<u64>,
    /// `qr_every`.
    pub qr_every: Option<u64>,
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
        qr_every: obj.optional("qr_every", |v, at| {
            count(v, at, "a whole number of steps ≥ 1")
        })?,
    })
}

/// The core's spec of the indicators, or `None` when none are asked for; the options without
/// `indicators` are an error naming them.
pub fn chaos_spec(
    indicators: &[Indicator],
    deviations: Option<u64>,
    qr_every: Option<u64>,
    stop_when: Option<&StopWhenRequest>,
) -> Result<Option<ChaosSpec>, CoreError> {
    let thresholds = stop_when
        .map(StopWhenRequest::thresholds)
        .unwrap_or_default();
    if indicators.is_empty() {
        let threshold = thresholds
            .first()
            .map(|(s, _)| Field::new("stop_when").key(s.as_str()));
        let stray = [
            deviations.is_some().then(|| Field::new("deviations")),
            qr_every.is_some().then(|| Field::new("qr_every")),
            threshold,
        ];
        if let Some(field) = stray.into_iter().flatten().next() {
            return Err(CoreError::Unsupported {
                field,
                reason: "it applies to chaos indicators: give `indicators` too",
            });
        }
        return Ok(None);
    }
    Ok(Some(ChaosSpec {
        indicators: indicators.to_vec(),
        deviations: deviations.map(|k| usize::try_from(k).unwrap_or(usize::MAX)),
        qr_every,
        stop_when: thresholds,
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
        solve_for: o.required(
            "solve_for",
            "the momentum solved from H = E, e.g. \"p0[0]\"",
            string,
        )?,
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
                    format!(
                        "{at}: `{}` is not an initial momentum p0[i]",
                        self.solve_for
                    ),
                ))
            }
        }
    }
}

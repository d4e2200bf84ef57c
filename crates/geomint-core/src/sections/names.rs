//! The names a section's expression may use: the coordinates and momenta of the run's chart,
//! the system's parameters (with the run's values) and the time `t`.
//!
//! A typed-in system's names are its definition's (`coordinates`, `momenta`, default
//! `p_<coordinate>`; `t` is the time unless the definition declares a name `t` itself). A
//! built-in system's coordinates are its chart's (`q`; `x`, `y`, `z`; `r`, `θ`; `ρ`, `φ`, `z`;
//! `y`, `ȳ`), its momenta `p_<coordinate>`, and N bodies' coordinates `x1, y1, z1, x2, …`.

use crate::systems::SystemInfo;
use crate::systems::{ChartInfo, ParamValues};

/// The names of a run's state and parameters, as expressions may use them.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct StateNames {
    /// The coordinates, in state order.
    pub coordinates: Vec<String>,
    /// The momenta, in state order.
    pub momenta: Vec<String>,
    /// The parameters with the run's values (the numbers among them).
    #[serde(skip)]
    pub params: Vec<(String, f64)>,
    /// The name of the time, unless a coordinate, momentum or parameter takes `t`.
    #[serde(skip)]
    pub time: Option<String>,
}

impl StateNames {
    /// The names of a run of `info` in `chart` with `dof` degrees of freedom and parameters
    /// `params`.
    pub fn of(info: &SystemInfo, chart: &ChartInfo, params: &ParamValues, dof: usize) -> Self {
        let (coordinates, momenta, params): (Vec<String>, Vec<String>, Vec<(String, f64)>) =
            match info.custom_model() {
                Some(model) => {
                    let def = model.definition();
                    let momenta = def.momenta.clone().unwrap_or_else(|| {
                        def.coordinates.iter().map(|c| format!("p_{c}")).collect()
                    });
                    let params = def
                        .parameters
                        .iter()
                        .map(|(name, default)| (name.clone(), params.get(name).unwrap_or(*default)))
                        .collect();
                    (def.coordinates.clone(), momenta, params)
                }
                None => {
                    let coordinates = if chart.coordinates.len() == dof
                        && chart.coordinates.iter().all(|c| *c != "…")
                    {
                        chart.coordinates.iter().map(|c| c.to_string()).collect()
                    } else {
                        // N bodies: x1, y1, z1, x2, …
                        (0..dof)
                            .map(|i| format!("{}{}", ["x", "y", "z"][i % 3], i / 3 + 1))
                            .collect::<Vec<_>>()
                    };
                    let momenta = coordinates.iter().map(|c| format!("p_{c}")).collect();
                    let params = params
                        .iter()
                        .filter_map(|(name, _)| params.get(name).map(|v| (name.to_string(), v)))
                        .collect();
                    (coordinates, momenta, params)
                }
            };
        let taken = |name: &str| {
            coordinates.iter().chain(&momenta).any(|c| c == name)
                || params.iter().any(|(p, _)| p == name)
        };
        let time = (!taken("t")).then(|| "t".to_string());
        StateNames {
            coordinates,
            momenta,
            params,
            time,
        }
    }

    /// Every name an expression may use, for messages.
    pub fn all(&self) -> Vec<String> {
        self.coordinates
            .iter()
            .chain(&self.momenta)
            .cloned()
            .chain(self.params.iter().map(|(name, _)| name.clone()))
            .chain(self.time.clone())
            .collect()
    }

    /// The index of the coordinate or momentum named `name`: `(false, i)` for q_i, `(true, i)`
    /// for p_i.
    pub fn find(&self, name: &str) -> Option<(bool, usize)> {
        if let Some(i) = self.coordinates.iter().position(|c| c == name) {
            return Some((false, i));
        }
        self.momenta
            .iter()
            .position(|c| c == name)
            .map(|i| (true, i))
    }
}

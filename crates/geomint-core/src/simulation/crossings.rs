//! A simulation's Poincaré section, event and energy level ([`crate::sections`]): attached to a
//! prepared [`Simulation`] ([`Simulation::watching`]), announced in the stream's header
//! ([`SurfaceInfo`]), sent as `crossings` chunks of located points ([`CrossingColumns`]) and
//! kept in the document beside each run's samples.

use std::sync::Arc;

use serde::Serialize;

use super::spec::Simulation;
use crate::error::{CoreError, Field};
use crate::sections::names::StateNames;
use crate::sections::{
    energy, Crossing, Crossings, Direction, EnergyLevel, EventSpec, SectionSpec, SurfaceSpec,
};
use crate::system::{MechanicalSystem, State};
use crate::with_system;

/// Located points: one entry per point in every column.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CrossingColumns {
    /// The crossing times.
    pub t: Vec<f64>,
    /// Positions at each crossing.
    pub q: Vec<Vec<f64>>,
    /// Momenta at each crossing.
    pub p: Vec<Vec<f64>>,
    /// H at each crossing.
    pub energy: Vec<f64>,
    /// Cartesian positions at each crossing, when the chart is not Cartesian.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cartesian_q: Option<Vec<Vec<f64>>>,
}

impl CrossingColumns {
    /// Appends a located point.
    pub fn push(&mut self, c: &Crossing<'_>) {
        self.t.push(c.t);
        self.q.push(c.q.to_vec());
        self.p.push(c.p.to_vec());
        self.energy.push(c.energy);
        if let Some(x) = c.cartesian_q {
            self.cartesian_q
                .get_or_insert_with(Vec::new)
                .push(x.to_vec());
        }
    }

    /// Appends the points of `more` after these.
    pub fn extend(&mut self, more: CrossingColumns) {
        self.t.extend(more.t);
        self.q.extend(more.q);
        self.p.extend(more.p);
        self.energy.extend(more.energy);
        if let Some(more) = more.cartesian_q {
            self.cartesian_q.get_or_insert_with(Vec::new).extend(more);
        }
    }

    /// Points held.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether no point is held.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
}

/// Which surface a `crossings` chunk is of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum SurfaceName {
    /// The section's (`section`).
    Section,
    /// The event's (`stop_when`).
    StopWhen,
}

/// A chunk of one run's located crossings.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CrossingsChunk {
    /// Index of the method in the header's `methods`.
    pub method: usize,
    /// Whose crossings.
    pub surface: SurfaceName,
    /// Index of this chunk's first point within the run's points of this surface.
    pub offset: u64,
    /// The points.
    #[serde(flatten)]
    pub columns: CrossingColumns,
}

/// A surface as the header announces it.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SurfaceInfo {
    /// The expression S (absent for a stroboscopic section).
    #[serde(rename = "where", skip_serializing_if = "Option::is_none")]
    pub expression: Option<String>,
    /// Which crossings count (absent for a stroboscopic section).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direction: Option<Direction>,
    /// The stroboscopic period T.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub period: Option<f64>,
    /// The stroboscopic phase φ: points at the times t ≡ φ (mod T) in (0, t_end].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase: Option<f64>,
    /// Most points per run (sections), or the crossing that ends the run (events).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_points: Option<u64>,
    /// The crossing that ends the run (events).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub count: Option<u64>,
    /// The names of the points' positions.
    pub coordinates: Vec<String>,
    /// The names of the points' momenta.
    pub momenta: Vec<String>,
}

/// What a simulation watches, as asked for: its section, its event, its energy level.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Watching {
    /// The section.
    pub section: Option<SectionSpec>,
    /// The event that ends each run.
    pub stop_when: Option<EventSpec>,
    /// The energy level the initial state is put on.
    pub energy: Option<EnergyLevel>,
}

impl Simulation {
    /// This simulation with `watching` attached: the initial momentum solved from the energy,
    /// then the surfaces compiled against the run's names. Errors name the fields.
    pub fn watching(mut self, watching: &Watching) -> Result<Simulation, CoreError> {
        let names = StateNames::of(&self.info, &self.chart, &self.params, self.q0.len());
        if let Some(level) = &watching.energy {
            let at = level.field.key("momentum");
            let index = match names.find(&level.momentum) {
                Some((true, i)) => i,
                _ => {
                    return Err(CoreError::UnknownName {
                        field: at,
                        what: "momentum".into(),
                        value: level.momentum.clone(),
                        known: names.momenta.clone(),
                    })
                }
            };
            let q0 = self.q0.clone();
            let h = |p: &[f64]| {
                with_system!(&self.system, s => {
                    let z = State::at_time(s, 0.0, &q0, p);
                    s.energy(&z.q, &z.p)
                })
            };
            self.p0[index] = energy::solve(&h, &self.p0, index, level.energy, &level.field)?;
        }
        if watching.section.is_some() || watching.stop_when.is_some() {
            let crossings = Crossings::new(
                watching.section.as_ref(),
                watching.stop_when.as_ref(),
                names,
            )?;
            self.crossings = Some(Arc::new(crossings));
        }
        Ok(self)
    }

    /// The section as the header announces it.
    pub fn section_info(&self) -> Option<SurfaceInfo> {
        let crossings = self.crossings.as_ref()?;
        let (surface, direction, max_points) = crossings.section.as_ref()?;
        Some(surface_info(
            crossings,
            surface,
            *direction,
            Some(*max_points),
            None,
        ))
    }

    /// The event as the header announces it.
    pub fn event_info(&self) -> Option<SurfaceInfo> {
        let crossings = self.crossings.as_ref()?;
        let (surface, direction, count) = crossings.event.as_ref()?;
        Some(surface_info(
            crossings,
            surface,
            *direction,
            None,
            Some(*count),
        ))
    }
}

fn surface_info(
    crossings: &Crossings,
    surface: &crate::sections::Surface,
    direction: Direction,
    max_points: Option<u64>,
    count: Option<u64>,
) -> SurfaceInfo {
    use crate::sections::Surface;
    let (expression, direction, period, phase) = match surface {
        Surface::Expression { text, .. } => (Some(text.clone()), Some(direction), None, None),
        Surface::Clock { period, phase } => (None, None, Some(*period), Some(*phase)),
    };
    SurfaceInfo {
        expression,
        direction,
        period,
        phase,
        max_points,
        count,
        coordinates: crossings.names.coordinates.clone(),
        momenta: crossings.names.momenta.clone(),
    }
}

/// The section spec of a stroboscopic or expression surface, for callers building one.
pub fn section(surface: SurfaceSpec, max_points: u64) -> SectionSpec {
    SectionSpec {
        surface,
        max_points,
        field: Field::new("section"),
    }
}

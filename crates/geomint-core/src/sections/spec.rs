//! What a run is asked to watch: a section (a surface and a direction, or a stroboscopic
//! period and phase) with its most points, and the events that end a run (`stop_when`),
//! checked against their limits before any work starts.

use crate::error::{CoreError, Field, Range};

/// Most points of one run's section.
pub const MAX_SECTION_POINTS: u64 = 1_000_000;
/// The highest crossing count an event may wait for.
pub const MAX_EVENT_COUNT: u64 = 1_000_000;

/// Which crossings of S = 0 count.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
#[cfg_attr(feature = "openapi", schema(as = CrossingDirection))]
pub enum Direction {
    /// S goes from negative to zero or positive.
    Up,
    /// S goes from positive to zero or negative.
    Down,
    /// Either.
    Both,
}

impl Direction {
    /// The direction named `name` in requests.
    pub fn parse(name: &str) -> Option<Direction> {
        match name {
            "up" => Some(Direction::Up),
            "down" => Some(Direction::Down),
            "both" => Some(Direction::Both),
            _ => None,
        }
    }

    /// Whether S going from `before` to `after` over a step is a crossing that counts.
    #[inline]
    pub fn crossed(self, before: f64, after: f64) -> bool {
        let up = before < 0.0 && after >= 0.0;
        let down = before > 0.0 && after <= 0.0;
        match self {
            Direction::Up => up,
            Direction::Down => down,
            Direction::Both => up || down,
        }
    }

    /// Whether no values within `margin` (exclusive) of `before` and `after` can make a
    /// crossing that counts: an upward one needs the value before below zero and the one after
    /// at or above it, a downward one the reverse. A value that is not a number is never beyond
    /// the margin.
    #[inline]
    pub fn cannot_cross(self, before: f64, after: f64, margin: f64) -> bool {
        let no_up = before > margin || after < -margin;
        let no_down = before < -margin || after > margin;
        match self {
            Direction::Up => no_up,
            Direction::Down => no_down,
            Direction::Both => no_up && no_down,
        }
    }
}

/// The surface of a section.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum SurfaceSpec {
    /// S(q, p, t) = 0 for an expression S in the coordinates, momenta, parameters and t.
    Where {
        /// The expression.
        text: String,
        /// Which crossings count.
        direction: Direction,
    },
    /// t = φ + kT, k = 0, 1, …: the state once per period of a driving force.
    Stroboscopic {
        /// T (> 0).
        period: f64,
        /// φ, a time (finite).
        phase: f64,
    },
}

/// A Poincaré section of each run.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SectionSpec {
    /// The surface.
    pub surface: SurfaceSpec,
    /// Most points per run (1 to [`MAX_SECTION_POINTS`]); later crossings are not collected.
    pub max_points: u64,
    /// Where the request gave it (`section`).
    pub field: Field,
}

/// An event that ends a run: the `count`-th crossing of S = 0 in `direction`.
#[derive(Clone, Debug, PartialEq)]
pub struct EventSpec {
    /// The expression S.
    pub text: String,
    /// Which crossings count.
    pub direction: Direction,
    /// The crossing that ends the run (1 to [`MAX_EVENT_COUNT`]).
    pub count: u64,
    /// Where the request gave it (`stop_when`).
    pub field: Field,
}

/// What ends a run before t_end. One object, so that further kinds of stop (thresholds of
/// indicators) sit beside the event as members of their own.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StopWhen {
    /// The crossing event, if any.
    pub event: Option<EventSpec>,
}

impl SectionSpec {
    /// Checks the numbers: `max_points` within its bounds, a period > 0 and a finite phase.
    pub fn check(&self) -> Result<(), CoreError> {
        Range::closed(1.0, false, MAX_SECTION_POINTS as f64)
            .check(self.max_points as f64, &self.field.key("max_points"))?;
        if let SurfaceSpec::Stroboscopic { period, phase } = self.surface {
            Range::POSITIVE.check(period, &self.field.key("period"))?;
            if !phase.is_finite() {
                return Err(CoreError::NotFinite {
                    field: self.field.key("phase"),
                });
            }
        }
        Ok(())
    }
}

impl EventSpec {
    /// Checks `count` against its bounds.
    pub fn check(&self) -> Result<(), CoreError> {
        Range::closed(1.0, false, MAX_EVENT_COUNT as f64)
            .check(self.count as f64, &self.field.key("count"))?;
        Ok(())
    }
}

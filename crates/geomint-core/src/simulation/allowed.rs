//! The energetically allowed part of a section's plane: for a grid of points of a plane spanned
//! by two of a system's coordinates or momenta, whether an orbit can start there at energy E —
//! whether the momentum that an energy level solves for ([`crate::sections::energy::solve`], the
//! same solve a launched orbit takes) has a value that gives H = E. Where it has none the point
//! lies outside the energy surface: with that momentum at 0 the point already has more energy
//! than E (`lowest` > E), or no value of the momentum reaches E. The rest of the state is the
//! simulation's initial state, as an orbit launched from the point would have it.

use serde::Serialize;

use super::spec::Simulation;
use crate::error::{CoreError, Field, Range};
use crate::sections::names::StateNames;
use crate::sections::{energy, EnergyLevel};
use crate::system::{MechanicalSystem, State};
use crate::with_system;

/// Fewest and most grid points along an axis of the plane.
pub const PLANE_POINTS: (u64, u64) = (2, 200);

/// One axis of the plane: a coordinate or momentum, sampled at `points` evenly spaced values
/// from `min` to `max` (both included).
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneAxis {
    /// The coordinate's or momentum's name, as the system's names go (`x`, `p_x`).
    pub name: String,
    /// The first value.
    pub min: f64,
    /// The last value.
    pub max: f64,
    /// How many values.
    pub points: u64,
    /// Where the request gave it, e.g. `plane.x`.
    pub field: Field,
}

/// The plane: values across (`x`) and up (`y`).
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    /// Across.
    pub x: PlaneAxis,
    /// Up.
    pub y: PlaneAxis,
}

/// Which points of the plane can start an orbit at the energy.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct AllowedRegion {
    /// E.
    pub energy: f64,
    /// The momentum solved for.
    pub momentum: String,
    /// The values across.
    pub x: Vec<f64>,
    /// The values up.
    pub y: Vec<f64>,
    /// One row per value up (from the first), one entry per value across: whether the solved
    /// momentum has a value that puts the point on the energy surface.
    pub allowed: Vec<Vec<bool>>,
    /// Per point, H with the solved momentum at 0: the least energy an orbit from the point
    /// can have (null where not finite). A point with `lowest` > E is outside the surface.
    pub lowest: Vec<Vec<Option<f64>>>,
    /// How many points are allowed.
    pub allowed_points: u64,
}

impl PlaneAxis {
    /// The axis's values, checked: finite ends, min < max, a count within [`PLANE_POINTS`].
    fn values(&self) -> Result<Vec<f64>, CoreError> {
        for (key, v) in [("min", self.min), ("max", self.max)] {
            if !v.is_finite() {
                return Err(CoreError::NotFinite {
                    field: self.field.key(key),
                });
            }
        }
        if !(self.max > self.min) {
            return Err(CoreError::OutOfRange {
                field: self.field.key("max"),
                value: self.max,
                range: Range::above(self.min, true),
            });
        }
        let (min, max) = PLANE_POINTS;
        if self.points < min || self.points > max {
            return Err(CoreError::Count {
                field: self.field.key("points"),
                got: self.points,
                min,
                max,
                what: "grid points",
            });
        }
        let last = (self.points - 1) as f64;
        Ok((0..self.points)
            .map(|i| self.min + (self.max - self.min) * (i as f64 / last))
            .collect())
    }
}

impl Simulation {
    /// The allowed region of `plane` at the energy `level`: each grid point's state is the
    /// simulation's initial state with the plane's two names set to the point, and the level's
    /// momentum solved as [`Simulation::watching`] solves it for a launched orbit. Errors name
    /// the fields: unknown names, the solved momentum as an axis, both axes on one name.
    pub fn allowed_region(
        &self,
        level: &EnergyLevel,
        plane: &Plane,
    ) -> Result<AllowedRegion, CoreError> {
        let names = StateNames::of(&self.info, &self.chart, &self.params, self.q0.len());
        let known: Vec<String> = names
            .coordinates
            .iter()
            .chain(&names.momenta)
            .cloned()
            .collect();
        let solved = match names.find(&level.momentum) {
            Some((true, i)) => i,
            _ => {
                return Err(CoreError::UnknownName {
                    field: level.field.key("momentum"),
                    what: "momentum".into(),
                    value: level.momentum.clone(),
                    known: names.momenta.clone(),
                })
            }
        };
        let mut slots = Vec::with_capacity(2);
        for axis in [&plane.x, &plane.y] {
            let at = axis.field.key("name");
            let slot = names
                .find(&axis.name)
                .ok_or_else(|| CoreError::UnknownName {
                    field: at.clone(),
                    what: "coordinate or momentum".into(),
                    value: axis.name.clone(),
                    known: known.clone(),
                })?;
            if slot == (true, solved) {
                return Err(CoreError::Unsupported {
                    field: at,
                    reason: "the momentum solved from the energy cannot also be an axis",
                });
            }
            if slots.contains(&slot) {
                return Err(CoreError::Duplicate {
                    field: at,
                    value: axis.name.clone(),
                });
            }
            slots.push(slot);
        }
        if !level.energy.is_finite() {
            return Err(CoreError::NotFinite {
                field: level.field.key("value"),
            });
        }
        let xs = plane.x.values()?;
        let ys = plane.y.values()?;
        let mut allowed = Vec::with_capacity(ys.len());
        let mut lowest = Vec::with_capacity(ys.len());
        let mut allowed_points = 0;
        for &b in &ys {
            let mut row = Vec::with_capacity(xs.len());
            let mut least = Vec::with_capacity(xs.len());
            for &a in &xs {
                let mut q = self.q0.clone();
                let mut p = self.p0.clone();
                for ((momentum, i), v) in slots.iter().copied().zip([a, b]) {
                    if momentum {
                        p[i] = v;
                    } else {
                        q[i] = v;
                    }
                }
                let h = |p: &[f64]| {
                    with_system!(&self.system, s => {
                        let z = State::at_time(s, 0.0, &q, p);
                        s.energy(&z.q, &z.p)
                    })
                };
                let mut at_zero = p.clone();
                at_zero[solved] = 0.0;
                let floor = h(&at_zero);
                let ok = match energy::solve(&h, &p, solved, level.energy, &level.field) {
                    Ok(_) => true,
                    Err(CoreError::OutOfRange { .. } | CoreError::Unsupported { .. }) => false,
                    Err(e) => return Err(e),
                };
                allowed_points += u64::from(ok);
                row.push(ok);
                least.push(floor.is_finite().then_some(floor));
            }
            allowed.push(row);
            lowest.push(least);
        }
        Ok(AllowedRegion {
            energy: level.energy,
            momentum: level.momentum.clone(),
            x: xs,
            y: ys,
            allowed,
            lowest,
            allowed_points,
        })
    }
}

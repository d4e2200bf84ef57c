//! The axes of a sweep: what an axis varies (a system parameter, the step size, a component of
//! the initial state) and the values it takes.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::error::{CoreError, Field, Range};
use crate::simulation::SimulationSpec;
use crate::systems::ParamValue;

/// Most points along one axis of a sweep (a basin map's axes may have more:
/// [`crate::studies::basins::MAX_MAP_POINTS`]).
pub const MAX_POINTS: usize = 401;

/// What an axis varies.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// A number parameter of the system (`params.gamma`).
    Param(String),
    /// The step size (`h`).
    Step,
    /// Initial position `i` (`q0[i]`), in the coordinates `initial_coordinates` names.
    Q0(usize),
    /// Initial momentum `i` (`p0[i]`).
    P0(usize),
}

impl Target {
    /// Reads `params.<name>`, `h`, `q0[i]` or `p0[i]`.
    pub fn parse(text: &str) -> Option<Target> {
        let component = |prefix: &str| -> Option<usize> {
            let index = text.strip_prefix(prefix)?.strip_suffix(']')?;
            // Digits only: no sign, no spaces, no leading `+`.
            (!index.is_empty() && index.bytes().all(|b| b.is_ascii_digit()))
                .then(|| index.parse().ok())
                .flatten()
        };
        if text == "h" {
            return Some(Target::Step);
        }
        if let Some(name) = text.strip_prefix("params.") {
            return (!name.is_empty()).then(|| Target::Param(name.to_string()));
        }
        if let Some(i) = component("q0[") {
            return Some(Target::Q0(i));
        }
        component("p0[").map(Target::P0)
    }

    /// The name the axis has in requests and documents.
    pub fn name(&self) -> String {
        match self {
            Target::Param(name) => format!("params.{name}"),
            Target::Step => "h".into(),
            Target::Q0(i) => format!("q0[{i}]"),
            Target::P0(i) => format!("p0[{i}]"),
        }
    }
}

/// A target is written by its name (`params.gamma`, `h`, `q0[1]`).
impl Serialize for Target {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.name())
    }
}

impl<'de> Deserialize<'de> for Target {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Target::parse(&name)
            .ok_or_else(|| serde::de::Error::custom(format!("`{name}` is not an axis")))
    }
}

/// How the points of an axis are spaced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Scale {
    /// Evenly: min + (max − min)·k/(n − 1).
    #[default]
    Linear,
    /// Evenly in the logarithm (min > 0): min·(max/min)^(k/(n − 1)).
    Log,
}

/// One axis of a sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Axis {
    /// What it varies.
    pub target: Target,
    /// The first value.
    pub min: f64,
    /// The last value.
    pub max: f64,
    /// Points (1 to the study's most, [`MAX_POINTS`] for a sweep); one point sits at the middle
    /// of [min, max].
    pub n: usize,
    /// Spacing.
    pub scale: Scale,
    /// Where the request gave it (`axes[1]`).
    pub field: Field,
}

impl Axis {
    /// Checks the range and the count (1 to `max_points`); errors name `axes[k].min`, `.max` or
    /// `.n`.
    pub fn check(&self, max_points: usize) -> Result<(), CoreError> {
        if self.n == 0 || self.n > max_points {
            return Err(CoreError::Count {
                field: self.field.key("n"),
                got: self.n as u64,
                min: 1,
                max: max_points as u64,
                what: "points",
            });
        }
        if !(self.min.is_finite() && self.max.is_finite() && self.min <= self.max) {
            return Err(CoreError::BadInterval {
                field: self.field.clone(),
                min: self.min,
                max: self.max,
            });
        }
        if self.scale == Scale::Log {
            Range::POSITIVE.check(self.min, &self.field.key("min"))?;
        }
        if self.target == Target::Step {
            Range::POSITIVE.check(self.min, &self.field.key("min"))?;
        }
        Ok(())
    }

    /// Point `k` of the axis. The linear spacing is min + (max − min)·k/(n − 1), multiplied
    /// before it is divided, as the energy-error map's grid always was (the map is a sweep).
    pub fn value(&self, k: usize) -> f64 {
        if self.n == 1 {
            return match self.scale {
                Scale::Linear => 0.5 * (self.min + self.max),
                Scale::Log => (self.min * self.max).sqrt(),
            };
        }
        let intervals = (self.n - 1) as f64;
        match self.scale {
            Scale::Linear => self.min + (self.max - self.min) * k as f64 / intervals,
            Scale::Log if k + 1 == self.n => self.max,
            Scale::Log => self.min * (self.max / self.min).powf(k as f64 / intervals),
        }
    }

    /// All points.
    pub fn values(&self) -> Vec<f64> {
        (0..self.n).map(|k| self.value(k)).collect()
    }

    /// `spec` with this axis at `value`. A component of q0/p0 fills in the rest of the vector
    /// from `default` (the system's default state) when the spec gives none.
    pub fn apply(&self, spec: &mut SimulationSpec, value: f64, default: (&[f64], &[f64])) {
        let set = |given: &mut Option<Vec<f64>>, default: &[f64], i: usize| {
            let v = given.get_or_insert_with(|| default.to_vec());
            if v.len() <= i {
                // Too short for the system: the simulation's own check names the vector.
                v.resize(i + 1, 0.0);
            }
            v[i] = value;
        };
        match &self.target {
            Target::Param(name) => {
                spec.params.insert(name.clone(), ParamValue::Number(value));
            }
            Target::Step => spec.h = value,
            Target::Q0(i) => set(&mut spec.q0, default.0, *i),
            Target::P0(i) => set(&mut spec.p0, default.1, *i),
        }
    }

    /// The field a simulation names for this axis's input (`params.gamma`, `h`, `q0`).
    pub fn input_field(&self) -> &'static str {
        match self.target {
            Target::Param(_) => "params",
            Target::Step => "h",
            Target::Q0(_) => "q0",
            Target::P0(_) => "p0",
        }
    }
}

/// The grid of a sweep: one or two axes, cells in row-major order (the first axis runs fastest:
/// cell j·n₀ + i is (axes[0][i], axes[1][j])).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// The axes.
    pub axes: Vec<Axis>,
}

impl Grid {
    /// Cells in all.
    pub fn cells(&self) -> usize {
        self.axes.iter().map(|a| a.n).product()
    }

    /// The axis values of `cell`, one per axis.
    pub fn point(&self, cell: usize) -> Vec<f64> {
        let mut rest = cell;
        self.axes
            .iter()
            .map(|a| {
                let k = rest % a.n;
                rest /= a.n;
                a.value(k)
            })
            .collect()
    }
}

//! Field paths as errors name them, and the valid ranges of numbers.

use std::fmt;

use super::CoreError;

/// The path of an input field as errors name it: `h`, `params.omega`, `methods[1].inner`,
/// `runs[0].h[2]`. Callers build it from the names their input uses, so an error raised deep in
/// the core names the field the user wrote.
#[derive(
    Clone,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    PartialOrd,
    Ord,
    serde::Serialize,
    serde::Deserialize,
)]
#[serde(transparent)]
pub struct Field(String);

impl Field {
    /// A top-level field.
    pub fn new(name: impl Into<String>) -> Self {
        Field(name.into())
    }

    /// The member `name` of this field (`params` → `params.omega`).
    pub fn key(&self, name: &str) -> Field {
        if self.0.is_empty() {
            Field(name.to_string())
        } else {
            Field(format!("{}.{name}", self.0))
        }
    }

    /// The entry `i` of this list field (`q0` → `q0[2]`).
    pub fn index(&self, i: usize) -> Field {
        Field(format!("{}[{i}]", self.0))
    }

    /// The path as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for Field {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl From<&str> for Field {
    fn from(name: &str) -> Self {
        Field::new(name)
    }
}

impl From<String> for Field {
    fn from(name: String) -> Self {
        Field(name)
    }
}

/// An interval of valid values; `min_open`/`max_open` exclude the bound. An infinite `max`
/// means "no upper bound".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Lower bound.
    pub min: f64,
    /// Whether `min` itself is excluded.
    pub min_open: bool,
    /// Upper bound (∞ for none).
    pub max: f64,
    /// Whether `max` itself is excluded.
    pub max_open: bool,
}

impl Range {
    /// Finite and > 0.
    pub const POSITIVE: Range = Range::above(0.0, true);
    /// Finite and ≥ 0.
    pub const NON_NEGATIVE: Range = Range::above(0.0, false);

    /// [min, max], or (min, max] with `min_open`.
    pub const fn closed(min: f64, min_open: bool, max: f64) -> Range {
        Range {
            min,
            min_open,
            max,
            max_open: false,
        }
    }

    /// Everything finite above `min` (excluded with `open`).
    pub const fn above(min: f64, open: bool) -> Range {
        Range {
            min,
            min_open: open,
            max: f64::INFINITY,
            max_open: true,
        }
    }

    /// Whether `x` is finite and inside.
    pub fn contains(&self, x: f64) -> bool {
        let above = if self.min_open {
            x > self.min
        } else {
            x >= self.min
        };
        let below = if self.max_open {
            x < self.max
        } else {
            x <= self.max
        };
        x.is_finite() && above && below
    }

    /// Checks `x` against the range; the error names `field`.
    pub fn check(&self, x: f64, field: &Field) -> Result<f64, CoreError> {
        if self.contains(x) {
            Ok(x)
        } else {
            Err(CoreError::OutOfRange {
                field: field.clone(),
                value: x,
                range: *self,
            })
        }
    }
}

/// A number as messages show it: plain decimals, or exponent notation for very small and very
/// large magnitudes (`1e-14`, not `0.00000000000001`).
pub fn show(x: f64) -> String {
    let a = x.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e16).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let open = if self.min_open { "(" } else { "[" };
        let close = if self.max_open { ")" } else { "]" };
        write!(f, "{open}{}, {}{close}", show(self.min), show(self.max))
    }
}

/// The numbers of a value outside its range, as the messages put them.
pub(super) fn out_of_range(field: &Field, value: f64, range: &Range) -> String {
    if range.max.is_infinite() {
        let relation = if range.min_open { ">" } else { "≥" };
        format!(
            "{field}: must be finite and {relation} {}, got {}",
            show(range.min),
            show(value)
        )
    } else {
        format!(
            "{field}: {} is outside the valid range {range}",
            show(value)
        )
    }
}

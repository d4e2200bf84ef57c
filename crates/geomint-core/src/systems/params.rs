//! A system's parameters: how each is declared ([`ParamSpec`], a constant beside the system that
//! reads it), what a request gives ([`ParamValue`]), and the validated, complete set a system is
//! built from ([`ParamValues`]).
//!
//! Systems read their parameters through their own `ParamSpec` constants
//! ([`ParamValues::number`]), so a parameter's name is written once; a value missing from the set
//! reads as the spec's default, never as a silent zero.

use std::borrow::Cow;
use std::collections::BTreeMap;

use serde::Serialize;

use super::SystemInfo;
use crate::error::{CoreError, Field, Range};

/// How a parameter is given and what values it accepts.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(tag = "kind", rename_all = "snake_case")]
#[cfg_attr(feature = "openapi", schema(as = ParamKindEntry))]
pub enum ParamKind {
    /// A number in [min, max] (min excluded when `min_exclusive`).
    Number {
        /// Default value.
        default: f64,
        /// Lower bound.
        min: f64,
        /// Whether the lower bound itself is excluded.
        min_exclusive: bool,
        /// Upper bound.
        max: f64,
    },
    /// One of a fixed set of names.
    Choice {
        /// Default option.
        default: &'static str,
        /// The options.
        options: &'static [&'static str],
    },
    /// A list of positive numbers (N-body masses).
    NumberList {
        /// Default list.
        default: &'static [f64],
        /// Lower bound (excluded) of every entry.
        min: f64,
        /// Upper bound of every entry.
        max: f64,
        /// Most entries allowed.
        max_len: usize,
    },
}

/// One parameter of a system.
#[derive(Clone, Debug, Serialize, PartialEq)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = ParamEntry))]
pub struct ParamSpec {
    /// Name used in `params`.
    #[cfg_attr(feature = "openapi", schema(value_type = String))]
    pub name: Cow<'static, str>,
    /// What it means.
    #[cfg_attr(feature = "openapi", schema(value_type = String))]
    pub description: Cow<'static, str>,
    /// Accepted values.
    #[serde(flatten)]
    pub kind: ParamKind,
}

impl ParamSpec {
    /// A number parameter with its default and valid range [min, max] ((min, max] when
    /// `min_exclusive`).
    pub const fn number(
        name: &'static str,
        description: &'static str,
        default: f64,
        min: f64,
        min_exclusive: bool,
        max: f64,
    ) -> ParamSpec {
        ParamSpec {
            name: Cow::Borrowed(name),
            description: Cow::Borrowed(description),
            kind: ParamKind::Number {
                default,
                min,
                min_exclusive,
                max,
            },
        }
    }

    /// The linear damping coefficient γ of a conformally damped system (`epsilon` = 2γ may be
    /// given instead).
    pub const fn gamma(default: f64) -> ParamSpec {
        ParamSpec::number(
            "gamma",
            "Linear damping coefficient γ in p' = −∇V − 2γp; `epsilon` = 2γ may be given instead (paper 000's ε).",
            default,
            0.0,
            false,
            1e6,
        )
    }

    /// The parameter's default value.
    pub fn default_value(&self) -> ParamValue {
        match self.kind {
            ParamKind::Number { default, .. } => ParamValue::Number(default),
            ParamKind::Choice { default, .. } => ParamValue::Text(default.to_string()),
            ParamKind::NumberList { default, .. } => ParamValue::Numbers(default.to_vec()),
        }
    }
}

/// A parameter's value as a request gives it.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(untagged)]
pub enum ParamValue {
    /// A number.
    Number(f64),
    /// A name (a choice).
    Text(String),
    /// A list of numbers.
    Numbers(Vec<f64>),
    /// Anything else (a boolean, an object, a list with a non-number): always refused, with
    /// the kind the parameter needs.
    #[serde(skip)]
    Other,
}

/// A system's parameters after validation: every one of them, defaults filled in.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(transparent)]
#[cfg_attr(feature = "openapi", schema(value_type = Object))]
pub struct ParamValues(BTreeMap<String, ParamValue>);

impl ParamValues {
    /// The value of `spec` (its default when not set).
    fn value(&self, spec: &ParamSpec) -> ParamValue {
        self.0
            .get(&*spec.name)
            .cloned()
            .unwrap_or_else(|| spec.default_value())
    }

    /// The number `spec`.
    pub fn number(&self, spec: &ParamSpec) -> f64 {
        match (self.value(spec), spec.kind) {
            (ParamValue::Number(x), _) => x,
            (_, ParamKind::Number { default, .. }) => default,
            _ => f64::NAN,
        }
    }

    /// The list of numbers `spec`.
    pub fn numbers(&self, spec: &ParamSpec) -> Vec<f64> {
        match (self.value(spec), spec.kind) {
            (ParamValue::Numbers(x), _) => x,
            (_, ParamKind::NumberList { default, .. }) => default.to_vec(),
            _ => Vec::new(),
        }
    }

    /// The name `spec`.
    pub fn text(&self, spec: &ParamSpec) -> String {
        match (self.value(spec), spec.kind) {
            (ParamValue::Text(x), _) => x,
            (_, ParamKind::Choice { default, .. }) => default.to_string(),
            _ => String::new(),
        }
    }

    /// The number named `name`, when it is set and is a number.
    pub fn get(&self, name: &str) -> Option<f64> {
        match self.0.get(name) {
            Some(ParamValue::Number(x)) => Some(*x),
            _ => None,
        }
    }

    /// Every parameter by name.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &ParamValue)> {
        self.0.iter().map(|(k, v)| (k.as_str(), v))
    }
}

/// Validates `given` against the system's parameters (unknown names, kinds, ranges; `gamma`
/// and `epsilon` are exclusive on a conformally damped system) and fills in defaults. `field`
/// names the parameters (`params`).
pub fn resolve(
    info: &SystemInfo,
    given: &BTreeMap<String, ParamValue>,
    field: &Field,
) -> Result<ParamValues, CoreError> {
    let alias = info.conformal_damping && given.contains_key("epsilon");
    if alias && given.contains_key("gamma") {
        return Err(CoreError::Either {
            field: field.key("epsilon"),
            first: "gamma",
            second: "epsilon (= 2γ)",
        });
    }
    for name in given.keys() {
        let known = info.params.iter().any(|p| p.name == *name) || (alias && name == "epsilon");
        if !known {
            return Err(CoreError::UnknownParameter {
                field: field.key(name),
                system: info.id.to_string(),
                known: info.params.iter().map(|p| p.name.to_string()).collect(),
            });
        }
    }
    let mut resolved = BTreeMap::new();
    for spec in &info.params {
        // `epsilon` = 2γ on a conformal system: errors name and show what was given.
        let (name, scale) = if spec.name == "gamma" && alias {
            ("epsilon", 2.0)
        } else {
            (&*spec.name, 1.0)
        };
        let at = field.key(name);
        let value = match given.get(name) {
            None => spec.default_value(),
            Some(v) => check(spec, v, scale, &at)?,
        };
        resolved.insert(spec.name.to_string(), value);
    }
    Ok(ParamValues(resolved))
}

/// Checks one given value against its spec; a number given as a multiple `scale` of the
/// parameter (epsilon for gamma) is divided by it, and its range shown in the given units.
fn check(
    spec: &ParamSpec,
    v: &ParamValue,
    scale: f64,
    at: &Field,
) -> Result<ParamValue, CoreError> {
    let wrong = |expected| CoreError::WrongKind {
        field: at.clone(),
        expected,
    };
    match (&spec.kind, v) {
        (
            ParamKind::Number {
                min,
                min_exclusive,
                max,
                ..
            },
            ParamValue::Number(x),
        ) => {
            let range = Range::closed(*min * scale, *min_exclusive, *max * scale);
            range.check(*x, at).map(|x| ParamValue::Number(x / scale))
        }
        (ParamKind::Number { .. }, _) => Err(wrong("a number")),
        (ParamKind::Choice { options, .. }, ParamValue::Text(name)) => {
            if options.contains(&name.as_str()) {
                Ok(ParamValue::Text(name.clone()))
            } else {
                Err(CoreError::UnknownName {
                    field: at.clone(),
                    what: spec.name.to_string(),
                    value: name.clone(),
                    known: options.iter().map(|o| o.to_string()).collect(),
                })
            }
        }
        (ParamKind::Choice { .. }, _) => Err(wrong("a string")),
        (
            ParamKind::NumberList {
                min, max, max_len, ..
            },
            ParamValue::Numbers(list),
        ) => {
            if list.is_empty() || list.len() > *max_len {
                return Err(CoreError::Count {
                    field: at.clone(),
                    got: list.len() as u64,
                    min: 1,
                    max: *max_len as u64,
                    what: "entries",
                });
            }
            let range = Range::closed(*min, true, *max);
            for &x in list {
                range.check(x, at)?;
            }
            Ok(ParamValue::Numbers(list.clone()))
        }
        (ParamKind::NumberList { .. }, _) => Err(wrong("a list of numbers")),
    }
}

//! A method as requests write it — an id (`"modin_3s"`) or an object with options
//! (`{"id": "modin_rks", "inner": "rk4"}`) — read with every problem named at its field, and
//! validated into the core's [`Method`].

use serde::Serialize;
use serde_json::Value;
use utoipa::ToSchema;

use super::json::{missing, number, string, wrong_type, Obj};
use crate::core::error::{CoreError, ErrorDetail, Field};
use crate::core::methods::composition::Scheme;
use crate::core::methods::rowlands::Processor;
use crate::core::methods::{Base, Inner, Method, MethodId, MethodOption, TOLERANCE_RANGE};
use crate::core::simulation::MethodAt;

/// A method: a bare id, or an object with options.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(untagged)]
pub enum MethodSpec {
    /// A method id such as `modin_3s`.
    #[schema(value_type = MethodId)]
    Id(String),
    /// A method with options.
    Options(MethodOptions),
}

/// A method with options.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MethodOptions {
    /// The method id.
    #[schema(value_type = MethodId)]
    pub id: String,
    /// Inner Runge–Kutta method of `modin_rks` (default `heun`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Inner>)]
    pub inner: Option<String>,
    /// Symmetric second-order base of a composition (the methods whose catalogue entry lists
    /// the `base` option, e.g. `triple_jump`); default `modin_3s`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Base>)]
    pub base: Option<String>,
    /// Relative tolerance of `reference` (in [1e-14, 1e-2]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1e-14, maximum = 1e-2)]
    pub tolerance: Option<f64>,
    /// Processor of `rowlands`: `none` (the second-order kernel alone), `original` (eqs. 32–33
    /// with h²/12) or `cheap` (eqs. 34–37; default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Processor>)]
    pub processor: Option<String>,
}

/// The fields of a method object.
pub const METHOD_FIELDS: &[&str] = &["id", "inner", "base", "tolerance", "processor"];

/// A known method id, else `unknown_method` at `field`.
fn method_id(id: &str, field: &Field) -> Result<MethodId, CoreError> {
    MethodId::parse(id).ok_or_else(|| CoreError::UnknownMethod {
        field: field.clone(),
        id: id.to_string(),
        known: MethodId::ALL
            .iter()
            .map(|m| m.as_str().to_string())
            .collect(),
    })
}

/// Reads a method: an id or an object with options, with unknown ids and fields named.
pub fn read_method(v: &Value, field: &Field) -> Result<MethodSpec, ErrorDetail> {
    let known = |id: String, at: &Field| -> Result<String, ErrorDetail> {
        method_id(&id, at).map(|_| id).map_err(ErrorDetail::from)
    };
    match v {
        Value::String(id) => Ok(MethodSpec::Id(known(id.clone(), field)?)),
        Value::Object(_) => {
            let o = Obj::new(v, field.clone(), METHOD_FIELDS)?;
            let id = match o.get("id") {
                Some(v) => known(string(v, &o.field("id"))?, &o.field("id"))?,
                None => return Err(missing(&o.field("id"), "the method id")),
            };
            let option = |name: &str| o.optional(name, |v, at| known(string(v, at)?, at));
            Ok(MethodSpec::Options(MethodOptions {
                id,
                inner: option("inner")?,
                base: option("base")?,
                tolerance: o.optional("tolerance", number)?,
                processor: o.optional("processor", |v, at| {
                    v.as_str().map(str::to_string).ok_or_else(|| {
                        wrong_type(at, "a processor name: none, original or cheap", v)
                    })
                })?,
            }))
        }
        other => Err(wrong_type(
            field,
            "a method id or an object such as {\"id\": \"modin_rks\", \"inner\": \"rk4\"}",
            other,
        )),
    }
}

/// Reads a list of methods, each named `field[i]`.
pub fn read_methods(v: &Value, field: &Field) -> Result<Vec<MethodSpec>, ErrorDetail> {
    super::json::list(v, field, "a list of methods", read_method)
}

impl MethodSpec {
    /// The method id as given.
    pub fn id(&self) -> &str {
        match self {
            MethodSpec::Id(id) => id,
            MethodSpec::Options(o) => &o.id,
        }
    }

    /// The core's method, options checked against what the method takes; errors name `field`
    /// and its members (`methods[1].inner`).
    pub fn to_method(&self, field: &Field) -> Result<Method, CoreError> {
        let o = match self {
            MethodSpec::Id(id) => return method_id(id, field).map(Method::new),
            MethodSpec::Options(o) => o,
        };
        let id = method_id(&o.id, &field.key("id"))?;
        let takes = id.info().options;
        for (option, given) in [
            (MethodOption::Inner, o.inner.is_some()),
            (MethodOption::Base, o.base.is_some()),
            (MethodOption::Tolerance, o.tolerance.is_some()),
            (MethodOption::Processor, o.processor.is_some()),
        ] {
            if given && !takes.contains(&option) {
                return Err(CoreError::UnknownOption {
                    field: field.key(option.as_str()),
                    method: id.as_str(),
                    option: option.as_str(),
                });
            }
        }
        let mut method = Method::new(id);
        if let Some(name) = &o.inner {
            let at = field.key("inner");
            let inner = method_id(name, &at)?;
            let inner = Inner::of(inner).ok_or_else(|| CoreError::NotAllowed {
                field: at,
                method: inner.as_str(),
                rule: Inner::RULE,
                allowed: Inner::ids(),
            })?;
            method = Method::ModinRks { inner };
        }
        if let Some(name) = &o.base {
            let at = field.key("base");
            let base = method_id(name, &at)?;
            let base = Base::of(base).ok_or_else(|| CoreError::NotAllowed {
                field: at,
                method: base.as_str(),
                rule: Base::RULE,
                allowed: Base::ids(),
            })?;
            let scheme = Scheme::of(id).unwrap_or(Scheme::TRIPLE_JUMP);
            method = Method::Composition { scheme, base };
        }
        if let Some(name) = &o.processor {
            let processor = Processor::parse(name).ok_or_else(|| CoreError::UnknownName {
                field: field.key("processor"),
                what: "processor".to_string(),
                value: name.clone(),
                known: Processor::ALL
                    .iter()
                    .map(|p| p.as_str().to_string())
                    .collect(),
            })?;
            method = Method::Rowlands { processor };
        }
        if let Some(t) = o.tolerance {
            let tolerance = TOLERANCE_RANGE.check(t, &field.key("tolerance"))?;
            method = Method::Reference { tolerance };
        }
        Ok(method)
    }

    /// The core's method with its field.
    pub fn at(&self, field: &Field) -> Result<MethodAt, CoreError> {
        Ok(MethodAt {
            method: self.to_method(field)?,
            field: field.clone(),
        })
    }
}

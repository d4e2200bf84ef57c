//! [`Method`]: a method with its options, as a request names it and a run uses it; its
//! defaults, its facts (order, requirements, labels) and its wire form (a bare id, or an object
//! with one option).

use serde::{Serialize, Serializer};

use super::composition::Scheme;
use super::reference;
use super::rowlands::Processor;
use super::{Base, Inner, MethodId, MethodInfo, Requirement};
use crate::error::{CoreError, Field};
use crate::system::Structure;

/// A method with its options: what a request asks for and a run uses. Options take their
/// defaults when a request leaves them out ([`Method::new`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// One of the methods without options.
    Plain(MethodId),
    /// modin_rks with its inner Runge–Kutta method (default heun).
    ModinRks {
        /// The inner method.
        inner: Inner,
    },
    /// A symmetric composition of a base (default modin_3s).
    Composition {
        /// The composition: a method whose catalogue entry gives its weights
        /// ([`Steps::Composition`](super::Steps::Composition)).
        scheme: Scheme,
        /// The base.
        base: Base,
    },
    /// rowlands with its processor (default cheap).
    Rowlands {
        /// The processor.
        processor: Processor,
    },
    /// The adaptive reference at a tolerance (default 1e-12).
    Reference {
        /// Relative and absolute tolerance, in [1e-14, 1e-2].
        tolerance: f64,
    },
}

/// The valid tolerances of the adaptive reference.
pub const TOLERANCE_RANGE: crate::error::Range = crate::error::Range::closed(1e-14, false, 1e-2);

impl Method {
    /// The method `id` with default options.
    pub fn new(id: MethodId) -> Method {
        match id {
            MethodId::ModinRks => Method::ModinRks { inner: Inner::Heun },
            MethodId::Rowlands => Method::Rowlands {
                processor: Processor::DEFAULT,
            },
            MethodId::Reference => Method::Reference {
                tolerance: reference::DEFAULT_TOLERANCE,
            },
            id => match Scheme::of(id) {
                Some(scheme) => Method::Composition {
                    scheme,
                    base: Base::Modin3s,
                },
                None => Method::Plain(id),
            },
        }
    }

    /// The composition `scheme` of `base`.
    pub fn composition(scheme: Scheme, base: Base) -> Method {
        Method::Composition { scheme, base }
    }

    /// The triple jump of `base`.
    pub fn triple_jump(base: Base) -> Method {
        Method::composition(Scheme::TRIPLE_JUMP, base)
    }

    /// The method's id.
    pub fn id(&self) -> MethodId {
        match self {
            Method::Plain(id) => *id,
            Method::ModinRks { .. } => MethodId::ModinRks,
            Method::Composition { scheme, .. } => scheme.id(),
            Method::Rowlands { .. } => MethodId::Rowlands,
            Method::Reference { .. } => MethodId::Reference,
        }
    }

    /// The method's catalogue entry.
    pub fn info(&self) -> &'static MethodInfo {
        self.id().info()
    }

    /// A label that tells runs apart: `modin_rks(rk4)`, `triple_jump(csv1)`, `reference(1e-10)`,
    /// `rowlands(cheap)`.
    pub fn label(&self) -> String {
        let id = self.id().as_str();
        match self {
            Method::Plain(_) => id.to_string(),
            Method::ModinRks { inner } => format!("{id}({})", inner.id()),
            Method::Composition { base, .. } => format!("{id}({})", base.id()),
            Method::Rowlands { processor } => format!("{id}({})", processor.as_str()),
            Method::Reference { tolerance } if *tolerance != reference::DEFAULT_TOLERANCE => {
                format!("{id}({tolerance:e})")
            }
            Method::Reference { .. } => id.to_string(),
        }
    }

    /// The requirements on the system (a composition inherits its base's).
    pub fn requirements(&self) -> &'static [Requirement] {
        match self {
            Method::Composition { base, .. } => base.id().info().requirements,
            _ => self.info().requirements,
        }
    }

    /// The order: the method's, except that rowlands without processing is its second-order
    /// kernel.
    pub fn order(&self) -> u32 {
        match self {
            Method::Rowlands {
                processor: Processor::None,
            } => 2,
            _ => self.info().order,
        }
    }

    /// Why the step has no Jacobian, if it has none (a composition has its base's).
    pub fn no_step_jacobian(&self) -> Option<&'static str> {
        match self {
            Method::Composition { base, .. } => base.id().info().no_step_jacobian,
            _ => self.info().no_step_jacobian,
        }
    }

    /// Checks the requirements against a system with this structure and damping rate; the
    /// error names the first unmet one, the method's `field` and the system as `system` says.
    pub fn check(
        &self,
        field: &Field,
        system: &str,
        structure: Structure,
        damping_rate: f64,
    ) -> Result<(), CoreError> {
        match self
            .requirements()
            .iter()
            .find(|r| !r.met_by(structure, damping_rate))
        {
            None => Ok(()),
            Some(&requirement) => Err(CoreError::Unmet {
                field: field.clone(),
                method: self.label(),
                system: system.to_string(),
                requirement,
            }),
        }
    }
}

impl From<MethodId> for Method {
    fn from(id: MethodId) -> Self {
        Method::new(id)
    }
}

/// A method is written as requests write it: its id alone when it has no options, else
/// `{"id", <option>}`.
impl Serialize for Method {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let id = self.id().as_str();
        /// An option's value: a name or the tolerance.
        #[derive(Serialize)]
        #[serde(untagged)]
        enum Value {
            Name(&'static str),
            Number(f64),
        }
        let option = match self {
            Method::Plain(_) => None,
            Method::ModinRks { inner } => Some(("inner", Value::Name(inner.id().as_str()))),
            Method::Composition { base, .. } => Some(("base", Value::Name(base.id().as_str()))),
            Method::Rowlands { processor } => Some(("processor", Value::Name(processor.as_str()))),
            Method::Reference { tolerance } => Some(("tolerance", Value::Number(*tolerance))),
        };
        match option {
            None => s.serialize_str(id),
            Some((name, value)) => {
                let mut map = s.serialize_map(Some(2))?;
                map.serialize_entry("id", id)?;
                map.serialize_entry(name, &value)?;
                map.end()
            }
        }
    }
}

/// Reads what [`Method`]'s `Serialize` writes (a study's spec carried to a worker or a part
/// file): an id, or `{"id", <option>}` with the option named as the method's. Requests are read
/// by the wire layer, which names fields in its errors; this reader only has to read back what
/// the core wrote.
impl<'de> serde::Deserialize<'de> for Method {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        #[derive(serde::Deserialize)]
        #[serde(untagged)]
        enum Form {
            Id(String),
            Options {
                id: String,
                inner: Option<String>,
                base: Option<String>,
                processor: Option<String>,
                tolerance: Option<f64>,
            },
        }
        let id_of = |s: &str| {
            MethodId::parse(s).ok_or_else(|| D::Error::custom(format!("no method `{s}`")))
        };
        let subset = |name: &Option<String>, what: &str| -> Result<MethodId, D::Error> {
            let name = name
                .as_deref()
                .ok_or_else(|| D::Error::custom(format!("a method without its {what}")))?;
            id_of(name)
        };
        match Form::deserialize(d)? {
            Form::Id(id) => Ok(Method::new(id_of(&id)?)),
            Form::Options {
                id,
                inner,
                base,
                processor,
                tolerance,
            } => {
                let id = id_of(&id)?;
                let wrong =
                    || D::Error::custom(format!("`{}` does not take that option", id.as_str()));
                match Method::new(id) {
                    Method::ModinRks { .. } => Ok(Method::ModinRks {
                        inner: Inner::of(subset(&inner, "inner method")?).ok_or_else(wrong)?,
                    }),
                    Method::Composition { scheme, .. } => Ok(Method::Composition {
                        scheme,
                        base: Base::of(subset(&base, "base")?).ok_or_else(wrong)?,
                    }),
                    Method::Rowlands { .. } => Ok(Method::Rowlands {
                        processor: processor
                            .as_deref()
                            .and_then(Processor::parse)
                            .ok_or_else(wrong)?,
                    }),
                    Method::Reference { .. } => Ok(Method::Reference {
                        tolerance: tolerance.ok_or_else(wrong)?,
                    }),
                    Method::Plain(_) => Err(wrong()),
                }
            }
        }
    }
}

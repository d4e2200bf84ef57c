//! A system as requests write it: an id (`"pendulum"`, or a stored definition's id) or a
//! definition of the user's own ([`SystemDefinition`]), read with every problem named at its
//! field (`system.damping.matrix[1][0]`) and checked into the core's user-defined system.
//!
//! A definition's id is a digest of its canonical form (its JSON with sorted keys and numbers as
//! f64), so the same definition always has the same id, whether stored or sent inline.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::Arc;

use serde::Serialize;
use serde_json::Value;
use sha2::{Digest, Sha256};
use utoipa::ToSchema;

use super::json::{self, list, number, numbers, string, wrong_type, Obj};
use crate::core::error::{CoreError, ErrorDetail, Field};
use crate::core::systems::custom::{self, CustomDefinition, Damping, Energy, Expression, Mass};
use crate::core::systems::{SystemInfo, SystemRef};

/// A system: an id, or a definition.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(untagged)]
pub enum SystemRequest {
    /// A built-in system's id (see `GET /api/v1/systems`) or a stored definition's.
    #[schema(example = "pendulum")]
    Id(String),
    /// A system defined in the request.
    Definition(Box<SystemDefinition>),
}

impl Default for SystemRequest {
    fn default() -> Self {
        SystemRequest::Id(String::new())
    }
}

impl From<&str> for SystemRequest {
    fn from(id: &str) -> Self {
        SystemRequest::Id(id.to_string())
    }
}

/// A number, or an expression in the names the place allows.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(untagged)]
pub enum Entry {
    /// A number.
    Number(f64),
    /// An expression, e.g. `k/m` or `x*y/(x^2+y^2)`.
    Expression(String),
}

/// A constant mass matrix.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(untagged)]
pub enum MassEntry {
    /// m: the mass matrix m·I.
    Scalar(Entry),
    /// The diagonal of a diagonal mass matrix.
    Diagonal(Vec<Entry>),
    /// A symmetric positive definite matrix, row by row.
    Matrix(Vec<Vec<Entry>>),
}

/// The damping of a user-defined system.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(untagged)]
pub enum DampingEntry {
    /// Linear conformal damping p' = … − 2γp: the conformal symplectic methods (csv1, csv2,
    /// cimp) apply.
    Conformal {
        /// γ ≥ 0, a number or an expression in the parameters.
        gamma: Entry,
    },
    /// Rayleigh damping p' = … − ε D(q) q̇, D symmetric positive semidefinite: the splittings
    /// (modin_3s, modin_2s, modin_rks) apply, with the exact damping sub-flow.
    Rayleigh {
        /// ε ≥ 0, a number or an expression in the parameters.
        epsilon: Entry,
        /// D(q), row by row, expressions in the coordinates and parameters.
        matrix: Vec<Vec<Entry>>,
    },
}

/// A damped Hamiltonian system written as text. Give `mass` and `potential` for a separable
/// H = ½pᵀM⁻¹p + V(q) (which the splittings need), or a general `hamiltonian` H(q, p).
/// Expressions use numbers, `+ - * / ^`, parentheses, `sin cos tan asin acos atan atan2 sinh
/// cosh tanh exp log sqrt abs`, `pi` and the declared names.
#[derive(Clone, Debug, Default, PartialEq, Serialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({
    "name": "Elastic pendulum with radial damping",
    "coordinates": ["x", "y"],
    "momenta": ["px", "py"],
    "mass": 1,
    "potential": "k/2*(sqrt(x^2 + y^2) - l)^2 - m*g*y",
    "damping": {"epsilon": 0.1, "matrix": [["x^2/(x^2+y^2)", "x*y/(x^2+y^2)"], ["x*y/(x^2+y^2)", "y^2/(x^2+y^2)"]]},
    "parameters": {"k": 1, "l": 1, "m": 1, "g": 0.2},
    "invariants": {"L": "x*py - y*px"},
    "positions": [["x", "-y"]],
    "q0": [1.2, 0.3], "p0": [0, 0]
}))]
pub struct SystemDefinition {
    /// A name for people.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The generalized coordinates' names (1 to 32).
    #[schema(min_items = 1, max_items = 32)]
    pub coordinates: Vec<String>,
    /// The momenta's names (default `p_<coordinate>`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub momenta: Option<Vec<String>>,
    /// The constant mass matrix of a separable H: a number (m·I), a list (a diagonal) or a
    /// symmetric positive definite matrix; entries are numbers or expressions in the
    /// parameters. Default 1 with a `potential`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<MassEntry>,
    /// V(q), with `mass`: H = ½pᵀM⁻¹p + V(q).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub potential: Option<String>,
    /// A general H(q, p), instead of `mass` and `potential`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hamiltonian: Option<String>,
    /// The damping (default none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<DampingEntry>,
    /// Named constants with their defaults; a request's `params` overrides them.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub parameters: BTreeMap<String, f64>,
    /// Named expressions in q and p to monitor, like the built-in systems' invariants.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub invariants: BTreeMap<String, String>,
    /// The bodies' positions, each 2-D (drawn in the vertical plane, the second coordinate up)
    /// or 3-D; expressions in the coordinates and parameters. Default: the first two or three
    /// coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub positions: Option<Vec<Vec<Entry>>>,
    /// Default initial positions (default zeros).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q0: Option<Vec<f64>>,
    /// Default initial momenta (default zeros).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p0: Option<Vec<f64>>,
}

/// The fields of a definition.
pub const DEFINITION_FIELDS: &[&str] = &[
    "name",
    "coordinates",
    "momenta",
    "mass",
    "potential",
    "hamiltonian",
    "damping",
    "parameters",
    "invariants",
    "positions",
    "q0",
    "p0",
];
const DAMPING_FIELDS: &[&str] = &["gamma", "epsilon", "matrix"];

/// An entry: a number or an expression.
fn entry(v: &Value, field: &Field) -> Result<Entry, ErrorDetail> {
    match v {
        Value::Number(_) => number(v, field).map(Entry::Number),
        Value::String(s) => Ok(Entry::Expression(s.clone())),
        _ => Err(wrong_type(field, "a number or an expression (a string)", v)),
    }
}

/// A matrix of entries, row by row.
fn matrix(v: &Value, field: &Field) -> Result<Vec<Vec<Entry>>, ErrorDetail> {
    list(v, field, "a matrix: a list of rows", |row, at| {
        list(row, at, "a row: a list of numbers or expressions", entry)
    })
}

/// A list of names.
fn names(v: &Value, field: &Field) -> Result<Vec<String>, ErrorDetail> {
    list(v, field, "a list of names", string)
}

/// `mass`: a number or expression, a list (diagonal), or a list of rows.
fn mass(v: &Value, field: &Field) -> Result<MassEntry, ErrorDetail> {
    match v {
        Value::Array(items) if items.first().is_some_and(Value::is_array) => {
            matrix(v, field).map(MassEntry::Matrix)
        }
        Value::Array(_) => list(v, field, "a list", entry).map(MassEntry::Diagonal),
        _ => entry(v, field)
            .map(MassEntry::Scalar)
            .map_err(|_| wrong_type(field, "a number, an expression, a list or a matrix", v)),
    }
}

/// `damping`: `{"gamma": …}` or `{"epsilon": …, "matrix": …}`.
fn damping(v: &Value, field: &Field) -> Result<DampingEntry, ErrorDetail> {
    let o = Obj::new(v, field.clone(), DAMPING_FIELDS)?;
    let rayleigh = o.has("epsilon") || o.has("matrix");
    if o.has("gamma") && rayleigh {
        return Err(CoreError::Either {
            field: o.field(if o.has("epsilon") {
                "epsilon"
            } else {
                "matrix"
            }),
            first: "gamma (conformal damping)",
            second: "epsilon and matrix (Rayleigh damping)",
        }
        .into());
    }
    if rayleigh {
        Ok(DampingEntry::Rayleigh {
            epsilon: o.required("epsilon", "the damping strength ε", entry)?,
            matrix: o.required("matrix", "the damping matrix D(q), row by row", matrix)?,
        })
    } else {
        Ok(DampingEntry::Conformal {
            gamma: o.required(
                "gamma",
                "γ for conformal damping, or epsilon and matrix for Rayleigh damping",
                entry,
            )?,
        })
    }
}

/// An object of numbers by name.
fn named_numbers(v: &Value, field: &Field) -> Result<BTreeMap<String, f64>, ErrorDetail> {
    let map = v
        .as_object()
        .ok_or_else(|| wrong_type(field, "an object of numbers by name", v))?;
    map.iter()
        .map(|(k, x)| Ok((k.clone(), number(x, &field.key(k))?)))
        .collect()
}

/// An object of expressions by name.
fn named_expressions(v: &Value, field: &Field) -> Result<BTreeMap<String, String>, ErrorDetail> {
    let map = v
        .as_object()
        .ok_or_else(|| wrong_type(field, "an object of expressions by name", v))?;
    map.iter()
        .map(|(k, x)| Ok((k.clone(), string(x, &field.key(k))?)))
        .collect()
}

/// Reads a system: an id, or a definition object.
pub fn read_system(v: &Value, field: &Field) -> Result<SystemRequest, ErrorDetail> {
    match v {
        Value::String(id) => Ok(SystemRequest::Id(id.clone())),
        Value::Object(_) => {
            SystemDefinition::read(v, field).map(|d| SystemRequest::Definition(Box::new(d)))
        }
        _ => Err(wrong_type(
            field,
            "a system id (a string) or a system definition (an object)",
            v,
        )),
    }
}

impl SystemDefinition {
    /// Reads a definition from JSON text (a body of `POST /api/v1/systems`).
    pub fn from_slice(bytes: &[u8]) -> Result<Self, ErrorDetail> {
        Self::read(&json::parse_json(bytes)?, &Field::default())
    }

    /// Reads a definition named `field`, naming the member at fault in every error.
    pub fn read(v: &Value, field: &Field) -> Result<Self, ErrorDetail> {
        let o = Obj::new(v, field.clone(), DEFINITION_FIELDS)?;
        Ok(SystemDefinition {
            name: o.optional("name", string)?,
            coordinates: o.required(
                "coordinates",
                "the coordinates' names, e.g. [\"x\", \"y\"]",
                names,
            )?,
            momenta: o.optional("momenta", names)?,
            mass: o.optional("mass", mass)?,
            potential: o.optional("potential", string)?,
            hamiltonian: o.optional("hamiltonian", string)?,
            damping: o.optional("damping", damping)?,
            parameters: o.optional("parameters", named_numbers)?.unwrap_or_default(),
            invariants: o
                .optional("invariants", named_expressions)?
                .unwrap_or_default(),
            positions: o.optional("positions", matrix)?,
            q0: o.optional("q0", numbers)?,
            p0: o.optional("p0", numbers)?,
        })
    }

    /// The definition's id: `sys-` and the first 16 hex digits of the SHA-256 of its canonical
    /// JSON.
    pub fn id(&self) -> String {
        // Serializing these types cannot fail: strings, finite numbers, maps with string keys.
        let canonical = serde_json::to_vec(self).unwrap_or_default();
        let digest = Sha256::digest(&canonical);
        let mut id = String::from("sys-");
        for byte in &digest[..8] {
            let _ = write!(id, "{byte:02x}");
        }
        id
    }

    /// The definition in core terms; `field` names it in errors (`system`, or nothing for a
    /// stored definition's body).
    pub fn to_core(&self, field: &Field) -> Result<CustomDefinition, CoreError> {
        let expression = |e: &Entry, at: Field| Expression {
            text: match e {
                // Debug writes the shortest text that reads back to the same f64.
                Entry::Number(x) => format!("{x:?}"),
                Entry::Expression(text) => text.clone(),
            },
            field: at,
        };
        let rows = |m: &[Vec<Entry>], at: &Field| -> Vec<Vec<Expression>> {
            m.iter()
                .enumerate()
                .map(|(i, row)| {
                    row.iter()
                        .enumerate()
                        .map(|(j, e)| expression(e, at.index(i).index(j)))
                        .collect()
                })
                .collect()
        };
        let text = |t: &str, at: Field| Expression {
            text: t.to_string(),
            field: at,
        };
        let energy = match (&self.potential, &self.hamiltonian) {
            (Some(_), Some(_)) => {
                return Err(CoreError::Either {
                    field: field.key("hamiltonian"),
                    first: "mass and potential (a separable H)",
                    second: "hamiltonian (a general H(q, p))",
                })
            }
            (None, None) => {
                return Err(CoreError::Missing {
                    field: field.key("potential"),
                    what: "the potential V(q) (with `mass`), or a general `hamiltonian` H(q, p)",
                })
            }
            (None, Some(h)) => {
                if self.mass.is_some() {
                    return Err(CoreError::Either {
                        field: field.key("mass"),
                        first: "mass and potential (a separable H)",
                        second: "hamiltonian (a general H(q, p), its kinetic energy included)",
                    });
                }
                Energy::General {
                    hamiltonian: text(h, field.key("hamiltonian")),
                }
            }
            (Some(v), None) => {
                let at = field.key("mass");
                let mass = match &self.mass {
                    None => Mass::Scalar(expression(&Entry::Number(1.0), at)),
                    Some(MassEntry::Scalar(e)) => Mass::Scalar(expression(e, at)),
                    Some(MassEntry::Diagonal(d)) => Mass::Diagonal(
                        d.iter()
                            .enumerate()
                            .map(|(i, e)| expression(e, at.index(i)))
                            .collect(),
                    ),
                    Some(MassEntry::Matrix(m)) => Mass::Matrix(rows(m, &at)),
                };
                Energy::Separable {
                    mass,
                    potential: text(v, field.key("potential")),
                }
            }
        };
        let at = field.key("damping");
        let damping = self.damping.as_ref().map(|d| match d {
            DampingEntry::Conformal { gamma } => Damping::Conformal {
                gamma: expression(gamma, at.key("gamma")),
            },
            DampingEntry::Rayleigh { epsilon, matrix } => Damping::Rayleigh {
                epsilon: expression(epsilon, at.key("epsilon")),
                matrix: rows(matrix, &at.key("matrix")),
            },
        });
        Ok(CustomDefinition {
            field: field.clone(),
            name: self.name.clone(),
            coordinates: self.coordinates.clone(),
            momenta: self.momenta.clone(),
            energy,
            damping,
            parameters: self
                .parameters
                .iter()
                .map(|(k, v)| (k.clone(), *v))
                .collect(),
            invariants: self
                .invariants
                .iter()
                .map(|(k, e)| (k.clone(), text(e, field.key("invariants").key(k))))
                .collect(),
            positions: self
                .positions
                .as_ref()
                .map(|p| rows(p, &field.key("positions"))),
            q0: self.q0.clone(),
            p0: self.p0.clone(),
        })
    }

    /// Checks the definition into a catalogue entry of its own id; `field` names it in errors.
    pub fn check(&self, field: &Field) -> Result<Arc<SystemInfo>, CoreError> {
        custom::define(self.to_core(field)?, &self.id())
    }

    /// The definition as the core names a system; `field` names it in errors.
    pub fn define(&self, field: &Field) -> Result<SystemRef, CoreError> {
        self.check(field).map(SystemRef::Defined)
    }
}

/// Stored definitions by id (the server's, the command line's `--systems-dir`): a request that
/// names one runs it as if it had sent the definition inline.
pub trait StoredSystems: Send + Sync {
    /// The stored definition `id` with its checked entry, if there is one.
    fn stored(&self, id: &str) -> Option<(SystemDefinition, Arc<SystemInfo>)>;
}

/// No stored definitions: built-in ids and inline definitions only.
pub struct NoStoredSystems;

impl StoredSystems for NoStoredSystems {
    fn stored(&self, _id: &str) -> Option<(SystemDefinition, Arc<SystemInfo>)> {
        None
    }
}

impl SystemRequest {
    /// The system in core terms: a stored definition's id as its checked entry, a built-in id
    /// as it is, a definition checked; errors name `field`.
    pub fn to_ref(
        &self,
        field: &Field,
        stored: &dyn StoredSystems,
    ) -> Result<SystemRef, CoreError> {
        match self {
            SystemRequest::Id(id) => Ok(match stored.stored(id) {
                Some((_, info)) => SystemRef::Defined(info),
                None => SystemRef::Id(id.clone()),
            }),
            SystemRequest::Definition(d) => d.define(field),
        }
    }

    /// The system with a stored definition's id replaced by the definition, as requests are
    /// identified (a sweep's digest) and sent to workers: the same whether the definition was
    /// named or sent.
    pub fn inlined(&self, stored: &dyn StoredSystems) -> SystemRequest {
        match self {
            SystemRequest::Id(id) => match stored.stored(id) {
                Some((definition, _)) => SystemRequest::Definition(Box::new(definition)),
                None => self.clone(),
            },
            SystemRequest::Definition(_) => self.clone(),
        }
    }
}

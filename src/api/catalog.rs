//! The system and method catalogues as the API and the command line publish them. These types
//! mirror the core's catalogue entries field for field (a test checks they serialize
//! identically) and carry the OpenAPI schemas.

use serde::Serialize;
use utoipa::ToSchema;

use crate::core::methods::{Kind, MethodId, MethodInfo, Requirement};
use crate::core::systems::{self, ParamKind, ParamSpec, SystemInfo};

/// A system of the catalogue.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct SystemEntry {
    /// Identifier used in requests.
    #[schema(example = "pendulum")]
    pub id: String,
    /// Human-readable name.
    pub name: String,
    /// What the system is, with its paper.
    pub description: String,
    /// Degrees of freedom (for N bodies: of the default case).
    pub degrees_of_freedom: usize,
    /// Coordinate charts the system is offered in; the first is the default and Cartesian
    /// (for a first-order ODE: the original variable), the coordinates of `q0` and `p0`.
    pub charts: Vec<ChartEntry>,
    /// Parameters.
    pub params: Vec<ParamEntry>,
    /// Default initial positions.
    pub q0: Vec<f64>,
    /// Default initial momenta.
    pub p0: Vec<f64>,
    /// Names of the invariants reported per sample.
    pub invariants: Vec<String>,
    /// Whether a closed-form solution gives the energy error.
    pub exact_solution: bool,
    /// Whether the damping is conformal (so `gamma` or `epsilon` = 2γ is accepted).
    pub conformal_damping: bool,
}

/// A coordinate chart of a system.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct ChartEntry {
    /// Identifier used in requests (`chart`).
    #[schema(example = "polar")]
    pub id: String,
    /// Names of the generalized coordinates, in state order.
    pub coordinates: Vec<String>,
    /// Whether H is separable with a constant mass matrix in this chart (the splitting methods
    /// need it).
    pub separable: bool,
    /// The chart's map to Cartesian coordinates and its Hamiltonian.
    pub description: String,
}

/// A parameter of a system.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct ParamEntry {
    /// Name used in `params`.
    pub name: String,
    /// What it means.
    pub description: String,
    /// Accepted values.
    #[serde(flatten)]
    pub kind: ParamKindEntry,
}

/// How a parameter is given and what values it accepts.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ParamKindEntry {
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
        default: String,
        /// The options.
        options: Vec<String>,
    },
    /// A list of positive numbers (N-body masses).
    NumberList {
        /// Default list.
        default: Vec<f64>,
        /// Lower bound (excluded) of every entry.
        min: f64,
        /// Upper bound of every entry.
        max: f64,
        /// Most entries allowed.
        max_len: usize,
    },
}

/// A method of the catalogue.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct MethodEntry {
    /// Identifier used in requests.
    #[schema(example = "modin_3s")]
    pub id: String,
    /// Human-readable name.
    pub name: String,
    /// Classical order (on smooth problems).
    pub order: u32,
    /// Work per step.
    pub kind: MethodKind,
    /// Symplectic when the damping is zero.
    pub symplectic: bool,
    /// Conformal symplectic under linear damping.
    pub conformal_symplectic: bool,
    /// Symmetric (self-adjoint), so it can be a triple-jump base.
    pub symmetric: bool,
    /// What the system must satisfy.
    pub requirements: Vec<MethodRequirement>,
    /// Where the method comes from.
    pub reference: CitationEntry,
    /// Group for display: geometric, conformal or baseline.
    pub group: String,
    /// Options the method accepts in the object form of a method choice.
    pub options: Vec<String>,
}

/// How much work a step takes.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum MethodKind {
    /// No equation solving.
    Explicit,
    /// A linear solve per step.
    LinearlyImplicit,
    /// A nonlinear (Newton) solve per step.
    Implicit,
    /// Adaptive step size control inside each step.
    Adaptive,
}

/// A structural requirement on the system.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum MethodRequirement {
    /// H = ½pᵀM⁻¹p + V(q) with constant M.
    SeparableConstantMass,
    /// D ∝ M (linear damping p' = … − 2γp).
    ConformalDamping,
    /// No damping (the system's damping rate is zero).
    Conservative,
}

/// Where a method comes from.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct CitationEntry {
    /// The paper or book.
    pub paper: String,
    /// Equation, algorithm or section.
    pub equation: String,
}

fn strings(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

impl From<&ParamSpec> for ParamEntry {
    fn from(p: &ParamSpec) -> Self {
        ParamEntry {
            name: p.name.to_string(),
            description: p.description.to_string(),
            kind: match &p.kind {
                ParamKind::Number {
                    default,
                    min,
                    min_exclusive,
                    max,
                } => ParamKindEntry::Number {
                    default: *default,
                    min: *min,
                    min_exclusive: *min_exclusive,
                    max: *max,
                },
                ParamKind::Choice { default, options } => ParamKindEntry::Choice {
                    default: default.to_string(),
                    options: strings(options),
                },
                ParamKind::NumberList {
                    default,
                    min,
                    max,
                    max_len,
                } => ParamKindEntry::NumberList {
                    default: default.clone(),
                    min: *min,
                    max: *max,
                    max_len: *max_len,
                },
            },
        }
    }
}

impl From<&SystemInfo> for SystemEntry {
    fn from(s: &SystemInfo) -> Self {
        SystemEntry {
            id: s.id.to_string(),
            name: s.name.to_string(),
            description: s.description.to_string(),
            degrees_of_freedom: s.degrees_of_freedom,
            charts: s
                .charts
                .iter()
                .map(|c| ChartEntry {
                    id: c.id.to_string(),
                    coordinates: strings(c.coordinates),
                    separable: c.separable,
                    description: c.description.to_string(),
                })
                .collect(),
            params: s.params.iter().map(ParamEntry::from).collect(),
            q0: s.q0.clone(),
            p0: s.p0.clone(),
            invariants: strings(s.invariants),
            exact_solution: s.exact_solution,
            conformal_damping: s.conformal_damping,
        }
    }
}

impl From<&MethodInfo> for MethodEntry {
    fn from(m: &MethodInfo) -> Self {
        MethodEntry {
            id: m.id.as_str().to_string(),
            name: m.name.to_string(),
            order: m.order,
            kind: match m.kind {
                Kind::Explicit => MethodKind::Explicit,
                Kind::LinearlyImplicit => MethodKind::LinearlyImplicit,
                Kind::Implicit => MethodKind::Implicit,
                Kind::Adaptive => MethodKind::Adaptive,
            },
            symplectic: m.symplectic,
            conformal_symplectic: m.conformal_symplectic,
            symmetric: m.symmetric,
            requirements: m
                .requirements
                .iter()
                .map(|r| match r {
                    Requirement::SeparableConstantMass => MethodRequirement::SeparableConstantMass,
                    Requirement::ConformalDamping => MethodRequirement::ConformalDamping,
                    Requirement::Conservative => MethodRequirement::Conservative,
                })
                .collect(),
            reference: CitationEntry {
                paper: m.reference.paper.to_string(),
                equation: m.reference.equation.to_string(),
            },
            group: m.group.to_string(),
            options: strings(m.options),
        }
    }
}

/// The system catalogue, in the core's order.
pub fn systems() -> Vec<SystemEntry> {
    systems::catalog().iter().map(SystemEntry::from).collect()
}

/// One system of the catalogue.
pub fn system(id: &str) -> Option<SystemEntry> {
    systems::info(id).ok().as_ref().map(SystemEntry::from)
}

/// The method catalogue, in the core's order.
pub fn methods() -> Vec<MethodEntry> {
    MethodId::ALL
        .iter()
        .map(|m| MethodEntry::from(&m.info()))
        .collect()
}

/// One method of the catalogue.
pub fn method(id: &str) -> Option<MethodEntry> {
    MethodId::parse(id).map(|m| MethodEntry::from(&m.info()))
}

#[cfg(test)]
mod tests {
    #[test]
    fn entries_serialize_like_the_core() {
        let core_systems = serde_json::to_value(crate::core::systems::catalog()).unwrap();
        assert_eq!(
            serde_json::to_value(super::systems()).unwrap(),
            core_systems
        );
        let core_methods: Vec<_> = crate::core::methods::MethodId::ALL
            .iter()
            .map(|m| m.info())
            .collect();
        assert_eq!(
            serde_json::to_value(super::methods()).unwrap(),
            serde_json::to_value(core_methods).unwrap()
        );
    }
}

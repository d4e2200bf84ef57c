//! Systems users define as text: damped Hamiltonian systems written as expressions, checked,
//! differentiated exactly and compiled (see [`crate::expr`]), then run by every method
//! whose requirements they meet, like the systems of the catalogue.
//!
//! A definition ([`CustomDefinition`]) names its coordinates (and momenta), gives either a
//! constant mass matrix and a potential V(q) — a separable H = ½pᵀM⁻¹p + V(q), which the
//! splittings need — or a general Hamiltonian H(q, p); optional damping, conformal
//! (p' = … − 2γp, paper 003's model) or Rayleigh (p' = … − ε D(q) M⁻¹p with D symmetric positive
//! semidefinite, paper 000's model); named parameters with defaults; invariants to monitor; the
//! bodies' positions for the pictures; default initial states.
//!
//! [`define`] checks a definition and builds its model ([`model::CustomModel`]) once: names,
//! expressions parsed against the names each may use, exact first and second derivatives, shapes,
//! and the numbers that can be checked with the default parameters (a mass matrix that is
//! positive definite, a damping matrix that is symmetric and positive semidefinite at sample
//! points). A run then compiles the model for its parameter values ([`model::CustomModel`]'s
//! `instantiate`), parameters folded into the machine code.
//! Its long runs then run whole stretches of splitting steps and Runge–Kutta steps compiled from
//! its programs (`flows::compiled`, given by `steps.rs`), with the generic steppers' bits.

mod buffers;
pub mod damping;
mod lanes;
mod mass;
pub mod model;
mod shapes;
mod steps;
pub mod system;

use std::borrow::Cow;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::{Builder, ChartInfo, ParamSpec, SystemInfo};
use crate::error::{CoreError, Field};
pub use model::CustomModel;
pub(in crate::systems) use steps::BuiltInSteps;

/// Most coordinates of a user-defined system.
pub const MAX_COORDINATES: usize = 32;
/// Most parameters, invariants or bodies of a user-defined system.
pub const MAX_NAMES: usize = 64;

/// An expression as a definition gives it, with the field that holds it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Expression {
    /// The text.
    pub text: String,
    /// Where it is, e.g. `system.damping.matrix[1][0]`.
    pub field: Field,
}

/// A constant mass matrix, entries in the parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Mass {
    /// m·I.
    Scalar(Expression),
    /// A diagonal.
    Diagonal(Vec<Expression>),
    /// A symmetric positive definite matrix, row by row.
    Matrix(Vec<Vec<Expression>>),
}

/// The energy: separable with a constant mass, or a general Hamiltonian.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Energy {
    /// H = ½ pᵀM⁻¹p + V(q).
    Separable {
        /// M.
        mass: Mass,
        /// V(q).
        potential: Expression,
    },
    /// H(q, p).
    General {
        /// H.
        hamiltonian: Expression,
    },
}

/// The damping.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Damping {
    /// p' = … − 2γp.
    Conformal {
        /// γ (in the parameters).
        gamma: Expression,
    },
    /// p' = … − ε D(q) M⁻¹p.
    Rayleigh {
        /// ε (in the parameters).
        epsilon: Expression,
        /// D(q), row by row.
        matrix: Vec<Vec<Expression>>,
    },
}

/// A user's system, as a request or a stored definition gives it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CustomDefinition {
    /// Where the definition is in the request (`system`).
    pub field: Field,
    /// A name for people.
    pub name: Option<String>,
    /// The generalized coordinates' names.
    pub coordinates: Vec<String>,
    /// The momenta's names (default `p_<coordinate>`).
    pub momenta: Option<Vec<String>>,
    /// The energy.
    pub energy: Energy,
    /// The damping, if any.
    pub damping: Option<Damping>,
    /// Named constants with their defaults, in the order given.
    pub parameters: Vec<(String, f64)>,
    /// Named expressions in q and p to monitor.
    pub invariants: Vec<(String, Expression)>,
    /// The bodies' positions (2-D or 3-D each), expressions in q.
    pub positions: Option<Vec<Vec<Expression>>>,
    /// Default initial positions (zeros when absent).
    pub q0: Option<Vec<f64>>,
    /// Default initial momenta (zeros when absent).
    pub p0: Option<Vec<f64>>,
}

/// The form a definition's damping takes once checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum DampingKind {
    /// Undamped.
    None,
    /// Conformal, p' = … − 2γp.
    Conformal,
    /// Rayleigh with D(q) an orthogonal projector and M = mI: the damping decays the momentum in
    /// a subspace at one rate (the elastic pendulum's spring damping).
    RayleighProjector,
    /// Rayleigh with a general D(q).
    Rayleigh,
}

/// What a definition is, derived from it (by [`facts`], which adds the methods
/// that apply).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Facts {
    /// Degrees of freedom.
    pub dimension: usize,
    /// H = ½pᵀM⁻¹p + V(q) with constant M.
    pub separable: bool,
    /// The damping's form.
    pub damping: DampingKind,
    /// The methods whose requirements the system meets (compositions with any base that does).
    #[cfg_attr(feature = "openapi", schema(value_type = Vec<String>))]
    pub methods: Vec<&'static str>,
    /// Whether the energy or the damping depends on the time `t` (a driven system, run in
    /// extended phase space); absent when not.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub time_dependent: bool,
}

/// The chart of a user-defined separable system: its own coordinates.
const SEPARABLE_CHART: ChartInfo = ChartInfo::new(
    "cartesian",
    &[],
    true,
    "The definition's own coordinates (see its `coordinates`).",
);
/// The chart of a user-defined general Hamiltonian.
const GENERAL_CHART: ChartInfo = ChartInfo::new(
    "cartesian",
    &[],
    false,
    "The definition's own coordinates (see its `coordinates`); H(q, p) is not separable.",
);

/// Checks a definition and builds its model; the catalogue entry it runs under, with `id`.
pub fn define(definition: CustomDefinition, id: &str) -> Result<Arc<SystemInfo>, CoreError> {
    let model = CustomModel::new(definition)?;
    let (structure, _) = model.structure_at_defaults();
    let def = model.definition();
    let n = model.dimension();
    let params = def
        .parameters
        .iter()
        .map(|(name, default)| ParamSpec {
            name: Cow::Owned(name.clone()),
            description: Cow::Borrowed("A parameter of the definition."),
            kind: super::ParamKind::Number {
                default: *default,
                min: f64::MIN,
                min_exclusive: false,
                max: f64::MAX,
            },
        })
        .collect();
    let name = def
        .name
        .clone()
        .unwrap_or_else(|| "A user-defined system".into());
    let info = SystemInfo {
        id: Cow::Owned(id.to_string()),
        name: Cow::Owned(name),
        description: Cow::Borrowed(
            "A damped Hamiltonian system defined by its user (see its definition).",
        ),
        degrees_of_freedom: n,
        charts: vec![if structure.separable_constant_mass {
            SEPARABLE_CHART
        } else {
            GENERAL_CHART
        }],
        params,
        q0: def.q0.clone().unwrap_or_else(|| vec![0.0; n]),
        p0: def.p0.clone().unwrap_or_else(|| vec![0.0; n]),
        invariants: def
            .invariants
            .iter()
            .map(|(name, _)| Cow::Owned(name.clone()))
            .collect(),
        exact_solution: false,
        // `epsilon` = 2γ is accepted where the damping's γ is the parameter named `gamma`.
        conformal_damping: matches!(&def.damping, Some(Damping::Conformal { gamma })
            if gamma.text.trim() == "gamma"
                && def.parameters.iter().any(|(name, _)| name == "gamma")),
        world: super::World::Line,
        build: Builder::Custom(Arc::new(model)),
    };
    Ok(Arc::new(info))
}

/// What a typed-in system's definition is, at its default parameter values: its dimension,
/// structure and damping, and the methods that apply (for a driven system, those that can take
/// the time t).
pub fn facts(model: &CustomModel) -> Facts {
    use crate::methods::{applicable, build, Method, MethodId};
    let (structure, rate) = model.structure_at_defaults();
    let time_dependent = model.time_dependent();
    let mut methods = applicable(structure, rate);
    if time_dependent {
        methods.retain(|id| {
            MethodId::parse(id).is_some_and(|m| build::no_time(&Method::new(m), rate).is_none())
        });
    }
    Facts {
        dimension: model.dimension(),
        separable: structure.separable_constant_mass,
        damping: model.damping_kind(),
        methods,
        time_dependent,
    }
}

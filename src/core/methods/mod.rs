//! The method catalogue: ids with their metadata (order, kind, geometric properties,
//! requirements, citation), parsing of method choices, and construction of a stepper for a
//! concrete system. One file per family beside this one.

pub mod composition;
pub mod conformal;
pub mod implicit;
pub mod reference;
pub mod rowlands;
pub mod runge_kutta;
pub mod splitting;
pub mod symplectic_euler;

use nalgebra::allocator::Allocator;
use nalgebra::DefaultAllocator;
use serde::{Deserialize, Serialize};

use crate::core::error::{CoreError, StepError};
use crate::core::flows::Tangent;
use crate::core::run::Stepper;
use crate::core::system::{MechanicalSystem, State, Structure};

use composition::{Composed, Scheme};
use conformal::Csv2;
use implicit::{ImplicitMidpoint, MidpointField};
use reference::Reference;
use rowlands::{Processor, Rowlands};
use runge_kutta::{InnerRk, MomentumRk, RungeKutta, Tableau};
use splitting::Splitting;
use symplectic_euler::{GeneralSymplecticEuler, Variant};

/// Every method the core offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum MethodId {
    /// Forward Euler.
    #[serde(rename = "explicit_euler")]
    ExplicitEuler,
    /// Heun's (explicit trapezoidal) method.
    #[serde(rename = "heun")]
    Heun,
    /// Kutta's third-order method.
    #[serde(rename = "rk3")]
    Rk3,
    /// Classical RK4.
    #[serde(rename = "rk4")]
    Rk4,
    /// Implicit midpoint rule (Newton).
    #[serde(rename = "implicit_midpoint")]
    ImplicitMidpoint,
    /// Symplectic Euler (kick then drift).
    #[serde(rename = "symplectic_euler")]
    SymplecticEuler,
    /// Adjoint symplectic Euler (drift then kick).
    #[serde(rename = "symplectic_euler_adjoint")]
    SymplecticEulerAdjoint,
    /// Störmer–Verlet, drift–kick–drift.
    #[serde(rename = "position_verlet")]
    PositionVerlet,
    /// Störmer–Verlet, kick–drift–kick.
    #[serde(rename = "velocity_verlet")]
    VelocityVerlet,
    /// Paper 000 Algorithm 3.1.
    #[serde(rename = "modin_3s")]
    Modin3s,
    /// Paper 000 Algorithm 3.2.
    #[serde(rename = "modin_2s")]
    Modin2s,
    /// Paper 000 Algorithm 3.3.
    #[serde(rename = "modin_rks")]
    ModinRks,
    /// Paper 003 eq. (2.12).
    #[serde(rename = "csv1")]
    Csv1,
    /// Paper 003 eq. (2.16).
    #[serde(rename = "csv2")]
    Csv2,
    /// Paper 003 eq. (2.3).
    #[serde(rename = "cimp")]
    Cimp,
    /// Fourth-order triple-jump composition of a symmetric second-order method.
    #[serde(rename = "triple_jump")]
    TripleJump,
    /// Suzuki's fourth-order five-stage composition.
    #[serde(rename = "suzuki_4")]
    Suzuki4,
    /// Yoshida's sixth-order seven-stage composition.
    #[serde(rename = "yoshida_6")]
    Yoshida6,
    /// Kahan and Li's sixth-order nine-stage composition.
    #[serde(rename = "kahan_li_6")]
    KahanLi6,
    /// Kahan and Li's eighth-order 17-stage composition.
    #[serde(rename = "kahan_li_8")]
    KahanLi8,
    /// Rowlands time stepping: Störmer–Verlet on a modified potential with processing (paper 001
    /// eqs. 30–37).
    #[serde(rename = "rowlands")]
    Rowlands,
    /// Adaptive DOP853 at a tight tolerance.
    #[serde(rename = "reference")]
    Reference,
}

/// How much work a step takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Requirement {
    /// H = ½pᵀM⁻¹p + V(q) with constant M.
    SeparableConstantMass,
    /// D ∝ M (linear damping p' = … − 2γp).
    ConformalDamping,
    /// No damping: the system's damping rate is zero.
    Conservative,
}

impl Requirement {
    /// The requirement in words, for error messages.
    pub fn describe(self) -> &'static str {
        match self {
            Requirement::SeparableConstantMass => {
                "a separable Hamiltonian with a constant mass matrix (its drift and kick flows must be exact)"
            }
            Requirement::ConformalDamping => "conformal damping D ∝ M (p' = −∇V − 2γp)",
            Requirement::Conservative => {
                "no damping (its modified potential and processors are derived for a conservative Hamiltonian; set the damping to 0)"
            }
        }
    }

    /// Whether a system with this structure and damping rate meets the requirement.
    pub fn met_by(self, s: Structure, damping_rate: f64) -> bool {
        match self {
            Requirement::SeparableConstantMass => s.separable_constant_mass,
            Requirement::ConformalDamping => s.conformal_damping,
            Requirement::Conservative => damping_rate == 0.0,
        }
    }
}

/// Where a method comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Citation {
    /// The paper or book.
    pub paper: &'static str,
    /// Equation, algorithm or section.
    pub equation: &'static str,
}

/// A catalogue entry for a method.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MethodInfo {
    /// Identifier used in requests.
    pub id: MethodId,
    /// Human-readable name.
    pub name: &'static str,
    /// Classical order (on smooth problems).
    pub order: u32,
    /// Work per step.
    pub kind: Kind,
    /// Symplectic when the damping is zero.
    pub symplectic: bool,
    /// Conformal symplectic under linear damping (det ∂Φ/∂z = e^{−2γh}·per dof).
    pub conformal_symplectic: bool,
    /// Symmetric (self-adjoint), so it can be a triple-jump base.
    pub symmetric: bool,
    /// What the system must satisfy.
    pub requirements: &'static [Requirement],
    /// Where it comes from.
    pub reference: Citation,
    /// Group for display: geometric, conformal or baseline.
    pub group: &'static str,
    /// Options the method accepts in the object form of a method choice.
    pub options: &'static [&'static str],
}

const SEP: &[Requirement] = &[Requirement::SeparableConstantMass];
const SEP_CONSERVATIVE: &[Requirement] = &[
    Requirement::SeparableConstantMass,
    Requirement::Conservative,
];
const SEP_CONF: &[Requirement] = &[
    Requirement::SeparableConstantMass,
    Requirement::ConformalDamping,
];
const HNW: &str = "Hairer, Nørsett, Wanner: Solving Ordinary Differential Equations I";
const GNI: &str = "Hairer, Lubich, Wanner: Geometric Numerical Integration";
const MODIN: &str = "000 Modin & Söderlind 2011";
const FLOYD: &str = "003 Floyd 2014";
const TAKACS: &str = "001 Takács & Fülöp";

/// A catalogue row: name, order, kind, symplectic, conformal symplectic, symmetric,
/// requirements, citation, group, options (the fields of [`MethodInfo`] after the id).
type InfoRow = (
    &'static str,
    u32,
    Kind,
    bool,
    bool,
    bool,
    &'static [Requirement],
    Citation,
    &'static str,
    &'static [&'static str],
);

impl MethodId {
    /// All methods, in catalogue order.
    pub const ALL: [MethodId; 22] = [
        MethodId::Modin3s,
        MethodId::Modin2s,
        MethodId::ModinRks,
        MethodId::Csv1,
        MethodId::Csv2,
        MethodId::Cimp,
        MethodId::TripleJump,
        MethodId::Suzuki4,
        MethodId::Yoshida6,
        MethodId::KahanLi6,
        MethodId::KahanLi8,
        MethodId::Rowlands,
        MethodId::SymplecticEuler,
        MethodId::SymplecticEulerAdjoint,
        MethodId::PositionVerlet,
        MethodId::VelocityVerlet,
        MethodId::ImplicitMidpoint,
        MethodId::ExplicitEuler,
        MethodId::Heun,
        MethodId::Rk3,
        MethodId::Rk4,
        MethodId::Reference,
    ];

    /// The id as used in requests.
    pub fn as_str(self) -> &'static str {
        self.info().name_id()
    }

    /// The composition scheme of a composition method (`triple_jump`, `suzuki_4`, …).
    pub fn scheme(self) -> Option<Scheme> {
        Some(match self {
            MethodId::TripleJump => Scheme::TripleJump,
            MethodId::Suzuki4 => Scheme::Suzuki4,
            MethodId::Yoshida6 => Scheme::Yoshida6,
            MethodId::KahanLi6 => Scheme::KahanLi6,
            MethodId::KahanLi8 => Scheme::KahanLi8,
            _ => return None,
        })
    }

    /// Parses a request id.
    pub fn parse(s: &str) -> Option<MethodId> {
        MethodId::ALL.into_iter().find(|m| m.as_str() == s)
    }

    /// The method's metadata.
    pub fn info(self) -> MethodInfo {
        use Kind::*;
        use MethodId as M;
        let cite = |paper, equation| Citation { paper, equation };
        let (
            name,
            order,
            kind,
            symplectic,
            conformal,
            symmetric,
            requirements,
            reference,
            group,
            options,
        ): InfoRow = match self {
            M::ExplicitEuler => (
                "Explicit Euler",
                1,
                Explicit,
                false,
                false,
                false,
                &[],
                cite(HNW, "Sec. I.7"),
                "baseline",
                &[],
            ),
            M::Heun => (
                "Heun (explicit trapezoid)",
                2,
                Explicit,
                false,
                false,
                false,
                &[],
                cite(MODIN, "footnote 1"),
                "baseline",
                &[],
            ),
            M::Rk3 => (
                "Kutta's third order",
                3,
                Explicit,
                false,
                false,
                false,
                &[],
                cite(HNW, "Table II.1.1"),
                "baseline",
                &[],
            ),
            M::Rk4 => (
                "Classical Runge–Kutta 4",
                4,
                Explicit,
                false,
                false,
                false,
                &[],
                cite(HNW, "Table II.1.2"),
                "baseline",
                &[],
            ),
            M::ImplicitMidpoint => (
                "Implicit midpoint",
                2,
                Implicit,
                true,
                false,
                true,
                &[],
                cite(GNI, "Sec. II.1.1"),
                "baseline",
                &[],
            ),
            M::SymplecticEuler => (
                "Symplectic Euler",
                1,
                Explicit,
                true,
                false,
                false,
                &[],
                cite(TAKACS, "eq. (42)"),
                "baseline",
                &[],
            ),
            M::SymplecticEulerAdjoint => (
                "Symplectic Euler (adjoint)",
                1,
                Explicit,
                true,
                false,
                false,
                &[],
                cite(TAKACS, "footnote 3 (the adjoint of eqs. 42–43)"),
                "baseline",
                &[],
            ),
            M::PositionVerlet => (
                "Störmer–Verlet (drift–kick–drift)",
                2,
                Explicit,
                true,
                false,
                true,
                SEP,
                cite(GNI, "Sec. I.1.4"),
                "baseline",
                &[],
            ),
            M::VelocityVerlet => (
                "Störmer–Verlet (kick–drift–kick)",
                2,
                Explicit,
                true,
                false,
                true,
                SEP,
                cite(GNI, "Sec. I.1.4"),
                "baseline",
                &[],
            ),
            M::Modin3s => (
                "Three-term splitting (3S)",
                2,
                Explicit,
                true,
                true,
                true,
                SEP,
                cite(MODIN, "Algorithm 3.1"),
                "geometric",
                &[],
            ),
            M::Modin2s => (
                "Two-term splitting (2S)",
                2,
                Explicit,
                true,
                true,
                true,
                SEP,
                cite(MODIN, "Algorithm 3.2"),
                "geometric",
                &[],
            ),
            M::ModinRks => (
                "Runge–Kutta splitting (RKS)",
                2,
                Explicit,
                true,
                false,
                false,
                SEP,
                cite(MODIN, "Algorithm 3.3"),
                "geometric",
                &["inner"],
            ),
            M::Csv1 => (
                "Conformal Störmer–Verlet 1 (CSV1)",
                2,
                Explicit,
                true,
                true,
                true,
                SEP_CONF,
                cite(FLOYD, "eq. (2.12)"),
                "conformal",
                &[],
            ),
            M::Csv2 => (
                "Conformal Störmer–Verlet 2 (CSV2)",
                2,
                Explicit,
                true,
                true,
                true,
                SEP_CONF,
                cite(FLOYD, "eq. (2.16)"),
                "conformal",
                &[],
            ),
            M::Cimp => (
                "Conformal implicit midpoint (CIMP)",
                2,
                Implicit,
                true,
                true,
                true,
                SEP_CONF,
                cite(FLOYD, "eq. (2.3)"),
                "conformal",
                &[],
            ),
            M::TripleJump => (
                "Triple-jump composition (order 4)",
                4,
                Explicit,
                true,
                true,
                true,
                &[],
                cite(GNI, "Sec. II.4, eq. (4.4)"),
                "geometric",
                &["base"],
            ),
            M::Suzuki4 => (
                "Suzuki fractal composition (order 4, 5 stages)",
                4,
                Explicit,
                true,
                true,
                true,
                &[],
                cite("Suzuki 1990; HLW", "Sec. II.4"),
                "geometric",
                &["base"],
            ),
            M::Yoshida6 => (
                "Yoshida composition (order 6, 7 stages)",
                6,
                Explicit,
                true,
                true,
                true,
                &[],
                cite("Yoshida 1990, solution A; HLW", "Sec. V.3.2"),
                "geometric",
                &["base"],
            ),
            M::KahanLi6 => (
                "Kahan–Li composition (order 6, 9 stages)",
                6,
                Explicit,
                true,
                true,
                true,
                &[],
                cite("Kahan & Li 1997; HLW", "Sec. V.3.2"),
                "geometric",
                &["base"],
            ),
            M::KahanLi8 => (
                "Kahan–Li composition (order 8, 17 stages)",
                8,
                Explicit,
                true,
                true,
                true,
                &[],
                cite("Kahan & Li 1997; HLW", "Sec. V.3.2"),
                "geometric",
                &["base"],
            ),
            M::Rowlands => (
                "Rowlands time stepping (processed Störmer–Verlet, effective order 4)",
                4,
                Explicit,
                true,
                false,
                true,
                SEP_CONSERVATIVE,
                cite(TAKACS, "eqs. (30)–(37), (32)–(33) with h²/12"),
                "geometric",
                &["processor"],
            ),
            M::Reference => (
                "Reference: adaptive DOP853",
                8,
                Adaptive,
                false,
                false,
                false,
                &[],
                cite(HNW, "Sec. II.10"),
                "baseline",
                &["tolerance"],
            ),
        };
        MethodInfo {
            id: self,
            name,
            order,
            kind,
            symplectic,
            conformal_symplectic: conformal,
            symmetric,
            requirements,
            reference,
            group,
            options,
        }
    }
}

impl MethodInfo {
    fn name_id(&self) -> &'static str {
        match self.id {
            MethodId::ExplicitEuler => "explicit_euler",
            MethodId::Heun => "heun",
            MethodId::Rk3 => "rk3",
            MethodId::Rk4 => "rk4",
            MethodId::ImplicitMidpoint => "implicit_midpoint",
            MethodId::SymplecticEuler => "symplectic_euler",
            MethodId::SymplecticEulerAdjoint => "symplectic_euler_adjoint",
            MethodId::PositionVerlet => "position_verlet",
            MethodId::VelocityVerlet => "velocity_verlet",
            MethodId::Modin3s => "modin_3s",
            MethodId::Modin2s => "modin_2s",
            MethodId::ModinRks => "modin_rks",
            MethodId::Csv1 => "csv1",
            MethodId::Csv2 => "csv2",
            MethodId::Cimp => "cimp",
            MethodId::TripleJump => "triple_jump",
            MethodId::Suzuki4 => "suzuki_4",
            MethodId::Yoshida6 => "yoshida_6",
            MethodId::KahanLi6 => "kahan_li_6",
            MethodId::KahanLi8 => "kahan_li_8",
            MethodId::Rowlands => "rowlands",
            MethodId::Reference => "reference",
        }
    }
}

/// Inner methods modin_rks accepts.
/// (At least second order, so that the splitting stays second order; paper 000 Sec. 3.)
pub const RKS_INNER: &[MethodId] = &[
    MethodId::Heun,
    MethodId::Rk3,
    MethodId::Rk4,
    MethodId::ImplicitMidpoint,
];
/// Bases the compositions (triple_jump, suzuki_4, yoshida_6, kahan_li_6, kahan_li_8) accept:
/// the symmetric second-order methods.
pub const COMPOSITION_BASES: &[MethodId] = &[
    MethodId::Modin3s,
    MethodId::Modin2s,
    MethodId::Csv1,
    MethodId::Csv2,
    MethodId::Cimp,
    MethodId::PositionVerlet,
    MethodId::VelocityVerlet,
    MethodId::ImplicitMidpoint,
];

/// A method as a request gives it: a bare id or an object with options.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(untagged)]
pub enum MethodInput {
    /// `"modin_3s"`.
    Id(String),
    /// `{"id": "modin_rks", "inner": "rk4"}`.
    Object {
        /// The method id.
        id: String,
        /// Inner Runge–Kutta method of modin_rks.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        inner: Option<String>,
        /// Base method of a composition (triple_jump, suzuki_4, …).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        base: Option<String>,
        /// Tolerance of reference.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        tolerance: Option<f64>,
        /// Processor of rowlands (none, original, cheap).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        processor: Option<String>,
    },
}

/// A validated method choice.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MethodChoice {
    /// The method.
    pub id: MethodId,
    /// Inner method (modin_rks).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inner: Option<MethodId>,
    /// Base method (a composition: triple_jump, suzuki_4, …).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub base: Option<MethodId>,
    /// Tolerance (reference).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Processor (rowlands).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub processor: Option<Processor>,
}

impl MethodChoice {
    /// A choice with default options.
    pub fn new(id: MethodId) -> Self {
        let mut choice = MethodChoice {
            id,
            inner: None,
            base: None,
            tolerance: None,
            processor: None,
        };
        choice.fill_defaults();
        choice
    }

    /// A triple jump of `base`.
    pub fn triple_jump(base: MethodId) -> Self {
        Self::composition(MethodId::TripleJump, base)
    }

    /// The composition `id` (triple_jump, suzuki_4, …) of `base`.
    pub fn composition(id: MethodId, base: MethodId) -> Self {
        MethodChoice {
            id,
            inner: None,
            base: Some(base),
            tolerance: None,
            processor: None,
        }
    }

    /// modin_rks with `inner`.
    pub fn rks(inner: MethodId) -> Self {
        MethodChoice {
            id: MethodId::ModinRks,
            inner: Some(inner),
            base: None,
            tolerance: None,
            processor: None,
        }
    }

    /// rowlands with `processor`.
    pub fn rowlands(processor: Processor) -> Self {
        MethodChoice {
            id: MethodId::Rowlands,
            inner: None,
            base: None,
            tolerance: None,
            processor: Some(processor),
        }
    }

    fn fill_defaults(&mut self) {
        match self.id {
            MethodId::ModinRks => self.inner = self.inner.or(Some(MethodId::Heun)),
            MethodId::Reference => {
                self.tolerance = self.tolerance.or(Some(reference::DEFAULT_TOLERANCE))
            }
            MethodId::Rowlands => self.processor = self.processor.or(Some(Processor::DEFAULT)),
            id if id.scheme().is_some() => self.base = self.base.or(Some(MethodId::Modin3s)),
            _ => {}
        }
    }

    /// A label that tells runs apart: `modin_rks(rk4)`, `triple_jump(csv1)`, `reference(1e-12)`,
    /// `rowlands(cheap)`.
    pub fn label(&self) -> String {
        let id = self.id.as_str();
        if let Some(p) = self.processor {
            return format!("{id}({})", p.as_str());
        }
        match (self.inner, self.base, self.tolerance) {
            (Some(i), _, _) => format!("{id}({})", i.as_str()),
            (_, Some(b), _) => format!("{id}({})", b.as_str()),
            (_, _, Some(t)) if t != reference::DEFAULT_TOLERANCE => format!("{id}({t:e})"),
            _ => id.to_string(),
        }
    }

    /// Parses and checks a request's method; `field` names it in errors (e.g. `methods[1]`).
    pub fn parse(input: &MethodInput, field: &str) -> Result<Self, CoreError> {
        let lookup = |s: &str, f: &str| {
            MethodId::parse(s).ok_or_else(|| {
                let known: Vec<&str> = MethodId::ALL.iter().map(|m| m.as_str()).collect();
                CoreError::invalid(
                    f,
                    format!("unknown method `{s}`; known: {}", known.join(", ")),
                )
            })
        };
        let mut choice = match input {
            MethodInput::Id(id) => MethodChoice {
                id: lookup(id, field)?,
                inner: None,
                base: None,
                tolerance: None,
                processor: None,
            },
            MethodInput::Object {
                id,
                inner,
                base,
                tolerance,
                processor,
            } => {
                let id = lookup(id, &format!("{field}.id"))?;
                let allowed = id.info().options;
                for (name, present) in [
                    ("inner", inner.is_some()),
                    ("base", base.is_some()),
                    ("tolerance", tolerance.is_some()),
                    ("processor", processor.is_some()),
                ] {
                    if present && !allowed.contains(&name) {
                        return Err(CoreError::invalid(
                            format!("{field}.{name}"),
                            format!("`{}` takes no option `{name}`", id.as_str()),
                        ));
                    }
                }
                let inner = inner
                    .as_deref()
                    .map(|s| lookup(s, &format!("{field}.inner")))
                    .transpose()?;
                let base = base
                    .as_deref()
                    .map(|s| lookup(s, &format!("{field}.base")))
                    .transpose()?;
                let processor = processor
                    .as_deref()
                    .map(|s| {
                        Processor::parse(s).ok_or_else(|| {
                            let known: Vec<&str> =
                                Processor::ALL.iter().map(|p| p.as_str()).collect();
                            CoreError::invalid(
                                format!("{field}.processor"),
                                format!("unknown processor `{s}`; known: {}", known.join(", ")),
                            )
                        })
                    })
                    .transpose()?;
                MethodChoice {
                    id,
                    inner,
                    base,
                    tolerance: *tolerance,
                    processor,
                }
            }
        };
        choice.fill_defaults();
        if let Some(inner) = choice.inner {
            if !RKS_INNER.contains(&inner) {
                return Err(CoreError::invalid(
                    format!("{field}.inner"),
                    format!(
                        "modin_rks needs a Runge–Kutta inner method: one of {}",
                        names(RKS_INNER)
                    ),
                ));
            }
        }
        if let Some(base) = choice.base {
            if !COMPOSITION_BASES.contains(&base) {
                return Err(CoreError::invalid(
                    format!("{field}.base"),
                    format!(
                        "a composition needs a symmetric second-order base: one of {}",
                        names(COMPOSITION_BASES)
                    ),
                ));
            }
        }
        if let Some(t) = choice.tolerance {
            if !(t.is_finite() && (1e-14..=1e-2).contains(&t)) {
                return Err(CoreError::invalid(
                    format!("{field}.tolerance"),
                    "must lie in [1e-14, 1e-2]",
                ));
            }
        }
        Ok(choice)
    }

    /// The requirements of this choice (a composition inherits its base's).
    pub fn requirements(&self) -> &'static [Requirement] {
        match (self.id.scheme(), self.base) {
            (Some(_), Some(base)) => base.info().requirements,
            _ => self.id.info().requirements,
        }
    }

    /// The order of this choice: the method's, except that rowlands without processing is its
    /// second-order kernel.
    pub fn order(&self) -> u32 {
        match (self.id, self.processor) {
            (MethodId::Rowlands, Some(Processor::None)) => 2,
            (id, _) => id.info().order,
        }
    }

    /// Checks the requirements against a system with this structure and damping rate
    /// ([`MechanicalSystem::damping_rate`]); the error names the first unmet one.
    pub fn check(
        &self,
        system_id: &str,
        structure: Structure,
        damping_rate: f64,
    ) -> Result<(), CoreError> {
        match self
            .requirements()
            .iter()
            .find(|r| !r.met_by(structure, damping_rate))
        {
            None => Ok(()),
            Some(r) => Err(CoreError::Unmet {
                method: self.label(),
                system: system_id.to_string(),
                requirement: r.describe().to_string(),
            }),
        }
    }
}

fn names(ids: &[MethodId]) -> String {
    ids.iter()
        .map(|m| m.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

fn tableau(id: MethodId) -> Option<&'static Tableau> {
    match id {
        MethodId::ExplicitEuler => Some(&runge_kutta::EXPLICIT_EULER),
        MethodId::Heun => Some(&runge_kutta::HEUN),
        MethodId::Rk3 => Some(&runge_kutta::RK3),
        MethodId::Rk4 => Some(&runge_kutta::RK4),
        _ => None,
    }
}

fn sequence(id: MethodId) -> Option<splitting::Sequence> {
    Some(match id {
        MethodId::Modin3s => splitting::MODIN_3S,
        MethodId::Modin2s => splitting::MODIN_2S,
        MethodId::ModinRks => splitting::MODIN_RKS,
        MethodId::Csv1 => splitting::CSV1,
        MethodId::SymplecticEuler => splitting::SYMPLECTIC_EULER,
        MethodId::SymplecticEulerAdjoint => splitting::SYMPLECTIC_EULER_ADJOINT,
        MethodId::PositionVerlet => splitting::POSITION_VERLET,
        MethodId::VelocityVerlet => splitting::VELOCITY_VERLET,
        _ => return None,
    })
}

/// A stepper for a concrete system, chosen at run time. Matching on it once per run (see
/// [`with_stepper!`](crate::with_stepper)) runs the driver monomorphised for the concrete stepper.
pub enum AnyStepper<S: MechanicalSystem>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    /// A splitting, or a composition of splittings.
    Splitting(Splitting<S>),
    /// An explicit Runge–Kutta method.
    RungeKutta(RungeKutta<S::Dim>),
    /// implicit_midpoint or cimp.
    Midpoint(ImplicitMidpoint<S>),
    /// csv2.
    Csv2(Csv2<S>),
    /// A composition of implicit_midpoint or cimp.
    ComposedMidpoint(Composed<ImplicitMidpoint<S>>),
    /// A composition of csv2.
    ComposedCsv2(Composed<Csv2<S>>),
    /// Symplectic Euler or its adjoint on a non-separable Hamiltonian.
    GeneralSymplecticEuler(GeneralSymplecticEuler<S>),
    /// The adaptive reference.
    Reference(Reference),
    /// rowlands.
    Rowlands(Rowlands<S>),
}

/// Runs `$body` with `$st` bound to the concrete stepper inside an [`AnyStepper`].
#[macro_export]
macro_rules! with_stepper {
    ($any:expr, $st:ident => $body:expr) => {
        match $any {
            $crate::core::methods::AnyStepper::Splitting($st) => $body,
            $crate::core::methods::AnyStepper::RungeKutta($st) => $body,
            $crate::core::methods::AnyStepper::Midpoint($st) => $body,
            $crate::core::methods::AnyStepper::Csv2($st) => $body,
            $crate::core::methods::AnyStepper::ComposedMidpoint($st) => $body,
            $crate::core::methods::AnyStepper::ComposedCsv2($st) => $body,
            $crate::core::methods::AnyStepper::GeneralSymplecticEuler($st) => $body,
            $crate::core::methods::AnyStepper::Reference($st) => $body,
            $crate::core::methods::AnyStepper::Rowlands($st) => $body,
        }
    };
}

impl<S: MechanicalSystem> Stepper<S> for AnyStepper<S>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    fn step(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) -> Result<(), StepError> {
        with_stepper!(self, st => st.step(sys, z, h))
    }
    fn force_evaluations(&self) -> u64 {
        with_stepper!(self, st => Stepper::<S>::force_evaluations(st))
    }
    fn check_interval(&self) -> u64 {
        with_stepper!(self, st => Stepper::<S>::check_interval(st))
    }
    fn pre_process(&mut self, sys: &S, z: &mut State<S::Dim>, h: f64) {
        with_stepper!(self, st => st.pre_process(sys, z, h))
    }
    fn post_process(
        &mut self,
        sys: &S,
        z: &State<S::Dim>,
        h: f64,
        out: &mut State<S::Dim>,
    ) -> bool {
        with_stepper!(self, st => st.post_process(sys, z, h, out))
    }
    fn step_tangent(
        &mut self,
        sys: &S,
        z: &mut State<S::Dim>,
        h: f64,
        t: &mut Tangent,
    ) -> Result<(), StepError> {
        with_stepper!(self, st => st.step_tangent(sys, z, h, t))
    }
}

/// Builds the stepper for `choice` on `sys` with step `h`, after checking the requirements and
/// step-size limits. `system_id` names the system in errors.
pub fn build<S: MechanicalSystem>(
    choice: &MethodChoice,
    sys: &S,
    system_id: &str,
    h: f64,
) -> Result<AnyStepper<S>, CoreError>
where
    DefaultAllocator: Allocator<S::Dim>,
{
    choice.check(system_id, sys.structure(), sys.damping_rate())?;
    let scheme = choice.id.scheme();
    let base = match scheme {
        Some(_) => choice.base.unwrap_or(MethodId::Modin3s),
        None => choice.id,
    };
    if scheme.is_some() && !COMPOSITION_BASES.contains(&base) {
        return Err(CoreError::invalid(
            "methods",
            format!("`{}` is not a composition base", base.as_str()),
        ));
    }
    let inner = match choice.id {
        MethodId::ModinRks => Some(choice.inner.unwrap_or(MethodId::Heun)),
        _ => None,
    };
    if let Some(i) = inner.filter(|i| !RKS_INNER.contains(i)) {
        return Err(CoreError::invalid(
            "methods",
            format!("`{}` is not an inner method of modin_rks", i.as_str()),
        ));
    }
    let weights = scheme.map_or_else(|| vec![1.0], Scheme::weights);
    check_divisors(base, sys.damping_rate(), h, &weights)?;
    let splitting = |seq: Vec<(splitting::SubFlow, f64)>| {
        let inner = inner.map(|i| {
            MomentumRk::new(
                tableau(i).map_or(InnerRk::ImplicitMidpoint, InnerRk::Explicit),
                sys.dim(),
            )
        });
        AnyStepper::Splitting(Splitting::new(sys, seq, inner))
    };
    if scheme.is_some() {
        return Ok(match (sequence(base), base) {
            (Some(seq), _) => splitting(splitting::compose(seq, &weights)),
            (None, MethodId::Csv2) => {
                AnyStepper::ComposedCsv2(Composed::new(Csv2::new(sys), weights))
            }
            (None, MethodId::Cimp) => AnyStepper::ComposedMidpoint(Composed::new(
                ImplicitMidpoint::new(sys, MidpointField::Conformal),
                weights,
            )),
            _ => AnyStepper::ComposedMidpoint(Composed::new(
                ImplicitMidpoint::new(sys, MidpointField::Full),
                weights,
            )),
        });
    }
    let separable = sys.structure().separable_constant_mass;
    Ok(match choice.id {
        MethodId::SymplecticEuler if !separable => {
            AnyStepper::GeneralSymplecticEuler(GeneralSymplecticEuler::new(sys, Variant::Original))
        }
        MethodId::SymplecticEulerAdjoint if !separable => {
            AnyStepper::GeneralSymplecticEuler(GeneralSymplecticEuler::new(sys, Variant::Adjoint))
        }
        MethodId::ImplicitMidpoint => {
            AnyStepper::Midpoint(ImplicitMidpoint::new(sys, MidpointField::Full))
        }
        MethodId::Cimp => {
            AnyStepper::Midpoint(ImplicitMidpoint::new(sys, MidpointField::Conformal))
        }
        MethodId::Csv2 => AnyStepper::Csv2(Csv2::new(sys)),
        MethodId::Reference => AnyStepper::Reference(Reference::new(
            choice.tolerance.unwrap_or(reference::DEFAULT_TOLERANCE),
        )),
        MethodId::Rowlands => AnyStepper::Rowlands(Rowlands::new(
            sys,
            choice.processor.unwrap_or(Processor::DEFAULT),
        )),
        id => match (tableau(id), sequence(id)) {
            (Some(t), _) => AnyStepper::RungeKutta(RungeKutta::new(t, sys.dim())),
            (None, Some(seq)) => splitting(seq.to_vec()),
            (None, None) => unreachable!("every method id has a constructor"),
        },
    })
}

/// Refuses a step whose sub-steps w·h make one of the method's linear solves singular: csv2
/// divides by 1 ∓ γτ/2, a damped θ-kick by 1 + θrτ. With a composition's negative weights
/// these vanish at values of γh other than the plain method's.
fn check_divisors(base: MethodId, r: f64, h: f64, weights: &[f64]) -> Result<(), CoreError> {
    let singular = |d: f64| d.abs() < 1e-9;
    for &w in weights {
        let bad = match (base, sequence(base)) {
            (MethodId::Csv2, _) => {
                let a = 0.25 * r * w * h;
                singular(1.0 - a) || singular(1.0 + a)
            }
            (_, Some(seq)) => seq.iter().any(|&(flow, frac)| match flow {
                splitting::SubFlow::DampedKick(theta) => {
                    singular(1.0 + theta.value() * r * w * frac * h)
                }
                _ => false,
            }),
            _ => false,
        };
        if bad {
            return Err(CoreError::invalid(
                "h",
                format!(
                    "{} needs to solve a singular linear system at this step size (γh = {}): choose another h",
                    base.as_str(),
                    0.5 * r * h
                ),
            ));
        }
    }
    Ok(())
}

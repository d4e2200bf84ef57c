//! The methods: what a run uses ([`Method`], a method with its options), the catalogue
//! ([`MethodId`] and its [`MethodInfo`]: order, kind, properties, requirements, citation), and the
//! construction of a stepper for a concrete system ([`build`](fn@build)). One file per family beside this
//! one, each with the catalogue entries of its methods; a method's id is written once, in its
//! entry. [`lanes`] holds the batched steppers that run several cells of a study side by side in
//! SIMD lanes (energy maps; compositions of kicks and drifts with their tangent maps for chaos
//! maps).

pub mod applicable;
pub mod build;
pub mod composition;
pub mod conformal;
pub mod dop853;
pub mod implicit;
pub mod lanes;
mod method;
pub mod reference;
pub mod rowlands;
pub mod runge_kutta;
pub mod splitting;
pub mod state_flows;
pub mod symplectic_euler;

use serde::{Serialize, Serializer};

pub use crate::system::Requirement;

pub use applicable::applicable;
pub use build::{build, AnyStepper};
pub use method::{Method, TOLERANCE_RANGE};

/// A method's coefficients as a type, `K` naming a constant table (a splitting's sequence, a
/// Butcher tableau): a stepper generic over it sees the table when it is compiled, so its loops
/// over flows or stages unroll and fold. The same steppers also take tables built at run time.
pub struct Known<K>(std::marker::PhantomData<fn() -> K>);

impl<K> Known<K> {
    /// The table `K`.
    pub const fn new() -> Self {
        Self(std::marker::PhantomData)
    }
}

impl<K> Default for Known<K> {
    fn default() -> Self {
        Self::new()
    }
}

pub(crate) use crate::flows::unroll;

/// How much work a step takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
#[cfg_attr(feature = "openapi", schema(as = MethodKind))]
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

/// Where a method comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = CitationEntry))]
pub struct Citation {
    /// The paper or book.
    pub paper: &'static str,
    /// Equation, algorithm or section.
    pub equation: &'static str,
}

/// The group a method is shown in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Group {
    /// Structure-preserving splittings and compositions (papers 000, 001).
    Geometric,
    /// Conformal symplectic schemes for linear damping (paper 003).
    Conformal,
    /// Ordinary methods to compare with.
    Baseline,
}

/// An option a method takes in the object form of a request's method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum MethodOption {
    /// The inner Runge–Kutta method of modin_rks.
    Inner,
    /// The symmetric second-order base of a composition.
    Base,
    /// The tolerance of the adaptive reference.
    Tolerance,
    /// The processor of rowlands.
    Processor,
}

impl MethodOption {
    /// The option's name in requests.
    pub fn as_str(self) -> &'static str {
        match self {
            MethodOption::Inner => "inner",
            MethodOption::Base => "base",
            MethodOption::Tolerance => "tolerance",
            MethodOption::Processor => "processor",
        }
    }
}

/// Sources cited by the catalogue entries.
pub(crate) mod sources {
    pub const HNW: &str = "Hairer, Nørsett, Wanner: Solving Ordinary Differential Equations I";
    pub const GNI: &str = "Hairer, Lubich, Wanner: Geometric Numerical Integration";
    pub const MODIN: &str = "000 Modin & Söderlind 2011";
    pub const FLOYD: &str = "003 Floyd 2014";
    pub const TAKACS: &str = "001 Takács & Fülöp";
    pub const BLANES_MOAN: &str = "Blanes & Moan, J. Comput. Appl. Math. 142 (2002) 313–330";
}

/// A method's catalogue entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = MethodEntry))]
pub struct MethodInfo {
    /// Identifier used in requests.
    #[cfg_attr(feature = "openapi", schema(value_type = MethodId))]
    pub id: &'static str,
    /// Human-readable name.
    pub name: &'static str,
    /// Classical order (on smooth problems).
    pub order: u32,
    /// Work per step.
    pub kind: Kind,
    /// Symplectic when the damping is zero.
    pub symplectic: bool,
    /// Conformal symplectic under linear damping (det ∂Φ/∂z = e^{−2γh} per degree of freedom).
    pub conformal_symplectic: bool,
    /// Symmetric (self-adjoint), so it can be a composition's base.
    pub symmetric: bool,
    /// What the system must satisfy.
    pub requirements: &'static [Requirement],
    /// Where it comes from.
    pub reference: Citation,
    /// Group for display.
    pub group: Group,
    /// Options the method accepts in the object form of a method.
    pub options: &'static [MethodOption],
    /// Whether the step's Jacobian can be propagated (`jacobian_defect`, stability analysis);
    /// when not, why.
    #[serde(skip)]
    pub no_step_jacobian: Option<&'static str>,
    /// What its step is made of: a sequence of exact flows, a tableau, a composition's weights,
    /// or a stepper of its own. A method given as data here runs on every path that walks such
    /// data (one run, SIMD lanes, compiled stretches, tangent maps) with nothing else written.
    #[serde(skip)]
    pub steps: Steps,
}

/// What a method's step is made of, as its catalogue entry gives it.
#[derive(Clone, Copy, Debug)]
pub enum Steps {
    /// A splitting: its sequence of exact sub-flows.
    Splitting(splitting::Sequence),
    /// An explicit Runge–Kutta method: its Butcher tableau.
    RungeKutta(&'static runge_kutta::Tableau),
    /// A symmetric composition of a symmetric second-order base method.
    Composition(composition::Weights),
    /// A stepper of its own (implicit, conformal with its own factor, processed by a modified
    /// potential, adaptive).
    Own,
}

impl PartialEq for Steps {
    /// Two entries' steps are equal when they are the same data; a composition's weights, made
    /// by a function, compare by the weights it makes.
    fn eq(&self, other: &Steps) -> bool {
        match (self, other) {
            (Steps::Splitting(a), Steps::Splitting(b)) => a == b,
            (Steps::RungeKutta(a), Steps::RungeKutta(b)) => a == b,
            (Steps::Composition(a), Steps::Composition(b)) => a.same_as(b),
            (Steps::Own, Steps::Own) => true,
            _ => false,
        }
    }
}

/// Declares [`MethodId`] from the catalogue entries, in catalogue order.
macro_rules! catalogue {
    ($($(#[$doc:meta])* $variant:ident => $info:path,)*) => {
        /// Every method the core offers, in catalogue order. Its request id is its entry's `id`.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum MethodId {
            $($(#[$doc])* $variant,)*
        }

        impl MethodId {
            /// All methods, in catalogue order.
            pub const ALL: &'static [MethodId] = &[$(MethodId::$variant,)*];

            /// The method's catalogue entry.
            pub fn info(self) -> &'static MethodInfo {
                match self {
                    $(MethodId::$variant => &$info,)*
                }
            }
        }
    };
}

catalogue! {
    /// Paper 000 Algorithm 3.1.
    Modin3s => splitting::MODIN_3S_INFO,
    /// Paper 000 Algorithm 3.2.
    Modin2s => splitting::MODIN_2S_INFO,
    /// Paper 000 Algorithm 3.3.
    ModinRks => splitting::MODIN_RKS_INFO,
    /// Paper 003 eq. (2.12).
    Csv1 => splitting::CSV1_INFO,
    /// Paper 003 eq. (2.16).
    Csv2 => conformal::CSV2_INFO,
    /// Paper 003 eq. (2.3).
    Cimp => implicit::CIMP_INFO,
    /// Fourth-order triple-jump composition of a symmetric second-order method.
    TripleJump => composition::TRIPLE_JUMP_INFO,
    /// Suzuki's fourth-order five-stage composition.
    Suzuki4 => composition::SUZUKI_4_INFO,
    /// McLachlan's fourth-order five-stage composition.
    McLachlan4 => composition::MCLACHLAN_4_INFO,
    /// Suzuki's sixth-order 25-stage composition.
    Suzuki6 => composition::SUZUKI_6_INFO,
    /// Yoshida's sixth-order seven-stage composition.
    Yoshida6 => composition::YOSHIDA_6_INFO,
    /// Kahan and Li's sixth-order nine-stage composition.
    KahanLi6 => composition::KAHAN_LI_6_INFO,
    /// Kahan and Li's eighth-order 17-stage composition.
    KahanLi8 => composition::KAHAN_LI_8_INFO,
    /// Blanes, Casas and Murua's processed composition of effective order 8, 13 stages.
    BlanesCasasMurua8 => composition::BLANES_CASAS_MURUA_8_INFO,
    /// Blanes and Moan's optimized fourth-order splitting, six stages.
    BlanesMoanS6 => splitting::BLANES_MOAN_S6_INFO,
    /// Blanes and Moan's optimized sixth-order Runge–Kutta–Nyström splitting, eleven stages.
    BlanesMoanSrkn11 => splitting::BLANES_MOAN_SRKN11_INFO,
    /// Rowlands time stepping: Störmer–Verlet on a modified potential with processing.
    Rowlands => rowlands::ROWLANDS_INFO,
    /// Symplectic Euler (kick then drift).
    SymplecticEuler => splitting::SYMPLECTIC_EULER_INFO,
    /// Adjoint symplectic Euler (drift then kick).
    SymplecticEulerAdjoint => splitting::SYMPLECTIC_EULER_ADJOINT_INFO,
    /// Störmer–Verlet, drift–kick–drift.
    PositionVerlet => splitting::POSITION_VERLET_INFO,
    /// Störmer–Verlet, kick–drift–kick.
    VelocityVerlet => splitting::VELOCITY_VERLET_INFO,
    /// Implicit midpoint rule (Newton).
    ImplicitMidpoint => implicit::IMPLICIT_MIDPOINT_INFO,
    /// Forward Euler.
    ExplicitEuler => runge_kutta::EXPLICIT_EULER_INFO,
    /// Heun's (explicit trapezoidal) method.
    Heun => runge_kutta::HEUN_INFO,
    /// Kutta's third-order method.
    Rk3 => runge_kutta::RK3_INFO,
    /// Classical RK4.
    Rk4 => runge_kutta::RK4_INFO,
    /// Adaptive DOP853 at a tight tolerance.
    Reference => reference::REFERENCE_INFO,
}

impl MethodId {
    /// The id as used in requests.
    pub fn as_str(self) -> &'static str {
        self.info().id
    }

    /// The method with this id, if any.
    pub fn parse(s: &str) -> Option<MethodId> {
        MethodId::ALL.iter().copied().find(|m| m.as_str() == s)
    }

    /// Every id, comma-separated (for messages).
    pub fn known() -> String {
        names(MethodId::ALL)
    }
}

impl std::fmt::Display for MethodId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for MethodId {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

#[cfg(feature = "openapi")]
impl utoipa::PartialSchema for MethodId {
    fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
        crate::schema::string_enum(
            "A method id (see GET /api/v1/methods).",
            MethodId::ALL.iter().map(|m| m.as_str()),
        )
    }
}

#[cfg(feature = "openapi")]
impl utoipa::ToSchema for MethodId {}

fn names(ids: &[MethodId]) -> String {
    ids.iter()
        .map(|m| m.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Declares a subset of the methods as its own type.
macro_rules! method_subset {
    ($(#[$doc:meta])* $name:ident, $rule:literal { $($variant:ident),* $(,)? }) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum $name {
            $(#[doc = concat!("[`MethodId::", stringify!($variant), "`].")] $variant,)*
        }

        impl $name {
            /// Every member, in catalogue order.
            pub const ALL: &'static [$name] = &[$($name::$variant,)*];
            /// What the subset is, for messages.
            pub const RULE: &'static str = $rule;

            /// The method's id.
            pub fn id(self) -> MethodId {
                match self {
                    $($name::$variant => MethodId::$variant,)*
                }
            }

            /// The member with this id, if it is one.
            pub fn of(id: MethodId) -> Option<$name> {
                $name::ALL.iter().copied().find(|m| m.id() == id)
            }

            /// Every member's id, for messages.
            pub fn ids() -> Vec<String> {
                $name::ALL.iter().map(|m| m.id().as_str().to_string()).collect()
            }
        }

        #[cfg(feature = "openapi")]
        impl utoipa::PartialSchema for $name {
            fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
                crate::schema::string_enum($rule, $name::ALL.iter().map(|m| m.id().as_str()))
            }
        }

        #[cfg(feature = "openapi")]
        impl utoipa::ToSchema for $name {}
    };
}

method_subset! {
    /// The inner methods modin_rks accepts: at least second order, so that the splitting stays
    /// second order (paper 000 Sec. 3; with forward Euler inside we measured order 1.02).
    Inner, "modin_rks needs a Runge–Kutta inner method" { Heun, Rk3, Rk4, ImplicitMidpoint }
}

method_subset! {
    /// The bases the compositions accept: the symmetric second-order methods.
    Base, "a composition needs a symmetric second-order base" {
        Modin3s, Modin2s, Csv1, Csv2, Cimp, PositionVerlet, VelocityVerlet, ImplicitMidpoint
    }
}

//! The system catalogue: each system's entry ([`SystemInfo`]: parameters with their ranges and
//! defaults, charts, default initial state, invariants, its embedding in space, and how to build
//! it) lives in the system's own file; this module gathers the entries and holds [`AnySystem`].
//!
//! [`AnySystem`] is the one place where a run dispatches dynamically: [`with_system!`](crate::with_system) matches it
//! once, and everything below runs monomorphised for the concrete system type.

pub mod custom;
mod elastic_pendulum;
mod first_order;
mod nbody;
mod oscillator;
pub mod params;
mod pendulum;
mod planar;
pub mod world;

use std::borrow::Cow;
use std::sync::{Arc, LazyLock};

use serde::Serialize;

pub use custom::system::CustomSystem;
pub use elastic_pendulum::{ElasticPendulum3d, ElasticPendulum3dCylindrical};
pub use first_order::{ExponentialDecay, Gompertz};
pub use nbody::{NBody, PairPotential};
pub use oscillator::{CompensatedOscillator, HarmonicOscillator};
pub use params::{ParamKind, ParamSpec, ParamValue, ParamValues};
pub use pendulum::Pendulum;
pub use planar::{
    planar_pendulum, wrap_angle, PlanarCartesian, PlanarKind, PlanarPolar, PlanarSpring,
};
pub use world::World;

use crate::error::{CoreError, Field};

/// A coordinate chart a system is offered in.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = ChartEntry))]
pub struct ChartInfo {
    /// Identifier used in requests (`chart`).
    #[cfg_attr(feature = "openapi", schema(example = "polar"))]
    pub id: &'static str,
    /// Names of the generalized coordinates, in state order.
    pub coordinates: &'static [&'static str],
    /// Whether H is separable with a constant mass matrix in this chart (the splitting methods
    /// need it).
    pub separable: bool,
    /// The chart's map to Cartesian coordinates and its Hamiltonian.
    pub description: &'static str,
}

impl ChartInfo {
    /// A chart.
    pub const fn new(
        id: &'static str,
        coordinates: &'static [&'static str],
        separable: bool,
        description: &'static str,
    ) -> ChartInfo {
        ChartInfo {
            id,
            coordinates,
            separable,
            description,
        }
    }
}

/// How a system is built from its parameters in a chart, for a run of step `h` (the
/// oscillator's compensating chart, 001 eq. 82, depends on h).
#[derive(Clone)]
pub enum Builder {
    /// A system of the catalogue, built by its own function.
    Catalog(fn(&ParamValues, &ChartInfo, f64) -> AnySystem),
    /// A system defined by a user, compiled from its model.
    Custom(Arc<custom::CustomModel>),
}

impl std::fmt::Debug for Builder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Builder::Catalog(_) => f.write_str("Builder::Catalog"),
            Builder::Custom(_) => f.write_str("Builder::Custom"),
        }
    }
}

/// A catalogue entry.
#[derive(Clone, Debug, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[cfg_attr(feature = "openapi", schema(as = SystemEntry))]
pub struct SystemInfo {
    /// Identifier used in requests.
    #[cfg_attr(feature = "openapi", schema(value_type = SystemId, example = "pendulum"))]
    pub id: Cow<'static, str>,
    /// Human-readable name.
    #[cfg_attr(feature = "openapi", schema(value_type = String))]
    pub name: Cow<'static, str>,
    /// What the system is, with its paper.
    #[cfg_attr(feature = "openapi", schema(value_type = String))]
    pub description: Cow<'static, str>,
    /// Degrees of freedom (for N bodies: of the default case).
    pub degrees_of_freedom: usize,
    /// Coordinate charts the system is offered in; the first is the default, and its
    /// coordinates are the Cartesian ones (for a first-order ODE: the original variable) in
    /// which `q0` and `p0` are given.
    pub charts: Vec<ChartInfo>,
    /// Parameters.
    pub params: Vec<ParamSpec>,
    /// Default initial positions.
    pub q0: Vec<f64>,
    /// Default initial momenta.
    pub p0: Vec<f64>,
    /// Names of the invariants reported per sample.
    #[cfg_attr(feature = "openapi", schema(value_type = Vec<String>))]
    pub invariants: Vec<Cow<'static, str>>,
    /// Whether a closed-form solution gives the energy error.
    pub exact_solution: bool,
    /// Whether the damping is conformal (so `gamma`/`epsilon` are both accepted).
    pub conformal_damping: bool,
    /// How the Cartesian configuration appears in space.
    #[serde(skip)]
    pub world: World,
    /// Builds the system.
    #[serde(skip)]
    pub build: Builder,
}

impl SystemInfo {
    /// The system of these parameters in `chart`, for a run of step `h`.
    pub fn build(
        &self,
        params: &ParamValues,
        chart: &ChartInfo,
        h: f64,
    ) -> Result<AnySystem, CoreError> {
        match &self.build {
            Builder::Catalog(build) => Ok(build(params, chart, h)),
            Builder::Custom(model) => model.instantiate(params),
        }
    }

    /// How the system appears in space with these parameters.
    pub fn world(&self, params: &ParamValues) -> Result<World, CoreError> {
        match &self.build {
            Builder::Catalog(_) => Ok(self.world.clone()),
            Builder::Custom(model) => model.world(params),
        }
    }

    /// The user's model, for a user-defined system.
    pub fn custom_model(&self) -> Option<&custom::CustomModel> {
        match &self.build {
            Builder::Catalog(_) => None,
            Builder::Custom(model) => Some(model),
        }
    }

    /// The chart `requested` (default: the first), or an error naming `field`.
    pub fn chart(&self, requested: Option<&str>, field: &Field) -> Result<&ChartInfo, CoreError> {
        match requested {
            None => Ok(&self.charts[0]),
            Some(id) => {
                self.charts
                    .iter()
                    .find(|c| c.id == id)
                    .ok_or_else(|| CoreError::UnknownChart {
                        field: field.clone(),
                        system: self.id.to_string(),
                        id: id.to_string(),
                        known: self.charts.iter().map(|c| c.id.to_string()).collect(),
                    })
            }
        }
    }
}

/// The whole catalogue, in a stable order, built once.
static CATALOG: LazyLock<Vec<Arc<SystemInfo>>> = LazyLock::new(|| {
    [
        oscillator::entry(),
        pendulum::entry(),
        elastic_pendulum::entry(),
        nbody::entry(),
        planar::pendulum_entry(),
        planar::free_particle_entry(),
        first_order::exponential_decay_entry(),
        first_order::gompertz_entry(),
    ]
    .into_iter()
    .map(Arc::new)
    .collect()
});

/// The whole catalogue, in a stable order.
pub fn catalog() -> &'static [Arc<SystemInfo>] {
    &CATALOG
}

/// The catalogue entry for `id`; the error names `field`.
pub fn info(id: &str, field: &Field) -> Result<Arc<SystemInfo>, CoreError> {
    catalog()
        .iter()
        .find(|s| s.id == id)
        .cloned()
        .ok_or_else(|| CoreError::UnknownSystem {
            field: field.clone(),
            id: id.to_string(),
            known: catalog().iter().map(|s| s.id.to_string()).collect(),
        })
}

/// A system as a request names it: an id of the catalogue, or a user's definition checked into
/// an entry of its own. (An interface that keeps users' definitions replaces their ids by the
/// definitions before the core sees them.)
#[derive(Clone, Debug)]
pub enum SystemRef {
    /// A catalogue id.
    Id(String),
    /// A user-defined system.
    Defined(Arc<SystemInfo>),
}

impl SystemRef {
    /// The entry; an unknown id is an error naming `field`.
    pub fn resolve(&self, field: &Field) -> Result<Arc<SystemInfo>, CoreError> {
        match self {
            SystemRef::Id(id) => info(id, field),
            SystemRef::Defined(info) => Ok(Arc::clone(info)),
        }
    }
}

impl PartialEq for SystemRef {
    /// The same id, or the same definition.
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (SystemRef::Id(a), SystemRef::Id(b)) => a == b,
            (SystemRef::Defined(a), SystemRef::Defined(b)) => a.id == b.id,
            _ => false,
        }
    }
}

/// A system reference as a study's spec carries it to workers and into part files: an id, or a
/// user's definition with its id (checked and compiled again where it is read).
#[derive(Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
enum SystemRefForm {
    Id(String),
    Defined {
        id: String,
        definition: custom::CustomDefinition,
    },
}

impl Serialize for SystemRef {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let form = match self {
            SystemRef::Id(id) => SystemRefForm::Id(id.clone()),
            SystemRef::Defined(info) => SystemRefForm::Defined {
                id: info.id.to_string(),
                definition: info
                    .custom_model()
                    .ok_or_else(|| serde::ser::Error::custom("a defined system without its model"))?
                    .definition()
                    .clone(),
            },
        };
        form.serialize(s)
    }
}

impl<'de> serde::Deserialize<'de> for SystemRef {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Ok(match SystemRefForm::deserialize(d)? {
            SystemRefForm::Id(id) => SystemRef::Id(id),
            SystemRefForm::Defined { id, definition } => SystemRef::Defined(
                custom::define(definition, &id).map_err(serde::de::Error::custom)?,
            ),
        })
    }
}

impl From<Arc<SystemInfo>> for SystemRef {
    fn from(info: Arc<SystemInfo>) -> Self {
        SystemRef::Defined(info)
    }
}

impl From<&str> for SystemRef {
    fn from(id: &str) -> Self {
        SystemRef::Id(id.to_string())
    }
}

impl From<String> for SystemRef {
    fn from(id: String) -> Self {
        SystemRef::Id(id)
    }
}

impl From<&String> for SystemRef {
    fn from(id: &String) -> Self {
        SystemRef::Id(id.clone())
    }
}

/// The schema of a system id: one of the catalogue's, or a stored definition's (`sys-` and 16
/// lowercase hex digits).
pub struct SystemId;

#[cfg(feature = "openapi")]
impl utoipa::PartialSchema for SystemId {
    fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
        use utoipa::openapi::schema::{AnyOfBuilder, ObjectBuilder, Type};
        AnyOfBuilder::new()
            .description(Some(
                "A system id (see GET /api/v1/systems): a built-in system's or a stored definition's.",
            ))
            .item(crate::schema::string_enum(
                "A built-in system.",
                catalog().iter().map(|s| &*s.id),
            ))
            .item(
                ObjectBuilder::new()
                    .schema_type(Type::String)
                    .description(Some("A stored definition (POST /api/v1/systems)."))
                    .pattern(Some("^sys-[0-9a-f]{16}$")),
            )
            .into()
    }
}

#[cfg(feature = "openapi")]
impl utoipa::ToSchema for SystemId {}

/// The schema of a chart id: one of the charts of the catalogue's systems.
pub struct ChartId;

#[cfg(feature = "openapi")]
impl utoipa::PartialSchema for ChartId {
    fn schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
        let mut ids: Vec<&str> = catalog()
            .iter()
            .flat_map(|s| s.charts.iter().map(|c| c.id))
            .collect();
        ids.sort_unstable();
        ids.dedup();
        crate::schema::string_enum(
            "A coordinate chart of the system (see its `charts` in GET /api/v1/systems).",
            ids.into_iter(),
        )
    }
}

#[cfg(feature = "openapi")]
impl utoipa::ToSchema for ChartId {}

/// A concrete system, chosen at run time.
#[derive(Clone, Debug, PartialEq)]
pub enum AnySystem {
    /// See [`HarmonicOscillator`].
    HarmonicOscillator(HarmonicOscillator),
    /// See [`Pendulum`].
    Pendulum(Pendulum),
    /// See [`ElasticPendulum3d`].
    ElasticPendulum3d(ElasticPendulum3d),
    /// See [`NBody`].
    NBody(NBody),
    /// See [`ElasticPendulum3dCylindrical`].
    ElasticPendulum3dCylindrical(ElasticPendulum3dCylindrical),
    /// See [`CompensatedOscillator`].
    CompensatedOscillator(CompensatedOscillator),
    /// See [`PlanarCartesian`].
    PlanarCartesian(PlanarCartesian),
    /// See [`PlanarPolar`].
    PlanarPolar(PlanarPolar),
    /// See [`ExponentialDecay`].
    ExponentialDecay(ExponentialDecay),
    /// See [`Gompertz`].
    Gompertz(Gompertz),
    /// A user-defined system of one degree of freedom.
    Custom1(CustomSystem<nalgebra::U1>),
    /// A user-defined system of two degrees of freedom.
    Custom2(CustomSystem<nalgebra::U2>),
    /// A user-defined system of three degrees of freedom.
    Custom3(CustomSystem<nalgebra::U3>),
    /// A user-defined system of more degrees of freedom.
    CustomN(CustomSystem<nalgebra::Dyn>),
}

/// Runs `$body` with `$s` bound to the concrete system inside an [`AnySystem`].
#[macro_export]
macro_rules! with_system {
    ($any:expr, $s:ident => $body:expr) => {
        match $any {
            $crate::systems::AnySystem::HarmonicOscillator($s) => $body,
            $crate::systems::AnySystem::Pendulum($s) => $body,
            $crate::systems::AnySystem::ElasticPendulum3d($s) => $body,
            $crate::systems::AnySystem::NBody($s) => $body,
            $crate::systems::AnySystem::ElasticPendulum3dCylindrical($s) => $body,
            $crate::systems::AnySystem::CompensatedOscillator($s) => $body,
            $crate::systems::AnySystem::PlanarCartesian($s) => $body,
            $crate::systems::AnySystem::PlanarPolar($s) => $body,
            $crate::systems::AnySystem::ExponentialDecay($s) => $body,
            $crate::systems::AnySystem::Gompertz($s) => $body,
            $crate::systems::AnySystem::Custom1($s) => $body,
            $crate::systems::AnySystem::Custom2($s) => $body,
            $crate::systems::AnySystem::Custom3($s) => $body,
            $crate::systems::AnySystem::CustomN($s) => $body,
        }
    };
}

impl AnySystem {
    /// The configuration-space dimension (of extended phase space for a driven system).
    pub fn dimension(&self) -> usize {
        use crate::system::MechanicalSystem;
        with_system!(self, s => nalgebra::Dim::value(&s.dim()))
    }

    /// The degrees of freedom: the dimension without a driven system's clock.
    pub fn degrees_of_freedom(&self) -> usize {
        use crate::system::MechanicalSystem;
        with_system!(self, s => s.clock().unwrap_or_else(|| nalgebra::Dim::value(&s.dim())))
    }
}

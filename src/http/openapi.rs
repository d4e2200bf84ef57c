//! The OpenAPI 3 document of the service, generated from the handlers' `#[utoipa::path]`
//! annotations and the request and response types, so it follows the code.

use utoipa::OpenApi;

use super::error::ErrorBody;
use super::recordings::{self, RecordingCreated};
use super::store::{Origin, RecordingEntry};
use super::systems::{self, StoredSystem, SystemEntry};
use super::{handlers, simulate, stability, studies};
use crate::api::stability::{PointRequest, StabilityRequest};
use crate::api::studies::{ConvergenceRequest, EnergyMapRequest, WorkPrecisionRequest};
use crate::api::sweep::{Preset, SweepRequest};
use crate::api::system::SystemDefinition;
use crate::api::SimulateRequest;
use crate::core::methods::MethodInfo;
use crate::core::simulation::{SimulationDocument, StreamLine};
use crate::core::studies::convergence::{ConvergenceDocument, ConvergenceLine};
use crate::core::studies::energy_map::{EnergyMapDocument, MapLine};
use crate::core::studies::stability::{PointDocument, StabilityDocument};
use crate::core::studies::sweep::{SweepDocument, SweepLine};
use crate::core::studies::work_precision::{StudyLine, WorkPrecisionDocument};
use crate::core::systems::SystemInfo;
use crate::recording::read::{RecordedDocument, RecordedRun};

/// The OpenAPI document: `ApiDoc::openapi()`.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "geomint",
        description = "Geometric numerical integration of damped Hamiltonian systems: structure-preserving \
            splittings and conformal symplectic methods beside Runge–Kutta baselines. Every error answers \
            `{\"error\": {\"code\", \"message\", \"field\"}}`."
    ),
    paths(
        handlers::healthz,
        systems::list_systems,
        systems::get_system,
        systems::create_system,
        systems::delete_system,
        handlers::list_methods,
        handlers::get_method,
        simulate::simulate,
        stability::stability_map,
        stability::stability_point,
        studies::work_precision,
        studies::energy_map,
        studies::convergence,
        studies::sweep,
        studies::sweep_presets,
        handlers::openapi_json,
        recordings::create_recording,
        recordings::list_recordings,
        recordings::get_recording,
        recordings::delete_recording,
        recordings::recording_samples,
    ),
    components(schemas(
        SimulateRequest,
        SimulationDocument,
        StreamLine,
        StabilityRequest,
        StabilityDocument,
        PointRequest,
        PointDocument,
        WorkPrecisionRequest,
        WorkPrecisionDocument,
        StudyLine,
        EnergyMapRequest,
        EnergyMapDocument,
        MapLine,
        ConvergenceRequest,
        ConvergenceDocument,
        ConvergenceLine,
        SweepRequest,
        SweepDocument,
        SweepLine,
        Preset,
        SystemInfo,
        SystemEntry,
        StoredSystem,
        SystemDefinition,
        MethodInfo,
        ErrorBody,
        handlers::Health,
        RecordingCreated,
        RecordingEntry,
        Origin,
        RecordedDocument,
        RecordedRun,
    )),
    tags(
        (name = "catalog", description = "The systems and methods on offer, and the system definitions users store"),
        (name = "simulation", description = "Running simulations"),
        (name = "stability", description = "Linear stability analysis on the damped oscillator"),
        (name = "studies", description = "Work–precision studies (time against accuracy per method), convergence studies (error against step size, with the observed orders, per method and coordinate chart), energy-error maps across coordinate charts, and sweeps of any system over one or two axes"),
        (name = "recordings", description = "Rerun recordings (.rrd) of simulations, stored or uploaded, downloadable, and read back as samples"),
        (name = "service", description = "Health and this document"),
    )
)]
pub struct ApiDoc;

//! Simulations: a system with parameters, chart and initial state, run with one or more methods
//! from the same state, sampled every so many steps.
//!
//! - [`spec`]: the simulation as asked for ([`SimulationSpec`]) and its validation into a
//!   [`Simulation`] (cheap, before any work is queued).
//! - [`run`]: one method's run, its samples with energies, energy errors and invariants handed
//!   to a [`SampleSink`]; the reference run.
//! - [`stream`]: the one way a whole simulation runs — its methods in parallel, emitting typed
//!   lines that the NDJSON stream, the JSON document and the recordings consume.
//! - [`document`]: the JSON document's types and the column collector.
//! - [`crossings`]: a run's Poincaré section, event and energy level, as the stream and the
//!   document carry them.
//! - [`surface`]: an initial state on an energy surface, one momentum solved from H = E.
//! - [`allowed`]: which points of a section's plane can start an orbit at an energy.
//! - `lanes`: runs from up to sixteen initial states ([`crate::flows::LANES`]) side by side in
//!   SIMD lanes, with their chaos indicators ([`Simulation::run_side_by_side`]), driven by the
//!   lanes' run loop ([`crate::run::driver`]).

pub mod allowed;
pub mod crossings;
pub mod document;
pub(crate) mod lanes;
pub mod run;
pub mod spec;
pub mod stream;
pub mod surface;

pub use allowed::{AllowedRegion, Plane, PlaneAxis, PLANE_POINTS};
pub use crossings::{CrossingColumns, SurfaceInfo, Watching};
pub use document::{
    ColumnSink, Columns, DivergedAt, RunDocument, RunOutcome, ScheduleSummary, SimulationDocument,
    Stop, SystemSummary,
};
pub(crate) use lanes::with_lane_systems;
pub use run::{for_each_method, RunReport, Sample, SampleSink};
pub use spec::{
    EnergyReference, InitialCoordinates, InputFields, Limits, MethodAt, Simulation, SimulationSpec,
    MAX_METHODS,
};
pub use stream::{DocumentCollector, StreamLine};
pub use surface::EnergySurface;

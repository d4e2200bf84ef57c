//! Serialisation of simulations, shared by the HTTP API and the command line.
//!
//! - [`request`]: the simulation request as users write it, and its strict parser.
//! - [`document`]: the JSON answer (one run per method, sample columns, stop and statistics) and
//!   the parallel execution of a request's methods.
//! - [`stream`]: the NDJSON form, written while the runs compute, and the document assembled
//!   from it.
//! - [`catalog`]: the system and method catalogues as published.
//! - [`stability`]: linear stability requests (maps over (γ, h), single points) and answers.
//! - [`work_precision`]: work–precision studies (time against energy error per method).
//! - [`convergence`]: convergence studies (errors at t_end against the step size, per method
//!   and chart, with the fitted orders).
//! - [`study`]: what the studies share (settings, the reference run, measurements, fits,
//!   progress lines).
//! - [`recording`]: Rerun recordings (`.rrd`) of simulations, stability and work–precision
//!   studies, with their default blueprints; a run streamed live to a Rerun viewer.
//! - [`error`]: the error shape every interface reports.
//!
//! Everything here is synchronous; the HTTP layer calls it off the async runtime.

pub mod catalog;
pub mod convergence;
pub mod document;
pub mod energy_map;
pub mod error;
pub mod request;
pub mod stability;
pub mod stream;
pub mod study;
pub mod work_precision;

pub use document::{simulate, RunDocument, SimulationDocument, Stop};
pub use error::{codes, ErrorBody, ErrorDetail};
pub use request::SimulateRequest;
pub use stream::{ndjson_line, StreamLine};

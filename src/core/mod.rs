//! The integrator core: systems, exact sub-flows, methods, the driver, simulations and studies,
//! diagnostics and typed errors. No HTTP, no files, no async.
//!
//! - [`system`] and [`systems`]: what a mechanical system is, and the catalogue of them.
//! - [`flows`] and [`methods`]: exact sub-flows, and the methods built from them.
//! - [`run`]: the driver loop.
//! - [`simulation`]: a simulation from its spec to its stream of samples and its document.
//! - [`studies`]: convergence, work–precision, energy maps, stability maps.
//! - [`stability`], [`diagnostics`]: linear stability analysis; drift and fits.
//! - [`error`], [`schema`]: typed errors with their codes; OpenAPI schemas of catalogue ids.

pub mod diagnostics;
pub mod error;
pub mod expr;
pub mod flows;
pub mod methods;
pub mod run;
pub mod schema;
pub mod simulation;
pub mod stability;
pub mod studies;
pub mod system;
pub mod systems;

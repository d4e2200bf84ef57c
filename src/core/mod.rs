//! The integrator core: systems, exact sub-flows, methods, the driver and diagnostics. No HTTP,
//! no files, no async.

pub mod diagnostics;
pub mod error;
pub mod flows;
pub mod methods;
pub mod run;
pub mod schema;
pub mod simulation;
pub mod stability;
pub mod studies;
pub mod system;
pub mod systems;

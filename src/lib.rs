//! geomint: geometric numerical integration of Hamiltonian systems with damping.
//!
//! Structure-preserving integrators — the Rayleigh-damped splittings of Modin & Söderlind (paper
//! 000), the conformal symplectic schemes of Floyd (paper 003) — beside ordinary Runge–Kutta
//! baselines, on damped mechanical systems, served over HTTP.
//!
//! - [`core`]: systems, exact sub-flows, methods, the driver loop and diagnostics; pure
//!   computation, no I/O.
//! - [`output`]: serialisation of runs (JSON documents and NDJSON streams).
//! - [`http`]: the axum service: routes, errors, limits.
//! - [`cli`]: the command line.
#![warn(missing_docs)]

pub mod api;
pub mod cli;
pub mod core;
pub mod http;
pub mod recording;

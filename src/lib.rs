//! geomint: geometric numerical integration of Hamiltonian systems with damping.
//!
//! Structure-preserving integrators — the Rayleigh-damped splittings of Modin & Söderlind (paper
//! 000), the conformal symplectic schemes of Floyd (paper 003), the coordinate studies of Takács &
//! Fülöp (paper 001) — beside ordinary Runge–Kutta baselines, on damped mechanical systems, served
//! over HTTP and on the command line.
//!
//! - [`core`]: the integrator core — systems, exact sub-flows, methods, the driver, simulations
//!   and studies as pure computations from typed specs to typed results, typed errors. No HTTP,
//!   no files, no async.
//! - [`access`]: who may do what: tokens, scopes, quotas, the policy for clients without a
//!   token.
//! - [`api`]: the wire layer (the crate `geomint-api`, which the Python module builds on too) —
//!   requests read strictly into the core's specs, the NDJSON encoding of the lines the core
//!   streams.
//! - [`recording`]: Rerun recordings (`.rrd`) of the core's results.
//! - [`store`]: what the service keeps on disk: recordings, stored system definitions, jobs.
//! - [`http`]: the axum service: routes, answer forms, limits.
//! - [`studies`]: every kind of study, one module each: how it is read, run, streamed, recorded
//!   and reported, for the routes, the command line and jobs alike.
//! - [`executor`], [`nats`]: where studies run: this machine, or NATS JetStream workers.
//! - [`jobs`]: studies submitted to run in the background, in stored parts that outlive a
//!   restart, owners' parts taking turns.
//! - [`cli`]: the command line.
#![warn(missing_docs)]

pub mod access;
/// The wire layer ([`geomint_api`]), under the name the service's modules use.
pub use geomint_api as api;
pub mod cli;
pub mod executor;
/// The integrator core ([`geomint_core`]), under the name the service's modules use.
pub use geomint_core as core;
pub mod http;
pub mod jobs;
pub mod nats;
pub mod recording;
pub mod store;
pub mod studies;

//! geomint's integrator core: geometric numerical integration of Hamiltonian systems with
//! damping, as a library. Structure-preserving integrators — the Rayleigh-damped splittings of
//! Modin & Söderlind (paper 000), the conformal symplectic schemes of Floyd (paper 003), the
//! coordinate charts of Takács & Fülöp (paper 001) — beside Runge–Kutta baselines, on built-in
//! and user-defined mechanical systems; simulations and studies as pure computations from typed
//! specs to typed results. No HTTP, no files, no async: the `geomint` service and command line
//! are built on it.
//!
//! - [`system`] and [`systems`]: what a mechanical system is, and the catalogue of them
//!   (with users' definitions, compiled from [`expr`]).
//! - [`flows`]: the kernel — the exact sub-flows written once over the number a step computes
//!   with (one `f64`, a pack of SIMD lanes, or a value of compiled code), the Butcher tableau
//!   and the plan of a compiled stretch; [`methods`]: the methods built from them;
//!   [`tangent`]: their tangent maps.
//! - [`run`]: the driver loop.
//! - [`simulation`]: a simulation from its spec to its stream of samples and its document.
//! - [`sections`]: Poincaré sections and events, located by Hénon's trick.
//! - [`studies`]: convergence, work–precision, energy maps, stability maps, sweeps.
//! - [`stability`], [`diagnostics`]: linear stability analysis; drift and fits.
//! - [`chaos`]: Lyapunov spectra, MEGNO, FLI, SALI and GALI from the methods' tangent maps.
//! - [`error`]: typed errors with their fields, numbers and codes; with the `openapi` feature,
//!   `schema`: OpenAPI schemas of the catalogue ids.
//!
//! ```
//! use geomint_core::methods::{Method, MethodId};
//! use geomint_core::simulation::{ColumnSink, Limits, Simulation, SimulationSpec};
//! use geomint_core::run::Budget;
//!
//! // The damped pendulum of paper 000 with Modin & Söderlind's 3-stage splitting.
//! let spec = SimulationSpec::new("pendulum", &[Method::Plain(MethodId::Modin3s)], 0.1, 100.0)
//!     .param("epsilon", 0.01);
//! let sim = Simulation::prepare(&spec, &Limits::default())?;
//! let mut columns = ColumnSink::new(sim.invariant_names());
//! let outcome = sim.run_method(0, None, Budget::default(), &mut columns)?;
//! let energy = columns.take().energy;
//! assert_eq!(outcome.stats.steps, 1000);
//! // Rayleigh damping dissipates: the energy at t = 100 is below the energy at the start.
//! assert!(energy.last().unwrap() < energy.first().unwrap());
//! # Ok::<(), geomint_core::error::CoreError>(())
//! ```
#![warn(missing_docs)]

pub mod chaos;
pub mod diagnostics;
pub mod error;
pub mod expr;
pub mod flows;
pub mod methods;
pub mod run;
#[cfg(feature = "openapi")]
pub mod schema;
pub mod sections;
pub mod simulation;
pub mod stability;
pub mod studies;
pub mod system;
pub mod systems;
pub mod tangent;

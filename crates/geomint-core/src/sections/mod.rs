//! Poincaré sections and events: where a run crosses a surface S(q, p, t) = 0, located to
//! round-off for any method by Hénon's trick (M. Hénon, *On the numerical computation of
//! Poincaré maps*, Physica D 5 (1982) 412–414), while the run itself goes on undisturbed.
//!
//! # Hénon's trick
//! Let z' = f(z) be the run's vector field (in extended phase space for a driven system, whose
//! clock t is a coordinate with t' = 1; for an autonomous one t is carried beside z with
//! t' = 1), and let s = S(z, t). Along a solution ds/dt = ∇_z S·f + ∂S/∂t =: σ(z, t). Where
//! σ ≠ 0 the map t ↦ s is invertible, and by the chain rule
//!
//! ```text
//! dz/ds = (dz/dt)(dt/ds) = f(z) / σ(z, t),        dt/ds = 1 / σ(z, t).
//! ```
//!
//! Integrating this system in the independent variable s from s_k = S(z_k, t_k), the last
//! state before the crossing, to s = 0 lands on the surface: the surface value is now the
//! clock, and a step of size −s_k reaches it. The printed form dz/dS = f/(∇S·f),
//! dt/dS = 1/(∇S·f) is the same once t counts among the coordinates (then ∇S·f includes
//! ∂S/∂t·1); for a surface that depends on t explicitly, σ must include ∂S/∂t. Checks of the
//! derivation (tests in `tests/core/sections.rs`): for S = t − t*, σ = 1 and the step is an
//! ordinary time step of t* − t_k; for S = q_j (Hénon's case) dq_j/ds = f_j/f_j = 1, so q_j
//! reaches 0 with s; on the harmonic oscillator q = cos t, the crossing of q = a from any
//! state before it is t* = arccos a to round-off; and dz/ds along the exact solution matches
//! the difference quotient (z(t + δ) − z(t − δ))/(S(t + δ) − S(t − δ)).
//!
//! The step is one step of the eighth-order Dormand–Prince method (DOP853's tableau, see
//! [`crate::methods::dop853`]) in s; its embedded error estimate splits it into equal
//! sub-steps when the crossing is nearly tangent (σ small, where s stops being a good clock),
//! and a last step of size −S(z*) from the result removes the step's own residue, so that the
//! located point lies on the surface to round-off. The gradient ∇S and ∂S/∂t are the
//! expression engine's exact derivatives ([`crate::expr`]). A point where σ has the wrong sign
//! at the last state before the crossing (the solution turns back within the step) is reached
//! from the state after it instead, stepping back in s.
//!
//! # What a run reports
//! - a **section**: every crossing of S = 0 in the chosen direction (`up`: S from negative to
//!   non-negative; `down`: the reverse; `both`), up to `max_points`, each with its t, q, p and
//!   H; or a **stroboscopic section** t = φ + kT (k = 0, 1, …, the times in (0, t_end]), located
//!   the same way with S = t − t* (one step of size t* − t_k in time);
//! - an **event**: the run ends at the `count`-th crossing of its surface (scipy's terminal
//!   events, DifferentialEquations.jl's ContinuousCallback), with that crossing's t as the
//!   stop's time.
//!
//! Pieces: [`spec`] (what is asked for and its limits), [`names`] (the names an expression
//! may use, for built-in and typed-in systems), [`surface`] (S and its gradient, compiled),
//! [`henon`] (the step), [`watch`] (the per-step detection beside a run), [`energy`] (an
//! initial momentum solved from the energy, for launching orbits on an energy surface).

pub mod energy;
pub mod henon;
pub mod names;
pub mod spec;
pub mod surface;
pub mod watch;

pub use energy::EnergyLevel;
pub use spec::{
    Direction, EventSpec, SectionSpec, StopWhen, SurfaceSpec, MAX_EVENT_COUNT, MAX_SECTION_POINTS,
};
pub use surface::{Crossings, Surface};
pub use watch::{Crossing, CrossingKind, SectionSummary, Watch};

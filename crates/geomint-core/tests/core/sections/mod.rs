//! Poincaré sections and events: Hénon's step checked against its derivation, sections of
//! Hénon–Heiles to round-off, located crossings on each method's own trajectory, events against
//! exact crossing times, and the bad inputs a section refuses.

mod henon;
mod henon_heiles;
mod inputs;
mod stroboscopic;

use std::sync::Arc;

use geomint_core::error::Field;
use geomint_core::methods::Method;
use geomint_core::run::Budget;
use geomint_core::sections::{Crossing, CrossingKind, SectionSummary};
use geomint_core::sections::{Direction, EventSpec, SectionSpec, SurfaceSpec};
use geomint_core::simulation::crossings::CrossingColumns;
use geomint_core::simulation::{Columns, Limits, Simulation, SimulationSpec, Watching};
use geomint_core::simulation::{Sample, SampleSink};
use geomint_core::systems::custom::{self, CustomDefinition, Damping, Energy, Expression, Mass};
use geomint_core::systems::{SystemInfo, SystemRef};

/// An expression at `system.<name>`.
pub fn expr(name: &str, text: &str) -> Expression {
    Expression {
        text: text.to_string(),
        field: Field::new("system").key(name),
    }
}

/// A separable definition with unit mass: coordinates, potential, damping and parameters.
pub fn separable(
    coordinates: &[&str],
    potential: &str,
    damping: Option<Damping>,
    parameters: &[(&str, f64)],
) -> Arc<SystemInfo> {
    let definition = CustomDefinition {
        field: Field::new("system"),
        name: None,
        coordinates: coordinates.iter().map(|c| c.to_string()).collect(),
        momenta: None,
        energy: Energy::Separable {
            mass: Mass::Scalar(expr("mass", "1")),
            potential: expr("potential", potential),
        },
        damping,
        parameters: parameters
            .iter()
            .map(|(n, v)| (n.to_string(), *v))
            .collect(),
        invariants: Vec::new(),
        positions: None,
        q0: None,
        p0: None,
    };
    custom::define(definition, "test").expect("a valid definition")
}

/// Hénon–Heiles: V = (x² + y²)/2 + x²y − y³/3.
pub fn henon_heiles() -> Arc<SystemInfo> {
    separable(&["x", "y"], "(x^2 + y^2)/2 + x^2*y - y^3/3", None, &[])
}

/// The driven damped Duffing oscillator x″ + δx′ − x + x³ = A cos ωt, as H = p²/2 − x²/2 + x⁴/4
/// − A x cos ωt with conformal damping γ = δ/2.
pub fn duffing(delta: f64, a: f64, omega: f64) -> Arc<SystemInfo> {
    separable(
        &["x"],
        "-x^2/2 + x^4/4 - A*x*cos(omega*t)",
        Some(Damping::Conformal {
            gamma: expr("damping.gamma", "delta/2"),
        }),
        &[("delta", delta), ("A", a), ("omega", omega)],
    )
}

/// A section `where` S = 0 in `direction`, at most `max_points`.
pub fn section(text: &str, direction: Direction, max_points: u64) -> SectionSpec {
    SectionSpec {
        surface: SurfaceSpec::Where {
            text: text.to_string(),
            direction,
        },
        max_points,
        field: Field::new("section"),
    }
}

/// A stroboscopic section at t ≡ φ (mod T).
pub fn stroboscopic(period: f64, phase: f64, max_points: u64) -> SectionSpec {
    SectionSpec {
        surface: SurfaceSpec::Stroboscopic { period, phase },
        max_points,
        field: Field::new("section"),
    }
}

/// The event ending a run at the `count`-th crossing of S = 0.
pub fn event(text: &str, direction: Direction, count: u64) -> EventSpec {
    EventSpec {
        text: text.to_string(),
        direction,
        count,
        field: Field::new("stop_when"),
    }
}

/// A simulation of `system` with one method, watching `watching`.
pub fn simulation(
    system: impl Into<SystemRef>,
    method: Method,
    (h, t_end): (f64, f64),
    (q0, p0): (&[f64], &[f64]),
    watching: Watching,
) -> Simulation {
    sampled_simulation(system, method, (h, t_end, None), (q0, p0), watching)
}

/// [`simulation`] with a sample every `every` steps (`None`: the default spacing).
pub fn sampled_simulation(
    system: impl Into<SystemRef>,
    method: Method,
    (h, t_end, every): (f64, f64, Option<u64>),
    (q0, p0): (&[f64], &[f64]),
    watching: Watching,
) -> Simulation {
    let mut spec = SimulationSpec::new(system, &[method], h, t_end);
    spec.q0 = Some(q0.to_vec());
    spec.p0 = Some(p0.to_vec());
    spec.every = every;
    let limits = Limits {
        max_steps: 100_000_000,
        max_samples: 1_000_000,
    };
    Simulation::prepare(&spec, &limits)
        .expect("a valid simulation")
        .watching(&watching)
        .expect("valid surfaces")
}

/// What one run produced: its last samples, its crossings and the section's summary.
#[derive(Default)]
pub struct Collected {
    /// The samples' times and energies.
    pub samples: Columns,
    /// The section's points.
    pub section: CrossingColumns,
    /// The event's points.
    pub events: CrossingColumns,
    /// The section's summary.
    pub summary: Option<SectionSummary>,
}

impl SampleSink for Collected {
    fn on_sample(&mut self, s: &Sample<'_>) {
        self.samples.t.push(s.t);
        self.samples.q.push(s.q.to_vec());
        self.samples.p.push(s.p.to_vec());
        self.samples.energy.push(s.energy);
    }

    fn on_crossing(&mut self, c: &Crossing<'_>) {
        match c.kind {
            CrossingKind::Section => self.section.push(c),
            CrossingKind::Event => self.events.push(c),
        }
    }

    fn on_section_end(&mut self, summary: &SectionSummary) {
        self.summary = Some(summary.clone());
    }
}

/// Runs the simulation's only method.
pub fn run(sim: &Simulation) -> (Collected, geomint_core::simulation::RunReport) {
    let mut collected = Collected::default();
    let outcome = sim
        .run_method(0, None, Budget::default(), &mut collected)
        .expect("the run succeeds");
    (collected, outcome)
}

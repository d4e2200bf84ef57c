//! 10⁶ Poincaré section points of Hénon–Heiles (y = 0, p_y > 0, E = 1/8) located by Hénon's
//! trick, at the accuracy the tests assert: |y| ≤ 1e-13 and |H − E| ≤ 1e-12 at every point, the
//! first 100 crossings of a regular orbit within 1e-10 of the adaptive reference; beside the peers
//! (heyoka.py, exact event detection on its Taylor polynomials; pynamicalsys) run at the same
//! accuracy by `benches/sections/peers.py`, each checked on the same bounds.
//!
//! geomint runs Blanes, Casas and Murua's processed eighth-order composition of velocity Verlet
//! at h = 0.1 (the largest step whose first 100 crossings stay within 1e-10 of the reference;
//! a watched run forms its output states only near the surface) from a chaotic start (x, y, p_x)
//! = (−0.2, 0, 0.1), p_y solved from E, through the same path as a request — a section and an
//! event on the same surface that ends the run at its 10⁶-th crossing — on the same potential
//! typed in (a definition compiled to machine code) and on the built-in system;
//! `GEOMINT_SECTION_SYSTEM=typed` or `builtin` runs one of them. `GEOMINT_SECTION_METHOD`
//! (kahan_li_8, whose step is 0.08; kahan_li_6, blanes_moan_srkn11) and `GEOMINT_SECTION_H` try
//! others; the bounds are asserted whatever the choice. The peers' ratios are to the first
//! system run.
//!
//! `scripts/bench-sections` sets up the peers' venv under target/ and runs this with
//! `GEOMINT_PEERS_PYTHON` pointing at it; `GEOMINT_SECTION_POINTS` (default 10⁶) sets the count.
//! `cargo bench --bench sections` alone runs geomint only.

use std::process::Command;
use std::time::Instant;

use geomint::core::error::Field;
use geomint::core::methods::composition::Scheme;
use geomint::core::methods::{Base, Method, MethodId};
use geomint::core::run::Budget;
use geomint::core::sections::{
    Crossing, Direction, EnergyLevel, EventSpec, SectionSpec, SectionSummary, SurfaceSpec,
};
use geomint::core::simulation::{Limits, Sample, SampleSink, Simulation, SimulationSpec, Watching};
use geomint::core::systems::custom::{self, CustomDefinition, Energy, Expression, Mass};
use geomint::core::systems::SystemRef;

const E: f64 = 0.125;
/// The steps of the processed and the plain eighth-order compositions at the bounds.
const H_PROCESSED: f64 = 0.1;
const H_PLAIN: f64 = 0.08;
const CHAOTIC: ([f64; 2], [f64; 2]) = ([-0.2, 0.0], [0.1, 0.0]);
const REGULAR: ([f64; 2], [f64; 2]) = ([0.1, 0.0], [0.05, 0.0]);

/// The built-in system, or the same potential typed in as text.
fn henon_heiles(built_in: bool) -> SystemRef {
    if built_in {
        return SystemRef::Id("henon_heiles".into());
    }
    let expr = |name: &str, text: &str| Expression {
        text: text.into(),
        field: Field::new("system").key(name),
    };
    let definition = CustomDefinition {
        field: Field::new("system"),
        name: Some("Hénon–Heiles".into()),
        coordinates: vec!["x".into(), "y".into()],
        momenta: None,
        energy: Energy::Separable {
            mass: Mass::Scalar(expr("mass", "1")),
            potential: expr("potential", "(x^2 + y^2)/2 + x^2*y - y^3/3"),
        },
        damping: None,
        parameters: Vec::new(),
        invariants: Vec::new(),
        positions: None,
        q0: None,
        p0: None,
    };
    SystemRef::Defined(custom::define(definition, "henon_heiles").expect("valid"))
}

/// The bounds of every point, and the first points kept.
#[derive(Default)]
struct Check {
    points: u64,
    max_y: f64,
    max_dh: f64,
    min_py: f64,
    first: Vec<[f64; 5]>,
    summary: Option<SectionSummary>,
}

impl SampleSink for Check {
    fn on_sample(&mut self, _: &Sample<'_>) {}

    fn on_crossing(&mut self, c: &Crossing<'_>) {
        if c.kind != geomint::core::sections::CrossingKind::Section {
            return;
        }
        if self.points == 0 {
            self.min_py = f64::INFINITY;
        }
        self.points += 1;
        self.max_y = self.max_y.max(c.q[1].abs());
        self.max_dh = self.max_dh.max((c.energy - E).abs());
        self.min_py = self.min_py.min(c.p[1]);
        if self.first.len() < 100 {
            self.first.push([c.t, c.q[0], c.q[1], c.p[0], c.p[1]]);
        }
    }

    fn on_section_end(&mut self, summary: &SectionSummary) {
        self.summary = Some(summary.clone());
    }
}

/// `points` crossings from `start` with `method`; the check and the wall time in seconds.
fn run(
    system: SystemRef,
    method: Method,
    h: f64,
    start: ([f64; 2], [f64; 2]),
    points: u64,
) -> (Check, f64) {
    let mut spec = SimulationSpec::new(system, &[method], h, 10.0 * points as f64);
    spec.q0 = Some(start.0.to_vec());
    spec.p0 = Some(start.1.to_vec());
    spec.every = Some(u64::MAX / 4);
    let limits = Limits {
        max_steps: u64::MAX,
        max_samples: u64::MAX,
    };
    let surface = |field: &str| (Field::new(field), "y".to_string(), Direction::Up);
    let (section_field, text, direction) = surface("section");
    let watching = Watching {
        section: Some(SectionSpec {
            surface: SurfaceSpec::Where {
                text: text.clone(),
                direction,
            },
            max_points: points,
            field: section_field,
        }),
        stop_when: Some(EventSpec {
            text,
            direction,
            count: points,
            field: Field::new("stop_when"),
        }),
        energy: Some(EnergyLevel {
            energy: E,
            momentum: "p_y".into(),
            field: Field::new("energy"),
        }),
    };
    let sim = Simulation::prepare(&spec, &limits)
        .and_then(|s| s.watching(&watching))
        .expect("a valid simulation");
    let mut check = Check::default();
    let started = Instant::now();
    sim.run_method(0, None, Budget::default(), &mut check)
        .expect("runs");
    (check, started.elapsed().as_secs_f64())
}

fn main() {
    let points: u64 = std::env::var("GEOMINT_SECTION_POINTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_000_000);
    let (method, default_h) = match std::env::var("GEOMINT_SECTION_METHOD").as_deref() {
        Ok("blanes_moan_srkn11") => (Method::new(MethodId::BlanesMoanSrkn11), H_PLAIN),
        Ok("kahan_li_6") => (
            Method::composition(
                Scheme::of(MethodId::KahanLi6).unwrap(),
                Base::VelocityVerlet,
            ),
            H_PLAIN,
        ),
        Ok("kahan_li_8") => (
            Method::composition(
                Scheme::of(MethodId::KahanLi8).unwrap(),
                Base::VelocityVerlet,
            ),
            H_PLAIN,
        ),
        _ => (
            Method::composition(
                Scheme::of(MethodId::BlanesCasasMurua8).unwrap(),
                Base::VelocityVerlet,
            ),
            H_PROCESSED,
        ),
    };
    let h: f64 = std::env::var("GEOMINT_SECTION_H")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default_h);

    let systems: &[(&str, bool)] = match std::env::var("GEOMINT_SECTION_SYSTEM").as_deref() {
        Ok("builtin") => &[("built-in", true)],
        Ok("typed") => &[("typed in", false)],
        _ => &[("typed in", false), ("built-in", true)],
    };
    let mut rows = Vec::new();
    for &(label, built_in) in systems {
        // The first 100 crossings of a regular orbit against the adaptive reference.
        let system = henon_heiles(built_in);
        let (ours, _) = run(system.clone(), method.clone(), h, REGULAR, 100);
        let reference = Method::Reference { tolerance: 1e-14 };
        let (reference, _) = run(system.clone(), reference, h, REGULAR, 100);
        let agreement = ours
            .first
            .iter()
            .zip(&reference.first)
            .map(|(a, b)| {
                a.iter()
                    .zip(b)
                    .map(|(x, y)| (x - y).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        let (check, seconds) = run(system, method.clone(), h, CHAOTIC, points);
        println!(
            "geomint {} on the {label} system, h = {h}: {} points in {seconds:.2} s ({:.0} ns per \
             point); |y| ≤ {:.1e}, |H − E| ≤ {:.1e}, least p_y {:.1e}, unlocated {}; the first \
             100 crossings of the regular orbit within {agreement:.1e} of the reference",
            method.label(),
            check.points,
            seconds * 1e9 / check.points as f64,
            check.max_y,
            check.max_dh,
            check.min_py,
            check.summary.as_ref().map_or(0, |s| s.unlocated),
        );
        assert_eq!(check.points, points);
        assert!(check.max_y <= 1e-13 && check.max_dh <= 1e-12 && agreement <= 1e-10);
        assert!(
            check.min_py > 0.0,
            "a point against the section's direction"
        );
        rows.push((label, check, seconds));
    }
    let seconds = rows[0].2;

    let Ok(python) = std::env::var("GEOMINT_PEERS_PYTHON") else {
        println!("(set GEOMINT_PEERS_PYTHON, or run scripts/bench-sections, for the peers)");
        return;
    };
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/sections/peers.py");
    let output = Command::new(python)
        .arg(script)
        .arg(points.to_string())
        .output()
        .expect("the peers' script runs");
    print!("{}", String::from_utf8_lossy(&output.stdout));
    eprint!("{}", String::from_utf8_lossy(&output.stderr));
    println!("| peer | points | seconds | ratio to geomint (first) | max abs y | max abs H − E |");
    println!("|---|---|---|---|---|---|");
    for (label, check, s) in &rows {
        println!(
            "| geomint ({label}) | {} | {s:.2} | {:.2} | {:.1e} | {:.1e} |",
            check.points,
            s / seconds,
            check.max_y,
            check.max_dh
        );
    }
    for line in String::from_utf8_lossy(&output.stdout).lines() {
        let Ok(row) = serde_json::from_str::<serde_json::Value>(line) else {
            continue;
        };
        let s = row["seconds"].as_f64().unwrap_or(f64::NAN);
        println!(
            "| {} | {} | {s:.2} | {:.2} | {:.1e} | {:.1e} |",
            row["peer"].as_str().unwrap_or("?"),
            row["points"],
            s / seconds,
            row["max_y"].as_f64().unwrap_or(f64::NAN),
            row["max_dh"].as_f64().unwrap_or(f64::NAN),
        );
    }
}

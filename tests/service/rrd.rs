//! Rerun recordings read back with Rerun's own decoder (`re_log_encoding`, the crate the viewer
//! uses): entity paths, timelines, row counts, the blueprint, and the energies bit for bit
//! against the JSON document, also for a run of 10⁶ samples (its writing time is measured by
//! `cargo bench --bench recording`).

use std::collections::BTreeSet;

use geomint::api::system::NoStoredSystems;
use geomint::api::SimulateRequest;
use geomint::core::run::Budget;
use geomint::core::simulation::Limits;
use geomint::core::simulation::SimulationDocument;
use geomint::recording::{self, APPLICATION_ID};
use geomint::recording::{path_blocks, MAX_PATH_ROWS};

use crate::decoded;
use decoded::Decoded;
use serde_json::{json, Value};

/// A run as the service answers it: the JSON text, and the recording.
struct Run {
    doc: SimulationDocument,
    json: String,
    rrd: Vec<u8>,
}

impl Run {
    /// Runs a request like the service does.
    fn of(body: Value, limits: &Limits) -> Run {
        let spec = SimulateRequest::from_value(&body).expect("valid request");
        let sim = spec
            .prepare(limits, &NoStoredSystems)
            .expect("valid simulation");
        let doc = sim.simulate(2, Budget::default()).expect("runs");
        let json = serde_json::to_string(&doc).unwrap();
        let rrd = recording::rrd_bytes(&recording::Spec::of(&spec), &doc).expect("recording");
        Run { doc, json, rrd }
    }

    /// Asserts that `decoded` are the values of `field` of run `index`, bit for bit: equal to
    /// the document's numbers, and printing as the same JSON text as the answer carries.
    fn assert_column(&self, index: usize, field: &str, decoded: &[(i64, f64)]) {
        let run = &self.doc.runs[index];
        let c = &run.columns;
        let want: &[f64] = match field {
            "energy" => &c.energy,
            "energy_error" => c.energy_error.as_deref().unwrap(),
            name => &c.invariants[name],
        };
        let got: Vec<f64> = decoded.iter().map(|r| r.1).collect();
        assert_eq!(got.len(), want.len(), "{} {field}", run.method);
        for (k, (a, b)) in got.iter().zip(want).enumerate() {
            assert_eq!(a.to_bits(), b.to_bits(), "{} {field}[{k}]", run.method);
        }
        let text = format!("\"{field}\":{}", serde_json::to_string(&got).unwrap());
        assert!(self.json.contains(&text), "{} {field} as JSON", run.method);
    }
}

#[test]
fn pendulum_recording_has_the_layout_and_the_json_energies() {
    let run = Run::of(
        json!({"system": "pendulum", "params": {"epsilon": 0.01},
            "methods": ["modin_3s", {"id": "modin_rks", "inner": "rk4"}],
            "h": 0.1, "t_end": 200, "q0": [2.827433], "p0": [0.0], "output": {"every": 10}}),
        &Limits::default(),
    );
    let d = Decoded::of(&run.rrd);
    assert_eq!(
        d.application_ids,
        BTreeSet::from([APPLICATION_ID.to_string()])
    );
    assert_eq!(d.recording_stores.len(), 1);
    assert_eq!(d.blueprint_stores.len(), 1);
    assert_eq!(d.activations, 1);

    assert_eq!(
        d.entity_paths(),
        decoded::simulation_entities(&["modin_3s", "modin_rks_rk4"])
    );

    // 200/0.1 = 2000 steps sampled every 10: 201 samples per method, 201 path rows (the first
    // sample alone, then one segment per sample).
    let samples = 201;
    assert_eq!(path_blocks(samples).len(), samples);
    for (i, m) in ["modin_3s", "modin_rks_rk4"].iter().enumerate() {
        assert_eq!(run.doc.runs[i].method, ["modin_3s", "modin_rks(rk4)"][i]);
        for path in [
            "energy",
            "phase/0/point",
            "phase/0/path",
            "world/bodies",
            "world/path",
        ] {
            let path = format!("/{m}/{path}");
            assert_eq!(d.rows(&path), samples, "{path}");
            assert_eq!(
                d.timelines(&path),
                BTreeSet::from(["step".to_string(), "t".to_string()]),
                "{path}"
            );
        }
        let decoded = d.scalars(&format!("/{m}/energy"));
        let steps: Vec<i64> = decoded.iter().map(|r| r.0).collect();
        assert_eq!(steps, (0..=2000).step_by(10).collect::<Vec<i64>>());
        run.assert_column(i, "energy", &decoded);
        // The force evaluations: one row, at the last step, equal to the statistics.
        let fe = d.scalars(&format!("/{m}/force_evaluations"));
        assert_eq!(
            fe,
            [(2000, run.doc.runs[i].outcome.stats.force_evaluations as f64)]
        );
    }
    // The t timeline is in nanoseconds: the last sample is at 200 s.
    let chunk = d.chunks["/modin_3s/energy"]
        .iter()
        .find(|c| !c.is_static())
        .unwrap();
    let t = chunk.timelines()[&"t".into()].times_raw();
    assert_eq!(*t.last().unwrap(), 200_000_000_000);
    // The bob on its rod: (sin q, 0, −cos q) and a segment from the origin to it.
    let bodies = d.chunks["/modin_3s/world/bodies"]
        .iter()
        .find(|c| !c.is_static())
        .unwrap();
    let positions: Vec<[f32; 3]> = bodies
        .iter_slices::<[f32; 3]>(rerun::Points3D::descriptor_positions().component)
        .flat_map(|s| s.to_vec())
        .collect();
    let q0 = 2.827433f64;
    assert_eq!(positions[0], [q0.sin() as f32, 0.0, -q0.cos() as f32]);
    let rods = bodies
        .iter_component_offsets(rerun::LineStrips3D::descriptor_strips().component)
        .count();
    assert_eq!(rods, samples);

    // The blueprint: views, containers, the viewport, and the growing paths' time ranges.
    let bp = &d.blueprint_entities;
    assert!(bp.contains("/viewport"), "{bp:?}");
    let views = bp
        .iter()
        .filter(|p| p.starts_with("/view/") && p.matches('/').count() == 2)
        .count();
    // energy, force evaluations, world, spec, one phase view.
    assert_eq!(views, 5, "{bp:?}");
    let trails: BTreeSet<&str> = bp
        .iter()
        .filter_map(|p| p.split("/ViewContents/overrides").nth(1))
        .collect();
    assert_eq!(
        trails,
        BTreeSet::from([
            "/modin_3s/world/path/visualizers",
            "/modin_rks_rk4/world/path/visualizers",
            "/modin_3s/phase/0/path/visualizers",
            "/modin_rks_rk4/phase/0/path/visualizers",
        ])
    );
}

#[test]
fn energy_errors_invariants_and_bodies_have_their_entities() {
    // The oscillator has an exact solution, so energy errors; the elastic pendulum an
    // invariant and a spring; three bodies nine degrees of freedom, six phase portraits.
    let run = Run::of(
        json!({"system": "harmonic_oscillator", "method": "csv1", "h": 0.05, "t_end": 10}),
        &Limits::default(),
    );
    let d = Decoded::of(&run.rrd);
    let decoded = d.scalars("/csv1/energy_error");
    assert_eq!(decoded.len(), 201);
    run.assert_column(0, "energy_error", &decoded);

    let run = Run::of(
        json!({"system": "elastic_pendulum_3d", "methods": ["modin_3s", "modin_3s"],
            "h": 0.1, "t_end": 20, "output": {"every": 4}}),
        &Limits::default(),
    );
    let d = Decoded::of(&run.rrd);
    let decoded = d.scalars("/modin_3s_2/invariants/J3");
    assert_eq!(decoded.len(), 51);
    run.assert_column(1, "J3", &decoded);
    assert_eq!(d.rows("/modin_3s/world/bodies"), 51);
    assert!(d.chunks.contains_key("/modin_3s/phase/2/path"));
    assert!(!d.chunks.contains_key("/modin_3s/phase/3/path"));

    let run = Run::of(
        json!({"system": "nbody", "method": "csv1", "h": 0.01, "t_end": 1}),
        &Limits::default(),
    );
    let d = Decoded::of(&run.rrd);
    let phases: BTreeSet<&str> = d
        .chunks
        .keys()
        .filter_map(|p| p.strip_prefix("/csv1/phase/"))
        .filter_map(|p| p.strip_suffix("/path"))
        .collect();
    assert_eq!(phases, BTreeSet::from(["0", "1", "2", "3", "4", "5"]));
    // Three bodies per row, one path piece per body, no link to the origin.
    let positions = rerun::Points3D::descriptor_positions().component;
    let strips = rerun::LineStrips3D::descriptor_strips().component;
    for (path, component) in [
        ("/csv1/world/bodies", positions),
        ("/csv1/world/path", strips),
    ] {
        let chunk = d.chunks[path].iter().find(|c| !c.is_static()).unwrap();
        let lengths: BTreeSet<usize> = chunk
            .iter_component_offsets(component)
            .map(|span| span.len)
            .collect();
        assert_eq!(lengths, BTreeSet::from([3]), "{path}");
    }
    let bodies = d.chunks["/csv1/world/bodies"]
        .iter()
        .find(|c| !c.is_static())
        .unwrap();
    assert_eq!(bodies.iter_component_offsets(strips).count(), 0);
    assert_eq!(d.rows("/csv1/world/bodies"), 101);
}

#[test]
fn a_million_samples_make_a_complete_recording() {
    let limits = Limits {
        max_steps: 10_000_000,
        max_samples: 2_000_000,
    };
    let spec = SimulateRequest::from_value(&json!({"system": "pendulum", "method": "modin_3s",
        "h": 0.001, "t_end": 1000, "output": {"every": 1}}))
    .unwrap();
    let sim = spec.prepare(&limits, &NoStoredSystems).unwrap();
    let doc = sim.simulate(1, Budget::default()).unwrap();
    assert_eq!(doc.runs[0].columns.energy.len(), 1_000_001);
    let bytes = recording::rrd_bytes(&recording::Spec::of(&spec), &doc).unwrap();
    let d = Decoded::of(&bytes);
    assert_eq!(d.rows("/modin_3s/energy"), 1_000_001);
    assert_eq!(d.rows("/modin_3s/world/bodies"), 1_000_001);
    assert_eq!(d.rows("/modin_3s/world/path"), MAX_PATH_ROWS + 1);
}

/// The threads of this process (Linux).
fn threads() -> usize {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let line = status
        .lines()
        .find(|l| l.starts_with("Threads:"))
        .expect("a Threads line");
    line["Threads:".len()..]
        .trim()
        .parse()
        .expect("a thread count")
}

#[test]
fn recordings_leave_nothing_behind_in_the_process() {
    let body = json!({"system": "elastic_pendulum_3d", "methods": ["modin_3s", "heun"],
        "h": 0.01, "t_end": 10});
    let first = Run::of(body.clone(), &Limits::default());
    // Each recording's streams end with it. (Rerun's memory sink held its own stream, a cycle
    // that kept every blueprint stream and its batcher threads alive: a server writing
    // recordings grew by two threads and about 200 kB of memory per recording.) Other tests of
    // this binary start threads of their own meanwhile, hence the margin; 40 leaks would be 80.
    let before = threads();
    for _ in 0..40 {
        Run::of(body.clone(), &Limits::default());
    }
    let after = threads();
    assert!(
        after < before + 20,
        "{before} threads before 40 recordings, {after} after"
    );
    // The same layout gives the same blueprint paths (Rerun interns entity paths for the life of
    // the process; random ids would grow that table with every recording).
    let again = Run::of(body, &Limits::default());
    let (a, b) = (Decoded::of(&first.rrd), Decoded::of(&again.rrd));
    assert!(
        a.blueprint_entities.iter().any(|p| p.contains("/view/")),
        "{:?}",
        a.blueprint_entities
    );
    assert_eq!(a.blueprint_entities, b.blueprint_entities);
}

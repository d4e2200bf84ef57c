//! A simulation streamed in chunks makes the document of the whole run.

use std::sync::Mutex;

use geomint_core::error::{ErrorCode, ErrorDetail};
use geomint_core::methods::{Inner, Method, MethodId};
use geomint_core::run::Budget;
use geomint_core::simulation::document::{ColumnSink, Columns};
use geomint_core::simulation::stream::*;
use geomint_core::simulation::{Limits, Simulation, SimulationSpec};

#[test]
fn columns_extend_appends_every_column() {
    let chunk = |t: f64| Columns {
        t: vec![t],
        q: vec![vec![t]],
        p: vec![vec![-t]],
        cartesian_q: Some(vec![vec![10.0 * t]]),
        cartesian_p: Some(vec![vec![-10.0 * t]]),
        energy: vec![2.0 * t],
        energy_error: Some(vec![t / 2.0]),
        invariants: [("J3".to_string(), vec![3.0 * t])].into(),
        jacobian_defect: None,
        bodies: Some(vec![vec![t, 2.0 * t]]),
        ..Columns::default()
    };
    let mut all = Columns::with_invariants(&["J3"]);
    all.extend(chunk(1.0));
    all.extend(chunk(2.0));
    assert_eq!(all.t, [1.0, 2.0]);
    assert_eq!(all.q, [[1.0], [2.0]]);
    assert_eq!(all.cartesian_q, Some(vec![vec![10.0], vec![20.0]]));
    assert_eq!(all.cartesian_p, Some(vec![vec![-10.0], vec![-20.0]]));
    assert_eq!(all.energy_error, Some(vec![0.5, 1.0]));
    assert_eq!(all.invariants["J3"], [3.0, 6.0]);
    assert_eq!(all.jacobian_defect, None);
    assert_eq!(all.bodies, Some(vec![vec![1.0, 2.0], vec![2.0, 4.0]]));
}

#[test]
fn the_collected_stream_holds_every_sample_of_each_run() {
    // Two methods, 1001 samples each: several chunks per method, interleaved over two
    // threads; an exact solution (energy errors) and the dissipation drift of a 1-DOF
    // system. The document assembled from the chunks equals each run made in one piece.
    let methods = [
        Method::Plain(MethodId::Modin3s),
        Method::ModinRks { inner: Inner::Rk4 },
    ];
    let mut spec =
        SimulationSpec::new("harmonic_oscillator", &methods, 0.01, 50.0).param("epsilon", 0.05);
    spec.every = Some(5);
    let sim = Simulation::prepare(&spec, &Limits::default()).unwrap();
    let collector = Mutex::new(DocumentCollector::new());
    let chunks = Mutex::new(0usize);
    let emit = |line: StreamLine| {
        if let StreamLine::Samples(_) = line {
            *chunks.lock().unwrap() += 1;
        }
        collector.lock().unwrap().push(line);
        true
    };
    sim.stream(2, Budget::default(), &emit);
    assert!(chunks.into_inner().unwrap() >= 8);
    let mut collected = collector.into_inner().unwrap().finish().unwrap();
    assert_eq!(collected.runs.len(), 2);
    for (i, run) in collected.runs.iter_mut().enumerate() {
        let mut whole = ColumnSink::new(sim.invariant_names());
        let outcome = sim
            .run_method(i, None, Budget::default(), &mut whole)
            .unwrap();
        let whole = whole.take();
        assert_eq!(run.columns.len(), 1001);
        assert!(run.columns.energy_error.is_some());
        assert_eq!(
            serde_json::to_string(&run.columns).unwrap(),
            serde_json::to_string(&whole).unwrap()
        );
        assert_eq!(run.outcome.stats.steps, outcome.stats.steps);
        let q: Vec<f64> = whole.q.iter().map(|q| q[0]).collect();
        assert_eq!(
            run.outcome.dissipation_drift,
            sim.dissipation_drift(&whole.t, &q)
        );
    }
}

#[test]
fn a_stream_cut_short_or_failed_makes_no_document() {
    let spec = SimulationSpec::new(
        "harmonic_oscillator",
        &[Method::Plain(MethodId::Csv1)],
        0.1,
        1.0,
    );
    let sim = Simulation::prepare(&spec, &Limits::default()).unwrap();
    let mut collector = DocumentCollector::new();
    collector.push(StreamLine::Header(sim.header()));
    assert_eq!(collector.finish().unwrap_err().code, ErrorCode::Internal);
    let mut collector = DocumentCollector::new();
    collector.push(StreamLine::Header(sim.header()));
    collector.push(StreamLine::Error(StreamError {
        method: None,
        error: ErrorDetail::new(ErrorCode::Timeout, "late"),
    }));
    collector.push(StreamLine::End);
    assert_eq!(collector.finish().unwrap_err().code, ErrorCode::Timeout);
}

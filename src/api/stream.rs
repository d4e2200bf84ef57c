//! The NDJSON form of a simulation: one JSON object per line, written as the runs compute.
//!
//! 1. a `header` line: the system, the method labels, the invariant names and the schedule;
//! 2. `samples` lines: column chunks of one method (`method` is its index in the header), at
//!    most [`CHUNK_SAMPLES`] samples each, flushed at least every [`CHUNK_INTERVAL`] while
//!    samples come; `offset` is the index of the chunk's first sample in its run;
//! 3. a `summary` line per method once it ends (how it stopped, statistics, sample count);
//! 4. an `error` line if something fails that is not part of one run's outcome;
//! 5. a final `end` line — a stream without it was cut short.
//!
//! Lines of different methods interleave when they run in parallel; the lines of one method
//! come in order, its summary after its last chunk. [`DocumentCollector`] assembles the JSON
//! document from the lines, so that one run can feed several outputs (see
//! [`crate::recording::live`]).

use std::time::{Duration, Instant};

use serde::Serialize;
use utoipa::ToSchema;

use super::document::{
    dissipation_drift, failed, for_each_method, reference_energies, ColumnSink, Columns,
    DivergedAt, DriftPoint, RunDocument, ScheduleSummary, SimulationDocument, Stats, Stop,
    SystemSummary,
};
use super::error::{codes, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulate::{Sample, SampleSink, Simulation};

/// Most samples per `samples` line.
pub const CHUNK_SAMPLES: usize = 256;
/// Longest time samples wait before their chunk is written.
pub const CHUNK_INTERVAL: Duration = Duration::from_millis(50);

/// One line of an NDJSON simulation stream.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum StreamLine {
    /// The first line.
    Header(StreamHeader),
    /// A chunk of one method's samples.
    Samples(SamplesChunk),
    /// One method's run has ended.
    Summary(RunSummary),
    /// A failure outside any one run's outcome (the reference run, a server fault).
    Error(StreamError),
    /// The last line of a complete stream.
    End,
}

/// What the stream will contain.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct StreamHeader {
    /// The system, parameters resolved.
    pub system: SystemSummary,
    /// Method labels; `method` in later lines indexes this list.
    pub methods: Vec<String>,
    /// Names of the invariants in each chunk's `invariants`.
    pub invariants: Vec<String>,
    /// Whether chunks carry `energy_error`.
    pub energy_error: bool,
    /// Whether chunks carry `jacobian_defect`.
    pub jacobian_defect: bool,
    /// The sampling.
    pub schedule: ScheduleSummary,
}

/// A chunk of one method's samples.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct SamplesChunk {
    /// Index of the method in the header's `methods`.
    pub method: usize,
    /// Index of this chunk's first sample within the run.
    pub offset: u64,
    /// The samples.
    #[serde(flatten)]
    pub columns: Columns,
}

/// How one method's run ended.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct RunSummary {
    /// Index of the method in the header's `methods`.
    pub method: usize,
    /// The method's label.
    pub label: String,
    /// Samples sent for this method.
    pub samples: u64,
    /// The dissipation drift (1-DOF systems with conformal damping only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dissipation_drift: Option<Vec<DriftPoint>>,
    /// Where the run diverged (null unless it did).
    pub diverged_at: Option<DivergedAt>,
    /// Why it stopped.
    pub stop: Stop,
    /// Statistics.
    pub stats: Stats,
}

/// A failure reported inside a stream.
#[derive(Clone, Debug, PartialEq, Serialize, ToSchema)]
pub struct StreamError {
    /// The method concerned, if any.
    pub method: Option<usize>,
    /// What went wrong.
    pub error: ErrorDetail,
}

/// Receives the lines of a stream; returns false once nobody listens any more (the producer
/// then stops sending, and the caller should cancel the runs).
pub type Emit<'a> = &'a (dyn Fn(StreamLine) -> bool + Sync);

/// A line as NDJSON: compact JSON and a newline.
pub fn ndjson_line(line: &StreamLine) -> Vec<u8> {
    let mut out = serde_json::to_vec(line).unwrap_or_else(|e| {
        // Serializing these types cannot fail (non-finite floats become null).
        format!(r#"{{"type":"error","method":null,"error":{{"code":"internal","message":"{e}","field":null}}}}"#)
            .into_bytes()
    });
    out.push(b'\n');
    out
}

/// Chunks one method's samples into `samples` lines.
struct ChunkSink<'a> {
    method: usize,
    buffer: ColumnSink,
    offset: u64,
    last_flush: Instant,
    emit: Emit<'a>,
    open: bool,
    /// Times and positions kept for the dissipation drift (1-DOF systems only).
    kept: Option<(Vec<f64>, Vec<Vec<f64>>)>,
}

impl ChunkSink<'_> {
    fn flush(&mut self) {
        if self.buffer.is_empty() || !self.open {
            return;
        }
        let n = self.buffer.len() as u64;
        let line = StreamLine::Samples(SamplesChunk {
            method: self.method,
            offset: self.offset,
            columns: self.buffer.take(),
        });
        self.open = (self.emit)(line);
        self.offset += n;
        self.last_flush = Instant::now();
    }
}

impl SampleSink for ChunkSink<'_> {
    fn on_sample(&mut self, sample: &Sample<'_>) {
        if !self.open {
            return;
        }
        if let Some((t, q)) = &mut self.kept {
            t.push(sample.t);
            q.push(sample.q.to_vec());
        }
        self.buffer.on_sample(sample);
        if self.buffer.len() >= CHUNK_SAMPLES || self.last_flush.elapsed() >= CHUNK_INTERVAL {
            self.flush();
        }
    }
}

/// Runs method `index`, sending its chunks and then its summary to `emit`.
pub fn stream_method(
    sim: &Simulation,
    index: usize,
    reference: Option<&[f64]>,
    budget: Budget<'_>,
    emit: Emit<'_>,
) {
    let mut sink = ChunkSink {
        method: index,
        buffer: ColumnSink::new(sim.invariant_names()),
        offset: 0,
        last_flush: Instant::now(),
        emit,
        open: true,
        kept: (sim.q0.len() == 1).then(|| (Vec::new(), Vec::new())),
    };
    let started = Instant::now();
    let result = sim.run_method(index, reference, budget, &mut sink);
    sink.flush();
    let (stop, stats) = match result {
        Ok(outcome) => (Stop::from(outcome.stop), Stats::from(outcome.stats)),
        Err(e) => {
            tracing::warn!(method = %sim.methods[index].label(), error = %e, "run failed");
            let stop = failed(e);
            let steps = match stop {
                Stop::Failed { step, .. } => step.saturating_sub(1),
                _ => 0,
            };
            let stats = Stats {
                steps,
                force_evaluations: 0,
                wall_time_ms: started.elapsed().as_secs_f64() * 1e3,
            };
            (stop, stats)
        }
    };
    if sink.open {
        emit(StreamLine::Summary(RunSummary {
            method: index,
            label: sim.methods[index].label(),
            samples: sink.offset,
            dissipation_drift: sink
                .kept
                .as_ref()
                .and_then(|(t, q)| dissipation_drift(sim, t, q)),
            diverged_at: stop.diverged_at(),
            stop,
            stats,
        }));
    }
}

/// The header line of `sim`'s stream.
pub fn header(sim: &Simulation) -> StreamHeader {
    StreamHeader {
        system: SystemSummary::of(sim),
        methods: sim.methods.iter().map(|m| m.label()).collect(),
        invariants: sim
            .invariant_names()
            .iter()
            .map(|s| s.to_string())
            .collect(),
        energy_error: sim.has_energy_error(),
        jacobian_defect: sim.jacobian_defect,
        schedule: ScheduleSummary::of(sim),
    }
}

/// Streams a whole simulation: header, the reference run if asked for, every method (on up to
/// `workers` threads), and the `end` line.
pub fn stream(sim: &Simulation, workers: usize, budget: Budget<'_>, emit: Emit<'_>) {
    if !emit(StreamLine::Header(header(sim))) {
        return;
    }
    let reference = match reference_energies(sim, budget) {
        Ok(r) => r,
        Err(error) => {
            emit(StreamLine::Error(StreamError {
                method: None,
                error,
            }));
            emit(StreamLine::End);
            return;
        }
    };
    for_each_method(sim.methods.len(), workers, |i| {
        stream_method(sim, i, reference.as_deref(), budget, emit)
    });
    emit(StreamLine::End);
}

/// Assembles the [`SimulationDocument`] of a stream from its lines: the header's system,
/// schedule and invariants, each method's chunks appended in order, its summary's outcome. The
/// document equals the one [`super::simulate`] computes for the same simulation (up to wall
/// times).
#[derive(Debug, Default)]
pub struct DocumentCollector {
    header: Option<StreamHeader>,
    columns: Vec<Columns>,
    summaries: Vec<Option<RunSummary>>,
    error: Option<ErrorDetail>,
    ended: bool,
}

impl DocumentCollector {
    /// A collector that has seen no line.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes in the next line of the stream.
    pub fn push(&mut self, line: StreamLine) {
        match line {
            StreamLine::Header(header) => {
                self.columns =
                    vec![Columns::with_invariants(&header.invariants); header.methods.len()];
                self.summaries = vec![None; header.methods.len()];
                self.header = Some(header);
            }
            StreamLine::Samples(chunk) => match self.columns.get_mut(chunk.method) {
                Some(columns) if columns.len() as u64 == chunk.offset => {
                    columns.extend(chunk.columns)
                }
                _ => self.fail(format!(
                    "samples of method {} from {} do not continue its run",
                    chunk.method, chunk.offset
                )),
            },
            StreamLine::Summary(summary) => match self.summaries.get_mut(summary.method) {
                Some(slot) => *slot = Some(summary),
                None => self.fail(format!("a summary of method {}", summary.method)),
            },
            StreamLine::Error(e) => {
                self.error.get_or_insert(e.error);
            }
            StreamLine::End => self.ended = true,
        }
    }

    fn fail(&mut self, message: String) {
        self.error
            .get_or_insert_with(|| ErrorDetail::new(codes::INTERNAL, message));
    }

    /// The document, once the stream has ended; the stream's error if it reported one.
    pub fn finish(self) -> Result<SimulationDocument, ErrorDetail> {
        if let Some(error) = self.error {
            return Err(error);
        }
        let cut = |what: &str| ErrorDetail::new(codes::INTERNAL, format!("the stream {what}"));
        let header = self.header.ok_or_else(|| cut("has no header"))?;
        if !self.ended {
            return Err(cut("was cut short"));
        }
        let runs = self
            .columns
            .into_iter()
            .zip(self.summaries)
            .map(|(columns, summary)| {
                let s = summary.ok_or_else(|| cut("lacks a summary"))?;
                Ok(RunDocument {
                    method: s.label,
                    columns,
                    dissipation_drift: s.dissipation_drift,
                    diverged_at: s.diverged_at,
                    stop: s.stop,
                    stats: s.stats,
                })
            })
            .collect::<Result<_, ErrorDetail>>()?;
        Ok(SimulationDocument {
            system: header.system,
            schedule: header.schedule,
            invariants: header.invariants,
            runs,
        })
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use serde_json::json;

    use super::*;
    use crate::api::{simulate, SimulateRequest};
    use crate::core::simulate::Limits;

    /// The JSON of a document with its wall times zeroed (the only numbers that differ between
    /// two computations of the same runs).
    fn json_without_wall_times(mut doc: SimulationDocument) -> String {
        for run in &mut doc.runs {
            run.stats.wall_time_ms = 0.0;
        }
        serde_json::to_string(&doc).unwrap()
    }

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
    }

    #[test]
    fn collected_stream_equals_the_document() {
        // Two methods, 1001 samples each: several chunks per method, interleaved over two
        // threads; an exact solution (energy errors) and the dissipation drift of a 1-DOF system.
        let spec = SimulateRequest::from_value(&json!({"system": "harmonic_oscillator",
            "params": {"epsilon": 0.05}, "methods": ["modin_3s", {"id": "modin_rks", "inner": "rk4"}],
            "h": 0.01, "t_end": 50, "output": {"every": 5}}))
        .unwrap();
        let sim = spec.prepare(&Limits::default()).unwrap();
        let doc = simulate(&sim, 2, Budget::default()).unwrap();

        let collector = Mutex::new(DocumentCollector::new());
        let chunks = Mutex::new(0usize);
        let emit = |line: StreamLine| {
            if let StreamLine::Samples(_) = line {
                *chunks.lock().unwrap() += 1;
            }
            collector.lock().unwrap().push(line);
            true
        };
        stream(&sim, 2, Budget::default(), &emit);
        assert!(chunks.into_inner().unwrap() >= 8);
        let collected = collector.into_inner().unwrap().finish().unwrap();
        assert_eq!(collected.runs.len(), 2);
        assert_eq!(collected.runs[0].columns.len(), 1001);
        assert!(collected.runs[0].columns.energy_error.is_some());
        assert_eq!(
            json_without_wall_times(collected),
            json_without_wall_times(doc)
        );
    }

    #[test]
    fn a_stream_cut_short_or_failed_makes_no_document() {
        let spec = SimulateRequest::from_value(
            &json!({"system": "harmonic_oscillator", "method": "csv1", "h": 0.1, "t_end": 1}),
        )
        .unwrap();
        let sim = spec.prepare(&Limits::default()).unwrap();
        let mut collector = DocumentCollector::new();
        collector.push(StreamLine::Header(header(&sim)));
        assert_eq!(collector.finish().unwrap_err().code, codes::INTERNAL);
        let mut collector = DocumentCollector::new();
        collector.push(StreamLine::Header(header(&sim)));
        collector.push(StreamLine::Error(StreamError {
            method: None,
            error: ErrorDetail::new(codes::TIMEOUT, "late"),
        }));
        collector.push(StreamLine::End);
        assert_eq!(collector.finish().unwrap_err().code, codes::TIMEOUT);
    }
}

//! The one way a simulation runs: its methods in parallel, each sending its samples in chunks as
//! they are computed, as a sequence of typed lines ([`StreamLine`]). Every output is a consumer of
//! these lines: the NDJSON stream writes them, [`DocumentCollector`] assembles the JSON document
//! from them, a Rerun recording logs them.
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
//! come in order, its summary after its last chunk.

use std::time::{Duration, Instant};

use serde::Serialize;

use super::crossings::{CrossingColumns, CrossingsChunk, SurfaceInfo, SurfaceName};
use super::document::{
    ColumnSink, Columns, RunDocument, RunOutcome, ScheduleSummary, SimulationDocument, Stop,
    SystemSummary,
};
use super::run::{for_each_method, Sample, SampleSink};
use super::spec::{EnergyReference, Simulation};
use crate::chaos::{Indicator, IndicatorValues};
use crate::diagnostics::{self, DriftPoint};
use crate::error::{CoreError, ErrorCode, ErrorDetail};
use crate::run::{Budget, RunStats};
use crate::sections::{Crossing, CrossingKind, SectionSummary};

/// Most samples per `samples` line.
pub const CHUNK_SAMPLES: usize = 256;
/// Longest time samples wait before their chunk is written.
pub const CHUNK_INTERVAL: Duration = Duration::from_millis(50);

/// One line of a simulation's stream.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum StreamLine {
    /// The first line.
    Header(StreamHeader),
    /// A chunk of one method's samples.
    Samples(SamplesChunk),
    /// One method's run has ended.
    Summary(RunSummary),
    /// A chunk of one method's located crossings (of its section, or its event's surface).
    Crossings(CrossingsChunk),
    /// A failure outside any one run's outcome (the reference run, a server fault).
    Error(StreamError),
    /// The last line of a complete stream.
    End,
}

/// What the stream will contain.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct StreamHeader {
    /// The system, parameters resolved.
    pub system: SystemSummary,
    /// Method labels; `method` in later lines indexes this list.
    pub methods: Vec<String>,
    /// Names of the invariants in each chunk's `invariants`.
    pub invariants: Vec<String>,
    /// Whether chunks carry `energy_error` (they do not when a reference run asked for stopped at
    /// the time limit: the runs then stop at their first sample).
    pub energy_error: bool,
    /// What `energy_error` is measured against: `exact` (the exact solution), `reference` (the
    /// reference run), `initial` (H₀: nothing damps or drives the system, so its exact flow
    /// keeps H); absent when there is none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_reference: Option<EnergyReference>,
    /// Whether chunks carry `jacobian_defect`.
    pub jacobian_defect: bool,
    /// The chaos indicators chunks carry (absent when none were asked for).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub indicators: Vec<Indicator>,
    /// Deviation vectors per run (with `indicators`): the length of each `lyapunov` entry.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub deviations: Option<usize>,
    /// The sampling.
    pub schedule: ScheduleSummary,
    /// The section each run collects (`crossings` chunks with `surface` = `section`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub section: Option<SurfaceInfo>,
    /// The event that ends each run (`crossings` chunks with `surface` = `stop_when`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop_when: Option<SurfaceInfo>,
}

/// A chunk of one method's samples.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RunSummary {
    /// Index of the method in the header's `methods`.
    pub method: usize,
    /// The method's label.
    pub label: String,
    /// Samples sent for this method.
    pub samples: u64,
    /// How it ended.
    #[serde(flatten)]
    pub outcome: RunOutcome,
}

/// A failure reported inside a stream.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct StreamError {
    /// The method concerned, if any.
    pub method: Option<usize>,
    /// What went wrong.
    pub error: ErrorDetail,
}

/// Receives the lines of a stream; returns false once nobody listens any more (the producer
/// then stops sending, and the caller should cancel the runs).
pub type Emit<'a> = &'a (dyn Fn(StreamLine) -> bool + Sync);

/// Chunks one method's samples into `samples` lines.
struct ChunkSink<'a> {
    method: usize,
    buffer: ColumnSink,
    offset: u64,
    last_flush: Instant,
    emit: Emit<'a>,
    open: bool,
    /// Times and positions kept for the dissipation drift (1-DOF systems only).
    kept: Option<(Vec<f64>, Vec<f64>)>,
    /// Located crossings not yet sent: the section's and the event's, with their offsets.
    crossings: [(CrossingColumns, u64); 2],
    section_summary: Option<SectionSummary>,
    /// The indicators of the last sample.
    indicators: Option<IndicatorValues>,
}

impl ChunkSink<'_> {
    fn flush(&mut self) {
        for (i, surface) in [SurfaceName::Section, SurfaceName::StopWhen]
            .into_iter()
            .enumerate()
        {
            let (columns, offset) = &mut self.crossings[i];
            if columns.is_empty() || !self.open {
                continue;
            }
            let n = columns.len() as u64;
            let line = StreamLine::Crossings(CrossingsChunk {
                method: self.method,
                surface,
                offset: *offset,
                columns: std::mem::take(columns),
            });
            *offset += n;
            self.open = (self.emit)(line);
        }
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
            q.push(sample.q[0]);
        }
        if let Some(values) = sample.indicators {
            self.indicators = Some(values.clone());
        }
        self.buffer.on_sample(sample);
        if self.buffer.len() >= CHUNK_SAMPLES || self.last_flush.elapsed() >= CHUNK_INTERVAL {
            self.flush();
        }
    }

    fn on_crossing(&mut self, crossing: &Crossing<'_>) {
        let i = match crossing.kind {
            CrossingKind::Section => 0,
            CrossingKind::Event => 1,
        };
        self.crossings[i].0.push(crossing);
        // Points come far apart in steps: they go out with the next flush, at the latest
        // CHUNK_INTERVAL after the last.
        if self.crossings[i].0.len() >= CHUNK_SAMPLES || self.last_flush.elapsed() >= CHUNK_INTERVAL
        {
            self.flush();
        }
    }

    fn on_section_end(&mut self, summary: &SectionSummary) {
        self.section_summary = Some(summary.clone());
    }
}

impl Simulation {
    /// The dissipation drift of paper 003 eq. (4.4) from a run's sample times and positions,
    /// for a 1-DOF system with conformal damping; `None` for other systems.
    pub fn dissipation_drift(&self, t: &[f64], q: &[f64]) -> Option<Vec<DriftPoint>> {
        use crate::system::MechanicalSystem;
        let (conformal, rate) = crate::with_system!(&self.system, s => {
            (s.structure().conformal_damping, s.damping_rate())
        });
        (self.q0.len() == 1 && conformal).then(|| diagnostics::dissipation_drift(t, q, 0.5 * rate))
    }

    /// The header line of this simulation's stream.
    pub fn header(&self) -> StreamHeader {
        StreamHeader {
            system: SystemSummary::of(self),
            methods: self.methods.iter().map(|m| m.label()).collect(),
            invariants: self
                .invariant_names()
                .iter()
                .map(|s| s.to_string())
                .collect(),
            energy_error: self.has_energy_error(),
            energy_reference: self.energy_reference(),
            jacobian_defect: self.jacobian_defect,
            indicators: self
                .chaos
                .as_ref()
                .map(|c| c.indicators.clone())
                .unwrap_or_default(),
            deviations: self.chaos.as_ref().map(|c| c.deviations),
            schedule: ScheduleSummary::of(self),
            section: self.section_info(),
            stop_when: self.event_info(),
        }
    }

    /// Runs method `index`, sending its chunks and then its summary to `emit`. A failing step
    /// ends the run with [`Stop::Failed`]; the samples before it have been sent.
    fn stream_method(
        &self,
        index: usize,
        reference: Option<&[f64]>,
        budget: Budget<'_>,
        emit: Emit<'_>,
    ) {
        let mut sink = ChunkSink {
            method: index,
            buffer: ColumnSink::new(self.invariant_names()),
            offset: 0,
            last_flush: Instant::now(),
            emit,
            open: true,
            kept: (self.q0.len() == 1).then(|| (Vec::new(), Vec::new())),
            crossings: Default::default(),
            section_summary: None,
            indicators: None,
        };
        let started = Instant::now();
        let result = self.run_method(index, reference, budget, &mut sink);
        sink.flush();
        let (stop, stats) = match result {
            Ok(outcome) => (Stop::from(outcome.stop), outcome.stats),
            Err(e) => {
                tracing::warn!(method = %self.methods[index].label(), error = %e, "run failed");
                let stats = RunStats {
                    steps: Stop::failed_steps(&e),
                    force_evaluations: 0,
                    wall_time_ms: started.elapsed().as_secs_f64() * 1e3,
                };
                (Stop::failed(&e), stats)
            }
        };
        if sink.open {
            emit(StreamLine::Summary(RunSummary {
                method: index,
                label: self.methods[index].label(),
                samples: sink.offset,
                outcome: RunOutcome {
                    dissipation_drift: sink
                        .kept
                        .as_ref()
                        .and_then(|(t, q)| self.dissipation_drift(t, q)),
                    indicators: sink.indicators.take(),
                    diverged_at: stop.diverged_at(),
                    stop,
                    stats,
                    section_summary: sink.section_summary.take(),
                },
            }));
        }
    }

    /// Runs the whole simulation, emitting its stream: header, the reference run if asked for,
    /// every method (on up to `workers` threads), and the `end` line. A reference run that
    /// reaches the time limit leaves the methods no time: they stop with `time_limit` at their
    /// first sample, whose chunk has no energy error, as any run past the deadline does.
    pub fn stream(&self, workers: usize, budget: Budget<'_>, emit: Emit<'_>) {
        if !emit(StreamLine::Header(self.header())) {
            return;
        }
        let reference = match self.reference_energies(budget) {
            Ok(r) => r,
            Err(CoreError::TimeLimit { .. }) => None,
            Err(e) => {
                emit(StreamLine::Error(StreamError {
                    method: None,
                    error: ErrorDetail::from(&e),
                }));
                emit(StreamLine::End);
                return;
            }
        };
        for_each_method(self.methods.len(), workers, |i| {
            self.stream_method(i, reference.as_deref(), budget, emit)
        });
        emit(StreamLine::End);
    }

    /// Runs every method (on up to `workers` threads) into the [`SimulationDocument`]: the
    /// stream, collected.
    pub fn simulate(
        &self,
        workers: usize,
        budget: Budget<'_>,
    ) -> Result<SimulationDocument, ErrorDetail> {
        let collector = std::sync::Mutex::new(DocumentCollector::new());
        let emit = |line: StreamLine| {
            collector
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .push(line);
            true
        };
        self.stream(workers, budget, &emit);
        collector
            .into_inner()
            .unwrap_or_else(|p| p.into_inner())
            .finish()
    }
}

/// Assembles the [`SimulationDocument`] of a stream from its lines: the header's system,
/// schedule and invariants, each method's chunks appended in order, its summary's outcome.
#[derive(Debug, Default)]
pub struct DocumentCollector {
    header: Option<StreamHeader>,
    columns: Vec<Columns>,
    /// Per method, the section's and the event's points.
    crossings: Vec<[Option<CrossingColumns>; 2]>,
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
                let empty = |on: bool| on.then(CrossingColumns::default);
                self.crossings = vec![
                    [
                        empty(header.section.is_some()),
                        empty(header.stop_when.is_some())
                    ];
                    header.methods.len()
                ];
                self.header = Some(header);
            }
            StreamLine::Crossings(chunk) => {
                let i = match chunk.surface {
                    SurfaceName::Section => 0,
                    SurfaceName::StopWhen => 1,
                };
                match self
                    .crossings
                    .get_mut(chunk.method)
                    .and_then(|c| c[i].as_mut())
                {
                    Some(points) if points.len() as u64 == chunk.offset => {
                        points.extend(chunk.columns)
                    }
                    _ => self.fail(format!(
                        "crossings of method {} from {} do not continue its run",
                        chunk.method, chunk.offset
                    )),
                }
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
            .get_or_insert_with(|| ErrorDetail::new(ErrorCode::Internal, message));
    }

    /// The document, once the stream has ended; the stream's error if it reported one.
    pub fn finish(self) -> Result<SimulationDocument, ErrorDetail> {
        if let Some(error) = self.error {
            return Err(error);
        }
        let cut = |what: &str| ErrorDetail::new(ErrorCode::Internal, format!("the stream {what}"));
        let header = self.header.ok_or_else(|| cut("has no header"))?;
        if !self.ended {
            return Err(cut("was cut short"));
        }
        let runs = self
            .columns
            .into_iter()
            .zip(self.summaries)
            .zip(self.crossings)
            .map(|((columns, summary), [section, events])| {
                let s = summary.ok_or_else(|| cut("lacks a summary"))?;
                Ok(RunDocument {
                    method: s.label,
                    columns,
                    outcome: s.outcome,
                    section,
                    events,
                })
            })
            .collect::<Result<_, ErrorDetail>>()?;
        Ok(SimulationDocument {
            system: header.system,
            energy_reference: header.energy_reference,
            schedule: header.schedule,
            invariants: header.invariants,
            runs,
            section: header.section,
            stop_when: header.stop_when,
        })
    }
}

//! A simulation streamed live to a running Rerun viewer: the lines of the NDJSON stream
//! ([`crate::core::simulation::stream`]) are logged as the integrator produces them, over gRPC, and
//! optionally written to an `.rrd` file by the same recording stream.
//!
//! The header sends the blueprint, the spec and every entity's style; each `samples` chunk is
//! logged at once as columns ([`RunLogger`](super::simulation::RunLogger)); a `summary` ends its
//! run (the rest of the paths, the force evaluations). The viewer thus receives each method's
//! samples while it runs, not after the whole simulation. A viewer that is not there is found before anything runs
//! ([`connect_viewer`] waits for the connection at most [`CONNECT_TIMEOUT`]), and the final
//! flush is bounded ([`LiveRecording::finish`]).

use std::io::Write;
use std::sync::{mpsc, OnceLock};
use std::time::{Duration, Instant};

use rerun::external::re_uri::RedapUri;
use rerun::log::ChunkBatcherConfig;
use rerun::sink::{GrpcSink, GrpcSinkConnectionState, LogSink};
use rerun::{RecordingStream, RecordingStreamBuilder};

use super::encode::{self, EncoderThread, EncodingSink};
use super::layout::{send_blueprint, Layout};
use super::simulation::SimulationLogger;
use super::Spec;
use super::{RecordingError, APPLICATION_ID};
use crate::core::simulation::crossings::SurfaceName;
use crate::core::simulation::StreamLine;

/// Longest wait for the viewer's connection before anything runs.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);
/// Longest wait, once the runs have ended, for the viewer to take what is still queued.
pub const FLUSH_TIMEOUT: Duration = Duration::from_secs(30);

/// The viewer URL for `host:port`: Rerun 0.33's gRPC proxy address form.
pub fn viewer_url(addr: &str) -> String {
    format!("rerun+http://{addr}/proxy")
}

/// Connects to the Rerun viewer (or any Rerun gRPC proxy) at `url`, for example
/// `rerun+http://127.0.0.1:9876/proxy`, and waits until the connection is open: an error if it
/// is not open within `timeout` (nothing listens there) or closes.
pub fn connect_viewer(url: &str, timeout: Duration) -> Result<GrpcSink, RecordingError> {
    let uri = match url.parse::<RedapUri>() {
        Ok(RedapUri::Proxy(uri)) => uri,
        Ok(_) => {
            return Err(RecordingError::Sink(format!(
                "`{url}` is not a viewer address (rerun+http://HOST:PORT/proxy)"
            )))
        }
        Err(e) => return Err(RecordingError::Sink(format!("`{url}`: {e}"))),
    };
    let sink = GrpcSink::new(uri);
    let started = Instant::now();
    loop {
        match sink.status() {
            GrpcSinkConnectionState::Connected => return Ok(sink),
            GrpcSinkConnectionState::Disconnected(Err(e)) => {
                return Err(RecordingError::Sink(format!("the connection failed: {e}")))
            }
            GrpcSinkConnectionState::Disconnected(Ok(())) => {
                return Err(RecordingError::Sink("the connection closed".into()))
            }
            GrpcSinkConnectionState::Connecting { .. } if started.elapsed() >= timeout => {
                return Err(RecordingError::Sink(format!(
                    "no viewer answered within {} s (is `rerun` running and listening there?)",
                    timeout.as_secs_f64()
                )))
            }
            GrpcSinkConnectionState::Connecting { .. } => {
                std::thread::sleep(Duration::from_millis(20))
            }
        }
    }
}

/// Logs the lines of a simulation stream into a recording as they come, from any thread: the
/// header starts the recording (blueprint, spec, styles), `samples` chunks and `summary` lines go
/// to their method's run.
pub struct StreamRecorder {
    rec: RecordingStream,
    spec: Spec,
    logger: OnceLock<SimulationLogger>,
}

impl StreamRecorder {
    /// A recorder logging the simulation of `spec` into `rec`.
    pub fn new(rec: RecordingStream, spec: Spec) -> Self {
        StreamRecorder {
            rec,
            spec,
            logger: OnceLock::new(),
        }
    }

    /// Logs one line of the stream.
    pub fn line(&self, line: &StreamLine) -> Result<(), RecordingError> {
        match line {
            StreamLine::Header(header) => {
                let layout = Layout::of_header(header);
                send_blueprint(&self.rec, &layout)?;
                let samples =
                    usize::try_from(header.schedule.samples_per_method).unwrap_or(usize::MAX);
                let logger = SimulationLogger::start(
                    &self.rec,
                    &self.spec,
                    &layout,
                    &header.schedule,
                    |_| samples,
                )?;
                self.logger
                    .set(logger)
                    .map_err(|_| RecordingError::Unexpected("a second header".into()))
            }
            StreamLine::Samples(chunk) => {
                self.logger()?
                    .samples(chunk.method, chunk.offset, &chunk.columns)
            }
            StreamLine::Summary(summary) => self
                .logger()?
                .finish(summary.method, summary.outcome.stats.force_evaluations),
            StreamLine::Crossings(chunk) => match chunk.surface {
                SurfaceName::Section => {
                    self.logger()?
                        .section(chunk.method, chunk.offset, &chunk.columns)
                }
                SurfaceName::StopWhen => Ok(()),
            },
            StreamLine::Error(_) | StreamLine::End => Ok(()),
        }
    }

    fn logger(&self) -> Result<&SimulationLogger, RecordingError> {
        self.logger
            .get()
            .ok_or_else(|| RecordingError::Unexpected("samples before the header".into()))
    }
}

/// A simulation recording streamed to a viewer while the runs compute, and also written to an
/// `.rrd` file when one is given (one recording stream with both sinks).
pub struct LiveRecording<W> {
    recorder: StreamRecorder,
    encoder: Option<EncoderThread<W>>,
}

impl<W: Write + Send + 'static> LiveRecording<W> {
    /// Starts a recording named `name` of the simulation of `spec`, sent through `viewer` (see
    /// [`connect_viewer`]) and, if `file` is given, encoded into it.
    pub fn start(
        viewer: GrpcSink,
        name: String,
        spec: Spec,
        file: Option<W>,
    ) -> Result<Self, RecordingError> {
        let mut sinks: Vec<Box<dyn LogSink>> = vec![Box::new(viewer)];
        let encoder = match file {
            Some(writer) => {
                let (sink, thread) = EncodingSink::spawn(writer)?;
                sinks.push(Box::new(sink));
                Some(thread)
            }
            None => None,
        };
        // Enabled whatever the `RERUN` environment variable says; rows logged one by one (the
        // static styles) reach the viewer within milliseconds, columns at once.
        let rec = RecordingStreamBuilder::new(APPLICATION_ID)
            .enabled(true)
            .recording_name(name)
            .batcher_config(ChunkBatcherConfig::LOW_LATENCY)
            .set_sinks(sinks)?;
        Ok(LiveRecording {
            recorder: StreamRecorder::new(rec, spec),
            encoder,
        })
    }

    /// Logs one line of the simulation stream (see [`StreamRecorder::line`]).
    pub fn line(&self, line: &StreamLine) -> Result<(), RecordingError> {
        self.recorder.line(line)
    }

    /// Ends the recording: waits up to `timeout` until the viewer has everything, then closes
    /// the connection and finishes the file, returning its writer. An error if the viewer did
    /// not take everything in time or the connection failed.
    pub fn finish(self, timeout: Duration) -> Result<Option<W>, RecordingError> {
        let started = Instant::now();
        let LiveRecording { recorder, encoder } = self;
        let rec = recorder.rec.clone();
        // Every other handle of the stream goes with the recorder.
        drop(recorder);
        let flushed = rec.flush_with_timeout(timeout).map_err(|e| {
            RecordingError::Sink(format!("the viewer did not take the whole recording: {e}"))
        });
        // Dropping the last handle of the stream waits, without a limit, until the viewer's
        // connection is closed and the file is finished: on a thread of its own, waited for up
        // to the time left.
        let (done, closed) = mpsc::channel();
        std::thread::Builder::new()
            .name("recording-close".into())
            .spawn(move || {
                drop(rec);
                let _ = done.send(encoder.map(encode::join).transpose());
            })
            .map_err(|e| RecordingError::Sink(format!("cannot close the recording: {e}")))?;
        let left = timeout
            .saturating_sub(started.elapsed())
            .max(Duration::from_secs(1));
        let written = closed.recv_timeout(left);
        flushed?;
        written.map_err(|_| {
            RecordingError::Sink("the connection to the viewer did not close in time".into())
        })?
    }
}

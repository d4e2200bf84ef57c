//! `geomint run spec.json`: one simulation without a server, written as JSON, NDJSON or a Rerun
//! recording, and optionally streamed live to a Rerun viewer while it runs. The run is computed
//! once, whatever the outputs.

use std::fs::File;
use std::io::{self, BufWriter, IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use clap::{Args, ValueEnum};
use rerun::sink::GrpcSink;

use super::{finish_output, parse_count, read_spec, SystemsDir, BAD_INPUT};
use crate::api::{ndjson_line, SimulateRequest};
use crate::core::run::Budget;
use crate::core::simulation::{
    DocumentCollector, Limits, Simulation, SimulationDocument, StreamLine,
};

use crate::recording::{self, live};

/// Output formats of `geomint run`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OutputFormat {
    /// One JSON document.
    Json,
    /// NDJSON lines, as the API streams them.
    Ndjson,
    /// A Rerun recording (`.rrd`).
    Rrd,
}

/// Settings of `geomint run`.
#[derive(Clone, Debug, Args)]
pub struct RunArgs {
    /// The spec file (JSON, as the body of POST /api/v1/simulate); `-` reads standard input.
    pub spec: PathBuf,
    /// Output file; `.ndjson` or `.jsonl` writes NDJSON, `.rrd` a Rerun recording, anything
    /// else JSON (default: standard output).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Also stream the run live, chunk by chunk as it computes, to a Rerun viewer listening at
    /// HOST:PORT (`rerun` serves gRPC on port 9876 by default), or at a full
    /// `rerun+http://HOST:PORT/proxy` URL; fails (exit code 1) if no viewer answers within 5 s.
    #[arg(long, value_name = "HOST:PORT")]
    pub rerun_addr: Option<String>,
    /// Output format, instead of the one the file extension implies.
    #[arg(long, value_enum)]
    pub format: Option<OutputFormat>,
    /// Indent the JSON document.
    #[arg(long)]
    pub pretty: bool,
    /// Most steps per method.
    #[arg(long, env = "GEOMINT_MAX_STEPS", default_value = "10000000", value_parser = parse_count)]
    pub max_steps: u64,
    /// Most samples over all methods.
    #[arg(long, env = "GEOMINT_MAX_SAMPLES", default_value = "1000000", value_parser = parse_count)]
    pub max_samples: u64,
    /// Stored system definitions.
    #[command(flatten)]
    pub systems: SystemsDir,
}

pub(crate) fn run_spec(args: &RunArgs) -> ExitCode {
    let (source, text) = match read_spec(&args.spec) {
        Ok(spec) => spec,
        Err(code) => return code,
    };
    let limits = Limits {
        max_steps: args.max_steps,
        max_samples: args.max_samples,
    };
    let stored = args.systems.open();
    let (spec, sim) = match SimulateRequest::from_slice(&text).and_then(|req| {
        let sim = req.prepare(&limits, &stored)?;
        Ok((req.inlined(&stored), sim))
    }) {
        Ok(parsed) => parsed,
        Err(e) => {
            eprintln!("error: {source}: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let format = args.format.unwrap_or_else(|| {
        let ext = args
            .output
            .as_ref()
            .and_then(|p| p.extension())
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("ndjson" | "jsonl") => OutputFormat::Ndjson,
            Some("rrd") => OutputFormat::Rrd,
            _ => OutputFormat::Json,
        }
    });
    if format == OutputFormat::Rrd && args.output.is_none() && io::stdout().is_terminal() {
        eprintln!("error: a recording is binary; give `-o FILE.rrd` or redirect standard output");
        return ExitCode::from(BAD_INPUT);
    }
    let workers = crate::executor::cores();
    // A viewer is found before anything runs or any file is created.
    let viewer = match &args.rerun_addr {
        Some(addr) => {
            let url = if addr.contains("://") {
                addr.clone()
            } else {
                recording::viewer_url(addr)
            };
            match recording::connect_viewer(&url, live::CONNECT_TIMEOUT) {
                Ok(sink) => Some((url, sink)),
                Err(e) => {
                    eprintln!("error: cannot stream to the Rerun viewer at {url}: {e}");
                    return ExitCode::FAILURE;
                }
            }
        }
        None => None,
    };
    let target = match &args.output {
        Some(path) => File::create(path).map(|f| Box::new(f) as Box<dyn Write + Send>),
        None => Ok(Box::new(io::stdout()) as Box<dyn Write + Send>),
    };
    let out = match target {
        Ok(w) => BufWriter::new(w),
        Err(e) => {
            eprintln!(
                "error: cannot create `{}`: {e}",
                args.output
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_default()
            );
            return ExitCode::FAILURE;
        }
    };
    let job = ValidatedRun {
        sim: &sim,
        source: &source,
        workers,
        pretty: args.pretty,
    };
    match viewer {
        Some((url, sink)) => job.run_live(format, out, spec, &url, sink),
        None => job.run(format, out, &spec),
    }
}

/// Where `geomint run` writes.
type Output = BufWriter<Box<dyn Write + Send>>;

/// A validated simulation to run and write.
struct ValidatedRun<'a> {
    sim: &'a Simulation,
    /// The spec's name in messages.
    source: &'a str,
    workers: usize,
    pretty: bool,
}

/// What went wrong while a simulation streamed, first failure of each kind.
#[derive(Default)]
struct StreamFailures {
    /// The stream's own error line (a failed reference run): bad input.
    stream: Option<String>,
    /// The output could not be written.
    write: Option<io::Error>,
    /// The recording refused a line.
    recording: Option<recording::RecordingError>,
}

impl ValidatedRun<'_> {
    /// Writes the simulation in `format` to `out`.
    fn run(&self, format: OutputFormat, mut out: Output, spec: &SimulateRequest) -> ExitCode {
        let written = match format {
            OutputFormat::Json | OutputFormat::Rrd => {
                let doc = match self.sim.simulate(self.workers, Budget::default()) {
                    Ok(doc) => doc,
                    Err(e) => return self.bad_input(&e),
                };
                if format == OutputFormat::Rrd {
                    return match recording::write_rrd(out, &recording::Spec::of(spec), &doc) {
                        Ok(mut w) => finish_output(w.flush()),
                        Err(e) => {
                            eprintln!("error: cannot write the recording: {e}");
                            ExitCode::FAILURE
                        }
                    };
                }
                self.write_document(&mut out, &doc)
            }
            OutputFormat::Ndjson => {
                let failures = self.stream(None, Some(&mut out), None);
                if let Some(e) = failures.stream {
                    let _ = out.flush();
                    return self.bad_input(&e);
                }
                failures.write.map_or(Ok(()), Err)
            }
        };
        finish_output(written.and_then(|()| out.flush()))
    }

    /// Runs the simulation once, streaming it live to the viewer (`sink`, connected to `url`)
    /// while writing `format` to `out`: NDJSON lines as they come, the JSON document once
    /// complete, or the same recording as the viewer gets.
    fn run_live(
        &self,
        format: OutputFormat,
        out: Output,
        spec: SimulateRequest,
        url: &str,
        sink: GrpcSink,
    ) -> ExitCode {
        let header = self.sim.header();
        let recording_spec = recording::Spec::of(&spec);
        // Named as a stored recording is: a typed-in system by its definition's name.
        let system = recording::system_label(&recording_spec, &header.system.id);
        let name = recording::recording_name(&system, &header.methods);
        let (file, mut text) = match format {
            OutputFormat::Rrd => (Some(out), None),
            OutputFormat::Json | OutputFormat::Ndjson => (None, Some(out)),
        };
        let live = match recording::LiveRecording::start(sink, name, recording_spec, file) {
            Ok(live) => live,
            Err(e) => {
                eprintln!("error: cannot stream to the Rerun viewer at {url}: {e}");
                return ExitCode::FAILURE;
            }
        };
        let mut collector = (format == OutputFormat::Json).then(DocumentCollector::new);
        let ndjson = if format == OutputFormat::Ndjson {
            text.as_mut()
        } else {
            None
        };
        let failures = self.stream(Some(&live), ndjson, collector.as_mut());
        let finished = live.finish(live::FLUSH_TIMEOUT);
        if let Some(e) = failures.recording {
            eprintln!("error: cannot stream to the Rerun viewer at {url}: {e}");
            return ExitCode::FAILURE;
        }
        let file = match finished {
            Ok(file) => file,
            Err(e) => {
                eprintln!("error: cannot stream to the Rerun viewer at {url}: {e}");
                return ExitCode::FAILURE;
            }
        };
        if let Some(e) = failures.stream {
            if let Some(out) = &mut text {
                let _ = out.flush();
            }
            return self.bad_input(&e);
        }
        if let Some(e) = failures.write {
            return finish_output(Err(e));
        }
        eprintln!("streamed the run live to the Rerun viewer at {url}");
        let written = match (text, collector, file) {
            (Some(mut out), Some(collector), _) => match collector.finish() {
                Ok(doc) => self
                    .write_document(&mut out, &doc)
                    .and_then(|()| out.flush()),
                Err(e) => {
                    // Not the input's fault: the stream's own errors were reported above.
                    eprintln!("error: {e}");
                    return ExitCode::FAILURE;
                }
            },
            (Some(mut out), None, _) => out.flush(),
            (None, _, Some(mut file)) => file.flush(),
            (None, _, None) => Ok(()),
        };
        finish_output(written)
    }

    /// Streams the simulation once: every line goes to the live recording, as NDJSON to
    /// `ndjson` and into the collector, whichever are given. A failing output or recording
    /// cancels the runs.
    fn stream(
        &self,
        live: Option<&recording::LiveRecording<Output>>,
        ndjson: Option<&mut Output>,
        collector: Option<&mut DocumentCollector>,
    ) -> StreamFailures {
        fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
            m.lock().unwrap_or_else(|p| p.into_inner())
        }
        let cancel = AtomicBool::new(false);
        let failures = Mutex::new(StreamFailures::default());
        let ndjson = ndjson.map(Mutex::new);
        let collector = collector.map(Mutex::new);
        let emit = |line: StreamLine| {
            if let StreamLine::Error(e) = &line {
                lock(&failures).stream.get_or_insert(e.error.to_string());
            }
            if let Some(live) = live {
                if let Err(e) = live.line(&line) {
                    cancel.store(true, Ordering::Relaxed);
                    lock(&failures).recording.get_or_insert(e);
                    return false;
                }
            }
            if let Some(w) = &ndjson {
                if let Err(e) = lock(w).write_all(&ndjson_line(&line)) {
                    cancel.store(true, Ordering::Relaxed);
                    lock(&failures).write.get_or_insert(e);
                    return false;
                }
            }
            if let Some(c) = &collector {
                lock(c).push(line);
            }
            true
        };
        let budget = Budget {
            cancel: Some(&cancel),
            deadline: None,
        };
        self.sim.stream(self.workers, budget, &emit);
        failures.into_inner().unwrap_or_else(|p| p.into_inner())
    }

    fn write_document(&self, out: &mut Output, doc: &SimulationDocument) -> io::Result<()> {
        let result = if self.pretty {
            serde_json::to_writer_pretty(&mut *out, doc)
        } else {
            serde_json::to_writer(&mut *out, doc)
        };
        result.map_err(io::Error::from).and_then(|()| writeln!(out))
    }

    fn bad_input(&self, e: &dyn std::fmt::Display) -> ExitCode {
        eprintln!("error: {}: {e}", self.source);
        ExitCode::from(BAD_INPUT)
    }
}

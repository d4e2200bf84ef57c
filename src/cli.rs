//! The command line: `geomint serve` (the default), `geomint run spec.json` (JSON, NDJSON or a
//! Rerun recording, optionally streamed live to a Rerun viewer with `--rerun-addr`),
//! `geomint study work-precision spec.json` (a work–precision study, JSON or `.rrd`),
//! `geomint study convergence spec.json` (a convergence study, JSON),
//! `geomint systems` and `geomint methods`. Every server setting can also come from a `GEOMINT_*` environment
//! variable.
//!
//! Exit codes: 0 on success, 2 for a bad command line, an unreadable spec or an invalid one
//! (the message names the field), 1 when output cannot be written, the Rerun viewer cannot be
//! reached or the server cannot start.

use std::fs::File;
use std::io::{self, BufWriter, IsTerminal, Read, Write};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use clap::{Args, Parser, Subcommand, ValueEnum};
use rerun::sink::GrpcSink;

use crate::core::run::Budget;
use crate::core::simulate::{Limits, Simulation};
use crate::http::{self, Config};
use crate::output::recording::{self, live};
use crate::output::stream::DocumentCollector;
use crate::output::study::{ProgressLine, Runner, StudyJob};
use crate::output::{self, catalog, SimulateRequest, SimulationDocument, StreamLine};

/// Geometric numerical integration of damped Hamiltonian systems, as a web service.
#[derive(Debug, Parser)]
#[command(
    name = "geomint",
    version,
    about,
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    /// What to do (default: serve).
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Server settings when no subcommand is given.
    #[command(flatten)]
    pub serve: ServeArgs,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Serve the HTTP API (the default).
    Serve(ServeArgs),
    /// Run a simulation spec (the body of POST /api/v1/simulate) without a server.
    Run(RunArgs),
    /// Run a study spec without a server (`work-precision`, `convergence`, `energy-map`: the
    /// body of POST /api/v1/studies/work-precision, /convergence or /energy-map).
    Study(StudyArgs),
    /// Print the system catalogue as JSON.
    Systems,
    /// Print the method catalogue as JSON.
    Methods,
}

/// Settings of `geomint serve`.
#[derive(Clone, Debug, Args)]
pub struct ServeArgs {
    /// Address to listen on.
    #[arg(long, env = "GEOMINT_ADDR", default_value = "127.0.0.1:8080")]
    pub addr: SocketAddr,
    /// Most steps per method (1e7 style accepted).
    #[arg(long, env = "GEOMINT_MAX_STEPS", default_value = "10000000", value_parser = parse_count)]
    pub max_steps: u64,
    /// Most samples per request over all methods.
    #[arg(long, env = "GEOMINT_MAX_SAMPLES", default_value = "1000000", value_parser = parse_count)]
    pub max_samples: u64,
    /// Most simulation threads at once (default: the number of cores).
    #[arg(long, env = "GEOMINT_MAX_CONCURRENT", value_parser = clap::value_parser!(u64).range(1..=4096))]
    pub max_concurrent: Option<u64>,
    /// Time limit of a simulation in seconds; runs then stop with `time_limit`.
    #[arg(long, env = "GEOMINT_REQUEST_TIMEOUT_SECS", default_value_t = 60, value_parser = clap::value_parser!(u64).range(1..))]
    pub request_timeout_secs: u64,
    /// How long a request waits for a free simulation slot before it gets 503, in milliseconds.
    #[arg(long, env = "GEOMINT_QUEUE_TIMEOUT_MS", default_value_t = 250)]
    pub queue_timeout_ms: u64,
    /// Origins allowed by CORS, comma-separated, or `*` (default: CORS off).
    #[arg(long, env = "GEOMINT_CORS_ORIGINS", value_delimiter = ',')]
    pub cors_origins: Vec<String>,
    /// Directory served at `/`, if it exists.
    #[arg(long, env = "GEOMINT_STATIC_DIR", default_value = "static")]
    pub static_dir: PathBuf,
    /// Largest request body in bytes.
    #[arg(long, env = "GEOMINT_BODY_LIMIT", default_value = "1048576", value_parser = parse_count)]
    pub body_limit: u64,
    /// Seconds running simulations may go on after a shutdown signal before they are cancelled.
    #[arg(long, env = "GEOMINT_SHUTDOWN_GRACE_SECS", default_value_t = 10)]
    pub shutdown_grace_secs: u64,
    /// Directory of the stored Rerun recordings (created when the first one is stored).
    #[arg(long, env = "GEOMINT_DATA_DIR", default_value = http::state::DEFAULT_DATA_DIR)]
    pub data_dir: PathBuf,
    /// Most bytes of stored recordings; past it the oldest are deleted (1e9 style accepted).
    #[arg(long, env = "GEOMINT_RECORDINGS_MAX_BYTES", default_value = "1073741824", value_parser = parse_count)]
    pub recordings_max_bytes: u64,
    /// Log filter (tracing's EnvFilter syntax).
    #[arg(long, env = "GEOMINT_LOG", default_value = "info")]
    pub log: String,
}

/// Output formats of `geomint run`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
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
    pub format: Option<Format>,
    /// Indent the JSON document.
    #[arg(long)]
    pub pretty: bool,
    /// Most steps per method.
    #[arg(long, env = "GEOMINT_MAX_STEPS", default_value = "10000000", value_parser = parse_count)]
    pub max_steps: u64,
    /// Most samples over all methods.
    #[arg(long, env = "GEOMINT_MAX_SAMPLES", default_value = "1000000", value_parser = parse_count)]
    pub max_samples: u64,
}

/// The kinds of study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum StudyKind {
    /// Wall time against energy error per method and setting.
    WorkPrecision,
    /// Errors at t_end against the step size per method and chart, with the fitted orders.
    Convergence,
    /// Energy-error map of the planar elastic pendulum, Cartesian against polar coordinates
    /// (paper 001 Fig. 6), on all cores.
    EnergyMap,
}

/// Settings of `geomint study`.
#[derive(Clone, Debug, Args)]
pub struct StudyArgs {
    /// The kind of study.
    #[arg(value_enum)]
    pub kind: StudyKind,
    /// The spec file (JSON); `-` reads standard input.
    pub spec: PathBuf,
    /// Output file; `.rrd` writes a Rerun recording (work-precision only), anything else JSON
    /// (default: standard output). Progress goes to standard error.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Most steps per setting.
    #[arg(long, env = "GEOMINT_MAX_STEPS", default_value = "10000000", value_parser = parse_count)]
    pub max_steps: u64,
}

/// Parses a positive whole number, also written as `1e7`.
fn parse_count(s: &str) -> Result<u64, String> {
    let s = s.trim().replace('_', "");
    if let Ok(n) = s.parse::<u64>() {
        return Ok(n);
    }
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 && x.fract() == 0.0 && x <= u64::MAX as f64 => {
            Ok(x as u64)
        }
        _ => Err(format!("`{s}` is not a whole number ≥ 0")),
    }
}

impl ServeArgs {
    /// The service configuration these settings describe.
    pub fn config(&self) -> Config {
        Config {
            limits: Limits {
                max_steps: self.max_steps,
                max_samples: self.max_samples,
            },
            max_concurrent: self
                .max_concurrent
                .map_or_else(http::state::default_concurrency, |n| n as usize),
            request_timeout: Duration::from_secs(self.request_timeout_secs),
            queue_timeout: Duration::from_millis(self.queue_timeout_ms),
            cors_origins: self.cors_origins.clone(),
            static_dir: Some(self.static_dir.clone()),
            body_limit: usize::try_from(self.body_limit).unwrap_or(usize::MAX),
            shutdown_grace: Duration::from_secs(self.shutdown_grace_secs),
            data_dir: self.data_dir.clone(),
            recordings_max_bytes: self.recordings_max_bytes,
        }
    }
}

/// Carries out a parsed command line.
pub fn run(cli: Cli) -> ExitCode {
    match cli.command.unwrap_or(Command::Serve(cli.serve)) {
        Command::Serve(args) => serve(&args),
        Command::Run(args) => run_spec(&args),
        Command::Study(args) => run_study(&args),
        Command::Systems => print_json(&catalog::systems()),
        Command::Methods => print_json(&catalog::methods()),
    }
}

fn serve(args: &ServeArgs) -> ExitCode {
    let filter = tracing_subscriber::EnvFilter::try_new(&args.log).unwrap_or_else(|e| {
        eprintln!(
            "warning: invalid log filter `{}` ({e}); using `info`",
            args.log
        );
        tracing_subscriber::EnvFilter::new("info")
    });
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(io::stderr)
        .with_ansi(io::stderr().is_terminal())
        .init();
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    match runtime.block_on(http::serve(args.addr, args.config())) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: cannot serve on {}: {e}", args.addr);
            ExitCode::FAILURE
        }
    }
}

fn print_json<T: serde::Serialize>(value: &T) -> ExitCode {
    let stdout = io::stdout();
    let mut out = stdout.lock();
    let written = serde_json::to_writer_pretty(&mut out, value)
        .map_err(io::Error::from)
        .and_then(|()| writeln!(out))
        .and_then(|()| out.flush());
    match written {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: cannot write to standard output: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Exit code for bad input.
const BAD_INPUT: u8 = 2;

fn run_spec(args: &RunArgs) -> ExitCode {
    let source = args.spec.display().to_string();
    let text = if source == "-" {
        let mut buf = Vec::new();
        io::stdin().read_to_end(&mut buf).map(|_| buf)
    } else {
        std::fs::read(&args.spec)
    };
    let text = match text {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: cannot read the spec `{source}`: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let limits = Limits {
        max_steps: args.max_steps,
        max_samples: args.max_samples,
    };
    let (spec, sim) = match SimulateRequest::from_slice(&text)
        .and_then(|req| req.prepare(&limits).map(|sim| (req, sim)))
    {
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
            Some("ndjson" | "jsonl") => Format::Ndjson,
            Some("rrd") => Format::Rrd,
            _ => Format::Json,
        }
    });
    if format == Format::Rrd && args.output.is_none() && io::stdout().is_terminal() {
        eprintln!("error: a recording is binary; give `-o FILE.rrd` or redirect standard output");
        return ExitCode::from(BAD_INPUT);
    }
    let workers = http::state::default_concurrency();
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
    let job = Job {
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
struct Job<'a> {
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

impl Job<'_> {
    /// Writes the simulation in `format` to `out`.
    fn run(&self, format: Format, mut out: Output, spec: &SimulateRequest) -> ExitCode {
        let written = match format {
            Format::Json | Format::Rrd => {
                let doc = match output::simulate(self.sim, self.workers, Budget::default()) {
                    Ok(doc) => doc,
                    Err(e) => return self.bad_input(&e),
                };
                if format == Format::Rrd {
                    return match recording::write_rrd(out, spec, &doc) {
                        Ok(mut w) => finish_output(w.flush()),
                        Err(e) => {
                            eprintln!("error: cannot write the recording: {e}");
                            ExitCode::FAILURE
                        }
                    };
                }
                self.write_document(&mut out, &doc)
            }
            Format::Ndjson => {
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
        format: Format,
        out: Output,
        spec: SimulateRequest,
        url: &str,
        sink: GrpcSink,
    ) -> ExitCode {
        let header = output::stream::header(self.sim);
        let name = recording::recording_name(&header.system.id, &header.methods);
        let (file, mut text) = match format {
            Format::Rrd => (Some(out), None),
            Format::Json | Format::Ndjson => (None, Some(out)),
        };
        let live = match recording::LiveRecording::start(sink, name, spec, file) {
            Ok(live) => live,
            Err(e) => {
                eprintln!("error: cannot stream to the Rerun viewer at {url}: {e}");
                return ExitCode::FAILURE;
            }
        };
        let mut collector = (format == Format::Json).then(DocumentCollector::new);
        let ndjson = if format == Format::Ndjson {
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
                if let Err(e) = lock(w).write_all(&output::ndjson_line(&line)) {
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
        output::stream::stream(self.sim, self.workers, budget, &emit);
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

/// The exit code once the output is written (or not).
fn finish_output(written: io::Result<()>) -> ExitCode {
    match written {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: cannot write the output: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Reads a spec file, or standard input for `-`.
fn read_spec(path: &std::path::Path) -> Result<Vec<u8>, String> {
    let source = path.display().to_string();
    let text = if source == "-" {
        let mut buf = Vec::new();
        io::stdin().read_to_end(&mut buf).map(|_| buf)
    } else {
        std::fs::read(path)
    };
    text.map_err(|e| format!("cannot read the spec `{source}`: {e}"))
}

fn run_study(args: &StudyArgs) -> ExitCode {
    use crate::output::convergence::{self, ConvergenceLine, ConvergenceRequest};
    use crate::output::work_precision::{self, StudyLine, WorkPrecisionRequest};
    let source = args.spec.display().to_string();
    let text = match read_spec(&args.spec) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let limits = Limits {
        max_steps: args.max_steps,
        ..Limits::default()
    };
    let reference = |reference: &str, ms: f64, total: usize| {
        eprintln!("errors against the {reference} ({ms:.0} ms); {total} settings")
    };
    let error = |e: Option<f64>| e.map_or("-".into(), |e| format!("{e:.2e}"));
    match args.kind {
        StudyKind::WorkPrecision => {
            let parsed = WorkPrecisionRequest::from_slice(&text)
                .and_then(|req| req.prepare(&limits).map(|job| (req, job)));
            let progress = |line: &StudyLine| match line {
                StudyLine::Reference {
                    reference: r,
                    reference_ms,
                    total,
                } => reference(r, *reference_ms, *total),
                StudyLine::Point { done, total, point } => eprintln!(
                    "[{done}/{total}] {} {}: {:.3} ms, max energy error {}",
                    point.method,
                    point
                        .h
                        .map(|h| format!("h = {h}"))
                        .or(point.tolerance.map(|t| format!("tol = {t:e}")))
                        .unwrap_or_default(),
                    point.wall_ms,
                    error(point.max_energy_error)
                ),
                _ => {}
            };
            let rrd = |f: File, spec: &WorkPrecisionRequest, doc: &_| {
                recording::work_precision::write_rrd(BufWriter::new(f), spec, doc)
                    .map_err(|e| e.to_string())
                    .and_then(|mut w| w.flush().map_err(|e| e.to_string()))
            };
            finish_study(
                args,
                &source,
                parsed,
                work_precision::run,
                progress,
                Some(rrd),
            )
        }
        StudyKind::Convergence => {
            let parsed = ConvergenceRequest::from_slice(&text)
                .and_then(|req| req.prepare(&limits).map(|job| (req, job)));
            let progress = |line: &ConvergenceLine| match line {
                ConvergenceLine::Reference {
                    reference: r,
                    reference_ms,
                    total,
                } => reference(r, *reference_ms, *total),
                ConvergenceLine::Point { done, total, point } => eprintln!(
                    "[{done}/{total}] {} ({}) h = {}: state error {}, energy error {}, max {}",
                    point.method,
                    point.chart,
                    point.h,
                    error(point.state_error),
                    error(point.energy_error),
                    error(point.max_energy_error)
                ),
                _ => {}
            };
            type Rrd = fn(
                File,
                &ConvergenceRequest,
                &convergence::ConvergenceDocument,
            ) -> Result<(), String>;
            finish_study(
                args,
                &source,
                parsed,
                convergence::run,
                progress,
                None::<Rrd>,
            )
        }
        StudyKind::EnergyMap => run_energy_map(args, &source, &text),
    }
}

/// An energy-error map (001 Fig. 6) on all cores, with progress on standard error.
fn run_energy_map(args: &StudyArgs, source: &str, text: &[u8]) -> ExitCode {
    use crate::output::energy_map::{self, EnergyMapRequest, MapLine};
    let parsed = crate::output::request::parse_json(text)
        .and_then(|v| EnergyMapRequest::from_value(&v))
        .and_then(|req| req.prepare().map(|spec| (req, spec)));
    let (request, spec) = match parsed {
        Ok(parsed) => parsed,
        Err(e) => {
            eprintln!("error: {source}: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    eprintln!(
        "{} cells × 2 charts × {} steps on {} threads",
        spec.nx * spec.ny,
        spec.steps,
        rayon::current_num_threads()
    );
    let progress = |line: MapLine| {
        if let MapLine::Progress { done, total } = line {
            eprint!("\r{done}/{total} cells");
            if done == total {
                eprintln!();
            }
        }
        true
    };
    let doc = match energy_map::run(&spec, request.t_max, Budget::default(), &progress) {
        Ok(doc) => doc,
        Err(e) => {
            eprintln!("error: {source}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let s = &doc.summary;
    eprintln!(
        "{:.1} s for {} steps: Cartesian better in {} cells, polar in {}; polar diverged in {} ({} outside the predicted region)",
        doc.wall_ms / 1e3,
        doc.steps,
        s.cartesian_better,
        s.polar_better,
        s.polar_diverged,
        s.diverged_outside_prediction
    );
    let wants_rrd = wants_rrd(args);
    write_document(
        args,
        wants_rrd,
        &doc,
        Some(|f: File, doc: &energy_map::EnergyMapDocument| {
            recording::energy_map::write_rrd(BufWriter::new(f), doc)
                .map_err(|e| e.to_string())
                .and_then(|mut w| w.flush().map_err(|e| e.to_string()))
        }),
    )
}

/// Whether the output file's name ends in `.rrd`.
fn wants_rrd(args: &StudyArgs) -> bool {
    args.output
        .as_ref()
        .and_then(|p| p.extension())
        .is_some_and(|e| e.eq_ignore_ascii_case("rrd"))
}

/// Runs a parsed study, reporting its progress lines with `progress` on standard error, and
/// writes the document: as JSON, or with `rrd` for an output file ending in `.rrd` (refused for
/// a kind without a recording).
fn finish_study<S, L: ProgressLine>(
    args: &StudyArgs,
    source: &str,
    parsed: Result<(S, StudyJob), output::ErrorDetail>,
    run: Runner<L>,
    progress: impl Fn(&L),
    rrd: Option<impl FnOnce(File, &S, &L::Document) -> Result<(), String>>,
) -> ExitCode {
    let (spec, job) = match parsed {
        Ok(parsed) => parsed,
        Err(e) => {
            eprintln!("error: {source}: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let wants_rrd = wants_rrd(args);
    if wants_rrd && rrd.is_none() {
        eprintln!("error: this kind of study has no recording; write JSON (e.g. -o out.json)");
        return ExitCode::from(BAD_INPUT);
    }
    let emit = |line: L| {
        progress(&line);
        true
    };
    let doc = match run(&job, Budget::default(), &emit) {
        Ok(doc) => doc,
        Err(e) => {
            eprintln!("error: {source}: {e}");
            return ExitCode::FAILURE;
        }
    };
    write_document(
        args,
        wants_rrd,
        &doc,
        rrd.map(|record| move |f: File, doc: &L::Document| record(f, &spec, doc)),
    )
}

/// Writes a study's document to the output file — a Rerun recording through `rrd` when
/// `wants_rrd`, pretty JSON otherwise — or prints it without one.
fn write_document<D: serde::Serialize>(
    args: &StudyArgs,
    wants_rrd: bool,
    doc: &D,
    rrd: Option<impl FnOnce(File, &D) -> Result<(), String>>,
) -> ExitCode {
    let written = match (&args.output, rrd) {
        (Some(path), Some(record)) if wants_rrd => File::create(path)
            .map_err(|e| e.to_string())
            .and_then(|f| record(f, doc)),
        (Some(path), _) => File::create(path).map_err(|e| e.to_string()).and_then(|f| {
            let mut w = BufWriter::new(f);
            serde_json::to_writer_pretty(&mut w, doc)
                .map_err(|e| e.to_string())
                .and_then(|()| {
                    writeln!(w)
                        .and_then(|()| w.flush())
                        .map_err(|e| e.to_string())
                })
        }),
        (None, _) => return print_json(doc),
    };
    match written {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: cannot write the output: {e}");
            ExitCode::FAILURE
        }
    }
}

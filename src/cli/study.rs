//! `geomint study KIND spec.json`: a work–precision or convergence study or an energy-error map
//! (sweeps, basin maps and merges: [`super::sweep`]), without a server, with progress on standard error; the
//! document as JSON, or as a Rerun recording for an output file ending in `.rrd` (work–precision
//! studies and maps).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, ValueEnum};

use super::{parse_count, print_json, read_spec, SystemsDir, BAD_INPUT};
use crate::core::error::{CoreError, ErrorDetail};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::engine::Local;
use crate::core::studies::settings::{ProgressLine, StudyJob};
use crate::recording;

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
    /// Any system over one or two axes, on all cores; with `--shard` one part of it.
    Sweep,
    /// Where each orbit of a grid of initial states ends up (attractors, exits), on all cores;
    /// with `--shard` one part of it.
    Basins,
    /// The parts of a sweep or a basin map (`--shard` outputs, every shard once) into its
    /// document.
    Merge,
}

/// Settings of `geomint study`.
#[derive(Clone, Debug, Args)]
pub struct StudyArgs {
    /// The kind of study.
    #[arg(value_enum)]
    pub kind: StudyKind,
    /// The spec file (JSON); `-` reads standard input. For `merge`, the first part.
    pub spec: PathBuf,
    /// For `merge`: the other parts.
    pub parts: Vec<PathBuf>,
    /// For `sweep` and `basins`: run shard `i/n` only (cells in a fixed order, so parts from any machines
    /// merge to the whole sweep bit for bit), or `auto` for the index of a Slurm array task
    /// (`SLURM_ARRAY_TASK_ID`) or a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`) and the
    /// count from `SLURM_ARRAY_TASK_COUNT` or `GEOMINT_SHARDS`.
    #[arg(long)]
    pub shard: Option<String>,
    /// Output file; `.rrd` writes a Rerun recording (work-precision only), anything else JSON
    /// (default: standard output). Progress goes to standard error.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Most steps per setting.
    #[arg(long, env = "GEOMINT_MAX_STEPS", default_value = "10000000", value_parser = parse_count)]
    pub max_steps: u64,
    /// Stored system definitions.
    #[command(flatten)]
    pub systems: SystemsDir,
}

impl StudyArgs {
    /// The limits the settings give.
    pub fn limits(&self) -> Limits {
        Limits {
            max_steps: self.max_steps,
            ..Limits::default()
        }
    }
}

pub(crate) fn run_study(args: &StudyArgs) -> ExitCode {
    use crate::api::studies::{ConvergenceRequest, WorkPrecisionRequest};
    use crate::core::studies::convergence::{self, ConvergenceLine};
    use crate::core::studies::work_precision::{self, StudyLine};
    let limits = args.limits();
    let (source, text) = match read_spec(&args.spec) {
        Ok(spec) => spec,
        Err(code) => return code,
    };
    if !args.parts.is_empty() && args.kind != StudyKind::Merge {
        eprintln!("error: one spec file only (several files are for `merge`)");
        return ExitCode::from(BAD_INPUT);
    }
    if args.shard.is_some() && !matches!(args.kind, StudyKind::Sweep | StudyKind::Basins) {
        eprintln!("error: --shard is for `sweep` and `basins` only");
        return ExitCode::from(BAD_INPUT);
    }
    let stored = args.systems.open();
    let reference = |reference: &str, ms: f64, total: usize| {
        eprintln!("errors against the {reference} ({ms:.0} ms); {total} settings")
    };
    let error = |e: Option<f64>| e.map_or("-".into(), |e| format!("{e:.2e}"));
    match args.kind {
        StudyKind::WorkPrecision => {
            let parsed = WorkPrecisionRequest::from_slice(&text).and_then(|req| {
                let job = req.to_spec(&stored)?.prepare(&limits)?;
                Ok((req.inlined(&stored), job))
            });
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
                recording::work_precision::write_rrd(
                    BufWriter::new(f),
                    &recording::Spec::of(spec),
                    doc,
                )
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
            let parsed = ConvergenceRequest::from_slice(&text).and_then(|req| {
                let job = req.to_spec(&stored)?.prepare(&limits)?;
                Ok((req, job))
            });
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
        StudyKind::Sweep | StudyKind::Basins | StudyKind::Merge => {
            unreachable!("`geomint study sweep|basins|merge` runs in cli::sweep")
        }
    }
}

/// An energy-error map (001 Fig. 6) on all cores, with progress on standard error.
fn run_energy_map(args: &StudyArgs, source: &str, text: &[u8]) -> ExitCode {
    use crate::api::studies::EnergyMapRequest;
    use crate::core::studies::energy_map::{self, MapLine};
    let parsed = crate::api::json::parse_json(text)
        .and_then(|v| EnergyMapRequest::from_value(&v))
        .and_then(|req| Ok(req.to_spec()?.prepare()?));
    let spec = match parsed {
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
    let doc = match energy_map::run(&spec, &Local, Budget::default(), &progress) {
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
pub(crate) fn wants_rrd(args: &StudyArgs) -> bool {
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
    parsed: Result<(S, StudyJob), ErrorDetail>,
    run: fn(
        &StudyJob,
        &Local,
        Budget<'_>,
        &(dyn Fn(L) -> bool + Sync),
    ) -> Result<L::Document, CoreError>,
    progress: impl Fn(&L) + Sync,
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
    let doc = match run(&job, &Local, Budget::default(), &emit) {
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
pub(crate) fn write_document<D: serde::Serialize>(
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

//! `geomint study sweep|basins spec.json [--shard i/n|auto] [-o out.json]` and
//! `geomint study merge part-*.json [-o result.json]`: a sweep or a basin map on all cores, whole
//! or one shard of it (an array task of Slurm or a Kubernetes Indexed Job takes its index from
//! `SLURM_ARRAY_TASK_ID` or `JOB_COMPLETION_INDEX`), and the merge of the parts into the document
//! the whole study gives, bit for bit.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::process::ExitCode;

use super::study::{wants_rrd, write_document, StudyArgs};
use super::{read_spec, BAD_INPUT};
use crate::api::basins::BasinsRequest;
use crate::api::sweep::SweepRequest;
use crate::api::system::StoredSystems;
use crate::core::error::ErrorDetail;
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::basins::{BasinsDocument, BasinsJob};
use crate::core::studies::engine::{self, CellLine, Documented, Local, Progress};
use crate::core::studies::parts::{self, Part, Shard};
use crate::core::studies::sweep::{SweepDocument, SweepJob, SweepSpec};
use crate::core::studies::StudySpec;
use crate::recording::RecordingError;

/// Reads a sweep request and prepares it: the spec and the job.
pub fn prepare(
    value: &serde_json::Value,
    limits: &Limits,
    stored: &dyn StoredSystems,
) -> Result<(SweepSpec, SweepJob), ErrorDetail> {
    let spec = SweepRequest::from_value(value)?.to_spec(stored)?;
    let job = spec.prepare(limits)?;
    Ok((spec, job))
}

/// The shard an array task runs: `i/n` as given, or for `auto` the index from
/// `SLURM_ARRAY_TASK_ID` (less `SLURM_ARRAY_TASK_MIN`) or `JOB_COMPLETION_INDEX`, and the count
/// from `SLURM_ARRAY_TASK_COUNT` or `GEOMINT_SHARDS`.
pub fn shard_of(given: &str, env: impl Fn(&str) -> Option<String>) -> Result<Shard, String> {
    if given != "auto" {
        return Shard::parse(given).map_err(|e| e.to_string());
    }
    let number = |name: &str| -> Result<Option<usize>, String> {
        env(name)
            .map(|v| {
                v.trim()
                    .parse::<usize>()
                    .map_err(|_| format!("{name}=`{v}` is not a whole number"))
            })
            .transpose()
    };
    let index = match (
        number("SLURM_ARRAY_TASK_ID")?,
        number("JOB_COMPLETION_INDEX")?,
    ) {
        (Some(id), _) => id
            .checked_sub(number("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0))
            .ok_or("SLURM_ARRAY_TASK_ID is below SLURM_ARRAY_TASK_MIN")?,
        (None, Some(index)) => index,
        (None, None) => {
            return Err("--shard auto needs SLURM_ARRAY_TASK_ID or JOB_COMPLETION_INDEX".into())
        }
    };
    let count =
        match (number("SLURM_ARRAY_TASK_COUNT")?, number("GEOMINT_SHARDS")?) {
            (Some(n), _) | (None, Some(n)) => n,
            (None, None) => return Err(
                "--shard auto needs the number of shards: SLURM_ARRAY_TASK_COUNT or GEOMINT_SHARDS"
                    .into(),
            ),
        };
    Shard::parse(&format!("{index}/{count}")).map_err(|e| e.to_string())
}

/// A study the command line runs whole or shard by shard: its spec as it travels, and the job.
type Prepared<S> = Result<(StudySpec, S), ErrorDetail>;

/// How a whole study's document is written as a Rerun recording, for kinds that have one.
type Recorder<D> = fn(File, &D) -> Result<(), String>;

/// `geomint study sweep`: the whole sweep, or with `--shard` one part of it.
pub(crate) fn run_sweep(args: &StudyArgs) -> ExitCode {
    run_cells(args, |value, limits, stored| {
        let (spec, job) = prepare(value, limits, stored)?;
        Ok((StudySpec::Sweep(spec), job))
    })
}

/// `geomint study basins`: the whole basin map, or with `--shard` one part of it.
pub(crate) fn run_basins(args: &StudyArgs) -> ExitCode {
    run_cells(args, |value, limits, stored| {
        let (request, sweep) = BasinsRequest::from_value(value)?;
        let spec = request.to_spec(&sweep, stored)?;
        let job = spec.prepare(limits)?;
        Ok((StudySpec::Basins(spec), job))
    })
}

/// Reads the spec file with `read` and runs the study it gives on all cores, whole or the shard
/// `--shard` names, with progress on standard error.
fn run_cells<S: Recorded>(
    args: &StudyArgs,
    read: impl FnOnce(&serde_json::Value, &Limits, &dyn StoredSystems) -> Prepared<S>,
) -> ExitCode {
    let limits = &args.limits();
    let (source, text) = match read_spec(&args.spec) {
        Ok(spec) => spec,
        Err(code) => return code,
    };
    let stored = args.systems.open();
    let parsed = crate::api::json::parse_json(&text).and_then(|v| read(&v, limits, &stored));
    let (spec, job) = match parsed {
        Ok(parsed) => parsed,
        Err(e) => {
            eprintln!("error: {source}: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let shard = match args
        .shard
        .as_deref()
        .map(|s| shard_of(s, |k| std::env::var(k).ok()))
    {
        None => None,
        Some(Ok(shard)) => Some(shard),
        Some(Err(e)) => {
            eprintln!("error: --shard: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let cells = match shard.map(|s| s.cells(job.cells())) {
        None => 0..job.cells(),
        Some(Ok(cells)) => cells,
        Some(Err(e)) => {
            eprintln!("error: --shard: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    eprintln!(
        "{} of {} cells of the {} (at most {} steps in all for the whole of it) on {} threads",
        cells.len(),
        job.cells(),
        job.name(),
        job.steps(),
        rayon::current_num_threads()
    );
    let report = |done: usize, total: usize| {
        eprint!("\r{done}/{total} cells");
        if done == total {
            eprintln!();
        }
    };
    let progress = Progress::new(cells.len(), &report);
    let written = match shard {
        Some(shard) => parts::run_shard(&job, spec, shard, &|_, _| progress.add(1)).map(|part| {
            eprintln!("{:.1} s", part.wall_ms / 1e3);
            write_document(args, false, &part, None::<Recorder<Part<S::Cell>>>)
        }),
        None => {
            engine::run(&job, &Local, Budget::default(), &|_, _| progress.add(1)).map(|finished| {
                eprintln!("{:.1} s", finished.wall_ms / 1e3);
                whole(args, &job.document_of(finished), S::recorder())
            })
        }
    };
    written.unwrap_or_else(|e| {
        eprintln!("error: {source}: {e}");
        ExitCode::FAILURE
    })
}

/// A study the command line runs in cells, and how its whole document is recorded.
trait Recorded: Documented {
    /// The recorder of its document, for kinds that have one.
    fn recorder() -> Option<Recorder<<Self::Line as CellLine>::Document>>;
}

/// Writes `doc` into `file` through the buffered recording writer `write`, flushed.
fn flushed<D>(
    write: fn(BufWriter<File>, &D) -> Result<BufWriter<File>, RecordingError>,
    file: File,
    doc: &D,
) -> Result<(), String> {
    write(BufWriter::new(file), doc)
        .map_err(|e| e.to_string())
        .and_then(|mut w| w.flush().map_err(|e| e.to_string()))
}

impl Recorded for SweepJob {
    fn recorder() -> Option<Recorder<SweepDocument>> {
        Some(|f, doc| flushed(crate::recording::sweep::write_rrd, f, doc))
    }
}

impl Recorded for BasinsJob {
    fn recorder() -> Option<Recorder<BasinsDocument>> {
        Some(|f, doc| flushed(crate::recording::basins::write_rrd, f, doc))
    }
}

/// Reads a part file as one of a study whose cells are `C`.
fn read_part<C: serde::de::DeserializeOwned>(path: &Path) -> Result<Part<C>, String> {
    let text = std::fs::read(path).map_err(|e| format!("cannot read it: {e}"))?;
    serde_json::from_slice(&text).map_err(|e| format!("not a part of a sweep or basin map: {e}"))
}

/// The spec a part file carries, read before its cells (whose type depends on it).
fn spec_of_part(path: &Path) -> Result<StudySpec, String> {
    #[derive(serde::Deserialize)]
    struct SpecOnly {
        spec: StudySpec,
    }
    let text = std::fs::read(path).map_err(|e| format!("cannot read it: {e}"))?;
    serde_json::from_slice::<SpecOnly>(&text)
        .map(|p| p.spec)
        .map_err(|e| format!("not a part of a sweep or basin map: {e}"))
}

/// `geomint study merge`: the parts of a sweep or a basin map (every shard exactly once) into
/// its document.
pub(crate) fn run_merge(args: &StudyArgs) -> ExitCode {
    let limits = &args.limits();
    let first = args.spec.display().to_string();
    let spec = match spec_of_part(&args.spec) {
        Ok(spec) => spec,
        Err(e) => {
            eprintln!("error: {first}: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    match &spec {
        StudySpec::Sweep(sweep) => match sweep.prepare(limits) {
            Ok(job) => merge_parts(args, &job, &spec),
            Err(e) => spec_error(&first, e),
        },
        StudySpec::Basins(map) => match map.prepare(limits) {
            Ok(job) => merge_parts(args, &job, &spec),
            Err(e) => spec_error(&first, e),
        },
        _ => {
            eprintln!("error: {first}: not a part of a sweep or basin map");
            ExitCode::from(BAD_INPUT)
        }
    }
}

fn spec_error(first: &str, e: crate::core::error::CoreError) -> ExitCode {
    eprintln!("error: {first}: its spec: {e}");
    ExitCode::from(BAD_INPUT)
}

/// Reads every part as one of `job` (whose spec is `spec`) and writes the merged document.
fn merge_parts<S: Recorded>(args: &StudyArgs, job: &S, spec: &StudySpec) -> ExitCode {
    let mut parts = Vec::new();
    for path in std::iter::once(&args.spec).chain(&args.parts) {
        let name = path.display().to_string();
        match read_part::<S::Cell>(path) {
            Ok(part) => parts.push((name, part)),
            Err(e) => {
                eprintln!("error: {name}: {e}");
                return ExitCode::from(BAD_INPUT);
            }
        }
    }
    let (cells, wall_ms) = match parts::merge(job, spec, parts) {
        Ok(merged) => merged,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    eprintln!("merged {} cells", cells.len());
    whole(
        args,
        &engine::document_of_parts(job, cells, wall_ms),
        S::recorder(),
    )
}

/// Writes a whole study's document: a Rerun recording for an output file ending in `.rrd` (for
/// kinds that have one), JSON otherwise.
fn whole<D: serde::Serialize>(args: &StudyArgs, doc: &D, record: Option<Recorder<D>>) -> ExitCode {
    write_document(args, wants_rrd(args), doc, record)
}

//! `geomint study sweep spec.json [--shard i/n|auto] [-o out.json]` and
//! `geomint study merge part-*.json [-o result.json]`: a sweep on all cores, whole or one shard
//! of it (an array task of Slurm or a Kubernetes Indexed Job takes its index from
//! `SLURM_ARRAY_TASK_ID` or `JOB_COMPLETION_INDEX`), and the merge of the parts into the document
//! the whole sweep gives, bit for bit.

use std::path::Path;
use std::process::ExitCode;

use super::study::{wants_rrd, write_document, StudyArgs};
use super::{read_spec, BAD_INPUT};
use crate::api::sweep::SweepRequest;
use crate::api::system::StoredSystems;
use crate::core::error::ErrorDetail;
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::engine::{Local, Progress, Study};
use crate::core::studies::parts::{self, Part, Shard};
use crate::core::studies::sweep::{self, RunMetrics, SweepJob, SweepLine, SweepSpec};
use crate::core::studies::StudySpec;

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

/// `geomint study sweep`: the whole sweep, or with `--shard` one part of it.
pub(crate) fn run_sweep(args: &StudyArgs) -> ExitCode {
    let limits = &args.limits();
    let (source, text) = match read_spec(&args.spec) {
        Ok(spec) => spec,
        Err(code) => return code,
    };
    let stored = args.systems.open();
    let parsed = crate::api::json::parse_json(&text).and_then(|v| prepare(&v, limits, &stored));
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
        "{} of {} cells × {} runs ({} steps in all for the whole sweep) on {} threads",
        cells.len(),
        job.cells(),
        job.runs.len(),
        job.total_steps,
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
        Some(shard) => {
            parts::run_shard(&job, StudySpec::Sweep(spec), shard, &|_, _| progress.add(1)).map(
                |part| {
                    eprintln!("{:.1} s", part.wall_ms / 1e3);
                    write_document(
                        args,
                        false,
                        &part,
                        None::<NoRecording<Part<Vec<RunMetrics>>>>,
                    )
                },
            )
        }
        None => {
            let emit = |line: SweepLine| {
                if let SweepLine::Progress { done, total } = line {
                    report(done, total);
                }
                true
            };
            sweep::run(&job, &Local, Budget::default(), &emit).map(|doc| {
                eprintln!("{:.1} s", doc.wall_ms / 1e3);
                whole(args, &doc)
            })
        }
    };
    written.unwrap_or_else(|e| {
        eprintln!("error: {source}: {e}");
        ExitCode::FAILURE
    })
}

type NoRecording<D> = fn(std::fs::File, &D) -> Result<(), String>;

/// Reads a part file.
fn read_part(path: &Path) -> Result<Part<Vec<RunMetrics>>, String> {
    let text = std::fs::read(path).map_err(|e| format!("cannot read it: {e}"))?;
    serde_json::from_slice(&text).map_err(|e| format!("not a part of a sweep: {e}"))
}

/// `geomint study merge`: the parts of a sweep (every shard exactly once) into its document.
pub(crate) fn run_merge(args: &StudyArgs) -> ExitCode {
    let limits = &args.limits();
    let mut parts = Vec::new();
    for path in std::iter::once(&args.spec).chain(&args.parts) {
        let name = path.display().to_string();
        match read_part(path) {
            Ok(part) => parts.push((name, part)),
            Err(e) => {
                eprintln!("error: {name}: {e}");
                return ExitCode::from(BAD_INPUT);
            }
        }
    }
    let (first, part) = &parts[0];
    let spec = part.spec.clone();
    let prepared = match &spec {
        StudySpec::Sweep(sweep) => sweep.prepare(limits).map_err(|e| e.to_string()),
        _ => Err("not a sweep".into()),
    };
    let job = match prepared {
        Ok(job) => job,
        Err(e) => {
            eprintln!("error: {first}: its spec: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    let (cells, wall_ms) = match parts::merge(&job, &spec, parts) {
        Ok(merged) => merged,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(BAD_INPUT);
        }
    };
    eprintln!("merged {} cells", cells.len());
    whole(args, &job.document(cells, wall_ms))
}

/// Writes a whole sweep's document: a Rerun recording for an output file ending in `.rrd`, JSON
/// otherwise.
fn whole(args: &StudyArgs, doc: &sweep::SweepDocument) -> ExitCode {
    let record = |f: std::fs::File, doc: &sweep::SweepDocument| {
        crate::recording::sweep::write_rrd(std::io::BufWriter::new(f), doc)
            .map_err(|e| e.to_string())
            .and_then(|mut w| std::io::Write::flush(&mut w).map_err(|e| e.to_string()))
    };
    write_document(args, wants_rrd(args), doc, Some(record))
}

//! `geomint study KIND spec.json [--shard i/n|auto] [-o out]` and `geomint study merge
//! part-*.json [-o out]`: any kind of study ([`crate::studies`]; the spec is the body of its
//! route) without a server, on all cores, whole or one shard of it (an array task of Slurm or a
//! Kubernetes Indexed Job takes its index from `SLURM_ARRAY_TASK_ID` or
//! `JOB_COMPLETION_INDEX`), and the merge of the parts into the document the whole study gives,
//! bit for bit apart from wall times. Progress goes to standard error; the document is JSON, or
//! a Rerun recording for an output file ending in `.rrd` (kinds that have one).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use clap::builder::{PossibleValue, PossibleValuesParser};
use clap::Args;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::{parse_count, print_json, read_spec, SystemsDir, BAD_INPUT};
use crate::core::run::Budget;
use crate::core::simulation::Limits;
use crate::core::studies::engine::{Local, Progress};
use crate::core::studies::parts::{self, AnyPart, Shard, ShardError};
use crate::core::studies::StudySpec;
use crate::studies::merged::{Merged, PartText};
use crate::studies::{self, Report, StudyKind, Visit};

/// The verb that merges parts rather than running a study.
pub const MERGE: &str = "merge";

/// Settings of `geomint study`.
#[derive(Clone, Debug, Args)]
pub struct StudyArgs {
    /// The kind of study (its route's name), or `merge`.
    #[arg(value_parser = kinds())]
    pub kind: String,
    /// The spec file (JSON, the body of the study's route); `-` reads standard input. For
    /// `merge`, the first part.
    pub spec: PathBuf,
    /// For `merge`: the other parts.
    pub parts: Vec<PathBuf>,
    /// Run shard `i/n` only (cells in a fixed order, so parts from any machines merge to the
    /// whole study bit for bit), or `auto` for the index of a Slurm array task
    /// (`SLURM_ARRAY_TASK_ID`) or a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`) and the
    /// count from `SLURM_ARRAY_TASK_COUNT` or `GEOMINT_SHARDS`.
    #[arg(long)]
    pub shard: Option<String>,
    /// Output file; `.rrd` writes the study's Rerun recording (kinds that have one), anything
    /// else JSON (default: standard output). Progress goes to standard error.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Most steps per run or setting.
    #[arg(long, env = "GEOMINT_MAX_STEPS", default_value = "10000000", value_parser = parse_count)]
    pub max_steps: u64,
    /// Stored system definitions.
    #[command(flatten)]
    pub systems: SystemsDir,
}

/// The kinds `geomint study` takes, each with its line of help, and `merge`.
fn kinds() -> PossibleValuesParser {
    let merge = PossibleValue::new(MERGE)
        .help("The parts of a study (`--shard` outputs, every shard once) into its document");
    PossibleValuesParser::new(
        studies::about()
            .into_iter()
            .map(|(name, about)| PossibleValue::new(name).help(about))
            .chain([merge]),
    )
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

/// `geomint study`: the kind named, or the merge of parts.
pub(crate) fn run_study(args: &StudyArgs) -> ExitCode {
    if args.kind == MERGE {
        return merge(args);
    }
    if !args.parts.is_empty() {
        return refuse("one spec file only (several files are for `merge`)");
    }
    studies::visit(&args.kind, Whole(args))
        .unwrap_or_else(|| refuse(&studies::unknown("study", &args.kind).to_string()))
}

/// Prints `message` as the command line's error and exits for bad input.
fn refuse(message: &str) -> ExitCode {
    eprintln!("error: {message}");
    ExitCode::from(BAD_INPUT)
}

/// Runs the kind of study visited, whole or a shard of it.
struct Whole<'a>(&'a StudyArgs);

impl Visit for Whole<'_> {
    type Output = ExitCode;
    fn kind<K: StudyKind>(self) -> ExitCode {
        run_kind::<K>(self.0)
    }
}

/// Reports a progress line on standard error.
fn report(report: Report) {
    match report {
        Report::Cells { done, total } => {
            eprint!("\r{done}/{total} cells");
            if done == total {
                eprintln!();
            }
        }
        Report::Line(line) => eprintln!("{line}"),
    }
}

/// What a part file holds: the kind of study and the request it was read from, so that
/// `merge` prepares the study again and makes its document and recording, and the part.
#[derive(Serialize)]
struct PartFile<'a> {
    study: &'static str,
    request: &'a Value,
    #[serde(flatten)]
    part: &'a AnyPart,
}

/// Reads the spec file as a `K` and runs it on all cores, whole or the shard `--shard` names,
/// with progress on standard error.
fn run_kind<K: StudyKind>(args: &StudyArgs) -> ExitCode {
    let limits = &args.limits();
    let (source, text) = match read_spec(&args.spec) {
        Ok(spec) => spec,
        Err(code) => return code,
    };
    let stored = args.systems.open();
    let parsed = crate::api::json::parse_json(&text)
        .and_then(|request| Ok((K::prepare(&request, &stored, limits)?, request)));
    let (study, request) = match parsed {
        Ok(parsed) => parsed,
        Err(e) => return refuse(&format!("{source}: {e}")),
    };
    let shard = match args
        .shard
        .as_deref()
        .map(|s| shard_of(s, |k| std::env::var(k).ok()))
        .transpose()
    {
        Ok(shard) => shard,
        Err(e) => return refuse(&format!("--shard: {e}")),
    };
    let cells = match shard.map(|s| s.cells(study.cells())).transpose() {
        Ok(cells) => cells.unwrap_or(0..study.cells()),
        Err(e) => return refuse(&format!("--shard: {e}")),
    };
    let wants_rrd = wants_rrd(args) && shard.is_none();
    if wants_rrd && K::ANSWERS.recording.is_none() {
        return refuse("this kind of study has no recording; write JSON (e.g. -o out.json)");
    }
    eprintln!(
        "{} of {} cells of the {} study (at most {} steps in all for the whole of it) on {} threads",
        cells.len(),
        study.cells(),
        K::NAME,
        study.steps(),
        rayon::current_num_threads()
    );
    let failed = |e: crate::core::error::CoreError| {
        eprintln!("error: {source}: {e}");
        ExitCode::FAILURE
    };
    if let Some(shard) = shard {
        let counted = |done, total| report(Report::Cells { done, total });
        let progress = Progress::new(cells.len(), &counted);
        let shard_limits = study.shard_limits(limits);
        let done = || progress.add(1);
        return match parts::run_part(&study.spec(), shard, None, &shard_limits, &done) {
            Ok(part) => {
                eprintln!("{:.1} s", part.wall_ms() / 1e3);
                let file = PartFile {
                    study: K::NAME,
                    request: &study.portable_request(&request),
                    part: &part,
                };
                write_json(args, &file)
            }
            Err(e) => failed(e),
        };
    }
    let emit = |line: K::Line| {
        if let Some(line) = K::report(&line) {
            report(line);
        }
        true
    };
    match study.run(&Local, Budget::default(), &emit) {
        Ok(doc) => finish(args, wants_rrd, &study, &doc),
        Err(e) => failed(e),
    }
}

/// Says what the study came to and writes its document.
fn finish<K: StudyKind>(
    args: &StudyArgs,
    wants_rrd: bool,
    study: &K,
    doc: &K::Document,
) -> ExitCode {
    if let Some(summary) = study.summary(doc) {
        eprintln!("{summary}");
    }
    write_document(args, wants_rrd, study, doc)
}

/// What `merge` reads of each part before it knows the kind of its cells.
#[derive(Deserialize)]
struct PartHeader {
    /// The kind of study (absent in parts of sweeps and basin maps written before parts
    /// carried it).
    study: Option<String>,
    /// The request the study was read from (absent likewise).
    request: Option<Value>,
    spec: StudySpec,
    shard: usize,
    wall_ms: f64,
}

/// `geomint study merge`: the parts of a study (every shard exactly once) into its document.
fn merge(args: &StudyArgs) -> ExitCode {
    let mut parts = Vec::new();
    let mut walls = Vec::new();
    let mut first = None;
    for path in std::iter::once(&args.spec).chain(&args.parts) {
        let name = path.display().to_string();
        let text = match std::fs::read(path) {
            Ok(text) => text,
            Err(e) => return refuse(&format!("{name}: cannot read it: {e}")),
        };
        let header = match serde_json::from_slice::<PartHeader>(&text) {
            Ok(header) => header,
            Err(e) => return refuse(&format!("{name}: not a part of a study: {e}")),
        };
        walls.push((header.shard, header.wall_ms));
        parts.push(PartText {
            name,
            spec: header.spec.clone(),
            text,
        });
        first.get_or_insert(header);
    }
    let Some(first) = first else {
        return refuse("no parts to merge");
    };
    // A part of another study is refused before anything is computed (a settings study's
    // reference run, say).
    if let Some(foreign) = parts.iter().find(|p| p.spec != first.spec) {
        return refuse(
            &ShardError::Foreign {
                part: foreign.name.clone(),
            }
            .to_string(),
        );
    }
    // The parts' wall times summed in shard order, whatever order they were given in.
    walls.sort_by_key(|&(shard, _)| shard);
    let wall_ms = walls.iter().map(|&(_, ms)| ms).sum();
    let kind = match (&first.study, &first.spec) {
        (Some(kind), _) => kind.clone(),
        (None, StudySpec::Sweep(_)) => "sweep".into(),
        (None, StudySpec::Basins(_)) => "basins".into(),
        (None, _) => return refuse(&format!("{}: does not say its study", parts[0].name)),
    };
    let merged = Merged::new(parts, wall_ms);
    let visit = MergeParts {
        args,
        first,
        merged: &merged,
    };
    studies::visit(&kind, visit).unwrap_or_else(|| {
        refuse(&format!(
            "{}: {}",
            args.spec.display(),
            studies::unknown("study", &kind)
        ))
    })
}

/// Merges parts into the kind of study visited.
struct MergeParts<'a> {
    args: &'a StudyArgs,
    first: PartHeader,
    merged: &'a Merged,
}

impl Visit for MergeParts<'_> {
    type Output = ExitCode;
    fn kind<K: StudyKind>(self) -> ExitCode {
        let MergeParts {
            args,
            first,
            merged,
        } = self;
        let source = args.spec.display().to_string();
        let limits = &args.limits();
        let stored = args.systems.open();
        let prepared = match (K::from_spec(&first.spec, limits), &first.request) {
            (Some(prepared), _) => prepared.map_err(Into::into),
            (None, Some(request)) => K::prepare(request, &stored, limits),
            (None, None) => return refuse(&format!("{source}: carries no request to merge it by")),
        };
        let study = match prepared {
            Ok(study) => study,
            Err(e) => return refuse(&format!("{source}: its study: {e}")),
        };
        let wants_rrd = wants_rrd(args);
        if wants_rrd && K::ANSWERS.recording.is_none() {
            return refuse("this kind of study has no recording; write JSON (e.g. -o out.json)");
        }
        match study.run(merged, Budget::default(), &|_| true) {
            Ok(doc) => {
                eprintln!("merged {} cells", study.cells());
                finish(args, wants_rrd, &study, &doc)
            }
            Err(e) => match merged.refused() {
                Some(refused) => refuse(&refused.to_string()),
                None => {
                    eprintln!("error: {source}: {e}");
                    ExitCode::FAILURE
                }
            },
        }
    }
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

/// Whether the output file's name ends in `.rrd`.
pub(crate) fn wants_rrd(args: &StudyArgs) -> bool {
    args.output
        .as_ref()
        .and_then(|p| p.extension())
        .is_some_and(|e| e.eq_ignore_ascii_case("rrd"))
}

/// Writes a study's document to the output file — the study's recording when `wants_rrd`,
/// pretty JSON otherwise — or prints it without one.
fn write_document<K: StudyKind>(
    args: &StudyArgs,
    wants_rrd: bool,
    study: &K,
    doc: &K::Document,
) -> ExitCode {
    match &args.output {
        Some(path) if wants_rrd => written(
            study
                .record(doc)
                .map_err(|e| e.to_string())
                .and_then(|bytes| std::fs::write(path, bytes).map_err(|e| e.to_string())),
        ),
        _ => write_json(args, doc),
    }
}

/// Writes `doc` as pretty JSON to the output file, or prints it without one.
fn write_json<D: Serialize>(args: &StudyArgs, doc: &D) -> ExitCode {
    let Some(path) = &args.output else {
        return print_json(doc);
    };
    written(File::create(path).map_err(|e| e.to_string()).and_then(|f| {
        let mut w = BufWriter::new(f);
        serde_json::to_writer_pretty(&mut w, doc)
            .map_err(|e| e.to_string())
            .and_then(|()| {
                writeln!(w)
                    .and_then(|()| w.flush())
                    .map_err(|e| e.to_string())
            })
    }))
}

/// The exit code of writing the output.
fn written(result: Result<(), String>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: cannot write the output: {e}");
            ExitCode::FAILURE
        }
    }
}

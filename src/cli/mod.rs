//! The command line: `geomint serve` (the default; [`serve`]), `geomint run spec.json` (a
//! simulation written as JSON, NDJSON or a Rerun recording, optionally streamed live to a Rerun
//! viewer; [`run`](mod@run)), `geomint study KIND spec.json` (any study, whole or a shard, and the
//! merge of shards, as JSON or `.rrd`; [`study`]), and `geomint systems` / `geomint methods`
//! (the catalogues), `geomint token NAME` (a bearer token's secret and its line of the tokens
//! file; [`token`]), `geomint job …` (a server's jobs; [`job`]). Every server setting can also come from a `GEOMINT_*` environment variable.
//!
//! Exit codes: 0 on success, 2 for a bad command line, an unreadable spec or an invalid one
//! (the message names the field), 1 when output cannot be written, the Rerun viewer cannot be
//! reached or the server cannot start.

pub mod job;
pub mod run;
pub mod serve;
pub mod study;
pub mod token;

use std::io::{self, Read, Write};
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

use crate::core::methods::MethodId;
use crate::core::systems;
use crate::store::systems::{SystemStore, DEFAULT_SYSTEMS_DIR};
pub use job::JobArgs;
pub use run::RunArgs;
pub use serve::{ServeArgs, WorkerArgs};
pub use study::StudyArgs;
pub use token::TokenArgs;

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
    /// Run a study spec without a server (`sweep`, `basins`, `energy-map`, `stability`,
    /// `convergence`, `work-precision`: the body of the study's route), whole or one shard of
    /// it, or merge the parts of a sharded study (`merge`).
    Study(StudyArgs),
    /// Run sweep shards from a NATS JetStream server for `geomint serve --nats` (any number of
    /// workers, on any machines).
    Worker(WorkerArgs),
    /// Make a bearer token: print its secret and the line of the tokens file (`serve --tokens`)
    /// that admits it.
    Token(TokenArgs),
    /// A server's jobs: submit a study, follow it, fetch its result, cancel it.
    Job(JobArgs),
    /// Print the system catalogue as JSON.
    Systems,
    /// Print the method catalogue as JSON.
    Methods,
}

/// Carries out a parsed command line.
pub fn run(cli: Cli) -> ExitCode {
    match cli.command.unwrap_or(Command::Serve(cli.serve)) {
        Command::Serve(args) => serve::serve(&args),
        Command::Run(args) => run::run_spec(&args),
        Command::Study(args) => study::run_study(&args),
        Command::Worker(args) => serve::work(&args),
        Command::Token(args) => token::make_token(&args),
        Command::Job(args) => job::run_job(&args),
        Command::Systems => print_json(&systems::catalog()),
        Command::Methods => {
            let methods: Vec<_> = MethodId::ALL.iter().map(|m| m.info()).collect();
            print_json(&methods)
        }
    }
}

/// Where the command line reads stored system definitions, so that a spec can name one by id.
#[derive(Clone, Debug, Args)]
pub struct SystemsDir {
    /// The directory of stored system definitions (the one `geomint serve` keeps), so that a spec
    /// can name a stored system by its `sys-…` id as requests to the server do.
    #[arg(long, env = "GEOMINT_SYSTEMS_DIR", default_value = DEFAULT_SYSTEMS_DIR)]
    pub systems_dir: std::path::PathBuf,
}

impl SystemsDir {
    /// The definitions found there (none when the directory does not exist).
    pub fn open(&self) -> SystemStore {
        SystemStore::open(&self.systems_dir, usize::MAX)
    }
}

pub(crate) use crate::access::tokens::parse_count;

pub(crate) fn print_json<T: serde::Serialize>(value: &T) -> ExitCode {
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
pub(crate) const BAD_INPUT: u8 = 2;

/// The exit code once the output is written (or not).
pub(crate) fn finish_output(written: io::Result<()>) -> ExitCode {
    match written {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: cannot write the output: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Reads a spec file, or standard input for `-`: its name for messages and its bytes, or the
/// exit code after saying why it cannot be read.
pub(crate) fn read_spec(path: &std::path::Path) -> Result<(String, Vec<u8>), ExitCode> {
    let source = path.display().to_string();
    let text = if source == "-" {
        let mut buf = Vec::new();
        io::stdin().read_to_end(&mut buf).map(|_| buf)
    } else {
        std::fs::read(path)
    };
    text.map(|t| (source.clone(), t)).map_err(|e| {
        eprintln!("error: cannot read the spec `{source}`: {e}");
        ExitCode::from(BAD_INPUT)
    })
}

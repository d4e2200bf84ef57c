//! `geomint token NAME --scopes read,run`: makes a bearer token's secret and the line of the
//! tokens file that admits it (the secret's SHA-256 digest, never the secret), so that nobody
//! digests secrets by hand. Prints the secret, then the line; with `--append FILE` the line goes
//! to the end of the tokens file instead (created readable by its owner only) and only the secret
//! is printed. A running server picks the new line up by itself.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::parse_count;
use crate::access::tokens::{generate, TokenFile};
use crate::access::{Quotas, Scopes};

/// Settings of `geomint token`.
#[derive(Clone, Debug, Args)]
pub struct TokenArgs {
    /// The token's name (1 to 64 of A-Z a-z 0-9 - _ .): the owner of what it stores.
    pub name: String,
    /// Its scopes, comma-separated: read, run, store, admin.
    #[arg(long, default_value = "read,run,store")]
    pub scopes: String,
    /// Bytes of recordings it may keep (its own oldest are evicted past it; 1e9 style accepted).
    #[arg(long, value_parser = parse_count)]
    pub recordings_bytes: Option<u64>,
    /// System definitions it may store.
    #[arg(long)]
    pub systems: Option<usize>,
    /// Runs and studies it may have in flight at once.
    #[arg(long)]
    pub runs: Option<usize>,
    /// Steps × coordinates of simulations it may start per minute (1e9 style accepted).
    #[arg(long, value_parser = parse_count)]
    pub steps_per_minute: Option<u64>,
    /// Append the line to this tokens file (checked first: the name must be new) and print
    /// only the secret.
    #[arg(long)]
    pub append: Option<PathBuf>,
}

/// Makes the token; exit code 2 for a bad name, scope or tokens file.
pub(crate) fn make_token(args: &TokenArgs) -> ExitCode {
    let fail = |message: String| {
        eprintln!("error: {message}");
        ExitCode::from(2)
    };
    let scopes = match Scopes::parse(&args.scopes) {
        Ok(scopes) => scopes,
        Err(e) => return fail(format!("--scopes: {e}")),
    };
    let quotas = Quotas {
        recordings_bytes: args.recordings_bytes,
        systems: args.systems,
        runs: args.runs,
        steps_per_minute: args.steps_per_minute,
    };
    let made = match generate(&args.name, scopes, &quotas) {
        Ok(made) => made,
        Err(e) => return fail(e),
    };
    let Some(path) = &args.append else {
        println!("{}\n{}", made.secret, made.line);
        return ExitCode::SUCCESS;
    };
    let existing = match std::fs::read_to_string(path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
        Err(e) => return fail(format!("cannot read {}: {e}", path.display())),
    };
    let mut text = existing.clone();
    if !text.is_empty() && !text.ends_with('\n') {
        text.push('\n');
    }
    text.push_str(&made.line);
    text.push('\n');
    // The file with the new line must still read (a name used twice is refused).
    if let Err(e) = TokenFile::parse(&text) {
        return fail(format!("{}: {e}", path.display()));
    }
    let appended = {
        use std::os::unix::fs::OpenOptionsExt;
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .mode(0o600)
            .open(path)
            .and_then(|mut file| {
                let start = if existing.is_empty() || existing.ends_with('\n') {
                    ""
                } else {
                    "\n"
                };
                writeln!(file, "{start}{}", made.line)?;
                file.sync_all()
            })
    };
    match appended {
        Ok(()) => {
            println!("{}", made.secret);
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: cannot write {}: {e}", path.display());
            ExitCode::FAILURE
        }
    }
}

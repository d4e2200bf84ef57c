//! The `geomint` executable: parses the command line and hands it to [`geomint::cli`].

use clap::Parser;

fn main() -> std::process::ExitCode {
    geomint::cli::run(geomint::cli::Cli::parse())
}

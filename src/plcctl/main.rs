//! The `plcctl` binary: argument parsing and dispatch to [`plcctl::run`].

use std::process::ExitCode;

use clap::Parser;
use plcctl::Cli;

fn main() -> ExitCode {
    let cli = Cli::parse();
    plcctl::run(&cli, &mut std::io::stdout(), &mut std::io::stderr())
}

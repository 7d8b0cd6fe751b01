//! The `plcctl` binary: argument parsing and dispatch to [`plcd::plcctl`].

use std::process::ExitCode;

use clap::Parser;
use plcd::plcctl::{self, Cli};

fn main() -> ExitCode {
    let cli = Cli::parse();
    plcctl::run(&cli, &mut std::io::stdout(), &mut std::io::stderr())
}

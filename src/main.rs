//! The `plcd` binary: argument parsing and dispatch to [`plcd::commands`].

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use plcd::commands::bench::BenchArgs;
use plcd::commands::run::RunArgs;
use plcd::commands::sim::SimArgs;
use plcd::commands::user::UserArgs;

#[derive(Parser)]
#[command(name = "plcd", version, about = "A real-time soft-PLC for Linux")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The daemon, in the foreground: the project on real time and real I/O.
    Run(RunArgs),
    /// Load and validate the config and every program it names; run nothing.
    Check {
        /// The project's TOML config.
        #[arg(long)]
        config: PathBuf,
    },
    /// Run the engine in virtual time, deterministically, as fast as the CPU allows.
    Sim(SimArgs),
    /// Measure the real-time driver on this machine: cycle-task and edge latency.
    Bench(BenchArgs),
    /// The users of the network services: add (password without echo), remove, list.
    User(UserArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Run(args) => plcd::commands::run::run(&args),
        Command::Check { config } => {
            plcd::commands::check::run(&config, &mut std::io::stdout(), &mut std::io::stderr())
        }
        Command::Sim(args) => plcd::commands::sim::run(&args, &mut std::io::stderr()),
        Command::Bench(args) => {
            plcd::commands::bench::run(&args, &mut std::io::stdout(), &mut std::io::stderr())
        }
        Command::User(args) => {
            plcd::commands::user::run(&args, &mut std::io::stdout(), &mut std::io::stderr())
        }
    }
}

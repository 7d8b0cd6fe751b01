//! The `plcd` binary: argument parsing and dispatch to [`plcd::commands`].

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "plcd", version, about = "A real-time soft-PLC for Linux")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Load and validate the config and every program it names; run nothing.
    Check {
        /// The project's TOML config.
        #[arg(long)]
        config: PathBuf,
    },
    /// Run the engine in virtual time, deterministically, as fast as the CPU allows.
    Sim {
        /// The project's TOML config.
        #[arg(long)]
        config: PathBuf,
        /// Virtual time to run, e.g. `500ms`, `1.5s`.
        #[arg(long = "for", value_name = "DURATION")]
        duration: String,
        /// Input changes: CSV lines `time, device, value` (CONTRACT §4).
        #[arg(long, value_name = "CSV")]
        inputs: Option<PathBuf>,
        /// Write the trace (JSON Lines) to FILE, or `-` for standard output.
        #[arg(long, value_name = "FILE|-")]
        trace: Option<String>,
        /// Devices whose changes are traced, comma separated (default: every output P bit).
        #[arg(long, value_name = "DEVICES")]
        watch: Option<String>,
        /// Virtual time an executed instruction costs (default: `[sim] step_ns`).
        #[arg(long, value_name = "N")]
        step_ns: Option<u64>,
        /// Print a text Gantt chart of the run, one row per task.
        #[arg(long)]
        timeline: bool,
        /// Columns of the timeline.
        #[arg(long, default_value_t = 100, value_name = "COLUMNS")]
        timeline_width: usize,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Check { config } => {
            plcd::commands::check::run(&config, &mut std::io::stdout(), &mut std::io::stderr())
        }
        Command::Sim {
            config,
            duration,
            inputs,
            trace,
            watch,
            step_ns,
            timeline,
            timeline_width,
        } => {
            let args = plcd::commands::sim::SimArgs {
                config,
                duration,
                inputs,
                trace,
                watch,
                step_ns,
                timeline,
                timeline_width,
            };
            plcd::commands::sim::run(&args, &mut std::io::stderr())
        }
    }
}

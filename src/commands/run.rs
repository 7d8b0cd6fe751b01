//! `plcd run --config FILE`: the daemon, in the foreground (docs/DAEMON.md).

use std::path::PathBuf;
use std::process::ExitCode;

use crate::daemon::logging;
use crate::daemon::supervisor::{self, DaemonError, Options};
use crate::drivers::real_time::driver::DriverError;

/// The command's arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct RunArgs {
    /// The project's TOML config.
    #[arg(long)]
    pub config: PathBuf,
    /// Least severe messages logged: error, warn, info, debug or trace.
    #[arg(long, default_value = "info", value_name = "LEVEL", value_parser = parse_level)]
    pub log_level: log::LevelFilter,
}

/// Exit 0 after a clean stop (SIGTERM/SIGINT); 1 when the daemon cannot start (invalid config
/// or program, I/O, real time required but refused) or a thread died.
pub fn run(args: &RunArgs) -> ExitCode {
    let _ = logging::init(args.log_level);
    let options = Options { config: args.config.clone() };
    match supervisor::run(&options) {
        Ok(()) => ExitCode::SUCCESS,
        Err(DaemonError::Invalid(diagnostics)) => {
            for d in diagnostics.iter() {
                log::error!("{d}");
            }
            log::error!("not started: {} errors in the project", diagnostics.len());
            ExitCode::from(1)
        }
        Err(DaemonError::Driver(DriverError::Stimulus { source, .. })) => {
            for d in source.iter() {
                log::error!("{d}");
            }
            log::error!("not started: the stimulus file has errors");
            ExitCode::from(1)
        }
        Err(e) => {
            log::error!("{e}");
            ExitCode::from(1)
        }
    }
}

fn parse_level(text: &str) -> Result<log::LevelFilter, String> {
    text.parse().map_err(|_| format!("`{text}`: expected error, warn, info, debug or trace"))
}

//! Starting the programs of this build (`plcd`, `plcctl`) through an emulator when the tests
//! are cross-built for another architecture.
//!
//! `PLCD_TEST_RUNNER` holds the command, split on whitespace, that runs a binary of the target
//! (tests/cross/run-aarch64-tests sets it to `qemu-aarch64 -L /usr/aarch64-linux-gnu`, cargo's
//! own runner for the test binaries). Unset or empty, programs start directly. A test that
//! starts a built program goes through [`command`]; the process it gets is the emulator, which
//! runs the program in the same process (same pid, same signals, same exit status).
//!
//! This file needs nothing of plcd: the plcctl package's test includes it alone.

use std::ffi::OsStr;
use std::process::Command;

/// The variable naming the runner.
pub const VAR: &str = "PLCD_TEST_RUNNER";

/// The runner's words; empty when the built programs run directly.
pub fn runner() -> Vec<String> {
    std::env::var(VAR)
        .map(|v| v.split_whitespace().map(str::to_string).collect())
        .unwrap_or_default()
}

/// Whether the built programs run under an emulator.
pub fn emulated() -> bool {
    !runner().is_empty()
}

/// A command starting the built `program`: through the runner when there is one.
pub fn command(program: impl AsRef<OsStr>) -> Command {
    let runner = runner();
    match runner.split_first() {
        None => Command::new(program),
        Some((emulator, args)) => {
            let mut command = Command::new(emulator);
            command.args(args).arg(program);
            command
        }
    }
}

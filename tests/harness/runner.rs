//! Starting the programs of this build (`plcd`, `plcctl`) through an emulator when the tests
//! are cross-built for another architecture.
//!
//! `PLCD_TEST_RUNNER` holds the command, split on whitespace, that runs a binary of the target
//! (tests/cross/run-aarch64-tests sets it to `qemu-aarch64 -L /usr/aarch64-linux-gnu`, cargo's
//! own runner for the test binaries). Unset or empty, programs start directly. A test that
//! starts a built program goes through [`command`]; the process it gets is the emulator, which
//! runs the program in the same process (same pid, same signals, same exit status).
//!
//! Emulated, the programs are slower (qemu-user: 5 to 20 times, far more while it translates
//! code it runs for the first time, as at a start). A test whose real-time figures only stand
//! for "long enough" (a request's timeout, a random moment within a start) scales them by
//! [`slowdown`]; the harness's waits have patience enough as they are.
//!
//! It also owns the signal dispositions of the tests and their children (the unsafe calls of
//! the harness) and a bounded wait for a child.
//!
//! This file needs nothing of plcd: the plcctl package's test includes it alone.

use std::ffi::OsStr;
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, ExitStatus};
use std::time::{Duration, Instant};

use nix::sys::signal::{signal, SigHandler, Signal};

/// The signals the tests send to the programs they start, set back to their default action in
/// each child: a test process started in the background by a non-interactive shell ignores
/// SIGINT and SIGQUIT, and a child inherits what is ignored (std resets only SIGPIPE and the
/// mask), so a `kill -INT` would do nothing and the test would wait for ever.
const SIGNALS_RESET: [Signal; 4] =
    [Signal::SIGINT, Signal::SIGQUIT, Signal::SIGTERM, Signal::SIGHUP];

/// The variable naming the runner.
pub const VAR: &str = "PLCD_TEST_RUNNER";

/// The variable that sets [`slowdown`] under a runner.
pub const SLOWDOWN_VAR: &str = "PLCD_TEST_SLOWDOWN";

/// The slowdown assumed under a runner unless `PLCD_TEST_SLOWDOWN` says otherwise.
pub const EMULATED_SLOWDOWN: u32 = 5;

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

/// A command starting the built `program`: through the runner when there is one, with the
/// signals of [`SIGNALS_RESET`] at their default action whatever the test process ignores.
pub fn command(program: impl AsRef<OsStr>) -> Command {
    let runner = runner();
    let mut command = match runner.split_first() {
        None => Command::new(program),
        Some((emulator, args)) => {
            let mut command = Command::new(emulator);
            command.args(args).arg(program);
            command
        }
    };
    // SAFETY: the closure runs in the child between fork and exec, where only
    // async-signal-safe calls are allowed: `signal` is sigaction(2), which is one, and the
    // closure allocates nothing and takes no lock.
    unsafe {
        command.pre_exec(|| {
            for sig in SIGNALS_RESET {
                signal(sig, SigHandler::SigDfl)?;
            }
            Ok(())
        });
    }
    command
}

/// Makes this test process ignore `sig`, as a shell's background job ignores SIGINT and
/// SIGQUIT: for the tests that check that the programs they start do not inherit it.
pub fn ignore_in_this_process(sig: Signal) {
    // SAFETY: SIG_IGN installs no handler, so no handler code can run at a bad moment.
    unsafe { signal(sig, SigHandler::SigIgn) }.unwrap_or_else(|e| panic!("ignore {sig}: {e}"));
}

/// Waits for `child` to exit for at most `patience`; past it, kills the child and fails the
/// test naming `what`. Whatever the child's output is piped to must be read by someone (or be
/// null): a child blocked on a full pipe never exits.
pub fn wait_bounded(child: &mut Child, patience: Duration, what: &str) -> ExitStatus {
    let deadline = Instant::now() + patience;
    loop {
        if let Some(status) = child.try_wait().expect("waitpid") {
            return status;
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running after {patience:?}; killed");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// How many times longer than natively the built programs may take: 1 without a runner; with
/// one, `PLCD_TEST_SLOWDOWN` (a positive integer) or [`EMULATED_SLOWDOWN`].
pub fn slowdown() -> u32 {
    if !emulated() {
        return 1;
    }
    match std::env::var(SLOWDOWN_VAR) {
        Ok(text) => match text.trim().parse::<u32>() {
            Ok(factor) if factor >= 1 => factor,
            _ => panic!("{SLOWDOWN_VAR}={text:?}: expected a positive integer"),
        },
        Err(_) => EMULATED_SLOWDOWN,
    }
}

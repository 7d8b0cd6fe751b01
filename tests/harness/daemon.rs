//! The real `plcd run` in a test: a project directory, the daemon started on it away from any
//! systemd environment the test runner inherited, its log, signals, and `plcctl` against it.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Child, Output, Stdio};
use std::thread::JoinHandle;
use std::time::Duration;

use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

use super::log::{wait_until, Log, PATIENCE};
use super::runner;
use super::tempdir::TempDir;

/// The `plcd` binary of this build; in the gpio-sim VM of `tests/qemu/run-gpiosim`, where the
/// test binaries run without their build tree, the `/bin/plcd` it installs beside them.
pub fn plcd_binary() -> PathBuf {
    let built = Path::new(env!("CARGO_BIN_EXE_plcd"));
    if built.exists() {
        built.to_path_buf()
    } else {
        PathBuf::from("/bin/plcd")
    }
}

/// The `plcctl` binary. It is a package of its own (it builds without the daemon), so cargo
/// gives this package no `CARGO_BIN_EXE_plcctl`; `cargo test` at the workspace root builds it
/// beside `plcd` (plcctl's own tests need it), in the same directory.
pub fn plcctl_binary() -> PathBuf {
    let path = plcd_binary().with_file_name("plcctl");
    assert!(
        path.is_file(),
        "{} is missing: run the tests from the workspace root with `cargo test` (it builds \
         plcctl), or `cargo build -p plcctl` first",
        path.display()
    );
    path
}

/// `plcd ARGS` in `dir` (`plcd check`, `plcd sim` on a project there), run to its end.
pub fn plcd_in(dir: &Path, args: &[&str]) -> Output {
    runner::command(plcd_binary()).current_dir(dir).args(args).output().expect("plcd runs")
}

/// `plcctl --socket SOCKET ARGS`, run to its end.
pub fn plcctl(socket: &Path, args: &[&str]) -> Output {
    runner::command(plcctl_binary())
        .arg("--socket")
        .arg(socket)
        .args(args)
        .env_remove("PLCD_SOCKET")
        .output()
        .expect("plcctl runs")
}

/// A project in a directory of its own: `plcd.toml` and its files, removed on drop.
#[derive(Debug)]
pub struct Project {
    pub dir: TempDir,
}

impl Project {
    /// A new project directory holding `files` (name, text).
    pub fn new(name: &str, files: &[(&str, &str)]) -> Project {
        Project::in_dir(TempDir::new(name), files)
    }

    /// A project in `dir`.
    pub fn in_dir(dir: TempDir, files: &[(&str, &str)]) -> Project {
        let project = Project { dir };
        for (file, text) in files {
            project.write(file, text);
        }
        project
    }

    pub fn write(&self, file: &str, text: &str) {
        self.dir.write(file, text);
    }

    /// `file` of the project.
    pub fn path(&self, file: &str) -> PathBuf {
        self.dir.join(file)
    }

    /// The project's `plcd.toml`.
    pub fn config(&self) -> PathBuf {
        self.path("plcd.toml")
    }

    /// Where the daemon's control socket is when the config says `socket = "plcd.sock"`.
    pub fn socket(&self) -> PathBuf {
        self.path("plcd.sock")
    }

    /// `plcd run --config plcd.toml`, its log collected from stderr.
    pub fn start(&self) -> Daemon {
        self.start_with(&[], &[])
    }

    /// `plcd run [extra] --config plcd.toml` with `env` set, its log collected from stderr.
    pub fn start_with(&self, extra: &[&str], env: &[(&str, &str)]) -> Daemon {
        Daemon::start(&self.config(), extra, env, Logging::Pipe)
    }

    /// `plcd run` with its log appended to `file` of the project, where it outlives the
    /// process (and `kill -9`) and gathers the log of every start.
    pub fn start_logging_to(&self, file: &str) -> Daemon {
        Daemon::start(&self.config(), &[], &[], Logging::File(self.path(file)))
    }

    /// `plcctl --socket plcd.sock ARGS`.
    pub fn plcctl(&self, args: &[&str]) -> Output {
        plcctl(&self.socket(), args)
    }
}

/// Where the daemon's log (its stderr) goes.
#[derive(Debug, Clone)]
pub enum Logging {
    /// Collected line by line through a pipe.
    Pipe,
    /// Appended to a file.
    File(PathBuf),
}

/// A running `plcd run`, killed (if it still runs) on drop.
#[derive(Debug)]
pub struct Daemon {
    child: Child,
    log: Log,
    /// Reads the pipe until the daemon closes it (it is gone then).
    reader: Option<JoinHandle<()>>,
    patience: Duration,
}

impl Daemon {
    /// `plcd run [extra] --config CONFIG` with `env` set, and none of the service manager's
    /// variables the test runner may have (they would make it notify, or write its retain
    /// files to a state directory).
    pub fn start(config: &Path, extra: &[&str], env: &[(&str, &str)], logging: Logging) -> Daemon {
        let mut command = runner::command(plcd_binary());
        command.arg("run").args(extra).arg("--config").arg(config).stdout(Stdio::null());
        for var in
            ["NOTIFY_SOCKET", "WATCHDOG_USEC", "JOURNAL_STREAM", "INVOCATION_ID", "STATE_DIRECTORY"]
        {
            command.env_remove(var);
        }
        for (key, value) in env {
            command.env(key, value);
        }
        match logging {
            Logging::Pipe => {
                let mut child = command.stderr(Stdio::piped()).spawn().expect("plcd starts");
                let (log, reader) = Log::collect(child.stderr.take().unwrap());
                Daemon { child, log, reader: Some(reader), patience: PATIENCE }
            }
            Logging::File(path) => {
                let file = File::options()
                    .create(true)
                    .append(true)
                    .open(&path)
                    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                let child = command.stderr(file).spawn().expect("plcd starts");
                Daemon { child, log: Log::File(path), reader: None, patience: PATIENCE }
            }
        }
    }

    /// The same daemon, with waits lasting `patience` instead of [`PATIENCE`].
    pub fn with_patience(mut self, patience: Duration) -> Daemon {
        self.patience = patience;
        self
    }

    pub fn pid(&self) -> Pid {
        Pid::from_raw(self.child.id() as i32)
    }

    pub fn log(&self) -> &Log {
        &self.log
    }

    pub fn lines(&self) -> Vec<String> {
        self.log.lines()
    }

    /// Waits for a log line with `text`; its index.
    pub fn wait_for(&self, text: &str) -> usize {
        self.log.wait_for_after(0, text, self.patience)
    }

    /// Waits for a log line with `text` after the first `after`; its index.
    pub fn wait_for_after(&self, after: usize, text: &str) -> usize {
        self.log.wait_for_after(after, text, self.patience)
    }

    /// Waits for a log line with `text`; the line.
    pub fn wait_for_line(&self, text: &str) -> String {
        self.log.wait_for_line(text, self.patience)
    }

    /// Waits until `done` holds (polling it); on running out of patience, fails naming `what`
    /// and showing the log.
    pub fn wait(&self, what: &str, done: impl FnMut() -> bool) {
        wait_until(self.patience, what, || self.log.text(), done);
    }

    pub fn signal(&self, signal: Signal) {
        kill(self.pid(), signal).unwrap_or_else(|e| panic!("kill -{signal} plcd: {e}"));
    }

    /// Whether the process is still running (it has not exited).
    pub fn running(&mut self) -> bool {
        self.child.try_wait().expect("waitpid plcd").is_none()
    }

    /// SIGTERM, then [`Daemon::finish`].
    pub fn stop(self) -> (i32, Vec<String>) {
        self.signal(Signal::SIGTERM);
        self.finish()
    }

    /// Waits for the process to exit on its own, and for its last log line; the exit code (-1
    /// when a signal ended it) and the whole log.
    pub fn finish(mut self) -> (i32, Vec<String>) {
        let mut status = None;
        let patience = self.patience;
        wait_until(
            patience,
            "plcd to exit",
            || self.log.text(),
            || {
                status = self.child.try_wait().expect("waitpid plcd");
                status.is_some()
            },
        );
        if let Some(reader) = self.reader.take() {
            reader.join().expect("the log reader");
        }
        (status.unwrap().code().unwrap_or(-1), self.log.lines())
    }

    /// SIGKILL, and the process reaped.
    pub fn kill9(mut self) {
        self.child.kill().expect("kill -9 plcd");
        self.child.wait().expect("waitpid plcd");
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        // Best effort for a test that failed before stopping its daemon: it must not outlive
        // the test. A daemon that was stopped is gone already, and these fail harmlessly.
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

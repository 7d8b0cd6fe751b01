//! Starting the real `plcd run` in a test, away from any systemd environment the test runner
//! may have inherited, with its log (stderr) collected line by line.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

/// The running daemon, the lines it logged so far, and the thread collecting them (it ends
/// when the daemon closes stderr).
pub struct Spawned {
    pub child: Child,
    pub log: Arc<Mutex<Vec<String>>>,
    #[allow(dead_code)] // joined by the tests that wait for the daemon's last line
    pub reader: JoinHandle<()>,
}

/// `plcd run [extra args] --config CONFIG` with `env` set.
pub fn spawn_plcd(extra: &[&str], config: &Path, env: &[(&str, &str)]) -> Spawned {
    let mut command = Command::new(env!("CARGO_BIN_EXE_plcd"));
    command
        .arg("run")
        .args(extra)
        .arg("--config")
        .arg(config)
        .env_remove("NOTIFY_SOCKET")
        .env_remove("WATCHDOG_USEC")
        .env_remove("JOURNAL_STREAM")
        .env_remove("INVOCATION_ID")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    for (key, value) in env {
        command.env(key, value);
    }
    let mut child = command.spawn().expect("plcd starts");
    let log = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&log);
    let stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            sink.lock().unwrap().push(line);
        }
    });
    Spawned { child, log, reader }
}

/// The `plcctl` binary. It is a package of its own (it builds without the daemon), so cargo
/// gives this package no `CARGO_BIN_EXE_plcctl`; `cargo test` at the workspace root builds it
/// beside `plcd` (plcctl's own tests need it), in the same directory.
#[allow(dead_code)] // not every test that starts plcd runs plcctl
pub fn plcctl_binary() -> PathBuf {
    let path = Path::new(env!("CARGO_BIN_EXE_plcd")).with_file_name("plcctl");
    assert!(
        path.is_file(),
        "{} is missing: run the tests from the workspace root with `cargo test` (it builds \
         plcctl), or `cargo build -p plcctl` first",
        path.display()
    );
    path
}

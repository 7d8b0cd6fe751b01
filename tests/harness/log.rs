//! A process's log as a test reads it, and waiting for what another process does.
//!
//! A daemon runs in real time in a process of its own: a test never asserts how long it takes,
//! it waits for an event (a log line, a state it can query) up to a generous patience, and on
//! running out says what it waited for and shows the log.

use std::io::{BufRead, BufReader, Read};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How long a wait lasts unless a test says otherwise.
pub const PATIENCE: Duration = Duration::from_secs(20);

/// How often a wait looks again.
const POLL: Duration = Duration::from_millis(5);

/// The lines a process logged so far.
#[derive(Debug, Clone)]
pub enum Log {
    /// Collected from a pipe by a thread (see [`Log::collect`]).
    Lines(Arc<Mutex<Vec<String>>>),
    /// A file the process appends to: it survives the process (even `kill -9`) and is shared
    /// by its successive runs.
    File(PathBuf),
}

impl Log {
    /// Collects the lines of `pipe` until it closes; the thread ends then.
    pub fn collect(pipe: impl Read + Send + 'static) -> (Log, JoinHandle<()>) {
        let lines = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&lines);
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                sink.lock().unwrap().push(line);
            }
        });
        (Log::Lines(lines), reader)
    }

    pub fn lines(&self) -> Vec<String> {
        match self {
            Log::Lines(lines) => lines.lock().unwrap().clone(),
            Log::File(path) => match std::fs::read_to_string(path) {
                Ok(text) => text.lines().map(str::to_string).collect(),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
                Err(e) => panic!("reading the log {}: {e}", path.display()),
            },
        }
    }

    /// The whole log, one line a line.
    pub fn text(&self) -> String {
        self.lines().join("\n")
    }

    /// Waits up to `patience` for a line after the first `after` lines that contains `text`;
    /// its index.
    pub fn wait_for_after(&self, after: usize, text: &str, patience: Duration) -> usize {
        let mut found = None;
        wait_until(
            patience,
            &format!("a log line with {text:?} after line {after}"),
            || self.text(),
            || {
                found = self.lines().iter().skip(after).position(|l| l.contains(text));
                found.is_some()
            },
        );
        after + found.unwrap()
    }

    /// The first line with `text`, once there is one (up to `patience`).
    pub fn wait_for_line(&self, text: &str, patience: Duration) -> String {
        let index = self.wait_for_after(0, text, patience);
        self.lines().swap_remove(index)
    }
}

/// Polls `done` until it holds; panics after `patience`, naming `what` and showing
/// `context()` (a log, a state).
pub fn wait_until(
    patience: Duration,
    what: &str,
    context: impl Fn() -> String,
    mut done: impl FnMut() -> bool,
) {
    let start = Instant::now();
    while !done() {
        if start.elapsed() > patience {
            panic!("waited {patience:?} for {what}; log:\n{}", context());
        }
        std::thread::sleep(POLL);
    }
}

/// Waits until the newest intact retain generation in `dir` (what the daemon's writer last
/// acknowledged) satisfies `done`; it. `context` gives the log shown on a timeout.
pub fn wait_for_generation(
    dir: &std::path::Path,
    context: impl Fn() -> String,
    what: &str,
    done: impl Fn(&plcd::services::retain::Generation) -> bool,
) -> plcd::services::retain::Generation {
    let mut found = None;
    wait_until(PATIENCE, &format!("a generation with {what}"), context, || {
        found = plcd::services::retain::newest_in(dir).filter(|g| done(g));
        found.is_some()
    });
    found.expect("waited for it")
}

//! Retained memory that survives crashes and power loss (docs/RETAIN.md).
//!
//! Which device words are retained (K always, the `[retain]` ranges) is device memory's rule:
//! [`crate::device::retained`]; which Structured Text variables are, leaf by leaf, and which of
//! them a changed program keeps, is the VM's: [`crate::vm::retained`].
//!
//! - [`format`](mod@format): the generation file and which of the two generations wins — pure
//!   functions;
//! - [`store`]: the files: atomic, durable replacement, reading, setting aside;
//! - [`startup`]: what the daemon restores at start;
//! - [`writer`]: the background thread writing the retained words while they change, at STOP
//!   and at shutdown;
//! - [`service`]: the daemon's retained memory as one object ([`service::Persistence`]): the
//!   files read at start, the restore, the writer thread, the final write.
//!
//! No code of this module runs on the scan thread. The restore runs on the main thread before
//! the scan thread starts (the driver applies [`service::Persistence::restore_into`] to the new
//! engine first); the writer's copies of the retained words are taken by the scan thread at a
//! scan boundary, without allocating, through a
//! [`Mirror`](crate::drivers::real_time::mirror::Mirror) that the writer asks on its own thread;
//! the final write reads the stopped engine on the main thread. Taking the retained words and
//! variables over into a replacement engine (a reload, a load) and clearing them (`reset
//! --cold`) are the engine's, on the scan thread.

pub mod format;
pub mod service;
pub mod store;
pub mod writer;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::device::RetainSet;
pub use format::{decode, encode, DecodeError, Generation, Slot};
pub use store::Store;

use crate::config::{Restart, RetainConfig};

/// What went wrong with the retain files, with the file and the step.
#[derive(Debug, thiserror::Error)]
pub enum RetainError {
    #[error("{path}: cannot {what}: {source}", path = .path.display())]
    Io { path: PathBuf, what: &'static str, source: std::io::Error },
    #[error("{path}: cannot write generation seq {seq}: {step} failed: {source}", path = .path.display())]
    Write { path: PathBuf, seq: u64, step: &'static str, source: std::io::Error },
    #[error("{path}: corrupt: {source}", path = .path.display())]
    Corrupt { path: PathBuf, source: DecodeError },
    #[error("{path}: not restored: {detail}", path = .path.display())]
    Mismatch { path: PathBuf, detail: String },
}

impl RetainError {
    /// The condition, for logging a failing write once and not at every interval: the step
    /// and the OS error, without the sequence number.
    pub fn condition(&self) -> String {
        match self {
            RetainError::Write { step, source, .. } => format!("{step}: {source}"),
            other => other.to_string(),
        }
    }
}

/// Where the retain files go: `[retain] dir`, else `$STATE_DIRECTORY` (its first path, as
/// systemd's `StateDirectory=` sets it); `None`: nothing is persisted.
pub fn directory(config: &RetainConfig, state_directory: Option<&str>) -> Option<PathBuf> {
    config.dir.clone().or_else(|| {
        let first = state_directory?.split(':').next()?;
        (!first.is_empty()).then(|| PathBuf::from(first))
    })
}

/// What the daemon starts with.
#[derive(Debug)]
pub struct Startup {
    /// The retained words to restore (as [`RetainSet::capture`] lays them out), if any.
    pub words: Option<Vec<u16>>,
    /// The retained variables of the same generation (none from a version 1 file).
    pub variables: Vec<crate::vm::retained::SavedVariable>,
    /// The restored file's format version.
    pub version: u16,
    /// The file they came from and its sequence number.
    pub from: Option<(PathBuf, u64)>,
    /// Where the writer goes on.
    pub next_slot: usize,
    pub next_seq: u64,
    /// Reading, checking and choosing took this long.
    pub took: Duration,
}

/// Reads both generation files and decides what to restore, logging every problem: a corrupt
/// or unreadable file (the other generation is used), files written for other ranges (set
/// aside as `*.mismatch`, not restored; the retained ranges start cleared), `restart = "cold"`
/// (nothing restored). Never fails: the PLC starts either way.
pub fn startup(store: &Store, set: &RetainSet, restart: Restart) -> Startup {
    let began = Instant::now();
    let mut slots: [Slot; 2] = [0, 1].map(|i| match store.read(i) {
        Ok(slot) => slot,
        Err(e) => {
            log::error!("retain: {e}; using the other generation");
            Slot::Missing
        }
    });
    for (i, slot) in slots.iter().enumerate() {
        if let Slot::Corrupt(source) = slot {
            let e = RetainError::Corrupt { path: store.slot_path(i), source: source.clone() };
            log::warn!("retain: {e}; falling back to the other generation");
        }
    }
    let choice = format::choose(&slots, &set.words);
    for (i, detail) in &choice.mismatched {
        let path = store.slot_path(*i);
        let e = RetainError::Mismatch { path: path.clone(), detail: detail.clone() };
        match store.set_aside(*i) {
            Ok(to) => log::error!(
                "retain: {e}; the config's retained ranges changed: the file is kept as {} \
                 and not overwritten (docs/RETAIN.md)",
                to.display()
            ),
            Err(rename) => log::error!("retain: {e}; and it cannot be set aside: {rename}"),
        }
    }
    let any_corrupt = slots.iter().any(|s| matches!(s, Slot::Corrupt(_)));
    // Taken, not cloned: a generation's variables may be an array of many megabytes.
    let restored =
        choice.restore.and_then(|i| match std::mem::replace(&mut slots[i], Slot::Missing) {
            Slot::Intact(g) => Some((i, g)),
            _ => None,
        });
    let mut startup = Startup {
        words: None,
        variables: Vec::new(),
        version: format::VERSION,
        from: None,
        next_slot: choice.next_slot,
        next_seq: choice.next_seq,
        took: Duration::ZERO,
    };
    match (restored, restart) {
        (Some((i, g)), Restart::Warm) => {
            startup.words = Some(g.words);
            startup.variables = g.variables;
            startup.version = g.version;
            startup.from = Some((store.slot_path(i), g.seq));
        }
        (Some((i, _)), Restart::Cold) => log::info!(
            "retain: restart = \"cold\": every device starts cleared; {} is not restored",
            store.slot_path(i).display()
        ),
        (None, _) if !choice.mismatched.is_empty() => {
            log::error!("retain: nothing restored: the retained devices start cleared")
        }
        (None, _) if any_corrupt => {
            log::error!("retain: no intact generation: the retained devices start cleared")
        }
        (None, _) => log::info!(
            "retain: no retained memory in {} yet: the retained devices start cleared",
            store.dir().display()
        ),
    }
    startup.took = began.elapsed();
    startup
}

/// Unix time in ms, for the file header.
pub(crate) fn unix_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// Decodes the newest intact generation in `dir`: for tools and tests ("what is acknowledged
/// on disk now").
pub fn newest_in(dir: &Path) -> Option<Generation> {
    let store = Store { dir: dir.to_path_buf() };
    [0, 1]
        .into_iter()
        .filter_map(|i| match store.read(i) {
            Ok(Slot::Intact(g)) => Some(g),
            _ => None,
        })
        .max_by_key(|g| g.seq)
}

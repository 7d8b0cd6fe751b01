//! The two generation files in their directory: atomic replacement (temporary file, fsync,
//! rename, fsync of the directory), reading, and setting a file aside.

use std::fs::{self, File, OpenOptions};
use std::io::{ErrorKind, Write};
use std::path::{Path, PathBuf};

use super::format::{self, Slot};
use super::RetainError;

/// The names of the two generation files.
pub const SLOT_NAMES: [&str; 2] = ["retain-a.bin", "retain-b.bin"];

/// The retain directory.
#[derive(Debug, Clone)]
pub struct Store {
    pub(super) dir: PathBuf,
}

impl Store {
    /// The directory, created if missing (mode 0750 under the service's umask).
    pub fn open(dir: &Path) -> Result<Store, RetainError> {
        fs::create_dir_all(dir).map_err(|source| RetainError::Io {
            path: dir.to_path_buf(),
            what: "create the retain directory",
            source,
        })?;
        Ok(Store { dir: dir.to_path_buf() })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn slot_path(&self, slot: usize) -> PathBuf {
        self.dir.join(SLOT_NAMES[slot])
    }

    fn temp_path(&self, slot: usize) -> PathBuf {
        self.dir.join(format!("{}.tmp", SLOT_NAMES[slot]))
    }

    /// Reads and decodes one slot. A missing file is [`Slot::Missing`]; a file that cannot be
    /// read is an error.
    pub fn read(&self, slot: usize) -> Result<Slot, RetainError> {
        let path = self.slot_path(slot);
        match fs::read(&path) {
            Ok(bytes) => Ok(match format::decode(&bytes) {
                Ok(generation) => Slot::Intact(generation),
                Err(e) => Slot::Corrupt(e),
            }),
            Err(e) if e.kind() == ErrorKind::NotFound => Ok(Slot::Missing),
            Err(source) => Err(RetainError::Io { path, what: "read", source }),
        }
    }

    /// Replaces slot `slot` with `bytes` atomically and durably: once this returns Ok, the file
    /// holds `bytes` after a crash or a power loss. On an error the slot is as it was (or,
    /// if only the final directory fsync failed, possibly already replaced).
    pub fn write(&self, slot: usize, seq: u64, bytes: &[u8]) -> Result<(), RetainError> {
        let temp = self.temp_path(slot);
        let fail = |step: &'static str, path: &Path| {
            let path = path.to_path_buf();
            move |source| RetainError::Write { path, seq, step, source }
        };
        let written = (|| {
            let mut file = OpenOptions::new()
                .write(true)
                .create(true)
                .truncate(true)
                .open(&temp)
                .map_err(fail("create", &temp))?;
            file.write_all(bytes).map_err(fail("write", &temp))?;
            file.sync_all().map_err(fail("fsync", &temp))?;
            Ok(())
        })();
        if let Err(e) = written {
            let _ = fs::remove_file(&temp);
            return Err(e);
        }
        let target = self.slot_path(slot);
        if let Err(source) = fs::rename(&temp, &target) {
            let _ = fs::remove_file(&temp);
            return Err(RetainError::Write { path: target, seq, step: "rename", source });
        }
        sync_dir(&self.dir).map_err(fail("fsync the directory of", &self.dir))
    }

    /// Renames slot `slot` to a name the writer never uses (`retain-a.bin.mismatch`, or
    /// `.mismatch.2`, … if taken) and returns it.
    pub fn set_aside(&self, slot: usize) -> Result<PathBuf, RetainError> {
        let from = self.slot_path(slot);
        let mut n = 1;
        let to = loop {
            let suffix = if n == 1 { String::new() } else { format!(".{n}") };
            let to = self.dir.join(format!("{}.mismatch{suffix}", SLOT_NAMES[slot]));
            if !to.exists() {
                break to;
            }
            n += 1;
        };
        fs::rename(&from, &to).map_err(|source| RetainError::Io {
            path: from,
            what: "set aside (rename)",
            source,
        })?;
        if let Ok(dir) = File::open(&self.dir) {
            let _ = dir.sync_all();
        }
        Ok(to)
    }
}

/// The fsync of the directory that makes a generation's rename durable: without it a power cut
/// can bring back the previous generation after this one was acknowledged.
#[cfg(not(feature = "fault-injection-skip-dir-fsync"))]
fn sync_dir(dir: &Path) -> std::io::Result<()> {
    File::open(dir)?.sync_all()
}

/// TEST ONLY (Cargo.toml, feature `fault-injection-skip-dir-fsync`): no fsync of the directory,
/// the mutant tests/qemu/run-powercut --without-dir-fsync must catch.
#[cfg(feature = "fault-injection-skip-dir-fsync")]
fn sync_dir(_dir: &Path) -> std::io::Result<()> {
    Ok(())
}

//! Scratch directories: one per use, removed when dropped.
//!
//! This module and [`super::nobody`] need nothing but std and nix, so that `tests/plcctl/cli.rs`
//! (the plcctl package's test, which cannot depend on the daemon) includes them too.

use std::fs;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh directory, mode 0755 whatever the umask, removed with everything in it on drop.
///
/// Its name holds the test binary's pid and a counter, so the directories of tests running in
/// parallel, in one process or in several, never meet. The path is canonical: it is what a child
/// process sees as its current directory even where the temp directory is a symlink.
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl TempDir {
    /// Under the system's temp directory (`$TMPDIR`, else `/tmp`).
    pub fn new(name: &str) -> TempDir {
        TempDir::under(&std::env::temp_dir(), name)
    }

    /// Under a directory every user can reach: `$TMPDIR` when every directory on its path lets
    /// others through, else `/tmp`. For files a test hands to another user (a copied binary, a
    /// socket a process of uid 65534 connects to).
    pub fn for_everyone(name: &str) -> TempDir {
        let base = [std::env::temp_dir(), PathBuf::from("/tmp")]
            .into_iter()
            .find(|dir| others_can_reach(dir).is_ok())
            .unwrap_or_else(|| {
                panic!(
                    "neither $TMPDIR ({}) nor /tmp can be reached by other users: {}",
                    std::env::temp_dir().display(),
                    others_can_reach(&std::env::temp_dir()).unwrap_err()
                )
            });
        TempDir::under(&base, name)
    }

    fn under(base: &Path, name: &str) -> TempDir {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let dir = base.join(format!("plcd-test-{name}-{}-{n}", std::process::id()));
        // A leftover of an earlier process with the same pid.
        if dir.exists() {
            fs::remove_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        }
        fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o755)).unwrap();
        TempDir(dir.canonicalize().unwrap())
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// `relative` inside the directory.
    pub fn join(&self, relative: impl AsRef<Path>) -> PathBuf {
        self.0.join(relative)
    }

    /// Writes `text` to `relative`, creating the directories on the way.
    pub fn write(&self, relative: impl AsRef<Path>, text: impl AsRef<[u8]>) -> PathBuf {
        let path = self.join(relative);
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        path
    }

    /// Sets the mode of `relative` (the directory itself for `""`).
    pub fn chmod(&self, relative: impl AsRef<Path>, mode: u32) {
        let path = self.join(relative);
        fs::set_permissions(&path, fs::Permissions::from_mode(mode))
            .unwrap_or_else(|e| panic!("chmod {mode:o} {}: {e}", path.display()));
    }

    /// The names of the directory's entries, sorted.
    pub fn entries(&self) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        // Best effort: cleaning up is no part of what a test checks. A test that failed halfway
        // may have left a directory without write permission (mode 0555, 0000) behind: opened
        // up, everything in it can go.
        if fs::remove_dir_all(&self.0).is_err() {
            open_up(&self.0);
            let _ = fs::remove_dir_all(&self.0);
        }
    }
}

/// Gives the owner every permission on `dir` and the directories under it.
fn open_up(dir: &Path) {
    let _ = fs::set_permissions(dir, fs::Permissions::from_mode(0o755));
    for entry in fs::read_dir(dir).into_iter().flatten().flatten() {
        if entry.file_type().is_ok_and(|t| t.is_dir()) {
            open_up(&entry.path());
        }
    }
}

/// `Ok` when every directory from `/` down to `dir` lets other users through (the x bit for
/// others), else which one does not.
pub fn others_can_reach(dir: &Path) -> Result<(), String> {
    let dir = dir.canonicalize().map_err(|e| format!("{}: {e}", dir.display()))?;
    for ancestor in dir.ancestors() {
        let mode = fs::metadata(ancestor)
            .map_err(|e| format!("{}: {e}", ancestor.display()))?
            .permissions()
            .mode();
        if mode & 0o001 == 0 {
            return Err(format!("{} is mode {:o}", ancestor.display(), mode & 0o7777));
        }
    }
    Ok(())
}

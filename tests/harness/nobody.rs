//! Running a program as another user (uid 65534, "nobody"), for the tests of who may connect.
//!
//! A program built into the clone's target directory is not necessarily reachable by that
//! user: CI and developers clone wherever they like, `mktemp -d` makes mode 0700 directories,
//! and exec then fails with EACCES before the program runs. So the program is copied first
//! into a fresh directory every user can reach ([`super::tempdir::TempDir::for_everyone`]), and
//! run from there.

use std::fs;
use std::os::unix::fs::PermissionsExt;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

use nix::errno::Errno::ETXTBSY;

use super::runner;
use super::tempdir::TempDir;

/// The uid (and gid) the tests switch to.
pub const NOBODY: u32 = 65534;

/// Why this process cannot start another user's process, or `None` when it can (as root).
/// A test checks this before anything else, and skips when it is `Some`.
pub fn unavailable() -> Option<String> {
    let euid = nix::unistd::geteuid();
    (!euid.is_root()).then(|| format!("needs root to run a process as uid {NOBODY} (euid {euid})"))
}

/// A copy of a program that uid 65534 can execute; removed on drop.
#[derive(Debug)]
pub struct Copy {
    _dir: TempDir,
    program: PathBuf,
}

impl Copy {
    /// Places `program` in a fresh directory every user can reach: a hard link when the file
    /// is readable and executable by others already (nothing is written, so no other thread's
    /// child can hold it open for writing), else a copy, mode 0755.
    pub fn of(program: &Path) -> Copy {
        let name = program.file_name().expect("a program file").to_string_lossy().into_owned();
        let dir = TempDir::for_everyone(&format!("as-nobody-{name}"));
        let place = dir.join(&name);
        let mode = fs::metadata(program)
            .unwrap_or_else(|e| panic!("{}: {e}", program.display()))
            .permissions()
            .mode();
        if mode & 0o005 != 0o005 || fs::hard_link(program, &place).is_err() {
            fs::copy(program, &place)
                .unwrap_or_else(|e| panic!("copying {} for uid {NOBODY}: {e}", program.display()));
            fs::set_permissions(&place, fs::Permissions::from_mode(0o755)).unwrap();
        }
        Copy { _dir: dir, program: place }
    }

    /// Where the copy is.
    pub fn path(&self) -> &Path {
        &self.program
    }

    /// The copy as uid 65534 with primary group `gid` and no supplementary groups (std drops
    /// them when a root process sets a uid), in `/`, through the emulator where there is one
    /// ([`runner`]). Run it with [`output`].
    pub fn command(&self, gid: u32) -> Command {
        let mut command = runner::command(&self.program);
        command.uid(NOBODY).gid(gid).current_dir("/");
        command
    }
}

/// `command.output()`, tried again while exec fails with ETXTBSY: a process another thread of
/// the test binary forked while a copy was being written holds it open for writing until that
/// process execs, a moment later.
pub fn output(command: &mut Command) -> Output {
    let mut tries = 0;
    loop {
        match command.output() {
            Err(e) if e.raw_os_error() == Some(ETXTBSY as i32) && tries < 100 => {
                tries += 1;
                std::thread::sleep(Duration::from_millis(10));
            }
            result => {
                return result
                    .unwrap_or_else(|e| panic!("running {:?}: {e}", command.get_program()))
            }
        }
    }
}

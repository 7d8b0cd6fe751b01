//! Reading a project's files from disk: the config, the programs it names, a simulation inputs
//! file, the users file. The core parses text and never opens a file; this is where the text comes from. A file
//! that cannot be read is a diagnostic like any other (line 0: the whole file), so a caller
//! reports it with the rest and keeps what it was running.

use std::path::{Path, PathBuf};

use crate::config::{self, Config};
use crate::diag::{Diagnostic, Diagnostics};
use crate::project::{self, Project};
use crate::stimulus::{self, Stimulus};
use crate::users::UsersFile;

/// Reads the config file at `path` and parses it ([`config::parse`]).
pub fn config(path: &Path) -> Result<Config, Diagnostics> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        Diagnostics(vec![Diagnostic::new(
            path,
            0,
            0,
            format!("cannot read {}: {e}", path.display()),
        )])
    })?;
    config::parse(&text, path)
}

/// Loads the config at `path` and every program it names, and compiles the Structured Text
/// programs to native code (`plcd_native`, with the default `native` feature; a program it
/// cannot compile runs on the interpreter, with a warning in the log). Every diagnostic of the config and of all programs
/// is returned at once.
pub fn project(path: &Path) -> Result<Project, Diagnostics> {
    #[allow(unused_mut)] // without the `native` feature, nothing is attached
    let mut project = interpreted_project(path)?;
    for note in &project.notes {
        log::info!("{note}");
    }
    for warning in &project.warnings {
        log::warn!("{warning}");
    }
    #[cfg(feature = "native")]
    for error in plcd_native::attach(&mut project) {
        log::warn!("{error}; it runs on the interpreter");
    }
    Ok(project)
}

/// [`project`](fn@project) without native code: every program on the interpreter (`plcd sim
/// --interpreter`, to compare the two or to measure the interpreter itself).
pub fn interpreted_project(path: &Path) -> Result<Project, Diagnostics> {
    let config = config(path)?;
    project::from_config_with(config, source_text, source_files, files_in)
}

/// A program or library file's text: UTF-8 (after a UTF-8 byte order mark, if any), or, when
/// the file is not valid UTF-8, Windows-1252, which every byte is a character of (older CODESYS
/// exports and OSCAT's sources are written so; docs/ST.md, Source form).
fn source_text(path: &Path) -> std::io::Result<String> {
    let mut bytes = std::fs::read(path)?;
    if bytes.starts_with(b"\xEF\xBB\xBF") {
        bytes.drain(..3);
    }
    Ok(match String::from_utf8(bytes) {
        Ok(text) => text,
        Err(e) => crate::value::decode_str(e.as_bytes()),
    })
}

/// Every file in `dir` and its subfolders (an `[st] library` folder; the core keeps the
/// Structured Text sources and the `.plcproj` files among them). Hidden entries (`.git`) are skipped; a symbolic link
/// to a file is a file, one to a folder is not entered (no loops).
fn source_files(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(dir) = pending.pop() {
        for entry in std::fs::read_dir(&dir)? {
            let entry = entry?;
            let path = entry.path();
            if entry.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            let kind = entry.file_type()?;
            if kind.is_dir() {
                pending.push(path);
            } else if kind.is_file() || path.is_file() {
                files.push(path);
            }
        }
    }
    Ok(files)
}

/// The files directly in `dir`, each as `dir` joined with its name (the empty path is the
/// current folder, and its files are their bare names): where the core looks for the
/// `.plcproj` of a program's TwinCAT file. Hidden entries are skipped, as in
/// [`source_files`]; a symbolic link to a file is a file.
fn files_in(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let listed = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(listed)? {
        let entry = entry?;
        let name = entry.file_name();
        if name.to_string_lossy().starts_with('.') {
            continue;
        }
        let path = dir.join(&name);
        if entry.file_type()?.is_file() || entry.path().is_file() {
            files.push(path);
        }
    }
    Ok(files)
}

/// Reads and parses the inputs file of a project, checked against its config
/// ([`stimulus::parse_for`]). `plcd sim --inputs` and the daemon's `io.stimulus` both load
/// through this.
pub fn stimulus_for(path: &Path, config: &Config) -> Result<Vec<Stimulus>, Diagnostics> {
    read_stimulus(path).and_then(|text| stimulus::parse_for(&text, path, config))
}

fn read_stimulus(path: &Path) -> Result<String, Diagnostics> {
    std::fs::read_to_string(path).map_err(|e| {
        Diagnostics(vec![Diagnostic::new(path, 0, 0, format!("cannot read the inputs file: {e}"))])
    })
}

/// Reads and parses the users file at `path` ([`UsersFile::parse`]): `plcd check` and `plcd
/// user` read it through this.
pub fn users(path: &Path) -> Result<UsersFile, Diagnostics> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        Diagnostics(vec![Diagnostic::new(path, 0, 0, format!("cannot read the users file: {e}"))])
    })?;
    UsersFile::parse(&text, path)
}

/// How often [`LiveUsers::refresh`] looks at the file at most.
pub const USERS_LOOK_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// The users file of `[users] file` as a network service holds it: read at start (a file with
/// errors stops the start), and read again when it changed on disk, so that `plcd user add`
/// and `plcd user remove` take effect at the next login without a restart. A changed file with
/// errors is not taken: the users read before stay, and the log says why once for that
/// version of the file.
pub struct LiveUsers {
    path: PathBuf,
    state: std::sync::Mutex<LiveState>,
}

struct LiveState {
    users: std::sync::Arc<UsersFile>,
    /// The file as last read or refused: its modification time, length and inode.
    stamp: Option<(std::time::SystemTime, u64, u64)>,
    looked: std::time::Instant,
}

fn stamp(path: &Path) -> Option<(std::time::SystemTime, u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    let meta = std::fs::metadata(path).ok()?;
    Some((meta.modified().ok()?, meta.len(), meta.ino()))
}

impl LiveUsers {
    /// Reads the users file at `path`.
    pub fn open(path: &Path) -> Result<LiveUsers, Diagnostics> {
        let stamp = stamp(path);
        let users = std::sync::Arc::new(users(path)?);
        let looked = std::time::Instant::now();
        let state = std::sync::Mutex::new(LiveState { users, stamp, looked });
        Ok(LiveUsers { path: path.to_path_buf(), state })
    }

    fn state(&self) -> std::sync::MutexGuard<'_, LiveState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The users as last read; no file is looked at.
    pub fn current(&self) -> std::sync::Arc<UsersFile> {
        std::sync::Arc::clone(&self.state().users)
    }

    /// The users, read again first if the file changed since (looked at once per
    /// [`USERS_LOOK_EVERY`] at most). Blocking file I/O: call it where blocking is allowed.
    pub fn refresh(&self) -> std::sync::Arc<UsersFile> {
        let now = std::time::Instant::now();
        {
            let mut state = self.state();
            if now.duration_since(state.looked) < USERS_LOOK_EVERY {
                return std::sync::Arc::clone(&state.users);
            }
            state.looked = now;
        }
        let seen = stamp(&self.path);
        if seen.is_none() || seen == self.state().stamp {
            // Gone (an editor's rename in progress, or removed: the users stay), or unchanged.
            return self.current();
        }
        let read = users(&self.path);
        let mut state = self.state();
        state.stamp = seen;
        match read {
            Ok(users) => {
                log::info!(
                    "users file {} read again: {} users",
                    self.path.display(),
                    users.users().len()
                );
                state.users = std::sync::Arc::new(users);
            }
            Err(diagnostics) => {
                let first = diagnostics.iter().next().map(ToString::to_string).unwrap_or_default();
                log::warn!(
                    "users file {} changed and has {} error(s), first {first}; the users read \
                     before stay until it is fixed",
                    self.path.display(),
                    diagnostics.len()
                );
            }
        }
        std::sync::Arc::clone(&state.users)
    }

    /// Makes the next [`LiveUsers::refresh`] look at the file whatever the time (tests).
    pub fn look_now(&self) {
        let mut state = self.state();
        state.looked = state.looked.checked_sub(USERS_LOOK_EVERY).unwrap_or(state.looked);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stimulus::Target;
    use plcd_core::io::SwitchPosition;

    /// A config, with a `[switch]` or without.
    fn config_with(with_switch: bool) -> Config {
        let switch = if with_switch { "[switch]\n" } else { "" };
        let text = format!("{switch}[[program]]\nfile = \"main.il\"\n");
        config::parse(&text, Path::new("plcd.toml")).unwrap()
    }

    #[test]
    fn a_source_is_utf8_after_its_byte_order_mark_else_windows_1252() {
        let path = std::env::temp_dir().join(format!("plcd-source-{}.st", std::process::id()));
        std::fs::write(&path, b"\xEF\xBB\xBF'Gr\xC3\xBC\xC3\x9Fe \xE2\x82\xAC'").unwrap();
        let utf8 = source_text(&path).unwrap();
        std::fs::write(&path, b"'Gr\xFC\xDFe \x80'").unwrap();
        let cp1252 = source_text(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(utf8, "'Grüße €'");
        assert_eq!(cp1252, "'Grüße €'");
    }

    #[test]
    fn files_in_lists_a_folders_own_files_without_its_subfolders_or_hidden_entries() {
        let dir = std::env::temp_dir().join(format!("plcd-files-in-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        for file in ["App.plcproj", "MAIN.TcPOU", ".hidden.plcproj", "sub/Lib.plcproj"] {
            std::fs::write(dir.join(file), "").unwrap();
        }
        let listed = files_in(&dir);
        std::fs::remove_dir_all(&dir).unwrap();
        let mut listed = listed.unwrap();
        listed.sort();
        assert_eq!(listed, [dir.join("App.plcproj"), dir.join("MAIN.TcPOU")]);
        assert!(files_in(&dir).is_err(), "a folder that is gone cannot be listed");
    }

    #[test]
    fn a_missing_inputs_file_is_one_diagnostic() {
        let path = Path::new("/nonexistent/plcd-inputs.csv");
        let diags = stimulus_for(path, &config_with(false)).unwrap_err();
        assert_eq!(diags.len(), 1);
        let text = diags.to_string();
        assert!(text.starts_with("/nonexistent/plcd-inputs.csv:0:0: error: cannot read"), "{text}");
    }

    #[test]
    fn an_inputs_file_is_read_and_sorted() {
        let path = std::env::temp_dir().join(format!("plcd-stimulus-{}.csv", std::process::id()));
        std::fs::write(&path, "2ms, P0001, 1\n1ms, P0000, 1\n").unwrap();
        let result = stimulus_for(&path, &config_with(false));
        std::fs::remove_file(&path).unwrap();
        let times: Vec<u64> = result.unwrap().iter().map(|s| s.t_ns).collect();
        assert_eq!(times, vec![1_000_000, 2_000_000]);
    }

    #[test]
    fn a_projects_inputs_file_is_checked_against_its_config() {
        let path =
            std::env::temp_dir().join(format!("plcd-stimulus-switch-{}.csv", std::process::id()));
        std::fs::write(&path, "1ms, SWITCH, STOP\n").unwrap();
        let with = stimulus_for(&path, &config_with(true));
        let without = stimulus_for(&path, &config_with(false));
        std::fs::remove_file(&path).unwrap();
        let expected = Stimulus {
            t_ns: 1_000_000,
            target: Target::Switch(SwitchPosition::Stop),
            value: 0,
            line: 1,
        };
        assert_eq!(with.unwrap(), vec![expected]);
        let text = without.unwrap_err().to_string();
        assert!(text.starts_with(&format!("{}:1:6: error: SWITCH: ", path.display())), "{text}");
        let missing =
            stimulus_for(Path::new("/nonexistent/in.csv"), &config_with(true)).unwrap_err();
        assert!(missing.to_string().contains("cannot read the inputs file"), "{missing}");
    }

    #[test]
    fn a_config_is_read_and_resolved_against_its_directory() {
        let dir = std::env::temp_dir().join(format!("plcd-config-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plcd.toml");
        std::fs::write(&path, "[[program]]\nfile = \"main.il\"\n").unwrap();
        let loaded = config(&path);
        std::fs::remove_dir_all(&dir).unwrap();
        let loaded = loaded.unwrap();
        assert_eq!(loaded.path, path);
        assert_eq!(loaded.programs[0].resolved, dir.join("main.il"));

        let missing = dir.join("missing.toml");
        let diags = config(&missing).unwrap_err();
        assert_eq!(diags.len(), 1);
        let d = &diags.0[0];
        assert_eq!((d.path.as_path(), d.line, d.col), (missing.as_path(), 0, 0));
        assert!(
            d.message.starts_with(&format!("cannot read {}: ", missing.display())),
            "{}",
            d.message
        );
    }

    #[test]
    fn live_users_follow_the_file_and_keep_the_last_good_one() {
        use crate::users::{hash_password, HashCosts, SALT_LEN};
        let costs = HashCosts { memory_kib: 64, passes: 1, lanes: 1 };
        let phc = hash_password(b"pw", &[3; SALT_LEN], costs).unwrap();
        let dir = std::env::temp_dir().join(format!("plcd-live-users-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("users");
        // Written as `plcd user` writes: a new file renamed over the old one.
        let write = |text: &str| {
            std::fs::write(dir.join("users.new"), text).unwrap();
            std::fs::rename(dir.join("users.new"), &path).unwrap();
        };
        write(&format!("alice:viewer:{phc}\n"));
        let live = LiveUsers::open(&path).unwrap();
        let names = |users: &UsersFile| -> Vec<String> {
            users.users().iter().map(|u| u.name.clone()).collect()
        };
        assert_eq!(names(&live.refresh()), ["alice"], "within a second: not looked at");
        write(&format!("alice:viewer:{phc}\nbob:operator:{phc}\n"));
        assert_eq!(names(&live.refresh()), ["alice"], "still within the second");
        live.look_now();
        assert_eq!(names(&live.refresh()), ["alice", "bob"], "read again");
        assert_eq!(names(&live.current()), ["alice", "bob"]);
        write("alice:nobody:x\n");
        live.look_now();
        assert_eq!(names(&live.refresh()), ["alice", "bob"], "a broken file: the last good one");
        std::fs::remove_file(&path).unwrap();
        live.look_now();
        assert_eq!(names(&live.refresh()), ["alice", "bob"], "gone: the last good one");
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(LiveUsers::open(&path).is_err(), "a file that cannot be read at start");
    }
}

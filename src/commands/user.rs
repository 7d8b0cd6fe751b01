//! `plcd user add|remove|list`: the users file of the network services (docs/USERS.md).
//!
//! This command owns what the core leaves to its caller: reading and writing the file (written
//! atomically: a temporary file in the same folder, fsync, rename, fsync of the folder; mode
//! 0600 when it is created, the mode and owner it had otherwise), the salt (from the OS random
//! source) and the password, read from the terminal without echo, twice, or from standard input
//! with `--password-stdin`. Two runs that change one file at once take turns: each reads,
//! changes and writes the file holding an exclusive lock on a lock file beside it, taken after
//! the password is read (so nobody waits on a prompt), and waits [`LOCK_WAIT`] at most for it.
//! The file's format, the roles and the hash are `plcd_core::users`'s.

use std::fs::{self, File, OpenOptions};
use std::io::{Read, Write};
use std::os::fd::{AsFd, BorrowedFd};
use std::os::unix::fs::{MetadataExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use nix::errno::Errno;
use nix::fcntl::{Flock, FlockArg};
use nix::poll::{PollFd, PollFlags, PollTimeout};
use nix::sys::termios::{self, LocalFlags, SetArg, SpecialCharacterIndices, Termios};
use password_hash::rand_core::{OsRng, RngCore};

use crate::diag::Diagnostics;
use crate::files;
use crate::users::{self, HashCosts, Role, UsersError, UsersFile, SALT_LEN};

/// The longest password read, in bytes: far beyond any passphrase, short of a file piped in by
/// mistake.
pub const PASSWORD_MAX: usize = 1024;

/// How long a change waits for another run changing the same file: far beyond the few
/// milliseconds a change holds the lock (the password's hash is made before it is taken).
pub const LOCK_WAIT: Duration = Duration::from_secs(10);

/// The command's arguments.
#[derive(Debug, Clone, clap::Args)]
pub struct UserArgs {
    #[command(subcommand)]
    pub command: UserCommand,
}

#[derive(Debug, Clone, clap::Subcommand)]
pub enum UserCommand {
    /// Add a user, or give one the file has a new password and role.
    Add {
        /// The user's name: letters, digits, `_`, `.` and `-`, at most 64.
        name: String,
        /// What the user may do: viewer, operator or engineer (docs/USERS.md).
        #[arg(long, value_parser = parse_role)]
        role: Role,
        #[command(flatten)]
        file: FileArgs,
        /// Read the password from standard input, one line, instead of asking on the terminal.
        #[arg(long)]
        password_stdin: bool,
    },
    /// Remove a user.
    Remove {
        name: String,
        #[command(flatten)]
        file: FileArgs,
    },
    /// List the users and their roles (never the hashes).
    List {
        #[command(flatten)]
        file: FileArgs,
    },
}

/// Which users file: the one the config's `[users] file` names, or one given.
#[derive(Debug, Clone, clap::Args)]
#[group(required = true, multiple = false)]
pub struct FileArgs {
    /// The project's config: its `[users] file` is the file.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The users file itself.
    #[arg(long)]
    pub file: Option<PathBuf>,
}

fn parse_role(text: &str) -> Result<Role, String> {
    text.parse().map_err(|e: users::UnknownRole| e.to_string())
}

/// What went wrong; every variant is one line for the user (the diagnostics, one each).
#[derive(Debug, thiserror::Error)]
pub enum UserError {
    /// The config, or the users file, has errors.
    #[error("{0}")]
    Diagnostics(Diagnostics),
    #[error("{config}: `[users] file` is not set; set it there, or give the file with --file")]
    NoUsersFile { config: PathBuf },
    #[error("cannot read the users file {path}: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("cannot write the users file {path}: {what}: {source}")]
    Write { path: PathBuf, what: &'static str, source: std::io::Error },
    #[error(
        "the users file {path} is being changed by another process (it has held {lock} for \
         {} s); nothing written",
        LOCK_WAIT.as_secs()
    )]
    Busy { path: PathBuf, lock: PathBuf },
    #[error("{0}")]
    Users(#[from] UsersError),
    #[error(
        "standard input is not a terminal: give the password on it with --password-stdin, or \
         run this on a terminal"
    )]
    NotATerminal,
    #[error(
        "standard input is a terminal that shows what is typed: leave out --password-stdin to \
         be asked for the password without echo"
    )]
    EchoOn,
    #[error("the terminal: {call}: {errno}")]
    Terminal { call: &'static str, errno: Errno },
    #[error("the passwords differ; nothing written")]
    Mismatch,
    #[error("the password is longer than {PASSWORD_MAX} bytes")]
    TooLong,
    #[error("interrupted; nothing written")]
    Interrupted,
    #[error("no password on standard input")]
    NoPassword,
}

/// Runs the command: messages to `out`, errors to `err`; exit 1 on error, 130 when
/// interrupted at the password prompt.
pub fn run(args: &UserArgs, out: &mut impl Write, err: &mut impl Write) -> ExitCode {
    let result = match &args.command {
        UserCommand::Add { name, role, file, password_stdin } => {
            add(name, *role, file, *password_stdin, out, err)
        }
        UserCommand::Remove { name, file } => remove(name, file, out),
        UserCommand::List { file } => list(file, out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // Diagnostics end each line themselves.
            match &e {
                UserError::Diagnostics(diags) => {
                    let _ = write!(err, "{diags}");
                }
                e => {
                    let _ = writeln!(err, "plcd user: {e}");
                }
            }
            ExitCode::from(if matches!(e, UserError::Interrupted) { 130 } else { 1 })
        }
    }
}

/// The users file the arguments name.
fn users_path(args: &FileArgs) -> Result<PathBuf, UserError> {
    if let Some(file) = &args.file {
        return Ok(file.clone());
    }
    // clap's group makes one of the two present.
    let config = args.config.clone().unwrap_or_default();
    let parsed = files::config(&config).map_err(UserError::Diagnostics)?;
    parsed.users.file.ok_or(UserError::NoUsersFile { config })
}

/// The file, parsed; `None` when it does not exist yet.
fn read(path: &Path) -> Result<Option<UsersFile>, UserError> {
    match fs::read_to_string(path) {
        Ok(text) => UsersFile::parse(&text, path).map(Some).map_err(UserError::Diagnostics),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(UserError::Read { path: path.to_path_buf(), source }),
    }
}

fn read_existing(path: &Path) -> Result<UsersFile, UserError> {
    read(path)?.ok_or_else(|| UserError::Read {
        path: path.to_path_buf(),
        source: std::io::ErrorKind::NotFound.into(),
    })
}

fn add(
    name: &str,
    role: Role,
    args: &FileArgs,
    password_stdin: bool,
    out: &mut impl Write,
    err: &mut impl Write,
) -> Result<(), UserError> {
    // Everything that can be refused is refused before the password is asked for.
    users::check_name(name)?;
    let path = users_path(args)?;
    // A file with errors is refused now; the change reads it again under the lock.
    let _ = read(&path)?;
    let stdin = std::io::stdin();
    let password = if password_stdin {
        password_from_stdin(stdin.as_fd())?
    } else {
        password_from_terminal(stdin.as_fd(), name, err)?
    };
    let mut salt = [0u8; SALT_LEN];
    OsRng.fill_bytes(&mut salt);
    let hash = users::hash_password(&password.0, &salt, HashCosts::DEFAULT)?;
    let previous = change(&path, LOCK_WAIT, |file| file.set(name, role, &hash))?;
    let _ = match previous {
        None => writeln!(out, "{}: added {name} ({role})", path.display()),
        Some(was) => writeln!(out, "{}: new password for {name} ({was} → {role})", path.display()),
    };
    Ok(())
}

fn remove(name: &str, args: &FileArgs, out: &mut impl Write) -> Result<(), UserError> {
    let path = users_path(args)?;
    // A missing file is its own error, not "no such user"; the change reads it again.
    let _ = read_existing(&path)?;
    let role = change(&path, LOCK_WAIT, |file| file.remove(name))?;
    let _ = writeln!(out, "{}: removed {name} ({role})", path.display());
    Ok(())
}

/// Reads the file at `path` (none yet: an empty one, created by the write), applies `edit` and
/// writes the result, holding the file's change lock throughout ([`lock`], waiting `wait` at
/// most), so that a change made by another run between its read and its write is never lost.
fn change<T>(
    path: &Path,
    wait: Duration,
    edit: impl FnOnce(&mut UsersFile) -> Result<T, UsersError>,
) -> Result<T, UserError> {
    let _lock = lock(path, wait)?;
    let existing = read(path)?;
    let created = existing.is_none();
    let mut file = match existing {
        Some(file) => file,
        None => UsersFile::parse("", path).map_err(UserError::Diagnostics)?,
    };
    let result = edit(&mut file)?;
    write_atomically(path, &file.text(), created)?;
    Ok(result)
}

/// The lock file of the users file at `path`: `.NAME.plcd-user.lock` beside the file (beside
/// the target of a symbolic link, which is what a change replaces). The users file itself cannot
/// carry the lock: a change replaces it by a rename, and a lock on the old file would not keep
/// another run from reading the new one.
fn lock_path(path: &Path) -> PathBuf {
    let target = fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    target.with_file_name(format!(".{name}.plcd-user.lock"))
}

/// Takes the exclusive lock of the users file at `path` (`flock` on [`lock_path`], created mode
/// 0600 and left in place: removing it would let two runs lock two different files), trying
/// again every 20 ms until `wait` has passed; released when dropped.
fn lock(path: &Path, wait: Duration) -> Result<Flock<File>, UserError> {
    let lock = lock_path(path);
    let failed = |source: std::io::Error| UserError::Write {
        path: path.to_path_buf(),
        what: "open its lock file",
        source,
    };
    let deadline = Instant::now() + wait;
    let mut file = OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(false)
        .mode(0o600)
        .open(&lock)
        .map_err(failed)?;
    loop {
        match Flock::lock(file, FlockArg::LockExclusiveNonblock) {
            Ok(locked) => return Ok(locked),
            Err((back, Errno::EWOULDBLOCK | Errno::EINTR)) if Instant::now() < deadline => {
                file = back;
                std::thread::sleep(Duration::from_millis(20));
            }
            Err((_, Errno::EWOULDBLOCK)) => {
                return Err(UserError::Busy { path: path.to_path_buf(), lock })
            }
            Err((_, errno)) => return Err(failed(errno.into())),
        }
    }
}

fn list(args: &FileArgs, out: &mut impl Write) -> Result<(), UserError> {
    let path = users_path(args)?;
    let file = read_existing(&path)?;
    let width = file.users().iter().map(|u| u.name.len()).max().unwrap_or(0);
    for user in file.users() {
        let _ = writeln!(out, "{:width$}  {}", user.name, user.role);
    }
    Ok(())
}

/// Writes `text` to `path` so that a reader sees the old file or the new one, never a part,
/// and a power cut leaves one of them: a temporary file beside it, written and synced, renamed
/// over it, and the folder synced. A new file is made mode 0600 (it holds the hashes); an
/// existing one keeps its mode and, where the caller may give it, its owner and group (root
/// editing the file of the daemon's user must not take it away from the daemon).
fn write_atomically(path: &Path, text: &str, created: bool) -> Result<(), UserError> {
    let failed = |what: &'static str| {
        move |source: std::io::Error| UserError::Write { path: path.to_path_buf(), what, source }
    };
    // A symbolic link is kept: its target is what is replaced.
    let target = if created {
        path.to_path_buf()
    } else {
        fs::canonicalize(path).map_err(failed("resolve"))?
    };
    let dir = match target.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let temp = dir.join(format!(".{name}.plcd-user-{}", std::process::id()));
    let old = if created { None } else { Some(fs::metadata(&target).map_err(failed("stat"))?) };
    // Never another's file: a temporary file that exists is an error, and is left alone.
    let mut file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&temp)
        .map_err(failed("create a temporary file"))?;
    let result = (|| {
        let mode = old.as_ref().map_or(0o600, |m| m.permissions().mode() & 0o7777);
        file.set_permissions(fs::Permissions::from_mode(mode)).map_err(failed("chmod"))?;
        if let Some(old) = &old {
            keep_owner(&file, old).map_err(failed("chown"))?;
        }
        file.write_all(text.as_bytes()).map_err(failed("write"))?;
        file.sync_all().map_err(failed("fsync"))?;
        fs::rename(&temp, &target).map_err(failed("rename"))?;
        File::open(&dir).and_then(|d| d.sync_all()).map_err(failed("fsync the folder"))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&temp);
    }
    result
}

/// Gives the new file the old one's owner and group. Only root may give a file away; anyone
/// else writes a file that is theirs, which is what it was if they could replace it, and a
/// group they are in (else `chown` fails and the file is not written).
fn keep_owner(file: &File, old: &fs::Metadata) -> std::io::Result<()> {
    let new = file.metadata()?;
    if (new.uid(), new.gid()) == (old.uid(), old.gid()) {
        return Ok(());
    }
    std::os::unix::fs::fchown(file, Some(old.uid()), Some(old.gid()))
}

/// A password, its bytes overwritten when dropped.
struct Password(Vec<u8>);

impl Drop for Password {
    fn drop(&mut self) {
        self.0.fill(0);
        // Keeps the overwrite from being optimised away as a store nobody reads.
        std::hint::black_box(&self.0);
    }
}

fn is_terminal(fd: BorrowedFd<'_>) -> bool {
    nix::unistd::isatty(fd).unwrap_or(false)
}

fn terminal_error(call: &'static str) -> impl Fn(Errno) -> UserError {
    move |errno| UserError::Terminal { call, errno }
}

/// One line of standard input, without its line ending. Standard input must not be a
/// terminal that echoes: the password would be on the screen.
fn password_from_stdin(stdin: BorrowedFd<'_>) -> Result<Password, UserError> {
    if is_terminal(stdin) {
        let attrs = termios::tcgetattr(stdin).map_err(terminal_error("tcgetattr"))?;
        if attrs.local_flags.contains(LocalFlags::ECHO) {
            return Err(UserError::EchoOn);
        }
    }
    let mut bytes = Vec::new();
    let mut limited = std::io::stdin().lock().take(PASSWORD_MAX as u64 + 2);
    let mut byte = [0u8; 1];
    // Byte by byte up to the first line end: what follows is not read.
    loop {
        match limited.read(&mut byte) {
            Ok(0) => break,
            Ok(_) if byte[0] == b'\n' => break,
            Ok(_) => bytes.push(byte[0]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(source) => return Err(UserError::Read { path: "standard input".into(), source }),
        }
    }
    let mut password = Password(bytes);
    if password.0.last() == Some(&b'\r') {
        password.0.pop();
    }
    match password.0.len() {
        0 => Err(UserError::NoPassword),
        n if n > PASSWORD_MAX => Err(UserError::TooLong),
        _ => Ok(password),
    }
}

/// Asks twice on the terminal, without echo; the two must be the same.
fn password_from_terminal(
    stdin: BorrowedFd<'_>,
    name: &str,
    err: &mut impl Write,
) -> Result<Password, UserError> {
    if !is_terminal(stdin) {
        return Err(UserError::NotATerminal);
    }
    let signals = Signals::register()?;
    let hidden = EchoOff::new(stdin)?;
    let first = hidden.read(&format!("password for {name}: "), &signals, err)?;
    let second = hidden.read("again: ", &signals, err)?;
    drop(hidden);
    if first.0 != second.0 {
        return Err(UserError::Mismatch);
    }
    if first.0.is_empty() {
        return Err(UsersError::EmptyPassword.into());
    }
    Ok(first)
}

/// SIGTERM, SIGHUP, SIGQUIT and SIGINT while the terminal does not echo: noted instead of
/// ending the process, so that the terminal is restored first. (Ctrl-C arrives as a byte: the
/// terminal sends no signals meanwhile; these come from `kill` or a closed session.)
struct Signals {
    caught: Arc<AtomicBool>,
    ids: Vec<signal_hook::SigId>,
}

impl Signals {
    fn register() -> Result<Signals, UserError> {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGQUIT, SIGTERM};
        let caught = Arc::new(AtomicBool::new(false));
        let mut ids = Vec::new();
        for signal in [SIGTERM, SIGHUP, SIGQUIT, SIGINT] {
            let id = signal_hook::flag::register(signal, Arc::clone(&caught)).map_err(|e| {
                UserError::Terminal {
                    call: "sigaction",
                    errno: Errno::from_raw(e.raw_os_error().unwrap_or(0)),
                }
            })?;
            ids.push(id);
        }
        Ok(Signals { caught, ids })
    }

    fn caught(&self) -> bool {
        self.caught.load(Ordering::Relaxed)
    }
}

impl Drop for Signals {
    fn drop(&mut self) {
        for id in self.ids.drain(..) {
            signal_hook::low_level::unregister(id);
        }
    }
}

/// The terminal with echo, line editing and signal keys off, restored when dropped: on every
/// way out of the prompt, an error or a panic included.
struct EchoOff<'fd> {
    fd: BorrowedFd<'fd>,
    saved: Termios,
}

impl<'fd> EchoOff<'fd> {
    fn new(fd: BorrowedFd<'fd>) -> Result<EchoOff<'fd>, UserError> {
        let saved = termios::tcgetattr(fd).map_err(terminal_error("tcgetattr"))?;
        let mut hidden = saved.clone();
        // Without ICANON the bytes come as typed and the line is edited here; without ISIG
        // Ctrl-C is a byte, so the terminal is restored before the command ends.
        hidden.local_flags.remove(
            LocalFlags::ECHO
                | LocalFlags::ECHOE
                | LocalFlags::ECHOK
                | LocalFlags::ECHONL
                | LocalFlags::ICANON
                | LocalFlags::ISIG,
        );
        hidden.control_chars[SpecialCharacterIndices::VMIN as usize] = 1;
        hidden.control_chars[SpecialCharacterIndices::VTIME as usize] = 0;
        termios::tcsetattr(fd, SetArg::TCSAFLUSH, &hidden).map_err(terminal_error("tcsetattr"))?;
        let guard = EchoOff { fd, saved };
        // tcsetattr succeeds when any one change took: check that echo is off indeed.
        let now = termios::tcgetattr(fd).map_err(terminal_error("tcgetattr"))?;
        if now.local_flags.contains(LocalFlags::ECHO) {
            return Err(UserError::EchoOn);
        }
        Ok(guard)
    }

    /// One password, after `prompt` on `err`.
    fn read(
        &self,
        prompt: &str,
        signals: &Signals,
        err: &mut impl Write,
    ) -> Result<Password, UserError> {
        let _ = write!(err, "{prompt}");
        let _ = err.flush();
        let mut password = Password(Vec::new());
        loop {
            if signals.caught() {
                let _ = writeln!(err);
                return Err(UserError::Interrupted);
            }
            // A short poll, so that a caught signal is seen while nobody types.
            let mut fds = [PollFd::new(self.fd, PollFlags::POLLIN)];
            match nix::poll::poll(&mut fds, PollTimeout::from(100u8)) {
                Ok(0) | Err(Errno::EINTR) => continue,
                Ok(_) => {}
                Err(errno) => return Err(UserError::Terminal { call: "poll", errno }),
            }
            let mut byte = [0u8; 1];
            let byte = match nix::unistd::read(self.fd, &mut byte) {
                Ok(0) => return Err(UserError::Interrupted), // the terminal hung up
                Ok(_) => byte[0],
                Err(Errno::EINTR | Errno::EAGAIN) => continue,
                Err(errno) => return Err(UserError::Terminal { call: "read", errno }),
            };
            match byte {
                b'\r' | b'\n' => {
                    let _ = writeln!(err);
                    return Ok(password);
                }
                // Ctrl-C, Ctrl-\, and Ctrl-D on an empty line.
                0x03 | 0x1c => {
                    let _ = writeln!(err);
                    return Err(UserError::Interrupted);
                }
                0x04 if password.0.is_empty() => {
                    let _ = writeln!(err);
                    return Err(UserError::Interrupted);
                }
                // Backspace (DEL or ^H): the last character, all of its UTF-8 bytes.
                0x7f | 0x08 => {
                    while let Some(b) = password.0.pop() {
                        if b & 0xc0 != 0x80 {
                            break;
                        }
                    }
                }
                // Ctrl-U: the whole line.
                0x15 => password.0.clear(),
                // Other control keys (Ctrl-Z among them) type nothing.
                b if b < 0x20 => {}
                b => {
                    if password.0.len() >= PASSWORD_MAX {
                        let _ = writeln!(err);
                        return Err(UserError::TooLong);
                    }
                    password.0.push(b);
                }
            }
        }
    }
}

impl Drop for EchoOff<'_> {
    fn drop(&mut self) {
        // TCSAFLUSH: typed-ahead bytes of the hidden password are not left for the shell.
        let _ = termios::tcsetattr(self.fd, SetArg::TCSAFLUSH, &self.saved);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("plcd-user-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_new_file_is_0600_and_an_old_one_keeps_its_mode() {
        let dir = temp_dir("modes");
        let path = dir.join("users");
        write_atomically(&path, "# one\n", true).unwrap();
        assert_eq!(fs::metadata(&path).unwrap().permissions().mode() & 0o7777, 0o600);
        fs::set_permissions(&path, fs::Permissions::from_mode(0o640)).unwrap();
        write_atomically(&path, "# two\n", false).unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "# two\n");
        assert_eq!(fs::metadata(&path).unwrap().permissions().mode() & 0o7777, 0o640);
        let names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert_eq!(names, ["users"], "no temporary file is left");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_symbolic_link_is_kept_and_its_target_replaced() {
        let dir = temp_dir("link");
        let (real, link) = (dir.join("real"), dir.join("users"));
        fs::write(&real, "# old\n").unwrap();
        std::os::unix::fs::symlink("real", &link).unwrap();
        write_atomically(&link, "# new\n", false).unwrap();
        assert!(fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
        assert_eq!(fs::read_to_string(&real).unwrap(), "# new\n");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_temporary_one() {
        let dir = temp_dir("failed");
        let path = dir.join("users");
        fs::write(&path, "# old\n").unwrap();
        // A folder where the temporary file would go: its creation fails.
        let temp = dir.join(format!(".users.plcd-user-{}", std::process::id()));
        fs::create_dir(&temp).unwrap();
        let error = write_atomically(&path, "# new\n", false).unwrap_err();
        assert!(error.to_string().contains("create a temporary file"), "{error}");
        assert_eq!(fs::read_to_string(&path).unwrap(), "# old\n");
        fs::remove_dir_all(&dir).unwrap();
    }

    /// A valid hash, made cheaply (the file takes any costs up to the maximum).
    fn cheap_hash() -> String {
        let costs = HashCosts { memory_kib: 8, passes: 1, lanes: 1 };
        users::hash_password(b"pw", &[7; SALT_LEN], costs).unwrap()
    }

    #[test]
    fn a_change_waits_for_the_lock_and_gives_up_after_its_wait() {
        let dir = temp_dir("busy");
        let path = dir.join("users");
        let hash = cheap_hash();
        let held = lock(&path, Duration::ZERO).unwrap();
        let started = Instant::now();
        let error =
            change(&path, Duration::from_millis(100), |f| f.set("ann", Role::Viewer, &hash))
                .unwrap_err();
        assert!(matches!(error, UserError::Busy { .. }), "{error}");
        assert!(started.elapsed() >= Duration::from_millis(100), "it waited its wait");
        assert!(error.to_string().contains(".users.plcd-user.lock"), "{error}");
        assert!(!path.exists(), "nothing written");
        drop(held);
        change(&path, Duration::ZERO, |f| f.set("ann", Role::Viewer, &hash)).unwrap();
        assert_eq!(read_existing(&path).unwrap().users().len(), 1);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn changes_at_once_from_many_threads_lose_nothing() {
        let dir = temp_dir("together");
        let path = dir.join("users");
        let hash = cheap_hash();
        // Each lock is its own open file description, so threads exclude each other as
        // processes do. Without the lock two changes read the same file and the later write
        // drops the earlier one's user (and, in one process, their temporary files collide).
        std::thread::scope(|scope| {
            for t in 0..8 {
                let (path, hash) = (&path, &hash);
                scope.spawn(move || {
                    for k in 0..5 {
                        let name = format!("u{t}_{k}");
                        change(path, LOCK_WAIT, |f| f.set(&name, Role::Operator, hash)).unwrap();
                    }
                });
            }
        });
        assert_eq!(read_existing(&path).unwrap().users().len(), 40);
        let lock_file = dir.join(".users.plcd-user.lock");
        assert_eq!(fs::metadata(&lock_file).unwrap().permissions().mode() & 0o7777, 0o600);
        fs::remove_dir_all(&dir).unwrap();
    }
}

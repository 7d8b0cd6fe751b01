//! Where the control socket lives and what its file looks like: the path (`[control] socket`,
//! or the first usable of the protocol's default paths, creating and checking its directory),
//! a stale socket left by a crash replaced and a live one refused, the file's mode 0660 and
//! group set before anyone can connect, and the file removed again when the server goes —
//! unless it is no longer the one we made.
//!
//! Who may connect once the file exists is [`super::access`]'s question; serving the
//! connections is [`super::server`]'s.

use std::fs;
use std::io;
use std::os::fd::AsRawFd;
use std::os::unix::fs::{DirBuilderExt, FileTypeExt, MetadataExt, PermissionsExt};
use std::os::unix::net::UnixListener;
use std::path::{Path, PathBuf};

use nix::errno::Errno;
use nix::sys::socket::{self, AddressFamily, Backlog, SockFlag, SockType, UnixAddr};
use nix::unistd::{Gid, Group};

use super::server::{io_error, ServerError};
use plcd_ipc as protocol;

const BACKLOG: i32 = 64;

/// A bound and listening socket, the path of its file and the file's identity. Dropping it
/// closes the socket and leaves the file: it becomes a [`SocketFile`], which removes the file,
/// only once the server that serves it exists.
pub(super) struct Bound {
    pub(super) listener: UnixListener,
    pub(super) path: PathBuf,
    /// Device and inode of the socket file we created, to remove only that one.
    pub(super) identity: (u64, u64),
}

/// The socket of a running server. See the module docs.
#[derive(Debug)]
pub(super) struct SocketFile {
    listener: UnixListener,
    path: PathBuf,
    identity: (u64, u64),
}

impl SocketFile {
    pub(super) fn new(bound: Bound) -> SocketFile {
        SocketFile { listener: bound.listener, path: bound.path, identity: bound.identity }
    }

    pub(super) fn listener(&self) -> &UnixListener {
        &self.listener
    }

    pub(super) fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for SocketFile {
    /// Removes the socket file, unless it is no longer ours (another daemon that found it
    /// stale replaced it, or someone put something else there).
    fn drop(&mut self) {
        if let Ok(meta) = fs::symlink_metadata(&self.path) {
            if (meta.dev(), meta.ino()) == self.identity {
                let _ = fs::remove_file(&self.path);
            }
        }
    }
}

/// Binds the socket at `path` when one is configured (already resolved against the config
/// file's directory), else at the first usable default path for the effective user `euid`.
pub(super) fn bind(
    path: Option<&Path>,
    euid: u32,
    group: Option<Gid>,
) -> Result<Bound, ServerError> {
    match path {
        Some(path) => bind_path(path, group),
        None => {
            let xdg = std::env::var("XDG_RUNTIME_DIR").ok();
            bind_default(&default_candidates(euid, xdg.as_deref()), group)
        }
    }
}

/// The group `[control] group` names.
pub(super) fn resolve_group(name: &str) -> Result<Gid, ServerError> {
    match Group::from_name(name) {
        Ok(Some(group)) => Ok(group.gid),
        Ok(None) => Err(ServerError::UnknownGroup { group: name.into() }),
        Err(source) => Err(ServerError::GroupLookup { group: name.into(), source }),
    }
}

/// A default socket path and how its directory is made.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Candidate {
    path: PathBuf,
    /// The mode of the directory when it has to be created.
    dir_mode: u32,
    /// In a world-writable place (/tmp): the directory must be ours and closed to others, or
    /// anyone could have prepared it to take over the socket.
    private: bool,
}

/// [`protocol::default_socket_paths`], in order, with how to make each directory.
fn default_candidates(uid: u32, xdg_runtime_dir: Option<&str>) -> Vec<Candidate> {
    protocol::default_socket_paths(uid, xdg_runtime_dir)
        .into_iter()
        .map(|path| {
            let path = PathBuf::from(path);
            let private = path.starts_with("/tmp");
            Candidate { path, dir_mode: if private { 0o750 } else { 0o755 }, private }
        })
        .collect()
}

/// Whether a failure at one default path means "try the next": the path is not ours to use
/// (no permission, a read-only or missing directory). Anything else (another plcd serving it,
/// a file in the way) is a real problem that a fallback would only hide.
fn falls_through(error: &ServerError) -> bool {
    const NEXT: [i32; 5] = [libc::EACCES, libc::EPERM, libc::EROFS, libc::ENOENT, libc::ENOTDIR];
    match error {
        ServerError::Io { source, .. } => source.raw_os_error().is_some_and(|e| NEXT.contains(&e)),
        _ => false,
    }
}

/// Tries `attempt` on each candidate in order until one works or fails for a reason that is
/// not [`falls_through`]. Returns the result and the index of the candidate used.
fn first_usable<T>(
    candidates: &[Candidate],
    mut attempt: impl FnMut(&Candidate) -> Result<T, ServerError>,
) -> Result<(T, usize), ServerError> {
    let mut tried = Vec::new();
    for (index, candidate) in candidates.iter().enumerate() {
        match attempt(candidate) {
            Ok(value) => return Ok((value, index)),
            Err(e) if falls_through(&e) => {
                log::debug!("{e}; trying the next default path");
                tried.push(e);
            }
            Err(e) => return Err(e),
        }
    }
    Err(ServerError::NoPath { tried })
}

/// Creates the directory of a default path when missing, and checks a private one.
fn prepare_dir(candidate: &Candidate) -> Result<(), ServerError> {
    let Some(dir) = candidate.path.parent() else { return Ok(()) };
    let io = |call: &'static str| {
        move |source: io::Error| ServerError::Io { path: dir.to_path_buf(), call, source }
    };
    match fs::DirBuilder::new().mode(candidate.dir_mode).create(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(io("mkdir")(e)),
    }
    if candidate.private {
        let meta = fs::symlink_metadata(dir).map_err(io("stat"))?;
        let euid = nix::unistd::geteuid().as_raw();
        let unsafe_dir = |reason: String| ServerError::UnsafeDir { dir: dir.to_path_buf(), reason };
        if !meta.file_type().is_dir() {
            return Err(unsafe_dir("not a directory (a symlink?)".into()));
        }
        if meta.uid() != euid {
            return Err(unsafe_dir(format!("owned by uid {}, not by uid {euid}", meta.uid())));
        }
        if meta.mode() & 0o022 != 0 {
            return Err(unsafe_dir(format!(
                "writable by others (mode {:o})",
                meta.mode() & 0o7777
            )));
        }
    }
    Ok(())
}

/// What a connect to an existing socket file says about it.
enum Probe {
    /// Something accepts on it.
    Live,
    /// Nothing listens: left behind by a process that died.
    Stale,
    /// The file went away meanwhile.
    Gone,
}

fn probe(path: &Path) -> Result<Probe, ServerError> {
    let flags = SockFlag::SOCK_CLOEXEC | SockFlag::SOCK_NONBLOCK;
    let fd = socket::socket(AddressFamily::Unix, SockType::Stream, flags, None)
        .map_err(io_error(path, "socket"))?;
    let addr = UnixAddr::new(path).map_err(io_error(path, "connect"))?;
    // Non-blocking: a live server with a full backlog answers EAGAIN instead of making us wait.
    match socket::connect(fd.as_raw_fd(), &addr) {
        Ok(()) | Err(Errno::EAGAIN) | Err(Errno::EINPROGRESS) => Ok(Probe::Live),
        Err(Errno::ECONNREFUSED) => Ok(Probe::Stale),
        Err(Errno::ENOENT) => Ok(Probe::Gone),
        Err(errno) => Err(io_error(path, "connect")(errno)),
    }
}

/// Removes a stale socket at `path`; refuses a live one and anything that is not a socket.
fn clear_stale(path: &Path) -> Result<(), ServerError> {
    let meta = match fs::symlink_metadata(path) {
        Ok(meta) => meta,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(()),
        Err(source) => return Err(ServerError::Io { path: path.into(), call: "stat", source }),
    };
    if !meta.file_type().is_socket() {
        return Err(ServerError::NotASocket { path: path.into() });
    }
    match probe(path)? {
        Probe::Live => Err(ServerError::InUse { path: path.into() }),
        Probe::Gone => Ok(()),
        Probe::Stale => {
            log::info!("removing the stale control socket {}", path.display());
            match fs::remove_file(path) {
                Ok(()) => Ok(()),
                Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
                Err(source) => Err(ServerError::Io { path: path.into(), call: "unlink", source }),
            }
        }
    }
}

/// Binds a socket at exactly `path`: mode 0660, group `group`, listening.
fn bind_path(path: &Path, group: Option<Gid>) -> Result<Bound, ServerError> {
    clear_stale(path)?;
    let flags = SockFlag::SOCK_CLOEXEC | SockFlag::SOCK_NONBLOCK;
    let fd = socket::socket(AddressFamily::Unix, SockType::Stream, flags, None)
        .map_err(io_error(path, "socket"))?;
    let addr = UnixAddr::new(path).map_err(io_error(path, "bind"))?;
    match socket::bind(fd.as_raw_fd(), &addr) {
        Ok(()) => {}
        // Another daemon bound it between our probe and now.
        Err(Errno::EADDRINUSE) => return Err(ServerError::InUse { path: path.into() }),
        Err(errno) => return Err(io_error(path, "bind")(errno)),
    }
    // The file is ours from here on: remove it again if the rest fails.
    let finish = || -> Result<(u64, u64), ServerError> {
        let io = |call: &'static str| {
            move |source: io::Error| ServerError::Io { path: path.to_path_buf(), call, source }
        };
        let meta = fs::symlink_metadata(path).map_err(io("stat"))?;
        // Mode and group before listen(): until then a connect is refused, so no client ever
        // sees the socket with the mode the umask gave it.
        fs::set_permissions(path, fs::Permissions::from_mode(0o660)).map_err(io("chmod"))?;
        if let Some(gid) = group {
            std::os::unix::fs::lchown(path, None, Some(gid.as_raw())).map_err(io("chown"))?;
        }
        let backlog = Backlog::new(BACKLOG).unwrap_or(Backlog::MAXCONN);
        socket::listen(&fd, backlog).map_err(|e| io("listen")(e.into()))?;
        Ok((meta.dev(), meta.ino()))
    };
    match finish() {
        Ok(identity) => {
            Ok(Bound { listener: UnixListener::from(fd), path: path.to_path_buf(), identity })
        }
        Err(e) => {
            let _ = fs::remove_file(path);
            Err(e)
        }
    }
}

/// Binds the first usable default path, creating its directory when needed.
fn bind_default(candidates: &[Candidate], group: Option<Gid>) -> Result<Bound, ServerError> {
    let (bound, index) = first_usable(candidates, |candidate| {
        prepare_dir(candidate)?;
        bind_path(&candidate.path, group)
    })?;
    if index > 0 {
        let skipped: Vec<String> =
            candidates[..index].iter().map(|c| c.path.display().to_string()).collect();
        log::info!(
            "control socket at {} ({} could not be used)",
            bound.path.display(),
            skipped.join(", ")
        );
    }
    Ok(bound)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_candidates_follow_the_protocols_order() {
        let c = default_candidates(1000, Some("/run/user/1000"));
        let paths: Vec<&Path> = c.iter().map(|c| c.path.as_path()).collect();
        assert_eq!(
            paths,
            [
                Path::new("/run/plcd/plcd.sock"),
                Path::new("/run/user/1000/plcd.sock"),
                Path::new("/tmp/plcd-1000/plcd.sock")
            ]
        );
        assert_eq!((c[0].dir_mode, c[0].private), (0o755, false));
        assert_eq!((c[1].dir_mode, c[1].private), (0o755, false));
        assert_eq!((c[2].dir_mode, c[2].private), (0o750, true));
        assert_eq!(default_candidates(0, None).len(), 2);
    }

    fn io(path: &str, errno: Errno) -> ServerError {
        ServerError::Io { path: path.into(), call: "bind", source: errno.into() }
    }

    #[test]
    fn a_path_we_may_not_use_falls_through_to_the_next() {
        let candidates = default_candidates(1000, Some("/run/user/1000"));
        for errno in [Errno::EACCES, Errno::EPERM, Errno::EROFS, Errno::ENOENT, Errno::ENOTDIR] {
            let mut tried = Vec::new();
            let (value, index) = first_usable(&candidates, |c| {
                tried.push(c.path.clone());
                if tried.len() < 3 {
                    Err(io("x", errno))
                } else {
                    Ok("bound")
                }
            })
            .unwrap();
            assert_eq!((value, index), ("bound", 2), "{errno}");
            assert_eq!(tried, candidates.iter().map(|c| c.path.clone()).collect::<Vec<_>>());
        }
        // The first that works is taken.
        let (_, index) = first_usable(&candidates, |_| Ok(())).unwrap();
        assert_eq!(index, 0);
    }

    #[test]
    fn a_real_problem_stops_the_search() {
        let candidates = default_candidates(1000, Some("/run/user/1000"));
        for error in [
            ServerError::InUse { path: "/run/plcd/plcd.sock".into() },
            ServerError::NotASocket { path: "/run/plcd/plcd.sock".into() },
            io("/run/plcd/plcd.sock", Errno::ENAMETOOLONG),
            io("/run/plcd/plcd.sock", Errno::EADDRINUSE),
        ] {
            let text = error.to_string();
            let mut error = Some(error);
            let mut calls = 0;
            let result: Result<((), usize), _> = first_usable(&candidates, |_| {
                calls += 1;
                Err(error.take().unwrap())
            });
            assert_eq!(result.unwrap_err().to_string(), text);
            assert_eq!(calls, 1);
        }
    }

    #[test]
    fn when_no_path_works_every_reason_is_named() {
        let candidates = default_candidates(1000, None);
        let error =
            first_usable::<()>(&candidates, |c| Err(io(c.path.to_str().unwrap(), Errno::EACCES)))
                .unwrap_err();
        let text = error.to_string();
        assert!(text.contains("/run/plcd/plcd.sock") && text.contains("/tmp/plcd-1000"), "{text}");
        assert!(matches!(error, ServerError::NoPath { tried } if tried.len() == 2));
    }

    /// A scratch directory under /tmp, removed on drop.
    struct Scratch(PathBuf);

    impl Scratch {
        fn new(name: &str) -> Scratch {
            let dir = std::env::temp_dir()
                .join(format!("plcd-server-unit-{name}-{}", std::process::id()));
            let _ = fs::remove_dir_all(&dir);
            fs::create_dir_all(&dir).unwrap();
            Scratch(dir)
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.0);
        }
    }

    #[test]
    fn binding_falls_back_past_a_directory_that_cannot_be_made() {
        let scratch = Scratch::new("fallback");
        let candidates = [
            // mkdir under a /proc directory that does not exist: ENOENT, even as root.
            Candidate {
                path: "/proc/plcd-no-such-dir/run/plcd.sock".into(),
                dir_mode: 0o755,
                private: false,
            },
            Candidate { path: scratch.0.join("run/plcd.sock"), dir_mode: 0o750, private: true },
        ];
        let bound = bind_default(&candidates, None).unwrap();
        assert_eq!(bound.path, candidates[1].path);
        let dir = fs::metadata(scratch.0.join("run")).unwrap();
        assert_eq!(dir.mode() & 0o777, 0o750 & !current_umask());
        let sock = fs::symlink_metadata(&bound.path).unwrap();
        assert!(sock.file_type().is_socket());
        assert_eq!(sock.mode() & 0o777, 0o660);
        assert_eq!((sock.dev(), sock.ino()), bound.identity);
    }

    #[test]
    fn a_private_directory_open_to_others_is_refused() {
        let scratch = Scratch::new("private");
        let dir = scratch.0.join("open");
        fs::create_dir(&dir).unwrap();
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o777)).unwrap();
        let candidate = Candidate { path: dir.join("plcd.sock"), dir_mode: 0o750, private: true };
        let error = bind_default(std::slice::from_ref(&candidate), None).err().unwrap();
        assert!(matches!(error, ServerError::UnsafeDir { .. }), "{error}");
        assert!(error.to_string().contains("writable by others"), "{error}");
        assert!(!candidate.path.exists());
    }

    fn current_umask() -> u32 {
        let status = fs::read_to_string("/proc/self/status").unwrap();
        status
            .lines()
            .find_map(|l| l.strip_prefix("Umask:"))
            .map(|m| u32::from_str_radix(m.trim(), 8).unwrap())
            .unwrap_or(0o022)
    }
}

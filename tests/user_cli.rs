//! `plcd user add|remove|list` end to end: the real binary on a scratch folder, the password
//! on standard input (`--password-stdin`, stdin closed after it) or typed on a pseudo-terminal
//! (`nix::pty`), each run bounded by a timeout. The file it writes is checked with the core's
//! own parser and verify; `plcd check` counts its users.

mod harness;

use std::fs;
use std::io::Write;
use std::os::fd::{AsFd, OwnedFd};
use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Child, Output, Stdio};
use std::time::{Duration, Instant};

use harness::runner::{command, wait_bounded};
use harness::tempdir::TempDir;
use nix::poll::{PollFd, PollFlags, PollTimeout};
use nix::sys::termios::{self, LocalFlags};
use plcd::users::{Role, UsersFile};

/// How long one run may take: a hash of the default costs is some 70 ms natively.
fn patience() -> Duration {
    Duration::from_secs(30) * harness::runner::slowdown()
}

/// `plcd ARGS` in `dir`, with `stdin` as its standard input then closed.
fn plcd(dir: &TempDir, args: &[&str], stdin: &str) -> Output {
    let mut child = command(env!("CARGO_BIN_EXE_plcd"))
        .args(args)
        .current_dir(dir.path())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("plcd starts");
    let mut input = child.stdin.take().unwrap();
    // A refused run may exit before reading: a broken pipe is then no failure.
    let _ = input.write_all(stdin.as_bytes());
    drop(input);
    // The output is small: it fits in the pipes while the wait runs.
    wait_bounded(&mut child, patience(), &format!("plcd {args:?}"));
    child.wait_with_output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn users(path: &Path) -> UsersFile {
    UsersFile::parse(&fs::read_to_string(path).unwrap(), path).unwrap()
}

fn mode(path: &Path) -> u32 {
    fs::metadata(path).unwrap().permissions().mode() & 0o7777
}

#[test]
fn add_list_replace_and_remove_with_the_password_on_stdin() {
    let dir = TempDir::new("user-cli");
    let add = |name: &str, role: &str, password: &str| {
        plcd(
            &dir,
            &["user", "add", name, "--role", role, "--file", "users", "--password-stdin"],
            password,
        )
    };
    let out = add("alice", "engineer", "correct horse\n");
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout), "users: added alice (engineer)\n");
    let path = dir.join("users");
    assert_eq!(mode(&path), 0o600, "a new users file is for its owner alone");
    assert_eq!(users(&path).verify("alice", b"correct horse"), Some(Role::Engineer));
    assert_eq!(users(&path).verify("alice", b"correct horse\n"), None, "the line end is no part");

    // Another user, comments of the administrator's, a new password: lines kept as they were.
    let out = add("bob", "viewer", "battery staple\r\n");
    assert!(out.status.success(), "{}", text(&out.stderr));
    let mut edited = fs::read_to_string(&path).unwrap();
    edited.insert_str(0, "# the plant's users\n\n");
    fs::write(&path, &edited).unwrap();
    fs::set_permissions(&path, fs::Permissions::from_mode(0o640)).unwrap();
    let out = add("alice", "operator", "new one");
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout), "users: new password for alice (engineer → operator)\n");
    let after = fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = after.lines().collect();
    assert_eq!(lines[..2], ["# the plant's users", ""]);
    assert!(lines[2].starts_with("alice:operator:$argon2id$v=19$m=32768,t=3,p=1$"), "{after}");
    assert_eq!(lines[3], edited.lines().nth(3).unwrap(), "bob's line is untouched");
    assert_eq!(mode(&path), 0o640, "an existing file keeps its mode");
    let file = users(&path);
    assert_eq!(file.verify("alice", b"new one"), Some(Role::Operator));
    assert_eq!(file.verify("alice", b"correct horse"), None);
    assert_eq!(file.verify("bob", b"battery staple"), Some(Role::Viewer));

    let out = plcd(&dir, &["user", "list", "--file", "users"], "");
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout), "alice  operator\nbob    viewer\n", "names and roles, no hash");

    let out = plcd(&dir, &["user", "remove", "alice", "--file", "users"], "");
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout), "users: removed alice (operator)\n");
    let left = fs::read_to_string(&path).unwrap();
    assert!(left.starts_with("# the plant's users\n\nbob:viewer:"), "{left}");
    assert_eq!(left.lines().count(), 3);
    let out = plcd(&dir, &["user", "remove", "alice", "--file", "users"], "");
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(text(&out.stderr), "plcd user: no user `alice` in the file\n");
    // The lock file stays, by design (docs/COMMANDS.md): removing it would let two runs lock
    // two different files.
    assert_eq!(dir.entries(), [".users.plcd-user.lock", "users"], "no temporary file is left");
}

#[test]
fn the_config_names_the_file_and_check_counts_its_users() {
    let dir = TempDir::new("user-config");
    dir.write("main.il", "END\n");
    dir.write("plcd.toml", "[users]\nfile = \"etc/users\"\n\n[[program]]\nfile = \"main.il\"\n");
    fs::create_dir(dir.join("etc")).unwrap();
    let args =
        ["user", "add", "op-1", "--role", "operator", "--config", "plcd.toml", "--password-stdin"];
    let out = plcd(&dir, &args, "s3cret\n");
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout), "etc/users: added op-1 (operator)\n");
    assert_eq!(users(&dir.join("etc/users")).verify("op-1", b"s3cret"), Some(Role::Operator));
    let out = plcd(&dir, &["check", "--config", "plcd.toml"], "");
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(
        text(&out.stdout),
        "plcd.toml: ok: 1 program(s), 1 instruction(s), 0 task(s), 1 user(s)\n"
    );

    // A config without [users]: the command says where the file should be named.
    dir.write("bare.toml", "[[program]]\nfile = \"main.il\"\n");
    let out = plcd(&dir, &["user", "list", "--config", "bare.toml"], "");
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        "plcd user: bare.toml: `[users] file` is not set; set it there, or give the file with \
         --file\n"
    );
    // One of --config and --file, never both.
    let out = plcd(&dir, &["user", "list", "--config", "plcd.toml", "--file", "x"], "");
    assert_eq!(out.status.code(), Some(2));
    let out = plcd(&dir, &["user", "list"], "");
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn what_cannot_be_a_user_is_refused_and_nothing_written() {
    let dir = TempDir::new("user-refused");
    let add = |args: &[&str], stdin: &str| {
        let mut all = vec!["user", "add"];
        all.extend_from_slice(args);
        plcd(&dir, &all, stdin)
    };
    let cases: [(&[&str], &str, i32, &str); 5] = [
        (
            &["alice", "--role", "engineer", "--file", "users", "--password-stdin"],
            "\n",
            1,
            "plcd user: no password on standard input\n",
        ),
        (
            &["alice", "--role", "engineer", "--file", "users", "--password-stdin"],
            "",
            1,
            "plcd user: no password on standard input\n",
        ),
        (
            &["al ice", "--role", "engineer", "--file", "users", "--password-stdin"],
            "pw\n",
            1,
            "plcd user: bad user name \"al ice\": character ' ' is not allowed in a user name \
          (letters, digits, `_`, `.` and `-`)\n",
        ),
        // Without --password-stdin, standard input must be a terminal (a pipe is not).
        (
            &["alice", "--role", "engineer", "--file", "users"],
            "pw\npw\n",
            1,
            "plcd user: standard input is not a terminal: give the password on it with \
          --password-stdin, or run this on a terminal\n",
        ),
        (
            &["alice", "--role", "admin", "--file", "users", "--password-stdin"],
            "pw\n",
            2,
            "error: invalid value 'admin' for '--role <ROLE>': unknown role `admin`, expected \
          viewer, operator or engineer\n\nFor more information, try '--help'.\n",
        ),
    ];
    for (args, stdin, code, message) in cases {
        let out = add(args, stdin);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {}", text(&out.stderr));
        assert_eq!(text(&out.stderr), message, "{args:?}");
    }
    let long = format!("{}\n", "x".repeat(1025));
    let out = add(&["alice", "--role", "viewer", "--file", "users", "--password-stdin"], &long);
    assert_eq!(text(&out.stderr), "plcd user: the password is longer than 1024 bytes\n");
    assert_eq!(dir.entries(), Vec::<String>::new(), "no file was made");

    // A file with a bad line is not edited: what it kept might not be what was meant.
    dir.write("users", "alice:engineer:hunter2\n");
    let out = add(&["bob", "--role", "viewer", "--file", "users", "--password-stdin"], "pw\n");
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        text(&out.stderr),
        "users:1:16: error: not a PHC hash string: password hash string missing field\n"
    );
    assert_eq!(fs::read_to_string(dir.join("users")).unwrap(), "alice:engineer:hunter2\n");
}

/// A pseudo-terminal: the test types on `master`, `plcd` has `slave` as its standard input,
/// output and error.
struct Terminal {
    master: OwnedFd,
    slave: OwnedFd,
    seen: String,
}

impl Terminal {
    fn open() -> Terminal {
        let pty = nix::pty::openpty(None, None).expect("openpty");
        Terminal { master: pty.master, slave: pty.slave, seen: String::new() }
    }

    fn spawn(&self, dir: &TempDir, args: &[&str]) -> Child {
        let slave = || Stdio::from(self.slave.try_clone().unwrap());
        command(env!("CARGO_BIN_EXE_plcd"))
            .args(args)
            .current_dir(dir.path())
            .stdin(slave())
            .stdout(slave())
            .stderr(slave())
            .spawn()
            .expect("plcd starts")
    }

    fn echo(&self) -> LocalFlags {
        termios::tcgetattr(self.slave.as_fd()).unwrap().local_flags
    }

    /// Reads what plcd wrote until it holds `wanted`, for at most the patience.
    fn wait_for(&mut self, wanted: &str) {
        let deadline = Instant::now() + patience();
        while !self.seen.contains(wanted) {
            assert!(Instant::now() < deadline, "no {wanted:?} on the terminal: {:?}", self.seen);
            let mut fds = [PollFd::new(self.master.as_fd(), PollFlags::POLLIN)];
            if nix::poll::poll(&mut fds, PollTimeout::from(100u8)).unwrap() == 0 {
                continue;
            }
            let mut buf = [0u8; 256];
            let n = nix::unistd::read(self.master.as_fd(), &mut buf).unwrap();
            self.seen.push_str(&String::from_utf8_lossy(&buf[..n]));
        }
    }

    fn type_in(&self, keys: &str) {
        nix::unistd::write(self.master.as_fd(), keys.as_bytes()).unwrap();
    }
}

#[test]
fn the_password_is_typed_twice_on_a_terminal_that_does_not_echo_it() {
    let dir = TempDir::new("user-tty");
    let mut tty = Terminal::open();
    assert!(tty.echo().contains(LocalFlags::ECHO), "a new terminal echoes");
    let mut child =
        tty.spawn(&dir, &["user", "add", "alice", "--role", "engineer", "--file", "users"]);
    // The prompt comes after echo is off: typing before it would be echoed.
    tty.wait_for("password for alice: ");
    assert!(!tty.echo().contains(LocalFlags::ECHO), "echo is off while the password is typed");
    // Typed with a mistake rubbed out, and a Ctrl-Z that types nothing.
    tty.type_in("Tr0ub4dor&3x\x7f\x1a\r");
    tty.wait_for("again: ");
    tty.type_in("Tr0ub4dor&3\n");
    let status = wait_bounded(&mut child, patience(), "plcd user add on a terminal");
    tty.wait_for("users: added alice (engineer)");
    assert!(status.success(), "{}", tty.seen);
    assert!(!tty.seen.contains("Tr0ub"), "the password was echoed: {:?}", tty.seen);
    assert!(tty.echo().contains(LocalFlags::ECHO | LocalFlags::ICANON | LocalFlags::ISIG));
    assert_eq!(users(&dir.join("users")).verify("alice", b"Tr0ub4dor&3"), Some(Role::Engineer));
}

#[test]
fn two_different_passwords_or_ctrl_c_write_nothing_and_restore_the_terminal() {
    let dir = TempDir::new("user-tty-refused");
    let args = ["user", "add", "alice", "--role", "engineer", "--file", "users"];
    let mut tty = Terminal::open();
    let mut child = tty.spawn(&dir, &args);
    tty.wait_for("password for alice: ");
    tty.type_in("one\r");
    tty.wait_for("again: ");
    tty.type_in("two\r");
    let status = wait_bounded(&mut child, patience(), "plcd user add, two passwords");
    tty.wait_for("the passwords differ; nothing written");
    assert_eq!(status.code(), Some(1));

    let mut tty = Terminal::open();
    let mut child = tty.spawn(&dir, &args);
    tty.wait_for("password for alice: ");
    tty.type_in("half a pass\x03");
    let status = wait_bounded(&mut child, patience(), "plcd user add, Ctrl-C");
    tty.wait_for("interrupted; nothing written");
    assert_eq!(status.code(), Some(130));
    let flags = tty.echo();
    assert!(flags.contains(LocalFlags::ECHO | LocalFlags::ICANON | LocalFlags::ISIG), "{flags:?}");
    assert_eq!(dir.entries(), Vec::<String>::new());
}

#[test]
fn a_signal_at_the_prompt_restores_the_terminal_first() {
    use nix::sys::signal::{kill, Signal};
    use nix::unistd::Pid;
    let dir = TempDir::new("user-tty-signal");
    for signal in [Signal::SIGTERM, Signal::SIGINT] {
        let mut tty = Terminal::open();
        let args = ["user", "add", "alice", "--role", "viewer", "--file", "users"];
        let mut child = tty.spawn(&dir, &args);
        tty.wait_for("password for alice: ");
        tty.type_in("half");
        kill(Pid::from_raw(child.id() as i32), signal).unwrap();
        let status = wait_bounded(&mut child, patience(), &format!("plcd user add, {signal}"));
        tty.wait_for("interrupted; nothing written");
        assert_eq!(status.code(), Some(130), "{signal}");
        let flags = tty.echo();
        assert!(
            flags.contains(LocalFlags::ECHO | LocalFlags::ICANON | LocalFlags::ISIG),
            "{flags:?}"
        );
    }
    assert_eq!(dir.entries(), Vec::<String>::new());
}

#[test]
fn a_password_is_not_read_from_a_terminal_that_echoes() {
    let dir = TempDir::new("user-tty-echo");
    let mut tty = Terminal::open();
    let args = ["user", "add", "alice", "--role", "viewer", "--file", "users", "--password-stdin"];
    let mut child = tty.spawn(&dir, &args);
    let status = wait_bounded(&mut child, patience(), "plcd user add --password-stdin on a tty");
    tty.wait_for("leave out --password-stdin to be asked for the password without echo");
    assert_eq!(status.code(), Some(1));
    assert_eq!(dir.entries(), Vec::<String>::new());
}

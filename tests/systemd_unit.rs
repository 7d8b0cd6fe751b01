//! The systemd integration: `systemd/plcd.service` as systemd itself judges it, and the install
//! script `systemd/install`.
//!
//! Wherever `systemd-analyze` exists: the unit passes `systemd-analyze verify` without a word,
//! `systemd-analyze security --offline=true` rates its exposure at 2.0 or less, and its
//! `SystemCallFilter=` lets through every system call plcd makes. systemd need not run (it is not
//! PID 1 in a container or on a CI runner): these commands only read unit files.
//!
//! The install script is run with `--dry-run` (it must name every file it would install, and
//! change nothing) and, where `systemd-sysusers` exists, for real into a scratch root.
//!
//! Where `systemd-analyze` or `systemd-sysusers` is missing, each test that needs it writes
//! `<test>: skipped: <reason>` to stderr and passes, so a plain `cargo test` works everywhere.
//! With `PLCD_REQUIRE_SYSTEMD=1` in the environment (anything but empty or `0`), as `.ci/run`
//! sets it, every such skip is a failure instead, so a suite that checked nothing cannot pass.

mod harness;

use std::collections::BTreeSet;
use std::fs;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use harness::tempdir::TempDir;

/// The worst exposure `systemd-analyze security` may give the unit (the bound).
const MAX_EXPOSURE: f64 = 2.0;

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn unit_file() -> PathBuf {
    repo().join("systemd/plcd.service")
}

/// The variable that turns every skip of these tests into a failure.
const REQUIRE: &str = "PLCD_REQUIRE_SYSTEMD";

/// A scratch root for systemd's tools, removed on drop.
struct Scratch(TempDir);

impl Scratch {
    fn new(name: &str) -> Scratch {
        Scratch(TempDir::new(&format!("systemd-{name}")))
    }

    fn root(&self) -> &Path {
        self.0.path()
    }

    fn path(&self, relative: &str) -> PathBuf {
        self.0.join(relative.trim_start_matches('/'))
    }

    /// Writes `text` at `relative`, creating directories, with `mode`.
    fn write(&self, relative: &str, text: &str, mode: u32) {
        let relative = relative.trim_start_matches('/');
        self.0.write(relative, text);
        self.0.chmod(relative, mode);
    }

    /// Places the plcd binary of this build at `relative`: a hard link, or a copy across file
    /// systems.
    fn plcd_at(&self, relative: &str) {
        let path = self.path(relative);
        fs::create_dir_all(path.parent().unwrap()).unwrap();
        let built = Path::new(env!("CARGO_BIN_EXE_plcd"));
        if fs::hard_link(built, &path).is_err() {
            fs::copy(built, &path).unwrap();
        }
    }
}

/// Whether `program` can be run: found on PATH and answering `--version`.
fn available(program: &str) -> Result<(), String> {
    match Command::new(program).arg("--version").output() {
        Ok(out) if out.status.success() => Ok(()),
        Ok(out) => Err(format!("`{program} --version` failed: {}", out.status)),
        Err(e) => Err(format!("{program} not available: {e}")),
    }
}

/// Whether `program` can be run here; when not, the running test reports a skip of what needs
/// it, or fails when [`REQUIRE`] is set.
fn have(program: &str) -> bool {
    match available(program) {
        Ok(()) => true,
        Err(reason) => {
            harness::skip::skip(Some(REQUIRE), &reason);
            false
        }
    }
}

fn text(out: &Output) -> String {
    format!(
        "status {}\n--- stdout\n{}--- stderr\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// A root for `systemd-analyze verify --root=`: verify loads the unit from the tree, requires
/// the executables of its command lines to exist there, and needs the units it requires by
/// default dependencies (sysinit.target, stubbed).
fn verify_root(name: &str, unit_text: &str) -> Scratch {
    let root = Scratch::new(name);
    root.write("etc/systemd/system/plcd.service", unit_text, 0o644);
    root.write("usr/lib/systemd/system/sysinit.target", "[Unit]\nDescription=stub\n", 0o644);
    root.write("bin/kill", "#!/bin/sh\nexit 0\n", 0o755);
    root
}

fn verify(root: &Scratch) -> Output {
    Command::new("systemd-analyze")
        .arg("verify")
        .arg(format!("--root={}", root.root().display()))
        .arg("plcd.service")
        .output()
        .expect("systemd-analyze verify")
}

fn assert_clean(out: &Output) {
    // Unknown keys and bad values are warnings with exit status 0: "clean" means silent.
    assert!(
        out.status.success() && out.stdout.is_empty() && out.stderr.is_empty(),
        "systemd-analyze verify is not clean:\n{}",
        text(out)
    );
}

#[test]
fn the_unit_passes_systemd_analyze_verify() {
    if !have("systemd-analyze") {
        return;
    }
    let unit = fs::read_to_string(unit_file()).unwrap();
    let root = verify_root("verify", &unit);
    root.plcd_at("usr/local/bin/plcd");
    assert_clean(&verify(&root));

    // The check is real: without the binary ExecStart names, verify complains.
    fs::remove_file(root.path("usr/local/bin/plcd")).unwrap();
    let out = verify(&root);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("/usr/local/bin/plcd"),
        "verify did not notice the missing binary:\n{}",
        text(&out)
    );
}

#[test]
fn retained_memory_has_a_state_directory_under_the_full_hardening() {
    // The daemon writes its retain files to $STATE_DIRECTORY (docs/RETAIN.md), which systemd
    // sets from StateDirectory=; everything else stays read-only.
    let unit = fs::read_to_string(unit_file()).unwrap();
    let lines: Vec<&str> = unit.lines().map(str::trim).collect();
    for directive in ["StateDirectory=plcd", "StateDirectoryMode=0750", "ProtectSystem=strict"] {
        assert!(lines.contains(&directive), "the unit lacks {directive}");
    }
    assert!(
        !lines.iter().any(|l| l.starts_with("ReadWritePaths=")),
        "no other writable path: the state directory is the one place the daemon writes"
    );
}

/// `systemd-analyze security --offline=true` of the unit installed in `root`, its drop-ins
/// included.
fn security_in(root: &Scratch) -> Output {
    Command::new("systemd-analyze")
        .args(["security", "--offline=true", "--no-pager"])
        .arg(format!("--root={}", root.root().display()))
        .arg("plcd.service")
        .output()
        .expect("systemd-analyze security")
}

#[test]
fn each_example_drop_in_keeps_the_unit_clean_and_at_most_2_0() {
    if !have("systemd-analyze") {
        return;
    }
    let unit = fs::read_to_string(unit_file()).unwrap();
    let mut seen = 0;
    for entry in fs::read_dir(repo().join("systemd/drop-ins")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        if !name.ends_with(".conf") {
            continue;
        }
        seen += 1;
        let root = verify_root(&format!("drop-in-{name}"), &unit);
        root.plcd_at("usr/local/bin/plcd");
        let drop_in = fs::read_to_string(&path).unwrap();
        root.write(&format!("etc/systemd/system/plcd.service.d/{name}"), &drop_in, 0o644);
        let out = verify(&root);
        assert!(
            out.status.success() && out.stdout.is_empty() && out.stderr.is_empty(),
            "with {name}, systemd-analyze verify is not clean:\n{}",
            text(&out)
        );
        let out = security_in(&root);
        let level = exposure(&String::from_utf8_lossy(&out.stdout))
            .unwrap_or_else(|| panic!("with {name}, no exposure level:\n{}", text(&out)));
        assert!(level <= MAX_EXPOSURE, "with {name}, exposure {level}:\n{}", text(&out));
        eprintln!("with drop-in {name}: exposure {level:.1}");
    }
    assert!(seen >= 3, "the example drop-ins are missing");
}

/// The "Overall exposure level" of `systemd-analyze security` output.
fn exposure(output: &str) -> Option<f64> {
    let line = output.lines().find(|l| l.contains("Overall exposure level"))?;
    line.split(':').nth(1)?.split_whitespace().next()?.parse().ok()
}

#[test]
fn the_exposure_is_at_most_2_0() {
    if !have("systemd-analyze") {
        return;
    }
    let out = Command::new("systemd-analyze")
        .args(["security", "--offline=true", "--no-pager"])
        .arg(unit_file())
        .output()
        .expect("systemd-analyze security");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let level = exposure(&stdout)
        .unwrap_or_else(|| panic!("no overall exposure level in the output:\n{}", text(&out)));
    assert!(level <= MAX_EXPOSURE, "exposure {level} > {MAX_EXPOSURE}:\n{}", text(&out));
    eprintln!("systemd-analyze security --offline=true: exposure {level:.1}");
}

#[test]
fn exposure_lines_parse() {
    let sample = "✗ UMask=   Files created by service are group-readable   0.1\n\n\
                  → Overall exposure level for plcd.service: 1.0 OK 🙂\n";
    assert_eq!(exposure(sample), Some(1.0));
    assert_eq!(exposure("nothing here"), None);
}

/// Every system call plcd makes (strace -f of `plcd run` on the example project, with
/// NOTIFY_SOCKET, WATCHDOG_USEC, [rt] *_cpus, a SIGHUP and a SIGTERM, on x86_64), the ones of the
/// gpiocdev backend and of other architectures' libc, and the ones of the control socket and
/// the retained memory.
const PLCD_SYSCALLS: &[&str] = &[
    // the runtime: glibc, the Rust standard library, threads
    "access",
    "arch_prctl",
    "brk",
    "clone",
    "clone3",
    "close",
    "execve",
    "exit",
    "exit_group",
    "futex",
    "getpid",
    "getrandom",
    "gettid",
    "madvise",
    "mmap",
    "mprotect",
    "munmap",
    "prctl",
    "prlimit64",
    "rseq",
    "set_robust_list",
    "set_tid_address",
    "sigaltstack",
    "restart_syscall",
    "clock_gettime",
    "clock_nanosleep",
    "nanosleep",
    "sched_getaffinity",
    "sched_yield",
    // files: the project, /proc/self/status, /dev for the GPIO chips
    "openat",
    "read",
    "pread64",
    "write",
    "fcntl",
    "newfstatat",
    "statx",
    "lseek",
    "getdents64",
    "readlink",
    "readlinkat",
    // signals
    "rt_sigaction",
    "rt_sigprocmask",
    "rt_sigreturn",
    // real time: SCHED_FIFO, CPU affinity, locked memory
    "sched_setscheduler",
    "sched_setaffinity",
    "mlockall",
    // timers and waiting
    "timerfd_create",
    "timerfd_settime",
    "timerfd_gettime",
    "eventfd2",
    "epoll_create1",
    "epoll_ctl",
    "epoll_wait",
    "epoll_pwait",
    "poll",
    "ppoll",
    // GPIO character devices
    "ioctl",
    // the signal self-pipe and the notification socket
    "socketpair",
    "socket",
    "connect",
    "sendto",
    "sendmsg",
    "recvfrom",
    "recvmsg",
    // the control socket (/run/plcd/plcd.sock) and retained memory (/var/lib/plcd: create the
    // directory, write a temporary file, fsync it, rename it, fsync the directory)
    "bind",
    "listen",
    "accept4",
    "getsockopt",
    "setsockopt",
    "unlinkat",
    "fchmod",
    "fchmodat",
    "ftruncate",
    "fsync",
    "fdatasync",
    "renameat",
    "renameat2",
    "mkdirat",
    // serial ports ([modbus.rtu]): opened exclusively (TIOCEXCL and flock), termios by ioctl
    "flock",
];

/// The groups `systemd-analyze syscall-filter` lists, each with its members (calls or groups).
fn syscall_groups(listing: &str) -> Vec<(String, Vec<String>)> {
    let mut groups: Vec<(String, Vec<String>)> = Vec::new();
    for line in listing.lines() {
        if line.starts_with('@') {
            groups.push((line.trim().to_string(), Vec::new()));
        } else if line.starts_with(char::is_whitespace) {
            let item = line.trim();
            if let (Some((_, members)), false) = (groups.last_mut(), item.starts_with('#')) {
                if !item.is_empty() {
                    members.push(item.to_string());
                }
            }
        } else if line.trim().is_empty() {
            continue;
        } else {
            // "# Unlisted System Calls ...": no more groups.
            break;
        }
    }
    groups
}

fn expand(item: &str, groups: &[(String, Vec<String>)], out: &mut BTreeSet<String>) {
    match groups.iter().find(|(name, _)| name == item) {
        Some((_, members)) => members.iter().for_each(|m| expand(m, groups, out)),
        None if item.starts_with('@') => panic!("unknown system call group {item}"),
        None => {
            out.insert(item.to_string());
        }
    }
}

/// The system calls the unit's `SystemCallFilter=` lines allow, merged as systemd merges them
/// when the first line is an allow list: later plain lines add, `~` lines remove.
fn allowed_syscalls(unit: &str, groups: &[(String, Vec<String>)]) -> BTreeSet<String> {
    let mut allowed = BTreeSet::new();
    let mut lines = unit.lines().filter_map(|l| l.trim().strip_prefix("SystemCallFilter="));
    let first = lines.next().expect("the unit has a SystemCallFilter=");
    assert!(!first.starts_with('~'), "the first SystemCallFilter= must be an allow list");
    for line in std::iter::once(first).chain(lines) {
        let (deny, items) = match line.strip_prefix('~') {
            Some(rest) => (true, rest),
            None => (false, line),
        };
        let mut set = BTreeSet::new();
        items.split_whitespace().for_each(|item| expand(item, groups, &mut set));
        if deny {
            allowed.retain(|call| !set.contains(call));
        } else {
            allowed.extend(set);
        }
    }
    allowed
}

#[test]
fn the_system_call_filter_lets_every_plcd_call_through() {
    if !have("systemd-analyze") {
        return;
    }
    let out = Command::new("systemd-analyze")
        .args(["syscall-filter", "--no-pager"])
        .output()
        .expect("systemd-analyze syscall-filter");
    assert!(out.status.success(), "{}", text(&out));
    let groups = syscall_groups(&String::from_utf8_lossy(&out.stdout));
    assert!(groups.iter().any(|(name, _)| name == "@system-service"), "{}", text(&out));

    let unit = fs::read_to_string(unit_file()).unwrap();
    let allowed = allowed_syscalls(&unit, &groups);
    let refused: Vec<&str> =
        PLCD_SYSCALLS.iter().copied().filter(|call| !allowed.contains(*call)).collect();
    assert!(refused.is_empty(), "the unit's SystemCallFilter= refuses {refused:?}");

    // And it is a filter: privileged calls and the resource calls plcd does not make stay out.
    for call in ["setuid", "chown", "mount", "reboot", "setrlimit", "mlock", "ioprio_set"] {
        assert!(!allowed.contains(call), "{call} is allowed");
    }
}

#[test]
fn filter_lines_merge_as_systemd_merges_them() {
    let groups = vec![
        ("@a".to_string(), vec!["one".to_string(), "two".to_string(), "@b".to_string()]),
        ("@b".to_string(), vec!["three".to_string(), "four".to_string()]),
    ];
    let unit = "SystemCallFilter=@a\nSystemCallFilter=~@b two\nSystemCallFilter=four\n";
    let allowed: Vec<String> = allowed_syscalls(unit, &groups).into_iter().collect();
    assert_eq!(allowed, ["four", "one"]);
    let listing = "@a\n    # comment\n    one\n    @b\n\n@b\n    three\n\n# Unlisted\n#   x\n";
    let parsed = syscall_groups(listing);
    assert_eq!(parsed[0], ("@a".to_string(), vec!["one".to_string(), "@b".to_string()]));
    assert_eq!(parsed.len(), 2);
}

// ---------------------------------------------------------------------------------------------
// systemd/install

/// Every file the install script places, relative to the target root, for `prefix`.
fn installed_files(prefix: &str) -> Vec<String> {
    let mut files: Vec<String> = [
        "/etc/systemd/system/plcd.service",
        "/etc/udev/rules.d/60-plcd-gpio.rules",
        "/etc/sysusers.d/plcd.conf",
        "/etc/plcd/plcd.toml",
        "/etc/plcd/stimulus.csv",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    files.push(format!("{prefix}/bin/plcd"));
    files.push(format!("{prefix}/bin/plcctl"));
    for doc in ["DEPLOY.md", "DAEMON.md", "CONFIG.md", "CONTROL.md", "PLCCTL.md"] {
        files.push(format!("{prefix}/share/doc/plcd/{doc}"));
    }
    for entry in fs::read_dir(repo().join("etc/programs")).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        if name.ends_with(".il") || name.ends_with(".st") {
            files.push(format!("/etc/plcd/programs/{name}"));
        }
    }
    files
}

fn install(args: &[&str]) -> Output {
    Command::new("bash")
        .arg(repo().join("systemd/install"))
        .args(args)
        .env_remove("CARGO_TARGET_DIR")
        .output()
        .expect("bash systemd/install")
}

fn tree(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(tree(&path));
        }
        out.push(path);
    }
    out
}

#[test]
fn the_install_dry_run_names_every_file_and_changes_nothing() {
    let root = Scratch::new("dry-run");
    let root_arg = root.root().to_str().unwrap();
    let out = install(&["--dry-run", "--root", root_arg, "--binary", env!("CARGO_BIN_EXE_plcd")]);
    assert!(out.status.success(), "{}", text(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    for file in installed_files("/usr/local") {
        let target = format!("{root_arg}{file}");
        assert!(
            stdout.lines().any(|l| l.contains("would install") && l.contains(&target)),
            "the dry run does not name {target}:\n{}",
            text(&out)
        );
    }
    assert!(tree(root.root()).is_empty(), "a dry run changed {:?}", tree(root.root()));

    // The prefix moves the binary and the documentation.
    let out = install(&["--dry-run", "--root", root_arg, "--prefix", "/opt/plcd"]);
    assert!(out.status.success(), "{}", text(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains(&format!("{root_arg}/opt/plcd/bin/plcd")), "{}", text(&out));
    assert!(stdout.contains(&format!("{root_arg}/opt/plcd/share/doc/plcd/DEPLOY.md")));
}

#[test]
fn the_install_script_refuses_bad_arguments() {
    for args in [&["--prefix", "relative"][..], &["--prefix", "/has space"], &["--bogus"]] {
        let out = install(&[&["--dry-run"], args].concat());
        assert!(!out.status.success(), "{args:?} accepted:\n{}", text(&out));
        assert!(String::from_utf8_lossy(&out.stderr).contains("error:"), "{}", text(&out));
    }
}

#[test]
fn the_install_script_installs_into_a_root_idempotently_and_uninstalls() {
    if !have("systemd-sysusers") {
        return;
    }
    let root = Scratch::new("install");
    let root_arg = root.root().to_str().unwrap();
    let args =
        ["--root", root_arg, "--prefix", "/opt/plcd", "--binary", env!("CARGO_BIN_EXE_plcd")];

    let first = install(&args);
    assert!(first.status.success(), "{}", text(&first));
    for file in installed_files("/opt/plcd") {
        assert!(root.path(&file).is_file(), "{file} not installed:\n{}", text(&first));
    }
    let passwd = fs::read_to_string(root.path("etc/passwd")).unwrap();
    let group = fs::read_to_string(root.path("etc/group")).unwrap();
    assert!(passwd.lines().any(|l| l.starts_with("plcd:")), "{passwd}");
    assert!(group.lines().any(|l| l.starts_with("gpio:")), "{group}");
    let unit = fs::read_to_string(root.path("etc/systemd/system/plcd.service")).unwrap();
    assert!(unit.contains("ExecStart=/opt/plcd/bin/plcd run --config /etc/plcd/plcd.toml"));
    assert!(!unit.contains("/usr/local"), "the prefix was not applied:\n{unit}");
    let mode = |file: &str| fs::metadata(root.path(file)).unwrap().permissions().mode() & 0o7777;
    assert_eq!(mode("opt/plcd/bin/plcd"), 0o755);
    assert_eq!(mode("etc/plcd/plcd.toml"), 0o640);
    assert_eq!(mode("etc/plcd"), 0o755);

    // A second run changes nothing; a user's config is never overwritten.
    root.write("etc/plcd/plcd.toml", "# mine\n", 0o640);
    fs::remove_file(root.path("etc/plcd/programs/main.il")).unwrap();
    let second = install(&args);
    assert!(second.status.success(), "{}", text(&second));
    let stdout = String::from_utf8_lossy(&second.stdout);
    assert!(!stdout.contains("  installed "), "the second run installed again:\n{stdout}");
    assert!(stdout.contains("kept"), "{stdout}");
    assert_eq!(fs::read_to_string(root.path("etc/plcd/plcd.toml")).unwrap(), "# mine\n");
    assert!(!root.path("etc/plcd/programs/main.il").exists(), "a user's project was completed");

    // The installed unit, with its prefix, passes verify in that tree.
    if have("systemd-analyze") {
        root.write("usr/lib/systemd/system/sysinit.target", "[Unit]\nDescription=stub\n", 0o644);
        root.write("bin/kill", "#!/bin/sh\nexit 0\n", 0o755);
        assert_clean(&verify(&root));
    }

    let removed = install(&["--uninstall", "--root", root_arg, "--prefix", "/opt/plcd"]);
    assert!(removed.status.success(), "{}", text(&removed));
    for file in ["opt/plcd/bin/plcd", "etc/systemd/system/plcd.service", "etc/sysusers.d/plcd.conf"]
    {
        assert!(!root.path(file).exists(), "{file} still there:\n{}", text(&removed));
    }
    assert!(!root.path("etc/udev/rules.d/60-plcd-gpio.rules").exists());
    assert!(!root.path("opt/plcd/share/doc/plcd").exists(), "{}", text(&removed));
    assert!(root.path("etc/plcd/plcd.toml").exists(), "uninstall removed the project");
}

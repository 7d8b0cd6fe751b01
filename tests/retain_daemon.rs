//! Retained memory through the real `plcd run`: `kill -9` at random moments 200 times while the
//! program counts every scan (the values on disk never go back past what was acknowledged and
//! are never garbage), warm and cold restarts, `plcctl reset --cold`, a reload changing
//! `[retain]`, files of other ranges, a full file system and a read-only one.
//!
//! What the writer acknowledged is what the generation files hold: a file exists only after
//! its write, fsync and rename, so reading and decoding the newest intact one
//! ([`plcd::services::retain::newest_in`]) is reading the last acknowledged write. Every assertion is an
//! ordering or a lower bound; waits are for an event, bounded by a generous patience.

mod harness;

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use nix::sys::signal::Signal;
use plcd::services::retain::{newest_in, Generation};

use harness::daemon::{Daemon, Project};

/// The log file of every start of a project's daemon: appended to, it survives `kill -9`.
const LOG: &str = "plcd.log";

/// A project of these tests: its retain files go to `retain/`, its log to [`LOG`].
struct Retained(Project);

impl Retained {
    fn new(name: &str) -> Retained {
        Retained(Project::new(&format!("retain-daemon-{name}"), &[]))
    }

    fn write(&self, file: &str, text: &str) {
        self.0.write(file, text);
    }

    fn retain_dir(&self) -> PathBuf {
        self.0.path("retain")
    }

    fn log(&self) -> String {
        harness::log::Log::File(self.0.path(LOG)).text()
    }

    /// Starts `plcd run`, its log appended to [`LOG`].
    fn start(&self) -> Daemon {
        self.0.start_logging_to(LOG)
    }

    /// Waits until the newest generation on disk satisfies `done`; it.
    fn wait_for_generation(&self, what: &str, done: impl Fn(&Generation) -> bool) -> Generation {
        harness::log::wait_for_generation(&self.retain_dir(), || self.log(), what, done)
    }
}

fn config(retain: &str, control: bool) -> String {
    let control = if control { "socket = \"plcd.sock\"" } else { "enabled = false" };
    format!(
        "[plc]\nscan_period_ms = 1\n\n[rt]\npolicy = \"other\"\nlock_memory = false\n\n\
         [control]\n{control}\n\n[retain]\ndir = \"retain\"\n{retain}\n\n\
         [[program]]\nfile = \"main.il\"\n"
    )
}

/// Counts every scan in K001:K000 and in D00001:D00000, 32 bits each.
const COUNT_SCANS: &str = "INC K000\nLOAD= K000 0\nINC K001\nLOAD _ON\nINC D00000\n\
                           LOAD= D00000 0\nINC D00001\nEND\n";

/// The two counters of a generation of COUNT_SCANS (K000.. are the first words, the D range
/// follows the 256 K words).
fn counters(g: &Generation) -> (u32, u32) {
    let w = &g.words;
    (u32::from(w[1]) << 16 | u32::from(w[0]), u32::from(w[257]) << 16 | u32::from(w[256]))
}

/// Not garbage: both counters count the same scans, in one consistent END snapshot.
fn checked(g: &Generation, when: &str) -> u32 {
    let (k, d) = counters(g);
    assert_eq!(k, d, "{when}: seq {}: K and D disagree: garbage or a torn snapshot", g.seq);
    k
}

#[test]
fn kill_9_at_random_moments_never_loses_an_acknowledged_write() {
    let project = Retained::new("kill9");
    project.write("plcd.toml", &config("ranges = [\"D00000-D00001\"]\ninterval_ms = 10", false));
    project.write("main.il", COUNT_SCANS);
    let mut rng = 0x9E37_79B9_7F4A_7C15_u64;
    let mut random = move |below: u64| {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng % below
    };
    let (mut acked_seq, mut acked) = (0u64, 0u32);
    let mut progressed = 0;
    // Rounds that surely restored: they started with a generation on disk and waited for a
    // write of their own, which comes after the restore. The other rounds restore only if the
    // kill comes late enough, which a loaded or emulated machine makes rare.
    let mut sure_restores = 0;
    // The kills fall anywhere in the first 120 ms of a run natively: through the start, the
    // restore and the first writes. Emulated, a start takes longer, and so does the window.
    let window_us = 120_000 * u64::from(harness::runner::slowdown());
    for round in 0..200 {
        let had_generation = newest_in(&project.retain_dir()).is_some();
        let daemon = project.start();
        if round % 4 == 0 {
            sure_restores += u32::from(had_generation);
            // Every 4th round waits for a write of this run, so the test always progresses.
            project.wait_for_generation("a write of this run", |g| g.seq > acked_seq);
        }
        std::thread::sleep(Duration::from_micros(random(window_us)));
        if let Some(g) = newest_in(&project.retain_dir()) {
            let value = checked(&g, "before the kill");
            assert!(g.seq >= acked_seq, "round {round}: seq {} went back from {acked_seq}", g.seq);
            assert!(value >= acked, "round {round}: {value} went back past acknowledged {acked}");
        }
        daemon.kill9();
        // What the killed daemon acknowledged last: the next run starts from at least this.
        if let Some(g) = newest_in(&project.retain_dir()) {
            let value = checked(&g, "after the kill");
            assert!(value >= acked, "round {round}: {value} went back past acknowledged {acked}");
            assert!(g.seq >= acked_seq);
            if g.seq > acked_seq {
                progressed += 1;
            }
            (acked_seq, acked) = (g.seq, value);
        }
    }
    assert!(progressed >= 50, "only {progressed} rounds wrote anything");
    assert!(acked > 0);
    let log = project.log();
    assert!(!log.contains("corrupt") && !log.contains("not restored"), "{log}");
    let restores = log.matches("retain: restored generation").count();
    assert!(
        restores >= sure_restores as usize && sure_restores >= 45,
        "{restores} restores logged, {sure_restores} rounds that surely restored"
    );
}

/// Counts RUN starts: K000 and D00000 grow by one at each RUN start.
const COUNT_RUNS: &str = "LOAD _1ON\nINC K000\nINC D00000\nEND\n";

fn runs(g: &Generation) -> (u16, u16) {
    (g.words[0], g.words[256])
}

#[test]
fn warm_restarts_keep_counting_a_cold_one_clears_everything() {
    let project = Retained::new("warmcold");
    let warm = config("ranges = [\"D00000-D00000\"]\ninterval_ms = 10", false);
    project.write("plcd.toml", &warm);
    project.write("main.il", COUNT_RUNS);
    for n in 1..=3u16 {
        let daemon = project.start();
        project.wait_for_generation("this start counted", |g| runs(g) == (n, n));
        assert_eq!(daemon.stop().0, 0);
        assert_eq!(runs(&newest_in(&project.retain_dir()).unwrap()), (n, n));
    }
    project.write(
        "plcd.toml",
        &warm.replace("interval_ms = 10", "interval_ms = 10\nrestart = \"cold\""),
    );
    let seq = newest_in(&project.retain_dir()).unwrap().seq;
    let daemon = project.start();
    // A write may come before the first scan (the cleared values, where a start is slow): the
    // first one with a RUN start counted is the one to judge.
    let g =
        project.wait_for_generation("the cold start's RUN", |g| g.seq > seq && runs(g) != (0, 0));
    assert_eq!(runs(&g), (1, 1), "cold: K and D started cleared");
    assert_eq!(daemon.stop().0, 0);
    assert!(project.log().contains("restart = \"cold\""));
    project.write("plcd.toml", &warm);
    let daemon = project.start();
    project.wait_for_generation("warm again, from the cold run's values", |g| runs(g) == (2, 2));
    assert_eq!(daemon.stop().0, 0);
}

#[test]
fn reset_cold_empties_the_persisted_image_and_a_reload_may_not_change_retain() {
    let project = Retained::new("resetcold");
    let text = config("ranges = [\"D00000-D00000\"]\ninterval_ms = 10", true);
    project.write("plcd.toml", &text);
    project.write("main.il", COUNT_RUNS);
    let daemon = project.start();
    project.wait_for_generation("the first RUN", |g| runs(g) == (1, 1));
    let plcctl = |args: &[&str]| {
        let out = project.0.plcctl(args);
        assert!(out.status.success(), "plcctl {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    plcctl(&["reset", "--cold"]);
    project.wait_for_generation("the cleared values", |g| runs(g) == (0, 0));
    plcctl(&["run"]);
    project.wait_for_generation("RUN again from zero", |g| runs(g) == (1, 1));

    // A reload that changes [retain] is refused; the running project goes on.
    project.write("plcd.toml", &text.replace("D00000-D00000", "D00000-D00001"));
    daemon.signal(Signal::SIGHUP);
    daemon.wait_for("reload refused: [retain] changed");
    plcctl(&["stop"]);
    plcctl(&["run"]);
    project.wait_for_generation("the old project still counts", |g| runs(g) == (2, 2));
    assert_eq!(daemon.stop().0, 0);
}

#[test]
fn files_of_other_ranges_are_set_aside_and_the_daemon_starts_cleared() {
    let project = Retained::new("mismatch");
    project.write("plcd.toml", &config("ranges = [\"D00000-D00000\"]\ninterval_ms = 10", false));
    project.write("main.il", COUNT_RUNS);
    let daemon = project.start();
    project.wait_for_generation("the first RUN", |g| runs(g) == (1, 1));
    assert_eq!(daemon.stop().0, 0);
    project.write("plcd.toml", &config("ranges = [\"D00000-D00009\"]\ninterval_ms = 10", false));
    let daemon = project.start();
    // A write may come before the first scan (the cleared values, where a start is slow): the
    // first one with the RUN start counted is the one to judge, and the last one too.
    let g = project.wait_for_generation("the RUN start with the new ranges", |g| {
        g.words.len() == 266 && runs(g) != (0, 0)
    });
    assert_eq!(runs(&g), (1, 1), "started cleared, not from the other file's 1");
    assert_eq!(daemon.stop().0, 0);
    assert_eq!(runs(&newest_in(&project.retain_dir()).unwrap()), (1, 1), "at the stop");
    let log = project.log();
    assert!(
        log.contains(
            "not restored: the file retains K000-K255, D00000-D00000; the config retains \
                      K000-K255, D00000-D00009"
        ),
        "{log}"
    );
    let kept: Vec<String> = std::fs::read_dir(project.retain_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.contains(".mismatch"))
        .collect();
    assert!(!kept.is_empty(), "the old files are kept aside");
    assert!(log.contains(".mismatch"), "and the log says where");
}

/// A tmpfs mounted on the project's retain directory, unmounted on drop.
struct Tmpfs(PathBuf);

impl Tmpfs {
    /// None (after a skip line saying why) when mounting is not permitted here.
    fn mount(dir: &Path, size: &str) -> Option<Tmpfs> {
        std::fs::create_dir_all(dir).unwrap();
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size},mode=0755"), "tmpfs"])
            .arg(dir)
            .output();
        match out {
            Ok(out) if out.status.success() => Some(Tmpfs(dir.to_path_buf())),
            Ok(out) => {
                let why = String::from_utf8_lossy(&out.stderr);
                harness::skip::skip(None, &format!("cannot mount a tmpfs: {}", why.trim()));
                None
            }
            Err(e) => {
                harness::skip::skip(None, &format!("cannot run mount: {e}"));
                None
            }
        }
    }

    fn remount(&self, options: &str) {
        let status = Command::new("mount")
            .args(["-o", &format!("remount,{options}")])
            .arg(&self.0)
            .status()
            .unwrap();
        assert!(status.success());
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// The daemon runs while the writes fail, the failure is logged once, and writing resumes
/// once `heal` ran.
fn survives_failing_writes(
    project: &Retained,
    error: &str,
    break_it: impl FnOnce(),
    heal: impl FnOnce(),
) {
    let daemon = project.start();
    let before = project.wait_for_generation("a first write", |g| checked(g, "first") > 0);
    break_it();
    daemon.wait_for(error);
    let seq_when_broken = newest_in(&project.retain_dir()).unwrap().seq;
    // Many intervals (10 ms) pass with the writes failing; the writer tries at each.
    std::thread::sleep(Duration::from_millis(300));
    assert!(
        newest_in(&project.retain_dir()).unwrap().seq == seq_when_broken,
        "the last good generation stays on disk"
    );
    heal();
    let healed = daemon.wait_for_line("retain: writing works again");
    let after = project.wait_for_generation("a write after healing", |g| g.seq > seq_when_broken);
    assert!(
        checked(&after, "healed") > checked(&before, "before"),
        "the PLC kept counting while the writes failed"
    );
    // Every attempt uses up a sequence number, a failed one too: the first write after healing
    // says how often the writer tried while it could not write.
    let first_seq: u64 = healed
        .rsplit_once("(seq ")
        .and_then(|(_, rest)| rest.strip_suffix(')'))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no sequence number in {healed:?}"));
    let attempts = first_seq - seq_when_broken - 1;
    assert!(attempts >= 2, "the writer tried {attempts} time(s) while the writes failed");
    let log = project.log();
    assert_eq!(
        log.matches(error).count(),
        1,
        "logged once, not at each of {attempts} attempts:\n{log}"
    );
    assert_eq!(daemon.stop().0, 0);
}

#[test]
fn a_full_file_system_is_logged_once_and_the_writer_retries() {
    let project = Retained::new("full");
    project.write("plcd.toml", &config("ranges = [\"D00000-D00001\"]\ninterval_ms = 10", false));
    project.write("main.il", COUNT_SCANS);
    let Some(_tmpfs) = Tmpfs::mount(&project.retain_dir(), "64k") else { return };
    let filler = project.retain_dir().join("filler");
    survives_failing_writes(
        &project,
        "No space left on device",
        || {
            let mut file = File::create(&filler).unwrap();
            let block = vec![0xA5u8; 4096];
            while std::io::Write::write_all(&mut file, &block).is_ok() {}
            // What a failed block left: that one byte fits or not, the file system is full.
            let _ = std::io::Write::write_all(&mut file, &[0]);
        },
        || std::fs::remove_file(&filler).unwrap(),
    );
}

#[test]
fn a_read_only_directory_is_logged_once_and_the_writer_retries() {
    let project = Retained::new("readonly");
    project.write("plcd.toml", &config("ranges = [\"D00000-D00001\"]\ninterval_ms = 10", false));
    project.write("main.il", COUNT_SCANS);
    if nix::unistd::geteuid().is_root() {
        // Root writes through file modes: a read-only mount it is.
        let Some(tmpfs) = Tmpfs::mount(&project.retain_dir(), "1m") else { return };
        survives_failing_writes(
            &project,
            "Read-only file system",
            || tmpfs.remount("ro"),
            || tmpfs.remount("rw"),
        );
    } else {
        use std::os::unix::fs::PermissionsExt;
        let dir = project.retain_dir();
        std::fs::create_dir_all(&dir).unwrap();
        let mode = |m| std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(m)).unwrap();
        survives_failing_writes(&project, "Permission denied", || mode(0o555), || mode(0o755));
    }
}

//! The harness's own checks, where a mistake in it would make other tests pass or fail for the
//! wrong reason: a program built in a private directory (a clone under `mktemp -d`, mode 0700)
//! still runs as uid 65534 through [`harness::nobody`], and scratch directories are what they
//! claim.

mod harness;

use std::os::unix::fs::PermissionsExt;
use std::os::unix::process::CommandExt;
use std::process::Command;

use harness::daemon::plcd_binary;
use harness::nobody::{self, NOBODY};
use harness::tempdir::{others_can_reach, TempDir};

#[test]
fn a_program_in_a_private_directory_runs_as_nobody_through_the_harness() {
    if let Some(reason) = nobody::unavailable() {
        return harness::skip::skip(None, &reason);
    }
    // A build in a clone under a mode 0700 directory, as `mktemp -d` makes them.
    let private = TempDir::new("private-clone");
    let built = private.join("target/debug/plcd");
    std::fs::create_dir_all(built.parent().unwrap()).unwrap();
    std::fs::copy(plcd_binary(), &built).unwrap();
    private.chmod("", 0o700);
    assert!(others_can_reach(&built).is_err(), "{} is reachable", private.path().display());

    // Run from there, uid 65534 cannot even start it: the failure the harness exists to avoid.
    let direct = Command::new(&built)
        .arg("--version")
        .uid(NOBODY)
        .gid(NOBODY)
        .current_dir("/")
        .output()
        .expect_err("uid 65534 executed a program in a mode 0700 directory");
    assert_eq!(direct.kind(), std::io::ErrorKind::PermissionDenied, "{direct}");

    // Through the harness it runs, as uid 65534.
    let copy = nobody::Copy::of(&built);
    let mode = std::fs::metadata(copy.path()).unwrap().permissions().mode();
    assert_eq!(mode & 0o005, 0o005, "{:o} {}", mode, copy.path().display());
    others_can_reach(copy.path().parent().unwrap()).unwrap();
    let out = nobody::output(copy.command(NOBODY).arg("--version"));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("plcd "), "{out:?}");

    // The copy goes with its guard.
    let dir = copy.path().parent().unwrap().to_path_buf();
    drop(copy);
    assert!(!dir.exists(), "{} outlived its copy", dir.display());
}

#[test]
fn a_temp_dir_is_fresh_0755_and_removed_with_its_contents() {
    let a = TempDir::new("fresh");
    let b = TempDir::new("fresh");
    assert_ne!(a.path(), b.path(), "two directories of one name in one process");
    let mode = std::fs::metadata(a.path()).unwrap().permissions().mode();
    assert_eq!(mode & 0o7777, 0o755);
    assert_eq!(a.entries(), Vec::<String>::new());
    a.write("sub/file", "text");
    a.chmod("sub", 0o555);
    assert_eq!(a.entries(), ["sub"]);
    let path = a.path().to_path_buf();
    drop(a);
    assert!(!path.exists(), "{} was not removed", path.display());
    assert!(b.path().exists());
}

#[test]
fn a_directory_for_everyone_is_reachable_by_everyone() {
    let dir = TempDir::for_everyone("reachable");
    others_can_reach(dir.path()).unwrap();
    let private = TempDir::new("unreachable");
    private.write("inner/x", "");
    private.chmod("", 0o700);
    let error = others_can_reach(&private.join("inner")).unwrap_err();
    assert!(error.contains(&private.path().display().to_string()), "{error}");
    assert!(error.ends_with("mode 700"), "{error}");
}

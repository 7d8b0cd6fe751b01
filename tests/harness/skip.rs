//! Skipping a test where the machine lacks what it needs, visibly, and never where a
//! `PLCD_REQUIRE_*` variable says the suite must not skip.
//!
//! A skipped test passes, so a skip must be seen: the line goes straight to the stderr handle
//! (the test harness captures `println!`/`eprintln!` of passing tests), as one write so the
//! lines of tests running in parallel do not mix. With the variable set (to anything but empty
//! or `0`), the skip is a failure instead, so a suite that ran nothing cannot pass.

use std::io::Write;

/// Whether `var` is set to anything but empty or `0`.
pub fn required(var: &str) -> bool {
    std::env::var_os(var).is_some_and(|v| !v.is_empty() && v != "0")
}

/// Reports that the running test skips (part of) its checks because of `reason`; panics
/// instead when `require` names a variable that is set.
pub fn skip(require: Option<&str>, reason: &str) {
    if let Some(var) = require.filter(|var| required(var)) {
        panic!("{var} is set, so this may not be skipped: {reason}");
    }
    let line = format!("{}: skipped: {reason}\n", test_name());
    let _ = std::io::stderr().write_all(line.as_bytes());
}

/// The running test's name, as the test harness named its thread.
pub fn test_name() -> String {
    match std::thread::current().name() {
        Some(name) if name != "main" => name.to_string(),
        _ => "test".to_string(),
    }
}

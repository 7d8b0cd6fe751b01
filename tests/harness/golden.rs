//! Golden files: compare what a test produced with the file that says what it must be, or,
//! with `PLCD_BLESS=1`, rewrite the file instead (then `git diff` shows what changed).

use std::fs;
use std::io::Write;
use std::path::Path;

/// The variable that rewrites expected files instead of comparing them.
pub const BLESS: &str = "PLCD_BLESS";

/// Whether this run rewrites expected files.
pub fn bless() -> bool {
    super::skip::required(BLESS)
}

/// Compares `actual` with the file `expected`; `None` when they agree or the file was blessed,
/// else what differs.
pub fn compare_or_bless(expected: &Path, actual: &str) -> Option<String> {
    let old = fs::read_to_string(expected).unwrap_or_default();
    if old == actual {
        return None;
    }
    if bless() {
        fs::write(expected, actual).unwrap_or_else(|e| panic!("{}: {e}", expected.display()));
        let line = format!("{BLESS}: rewrote {}\n", expected.display());
        let _ = std::io::stderr().write_all(line.as_bytes());
        return None;
    }
    Some(format!(
        "{} ({BLESS}=1 rewrites it):\n--- expected\n{old}--- actual\n{actual}",
        expected.display()
    ))
}

/// Whether `message` is `template` with each `{}` filled in: how a diagnostic golden case is
/// matched to the message template of the source that produced it.
pub fn matches_template(template: &str, message: &str) -> bool {
    let parts: Vec<&str> = template.split("{}").collect();
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if parts.len() == 1 {
        return template == message;
    }
    if !message.starts_with(first)
        || !message.ends_with(last)
        || message.len() < first.len() + last.len()
    {
        return false;
    }
    let mut rest = &message[first.len()..message.len() - last.len()];
    for middle in &parts[1..parts.len() - 1] {
        match rest.find(middle) {
            Some(at) => rest = &rest[at + middle.len()..],
            None => return false,
        }
    }
    true
}

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

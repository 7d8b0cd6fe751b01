//! Result fragments for BENCHMARKS.md and the one-line description of the machine they were
//! measured on.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The machine, as one line: CPU model and count, caches, kernel, real-time capability and
/// rustc version, e.g. `2 × AMD EPYC (L2 2 MiB, L3 32 MiB), Linux 6.18.44 PREEMPT_DYNAMIC,
/// rustc 1.95.0`.
pub fn machine() -> String {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = cpuinfo
        .lines()
        .find_map(|l| l.strip_prefix("model name").and_then(|r| r.split_once(':')))
        .map(|(_, m)| m.trim().to_string())
        .unwrap_or_else(|| std::env::consts::ARCH.to_string());
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    let cache = |index: u32| {
        let dir = format!("/sys/devices/system/cpu/cpu0/cache/index{index}");
        let level = std::fs::read_to_string(format!("{dir}/level")).ok()?;
        let size = std::fs::read_to_string(format!("{dir}/size")).ok()?;
        let size = size.trim();
        let size = match size.strip_suffix('K').and_then(|k| k.parse::<u64>().ok()) {
            Some(k) if k >= 1024 && k % 1024 == 0 => format!("{} MiB", k / 1024),
            Some(k) => format!("{k} KiB"),
            None => size.to_string(),
        };
        Some(format!("L{} {size}", level.trim()))
    };
    let caches: Vec<String> = (2..=3).filter_map(cache).collect();
    let uname = nix::sys::utsname::uname().ok();
    let release = uname.as_ref().map_or(String::new(), |u| u.release().to_string_lossy().into());
    let version = uname.as_ref().map_or(String::new(), |u| u.version().to_string_lossy().into());
    let preempt = ["PREEMPT_RT", "PREEMPT_DYNAMIC", "PREEMPT"]
        .into_iter()
        .find(|p| version.contains(p))
        .unwrap_or("no preemption");
    let rustc = std::process::Command::new("rustc")
        .arg("--version")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .and_then(|v| v.split_whitespace().nth(1).map(str::to_string))
        .map_or(String::new(), |v| format!(", rustc {v}"));
    let mut line = format!("{cpus} × {model}");
    if !caches.is_empty() {
        let _ = write!(line, " ({})", caches.join(", "));
    }
    let _ = write!(line, ", Linux {release} {preempt}{rustc}");
    line
}

/// Cargo's target directory: `$CARGO_TARGET_DIR`, else `target` under the current directory
/// (cargo runs benches from the package root).
pub fn target_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| "target".into(), PathBuf::from)
}

/// Criterion's median for `group/id` in ns (its `new/estimates.json` under the target
/// directory), if a run started at `since` produced it: a figure of an earlier run is `None`.
pub fn criterion_median_ns(group: &str, id: &str, since: std::time::SystemTime) -> Option<f64> {
    let path = target_dir().join("criterion").join(group).join(id).join("new/estimates.json");
    let modified = std::fs::metadata(&path).and_then(|m| m.modified()).ok()?;
    if modified < since {
        return None;
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
    json["median"]["point_estimate"].as_f64()
}

/// Where fragments go: `bench-results` in the target directory.
pub fn results_dir() -> PathBuf {
    target_dir().join("bench-results")
}

/// A Markdown fragment under construction: a section body for BENCHMARKS.md.
#[derive(Debug, Default)]
pub struct Fragment {
    text: String,
}

impl Fragment {
    /// Starts with the command that produces it, the machine and the date.
    pub fn new(command: &str) -> Fragment {
        let mut f = Fragment::default();
        let _ = writeln!(f.text, "Command: `{command}`  ");
        let _ = writeln!(f.text, "Machine: {}  ", machine());
        let _ = writeln!(f.text, "Run: {}\n", today());
        f
    }

    pub fn line(&mut self, line: impl AsRef<str>) -> &mut Fragment {
        self.text.push_str(line.as_ref());
        self.text.push('\n');
        self
    }

    /// A Markdown table.
    pub fn table<R: AsRef<[String]>>(&mut self, header: &[&str], rows: &[R]) -> &mut Fragment {
        let _ = writeln!(self.text, "| {} |", header.join(" | "));
        let _ = writeln!(self.text, "|{}", "---|".repeat(header.len()));
        for row in rows {
            let _ = writeln!(self.text, "| {} |", row.as_ref().join(" | "));
        }
        self.text.push('\n');
        self
    }

    pub fn as_str(&self) -> &str {
        &self.text
    }
}

/// Writes `fragment` to `results_dir()/NAME.md` and prints it; the path written.
pub fn write_fragment(name: &str, fragment: &Fragment) -> std::io::Result<PathBuf> {
    write_fragment_to(&results_dir(), name, fragment)
}

fn write_fragment_to(dir: &Path, name: &str, fragment: &Fragment) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join(format!("{name}.md"));
    std::fs::write(&path, fragment.as_str())?;
    println!("{}", fragment.as_str());
    eprintln!("wrote {}", path.display());
    Ok(path)
}

/// Today's date (UTC) as YYYY-MM-DD: the date part of the log's timestamp.
fn today() -> String {
    let mut stamp = String::new();
    crate::timestamp::write_timestamp(&mut stamp, std::time::SystemTime::now());
    stamp.truncate("YYYY-MM-DD".len());
    stamp
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn today_is_a_date() {
        let today = today();
        let digits: Vec<&str> = today.split('-').collect();
        assert_eq!(digits.iter().map(|d| d.len()).collect::<Vec<_>>(), [4, 2, 2], "{today}");
    }

    #[test]
    fn fragments_are_tables_with_their_command() {
        let dir = std::env::temp_dir().join(format!("plcd-frag-{}", std::process::id()));
        let mut f = Fragment::new("cargo bench --bench x");
        f.table(&["a", "b"], &[vec!["1".to_string(), "2".to_string()]]);
        let path = write_fragment_to(&dir, "x", &f).unwrap();
        let text = std::fs::read_to_string(path).unwrap();
        assert!(text.starts_with("Command: `cargo bench --bench x`"));
        assert!(text.contains("| a | b |\n|---|---|\n| 1 | 2 |\n"));
        std::fs::remove_dir_all(dir).unwrap();
    }
}

//! The architecture, checked: the layer tables of docs/ARCHITECTURE.md are the rule, and every
//! source file of the workspace is read against them.
//!
//! - In the `plcd` crate a module imports only from units of lower layers (`crate::drivers::…`
//!   from a service, never a service from a driver, never two drivers from each other).
//! - In the core, a module imports only modules of lower rank.
//! - `super::super::…` never climbs out of a unit into a sibling.
//! - The crates' manifests keep the core pure (no crate that reaches the kernel), the protocol
//!   serde-only, and plcctl clear of the daemon; the core's sources open no files, threads,
//!   sockets or processes, read no clock and draw no random numbers.
//! - `unsafe` lives in two modules, `drivers::real_time::sys` (system calls) and `plcd-native`'s
//!   `code` (executable memory), every block with a `// SAFETY:`.
//!
//! The checks read text: a `crate::` path in a comment is not an import and is skipped.

mod harness;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use harness::runner::wait_bounded;
use harness::tempdir::TempDir;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The rows of the table that follows `marker` in docs/ARCHITECTURE.md: its first two cells.
fn table(marker: &str) -> Vec<(u32, String)> {
    let doc = std::fs::read_to_string(root().join("docs/ARCHITECTURE.md")).unwrap();
    let start = doc.find(marker).unwrap_or_else(|| panic!("docs/ARCHITECTURE.md has no {marker}"));
    let mut rows = Vec::new();
    for line in doc[start..].lines().skip(1) {
        let Some(row) = line.strip_prefix('|') else { break };
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let Ok(level) = cells[0].parse::<u32>() else { continue }; // the header and its rule
        rows.push((level, cells[1].trim_matches('`').to_string()));
    }
    assert!(!rows.is_empty(), "the table after {marker} is empty");
    rows
}

/// The plcd crate's units by their module path (`drivers::real_time`), with their layer.
fn layers() -> BTreeMap<String, u32> {
    table("<!-- layers:").into_iter().map(|(layer, unit)| (unit, layer)).collect()
}

/// The core's modules with their rank.
fn core_ranks() -> BTreeMap<String, u32> {
    table("<!-- core:").into_iter().map(|(rank, module)| (module, rank)).collect()
}

/// Every `.rs` file under `dir`, sorted.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                found.push(path);
            }
        }
    }
    found.sort();
    found
}

/// The lines of a file that are code: comments dropped (a `//` inside a string literal is rare
/// enough in this code base not to matter), with their line numbers and whether they are in the
/// file's `#[cfg(test)]` part (which starts at its first `#[cfg(test)]`).
fn code_lines(text: &str) -> Vec<(usize, &str, bool)> {
    let mut in_tests = false;
    let mut lines = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let code = match line.find("//") {
            Some(at) => &line[..at],
            None => line,
        };
        if code.trim() == "#[cfg(test)]" {
            in_tests = true;
        }
        if !code.trim().is_empty() {
            lines.push((index + 1, code, in_tests));
        }
    }
    lines
}

/// Every `crate::a::b` path of a line, as its first two segments.
fn crate_paths(code: &str) -> Vec<(String, Option<String>)> {
    let mut paths = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("crate::") {
        let before = rest[..at].chars().last();
        rest = &rest[at + "crate::".len()..];
        // `plcd_crate::` or `my_crate::` are other names.
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let segment = |s: &str| -> String {
            s.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect()
        };
        let first = segment(rest);
        let second = rest[first.len()..].strip_prefix("::").map(segment).filter(|s| !s.is_empty());
        if !first.is_empty() {
            paths.push((first, second));
        }
    }
    paths
}

/// The module path of a file relative to its crate's root directory: `drivers/real_time/mod.rs`
/// is `[drivers, real_time]`, `files.rs` is `[files]`, `lib.rs` is `[]`.
fn module_path(relative: &Path) -> Vec<String> {
    let mut parts: Vec<String> =
        relative.iter().map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string()).collect();
    if matches!(parts.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        parts.pop();
    }
    parts
}

/// `super::super::x` from module `module` (one level deeper in a file's tests part): the module
/// it names, or `None` when it climbs above the crate root.
fn climb(module: &[String], code: &str, in_tests: bool) -> Vec<Vec<String>> {
    let mut here = module.to_vec();
    if in_tests {
        here.push("tests".to_string());
    }
    let mut targets = Vec::new();
    let mut rest = code;
    while let Some(at) = rest.find("super::") {
        let before = rest[..at].chars().last();
        let mut tail = &rest[at..];
        let mut depth = 0;
        while let Some(after) = tail.strip_prefix("super::") {
            depth += 1;
            tail = after;
        }
        rest = tail;
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue; // `my_super::`
        }
        targets.push(here[..here.len().saturating_sub(depth)].to_vec());
    }
    targets
}

#[test]
fn the_plcd_crate_imports_only_from_lower_layers() {
    let layers = layers();
    let core = core_ranks();
    let src = root().join("src");
    let members = ["core", "ipc", "plcctl"];
    let unit_of = |module: &[String]| -> Option<String> {
        let two = module.iter().take(2).cloned().collect::<Vec<_>>().join("::");
        let one = module.first()?.clone();
        [two, one].into_iter().find(|u| layers.contains_key(u))
    };
    let mut violations = Vec::new();
    let mut checked = 0;
    for path in sources(&src) {
        let relative = path.strip_prefix(&src).unwrap();
        if members.iter().any(|m| relative.starts_with(m)) {
            continue;
        }
        let module = module_path(relative);
        // lib.rs, main.rs and the containers drivers/mod.rs, services/mod.rs declare modules.
        let Some(unit) = unit_of(&module) else { continue };
        let layer = layers[&unit];
        checked += 1;
        let text = std::fs::read_to_string(&path).unwrap();
        for (line, code, in_tests) in code_lines(&text) {
            for (first, second) in crate_paths(code) {
                if core.contains_key(&first) && !layers.contains_key(&first) {
                    continue; // the core, re-exported: layer 0
                }
                let target = match second {
                    Some(second) if layers.contains_key(&format!("{first}::{second}")) => {
                        format!("{first}::{second}")
                    }
                    _ => first.clone(),
                };
                let Some(&target_layer) = layers.get(&target) else {
                    violations.push(format!(
                        "{}:{line}: `crate::{first}` is in no layer of docs/ARCHITECTURE.md",
                        relative.display()
                    ));
                    continue;
                };
                if target != unit && target_layer >= layer {
                    violations.push(format!(
                        "{}:{line}: {unit} (layer {layer}) imports {target} (layer {target_layer})",
                        relative.display()
                    ));
                }
            }
            for target in climb(&module, code, in_tests) {
                if !target.starts_with(&unit.split("::").map(String::from).collect::<Vec<_>>()) {
                    violations.push(format!(
                        "{}:{line}: `super::` climbs out of {unit} to `{}`",
                        relative.display(),
                        target.join("::")
                    ));
                }
            }
        }
    }
    assert!(checked > 40, "only {checked} files were checked: has the layout moved?");
    assert!(violations.is_empty(), "imports against the layers:\n{}", violations.join("\n"));
}

#[test]
fn the_core_imports_only_lower_ranks() {
    let ranks = core_ranks();
    let src = root().join("src/core");
    let mut violations = Vec::new();
    for path in sources(&src) {
        let relative = path.strip_prefix(&src).unwrap();
        let module = module_path(relative);
        let Some(own) = module.first() else { continue }; // lib.rs
        let rank = *ranks.get(own).unwrap_or_else(|| {
            panic!(
                "src/core/{}: module `{own}` has no rank in docs/ARCHITECTURE.md",
                relative.display()
            )
        });
        let text = std::fs::read_to_string(&path).unwrap();
        for (line, code, in_tests) in code_lines(&text) {
            for (first, _) in crate_paths(code) {
                match ranks.get(&first) {
                    None => violations.push(format!(
                        "src/core/{}:{line}: `crate::{first}` has no rank",
                        relative.display()
                    )),
                    Some(&r) if first != *own && r >= rank => violations.push(format!(
                        "src/core/{}:{line}: {own} (rank {rank}) imports {first} (rank {r})",
                        relative.display()
                    )),
                    _ => {}
                }
            }
            for target in climb(&module, code, in_tests) {
                if target.first() != Some(own) {
                    violations.push(format!(
                        "src/core/{}:{line}: `super::` climbs out of {own}",
                        relative.display()
                    ));
                }
            }
        }
    }
    assert!(violations.is_empty(), "imports against the core's ranks:\n{}", violations.join("\n"));
}

#[test]
fn the_core_opens_no_files_threads_sockets_or_clocks() {
    let forbidden = [
        "std::fs",
        "std::thread",
        "std::process",
        "std::env",
        "std::os::",
        "TcpStream",
        "TcpListener",
        "UdpSocket",
        "Instant::now",
        "SystemTime::now",
        "std::io::stdin",
        "std::io::stdout",
        "std::io::stderr",
        // Random numbers: salts are the caller's (`plcd user`), the core has no random source.
        "OsRng",
        "getrandom",
        "thread_rng",
    ];
    let src = root().join("src/core");
    let mut found = Vec::new();
    for path in sources(&src) {
        let text = std::fs::read_to_string(&path).unwrap();
        for (line, code, _) in code_lines(&text) {
            for word in forbidden.iter().filter(|w| code.contains(*w)) {
                found.push(format!(
                    "{}:{line}: {word}",
                    path.strip_prefix(root()).unwrap().display()
                ));
            }
        }
    }
    assert!(found.is_empty(), "the pure core reaches outside the process:\n{}", found.join("\n"));
}

/// The names of a manifest's `[dependencies]`.
fn dependencies(manifest: &str) -> Vec<String> {
    let text = std::fs::read_to_string(root().join(manifest)).unwrap();
    let value: toml::Table = toml::from_str(&text).unwrap();
    value
        .get("dependencies")
        .and_then(|d| d.as_table())
        .map(|t| t.keys().cloned().collect())
        .unwrap_or_default()
}

#[test]
fn the_manifests_keep_each_crate_to_its_layer() {
    // What reaches the kernel or a layer above the core.
    let impure = [
        "nix",
        "gpiocdev",
        "libc",
        "rtrb",
        "signal-hook",
        "modbus-core",
        "plcd",
        "plcd-ipc",
        "plcctl",
    ];
    let core = dependencies("src/core/Cargo.toml");
    let bad: Vec<_> = core.iter().filter(|d| impure.contains(&d.as_str())).collect();
    assert!(bad.is_empty(), "plcd-core depends on {bad:?}");

    let ipc = dependencies("src/ipc/Cargo.toml");
    assert!(
        ipc.iter().all(|d| d == "serde" || d == "serde_json"),
        "plcd-ipc is serde only, but depends on {ipc:?}"
    );

    let plcctl = dependencies("src/plcctl/Cargo.toml");
    let daemon = ["plcd", "gpiocdev", "rtrb", "signal-hook", "modbus-core"];
    let bad: Vec<_> = plcctl.iter().filter(|d| daemon.contains(&d.as_str())).collect();
    assert!(bad.is_empty(), "plcctl must build without the daemon, but depends on {bad:?}");
    assert!(plcctl.contains(&"plcd-ipc".to_string()), "plcctl speaks the protocol of plcd-ipc");

    // The code generator stands on the core alone, beside it, below the shell.
    let native = dependencies("src/native/Cargo.toml");
    assert!(
        native.iter().all(|d| d == "plcd-core" || d == "thiserror" || d.starts_with("cranelift-")),
        "plcd-native is the core and Cranelift only, but depends on {native:?}"
    );
}

#[test]
fn unsafe_lives_in_one_module_and_says_why() {
    for (root_file, attribute) in [
        ("src/core/lib.rs", "#![forbid(unsafe_code)]"),
        ("src/ipc/lib.rs", "#![forbid(unsafe_code)]"),
        ("src/plcctl/lib.rs", "#![forbid(unsafe_code)]"),
        ("src/lib.rs", "#![deny(unsafe_code)]"),
        ("src/native/src/lib.rs", "#![deny(unsafe_code)]"),
    ] {
        let text = std::fs::read_to_string(root().join(root_file)).unwrap();
        assert!(text.contains(attribute), "{root_file} lacks {attribute}");
    }
    // The system calls of the real-time driver, and the executable memory of native code.
    let allowed = [Path::new("src/drivers/real_time/sys.rs"), Path::new("src/native/src/code.rs")];
    for path in sources(&root().join("src")) {
        let relative = path.strip_prefix(root()).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines = code_lines(&text);
        let uses_unsafe = lines.iter().any(|(_, code, _)| {
            code.contains("unsafe {") || code.contains("unsafe fn") || code.contains("unsafe impl")
        });
        if !allowed.contains(&relative) {
            assert!(!uses_unsafe, "{}: unsafe outside {allowed:?}", relative.display());
            continue;
        }
        let all: Vec<&str> = text.lines().collect();
        for (line, code, _) in &lines {
            if code.contains("unsafe {") {
                let above = all[..line - 1].iter().rev().take_while(|l| l.trim().starts_with("//"));
                assert!(
                    above.clone().any(|l| l.contains("SAFETY:")),
                    "{}:{line}: an unsafe block without a // SAFETY: comment above it",
                    relative.display()
                );
            }
        }
    }
}

#[test]
fn the_checks_see_what_they_must() {
    // The parsers of this file, on the cases that matter.
    assert_eq!(
        crate_paths("use crate::drivers::real_time::Shared; x(plcd_crate::y)"),
        [("drivers".to_string(), Some("real_time".to_string()))]
    );
    assert_eq!(
        crate_paths("let x = crate::config::parse(t);"),
        [("config".into(), Some("parse".into()))]
    );
    let module: Vec<String> = ["drivers", "real_time", "scan"].map(String::from).to_vec();
    assert_eq!(
        climb(&module, "use super::super::virtual_time;", false),
        [["drivers"].map(String::from).to_vec()]
    );
    assert_eq!(
        climb(&module, "use super::Shared;", false),
        [["drivers", "real_time"].map(String::from).to_vec()]
    );
    assert_eq!(climb(&module, "use super::*;", true), std::slice::from_ref(&module));
    assert!(code_lines("a // crate::daemon\n#[cfg(test)]\nb")[2].2);
    assert_eq!(module_path(Path::new("drivers/real_time/mod.rs")), ["drivers", "real_time"]);
}

/// The features `cargo tree` says each package of `plcd`'s graph is built with, by
/// "name version", for the kinds of dependencies in `edges`: a set, as a package built for the
/// host (a build script's or a procedural macro's dependency) may have other features.
/// Bounded: `cargo tree` reads the lock file and the local registry (offline), and is stopped
/// after two minutes.
fn built_features(edges: &str) -> BTreeMap<String, BTreeSet<String>> {
    let dir = TempDir::new("architecture-tree");
    let out = dir.join("tree.txt");
    let mut child = Command::new(env!("CARGO"))
        .args(["tree", "--locked", "--offline", "--package", "plcd", "--prefix", "none"])
        .args(["--edges", edges, "--format", "{p} {f}"])
        .current_dir(root())
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out).unwrap())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("cargo tree starts");
    let what = format!("cargo tree --edges {edges}");
    let status = wait_bounded(&mut child, Duration::from_secs(120), &what);
    assert!(status.success(), "{what}: {status}");
    let mut features: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for line in std::fs::read_to_string(&out).unwrap().lines() {
        let mut words = line.split_whitespace();
        let (Some(name), Some(version)) = (words.next(), words.next()) else { continue };
        let enabled = words.next().filter(|w| !w.starts_with('(')).unwrap_or("");
        features.entry(format!("{name} {version}")).or_default().insert(enabled.to_string());
    }
    assert!(features.len() > 50, "{what} listed {} packages", features.len());
    features
}

/// The release build of the binaries (no dev-dependencies) and the bench build (with them)
/// share their compiled dependencies only where every package has the same features in both:
/// Cargo.toml asks for those the dev-dependencies would add (its "feature unification" entries).
#[test]
fn builds_with_and_without_dev_dependencies_share_their_dependencies() {
    let without = built_features("normal,build");
    let with = built_features("normal,build,dev");
    let differing: Vec<String> = without
        .iter()
        .filter_map(|(package, features)| {
            let other = with.get(package)?;
            (other != features).then(|| format!("{package}: {features:?} without, {other:?} with"))
        })
        .collect();
    assert!(
        differing.is_empty(),
        "packages built with other features when the dev-dependencies are in (add them to \
         plcd's feature unification entries in Cargo.toml):\n{}",
        differing.join("\n")
    );
}

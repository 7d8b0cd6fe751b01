//! Replays every kept input of every fuzz target through its body: the corpus AFL++ grew
//! (`corpus/TARGET/`) and every input that ever crashed a target (`crashes/TARGET/`, each
//! fixed since). A regression of a fixed crash, or an invariant a change broke on an input the
//! fuzzer once found, fails here, in `cargo test`, without AFL++.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

fn inputs(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut files: Vec<PathBuf> = entries
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.is_file() && p.file_name().is_none_or(|n| n != "README.txt"))
        .collect();
    files.sort();
    files
}

/// Runs target `name` on each of its inputs; fails naming every input that panicked.
fn replay(name: &str) {
    let target = plcd_fuzz::target(name).expect("a target");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let corpus = inputs(&root.join("corpus").join(name));
    assert!(!corpus.is_empty(), "target {name} has no corpus in corpus/{name}/");
    let crashes = inputs(&root.join("crashes").join(name));
    let mut failed = Vec::new();
    for path in corpus.iter().chain(&crashes) {
        let data = std::fs::read(path).expect("an input");
        if catch_unwind(AssertUnwindSafe(|| (target.run)(&data))).is_err() {
            failed.push(path.display().to_string());
        }
    }
    assert!(
        failed.is_empty(),
        "target {name}: {} of {} inputs failed (replay one with `cargo run -p plcd-fuzz --features \
         afl -- {name} < FILE` or this test's output above):\n{}",
        failed.len(),
        corpus.len() + crashes.len(),
        failed.join("\n")
    );
}

#[test]
fn every_target_has_a_corpus_test_and_dictionary_entry() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let this = std::fs::read_to_string(root.join("tests/replay.rs")).unwrap();
    let run = std::fs::read_to_string(root.join("run")).unwrap();
    for t in plcd_fuzz::TARGETS {
        assert!(this.contains(&format!("replay(\"{}\")", t.name)), "no replay test for {}", t.name);
        assert!(run.contains(&format!("{}:", t.name)), "tests/fuzz/run has no line for {}", t.name);
    }
}

#[test]
fn il() {
    replay("il");
}

#[test]
fn twincat() {
    replay("twincat");
}

#[test]
fn plcproj() {
    replay("plcproj");
}

#[test]
fn st() {
    replay("st");
}

#[test]
fn config() {
    replay("config");
}

#[test]
fn stimulus() {
    replay("stimulus");
}

#[test]
fn retain() {
    replay("retain");
}

#[test]
fn control() {
    replay("control");
}

#[test]
fn modbus_tcp() {
    replay("modbus_tcp");
}

#[test]
fn modbus_rtu() {
    replay("modbus_rtu");
}

#[test]
fn remote() {
    replay("remote");
}

#[test]
fn users() {
    replay("users");
}

#[test]
fn mqtt() {
    replay("mqtt");
}

/// The `mqtt` seeds are what a host application sends (`examples/mqtt-seeds.rs`): from them the
/// target must reach every kind of command and event, or it fuzzes only the payload decoding.
#[test]
fn mqtt_seeds_reach_every_kind_of_message() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut seen = plcd_fuzz::targets::mqtt::Seen::new();
    for path in inputs(&root.join("corpus/mqtt")) {
        let data = std::fs::read(path).expect("an input");
        plcd_fuzz::targets::mqtt::steps(&data, &mut seen);
    }
    for kind in [
        "NCMD set",
        "DCMD set",
        "refused and sent again",
        "rebirth",
        "scan rate",
        "next server",
        "malformed",
        "data",
        "connection lost",
        "stored",
        "history",
        "overflowed",
        "remote lost",
        "remote back",
    ] {
        assert!(seen.contains(kind), "no {kind} reached from the seeds: {seen:?}");
    }
}

#[cfg(feature = "opcua")]
#[test]
fn opcua() {
    replay("opcua");
}

/// The `opcua` seeds are what a real client sends (`tests/fuzz/opcua-seeds`): the target must
/// decode from them every service plcd's server is asked for, or it fuzzes only the framing.
#[cfg(feature = "opcua")]
#[test]
fn opcua_seeds_reach_every_service() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut seen = std::collections::BTreeSet::new();
    for path in inputs(&root.join("corpus/opcua")) {
        let data = std::fs::read(path).expect("an input");
        plcd_fuzz::targets::opcua::requests(&data, |_, request, _| {
            seen.insert(request.type_name());
        });
    }
    for service in [
        "OpenSecureChannel",
        "CreateSession",
        "ActivateSession",
        "Read",
        "Write",
        "Call",
        "Browse",
        "CreateSubscription",
        "CreateMonitoredItems",
        "CloseSession",
        "CloseSecureChannel",
    ] {
        assert!(seen.contains(service), "no {service} decoded from the seeds: {seen:?}");
    }
}

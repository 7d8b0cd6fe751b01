//! The targets, one file each (see the crate docs), and what the language targets share.

pub mod config;
pub mod control;
pub mod il;
pub mod modbus_rtu;
pub mod modbus_tcp;
pub mod mqtt;
#[cfg(feature = "opcua")]
pub mod opcua;
pub mod plcproj;
pub mod remote;
pub mod retain;
pub mod st;
pub mod stimulus;
pub mod twincat;
pub mod users;

use std::path::Path;

use plcd::drivers::virtual_time::{simulate, SimOptions};
use plcd::engine::event::Recorder;
use plcd::project::{self, Project};
use plcd::stimulus::Stimulus;

use crate::assert_located;

/// Virtual time a project runs for: a few scans, and a few periods of a 1 ms task.
const SIM_NS: u64 = 5_000_000;
/// What an instruction costs: 1 µs, so a scan that loops trips the 10 ms watchdog.
const STEP_NS: u64 = 1_000;

/// Runs `project` in virtual time twice with `stimuli`: the two runs must agree, event for
/// event, in steps and in scans (the engine is deterministic).
pub fn run_twice(project: &Project, stimuli: &[Stimulus]) {
    let options = SimOptions { duration_ns: SIM_NS, step_ns: STEP_NS };
    let mut first = Recorder::default();
    let a = simulate(project, stimuli, &[] as &[project::Watched], options, &mut first);
    let mut second = Recorder::default();
    let b = simulate(project, stimuli, &[] as &[project::Watched], options, &mut second);
    assert_eq!(first.0, second.0, "two runs of one project disagree");
    assert_eq!((a.steps(), a.scan_count()), (b.steps(), b.scan_count()));
    assert_eq!(a.vm().mem.words(), b.vm().mem.words(), "two runs end with other memory");
}

/// A program target: `data` as the file `main` of the project `config`, whose other programs'
/// texts are `others` (by file name), played with the inputs file `inputs`. Rejected, its
/// diagnostics point into it; accepted, it runs twice the same way ([`run_twice`]).
pub fn program(config_text: &str, main: &str, others: &[(&str, &str)], inputs: &str, data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let config =
        plcd::config::parse(config_text, Path::new("plcd.toml")).expect("the target's config");
    let stimuli = plcd::stimulus::parse_for(inputs, Path::new("inputs.csv"), &config)
        .expect("the target's inputs");
    let read = |path: &Path| {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        match others.iter().find(|(file, _)| *file == name) {
            Some((_, other)) => other.to_string(),
            None => text.to_string(),
        }
    };
    match project::from_config(config, |p| Ok(read(p))) {
        Err(diags) => assert_located(&diags, Path::new(main), text),
        Ok(project) => run_twice(&project, &stimuli),
    }
}

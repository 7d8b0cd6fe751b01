//! An inputs file (`plcd sim --inputs`, `[io] stimulus`): parsed against the instruction-list
//! target's project and, if accepted, played into it for a few scans in virtual time, twice
//! the same way. Rejected, its diagnostics point into it.

use std::path::Path;

use plcd::{config, stimulus};

use super::run_twice;
use crate::assert_located;

const MAIN: &str = "LOAD P0001\nOUT P0040\nMOV D00010 D00020\nEND\n";

pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let config = config::parse(super::il::CONFIG, Path::new("plcd.toml")).expect("config");
    let path = Path::new("inputs.csv");
    let stimuli = match stimulus::parse_for(text, path, &config) {
        Ok(stimuli) => stimuli,
        Err(diags) => return assert_located(&diags, path, text),
    };
    assert!(stimuli.windows(2).all(|w| w[0].t_ns <= w[1].t_ns), "stimuli out of time order");
    let read = |file: &Path| match file.file_name().and_then(|n| n.to_str()) {
        Some("main.il") => MAIN.to_string(),
        _ => "INC D00500\nEND\n".to_string(),
    };
    let project = plcd::project::from_config(config, |f| Ok(read(f))).expect("the project");
    run_twice(&project, &stimuli);
}

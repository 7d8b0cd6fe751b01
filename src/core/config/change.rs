//! What may change while plcd runs: which config sections each way of taking a new project can
//! take a new value of. The daemon's SIGHUP reload, `plcctl load` and the engine's online
//! change all ask [`Config::refused_sections`]; the answer is the one table below.
//!
//! `[[program]]` entries are what every change is for. `[[task]]` entries are taken by a reload
//! and a load (the engine starts anew); an online change compares them task by task
//! (`engine::online`), because its reasons name the task and what changed in it.

use super::Config;

/// A way a running plcd takes a new project.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProjectChange {
    /// SIGHUP: the daemon reads its config file again and replaces the engine. A section it
    /// cannot take needs a restart of the service.
    Reload,
    /// `plcctl load`, with or without `--online`. A section it cannot take needs a restart of
    /// the service.
    Load,
    /// An online change (`plcctl load --online` in RUN or DEBUG): the new engine takes the
    /// running one's state over at a scan boundary. A section it cannot take can only change
    /// with the PLC in STOP. The daemon asks [`ProjectChange::Load`] first, so what only a
    /// restart can change never gets here.
    Online,
}

/// One config section and which changes take a new value of it.
struct Section {
    name: &'static str,
    differs: fn(&Config, &Config) -> bool,
    reload: bool,
    load: bool,
    online: bool,
}

impl Section {
    fn takes(&self, change: ProjectChange) -> bool {
        match change {
            ProjectChange::Reload => self.reload,
            ProjectChange::Load => self.load,
            ProjectChange::Online => self.online,
        }
    }
}

const fn section(
    name: &'static str,
    differs: fn(&Config, &Config) -> bool,
    [reload, load, online]: [bool; 3],
) -> Section {
    Section { name, differs, reload, load, online }
}

/// Every section, in the order the refusals name them, and whether a reload, a load and an
/// online change take a new value of it. The online column is what the running engine can take
/// over; what a load refuses never reaches it.
#[rustfmt::skip]
const SECTIONS: [Section; 15] = [
    //       section      differs                              reload  load   online
    section("[plc]",     |a, b| a.plc != b.plc,              [true,  true,  false]),
    // Read by `plcd sim` alone.
    section("[sim]",     |a, b| a.sim != b.sim,              [true,  true,  true ]),
    section("[timers]",  |a, b| a.timers != b.timers,        [true,  true,  false]),
    section("[io]",      |a, b| a.io != b.io,                [false, false, false]),
    section("[rt]",      |a, b| a.rt != b.rt,                [false, false, false]),
    // The control socket and the field's switch line are set up at start: like `plcctl
    // load`, a reload refuses a new [control] or [switch] rather than take it and not apply it.
    section("[control]", |a, b| a.control != b.control,      [false, false, true ]),
    section("[switch]",  |a, b| a.switch != b.switch,        [false, false, false]),
    section("[retain]",  |a, b| a.retain != b.retain,        [false, false, false]),
    section("[modbus]",  |a, b| a.modbus != b.modbus,        [false, false, true ]),
    // The OPC UA server's socket, certificates and limits are set up at start.
    section("[opcua]",   |a, b| a.opcua != b.opcua,          [false, false, true ]),
    // The poller threads and their links are set up at start.
    section("[[remote]]", |a, b| a.remotes != b.remotes,     [false, false, true ]),
    // Program code, like `[[program]]`: an online change keeps the variables it can.
    section("[st]",      |a, b| a.st != b.st,                [true,  true,  true ]),
    // Where the IEC direct addresses are: an online change would carry the located variables'
    // values over to other devices and leave the old ones (outputs among them) as they were.
    section("[iec]",     |a, b| a.iec != b.iec,              [true,  true,  false]),
    // The services that take named logins open the users file they were started with; they
    // read its lines again on a reload (docs/USERS.md), but another file takes a restart.
    section("[users]",   |a, b| a.users != b.users,          [false, false, true ]),
    // Not a section but what the field was opened for: the edge detection of the contacts io
    // tasks start on (an online change refuses any task change on its own, task by task).
    section("the contacts and edges io tasks start on",
        |a, b| a.edge_detection() != b.edge_detection(),    [false, false, true ]),
];

impl Config {
    /// The sections that differ between this (the running) config and `new` and that `change`
    /// cannot take, in the order of the table (`SECTIONS`); empty when it can take `new`.
    pub fn refused_sections(&self, new: &Config, change: ProjectChange) -> Vec<&'static str> {
        SECTIONS
            .iter()
            .filter(|section| !section.takes(change) && (section.differs)(self, new))
            .map(|section| section.name)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::config::parse;

    const PROGRAM: &str = "[[program]]\nfile = \"main.il\"\n";

    #[test]
    fn an_unchanged_config_is_taken_by_every_change() {
        let config = parse(PROGRAM, Path::new("a.toml")).unwrap();
        for change in [ProjectChange::Reload, ProjectChange::Load, ProjectChange::Online] {
            assert!(config.refused_sections(&config.clone(), change).is_empty(), "{change:?}");
        }
    }

    #[test]
    fn new_edges_for_io_tasks_take_a_restart_of_the_field() {
        let task = |contact: &str, edge: &str| {
            format!(
                "{PROGRAM}[[task]]\nname = \"edge\"\nkind = \"io\"\nnumber = 8\npriority = 2\n\
                 contact = \"{contact}\"\nedge = \"{edge}\"\n"
            )
        };
        let old = parse(&task("P0000", "rising"), Path::new("a.toml")).unwrap();
        let name = "the contacts and edges io tasks start on";
        for (contact, edge) in [("P0001", "rising"), ("P0000", "both")] {
            let new = parse(&task(contact, edge), Path::new("a.toml")).unwrap();
            assert_eq!(
                old.refused_sections(&new, ProjectChange::Reload),
                [name],
                "{contact} {edge}"
            );
            assert_eq!(old.refused_sections(&new, ProjectChange::Load), [name], "{contact} {edge}");
            // An online change refuses the changed task itself (engine::online).
            assert!(old.refused_sections(&new, ProjectChange::Online).is_empty());
        }
        // A program without io tasks, or the same edges from a renamed task: nothing to refuse.
        let renamed = task("P0000", "rising").replace("\"edge\"", "\"sensor\"");
        let new = parse(&renamed, Path::new("a.toml")).unwrap();
        assert!(old.refused_sections(&new, ProjectChange::Reload).is_empty());
    }

    #[test]
    fn each_change_refuses_its_sections_in_order() {
        let old = parse(PROGRAM, Path::new("a.toml")).unwrap();
        let switched = format!("[switch]\nposition = \"stop\"\n{PROGRAM}");
        let mut new = parse(&switched, Path::new("a.toml")).unwrap();
        new.plc.watchdog_ms += 1;
        new.sim.step_ns += 1;
        new.timers.ms100 = Some(0..=9);
        new.io.stimulus_loop = !new.io.stimulus_loop;
        new.rt.scan_priority -= 1;
        new.control.max_clients += 1;
        new.retain.interval_ms += 1;
        new.modbus.unit_id += 1;
        new.opcua.max_sessions += 1;
        new.iec.layout = crate::device::iec::IecLayout::of(crate::device::iec::Preset::Codesys);
        new.users.file = Some("users".into());
        new.remotes = parse(
            &format!(
                "{PROGRAM}[[remote]]\nname = \"a\"\ntransport = \"tcp\"\n\
                 address = \"10.0.0.5:502\"\n[[remote.read]]\ntable = \"coils\"\n\
                 address = 0\ncount = 1\ndevice = \"M0000\"\n"
            ),
            Path::new("a.toml"),
        )
        .unwrap()
        .remotes;
        // What only a restart takes: the same for a reload and a load.
        let restart_only = [
            "[io]",
            "[rt]",
            "[control]",
            "[switch]",
            "[retain]",
            "[modbus]",
            "[opcua]",
            "[[remote]]",
            "[users]",
        ];
        assert_eq!(old.refused_sections(&new, ProjectChange::Reload), restart_only);
        assert_eq!(old.refused_sections(&new, ProjectChange::Load), restart_only);
        assert_eq!(
            old.refused_sections(&new, ProjectChange::Online),
            ["[plc]", "[timers]", "[io]", "[rt]", "[switch]", "[retain]", "[iec]"]
        );
    }
}

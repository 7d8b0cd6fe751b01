//! The soak's project, written into a private directory: the config and its programs in two
//! variants that a SIGHUP reload alternates between, a scan program whose markers an online
//! change rewrites, and the edge storm the sim backend plays on P0000–P0007.
//!
//! Device memory, by who writes it:
//!
//! | devices | written by | checked |
//! |---|---|---|
//! | D00000 | the scan program: `INC` once a scan | equals the scan count of every `get` |
//! | D00001 | the scan program: the reload marker | the variant's number after each SIGHUP |
//! | D00002 | the scan program: the online marker | the change's number after each online change |
//! | D00003, D00004 | the two 1 ms cycle tasks, one `INC` a run | |
//! | D00020–D00027 | the io tasks of P0000–P0007, one `INC` a run | |
//! | K020–K069 | control client k: `set`, then `get` | its own last value |
//! | P0040–P0071 | control client k: `force`, `unforce` | the force table of the answer |
//! | K100–K179 | Modbus client k: 4 holding registers (FC 16, FC 6) | FC 3 reads them back |
//! | K200–K219 | Modbus client k: 16 coils (FC 15) | FC 1 reads them back |
//!
//! K is retained across a reload and an online change (docs/RETAIN.md), so a value a client
//! wrote is still there when it reads it back, whatever the reloads did in between; M, P and D
//! are cleared at the RUN start of a reload, so the clients write none of them.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The holding registers of Modbus client k: `MODBUS_REGISTERS + 4k` ..= `+ 3`.
pub const MODBUS_REGISTERS: u16 = 100;
/// The coils of Modbus client k: `16k` ..= `16k + 15`.
pub const COILS_PER_CLIENT: u16 = 16;
/// The first K word of the control clients.
pub const CONTROL_WORDS: usize = 20;
/// The first P bit the control clients force: client k forces bit `FORCED_BITS + k`.
pub const FORCED_BITS: usize = 0x40;

/// The K word control client `k` writes.
pub fn control_word(k: usize) -> String {
    format!("K{:03}", CONTROL_WORDS + k)
}

/// The P bit control client `k` forces.
pub fn forced_bit(k: usize) -> String {
    let bit = FORCED_BITS + k;
    format!("P{:03}{:X}", bit / 16, bit % 16)
}

/// The project directory and what it is running.
pub struct Project {
    pub dir: PathBuf,
    /// Lines of the stimulus file, all of them edges.
    pub storm_lines: usize,
}

impl Project {
    /// Writes variant 0 into `dir`, with a storm of `storm_lines` lines `step_ns` apart.
    pub fn write(dir: &Path, storm_lines: usize, step_ns: u64, modbus_clients: usize) -> Project {
        std::fs::create_dir_all(dir).unwrap();
        let project = Project { dir: dir.to_path_buf(), storm_lines };
        std::fs::write(dir.join("storm.csv"), storm(storm_lines, step_ns)).unwrap();
        for c in 0..8 {
            std::fs::write(dir.join(format!("edge{c}.il")), format!("INC D0002{c}\nEND\n"))
                .unwrap();
        }
        std::fs::write(dir.join("fast1.il"), "INC D00003\nEND\n").unwrap();
        std::fs::write(
            dir.join("fast2.il"),
            "INC D00004\nLOAD NOT T1501           ; a 2 ms pulse train on a 1 ms timer\n\
             TON T1501 2\nLOAD T1501\nCTU C0001 50\nLOAD C0001\nRST C0001\nEND\n",
        )
        .unwrap();
        project.write_variant(0, 0, modbus_clients);
        project
    }

    pub fn config(&self) -> PathBuf {
        self.dir.join("plcd.toml")
    }

    pub fn socket(&self) -> PathBuf {
        self.dir.join("plcd.sock")
    }

    /// Writes the config of reload variant `reload` (its parity decides what differs) and the
    /// scan program with markers `reload` and `online`.
    pub fn write_variant(&self, reload: u32, online: u32, modbus_clients: usize) {
        std::fs::write(self.config(), config(reload % 2 == 1, modbus_clients)).unwrap();
        self.write_scan_program(reload, online);
    }

    /// Writes the scan program alone: what an online change may change.
    pub fn write_scan_program(&self, reload: u32, online: u32) {
        let text = format!(
            "; the soak's scan program (benches/soak/project.rs)\n\
             INC D00000              ; the scan counter, checked against the scan count\n\
             MOV {} D00001           ; the reload marker\n\
             MOV {} D00002           ; the online marker\n\
             LOAD NOT T1500          ; a 5 ms pulse train on a 1 ms timer\n\
             TON T1500 5\n\
             LOAD T1500\n\
             CTU C0000 100           ; counts the pulses, and starts again at 100\n\
             LOAD C0000\n\
             RST C0000\n\
             LOAD _ON\n\
             TON T1000 50            ; a 10 ms timer that runs once to 500 ms\n\
             LOAD T1000\n\
             OUT M0001\n\
             ADD D00010 1 D00010\n\
             END\n",
            marker(reload),
            marker(online)
        );
        std::fs::write(self.dir.join("main.il"), text).unwrap();
    }
}

/// A marker as the program writes it into a word: 1..=30000, never 0 (the value of a cleared
/// word).
pub fn marker(n: u32) -> i64 {
    i64::from(n % 30000) + 1
}

/// The config; `odd` is the other reload variant: a longer watchdog and the second cycle
/// task at another priority, which a reload may change and an online change may not.
fn config(odd: bool, modbus_clients: usize) -> String {
    let mut c = String::new();
    let watchdog = if odd { 250 } else { 200 };
    let fast2_priority = if odd { 5 } else { 4 };
    writeln!(
        c,
        "# The soak's project (benches/soak/project.rs); variant {}\n\
         [plc]\nwatchdog_ms = {watchdog}\nscan_period_ms = 1\n\n\
         [[program]]\nfile = \"main.il\"\n\n\
         [[program]]\nfile = \"fast1.il\"\ntask = \"fast1\"\n\n\
         [[program]]\nfile = \"fast2.il\"\ntask = \"fast2\"\n\n\
         [[task]]\nname = \"fast1\"\nkind = \"cycle\"\nnumber = 0\npriority = 3\ninterval_ms = 1\n\n\
         [[task]]\nname = \"fast2\"\nkind = \"cycle\"\nnumber = 1\npriority = {fast2_priority}\n\
         interval_ms = 1\n",
        u8::from(odd)
    )
    .unwrap();
    for contact in 0..8 {
        writeln!(
            c,
            "[[program]]\nfile = \"edge{contact}.il\"\ntask = \"edge{contact}\"\n\n\
             [[task]]\nname = \"edge{contact}\"\nkind = \"io\"\nnumber = {}\npriority = 2\n\
             contact = \"P000{contact}\"\nedge = \"both\"\n",
            8 + contact
        )
        .unwrap();
    }
    writeln!(
        c,
        "[io]\nbackend = \"sim\"\nstimulus = \"storm.csv\"\nstimulus_loop = true\n\n\
         [retain]\ndir = \"retain\"\ninterval_ms = 1000\n\n\
         [control]\nsocket = \"plcd.sock\"\nmax_clients = 64\n\n\
         [modbus]\nlisten = \"127.0.0.1:0\"\nmax_connections = 32\n\n\
         [[modbus.holding_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 32\n\n\
         [[modbus.holding_registers]]\nstart = {MODBUS_REGISTERS}\ndevice = \"K{MODBUS_REGISTERS}\"\n\
         count = {}\nwritable = true\n\n\
         [[modbus.coils]]\nstart = 0\ndevice = \"K2000\"\ncount = {}\nwritable = true\n\n\
         [[modbus.input_registers]]\nstart = 0\ndevice = \"_SCAN_CUR\"\ncount = 4",
        4 * modbus_clients.max(1),
        usize::from(COILS_PER_CLIENT) * modbus_clients.max(1)
    )
    .unwrap();
    c
}

/// The storm: P0000–P0007 toggled in turn, one line every `step_ns`, `lines` lines (a
/// multiple of 16, so that each contact ends a pass where it started and every line of every
/// pass is an edge).
fn storm(lines: usize, step_ns: u64) -> String {
    let mut text = String::from("# the soak's edge storm (benches/soak/project.rs)\n");
    let mut state = [0u8; 8];
    for i in 0..lines {
        let contact = i % 8;
        state[contact] ^= 1;
        writeln!(text, "{}ns, P000{contact}, {}", (i as u64 + 1) * step_ns, state[contact])
            .unwrap();
    }
    text
}

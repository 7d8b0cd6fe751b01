use std::path::{Path, PathBuf};

use super::*;
use crate::io::SwitchPosition;

const PATH: &str = "etc/plcd.toml";

/// A scan program, to make a config valid; appended after the parts under test so that their
/// line numbers start at 1.
const SCAN: &str = "\n[[program]]\nfile = \"main.il\"\n";

fn config(text: &str) -> Config {
    parse(text, Path::new(PATH)).unwrap_or_else(|d| panic!("unexpected errors:\n{d}"))
}

/// Every diagnostic as `line:col: message`.
fn errors(text: &str) -> Vec<String> {
    let diags = match parse(text, Path::new(PATH)) {
        Ok(config) => panic!("expected errors, got {config:#?}"),
        Err(diags) => diags,
    };
    assert!(diags.iter().all(|d| d.path == Path::new(PATH)));
    diags.iter().map(|d| format!("{}:{}: {}", d.line, d.col, d.message)).collect()
}

fn with_scan(text: &str) -> String {
    format!("{text}{SCAN}")
}

/// The config of `text` followed by a scan program (so `text`'s lines count from 1), for the
/// literal tests of each section's module.
pub(super) fn scan_config(text: &str) -> Config {
    parse(&with_scan(text), Path::new("plcd.toml"))
        .unwrap_or_else(|d| panic!("unexpected errors:\n{d}"))
}

/// Every diagnostic of `text` followed by a scan program, as `line:col: message`.
pub(super) fn scan_errors(text: &str) -> Vec<String> {
    match parse(&with_scan(text), Path::new("plcd.toml")) {
        Ok(config) => panic!("expected errors, got {config:#?}"),
        Err(d) => d.iter().map(|d| format!("{}:{}: {}", d.line, d.col, d.message)).collect(),
    }
}

fn addr(text: &str) -> Address {
    Address::parse(text).unwrap()
}

fn task(name: &str, kind: &str, number: u8, extra: &str) -> String {
    format!("[[task]]\nname = \"{name}\"\nkind = \"{kind}\"\nnumber = {number}\npriority = 3\n{extra}\n")
}

/// The one task of `text` (a scan program is added).
fn only_task(text: &str) -> TaskConfig {
    let config = config(&with_scan(text));
    assert_eq!(config.tasks.len(), 1);
    config.tasks[0].clone()
}

// ---- defaults and whole configs ----

#[test]
fn section_defaults_are_the_documented_ones() {
    assert_eq!(
        PlcConfig::default(),
        PlcConfig {
            watchdog_ms: 200,
            on_fault: OnFault::Clear,
            scan_period_ms: 0,
            continue_on_congestion: false
        }
    );
    assert_eq!(SimConfig::default().step_ns, 1000);
    assert_eq!(SimConfig::default().start_utc_ns, 0);
    let timers = TimerConfig::default();
    assert_eq!(timers.ms100, Some(0..=999));
    assert_eq!(timers.ms10, Some(1000..=1499));
    assert_eq!(timers.ms1, Some(1500..=2047));
    let io = IoConfig::default();
    assert_eq!(io.backend, Backend::Sim);
    assert_eq!((io.chip, io.stimulus, io.stimulus_loop), (None, None, false));
    assert!(io.inputs.is_empty() && io.outputs.is_empty());
    assert_eq!(
        RtConfig::default(),
        RtConfig {
            policy: RtPolicy::Fifo,
            scan_priority: 80,
            event_priority: 85,
            watchdog_priority: 90,
            scan_cpus: vec![],
            event_cpus: vec![],
            watchdog_cpus: vec![],
            lock_memory: true,
            cpu_dma_latency_us: None,
            require: false,
        }
    );
    assert_eq!(
        ControlConfig::default(),
        ControlConfig {
            enabled: true,
            socket: None,
            group: None,
            max_clients: 64,
            max_request_bytes: 65_536,
            idle_timeout_s: 300,
        }
    );
    assert_eq!(
        SwitchConfig::default(),
        SwitchConfig {
            line: None,
            active_low: false,
            bias: Bias::Disabled,
            debounce_us: 10_000,
            position: SwitchPosition::Run,
        }
    );
}

#[test]
fn a_minimal_config_takes_every_default() {
    let config = config("[[program]]\nfile = \"main.il\"\n");
    assert_eq!(config.path, PathBuf::from(PATH));
    assert_eq!(config.plc, PlcConfig::default());
    assert_eq!(config.sim, SimConfig::default());
    assert_eq!(config.timers, TimerConfig::default());
    assert_eq!(config.io, IoConfig::default());
    assert_eq!(config.rt, RtConfig::default());
    assert_eq!(config.control, ControlConfig::default());
    assert_eq!(config.switch, None);
    assert!(config.tasks.is_empty());
    assert_eq!(
        config.programs,
        [ProgramConfig {
            name: "main".into(),
            file: "main.il".into(),
            resolved: "etc/main.il".into(),
            task: TaskRef::Scan,
            language: Language::InstructionList,
            pou: None,
            configured: false,
            line: 2,
            col: 8,
        }]
    );
}

/// The full example of docs/CONFIG.md, verbatim: every section and kind of task.
const FULL_EXAMPLE: &str = r#"[plc]
watchdog_ms = 200          # scan watchdog, 10..=1000 (1 ms unit)
on_fault = "clear"         # outputs on a stopping error: "clear" or "hold"
scan_period_ms = 0         # 0 = free-running scan; N = a new scan starts every N ms
continue_on_congestion = false

[sim]
step_ns = 1000             # virtual time one executed instruction costs (sim only)

[timers]                   # timer base by timer number; these are the defaults
ms100 = "T0000-T0999"
ms10  = "T1000-T1499"
ms1   = "T1500-T2047"

[[program]]
name = "main"
file = "main.il"
task = "scan"              # "init", "scan", or the name of a [[task]]; several programs may share a task, run in file order

[[task]]
name = "10ms_cycle"
kind = "cycle"             # "cycle" | "io" | "device"
number = 0                 # cycle 0..=7, io 8..=15, device 16..=23; unique
priority = 3               # 2 (highest) ..= 7 (lowest)
interval_ms = 10           # cycle only: 1..=4294967295
# io only:     contact = "P0000" (P0000..=P0007), edge = "rising" | "falling" | "both"
# device only: device = "M0000", condition = "rising" | "falling" | "transition" | "on" | "off"   (bit device)
#              device = "D00010", condition = ">" | ">=" | "<" | "<=", value = 100              (word device)
# optional for every task: max_exec_ms = N   (congestion limit, see the Hitachi manual)

[io]
backend = "sim"            # "sim" (in-process, the default) | "gpiocdev"
# gpiocdev: chip = "/dev/gpiochip0" or a chip label
# [[io.input]]  device = "P0000", line = 17, active_low = false, bias = "pull-up"|"pull-down"|"disabled", debounce_us = 0
# [[io.output]] device = "P0040", line = 27, active_low = false
"#;

#[test]
fn the_contract_example_parses_to_its_defaults() {
    let config = config(FULL_EXAMPLE);
    let expected = Config {
        path: PATH.into(),
        plc: PlcConfig::default(),
        sim: SimConfig::default(),
        timers: TimerConfig::default(),
        programs: vec![ProgramConfig {
            name: "main".into(),
            file: "main.il".into(),
            resolved: "etc/main.il".into(),
            task: TaskRef::Scan,
            language: Language::InstructionList,
            pou: None,
            configured: false,
            line: 17,
            col: 8,
        }],
        tasks: vec![TaskConfig {
            name: "10ms_cycle".into(),
            number: 0,
            priority: 3,
            kind: TaskKind::Cycle { interval_ms: 10 },
            max_exec_ms: None,
            line: 20,
            col: 1,
        }],
        io: IoConfig::default(),
        rt: RtConfig::default(),
        control: crate::config::ControlConfig::default(),
        switch: None,
        retain: RetainConfig::default(),
        modbus: crate::config::ModbusConfig::default(),
        opcua: crate::config::OpcuaConfig::default(),
        mqtt: crate::config::MqttConfig::default(),
        st: StConfig::default(),
        iec: IecConfig::default(),
        remotes: Vec::new(),
        users: UsersConfig::default(),
    };
    assert_eq!(config, expected);
}

#[test]
fn every_kind_of_task_and_io_line_parses() {
    let text = r#"
[plc]
watchdog_ms = 50
on_fault = "hold"
scan_period_ms = 10
continue_on_congestion = true

[sim]
step_ns = 250
start = "2026-01-01-00:00:00.5"

[[program]]
file = "prog/init.il"
task = "init"
[[program]]
name = "logic"
file = "prog/main.il"
[[program]]
file = "fast.il"
task = "fast"
[[program]]
file = "irq.il"
task = "irq"
[[program]]
file = "level.il"
task = "level"

[[task]]
name = "fast"
kind = "cycle"
number = 7
priority = 2
interval_ms = 4294967295
max_exec_ms = 5

[[task]]
name = "irq"
kind = "io"
number = 15
priority = 7
contact = "P0007"
edge = "both"

[[task]]
name = "level"
kind = "device"
number = 23
priority = 4
device = "D00100"
condition = "<="
value = -32768

[[task]]
name = "flag"
kind = "device"
number = 16
priority = 4
device = "M0010"
condition = "transition"

[io]
backend = "gpiocdev"
chip = "/dev/gpiochip0"

[[io.input]]
device = "P0007"
line = 17
active_low = true
bias = "pull-up"
debounce_us = 4294967295

[[io.output]]
device = "P0040"
line = 0
"#;
    let config = config(text);
    assert_eq!(
        config.plc,
        PlcConfig {
            watchdog_ms: 50,
            on_fault: OnFault::Hold,
            scan_period_ms: 10,
            continue_on_congestion: true
        }
    );
    assert_eq!(config.sim.step_ns, 250);
    // 2026-01-01 is day 20454 after 1970-01-01; and half a second.
    assert_eq!(config.sim.start_utc_ns, 20_454 * 86_400_000_000_000 + 500_000_000);
    let programs: Vec<_> = config
        .programs
        .iter()
        .map(|p| (p.name.as_str(), p.resolved.to_str().unwrap(), p.task.name()))
        .collect();
    assert_eq!(
        programs,
        [
            ("init", "etc/prog/init.il", "init"),
            ("logic", "etc/prog/main.il", "scan"),
            ("fast", "etc/fast.il", "fast"),
            ("irq", "etc/irq.il", "irq"),
            ("level", "etc/level.il", "level"),
        ]
    );
    assert_eq!(config.programs[0].task, TaskRef::Init);
    assert_eq!(config.programs[2].task, TaskRef::Named("fast".into()));

    let kinds: Vec<_> = config
        .tasks
        .iter()
        .map(|t| (t.name.as_str(), t.number, t.priority, t.kind, t.max_exec_ms))
        .collect();
    assert_eq!(
        kinds,
        [
            ("fast", 7, 2, TaskKind::Cycle { interval_ms: u32::MAX }, Some(5)),
            ("irq", 15, 7, TaskKind::Io { contact: addr("P0007"), edge: Edge::Both }, None),
            (
                "level",
                23,
                4,
                TaskKind::Device {
                    device: addr("D00100"),
                    condition: DeviceCondition::LessEq(-32768)
                },
                None
            ),
            (
                "flag",
                16,
                4,
                TaskKind::Device { device: addr("M0010"), condition: DeviceCondition::Transition },
                None
            ),
        ]
    );
    assert_eq!(
        config.io,
        IoConfig {
            backend: Backend::Gpiocdev,
            chip: Some("/dev/gpiochip0".into()),
            inputs: vec![IoLine {
                device: addr("P0007"),
                line: LineRef::Offset(17),
                active_low: true,
                bias: Bias::PullUp,
                debounce_us: u32::MAX,
            }],
            outputs: vec![IoLine {
                device: addr("P0040"),
                line: LineRef::Offset(0),
                active_low: false,
                bias: Bias::Disabled,
                debounce_us: 0,
            }],
            stimulus: None,
            stimulus_loop: false,
        }
    );
}

// ---- [plc] and [sim] ----

#[test]
fn watchdog_range_is_10_to_1000() {
    assert_eq!(config(&with_scan("[plc]\nwatchdog_ms = 10")).plc.watchdog_ms, 10);
    assert_eq!(config(&with_scan("[plc]\nwatchdog_ms = 1000")).plc.watchdog_ms, 1000);
    assert_eq!(
        errors(&with_scan("[plc]\nwatchdog_ms = 9")),
        ["2:15: plc.watchdog_ms 9 out of range 10..=1000"]
    );
    assert_eq!(
        errors(&with_scan("[plc]\nwatchdog_ms = 1001")),
        ["2:15: plc.watchdog_ms 1001 out of range 10..=1000"]
    );
}

#[test]
fn scan_period_range_is_0_to_1000() {
    assert_eq!(config(&with_scan("[plc]\nscan_period_ms = 1000")).plc.scan_period_ms, 1000);
    assert_eq!(
        errors(&with_scan("[plc]\nscan_period_ms = 1001")),
        ["2:18: plc.scan_period_ms 1001 out of range 0..=1000"]
    );
    assert_eq!(
        errors(&with_scan("[plc]\nscan_period_ms = -1")),
        ["2:18: plc.scan_period_ms -1 out of range 0..=1000"]
    );
}

#[test]
fn on_fault_is_clear_or_hold() {
    assert_eq!(config(&with_scan("[plc]\non_fault = \"hold\"")).plc.on_fault, OnFault::Hold);
    assert_eq!(
        errors(&with_scan("[plc]\non_fault = \"keep\"")),
        ["2:12: plc.on_fault: unknown variant `keep`, expected `clear` or `hold`"]
    );
}

#[test]
fn step_ns_is_at_least_1() {
    assert_eq!(config(&with_scan("[sim]\nstep_ns = 1")).sim.step_ns, 1);
    assert_eq!(
        errors(&with_scan("[sim]\nstep_ns = 0")),
        ["2:11: sim.step_ns 0 must be at least 1"]
    );
}

// ---- syntax, unknown keys and types ----

#[test]
fn syntax_errors_are_located_and_stop_the_checks() {
    // No "no scan program" error: a broken document is not checked further.
    assert_eq!(
        errors("[plc]\nwatchdog_ms = = 5\n"),
        [
            "2:15: extra `=`, expected nothing",
            "2:17: unexpected key or value, expected newline, `#`"
        ]
    );
    assert_eq!(
        errors("[plc]\nwatchdog_ms = 5\nwatchdog_ms = 6\n"),
        ["3:1: duplicate key `watchdog_ms`"]
    );
}

#[test]
fn unknown_keys_are_errors_at_the_key() {
    assert_eq!(
        errors(&with_scan("[plcc]\n")),
        ["1:2: unknown key `plcc`, expected one of `plc`, `sim`, `timers`, `program`, `task`, \
          `io`, `rt`, `control`, `switch`, `retain`, `modbus`, `opcua`, `mqtt`, `st`, `iec`, \
          `remote`, `users`"]
    );
    assert_eq!(
        errors(&with_scan("[plc]\nwatchdog = 5\n")),
        ["2:1: [plc]: unknown key `watchdog`, expected one of `watchdog_ms`, `on_fault`, \
          `scan_period_ms`, `continue_on_congestion`"]
    );
    let errs = errors(&with_scan(&task("t", "cycle", 0, "interval_ms = 5\nintervall = 5")));
    assert_eq!(errs.len(), 1);
    assert!(
        errs[0].starts_with("7:1: task \"t\": unknown key `intervall`, expected one of"),
        "{errs:?}"
    );
    let errs = errors(&with_scan("[[io.input]]\ndevice = \"P0000\"\nline = 1\npull = \"up\""));
    assert!(errs[0].starts_with("4:1: io.input \"P0000\": unknown key `pull`"), "{errs:?}");
}

#[test]
fn wrong_types_name_the_key() {
    assert_eq!(
        errors(&with_scan("[plc]\nwatchdog_ms = \"200\"\ncontinue_on_congestion = 1")),
        [
            "2:15: plc.watchdog_ms: invalid type: string \"200\", expected an integer",
            "3:26: plc.continue_on_congestion: invalid type: integer `1`, expected a boolean",
        ]
    );
    assert_eq!(
        errors(&with_scan("[plc]\non_fault = 1")),
        ["2:12: plc.on_fault: expected a string"]
    );
    assert_eq!(errors(&with_scan("plc = 5")), ["1:7: `plc` must be a table, written [plc]"]);
    assert_eq!(
        errors(&with_scan("[task]\nname = \"t\"")),
        ["1:1: `task` must be an array of tables, written [[task]]"]
    );
}

#[test]
fn bad_enum_values_list_the_choices() {
    let errs = errors(&with_scan("[io]\nbackend = \"gpio\""));
    assert_eq!(errs, ["2:11: io.backend: unknown variant `gpio`, expected `sim` or `gpiocdev`"]);
    let errs = errors(&with_scan(&task("t", "timer", 0, "")));
    assert_eq!(
        errs,
        ["3:8: task \"t\": kind: unknown variant `timer`, expected one of `cycle`, `io`, `device`"]
    );
    let errs = errors(&with_scan(&task("t", "io", 8, "contact = \"P0000\"\nedge = \"up\"")));
    assert_eq!(errs, ["7:8: task \"t\": edge: unknown variant `up`, expected one of `rising`, `falling`, `both`"]);
    let errs = errors(&with_scan(&task("t", "device", 16, "device = \"D0\"\ncondition = \"==\"")));
    assert!(errs[0].starts_with("7:13: task \"t\": condition: unknown variant `==`"), "{errs:?}");
    let errs = errors(&with_scan("[[io.input]]\ndevice = \"P0000\"\nline = 1\nbias = \"up\""));
    assert!(errs[0].starts_with("4:8: io.input \"P0000\": bias: unknown variant `up`"), "{errs:?}");
}

// ---- tasks ----

#[test]
fn task_numbers_follow_the_kind() {
    for (kind, extra, numbers) in [
        ("cycle", "interval_ms = 1", 0..=7),
        ("io", "contact = \"P0000\"\nedge = \"rising\"", 8..=15),
        ("device", "device = \"M0000\"\ncondition = \"on\"", 16..=23),
    ] {
        for number in 0..=24 {
            let text = with_scan(&task("t", kind, number, extra));
            if numbers.contains(&number) {
                assert_eq!(only_task(&task("t", kind, number, extra)).number, number);
            } else {
                let message = format!(
                    "4:10: task \"t\": number {number} out of range {}..={} for a {kind} task",
                    numbers.start(),
                    numbers.end()
                );
                assert_eq!(errors(&text), [message]);
            }
        }
    }
}

#[test]
fn priority_is_2_to_7() {
    let text = |p: i64| {
        format!("[[task]]\nname = \"t\"\nkind = \"cycle\"\nnumber = 0\npriority = {p}\ninterval_ms = 1\n")
    };
    assert_eq!(only_task(&text(2)).priority, 2);
    assert_eq!(only_task(&text(7)).priority, 7);
    assert_eq!(errors(&with_scan(&text(1))), ["5:12: task \"t\": priority 1 out of range 2..=7"]);
    assert_eq!(errors(&with_scan(&text(8))), ["5:12: task \"t\": priority 8 out of range 2..=7"]);
}

#[test]
fn diagnostics_print_as_path_line_col() {
    // The brief's example, at its exact place: line 14, column 12.
    let text = format!(
        "{}\n{}",
        "#\n".repeat(8),
        "[[task]]\nname = \"fast\"\nkind = \"cycle\"\nnumber = 0\npriority = 9\ninterval_ms = 1\n"
    );
    let diags = parse(&with_scan(&text), Path::new(PATH)).unwrap_err();
    assert_eq!(
        diags.to_string(),
        "etc/plcd.toml:14:12: error: task \"fast\": priority 9 out of range 2..=7\n"
    );
}

#[test]
fn interval_is_1_to_u32_max_and_only_for_cycle_tasks() {
    assert_eq!(
        only_task(&task("t", "cycle", 0, "interval_ms = 1")).kind,
        TaskKind::Cycle { interval_ms: 1 }
    );
    assert_eq!(
        errors(&with_scan(&task("t", "cycle", 0, "interval_ms = 0"))),
        ["6:15: task \"t\": interval_ms 0 out of range 1..=4294967295"]
    );
    assert_eq!(
        errors(&with_scan(&task("t", "cycle", 0, "interval_ms = 4294967296"))),
        ["6:15: task \"t\": interval_ms 4294967296 out of range 1..=4294967295"]
    );
    assert_eq!(
        errors(&with_scan(&task("t", "cycle", 0, ""))),
        ["1:1: task \"t\": a cycle task needs `interval_ms`"]
    );
    assert_eq!(
        errors(&with_scan(&task(
            "t",
            "io",
            8,
            "contact = \"P0000\"\nedge = \"rising\"\ninterval_ms = 5"
        ))),
        ["8:15: task \"t\": interval_ms is only for cycle tasks"]
    );
}

#[test]
fn keys_of_other_kinds_are_errors() {
    let errs = errors(&with_scan(&task(
        "t",
        "cycle",
        0,
        "interval_ms = 5\ncontact = \"P0000\"\nedge = \"rising\"\ndevice = \"M0000\"\ncondition = \"on\"\nvalue = 1",
    )));
    assert_eq!(
        errs,
        [
            "7:11: task \"t\": contact is only for io tasks",
            "8:8: task \"t\": edge is only for io tasks",
            "9:10: task \"t\": device is only for device tasks",
            "10:13: task \"t\": condition is only for device tasks",
            "11:9: task \"t\": value is only for device tasks with a word condition (>, >=, <, <=)",
        ]
    );
    let errs = errors(&with_scan(&task(
        "t",
        "device",
        16,
        "device = \"M0000\"\ncondition = \"on\"\nedge = \"rising\"",
    )));
    assert_eq!(errs, ["8:8: task \"t\": edge is only for io tasks"]);
}

#[test]
fn io_tasks_need_a_contact_p0000_to_p0007_and_an_edge() {
    let t = only_task(&task("t", "io", 8, "contact = \"p0003\"\nedge = \"falling\""));
    assert_eq!(t.kind, TaskKind::Io { contact: addr("P0003"), edge: Edge::Falling });
    for contact in ["P0008", "P0010", "M0000", "P000"] {
        let errs = errors(&with_scan(&task(
            "t",
            "io",
            8,
            &format!("contact = \"{contact}\"\nedge = \"rising\""),
        )));
        assert_eq!(
            errs,
            [format!("6:11: task \"t\": contact \"{contact}\" must be one of P0000..=P0007")]
        );
    }
    assert_eq!(
        errors(&with_scan(&task("t", "io", 8, "contact = \"X1\"\nedge = \"rising\""))),
        ["6:11: task \"t\": contact: `X1` is not a device address"]
    );
    assert_eq!(
        errors(&with_scan(&task("t", "io", 8, ""))),
        ["1:1: task \"t\": an io task needs `contact`", "1:1: task \"t\": an io task needs `edge`"]
    );
}

#[test]
fn bit_conditions_need_a_bit_device() {
    for (device, condition, expected) in [
        ("M0000", "rising", DeviceCondition::Rising),
        ("P0040", "falling", DeviceCondition::Falling),
        ("K001F", "transition", DeviceCondition::Transition),
        ("D00010.3", "on", DeviceCondition::On),
        ("T0005", "off", DeviceCondition::Off),
        ("C2047", "on", DeviceCondition::On),
        ("SM400", "on", DeviceCondition::On),
        ("_T1S", "rising", DeviceCondition::Rising),
    ] {
        let t = only_task(&task(
            "t",
            "device",
            16,
            &format!("device = \"{device}\"\ncondition = \"{condition}\""),
        ));
        assert_eq!(
            t.kind,
            TaskKind::Device { device: addr(device), condition: expected },
            "{device}"
        );
    }
    assert_eq!(
        errors(&with_scan(&task("t", "device", 16, "device = \"D00010\"\ncondition = \"rising\""))),
        ["6:10: task \"t\": condition \"rising\": `D00010` is a word device, a bit is needed here"]
    );
    assert_eq!(
        errors(&with_scan(&task("t", "device", 16, "device = \"M000\"\ncondition = \"on\""))),
        ["6:10: task \"t\": condition \"on\": `M000` is a word device, a bit is needed here"]
    );
    assert_eq!(
        errors(&with_scan(&task(
            "t",
            "device",
            16,
            "device = \"M0000\"\ncondition = \"on\"\nvalue = 1"
        ))),
        ["8:9: task \"t\": value is only for device tasks with a word condition (>, >=, <, <=)"]
    );
}

#[test]
fn word_conditions_need_a_word_device_and_an_i16_value() {
    for (device, condition, expected) in [
        ("D00010", ">", DeviceCondition::Greater(5)),
        ("M001", ">=", DeviceCondition::GreaterEq(5)),
        ("T0005", "<", DeviceCondition::Less(5)),
        ("_SCAN_CUR", "<=", DeviceCondition::LessEq(5)),
    ] {
        let text = format!("device = \"{device}\"\ncondition = \"{condition}\"\nvalue = 5");
        let t = only_task(&task("t", "device", 16, &text));
        assert_eq!(
            t.kind,
            TaskKind::Device { device: addr(device), condition: expected },
            "{device}"
        );
    }
    let value = |v: i64| {
        task("t", "device", 16, &format!("device = \"D0\"\ncondition = \">\"\nvalue = {v}"))
    };
    assert_eq!(
        only_task(&value(32767)).kind,
        TaskKind::Device { device: addr("D0"), condition: DeviceCondition::Greater(32767) }
    );
    assert_eq!(
        errors(&with_scan(&value(32768))),
        ["8:9: task \"t\": value 32768 out of range -32768..=32767"]
    );
    assert_eq!(
        errors(&with_scan(&value(-32769))),
        ["8:9: task \"t\": value -32769 out of range -32768..=32767"]
    );
    assert_eq!(
        errors(&with_scan(&task(
            "t",
            "device",
            16,
            "device = \"M0000\"\ncondition = \">\"\nvalue = 1"
        ))),
        ["6:10: task \"t\": condition \">\": `M0000` is a bit device, a word is needed here"]
    );
    assert_eq!(
        errors(&with_scan(&task("t", "device", 16, "device = \"D0\"\ncondition = \"<\""))),
        ["1:1: task \"t\": condition \"<\" needs `value`"]
    );
    assert_eq!(
        errors(&with_scan(&task(
            "t",
            "device",
            16,
            "device = \"D99999\"\ncondition = \"<\"\nvalue = 1"
        ))),
        ["6:10: task \"t\": device: `D99999` is out of range (D00000-D32767)"]
    );
    assert_eq!(
        errors(&with_scan(&task("t", "device", 16, ""))),
        [
            "1:1: task \"t\": a device task needs `device`",
            "1:1: task \"t\": a device task needs `condition`"
        ]
    );
}

#[test]
fn max_exec_ms_is_at_least_1() {
    assert_eq!(
        only_task(&task("t", "cycle", 0, "interval_ms = 1\nmax_exec_ms = 1")).max_exec_ms,
        Some(1)
    );
    assert_eq!(
        errors(&with_scan(&task("t", "cycle", 0, "interval_ms = 1\nmax_exec_ms = 0"))),
        ["7:15: task \"t\": max_exec_ms 0 out of range 1..=4294967295"]
    );
}

#[test]
fn task_numbers_and_names_are_unique_and_not_reserved() {
    let text = [
        task("a", "cycle", 0, "interval_ms = 1"),
        task("a", "cycle", 1, "interval_ms = 1"),
        task("b", "cycle", 0, "interval_ms = 1"),
        task("Scan", "cycle", 2, "interval_ms = 1"),
        task("init", "cycle", 3, "interval_ms = 1"),
    ]
    .concat();
    assert_eq!(
        errors(&with_scan(&text)),
        [
            "8:8: task \"a\": name already used by the task at line 1",
            "16:10: task \"b\": number 0 is already used by task \"a\"",
            "20:8: task \"Scan\": the name \"Scan\" is reserved for the built-in task",
            "26:8: task \"init\": the name \"init\" is reserved for the built-in task",
        ]
    );
}

// ---- programs ----

#[test]
fn programs_name_existing_tasks() {
    let text = format!(
        "{}[[program]]\nfile = \"a.il\"\ntask = \"slow\"\n",
        task("fast", "cycle", 0, "interval_ms = 1")
    );
    assert_eq!(
        errors(&with_scan(&text)),
        ["9:8: program \"a\": task \"slow\" is not defined: expected \"init\", \"scan\" or the name of a [[task]]"]
    );
}

#[test]
fn a_task_with_errors_still_counts_as_defined() {
    // Only the task's own errors (the unknown key, and the key it was meant to be): the
    // program's reference to it is not reported as well.
    let text = format!(
        "{}[[program]]\nfile = \"a.il\"\ntask = \"fast\"\n",
        task("fast", "cycle", 0, "interval = 1")
    );
    let errs = errors(&with_scan(&text));
    assert_eq!(errs.len(), 2, "{errs:?}");
    assert_eq!(errs[0], "1:1: task \"fast\": a cycle task needs `interval_ms`");
    assert!(errs[1].starts_with("6:1: task \"fast\": unknown key `interval`"), "{errs:?}");
}

#[test]
fn an_entry_with_an_unknown_key_is_still_validated() {
    let text =
        task("full", "device", 16, "device = \"M0000\"\ncondition = \">\"\nvalue = 5\ncolour = 1");
    let errs = errors(&with_scan(&text));
    assert_eq!(errs.len(), 2, "{errs:?}");
    assert!(errs[0].contains("condition \">\": `M0000` is a bit device"), "{errs:?}");
    assert!(errs[1].contains("unknown key `colour`"), "{errs:?}");
}

#[test]
fn program_names_default_to_the_file_stem_and_are_unique() {
    let config = config("[[program]]\nfile = \"dir/logic.il\"\n[[program]]\nname = \"x\"\nfile = \"x.il\"\ntask = \"init\"\n");
    assert_eq!(config.programs[0].name, "logic");
    assert_eq!(config.programs[1].name, "x");
    assert_eq!(
        errors("[[program]]\nfile = \"main.il\"\n[[program]]\nfile = \"other/main.il\"\n"),
        ["4:8: program \"main\": name \"main\" is already used by the program at line 2"]
    );
    assert_eq!(
        errors("[[program]]\nfile = \"main.il\"\n[[program]]\nname = \"main\"\nfile = \"b.il\"\n"),
        ["4:8: program \"main\": name \"main\" is already used by the program at line 2"]
    );
    assert_eq!(
        errors(&with_scan("[[program]]\nname = \"\"\nfile = \"b.il\"")),
        ["2:8: program \"\": name must not be empty"]
    );
}

#[test]
fn a_program_without_file_is_an_error_at_its_table() {
    assert_eq!(
        errors(&with_scan("\n[[program]]\nname = \"a\"\ntask = \"init\"\n")),
        ["2:1: program \"a\": missing key `file`"]
    );
    assert_eq!(
        errors(&with_scan("[[program]]\nfile = \"\"")),
        ["2:8: program #1: file must not be empty"]
    );
}

#[test]
fn a_plc_needs_a_scan_program() {
    let expected = "0:0: no [[program]] runs in the scan task: a PLC needs a scan program \
                    (a [[program]] with task = \"scan\", the default)";
    assert_eq!(errors(""), [expected]);
    assert_eq!(errors("[[program]]\nfile = \"init.il\"\ntask = \"init\"\n"), [expected]);
    assert_eq!(
        config("[[program]]\nfile = \"main.il\"\ntask = \"scan\"\n").programs[0].task,
        TaskRef::Scan
    );
}

#[test]
fn program_and_stimulus_paths_resolve_against_the_config_directory() {
    let text = "[[program]]\nfile = \"main.il\"\n[[program]]\nfile = \"../lib/x.il\"\n\
                [[program]]\nfile = \"/opt/plc/abs.il\"\n[io]\nstimulus = \"in.csv\"\n";
    let resolved = |path: &str| {
        let config = parse(text, Path::new(path)).unwrap();
        let mut paths: Vec<PathBuf> = config.programs.iter().map(|p| p.resolved.clone()).collect();
        paths.extend(config.io.stimulus);
        paths
    };
    assert_eq!(
        resolved("etc/plcd.toml"),
        ["etc/main.il", "etc/../lib/x.il", "/opt/plc/abs.il", "etc/in.csv"].map(PathBuf::from)
    );
    assert_eq!(
        resolved("plcd.toml"),
        ["main.il", "../lib/x.il", "/opt/plc/abs.il", "in.csv"].map(PathBuf::from)
    );
    assert_eq!(resolved("/srv/plc/plcd.toml")[0], PathBuf::from("/srv/plc/main.il"));
    // `file` keeps what was written.
    let config = parse(text, Path::new("etc/plcd.toml")).unwrap();
    assert_eq!(config.programs[1].file, PathBuf::from("../lib/x.il"));
}

// ---- [timers] ----

#[test]
fn timer_ranges_override_and_clear() {
    let timers = config(&with_scan(
        "[timers]\nms100 = \"T0000-T0099\"\nms10 = \"\"\nms1 = \"T2000 - T2047\"",
    ))
    .timers;
    assert_eq!(timers, TimerConfig { ms100: Some(0..=99), ms10: None, ms1: Some(2000..=2047) });
    // A key not given keeps its default.
    let timers = config(&with_scan("[timers]\nms1 = \"T1500-T1599\"")).timers;
    assert_eq!(timers, TimerConfig { ms1: Some(1500..=1599), ..TimerConfig::default() });
}

#[test]
fn base_ms_at_the_range_edges() {
    let timers = TimerConfig::default();
    for (timer, base) in [
        (0, Some(100)),
        (999, Some(100)),
        (1000, Some(10)),
        (1499, Some(10)),
        (1500, Some(1)),
        (2047, Some(1)),
        (2048, None),
    ] {
        assert_eq!(timers.base_ms(timer), base, "T{timer}");
    }
    let timers = config(&with_scan("[timers]\nms10 = \"T1000-T1009\"\nms1 = \"\"")).timers;
    assert_eq!(timers.base_ms(1009), Some(10));
    assert_eq!(timers.base_ms(1010), None);
    assert_eq!(timers.base_ms(2047), None);
}

#[test]
fn overlapping_timer_ranges_name_both_keys() {
    assert_eq!(
        errors(&with_scan("[timers]\nms100 = \"T0000-T1000\"")),
        ["2:9: timers.ms100 \"T0000-T1000\" overlaps timers.ms10 \"T1000-T1499\" (its default)"]
    );
    assert_eq!(
        errors(&with_scan("[timers]\nms1 = \"T0000-T0000\"\nms100 = \"\"\nms10 = \"T0000-T0009\"")),
        ["4:8: timers.ms10 \"T0000-T0009\" overlaps timers.ms1 \"T0000-T0000\""]
    );
}

#[test]
fn malformed_timer_ranges() {
    assert_eq!(
        errors(&with_scan(
            "[timers]\nms100 = \"T0999-T0000\"\nms10 = \"T1000\"\nms1 = \"T1500-T2048\"\n"
        )),
        [
            "2:9: timers.ms100: \"T0999-T0000\" is backwards: T0999 comes after T0000",
            "3:8: timers.ms10: \"T1000\" is not a range \"Txxxx-Tyyyy\" (or \"\" for none)",
            "4:7: timers.ms1: `T2048` is out of range (T0000-T2047)",
        ]
    );
    assert_eq!(
        errors(&with_scan("[timers]\nms1 = \"C0000-C0010\"")),
        ["2:7: timers.ms1: `C0000` is not a timer (T0000-T2047)"]
    );
}

// ---- [io] ----

#[test]
fn gpiocdev_needs_a_chip() {
    assert_eq!(
        errors(&with_scan("[io]\nbackend = \"gpiocdev\"")),
        ["1:1: io.chip is required for the gpiocdev backend"]
    );
    let config = config(&with_scan("[io]\nbackend = \"gpiocdev\"\nchip = \"pinctrl-bcm2711\""));
    assert_eq!(config.io.chip.as_deref(), Some("pinctrl-bcm2711"));
}

#[test]
fn a_chip_label_is_at_most_31_bytes() {
    let gpio = |chip: &str| format!("[io]\nbackend = \"gpiocdev\"\nchip = {chip:?}\n");
    let label = "pinctrl-of-a-board-with-a-long-name";
    assert_eq!(
        errors(&with_scan(&gpio(label))),
        [format!(
            "3:8: io.chip {label:?} is 35 bytes long, but the kernel reports chip labels of at \
             most 31 bytes: no chip is labelled so (a path starts with `/`)"
        )]
    );
    let at_most = "x".repeat(LINE_NAME_MAX);
    assert_eq!(config(&with_scan(&gpio(&at_most))).io.chip, Some(at_most));
    // A path may be longer.
    let path = "/dev/gpio/by-label/pinctrl-of-a-board-with-a-long-name";
    assert_eq!(config(&with_scan(&gpio(path))).io.chip.as_deref(), Some(path));
}

#[test]
fn io_devices_are_p_bits() {
    for device in ["M0000", "P000", "D00001.1"] {
        let text = format!("[[io.input]]\ndevice = \"{device}\"\nline = 1");
        assert_eq!(
            errors(&with_scan(&text)),
            [format!(
                "2:10: io.input \"{device}\": device \"{device}\" is not a P bit (P0000..=P127F)"
            )]
        );
    }
    assert_eq!(
        errors(&with_scan("[[io.output]]\ndevice = \"P1280\"\nline = 1")),
        ["2:10: io.output \"P1280\": device: `P1280` is out of range (P0000-P127F, P000-P127)"]
    );
}

#[test]
fn io_devices_and_lines_are_unique_across_inputs_and_outputs() {
    let text = "[[io.output]]\ndevice = \"P0040\"\nline = 5\n\
                [[io.input]]\ndevice = \"P0000\"\nline = 5\n\
                [[io.input]]\ndevice = \"P0040\"\nline = 6\n";
    assert_eq!(
        errors(&with_scan(text)),
        [
            "6:8: io.input \"P0000\": line 5 is already used by io.output \"P0040\"",
            "8:10: io.input \"P0040\": device P0040 is already used by io.output \"P0040\"",
        ]
    );
}

#[test]
fn bias_and_debounce_are_for_inputs_only() {
    let text =
        "[[io.output]]\ndevice = \"P0040\"\nline = 5\nbias = \"pull-up\"\ndebounce_us = 10\n";
    assert_eq!(
        errors(&with_scan(text)),
        [
            "4:8: io.output \"P0040\": bias is only for inputs",
            "5:15: io.output \"P0040\": debounce_us is only for inputs"
        ]
    );
    let config = config(&with_scan(
        "[[io.input]]\ndevice = \"P0000\"\nline = 5\nbias = \"pull-down\"\ndebounce_us = 10\n",
    ));
    assert_eq!(config.io.inputs[0].bias, Bias::PullDown);
    assert_eq!(config.io.inputs[0].debounce_us, 10);
}

#[test]
fn io_line_ranges() {
    assert_eq!(
        errors(&with_scan("[[io.input]]\ndevice = \"P0000\"\nline = -1\ndebounce_us = 4294967296")),
        [
            "3:8: io.input \"P0000\": line -1 out of range 0..=4294967295",
            "4:15: io.input \"P0000\": debounce_us 4294967296 out of range 0..=4294967295",
        ]
    );
    assert_eq!(
        errors(&with_scan("[[io.input]]\ndevice = \"P0000\"")),
        ["1:1: io.input \"P0000\": missing key `line`"]
    );
}

#[test]
fn gpiocdev_io_task_contacts_must_be_inputs() {
    let io = "[io]\nbackend = \"gpiocdev\"\nchip = \"gpiochip0\"\n[[io.input]]\ndevice = \"P0001\"\nline = 3\n";
    let irq = |contact: &str| {
        task("irq", "io", 8, &format!("contact = \"{contact}\"\nedge = \"rising\""))
    };
    assert_eq!(
        errors(&with_scan(&format!("{}{io}", irq("P0000")))),
        ["6:11: task \"irq\": contact P0000 is not wired: add an [[io.input]] with device = \"P0000\" \
          (the gpiocdev backend could never start the task)"]
    );
    config(&with_scan(&format!("{}{io}", irq("P0001"))));
    // The sim backend drives any P bit: nothing to wire.
    config(&with_scan(&irq("P0000")));
    // An output is not an input.
    let output = "[[io.output]]\ndevice = \"P0002\"\nline = 4\n";
    let errs = errors(&with_scan(&format!("{}{io}{output}", irq("P0002"))));
    assert_eq!(errs.len(), 1, "{errs:?}");
    assert!(errs[0].starts_with("6:11: task \"irq\": contact P0002 is not wired"), "{errs:?}");
    // An input entry with errors may have been the contact's: only its own error is reported.
    let broken = "[[io.input]]\ndevice = \"P0000\"\nline = true\n";
    assert_eq!(
        errors(&with_scan(&format!("{}{io}{broken}", irq("P0000")))),
        ["16:8: io.input \"P0000\": line: invalid type: boolean `true`, expected a line offset \
          (an integer) or a line name (a string)"]
    );
}

#[test]
fn an_output_device_cannot_also_be_an_input() {
    // The later entry is reported, naming the earlier (an output first: see above).
    let text = "[[io.input]]\ndevice = \"P0000\"\nline = 1\n\
                [[io.output]]\ndevice = \"P0000\"\nline = 2\n";
    assert_eq!(
        errors(&with_scan(text)),
        ["5:10: io.output \"P0000\": device P0000 is already used by io.input \"P0000\""]
    );
}

#[test]
fn stimulus_is_for_the_sim_backend() {
    let gpio = "[io]\nbackend = \"gpiocdev\"\nchip = \"gpiochip0\"\n";
    assert_eq!(
        errors(&with_scan(&format!("{gpio}stimulus = \"in.csv\""))),
        ["4:12: io.stimulus is for the sim backend: the gpiocdev backend reads its inputs from \
          the chip's lines"]
    );
    let config = config(&with_scan("[io]\nbackend = \"sim\"\nstimulus = \"in.csv\""));
    assert_eq!(config.io.stimulus, Some(PathBuf::from("etc/in.csv")));
}

// ---- [rt] ----

#[test]
fn rt_keys_parse() {
    let text = "[rt]\npolicy = \"other\"\nscan_priority = 1\nevent_priority = 2\n\
                watchdog_priority = 99\nscan_cpus = [3, 1023]\nevent_cpus = [0]\n\
                watchdog_cpus = []\nlock_memory = false\ncpu_dma_latency_us = 0\nrequire = true";
    assert_eq!(
        config(&with_scan(text)).rt,
        RtConfig {
            policy: RtPolicy::Other,
            scan_priority: 1,
            event_priority: 2,
            watchdog_priority: 99,
            scan_cpus: vec![3, 1023],
            event_cpus: vec![0],
            watchdog_cpus: vec![],
            lock_memory: false,
            cpu_dma_latency_us: Some(0),
            require: true,
        }
    );
    // A key not given keeps its default; one CPU may serve every thread.
    let text = "[rt]\npolicy = \"fifo\"\nscan_priority = 50\nscan_cpus = [1]\nevent_cpus = [1]";
    assert_eq!(
        config(&with_scan(text)).rt,
        RtConfig {
            scan_priority: 50,
            scan_cpus: vec![1],
            event_cpus: vec![1],
            ..RtConfig::default()
        }
    );
    assert_eq!(config(&with_scan("[rt]\n")).rt, RtConfig::default());
}

#[test]
fn rt_priorities_are_1_to_99() {
    for (key, col) in [("scan_priority", 17), ("event_priority", 18), ("watchdog_priority", 21)] {
        for value in [0, 100, -1, 256] {
            assert_eq!(
                errors(&with_scan(&format!("[rt]\n{key} = {value}"))),
                [format!("2:{col}: rt.{key} {value} out of range 1..=99")]
            );
        }
    }
}

#[test]
fn rt_priorities_rise_from_scan_to_event_to_watchdog() {
    // Both keys written: the error is at the later one.
    assert_eq!(
        errors(&with_scan("[rt]\nscan_priority = 85\nevent_priority = 85")),
        ["3:18: rt.event_priority 85 must be above rt.scan_priority 85"]
    );
    assert_eq!(
        errors(&with_scan("[rt]\nevent_priority = 70\nscan_priority = 75")),
        ["3:17: rt.scan_priority 75 must be below rt.event_priority 70"]
    );
    // One written: the error is at it, naming the other's default.
    assert_eq!(
        errors(&with_scan("[rt]\nscan_priority = 86")),
        ["2:17: rt.scan_priority 86 must be below rt.event_priority 85 (its default)"]
    );
    assert_eq!(
        errors(&with_scan("[rt]\nevent_priority = 95")),
        ["2:18: rt.event_priority 95 must be below rt.watchdog_priority 90 (its default)"]
    );
    assert_eq!(
        errors(&with_scan("[rt]\nwatchdog_priority = 85")),
        ["2:21: rt.watchdog_priority 85 must be above rt.event_priority 85 (its default)"]
    );
    // Both pairs out of order: both reported.
    assert_eq!(
        errors(&with_scan("[rt]\nscan_priority = 90\nevent_priority = 90\nwatchdog_priority = 90")),
        [
            "3:18: rt.event_priority 90 must be above rt.scan_priority 90",
            "4:21: rt.watchdog_priority 90 must be above rt.event_priority 90",
        ]
    );
    // With the event priority out of range, scan and watchdog are still compared.
    assert_eq!(
        errors(&with_scan("[rt]\nscan_priority = 95\nevent_priority = 0")),
        [
            "2:17: rt.scan_priority 95 must be below rt.watchdog_priority 90 (its default)",
            "3:18: rt.event_priority 0 out of range 1..=99",
        ]
    );
    // A malformed priority is unknown, not its default (80, which 70 would be below).
    assert_eq!(
        errors(&with_scan("[rt]\nscan_priority = \"high\"\nevent_priority = 70")),
        ["2:17: rt.scan_priority: invalid type: string \"high\", expected an integer"]
    );
}

#[test]
fn rt_cpus_are_0_to_1023_each_listed_once() {
    assert_eq!(
        errors(&with_scan(
            "[rt]\nscan_cpus = [0, -1, 1024]\nevent_cpus = [2, 3, 2, 3]\nwatchdog_cpus = [5, 5]"
        )),
        [
            "2:17: rt.scan_cpus: CPU -1 out of range 0..=1023",
            "2:21: rt.scan_cpus: CPU 1024 out of range 0..=1023",
            "3:21: rt.event_cpus: CPU 2 is listed twice",
            "3:24: rt.event_cpus: CPU 3 is listed twice",
            "4:21: rt.watchdog_cpus: CPU 5 is listed twice",
        ]
    );
}

#[test]
fn rt_unknown_keys_and_wrong_types() {
    assert_eq!(
        errors(&with_scan("[rt]\nscan_prio = 80")),
        ["2:1: [rt]: unknown key `scan_prio`, expected one of `policy`, `scan_priority`, \
          `event_priority`, `watchdog_priority`, `scan_cpus`, `event_cpus`, `watchdog_cpus`, \
          `lock_memory`, `cpu_dma_latency_us`, `require`"]
    );
    assert_eq!(
        errors(&with_scan(
            "[rt]\npolicy = \"rr\"\nscan_cpus = 3\nevent_cpus = [1, \"2\"]\n\
             lock_memory = \"yes\"\nrequire = 1"
        )),
        [
            "2:10: rt.policy: unknown variant `rr`, expected `fifo` or `other`",
            "3:13: rt.scan_cpus: invalid type: integer `3`, expected a sequence",
            "4:18: rt.event_cpus: invalid type: string \"2\", expected an integer",
            "5:15: rt.lock_memory: invalid type: string \"yes\", expected a boolean",
            "6:11: rt.require: invalid type: integer `1`, expected a boolean",
        ]
    );
    assert_eq!(errors(&with_scan("rt = 5")), ["1:6: `rt` must be a table, written [rt]"]);
}

#[test]
fn cpu_dma_latency_takes_microseconds_or_minus_one() {
    let rt = |line: &str| config(&with_scan(&format!("[rt]\n{line}"))).rt.cpu_dma_latency_us;
    assert_eq!(rt("cpu_dma_latency_us = 20"), Some(20));
    assert_eq!(rt("cpu_dma_latency_us = 2000000000"), Some(2_000_000_000));
    assert_eq!(rt("cpu_dma_latency_us = -1"), None);
    assert_eq!(
        errors(&with_scan("[rt]\ncpu_dma_latency_us = -2")),
        ["2:22: rt.cpu_dma_latency_us -2 out of range -1..=2000000000"]
    );
}

#[test]
fn every_rt_error_is_reported_at_once() {
    let text = r#"[plc]
watchdog_ms = 5

[rt]
policy = "realtime"
scan_priority = 95
event_priority = 100
watchdog_priority = 80
scan_cpus = [1, 1]
event_cpus = [2048]
lock_memory = "yes"
priority = 5
"#;
    assert_eq!(
        errors(&with_scan(text)),
        [
            "2:15: plc.watchdog_ms 5 out of range 10..=1000",
            "5:10: rt.policy: unknown variant `realtime`, expected `fifo` or `other`",
            "7:18: rt.event_priority 100 out of range 1..=99",
            "8:21: rt.watchdog_priority 80 must be above rt.scan_priority 95",
            "9:17: rt.scan_cpus: CPU 1 is listed twice",
            "10:15: rt.event_cpus: CPU 2048 out of range 0..=1023",
            "11:15: rt.lock_memory: invalid type: string \"yes\", expected a boolean",
            "12:1: [rt]: unknown key `priority`, expected one of `policy`, `scan_priority`, \
             `event_priority`, `watchdog_priority`, `scan_cpus`, `event_cpus`, `watchdog_cpus`, \
             `lock_memory`, `cpu_dma_latency_us`, `require`",
        ]
    );
}

// ---- [control] ----

#[test]
fn control_keys_parse() {
    let text = "[control]\nenabled = false\nsocket = \"run/plcd.sock\"\ngroup = \"plc\"\n\
                max_clients = 8\nmax_request_bytes = 4096\nidle_timeout_s = 0";
    assert_eq!(
        config(&with_scan(text)).control,
        ControlConfig {
            enabled: false,
            socket: Some(PathBuf::from("etc/run/plcd.sock")),
            group: Some("plc".into()),
            max_clients: 8,
            max_request_bytes: 4096,
            idle_timeout_s: 0,
        }
    );
    // A key not given keeps its default; an empty section is all defaults.
    let control = config(&with_scan("[control]\nmax_clients = 2")).control;
    assert_eq!(control, ControlConfig { max_clients: 2, ..ControlConfig::default() });
    assert_eq!(config(&with_scan("[control]\n")).control, ControlConfig::default());
}

#[test]
fn control_socket_resolves_against_the_config_directory() {
    let socket = |config_path: &str, socket: &str| {
        let text = with_scan(&format!("[control]\nsocket = \"{socket}\""));
        parse(&text, Path::new(config_path)).unwrap().control.socket.unwrap()
    };
    assert_eq!(socket("etc/plcd.toml", "plcd.sock"), PathBuf::from("etc/plcd.sock"));
    assert_eq!(
        socket("/srv/plc/plcd.toml", "../s/plcd.sock"),
        PathBuf::from("/srv/plc/../s/plcd.sock")
    );
    assert_eq!(socket("plcd.toml", "plcd.sock"), PathBuf::from("plcd.sock"));
    assert_eq!(socket("etc/plcd.toml", "/run/plcd/x.sock"), PathBuf::from("/run/plcd/x.sock"));
}

#[test]
fn control_socket_and_group_are_not_empty() {
    assert_eq!(
        errors(&with_scan("[control]\nsocket = \"\"\ngroup = \" \"")),
        ["2:10: control.socket must not be empty", "3:9: control.group must not be empty"]
    );
}

#[test]
fn control_socket_fits_a_unix_socket_address() {
    // 107 bytes resolved is the most; "etc/" counts.
    let fits = format!("{}.sock", "s".repeat(107 - 4 - 5));
    let socket = config(&with_scan(&format!("[control]\nsocket = \"{fits}\""))).control.socket;
    assert_eq!(socket.unwrap().as_os_str().len(), 107);
    let long = format!("{}.sock", "s".repeat(107 - 4 - 5 + 1));
    assert_eq!(
        errors(&with_scan(&format!("[control]\nsocket = \"{long}\""))),
        [format!(
            "2:10: control.socket \"{long}\" is 108 bytes long as resolved (etc/{long}); a Unix \
             socket path holds at most 107"
        )]
    );
}

#[test]
fn control_max_clients_is_1_to_1024() {
    assert_eq!(config(&with_scan("[control]\nmax_clients = 1")).control.max_clients, 1);
    assert_eq!(config(&with_scan("[control]\nmax_clients = 1024")).control.max_clients, 1024);
    assert_eq!(
        errors(&with_scan("[control]\nmax_clients = 0")),
        ["2:15: control.max_clients 0 out of range 1..=1024"]
    );
    assert_eq!(
        errors(&with_scan("[control]\nmax_clients = 1025")),
        ["2:15: control.max_clients 1025 out of range 1..=1024"]
    );
}

#[test]
fn control_max_request_bytes_is_256_to_1048576() {
    let bytes = |n: &str| config(&with_scan(&format!("[control]\nmax_request_bytes = {n}")));
    assert_eq!(bytes("256").control.max_request_bytes, 256);
    assert_eq!(bytes("1048576").control.max_request_bytes, 1_048_576);
    assert_eq!(
        errors(&with_scan("[control]\nmax_request_bytes = 255")),
        ["2:21: control.max_request_bytes 255 out of range 256..=1048576"]
    );
    assert_eq!(
        errors(&with_scan("[control]\nmax_request_bytes = 1048577")),
        ["2:21: control.max_request_bytes 1048577 out of range 256..=1048576"]
    );
}

#[test]
fn control_idle_timeout_is_a_u32_and_0_is_never() {
    assert_eq!(config(&with_scan("[control]\nidle_timeout_s = 0")).control.idle_timeout_s, 0);
    let max = config(&with_scan("[control]\nidle_timeout_s = 4294967295")).control;
    assert_eq!(max.idle_timeout_s, u32::MAX);
    assert_eq!(
        errors(&with_scan("[control]\nidle_timeout_s = -1\n")),
        ["2:18: control.idle_timeout_s -1 out of range 0..=4294967295"]
    );
    assert_eq!(
        errors(&with_scan("[control]\nidle_timeout_s = 4294967296\n")),
        ["2:18: control.idle_timeout_s 4294967296 out of range 0..=4294967295"]
    );
}

#[test]
fn control_unknown_keys_and_wrong_types() {
    assert_eq!(
        errors(&with_scan("[control]\nsocket_path = \"x\"")),
        ["2:1: [control]: unknown key `socket_path`, expected one of `enabled`, `socket`, `group`, \
          `max_clients`, `max_request_bytes`, `idle_timeout_s`"]
    );
    assert_eq!(
        errors(&with_scan(
            "[control]\nenabled = \"yes\"\nsocket = 1\ngroup = 100\nmax_clients = \"8\"\n\
             max_request_bytes = 1.5\nidle_timeout_s = true"
        )),
        [
            "2:11: control.enabled: invalid type: string \"yes\", expected a boolean",
            "3:10: control.socket: invalid type: integer `1`, expected a string",
            "4:9: control.group: invalid type: integer `100`, expected a string",
            "5:15: control.max_clients: invalid type: string \"8\", expected an integer",
            "6:21: control.max_request_bytes: invalid type: floating point `1.5`, expected an \
             integer",
            "7:18: control.idle_timeout_s: invalid type: boolean `true`, expected an integer",
        ]
    );
    assert_eq!(
        errors(&with_scan("control = true")),
        ["1:11: `control` must be a table, written [control]"]
    );
}

#[test]
fn every_control_error_is_reported_at_once() {
    let text = "[control]\nsocket = \"\"\ngroup = \"\"\nmax_clients = 0\n\
                max_request_bytes = 2000000\nidle_timeout_s = -5\ntimeout = 1\n";
    assert_eq!(
        errors(&with_scan(text)),
        [
            "2:10: control.socket must not be empty",
            "3:9: control.group must not be empty",
            "4:15: control.max_clients 0 out of range 1..=1024",
            "5:21: control.max_request_bytes 2000000 out of range 256..=1048576",
            "6:18: control.idle_timeout_s -5 out of range 0..=4294967295",
            "7:1: [control]: unknown key `timeout`, expected one of `enabled`, `socket`, \
             `group`, `max_clients`, `max_request_bytes`, `idle_timeout_s`",
        ]
    );
}

// ---- [switch] ----

const GPIO: &str = "[io]\nbackend = \"gpiocdev\"\nchip = \"gpiochip0\"\n";

#[test]
fn no_switch_section_is_no_switch() {
    assert_eq!(config(&with_scan("")).switch, None);
    assert_eq!(config(&with_scan(GPIO)).switch, None);
}

#[test]
fn io_lines_are_offsets_or_names() {
    let text = "[[io.input]]\ndevice = \"P0000\"\nline = \"GPIO17\"\n\
                [[io.input]]\ndevice = \"P0001\"\nline = 27\n\
                [[io.output]]\ndevice = \"P0040\"\nline = \"GPIO23\"\nactive_low = true\n";
    for backend in ["sim", "gpiocdev"] {
        let io = format!("[io]\nbackend = \"{backend}\"\nchip = \"pinctrl-bcm2711\"\n{text}");
        let config = config(&with_scan(&io));
        let lines: Vec<&LineRef> =
            config.io.inputs.iter().chain(&config.io.outputs).map(|l| &l.line).collect();
        assert_eq!(
            lines,
            [
                &LineRef::Name("GPIO17".into()),
                &LineRef::Offset(27),
                &LineRef::Name("GPIO23".into())
            ]
        );
        assert!(config.io.outputs[0].active_low);
        assert!(config.uses_line_names());
    }
    assert!(!config(&with_scan("[[io.input]]\ndevice = \"P0000\"\nline = 17")).uses_line_names());
    // Any name the kernel could report: spaces, punctuation, other scripts.
    for name in ["-", "PIN 11", "RP1 RUN", "Ünter_3", "a", &"X".repeat(LINE_NAME_MAX)] {
        let text = format!("[[io.input]]\ndevice = \"P0000\"\nline = {name:?}");
        assert_eq!(config(&with_scan(&text)).io.inputs[0].line, LineRef::Name(name.to_string()));
    }
    assert_eq!(LineRef::Name("GPIO17".into()).to_string(), "\"GPIO17\"");
    assert_eq!(LineRef::Offset(17).to_string(), "17");
    assert_eq!(LineRef::Offset(17).offset(), Some(17));
    assert_eq!(LineRef::Name("GPIO17".into()).name(), Some("GPIO17"));
}

#[test]
fn what_a_line_name_must_be() {
    let input = |line: &str| with_scan(&format!("[[io.input]]\ndevice = \"P0000\"\nline = {line}"));
    assert_eq!(
        errors(&input("\"\"")),
        ["3:8: io.input \"P0000\": line must not be empty: a line name (\"GPIO17\") or an offset \
          (17)"]
    );
    // The kernel reports names in 32 bytes with their NUL: 31 is the most that can match.
    let long = "GPIO_OF_A_NAME_LONGER_THAN_31_BYTES";
    assert_eq!(
        errors(&input(&format!("{long:?}"))),
        [format!(
            "3:8: io.input \"P0000\": line {long:?} is 35 bytes long, but the kernel reports line \
             names of at most 31 bytes: no line is named so"
        )]
    );
    // Bytes, not characters: 16 two-byte characters are 32 bytes.
    assert_eq!(errors(&input(&format!("{:?}", "é".repeat(16)))).len(), 1);
    assert_eq!(
        errors(&input("\"17\"")),
        ["3:8: io.input \"P0000\": line \"17\" is a number in quotes: an offset is written \
          without them (line = 17)"]
    );
    assert_eq!(
        errors(&input("[17]")),
        ["3:8: io.input \"P0000\": line: invalid type: sequence, expected a line offset (an \
          integer) or a line name (a string)"]
    );
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}[switch]\nline = \"\""))),
        ["5:8: switch.line must not be empty: a line name (\"GPIO17\") or an offset (17)"]
    );
}

#[test]
fn a_line_name_is_used_once() {
    // As with offsets: the later entry is reported, naming the earlier.
    let text = "[[io.input]]\ndevice = \"P0000\"\nline = \"GPIO17\"\n\
                [[io.output]]\ndevice = \"P0040\"\nline = \"GPIO17\"\n";
    assert_eq!(
        errors(&with_scan(text)),
        ["6:8: io.output \"P0040\": line \"GPIO17\" is already used by io.input \"P0000\""]
    );
    // Names are the kernel's, case-sensitive: these are two names (a chip may have both, and
    // if it has one only, the other fails `plcd run` with it as a near name).
    config(&with_scan(&text.replacen("\"GPIO17\"", "\"gpio17\"", 1)));
    // A name and an offset may be one line: only the chip can tell (`plcd run`).
    config(&with_scan(&text.replacen("\"GPIO17\"", "17", 1)));
    // The switch's line too, whichever comes first in the file.
    let wiring = "[[io.input]]\ndevice = \"P0000\"\nline = \"GPIO5\"\n";
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}{wiring}[switch]\nline = \"GPIO5\""))),
        ["8:8: switch.line \"GPIO5\" is already used by io.input \"P0000\""]
    );
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}[switch]\nline = \"GPIO5\"\n{wiring}"))),
        ["8:8: io.input \"P0000\": line \"GPIO5\" is already used by [switch]"]
    );
    config(&with_scan(&format!("{GPIO}{wiring}[switch]\nline = 5")));
    let switch = config(&with_scan(&format!("{GPIO}[switch]\nline = \"KEY\""))).switch.unwrap();
    assert_eq!(switch.line, Some(LineRef::Name("KEY".into())));
}

#[test]
fn a_sim_switch_starts_at_its_position() {
    assert_eq!(config(&with_scan("[switch]\n")).switch, Some(SwitchConfig::default()));
    let switch = config(&with_scan("[switch]\nposition = \"stop\"")).switch.unwrap();
    assert_eq!(switch, SwitchConfig { position: SwitchPosition::Stop, ..SwitchConfig::default() });
    let switch = config(&with_scan("[switch]\nposition = \"run\"")).switch.unwrap();
    assert_eq!(switch.position, SwitchPosition::Run);
    // The line settings mean nothing to the sim backend, but are not wrong there.
    let text = "[switch]\nactive_low = true\nbias = \"pull-up\"\ndebounce_us = 0";
    assert_eq!(config(&with_scan(text)).switch.unwrap().bias, Bias::PullUp);
}

#[test]
fn a_gpio_switch_has_a_line_with_settings() {
    let text = format!(
        "{GPIO}[switch]\nline = 7\nactive_low = true\nbias = \"pull-down\"\ndebounce_us = 500"
    );
    assert_eq!(
        config(&with_scan(&text)).switch,
        Some(SwitchConfig {
            line: Some(LineRef::Offset(7)),
            active_low: true,
            bias: Bias::PullDown,
            debounce_us: 500,
            position: SwitchPosition::Run,
        })
    );
    let switch = config(&with_scan(&format!("{GPIO}[switch]\nline = 0"))).switch.unwrap();
    assert_eq!(switch, SwitchConfig { line: Some(LineRef::Offset(0)), ..SwitchConfig::default() });
    let text = format!("{GPIO}[switch]\nline = 4294967295");
    assert_eq!(config(&with_scan(&text)).switch.unwrap().line, Some(LineRef::Offset(u32::MAX)));
}

#[test]
fn the_switch_line_is_for_gpiocdev_and_required_there() {
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}[switch]\nactive_low = true"))),
        ["4:1: switch.line is required for the gpiocdev backend: the input line that is active \
          at RUN"]
    );
    assert_eq!(
        errors(&with_scan("[switch]\nline = 3")),
        ["2:8: switch.line is for the gpiocdev backend: the sim backend simulates the switch \
          (`position`, and `SWITCH` lines of a stimulus)"]
    );
    // The default backend is sim, with or without an [io] section.
    assert_eq!(errors(&with_scan("[io]\n[switch]\nline = 3")).len(), 1);
}

#[test]
fn the_switch_position_is_for_sim_only() {
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}[switch]\nline = 1\nposition = \"run\""))),
        ["6:12: switch.position is for the sim backend: the gpiocdev backend reads the switch \
          from its line"]
    );
    assert_eq!(
        errors(&with_scan("[switch]\nposition = \"middle\"")),
        ["2:12: switch.position: unknown variant `middle`, expected `run` or `stop`"]
    );
}

#[test]
fn switch_ranges() {
    let debounce = |us: &str| format!("{GPIO}[switch]\nline = 1\ndebounce_us = {us}");
    assert_eq!(config(&with_scan(&debounce("0"))).switch.unwrap().debounce_us, 0);
    assert_eq!(config(&with_scan(&debounce("1000000"))).switch.unwrap().debounce_us, 1_000_000);
    assert_eq!(
        errors(&with_scan(&debounce("1000001"))),
        ["6:15: switch.debounce_us 1000001 out of range 0..=1000000"]
    );
    assert_eq!(
        errors(&with_scan(&debounce("-1"))),
        ["6:15: switch.debounce_us -1 out of range 0..=1000000"]
    );
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}[switch]\nline = -1"))),
        ["5:8: switch.line -1 out of range 0..=4294967295"]
    );
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}[switch]\nline = 4294967296"))),
        ["5:8: switch.line 4294967296 out of range 0..=4294967295"]
    );
}

#[test]
fn switch_bias_takes_the_input_values() {
    for (text, bias) in
        [("disabled", Bias::Disabled), ("pull-up", Bias::PullUp), ("pull-down", Bias::PullDown)]
    {
        let text = format!("{GPIO}[switch]\nline = 1\nbias = \"{text}\"");
        assert_eq!(config(&with_scan(&text)).switch.unwrap().bias, bias);
    }
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}[switch]\nline = 1\nbias = \"up\""))),
        ["6:8: switch.bias: unknown variant `up`, expected one of `disabled`, `pull-up`, \
          `pull-down`"]
    );
}

#[test]
fn the_switch_line_is_no_io_line() {
    let wiring = "[[io.input]]\ndevice = \"P0000\"\nline = 5\n\
                  [[io.output]]\ndevice = \"P0040\"\nline = 6\n";
    // The switch after the entries: reported at the switch, naming the entry.
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}{wiring}[switch]\nline = 5"))),
        ["11:8: switch.line 5 is already used by io.input \"P0000\""]
    );
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}{wiring}[switch]\nline = 6"))),
        ["11:8: switch.line 6 is already used by io.output \"P0040\""]
    );
    // The switch before them: reported at the entry, naming the switch.
    assert_eq!(
        errors(&with_scan(&format!("[switch]\nline = 6\n{GPIO}{wiring}"))),
        ["11:8: io.output \"P0040\": line 6 is already used by [switch]"]
    );
    config(&with_scan(&format!("{GPIO}{wiring}[switch]\nline = 7")));
}

#[test]
fn switch_unknown_keys_and_malformed_keys() {
    assert_eq!(
        errors(&with_scan("[switch]\ninitial = \"run\"")),
        ["2:1: [switch]: unknown key `initial`, expected one of `line`, `active_low`, `bias`, \
          `debounce_us`, `position`"]
    );
    // A malformed line is not reported missing as well.
    assert_eq!(
        errors(&with_scan(&format!("{GPIO}[switch]\nline = 7.5\nactive_low = 1"))),
        [
            "5:8: switch.line: invalid type: floating point `7.5`, expected a line offset (an \
             integer) or a line name (a string)",
            "6:14: switch.active_low: invalid type: integer `1`, expected a boolean",
        ]
    );
    assert_eq!(
        errors(&with_scan("switch = \"run\"")),
        ["1:10: `switch` must be a table, written [switch]"]
    );
}

#[test]
fn with_the_backend_unknown_the_switch_keys_of_both_pass() {
    // io.backend is malformed: whether line or position belongs cannot be said.
    assert_eq!(
        errors(&with_scan("[io]\nbackend = \"gpio\"\n[switch]\nline = 1\nposition = \"stop\"")),
        ["2:11: io.backend: unknown variant `gpio`, expected `sim` or `gpiocdev`"]
    );
}

// ---- all errors at once ----

#[test]
fn every_error_is_reported_in_file_order() {
    let text = r#"[plc]
watchdog_ms = 5
on_fault = "keep"

[[program]]
file = "main.il"
task = "nope"

[[task]]
name = "fast"
kind = "cycle"
number = 8
priority = 1
interval_ms = 0

[io]
backend = "gpiocdev"
"#;
    assert_eq!(
        errors(text),
        [
            "2:15: plc.watchdog_ms 5 out of range 10..=1000",
            "3:12: plc.on_fault: unknown variant `keep`, expected `clear` or `hold`",
            "7:8: program \"main\": task \"nope\" is not defined: expected \"init\", \"scan\" or the name of a [[task]]",
            "12:10: task \"fast\": number 8 out of range 0..=7 for a cycle task",
            "13:12: task \"fast\": priority 1 out of range 2..=7",
            "14:15: task \"fast\": interval_ms 0 out of range 1..=4294967295",
            "16:1: io.chip is required for the gpiocdev backend",
        ]
    );
}

#[test]
fn every_bad_key_of_one_table_is_reported() {
    // serde stops at the first bad key; each is taken out and the table tried again.
    assert_eq!(
        errors(&with_scan("[plc]\nwatchdog_ms = \"x\"\non_fault = 3\nbogus = 1\nscan_period_ms = true")),
        [
            "2:15: plc.watchdog_ms: invalid type: string \"x\", expected an integer",
            "3:12: plc.on_fault: expected a string",
            "4:1: [plc]: unknown key `bogus`, expected one of `watchdog_ms`, `on_fault`, `scan_period_ms`, `continue_on_congestion`",
            "5:18: plc.scan_period_ms: invalid type: boolean `true`, expected an integer",
        ]
    );
    // A malformed required key is not reported missing as well.
    assert_eq!(
        errors(&with_scan("[[task]]\nname = \"t\"\nkind = \"cycle\"\nnumber = \"0\"\npriority = 3\ninterval_ms = 1")),
        ["4:10: task \"t\": number: invalid type: string \"0\", expected an integer"]
    );
}

#[test]
fn a_malformed_key_is_not_also_reported_missing_or_defaulted() {
    // A malformed chip is not "required" as well.
    assert_eq!(
        errors(&with_scan("[io]\nbackend = \"gpiocdev\"\nchip = 0")),
        ["3:8: io.chip: invalid type: integer `0`, expected a string"]
    );
    // A malformed ms10 does not fall back to its default, which ms100 would overlap.
    assert_eq!(
        errors(&with_scan("[timers]\nms100 = \"T0000-T1200\"\nms10 = 5")),
        ["3:8: timers.ms10: invalid type: integer `5`, expected a string"]
    );
    // A program whose task is undefined may have been meant for the scan task.
    assert_eq!(
        errors("[[program]]\nfile = \"main.il\"\ntask = \"scna\"\n"),
        ["3:8: program \"main\": task \"scna\" is not defined: expected \"init\", \"scan\" or the name of a [[task]]"]
    );
}

// ---- [retain] ----

#[test]
fn retain_keys_parse_with_their_defaults() {
    let defaults = config(SCAN).retain;
    assert_eq!(defaults, RetainConfig::default());
    assert_eq!((defaults.interval_ms, defaults.restart, defaults.dir), (1000, Restart::Warm, None));
    let text = "[retain]\nranges = [\"D00000-D00099\", \"C0000-C0015\", \"T0002-T0002\"]\n\
                interval_ms = 10\ndir = \"state\"\nrestart = \"cold\"\n";
    let retain = config(&with_scan(text)).retain;
    assert_eq!(
        retain.ranges,
        [
            RetainRange { area: RetainArea::D, first: 0, last: 99 },
            RetainRange { area: RetainArea::C, first: 0, last: 15 },
            RetainRange { area: RetainArea::T, first: 2, last: 2 },
        ]
    );
    assert_eq!(retain.interval_ms, 10);
    assert_eq!(retain.dir, Some(PathBuf::from("etc/state")));
    assert_eq!(retain.restart, Restart::Cold);
}

#[test]
fn retain_errors_name_the_key_and_the_range() {
    let text = "[retain]\nranges = [\"D00000-D00099\", \"D00050-D00150\", \"K000-K010\", \
                \"M000-M001\", \"D00010\", \"D00009-D00001\", \"D00001-C0002\", \"D00001.3-D00002\"]\n\
                interval_ms = 9\ndir = \"\"\nrestart = \"hot\"\n";
    assert_eq!(
        errors(&with_scan(text)),
        [
            "2:28: retain.ranges: D00050-D00150 overlaps D00000-D00099",
            "2:45: retain.ranges: `K000-K010`: the K area is always retained",
            "2:58: retain.ranges: `M000-M001`: M cannot be retained; D, T and C ranges can (K always is)",
            "2:71: retain.ranges: `D00010` is not a range: write it `D00000-D00099`",
            "2:81: retain.ranges: `D00009-D00001`: the first device is after the last",
            "2:98: retain.ranges: `D00001-C0002`: both ends must be of one area",
            "2:114: retain.ranges: `D00001.3-D00002`: a range of words, not of bits",
            "3:15: retain.interval_ms 9 out of range 10..=3600000",
            "4:7: retain.dir must not be empty",
            "5:11: retain.restart: unknown variant `hot`, expected `warm` or `cold`",
        ]
    );
    assert_eq!(
        errors(&with_scan("[retain]\nperiod = 3\n"))[0],
        "2:1: [retain]: unknown key `period`, expected one of `ranges`, `interval_ms`, `dir`, `restart`"
    );
}

#[test]
fn a_st_program_is_known_by_its_extension_and_may_name_its_pou() {
    let c = config(
        "[[program]]\nfile = \"main.il\"\n\
         [[program]]\nname = \"tank\"\nfile = \"level.ST\"\npou = \"Level\"\n\
         [[program]]\nfile = \"other.st\"\n",
    );
    let languages: Vec<_> = c.programs.iter().map(|p| (p.language, p.pou.as_deref())).collect();
    assert_eq!(
        languages,
        [
            (Language::InstructionList, None),
            (Language::StructuredText, Some("Level")),
            (Language::StructuredText, None),
        ]
    );
}

#[test]
fn pou_is_for_st_files_only_and_not_empty() {
    assert_eq!(
        errors("[[program]]\nfile = \"main.il\"\npou = \"Main\"\n"),
        ["3:7: program \"main\": pou names a PROGRAM of a Structured Text file, and `main.il` is not a `.st` file"]
    );
    assert_eq!(
        errors("[[program]]\nfile = \"main.st\"\npou = \" \"\n"),
        ["3:7: program \"main\": pou must not be empty"]
    );
}

#[test]
fn st_library_lists_st_files_once_each() {
    let c = config(&with_scan("[st]\nlibrary = [\"types.st\", \"lib/pid.st\"]\n"));
    let files: Vec<_> = c.st.library.iter().map(|l| l.resolved.clone()).collect();
    assert_eq!(files, [Path::new("etc/types.st"), Path::new("etc/lib/pid.st")]);
    assert_eq!(c.st.library[1].line, 2);
    assert_eq!(
        errors(&with_scan("[st]\nlibrary = [\"a.st\", \"b.il\", \"a.st\"]\n")),
        [
            "2:20: st.library: `b.il` is not a `.st`, `.TcPOU`, `.TcDUT`, `.TcGVL` or `.TcIO` file (a folder is written with a final `/`)",
            "2:28: st.library: `a.st` is listed twice"
        ]
    );
    assert_eq!(config(&with_scan("")).st, StConfig::default());
    let c = config(&with_scan("[st]\nlibrary = [\"oscat/\", \"lib/F.TcPOU\", \"T.tcdut\"]\n"));
    let kinds: Vec<bool> = c.st.library.iter().map(|l| l.folder).collect();
    assert_eq!(kinds, [true, false, false]);
}

#[test]
fn st_strict_is_off_unless_set() {
    assert!(!config(&with_scan("")).st.strict);
    assert!(config(&with_scan("[st]\nstrict = true\n")).st.strict);
    assert!(!errors(&with_scan("[st]\nstrict = 1\n")).is_empty());
}

#[test]
fn st_defines_are_names_listed_once_each() {
    assert!(config(&with_scan("")).st.defines.is_empty());
    let c = config(&with_scan("[st]\ndefines = [\"plant_b\", \"WithLog\"]\n"));
    assert_eq!(c.st.defines, ["plant_b", "WithLog"]);
    assert_eq!(
        errors(&with_scan("[st]\ndefines = [\"a b\", \"x\", \"X\"]\n")),
        [
            "2:12: st.defines: `a b` is not a name (letters, digits and `_`)",
            "2:24: st.defines: `X` is listed twice"
        ]
    );
}

#[test]
fn iec_layout_is_openplc_unless_set_and_images_move() {
    use crate::device::iec::{IecLayout, Image, Preset, Start};
    use crate::device::Area;
    assert_eq!(config(&with_scan("")).iec.layout, IecLayout::of(Preset::OpenPlc));
    let c = config(&with_scan(
        "[iec]\npreset = \"CODESYS\"\noutput = \"P100\"\noutput_bytes = 56\nmemory = \"K000\"\n",
    ));
    assert_eq!(c.iec.layout.preset, Preset::Codesys);
    assert_eq!(c.iec.layout.start(Image::Output), Start { area: Area::P, word: 100 });
    assert_eq!(c.iec.layout.start(Image::Memory), Start { area: Area::K, word: 0 });
    assert_eq!(c.iec.layout.start(Image::Input), Start { area: Area::P, word: 0 });
    let c = config(&with_scan("[iec]\nmemory_lwords = \"D00000\"\n"));
    assert_eq!(c.iec.layout.start(Image::MemoryLwords), Start { area: Area::D, word: 0 });
    assert_eq!(config(&with_scan("[iec]\npreset = \"plcd\"\n")).iec.layout.preset, Preset::Plcd);
    // plcd's habit, inputs from P0000 and outputs from P0040: eight bytes of %IX, %QX from P004
    let c = config(&with_scan("[iec]\ninput_bytes = 8\noutput = \"P004\"\n"));
    let lamp = c.iec.layout.resolve("QX0.0").unwrap().unwrap().address;
    assert_eq!(lamp.to_string(), "P0040");
    // openplc's %IB and %QB areas move as its word areas do
    let c = config(&with_scan("[iec]\nbyte_input = \"D00000\"\nbyte_output = \"D00512\"\n"));
    assert_eq!(c.iec.layout.start(Image::InputBytes), Start { area: Area::D, word: 0 });
    assert_eq!(c.iec.layout.resolve("QB3").unwrap().unwrap().to_string(), "D00513 (high byte)");
}

#[test]
fn iec_layout_errors_name_their_key() {
    assert_eq!(
        errors(&with_scan("[iec]\npreset = \"s7\"\n")),
        ["2:10: iec.preset: \"s7\" is not a layout, one of \"openplc\", \"codesys\", \"plcd\""]
    );
    assert_eq!(
        errors(&with_scan("[iec]\ninput = \"P0040\"\noutput = \"T0001\"\nmemory = \"M300\"\n")),
        [
            "2:9: iec.input: `P0040` is not a word of P, M, K or D (an image starts at a word: `P064`, `D10000`)",
            "3:10: iec.output: `T0001` is not a word of P, M, K or D (an image starts at a word: `P064`, `D10000`)",
            "4:10: iec.memory: `M300` is out of range (M0000-M255F, M000-M255)",
        ]
    );
    // a %QW image of 1024 words from D32000 runs past D32767; the %MW image moved onto %IW's
    // (and not as far as %IB's, from D11024)
    assert_eq!(
        errors(&with_scan("[iec]\noutput_words = \"D32000\"\nmemory_words = \"D09500\"\n")),
        [
            "2:16: iec.output_words: the %QW image needs 1024 words from `D32000`: past the end of D (D00000-D32767)",
            "3:16: iec.memory_words: the %MW image (`D09500`, 1024 words) overlaps the %IW image (`D10000` to `D11023`, `iec.input_words`)",
        ]
    );
    assert_eq!(
        errors(&with_scan("[iec]\npreset = \"plcd\"\ninput = \"P000\"\n")),
        ["3:9: iec.input: the plcd layout has no such image (its addresses are P and M words: `%IX4.0` is P0040)"]
    );
    assert!(!errors(&with_scan("[iec]\nbytes = 4\n")).is_empty());
    // %QB moved onto %QW's words; a byte area under codesys
    assert_eq!(
        errors(&with_scan("[iec]\nbyte_output = \"D12500\"\n")),
        ["2:15: iec.byte_output: the %QB image (`D12500`, 512 words) overlaps the %QW image (`D12000` to `D13023`, `iec.output_words`)"]
    );
    assert_eq!(
        errors(&with_scan("[iec]\npreset = \"codesys\"\nbyte_input = \"D00000\"\n")),
        ["3:14: iec.byte_input: the codesys layout has no such image (only `preset = \"openplc\"` has images of words and bytes apart)"]
    );
    assert_eq!(
        errors(&with_scan("[iec]\ninput_bytes = 0\noutput = \"P004\"\n")),
        ["2:15: iec.input_bytes 0 out of range 1..=65536"]
    );
    // 128 bytes of %IX from P000 take P000..P063: P004 is among them
    assert_eq!(
        errors(&with_scan("[iec]\noutput = \"P004\"\n")),
        ["2:10: iec.output: the %QX image (`P004`, 64 words) overlaps the %IX image (`P000` to `P063`, `iec.input`)"]
    );
    assert_eq!(
        errors(&with_scan("[iec]\npreset = \"plcd\"\nmemory_bytes = 2\n")),
        ["3:16: iec.memory_bytes: the plcd layout has no byte images to size"]
    );
}

#[test]
fn iec_variables_and_addresses_parse_in_file_order_with_their_places() {
    let c = config(&with_scan(
        "[iec.variables]\n\"main.lamp\" = \"%QX0.3\"\n\"Res0.inst.fb.lvl\" = \"MW5\"\n\
         \"main.start\" = \"%P0040\"\n\"main.x\" = \"%IX100.0.0\"\n\n[iec.addresses]\n\
         \"%ix100.00.0\" = \"%IX4.0\"\n\"IW100.0.1\" = \"D00100\"\n",
    ));
    let v = &c.iec.variables;
    assert_eq!(v.len(), 4);
    assert_eq!((v[0].key.as_str(), v[0].path.join(" ")), ("main.lamp", "main lamp".into()));
    assert_eq!((v[0].line, v[0].col, v[0].value_line, v[0].value_col), (2, 1, 2, 15));
    assert_eq!(v[0].address, "QX0.3");
    // the `%` may be left out; a path of any depth, from a resource
    assert_eq!((v[1].path.len(), v[1].address.as_str()), (4, "MW5"));
    assert_eq!(v[2].address, "P0040");
    assert_eq!(v[0].subject(), "iec.variables \"main.lamp\"");
    // an [iec.variables] value may be an address [iec.addresses] places
    assert_eq!(v[3].address, "IX100.0.0");
    let a = &c.iec.addresses;
    assert_eq!(a.len(), 2);
    assert_eq!((a[0].key.to_string(), a[0].written.as_str()), ("%IX100.0.0".into(), "%ix100.00.0"));
    assert_eq!((a[0].target.as_str(), a[0].line, a[0].col), ("%IX4.0", 8, 1));
    // placed in the layout: the compiler's addresses resolve through it
    let placed = |t| c.iec.layout.resolve(t).unwrap().unwrap().to_string();
    assert_eq!(placed("IX100.0.0"), "P0020");
    assert_eq!(placed("IW100.0.1"), "D00100");
    // none: none
    assert_eq!(config(&with_scan("")).iec.variables, []);
    assert_eq!(config(&with_scan("[iec]\n")).iec.addresses, []);
}

#[test]
fn iec_variables_and_addresses_errors_name_their_key() {
    assert_eq!(
        errors(&with_scan(
            "[iec.variables]\n\"lamp\" = \"%QX0.1\"\n\"main.2x\" = \"%QX0.1\"\n\"main.lamp\" = 3\n\
             \"main.a\" = \"%QX0.9\"\n\"main.b\" = \"%T0001\"\n\"main.c\" = \"%IX9.9.9\"\n"
        )),
        [
            "2:1: iec.variables \"lamp\": not a variable path: a program instance, then its variables and function block instances, names joined by dots (`main.lamp`, `main.fb.level`, `Res0.inst.lamp`)",
            "3:1: iec.variables \"main.2x\": not a variable path: a program instance, then its variables and function block instances, names joined by dots (`main.lamp`, `main.fb.level`, `Res0.inst.lamp`)",
            "4:15: iec.variables \"main.lamp\": expected a string, an address",
            "5:12: iec.variables \"main.a\": `%QX0.9`: bit 9 of a byte: the openplc layout numbers %QX by byte and bit, the bit 0 to 7 (`%QX1.0` is the bit after `%QX0.7`; `[iec] preset = \"plcd\"` numbers P words and their bits 0 to 15)",
            "6:12: iec.variables \"main.b\": `T0001` is not a device of P, M, K or D: an address is one of the [iec] layout or one of those devices",
            "7:12: iec.variables \"main.c\": `%IX9.9.9` is a multi-level address (3 levels), as Beremiz numbers an extension's I/O (its channel, then the extension's own items), and the config does not place it: add `\"%IX9.9.9\" = \"…\"` to `[iec.addresses]` in the config, an address of the [iec] layout or a device of P, M, K or D (docs/CONFIG.md), or declare the variable `AT %IX*` and bind it with VAR_CONFIG or `[iec.variables]`",
        ]
    );
    assert_eq!(
        errors(&with_scan(
            "[iec.addresses]\n\"%IX4.0\" = \"%IX5.0\"\n\"%IW1.2\" = \"%IX5.0\"\n\
             \"%IX1.2.3\" = \"%IX4.0\"\n\"%ix1.2.03\" = \"%IX4.1\"\n\"%IX1.2.4\" = \"%IX1.2.5\"\n\
             \"%IW1.3\" = \"%T0001\"\n\"%ML1.4\" = \"%D32766\"\n\"%IX1.2.6\" = \"%D00100\"\n\
             \"%IW1.5\" = \"%P0040\"\n\"%IX1.2.7\" = 1\n"
        )),
        [
            "2:1: iec.addresses \"%IX4.0\": `%IX4.0` is not a multi-level address: an area letter (I, Q, M), a size letter (X, B, W, D, L), then numbers joined by dots, more than an address of the [iec] layout has (`%IX100.0.0`, `%IW100.0.1`, `%QW2.1`)",
            "3:12: iec.addresses \"%IW1.2\": `%IX5.0` is a 1-bit location, `%IW1.2` a 16-bit one",
            "5:1: iec.addresses \"%ix1.2.03\": `%IX1.2.3` is placed already (line 4): an address is in one place",
            "6:14: iec.addresses \"%IX1.2.4\": `%IX1.2.5` is itself a multi-level address: an entry places one at an address of the [iec] layout or at a device of P, M, K or D",
            "7:12: iec.addresses \"%IW1.3\": `T0001` is not a device of P, M, K or D: an address is one of the [iec] layout or one of those devices",
            "8:12: iec.addresses \"%ML1.4\": `D32766` and the 3 word(s) after it hold `%ML1.4`: past the end of D (D00000-D32767)",
            "9:14: iec.addresses \"%IX1.2.6\": `D00100` is a word device, a bit is needed here",
            "10:12: iec.addresses \"%IW1.5\": `P0040` is a bit device, a word is needed here",
            "11:14: iec.addresses \"%IX1.2.7\": expected a string, an address",
        ]
    );
    // a table each, not a value; and no other key in [iec]
    assert_eq!(
        errors(&with_scan("[iec]\nvariables = \"main.lamp\"\naddresses = []\n")),
        [
            "2:13: `iec.variables` must be a table, written [iec.variables]",
            "3:13: `iec.addresses` must be a table, written [iec.addresses]",
        ]
    );
    let unknown = errors(&with_scan("[iec]\nvariable = 1\n"));
    assert!(unknown[0].contains("`variables`, `addresses`"), "{unknown:?}");
    // the variables are checked whatever the addresses' errors
    assert_eq!(
        errors(&with_scan(
            "[iec.addresses]\n\"%IX4.0\" = \"%IX5.0\"\n[iec.variables]\n\"x\" = \"%QX0.1\"\n"
        ))
        .len(),
        2
    );
}

#[test]
fn users_names_a_file_resolved_against_the_config() {
    let config = |text: &str| parse(&with_scan(text), Path::new("/etc/plcd/plcd.toml"));
    assert_eq!(config("").unwrap().users.file, None);
    let users = config("[users]\nfile = \"users\"\n").unwrap().users;
    assert_eq!(users.file.as_deref(), Some(Path::new("/etc/plcd/users")));
    let users = config("[users]\nfile = \"/var/lib/plcd/users\"\n").unwrap().users;
    assert_eq!(users.file.as_deref(), Some(Path::new("/var/lib/plcd/users")));
    assert_eq!(
        errors(&with_scan("[users]\nfile = \" \"\n")),
        ["2:8: users.file must not be empty"]
    );
    assert_eq!(
        errors(&with_scan("[users]\npath = \"users\"\n")),
        ["2:1: [users]: unknown key `path`, expected `file`"]
    );
}

//! Remote I/O end to end: one `plcd run` (the PLC) polls another (the device, serving its
//! device memory over Modbus TCP) as a `[[remote]]`: inputs reach the PLC's program, its
//! outputs reach the device, the device stopping is seen (status bit OFF, inputs cleared, one
//! log line per condition, `plcctl status`), and the device coming back is taken up without a
//! restart. The device side is plcd's own Modbus server, an implementation of its own; the
//! suite against pymodbus is tests/remote/run-pymodbus-remote.
//!
//! Real time is only waited on, never asserted.

mod harness;

use std::net::{SocketAddr, TcpListener};

use harness::daemon::{Daemon, Project};

/// The device: its discrete inputs are M0000–M000F, its coils M0100–M010F (writable), its
/// holding registers D00000–D00009 (writable), its input registers D00010–D00013.
const DEVICE_MAP: &str = "[[modbus.discrete_inputs]]\nstart = 0\ndevice = \"M0000\"\ncount = 16\n\
    [[modbus.coils]]\nstart = 0\ndevice = \"M0100\"\ncount = 16\nwritable = true\n\
    [[modbus.holding_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 10\nwritable = true\n\
    [[modbus.input_registers]]\nstart = 0\ndevice = \"D00010\"\ncount = 4\n";

/// The PLC copies the device's inputs to its outputs: P0100 → P0140, D00100 → D00200 (a
/// DINT, D00100–D00101).
const PLC_MAIN: &str = "LOAD P0100\nOUT P0140\nLOAD _ON\nDMOV D00100 D00200\nEND\n";

fn device_config(port: u16) -> String {
    format!(
        "[plc]\nscan_period_ms = 5\n[rt]\npolicy = \"other\"\nlock_memory = false\n\
         [control]\nsocket = \"plcd.sock\"\n[[program]]\nfile = \"main.il\"\n\
         [modbus]\nlisten = \"127.0.0.1:{port}\"\n{DEVICE_MAP}"
    )
}

/// The PLC's config; its request timeout (200 ms natively) scaled to the programs' speed: the
/// device being slow to answer is not what these tests are about.
fn plc_config(port: u16, on_loss: &str) -> String {
    let timeout_ms = 200 * harness::runner::slowdown();
    format!(
        "[plc]\nscan_period_ms = 5\n[rt]\npolicy = \"other\"\nlock_memory = false\n\
         [control]\nsocket = \"plcd.sock\"\n[[program]]\nfile = \"main.il\"\n\
         [[remote]]\nname = \"rack1\"\ntransport = \"tcp\"\naddress = \"127.0.0.1:{port}\"\n\
         period_ms = 20\ntimeout_ms = {timeout_ms}\non_loss = \"{on_loss}\"\nstatus = \"M0050\"\n\
         reconnect_ms = 50\nreconnect_max_ms = 200\n\
         [[remote.read]]\ntable = \"discrete_inputs\"\naddress = 0\ncount = 16\ndevice = \"P0100\"\n\
         [[remote.read]]\ntable = \"input_registers\"\naddress = 0\ncount = 2\n\
         device = \"D00100\"\nswap_words = true\n\
         [[remote.write]]\ntable = \"coils\"\naddress = 0\ncount = 16\ndevice = \"P0140\"\n\
         [[remote.write]]\ntable = \"holding_registers\"\naddress = 0\ncount = 2\n\
         device = \"D00200\"\n"
    )
}

fn free_port() -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr: SocketAddr = listener.local_addr().unwrap();
    addr.port()
}

fn get(project: &Project, device: &str) -> i64 {
    let out = project.plcctl(&["--json", "get", device]);
    serde_json::from_slice::<serde_json::Value>(&out.stdout)
        .ok()
        .and_then(|v| v["values"][0]["value"].as_i64())
        .unwrap_or(i64::MIN)
}

fn set(project: &Project, device: &str, value: i64) {
    let out = project.plcctl(&["set", device, &value.to_string()]);
    assert!(out.status.success(), "set {device}: {}", String::from_utf8_lossy(&out.stderr));
}

fn remote_status(project: &Project) -> serde_json::Value {
    let out = project.plcctl(&["--json", "status"]);
    let status: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    status["remotes"][0].clone()
}

/// Started, and answering on its control socket: the daemon binds that socket after its
/// Modbus server, so "modbus: serving" alone does not mean `plcctl` can connect yet.
fn start(project: &Project) -> Daemon {
    let daemon = project.start_with(&["--log-level", "info"], &[]);
    daemon.wait_for("control socket");
    daemon
}

#[test]
fn a_plc_polls_a_device_sees_it_go_and_takes_it_back() {
    let port = free_port();
    let device =
        Project::new("remote-device", &[("plcd.toml", &device_config(port)), ("main.il", "END\n")]);
    let device_daemon = start(&device);
    device_daemon.wait_for(&format!("modbus: serving 127.0.0.1:{port}"));
    let plc = Project::new(
        "remote-plc",
        &[("plcd.toml", &plc_config(port, "clear")), ("main.il", PLC_MAIN)],
    );
    let plc_daemon = start(&plc);

    // Online: the status bit, and inputs both ways through the PLC's program.
    plc_daemon.wait("rack1 online", || get(&plc, "M0050") == 1);
    set(&device, "M0000", 1);
    // 0x0001_2345 sent high word first: D00010 = 0x0001, D00011 = 0x2345.
    set(&device, "D00010", 1);
    set(&device, "D00011", 0x2345);
    plc_daemon.wait("P0100 from the device", || get(&plc, "P0100") == 1);
    plc_daemon.wait("the DINT, words swapped", || get(&plc, "D00100") == 0x2345);
    assert_eq!(get(&plc, "D00101"), 1);
    device_daemon.wait("the coil written back", || get(&device, "M0100") == 1);
    device_daemon.wait("the registers written back", || get(&device, "D00000") == 0x2345);
    assert_eq!(get(&device, "D00001"), 1, "holding registers low word first, as written");
    set(&device, "M0000", 0);
    device_daemon.wait("the coil follows", || get(&device, "M0100") == 0);
    let status = remote_status(&plc);
    assert_eq!(status["name"], "rack1");
    assert_eq!(status["state"], "online");
    assert!(status["requests"].as_u64().unwrap() > 3, "{status}");
    assert!(status["writes"].as_u64().unwrap() >= 2, "{status}");
    set(&device, "M0000", 1);
    plc_daemon.wait("P0100 ON again", || get(&plc, "P0100") == 1);

    // The device goes away: the status bit OFF, the inputs cleared, logged once.
    let before = plc_daemon.lines().len();
    let (code, _) = device_daemon.stop();
    assert_eq!(code, 0);
    plc_daemon.wait("rack1 lost", || get(&plc, "M0050") == 0);
    plc_daemon.wait("inputs cleared", || get(&plc, "P0100") == 0 && get(&plc, "D00100") == 0);
    plc_daemon.wait("a few more tries", || remote_status(&plc)["failures"].as_u64() > Some(4));
    let status = remote_status(&plc);
    assert_eq!(status["state"], "lost");
    assert_eq!(status["losses"], 1);
    assert!(status["last_error"].as_str().is_some(), "{status}");
    let lines = plc_daemon.lines();
    let about: Vec<&String> =
        lines[before..].iter().filter(|l| l.contains("remote rack1 (tcp 127.0.0.1:")).collect();
    let lost = about.iter().filter(|l| l.contains("lost after 1 failed request")).count();
    assert_eq!(lost, 1, "one line for the loss: {about:#?}");
    assert!(about.len() <= 4, "a line per condition, not per poll: {about:#?}");

    // Back on the same port: taken up without a restart.
    let device_daemon = start(&device);
    device_daemon.wait_for(&format!("modbus: serving 127.0.0.1:{port}"));
    set(&device, "M0000", 1);
    plc_daemon.wait("rack1 back", || get(&plc, "M0050") == 1 && get(&plc, "P0100") == 1);
    plc_daemon.wait_for("remote rack1 (tcp 127.0.0.1");
    plc_daemon.wait_for("answering again after");
    assert_eq!(remote_status(&plc)["state"], "online");
    device_daemon.wait("outputs written again", || get(&device, "M0100") == 1);

    let (code, log) = plc_daemon.stop();
    assert_eq!(code, 0);
    if std::env::var_os("PLCD_SHOW_LOG").is_some() {
        eprintln!("{}", log.join("\n"));
    }
    // At its stop the PLC wrote its remote outputs' safe state: zeros.
    assert_eq!(get(&device, "M0100"), 0, "the coils were switched off at the PLC's stop");
    assert_eq!(get(&device, "D00000"), 0);
    device_daemon.stop();
}

#[test]
fn held_inputs_keep_their_last_values_when_the_device_is_lost() {
    let port = free_port();
    let device = Project::new(
        "remote-hold-dev",
        &[("plcd.toml", &device_config(port)), ("main.il", "END\n")],
    );
    let device_daemon = start(&device);
    device_daemon.wait_for(&format!("modbus: serving 127.0.0.1:{port}"));
    set(&device, "M0000", 1);
    let plc = Project::new(
        "remote-hold-plc",
        &[("plcd.toml", &plc_config(port, "hold")), ("main.il", PLC_MAIN)],
    );
    let plc_daemon = start(&plc);
    plc_daemon.wait("P0100 from the device", || get(&plc, "P0100") == 1);
    device_daemon.stop();
    plc_daemon.wait("rack1 lost", || get(&plc, "M0050") == 0);
    assert_eq!(get(&plc, "P0100"), 1, "on_loss = hold keeps the last value read");
    plc_daemon.stop();
}

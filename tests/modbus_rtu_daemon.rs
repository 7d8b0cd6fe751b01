//! The Modbus RTU server of a real `plcd run` on the sim backend, spoken to over a pty pair as
//! a master would: every function code and exception, broadcasts (carried out, not answered),
//! requests to other units (ignored), bad frames (dropped and counted), the longest frame, the
//! TCP and RTU servers on one map, a serial port that cannot be opened, and a line that hangs
//! up under the daemon.
//!
//! Real time is only waited on, never asserted: "not answered" is shown by order (the next
//! answer on the line is another request's), never by waiting for silence.

mod harness;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use plcd::services::modbus::rtu::{crc_ok, with_crc};
use serialport::{SerialPort, TTYPort};

use harness::daemon::{Daemon, Project};
use harness::log::PATIENCE;
use harness::modbus::{bits, read, words, write_registers};

/// Scan program: D00400 counts scans; M0000 is copied to M0010 (coil 16); D00300 counts the
/// scans that saw D00000 differ from D00122 (the first and last words of a 123-register write).
const MAIN: &str = "INC D00400\nLOAD M0000\nOUT M0010\nLOAD<> D00000 D00122\nINC D00300\nEND\n";

const MAP: &str = "[[modbus.coils]]\nstart = 0\ndevice = \"M0000\"\ncount = 32\nwritable = true\n\
    [[modbus.discrete_inputs]]\nstart = 0\ndevice = \"P0000\"\ncount = 16\n\
    [[modbus.holding_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 125\nwritable = true\n\
    [[modbus.holding_registers]]\nstart = 300\ndevice = \"D00300\"\ncount = 1\n\
    [[modbus.holding_registers]]\nstart = 1050\ndevice = \"D00400\"\ncount = 1\n\
    [[modbus.input_registers]]\nstart = 0\ndevice = \"_SCAN_CUR\"\ncount = 4\n";

/// The unit the daemon serves.
const UNIT: u8 = 7;

/// `[modbus]` with `modbus` in it, `[modbus.rtu]` on `port` (no parity: a pty carries bytes,
/// and the kernel may refuse PARENB on one), the map.
fn config(modbus: &str, port: &str) -> String {
    format!(
        "[plc]\nscan_period_ms = 1\n[rt]\npolicy = \"other\"\nlock_memory = false\n\
         [control]\nsocket = \"plcd.sock\"\n[[program]]\nfile = \"main.il\"\n\
         [modbus]\n{modbus}\n[modbus.rtu]\nport = \"{port}\"\nbaud = 115200\nparity = \"none\"\n\
         unit_id = {UNIT}\n\
         {MAP}"
    )
}

/// The master's end of the line.
struct Master {
    tty: TTYPort,
}

impl Master {
    /// Sends `adu` (address and PDU) with its CRC, expecting no answer.
    fn send(&mut self, adu: &[u8]) {
        self.send_raw(&with_crc(adu));
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        self.tty.write_all(bytes).expect("writing the pty");
    }

    /// Reads one response (bytes until they end with their CRC) within `patience`.
    fn response_within(&mut self, patience: Duration) -> Option<Vec<u8>> {
        let mut got = Vec::new();
        let mut buf = [0u8; 300];
        let until = Instant::now() + patience;
        while !crc_ok(&got) {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return None;
            }
            self.tty.set_timeout(left).unwrap();
            match self.tty.read(&mut buf) {
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => panic!("reading the pty: {e}"),
            }
        }
        Some(got)
    }

    /// One request to this server; its response without the address and CRC (the PDU),
    /// after checking them.
    fn request(&mut self, pdu: &[u8]) -> Vec<u8> {
        self.send(&[&[UNIT][..], pdu].concat());
        let r = self.response_within(PATIENCE).unwrap_or_else(|| panic!("no answer to {pdu:02x?}"));
        assert_eq!(r[0], UNIT, "the response's address: {r:02x?}");
        r[1..r.len() - 2].to_vec()
    }

    /// A request as a master sends it after a bad frame: again if no answer came within the
    /// server's bound (`answer_timeout_ms`, 2 s, and the frame gap), when the bad frame took
    /// it down with it.
    fn request_again(&mut self, pdu: &[u8]) -> Vec<u8> {
        for _ in 0..3 {
            self.send(&[&[UNIT][..], pdu].concat());
            if let Some(r) = self.response_within(Duration::from_secs(3)) {
                return r[1..r.len() - 2].to_vec();
            }
        }
        panic!("no answer to {pdu:02x?}");
    }

    fn read_holdings(&mut self, start: u16, count: u16) -> Vec<u16> {
        let r = self.request(&read(3, start, count));
        assert_eq!(r[0], 3, "read holding registers {start}+{count}: {r:02x?}");
        words(&r[2..])
    }
}

/// Held while a pty's descriptors may be inherited (`TTYPort::pair` opens them without
/// close-on-exec) and while a daemon is spawned: no daemon of this file inherits another
/// test's pty, which would keep it from hanging up.
static SPAWNING: Mutex<()> = Mutex::new(());

/// A pty pair: the master's end, close-on-exec, and the name of the other end (not open).
fn pty() -> (TTYPort, String) {
    let _spawning = SPAWNING.lock().unwrap_or_else(|e| e.into_inner());
    let (master, slave) = TTYPort::pair().expect("a pty pair");
    let name = slave.name().expect("the pty's name");
    (master.try_clone_native().expect("F_DUPFD_CLOEXEC"), name)
}

fn start(project: &Project) -> Daemon {
    let _spawning = SPAWNING.lock().unwrap_or_else(|e| e.into_inner());
    project.start_with(&["--log-level", "debug"], &[])
}

struct Plc {
    // Declared first, dropped first: the daemon is gone before the pty and the directory.
    daemon: Daemon,
    master: Master,
    project: Project,
    port: String,
}

/// Why a pty cannot be opened as a serial port here, or `None`. Probed only under an emulator
/// (tests/harness/runner.rs): qemu-user does not emulate the TCGETS2/TCSETS2 ioctls with which
/// the serialport crate sets up a line, so neither this test nor the daemon can open one.
/// Natively nothing is probed: a port that does not open fails the test.
fn serial_ports_unavailable() -> Option<String> {
    if !harness::runner::emulated() {
        return None;
    }
    let (_master, port) = pty();
    let error = serialport::new(&port, 115_200).open_native().err()?;
    Some(format!(
        "a pty cannot be opened as a serial port under `{}` ({port}: {error}): qemu-user does \
         not emulate TCGETS2/TCSETS2",
        harness::runner::runner().join(" ")
    ))
}

impl Plc {
    /// `plcd run` serving unit 7 on a fresh pty, with `modbus` added to `[modbus]`; `None`
    /// (a visible skip) where no pty can be a serial port.
    fn start(name: &str, modbus: &str) -> Option<Plc> {
        if let Some(reason) = serial_ports_unavailable() {
            harness::skip::skip(None, &reason);
            return None;
        }
        let (master, port) = pty();
        let project = Project::new(
            &format!("modbus-rtu-{name}"),
            &[("plcd.toml", &config(modbus, &port)), ("main.il", MAIN)],
        );
        let daemon = start(&project);
        daemon.wait_for_line(&format!("modbus: serving rtu {port}"));
        let plc = Plc { daemon, master: Master { tty: master }, project, port };
        plc.daemon.wait("scans", || plc.scans() > 2);
        Some(plc)
    }

    /// D00400, the scan counter, through `plcctl --json get`.
    fn scans(&self) -> i64 {
        let out = self.project.plcctl(&["--json", "get", "D00400"]);
        serde_json::from_slice::<serde_json::Value>(&out.stdout)
            .ok()
            .and_then(|v| v["values"][0]["value"].as_i64())
            .unwrap_or(-1)
    }

    /// SIGTERM: a clean stop; the whole log.
    fn stop(self) -> Vec<String> {
        let (code, log) = self.daemon.stop();
        assert_eq!(code, 0, "clean stop:\n{}", log.join("\n"));
        log
    }
}

#[test]
fn every_function_code_over_a_serial_line() {
    let Some(mut plc) = Plc::start("fcs", "") else { return };
    let m = &mut plc.master;
    // FC 6 then FC 3.
    assert_eq!(m.request(&[6, 0, 1, 0xBE, 0xEF]), [6, 0, 1, 0xBE, 0xEF]);
    assert_eq!(m.read_holdings(0, 3), [0, 0xBEEF, 0]);
    // FC 16 of the maximum 123 registers: a frame of 255 bytes; FC 3 of 125 answers 255.
    let values: Vec<u16> = (0..123).map(|i| 7 * i + 1).collect();
    assert_eq!(m.request(&write_registers(1, &values)), [16, 0, 1, 0, 123]);
    assert_eq!(&m.read_holdings(0, 125)[1..124], &values[..]);
    // FC 23: the read sees the write.
    let r = m.request(&[23, 0, 9, 0, 4, 0, 10, 0, 2, 4, 0x12, 0x34, 0x56, 0x78]);
    assert_eq!((r[0], r[1]), (23, 8));
    assert_eq!(words(&r[2..]), [values[8], 0x1234, 0x5678, values[11]]);
    // FC 22: 0x12 AND 0xF2 OR 0x25 = 0x17.
    assert_eq!(m.request(&[6, 0, 7, 0, 0x12]), [6, 0, 7, 0, 0x12]);
    assert_eq!(m.request(&[22, 0, 7, 0xFF, 0xF2, 0, 0x25]), [22, 0, 7, 0xFF, 0xF2, 0, 0x25]);
    assert_eq!(m.read_holdings(7, 1), [0x17]);
    // FC 5 sets coil 0 (M0000); the program copies it to coil 16; FC 1 reads both.
    assert_eq!(m.request(&[5, 0, 0, 0xFF, 0]), [5, 0, 0, 0xFF, 0]);
    let deadline = Instant::now() + PATIENCE;
    while !bits(&m.request(&read(1, 0, 17))[2..], 17)[16] {
        assert!(Instant::now() < deadline, "M0010 to follow M0000");
    }
    // FC 15, then FC 1.
    assert_eq!(m.request(&[15, 0, 1, 0, 3, 1, 0b101]), [15, 0, 1, 0, 3]);
    assert_eq!(bits(&m.request(&read(1, 0, 4))[2..], 4), [true, true, false, true]);
    // FC 2 and FC 4.
    assert_eq!(m.request(&read(2, 0, 16)), [2, 2, 0, 0]);
    let r = m.request(&read(4, 0, 4));
    assert_eq!((r[0], r[1], &r[8..]), (4, 8, &[0u8, 0][..]), "no error code");
    // FC 17: the server id is this unit; RUN last. FC 43/14: the basic objects.
    let r = m.request(&[17]);
    let text = format!("plcd {}", env!("CARGO_PKG_VERSION"));
    assert_eq!(r[..3], [17, 2 + text.len() as u8, UNIT]);
    assert_eq!(&r[3..r.len() - 1], text.as_bytes());
    assert_eq!(r[r.len() - 1], 0xFF);
    let r = m.request(&[43, 14, 1, 0]);
    assert_eq!(r[..7], [43, 14, 1, 0x81, 0, 0, 3]);
    // What plcctl sees is what Modbus wrote.
    let out = plc.project.plcctl(&["--json", "get", "D00010"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("4660"), "D00010 = 0x1234");
    let log = plc.stop();
    assert!(!log.iter().any(|l| l.contains("ERROR")), "{}", log.join("\n"));
    assert!(log.iter().any(|l| l.contains("the first request served")), "{}", log.join("\n"));
}

#[test]
fn exceptions_are_those_of_the_tcp_server() {
    let Some(mut plc) = Plc::start("exceptions", "") else { return };
    let m = &mut plc.master;
    let cases: Vec<(&str, Vec<u8>, [u8; 2])> = vec![
        ("FC 7 (not served)", vec![7], [0x87, 1]),
        ("FC 8 diagnostics (framed by silence)", vec![8, 0, 0, 0x12, 0x34], [0x88, 1]),
        ("FC 43 MEI type 13", vec![43, 13, 1, 0], [0xAB, 1]),
        ("FC 3 quantity 126", read(3, 0, 126), [0x83, 3]),
        ("FC 3 a byte too many", [read(3, 0, 1), vec![0]].concat(), [0x83, 3]),
        ("FC 5 value 0x1234", vec![5, 0, 0, 0x12, 0x34], [0x85, 3]),
        ("FC 16 byte count", vec![16, 0, 0, 0, 2, 2, 0, 1], [0x90, 3]),
        ("FC 3 gap", read(3, 130, 10), [0x83, 2]),
        ("FC 6 read-only register", vec![6, 0x04, 0x1A, 0, 1], [0x86, 2]),
        ("FC 1 unmapped", read(1, 32, 1), [0x81, 2]),
    ];
    for (what, pdu, expected) in &cases {
        assert_eq!(m.request(pdu), expected, "{what}");
    }
    assert_eq!(m.read_holdings(0, 1), [0], "nothing was written by a refused request");
    plc.stop();
}

#[test]
fn broadcasts_are_carried_out_other_units_and_bad_frames_are_not_answered() {
    let Some(mut plc) = Plc::start("broadcast", "") else { return };
    let m = &mut plc.master;
    // A write to unit 2, then a read of ours: the first answer is ours, and unit 2's write
    // was not carried out.
    m.send(&[2, 6, 0, 0, 0, 9]);
    assert_eq!(m.read_holdings(0, 1), [0]);
    // A broadcast write (FC 16), a broadcast read (ignored), then a read of ours: the first
    // answer is ours, with the broadcast's values.
    m.send(&[&[0][..], &write_registers(0, &[42, 43])].concat());
    m.send(&[0, 3, 0, 0, 0, 1]);
    assert_eq!(m.read_holdings(0, 2), [42, 43]);
    // A frame with a bad CRC is dropped; a master's next request is answered.
    let mut bad = with_crc(&[UNIT, 6, 0, 0, 0, 99]);
    bad[6] ^= 0xFF;
    m.send_raw(&bad);
    // Garbage: bytes that are no frame at all.
    m.send_raw(&[0xFF, 0x00, 0x13]);
    // A master waits for an answer before it sends again: a pause above t1.5 keeps the next
    // request apart (and if it does not, the request is dropped too and sent again).
    std::thread::sleep(Duration::from_millis(20));
    assert_eq!(m.request_again(&read(3, 0, 1)), [3, 2, 0, 42], "the bad write was dropped");
    let log = plc.stop();
    let text = log.join("\n");
    assert!(
        log.iter().any(|l| l.contains("a request to unit 2 ignored: this server is unit 7")),
        "{text}"
    );
    assert!(log.iter().any(|l| l.contains("bad frames dropped (a bad CRC or garbled)")), "{text}");
    let totals = log.iter().find(|l| l.contains(" frames: ")).expect("the totals at stop");
    assert!(totals.contains("1 broadcasts carried out, 2 ignored;"), "{totals}");
    assert!(!totals.contains("; 0 bad frames"), "{totals}");
}

#[test]
fn a_long_write_lands_at_one_scan_boundary() {
    // The program counts the scans that see D00000 != D00122: the first and last registers
    // of a 123-register write, two commands apart.
    let Some(mut plc) = Plc::start("boundary", "") else { return };
    let m = &mut plc.master;
    let first = m.read_holdings(1050, 1)[0];
    let mut i = 0u16;
    while i < 50 || m.read_holdings(1050, 1)[0].wrapping_sub(first) < 50 {
        assert_eq!(m.request(&write_registers(0, &[i; 123]))[0], 16);
        i += 1;
        assert!(i < 20_000, "the scan does not go on");
    }
    assert_eq!(m.read_holdings(300, 1), [0], "no scan saw half a write");
    plc.stop();
}

#[test]
fn tcp_and_rtu_serve_one_map() {
    let Some(mut plc) = Plc::start("both", "listen = \"127.0.0.1:0\"") else { return };
    let line = plc.daemon.wait_for_line("modbus: serving 127.0.0.1:");
    let addr: std::net::SocketAddr = line.rsplit(' ').next().unwrap().parse().unwrap();
    let mut tcp = TcpStream::connect(addr).unwrap();
    tcp.set_read_timeout(Some(PATIENCE)).unwrap();
    // Written over RTU, read over TCP.
    assert_eq!(plc.master.request(&[6, 0, 3, 0x0A, 0x0B]), [6, 0, 3, 0x0A, 0x0B]);
    tcp.write_all(&[0, 1, 0, 0, 0, 6, 1, 3, 0, 3, 0, 1]).unwrap();
    let mut r = [0u8; 11];
    tcp.read_exact(&mut r).unwrap();
    assert_eq!(r[7..], [3, 2, 0x0A, 0x0B]);
    // Written over TCP, read over RTU.
    tcp.write_all(&[0, 2, 0, 0, 0, 6, 1, 6, 0, 4, 0, 77]).unwrap();
    let mut r = [0u8; 12];
    tcp.read_exact(&mut r).unwrap();
    assert_eq!(plc.master.read_holdings(3, 2), [0x0A0B, 77]);
    let log = plc.stop();
    assert!(!log.iter().any(|l| l.contains("ERROR")), "{}", log.join("\n"));
}

#[test]
fn a_serial_port_that_cannot_be_opened_stops_the_start() {
    let project = Project::new(
        "modbus-rtu-noport",
        &[("plcd.toml", &config("", "/dev/plcd-no-such-tty")), ("main.il", MAIN)],
    );
    let (code, log) = start(&project).finish();
    let log = log.join("\n");
    assert_eq!(code, 1, "{log}");
    assert!(log.contains("cannot open /dev/plcd-no-such-tty ([modbus.rtu] port)"), "{log}");
    assert!(!log.contains("running"), "stopped before the project ran: {log}");
}

#[test]
fn a_line_that_hangs_up_is_logged_and_the_daemon_goes_on() {
    let Some(plc) = Plc::start("hangup", "") else { return };
    let Plc { daemon, master, project, port } = plc;
    // The master's end closes: the daemon's end hangs up.
    drop(master);
    daemon.wait_for(&format!("modbus: rtu {port}: reading"));
    let before = {
        let out = project.plcctl(&["--json", "get", "D00400"]);
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    daemon.wait("the scan to go on", || {
        let out = project.plcctl(&["--json", "get", "D00400"]);
        String::from_utf8_lossy(&out.stdout) != before
    });
    let (code, log) = daemon.stop();
    assert_eq!(code, 0, "{}", log.join("\n"));
    let errors: Vec<_> = log.iter().filter(|l| l.contains("ERROR")).collect();
    assert_eq!(errors.len(), 1, "one error for the failing line, not one a retry: {errors:?}");
}

//! The Modbus TCP server of a real `plcd run` on the sim backend, spoken to with raw frames:
//! every function code and exception, malformed frames (the connection is closed or answered,
//! the daemon keeps scanning and answering), 20 concurrent clients, the bounds, writes that
//! land at one scan boundary, STOP, forcing, and a reload with a changed map.
//!
//! Real time is only waited on, never asserted: each check waits for a state with a generous
//! bound, and the one timing assertion (the idle timeout) is a lower bound.

mod harness;

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::Output;
use std::time::{Duration, Instant};

use nix::sys::signal::Signal;

use harness::daemon::{Daemon, Project};
use harness::log::PATIENCE;
use harness::modbus::{bits, exception, read, words, write_coils, write_registers};

/// Scan program: D00400 counts scans (holding register 1050); M0000 is copied to M0010 (coil 16); P0000 to P0040;
/// D00300 counts the scans that saw D00000 differ from D00122 or M0000 from M007F.
const MAIN: &str = "INC D00400\nLOAD M0000\nOUT M0010\nLOAD P0000\nOUT P0040\n\
                    LOAD<> D00000 D00122\nINC D00300\nLOAD M0000\nAND NOT M122F\nINC D00301\n\
                    LOAD NOT M0000\nAND M122F\nINC D00301\nEND\n";

const MAP: &str =
    "[[modbus.coils]]\nstart = 0\ndevice = \"M0000\"\ncount = 1968\nwritable = true\n\
    [[modbus.coils]]\nstart = 2000\ndevice = \"P0040\"\ncount = 16\nwritable = true\n\
    [[modbus.coils]]\nstart = 3000\ndevice = \"K0000\"\ncount = 8\n\
    [[modbus.discrete_inputs]]\nstart = 0\ndevice = \"P0000\"\ncount = 16\n\
    [[modbus.holding_registers]]\nstart = 0\ndevice = \"D00000\"\ncount = 125\nwritable = true\n\
    [[modbus.holding_registers]]\nstart = 125\ndevice = \"D00125\"\ncount = 10\n\
    [[modbus.holding_registers]]\nstart = 300\ndevice = \"D00300\"\ncount = 2\n\
    [[modbus.holding_registers]]\nstart = 1050\ndevice = \"D00400\"\ncount = 1\n\
    [[modbus.input_registers]]\nstart = 0\ndevice = \"_SCAN_CUR\"\ncount = 4\n\
    [[modbus.input_registers]]\nstart = 10\ndevice = \"T0000\"\ncount = 2\n";

fn config(modbus: &str) -> String {
    format!(
        "[plc]\nscan_period_ms = 1\n[rt]\npolicy = \"other\"\nlock_memory = false\n\
         [control]\nsocket = \"plcd.sock\"\n[[program]]\nfile = \"main.il\"\n\
         [modbus]\nlisten = \"127.0.0.1:0\"\n{modbus}\n{MAP}"
    )
}

struct Plc {
    // Declared first, dropped first: the daemon is gone before its directory is removed.
    daemon: Daemon,
    project: Project,
    addr: SocketAddr,
}

impl Plc {
    fn start(name: &str, modbus: &str) -> Plc {
        let project = project(name, modbus);
        let daemon = start(&project);
        let line = daemon.wait_for_line("modbus: serving ");
        let addr = line.rsplit(' ').next().unwrap().parse().unwrap();
        let plc = Plc { daemon, project, addr };
        // Through the control socket: a Modbus probe would take one of the connections that
        // a test may limit.
        plc.wait(|p| p.scans() > 2, "scans");
        plc
    }

    /// D00400, the scan counter, through `plcctl --json get`.
    fn scans(&self) -> i64 {
        let out = self.ctl(&["--json", "get", "D00400"]);
        serde_json::from_slice::<serde_json::Value>(&out.stdout)
            .ok()
            .and_then(|v| v["values"][0]["value"].as_i64())
            .unwrap_or(-1)
    }

    fn connect(&self) -> TcpStream {
        let stream = TcpStream::connect(self.addr).expect("connects");
        stream.set_read_timeout(Some(PATIENCE)).unwrap();
        stream
    }

    /// One request on a fresh connection; the response PDU.
    fn request(&self, pdu: &[u8]) -> Vec<u8> {
        transact(&mut self.connect(), 1, 1, pdu)
    }

    fn read_holdings(&self, start: u16, count: u16) -> Vec<u16> {
        let r = self.request(&read(3, start, count));
        assert_eq!(r[0], 3, "read holding registers {start}+{count}: {r:02x?}");
        words(&r[2..])
    }

    fn ctl(&self, args: &[&str]) -> Output {
        self.project.plcctl(args)
    }

    fn wait(&self, mut done: impl FnMut(&Plc) -> bool, what: &str) {
        self.daemon.wait(what, || done(self));
    }

    /// The daemon still runs, the scan count goes on and a new connection is answered.
    fn assert_unharmed(&mut self) {
        assert!(self.daemon.running(), "plcd exited:\n{}", self.daemon.log().text());
        let before = self.read_holdings(1050, 1)[0];
        self.wait(|p| p.read_holdings(1050, 1)[0] != before, "the scan to go on");
    }

    /// SIGTERM: a clean stop; the whole log.
    fn stop(self) -> Vec<String> {
        let (code, log) = self.daemon.stop();
        assert_eq!(code, 0, "clean stop:\n{}", log.join("\n"));
        log
    }
}

/// A project of the scan program and a config with `modbus` added to `[modbus]`.
fn project(name: &str, modbus: &str) -> Project {
    Project::new(&format!("modbus-{name}"), &[("plcd.toml", &config(modbus)), ("main.il", MAIN)])
}

/// A Structured Text program whose located variables are holding registers 100-105 of the map:
/// a DINT and a REAL take two registers each, low word first.
const METER: &str = "PROGRAM Meter\nVAR\n  total AT %D00100 : DINT;\n  flow AT %D00102 : REAL;\n  \
                     setpoint AT %D00104 : INT;\n  doubled AT %D00105 : INT;\nEND_VAR\n\
                     total := 100000;\nflow := 1.5;\ndoubled := setpoint * 2;\nEND_PROGRAM\n";

/// The daemon on `project`, logging at debug level.
fn start(project: &Project) -> Daemon {
    project.start_with(&["--log-level", "debug"], &[])
}

fn frame(transaction: u16, unit: u8, pdu: &[u8]) -> Vec<u8> {
    let mut f = Vec::with_capacity(7 + pdu.len());
    f.extend_from_slice(&transaction.to_be_bytes());
    f.extend_from_slice(&[0, 0]);
    f.extend_from_slice(&(pdu.len() as u16 + 1).to_be_bytes());
    f.push(unit);
    f.extend_from_slice(pdu);
    f
}

/// Sends one request and reads its response; checks the MBAP header; the response PDU.
fn transact(stream: &mut TcpStream, transaction: u16, unit: u8, pdu: &[u8]) -> Vec<u8> {
    stream.write_all(&frame(transaction, unit, pdu)).unwrap();
    response(stream, transaction, unit)
}

fn response(stream: &mut TcpStream, transaction: u16, unit: u8) -> Vec<u8> {
    let mut header = [0u8; 7];
    stream.read_exact(&mut header).expect("a response header");
    assert_eq!(u16::from_be_bytes([header[0], header[1]]), transaction, "transaction id echoed");
    assert_eq!(&header[2..4], &[0, 0], "protocol id");
    assert_eq!(header[6], unit, "unit id echoed");
    let len = u16::from_be_bytes([header[4], header[5]]) as usize;
    let mut pdu = vec![0u8; len - 1];
    stream.read_exact(&mut pdu).expect("the response PDU");
    pdu
}

/// The server closed the connection: a read sees the end (or a reset).
fn closed(stream: &mut TcpStream) -> bool {
    let mut byte = [0u8; 1];
    matches!(stream.read(&mut byte), Ok(0) | Err(_))
}

#[test]
fn every_function_code_reads_and_writes_device_memory() {
    let plc = Plc::start("fcs", "");
    let mut c = plc.connect();
    // FC 6 then FC 3: D00001 = 0xBEEF.
    assert_eq!(transact(&mut c, 1, 1, &[6, 0, 1, 0xBE, 0xEF]), [6, 0, 1, 0xBE, 0xEF]);
    let r = transact(&mut c, 2, 1, &read(3, 0, 3));
    assert_eq!((r[0], r[1]), (3, 6));
    assert_eq!(words(&r[2..])[1], 0xBEEF);
    // FC 16 of the maximum 123 registers, read back with FC 3 of the maximum 125.
    let values: Vec<u16> = (0..123).map(|i| 7 * i + 1).collect();
    assert_eq!(transact(&mut c, 3, 1, &write_registers(1, &values)), [16, 0, 1, 0, 123]);
    let r = transact(&mut c, 4, 1, &read(3, 0, 125));
    assert_eq!((r[0], r[1]), (3, 250));
    assert_eq!(&words(&r[2..])[1..124], &values[..]);
    // FC 23: write D00010..=D00011, read D00009..=D00012 in the same request: the read sees
    // the write.
    let mut rw = vec![23, 0, 9, 0, 4, 0, 10, 0, 2, 4];
    rw.extend_from_slice(&[0x12, 0x34, 0x56, 0x78]);
    let r = transact(&mut c, 5, 1, &rw);
    assert_eq!((r[0], r[1]), (23, 8));
    assert_eq!(words(&r[2..]), [values[8], 0x1234, 0x5678, values[11]]);
    // FC 5 sets coil 0 (M0000); the program copies it to M0010, coil 16; FC 1 reads both.
    assert_eq!(transact(&mut c, 6, 1, &[5, 0, 0, 0xFF, 0]), [5, 0, 0, 0xFF, 0]);
    plc.wait(|p| bits(&p.request(&read(1, 0, 17))[2..], 17)[16], "M0010 to follow M0000");
    let r = transact(&mut c, 7, 1, &read(1, 0, 17));
    assert_eq!((r[0], r[1]), (1, 3));
    assert_eq!(bits(&r[2..], 17)[..2], [true, false]);
    // FC 15 of the maximum 1968 coils, read back with FC 1 (2000 is the read maximum, but
    // only 1968 are mapped from 0).
    let pattern: Vec<bool> = (0..1968).map(|i| i % 3 == 0).collect();
    assert_eq!(transact(&mut c, 8, 1, &write_coils(0, &pattern)), [15, 0, 0, 0x07, 0xB0]);
    let r = transact(&mut c, 9, 1, &read(1, 0, 1968));
    assert_eq!(bits(&r[2..], 1968)[17..], pattern[17..]);
    // FC 2: P0000..P000F are inputs; P0040.. are coils 2000.. (outputs written by the
    // program every scan: P0040 follows P0000, which the sim leaves OFF).
    let r = transact(&mut c, 10, 1, &read(2, 0, 16));
    assert_eq!((r[0], r[1], r[2], r[3]), (2, 2, 0, 0));
    // FC 4: _SCAN_CUR.._ERR_CODE, then T0000..T0001 current values.
    let r = transact(&mut c, 11, 1, &read(4, 0, 4));
    assert_eq!((r[0], r[1]), (4, 8));
    assert_eq!(words(&r[2..])[3], 0, "no error code");
    assert_eq!(transact(&mut c, 12, 1, &read(4, 10, 2)), [4, 4, 0, 0, 0, 0]);
    // The unit id 255 is served as well.
    assert_eq!(transact(&mut c, 13, 255, &read(3, 1050, 1))[0], 3);
    // What plcctl sees is what Modbus wrote.
    let out = plc.ctl(&["--json", "get", "D00010"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("4660"), "{text}");
    drop(c);
    let log = plc.stop();
    assert!(!log.iter().any(|l| l.contains("ERROR")), "{}", log.join("\n"));
}

#[test]
fn located_structured_text_variables_are_registers() {
    let config = format!("{}[[program]]\nname = \"meter\"\nfile = \"meter.st\"\n", config(""));
    let project = Project::new(
        "modbus-st",
        &[("plcd.toml", &config), ("main.il", MAIN), ("meter.st", METER)],
    );
    let daemon = start(&project);
    let line = daemon.wait_for_line("modbus: serving ");
    let addr = line.rsplit(' ').next().unwrap().parse().unwrap();
    let plc = Plc { daemon, project, addr };
    plc.wait(|p| p.read_holdings(100, 4) != [0; 4], "the program to run");
    // 100000 = 0x0001_86A0, 1.5 = 0x3FC0_0000: low words first.
    assert_eq!(plc.read_holdings(100, 4), [0x86A0, 0x0001, 0x0000, 0x3FC0]);
    // An HMI writes the INT set point; the program sees it at the next scan.
    assert_eq!(plc.request(&[6, 0, 104, 0, 21]), [6, 0, 104, 0, 21]);
    plc.wait(|p| p.read_holdings(105, 1) == [42], "doubled = 2 × the set point");
    let log = plc.stop();
    assert!(!log.iter().any(|l| l.contains("ERROR")), "{}", log.join("\n"));
}

#[test]
fn mask_write_server_id_device_identification_and_unit_zero() {
    let plc = Plc::start("more-fcs", "");
    let mut c = plc.connect();
    // FC 22 with the Modbus specification's example: 0x12 AND 0xF2 OR 0x25 gives 0x17; the
    // bits the AND mask keeps are the register's at the scan boundary that applies it.
    assert_eq!(transact(&mut c, 1, 1, &[6, 0, 7, 0x12, 0x12]), [6, 0, 7, 0x12, 0x12]);
    let mask = [22, 0, 7, 0xFF, 0xF2, 0x00, 0x25];
    assert_eq!(transact(&mut c, 2, 1, &mask), mask, "the response echoes the request");
    assert_eq!(plc.read_holdings(7, 1), [0x1217]);
    // FC 17: the byte count, the server id (unit_id and the product), the run indicator (RUN).
    let r = transact(&mut c, 3, 1, &[17]);
    let version = env!("CARGO_PKG_VERSION");
    let text = format!("plcd {version}");
    assert_eq!(r[..3], [17, 2 + text.len() as u8, 1]);
    assert_eq!(&r[3..r.len() - 1], text.as_bytes());
    assert_eq!(r[r.len() - 1], 0xFF, "the run indicator, last");
    // FC 43/14, the basic objects as a stream from object 0, and object 2 alone.
    let r = transact(&mut c, 4, 1, &[43, 14, 1, 0]);
    let mut basic = vec![43, 14, 1, 0x81, 0, 0, 3];
    for (id, text) in ["plcd", "plcd", version].iter().enumerate() {
        basic.extend([id as u8, text.len() as u8]);
        basic.extend(text.as_bytes());
    }
    assert_eq!(r, basic);
    let r = transact(&mut c, 5, 1, &[43, 14, 4, 2]);
    assert_eq!(r[..9], [43, 14, 4, 0x81, 0, 0, 1, 2, version.len() as u8]);
    // Unit id 0 is served like 255 and the configured one (the TCP implementation guide).
    assert_eq!(transact(&mut c, 6, 0, &read(3, 7, 1)), [3, 2, 0x12, 0x17]);
    let log = plc.stop();
    assert!(!log.iter().any(|l| l.contains("ERROR")), "{}", log.join("\n"));
}

#[test]
fn every_exception_is_answered_and_the_connection_stays_usable() {
    let plc = Plc::start("exceptions", "max_request_bytes = 200\n");
    let mut c = plc.connect();
    let cases: Vec<(&str, u8, Vec<u8>, Vec<u8>)> = vec![
        ("FC 7 (serial only)", 1, vec![7], exception(7, 1)),
        ("FC 22 a byte short", 1, vec![22, 0, 0, 0xFF, 0xFF, 0], exception(22, 3)),
        ("FC 22 unmapped", 1, vec![22, 0, 200, 0xFF, 0xFF, 0, 0], exception(22, 2)),
        ("FC 22 read-only", 1, vec![22, 0, 125, 0xFF, 0xFF, 0, 0], exception(22, 2)),
        ("FC 17 with data", 1, vec![17, 0], exception(17, 3)),
        ("FC 43 MEI type 13", 1, vec![43, 13, 1, 0], exception(43, 1)),
        ("FC 43 read code 5", 1, vec![43, 14, 5, 0], exception(43, 3)),
        ("FC 43 object 7 alone", 1, vec![43, 14, 4, 7], exception(43, 2)),
        ("FC 0", 1, vec![0], exception(0, 1)),
        ("FC 1 quantity 0", 1, read(1, 0, 0), exception(1, 3)),
        ("FC 1 quantity 2001", 1, read(1, 0, 2001), exception(1, 3)),
        ("FC 2 quantity 0", 1, read(2, 0, 0), exception(2, 3)),
        ("FC 3 quantity 126", 1, read(3, 0, 126), exception(3, 3)),
        ("FC 4 quantity 0", 1, read(4, 0, 0), exception(4, 3)),
        ("FC 3 a byte too many", 1, [read(3, 0, 1), vec![0]].concat(), exception(3, 3)),
        ("FC 3 a byte short", 1, vec![3, 0, 0, 0], exception(3, 3)),
        ("FC 5 value 0x1234", 1, vec![5, 0, 0, 0x12, 0x34], exception(5, 3)),
        ("FC 15 byte count", 1, vec![15, 0, 0, 0, 9, 1, 0xFF], exception(15, 3)),
        ("FC 15 quantity 1969", 1, write_coils(0, &[true; 1969]), exception(15, 3)),
        ("FC 16 byte count", 1, vec![16, 0, 0, 0, 2, 2, 0, 1], exception(16, 3)),
        ("FC 16 quantity 0", 1, vec![16, 0, 0, 0, 0, 0], exception(16, 3)),
        ("FC 23 read 126", 1, vec![23, 0, 0, 0, 126, 0, 0, 0, 1, 2, 0, 1], exception(23, 3)),
        ("FC 23 write 0", 1, vec![23, 0, 0, 0, 1, 0, 0, 0, 0, 0], exception(23, 3)),
        ("FC 1 unmapped", 1, read(1, 1968, 1), exception(1, 2)),
        ("FC 1 across the end", 1, read(1, 1960, 10), exception(1, 2)),
        ("FC 2 unmapped", 1, read(2, 16, 1), exception(2, 2)),
        ("FC 3 gap", 1, read(3, 130, 10), exception(3, 2)),
        ("FC 4 gap", 1, read(4, 3, 8), exception(4, 2)),
        ("FC 5 read-only coil", 1, vec![5, 0x0B, 0xB8, 0xFF, 0], exception(5, 2)),
        ("FC 6 read-only register", 1, vec![6, 0, 125, 0, 1], exception(6, 2)),
        ("FC 6 unmapped", 1, vec![6, 0xFF, 0xFF, 0, 1], exception(6, 2)),
        ("FC 15 past the mapped coils", 1, write_coils(2010, &[true; 8]), exception(15, 2)),
        ("FC 15 to read-only coils", 1, write_coils(3000, &[true; 2]), exception(15, 2)),
        ("FC 16 into read-only", 1, write_registers(120, &[1; 10]), exception(16, 2)),
        ("FC 23 read unmapped", 1, vec![23, 0, 200, 0, 1, 0, 0, 0, 1, 2, 0, 1], exception(23, 2)),
        ("FC 23 write read-only", 1, vec![23, 0, 0, 0, 1, 0, 125, 0, 1, 2, 0, 1], exception(23, 2)),
        ("another unit", 9, read(3, 0, 1), exception(3, 0x0B)),
        ("frame over max_request_bytes", 1, write_registers(0, &[0; 100]), exception(16, 3)),
    ];
    for (n, (what, unit, request, expected)) in cases.iter().enumerate() {
        eprintln!("{what}");
        let got = transact(&mut c, n as u16, *unit, request);
        assert_eq!(&got, expected, "{what}");
    }
    // Nothing was written by a refused request.
    assert_eq!(plc.read_holdings(0, 2), [0, 0]);
    // The same connection still reads.
    assert_eq!(transact(&mut c, 99, 1, &read(3, 0, 1)), [3, 2, 0, 0]);
    plc.stop();
}

#[test]
fn malformed_frames_close_the_connection_and_leave_the_daemon_unharmed() {
    let mut plc = Plc::start("malformed", "");
    let garbage: Vec<(&str, Vec<u8>)> = vec![
        ("a truncated MBAP header", vec![0, 1, 0, 0]),
        ("a frame cut short", frame(1, 1, &read(3, 0, 1))[..9].to_vec()),
        ("protocol id 1", vec![0, 1, 0, 1, 0, 6, 1, 3, 0, 0, 0, 1]),
        ("length 0", vec![0, 1, 0, 0, 0, 0, 1]),
        ("length 1 (no function code)", vec![0, 1, 0, 0, 0, 1, 1]),
        ("length 300", [vec![0, 1, 0, 0, 0x01, 0x2C, 1], vec![3; 299]].concat()),
        ("an exception code as a request", frame(1, 1, &[0x83, 2])),
        ("HTTP", b"GET / HTTP/1.1\r\nHost: plc\r\n\r\n".to_vec()),
    ];
    for (what, bytes) in &garbage {
        let mut c = plc.connect();
        c.write_all(bytes).unwrap();
        // A cut frame is closed by the client; the server must not wait forever for the rest.
        // A frame it refuses at once it may have closed already, and then the shutdown finds
        // the connection gone (ENOTCONN): either way it must end closed.
        let _ = c.shutdown(std::net::Shutdown::Write);
        assert!(closed(&mut c), "{what}: closed");
        plc.assert_unharmed();
    }
    // Random bytes, 200 connections of them: each is closed or answered, never a hang.
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    for _ in 0..200 {
        let mut c = plc.connect();
        let len = (seed % 300) as usize + 1;
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                seed as u8
            })
            .collect();
        let _ = c.write_all(&bytes);
        let _ = c.shutdown(std::net::Shutdown::Write);
        let mut rest = Vec::new();
        let _ = c.read_to_end(&mut rest);
    }
    plc.assert_unharmed();
    // A frame in two pieces is one frame.
    let mut c = plc.connect();
    let f = frame(7, 1, &read(3, 1050, 1));
    c.write_all(&f[..3]).unwrap();
    std::thread::sleep(Duration::from_millis(50));
    c.write_all(&f[3..]).unwrap();
    assert_eq!(response(&mut c, 7, 1)[0], 3);
    // Two frames in one write are two requests.
    let two = [frame(8, 1, &read(3, 0, 1)), frame(9, 1, &read(3, 1, 1))].concat();
    c.write_all(&two).unwrap();
    assert_eq!(response(&mut c, 8, 1)[0], 3);
    assert_eq!(response(&mut c, 9, 1)[0], 3);
    let log = plc.stop();
    assert!(log.iter().any(|l| l.contains("protocol id 0x0001 is not Modbus")), "logged");
}

#[test]
fn twenty_concurrent_clients_each_read_their_own_writes() {
    let mut plc = Plc::start("clients", "");
    let addr = plc.addr;
    let clients: Vec<_> = (0..20u16)
        .map(|k| {
            std::thread::spawn(move || {
                let mut c = TcpStream::connect(addr).unwrap();
                c.set_read_timeout(Some(PATIENCE)).unwrap();
                for i in 0..50u16 {
                    let value = k * 1000 + i;
                    let mut single = vec![6];
                    single.extend_from_slice(&(20 + k).to_be_bytes());
                    single.extend_from_slice(&value.to_be_bytes());
                    assert_eq!(transact(&mut c, i, 1, &single), single);
                    let r = transact(&mut c, i, 1, &read(3, 20 + k, 1));
                    assert_eq!(words(&r[2..]), [value], "client {k} reads its write");
                    let r = transact(&mut c, i, 1, &read(1, 0, 1968));
                    assert_eq!(r[0], 1);
                }
            })
        })
        .collect();
    for c in clients {
        c.join().expect("a client failed");
    }
    assert_eq!(plc.read_holdings(20, 20), (0..20).map(|k| k * 1000 + 49).collect::<Vec<_>>());
    plc.assert_unharmed();
    plc.stop();
}

#[test]
fn a_long_write_lands_at_one_scan_boundary() {
    // The program counts the scans that see D00000 != D00122 (D00300), or M0000 != M122F
    // (D00301): the first and last words of a 123-register and a 1968-coil write, four
    // commands apart.
    let plc = Plc::start("boundary", "");
    let mut c = plc.connect();
    let first = plc.read_holdings(1050, 1)[0];
    let mut i = 0u16;
    // At least 200 writes of each, and until the program scanned 100 times meanwhile.
    while i < 200 || plc.read_holdings(1050, 1)[0].wrapping_sub(first) < 100 {
        assert_eq!(transact(&mut c, i, 1, &write_registers(0, &[i; 123]))[0], 16);
        assert_eq!(transact(&mut c, i, 1, &write_coils(0, &vec![i % 2 == 1; 1968]))[0], 15);
        i += 1;
        assert!(i < 20_000, "the scan does not go on");
    }
    assert_eq!(plc.read_holdings(300, 2), [0, 0], "no scan saw half a write");
    plc.stop();
}

#[test]
fn connections_and_idle_time_are_bounded() {
    let plc = Plc::start("bounds", "max_connections = 2\nidle_timeout_s = 1\n");
    let mut a = plc.connect();
    let mut b = plc.connect();
    // The server's idle clock for `a` starts after it answered, so after this.
    let idle = Instant::now();
    assert_eq!(transact(&mut a, 1, 1, &read(3, 0, 1))[0], 3);
    assert_eq!(transact(&mut b, 1, 1, &read(3, 0, 1))[0], 3);
    let mut third = plc.connect();
    let _ = third.write_all(&frame(1, 1, &read(3, 0, 1)));
    assert!(closed(&mut third), "a third connection is closed at once");
    plc.daemon.wait_for("max_connections");
    // Idle for a second: closed, not before.
    assert!(closed(&mut a));
    assert!(idle.elapsed() >= Duration::from_secs(1), "closed after {:?}", idle.elapsed());
    assert!(closed(&mut b));
    // Room again.
    let mut d = plc.connect();
    assert_eq!(transact(&mut d, 1, 1, &read(3, 0, 1))[0], 3);
    let log = plc.stop();
    assert!(log.iter().any(|l| l.contains("idle timeout")), "{}", log.join("\n"));
}

#[test]
fn writes_in_stop_are_applied_and_forced_bits_keep_their_force() {
    let plc = Plc::start("stop", "");
    assert!(plc.ctl(&["stop"]).status.success());
    let mut c = plc.connect();
    assert_eq!(transact(&mut c, 1, 1, &[6, 0, 5, 0, 42]), [6, 0, 5, 0, 42]);
    assert_eq!(transact(&mut c, 2, 1, &read(3, 5, 1)), [3, 2, 0, 42], "read in STOP");
    let out = plc.ctl(&["--json", "get", "D00005"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("42"), "plcctl sees it");
    assert!(plc.ctl(&["run"]).status.success());
    // A forced output: a coil write reaches memory, the force wins at the output refresh.
    assert!(plc.ctl(&["force", "P0041=1"]).status.success());
    assert_eq!(transact(&mut c, 3, 1, &[5, 0x07, 0xD1, 0, 0]), [5, 0x07, 0xD1, 0, 0]);
    plc.wait(
        |p| bits(&p.request(&read(1, 2000, 2))[2..], 2)[1],
        "the forced P0041 to read ON after the next refresh",
    );
    plc.stop();
}

#[test]
fn a_reload_with_another_map_is_refused_and_the_old_map_served() {
    let mut plc = Plc::start("reload", "");
    let path = plc.project.config();
    let text = std::fs::read_to_string(&path).unwrap().replace("start = 1050", "start = 1051");
    plc.project.write("plcd.toml", &text);
    plc.daemon.signal(Signal::SIGHUP);
    plc.daemon.wait_for("reload refused: [modbus] changed");
    assert_eq!(plc.request(&read(3, 1051, 1)), exception(3, 2), "the new map is not served");
    plc.assert_unharmed();
    plc.stop();
}

#[test]
fn a_port_in_use_stops_the_start() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    let project = project("inuse", "");
    let text = config("").replace("127.0.0.1:0", &format!("127.0.0.1:{port}"));
    project.write("plcd.toml", &text);
    // The daemon exits by itself; its last line is read before the log is looked at.
    let (code, log) = start(&project).finish();
    let log = log.join("\n");
    assert_eq!(code, 1, "{log}");
    assert!(log.contains(&format!("cannot listen on 127.0.0.1:{port}")), "{log}");
}

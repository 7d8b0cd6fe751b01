//! The soak's clients: control clients over the Unix socket and Modbus TCP clients, each a
//! thread looping until told to stop, checking every answer, reconnecting every
//! `reconnect_every` rounds so that a leak per connection would show in the daemon's fds,
//! threads and memory.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use plcctl::client::{Client, ClientError};
use plcd_ipc::{ErrorKind, NamedValue, Reply, Request};

use super::project::{control_word, forced_bit, COILS_PER_CLIENT, MODBUS_REGISTERS};

/// How long a client waits for an answer before it counts a failure.
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(10);
/// Failures quoted in the report, at most.
const QUOTED: usize = 20;

/// What the clients counted.
#[derive(Default)]
pub struct Tally {
    /// Requests answered as expected.
    pub ok: AtomicU64,
    /// `busy` answers (control) and exception 06 (Modbus): the command queue was full; retried.
    pub busy: AtomicU64,
    /// Anything else: a wrong value, an unexpected error, a lost connection, a timeout.
    pub failures: AtomicU64,
    pub connections: AtomicU64,
    /// `get` answers whose scan counter D00000 was not the capture's scan count: a scan that
    /// did not run its program to END once.
    pub counter_mismatches: AtomicU64,
    /// The first failures, for the report.
    pub quoted: Mutex<Vec<String>>,
}

impl Tally {
    fn fail(&self, what: String) {
        self.failures.fetch_add(1, Ordering::Relaxed);
        let mut quoted = self.quoted.lock().unwrap();
        if quoted.len() < QUOTED {
            quoted.push(what);
        }
    }

    fn ok(&self) {
        self.ok.fetch_add(1, Ordering::Relaxed);
    }
}

fn connect_control(socket: &PathBuf, tally: &Tally) -> Option<Client> {
    for _ in 0..100 {
        match Client::connect(socket, ANSWER_TIMEOUT) {
            Ok(c) => {
                tally.connections.fetch_add(1, Ordering::Relaxed);
                return Some(c);
            }
            Err(_) => std::thread::sleep(Duration::from_millis(100)),
        }
    }
    tally.fail(format!("control: cannot connect to {}", socket.display()));
    None
}

/// One request, retried while the daemon answers `busy` (a full command queue is a designed
/// answer: "try again").
fn ask_raw(client: &mut Client, request: &Request, tally: &Tally) -> Result<Reply, ClientError> {
    loop {
        match client.request(request) {
            Err(ClientError::Daemon { failure, .. }) if failure.kind == ErrorKind::Busy => {
                tally.busy.fetch_add(1, Ordering::Relaxed);
                std::thread::sleep(Duration::from_millis(1));
            }
            other => return other,
        }
    }
}

/// [`ask_raw`]; `None` after a failure, counted.
fn ask(client: &mut Client, request: &Request, tally: &Tally, k: usize) -> Option<Reply> {
    match ask_raw(client, request, tally) {
        Ok(reply) => Some(reply),
        Err(e) => {
            tally.fail(format!("control client {k}: {request:?}: {e}"));
            None
        }
    }
}

/// Control client `k`, a round at a time (each after `pause`): `status`; `set` of its K word and a `get` of it with the scan counter
/// D00000 (the value it wrote; D00000 equal to the capture's scan count: every scan ran its
/// program to END, once); every fourth round `force` and `unforce` of its P bit (the answer's
/// force table shows it, then not; a reload or an online change between them keeps the force).
pub fn control_client(
    k: usize,
    socket: PathBuf,
    reconnect_every: u32,
    pause: Duration,
    stop: Arc<AtomicBool>,
    tally: Arc<Tally>,
) {
    let word = control_word(k);
    let bit = forced_bit(k);
    let mut round = 0u32;
    'connection: while !stop.load(Ordering::Relaxed) {
        let Some(mut c) = connect_control(&socket, &tally) else { return };
        for _ in 0..reconnect_every {
            if stop.load(Ordering::Relaxed) {
                break 'connection;
            }
            round = round.wrapping_add(1);
            std::thread::sleep(pause);
            match ask(&mut c, &Request::Status, &tally, k) {
                Some(Reply::Status(_)) => tally.ok(),
                Some(other) => tally.fail(format!("control client {k}: status: {other:?}")),
                None => continue 'connection,
            }
            let value = ((round as usize * 7 + k) % 30000) as i32;
            let set = Request::Set { writes: vec![NamedValue::device(&word, value)] };
            match ask(&mut c, &set, &tally, k) {
                Some(Reply::Written { count: 1, .. }) => tally.ok(),
                Some(other) => tally.fail(format!("control client {k}: set: {other:?}")),
                None => continue 'connection,
            }
            let get = Request::Get { devices: vec![word.clone(), "D00000".into()] };
            match ask(&mut c, &get, &tally, k) {
                Some(Reply::Values { scan, values }) => {
                    let got: Vec<Option<i64>> = values.iter().map(|v| v.value.as_i64()).collect();
                    let counter = scan as u16 as i16 as i64;
                    if got == [Some(i64::from(value)), Some(counter)] {
                        tally.ok();
                    } else {
                        if got[1] != Some(counter) {
                            tally.counter_mismatches.fetch_add(1, Ordering::Relaxed);
                        }
                        tally.fail(format!(
                            "control client {k}: get {word}, D00000 at scan {scan}: {got:?}, \
                             expected [{value}, {counter}]"
                        ));
                    }
                }
                Some(other) => tally.fail(format!("control client {k}: get: {other:?}")),
                None => continue 'connection,
            }
            if round.is_multiple_of(4) {
                let forced = |forces: &[plcd_ipc::DeviceValue]| {
                    forces.iter().find(|f| f.dev == bit).map(|f| f.value)
                };
                let force = ask(&mut c, &Request::Force { dev: bit.clone(), value: 1 }, &tally, k);
                let Some(force) = force else { continue 'connection };
                let unforce = match ask_raw(&mut c, &Request::Unforce { dev: bit.clone() }, &tally)
                {
                    Ok(reply) => Ok(reply),
                    Err(ClientError::Daemon { failure, .. })
                        if failure.kind == ErrorKind::Invalid =>
                    {
                        Err(failure.message)
                    }
                    Err(e) => {
                        tally.fail(format!("control client {k}: unforce: {e}"));
                        continue 'connection;
                    }
                };
                let forced_then =
                    matches!(&force, Reply::Forces { forces } if forced(forces) == Some(1));
                let unforced =
                    matches!(&unforce, Ok(Reply::Forces { forces }) if forced(forces).is_none());
                if forced_then && unforced {
                    tally.ok();
                    tally.ok();
                } else {
                    tally.fail(format!(
                        "control client {k}: force {bit} answered {force:?}, unforce {unforce:?}"
                    ));
                }
            }
        }
    }
}

/// One Modbus TCP transaction: the response's PDU, or why there is none.
fn transact(stream: &mut TcpStream, transaction: u16, pdu: &[u8]) -> Result<Vec<u8>, String> {
    let mut frame = Vec::with_capacity(7 + pdu.len());
    frame.extend_from_slice(&transaction.to_be_bytes());
    frame.extend_from_slice(&[0, 0]);
    frame.extend_from_slice(&(pdu.len() as u16 + 1).to_be_bytes());
    frame.push(1);
    frame.extend_from_slice(pdu);
    stream.write_all(&frame).map_err(|e| format!("sending: {e}"))?;
    let mut header = [0u8; 7];
    stream.read_exact(&mut header).map_err(|e| format!("reading the header: {e}"))?;
    if u16::from_be_bytes([header[0], header[1]]) != transaction {
        return Err(format!("transaction id {header:02x?}, expected {transaction}"));
    }
    let len = usize::from(u16::from_be_bytes([header[4], header[5]]));
    if !(2..=254).contains(&len) {
        return Err(format!("MBAP length {len}"));
    }
    let mut body = vec![0u8; len - 1];
    stream.read_exact(&mut body).map_err(|e| format!("reading the PDU: {e}"))?;
    Ok(body)
}

fn connect_modbus(address: SocketAddr, tally: &Tally) -> Option<TcpStream> {
    for _ in 0..100 {
        if let Ok(stream) = TcpStream::connect(address) {
            stream.set_nodelay(true).unwrap();
            stream.set_read_timeout(Some(ANSWER_TIMEOUT)).unwrap();
            stream.set_write_timeout(Some(ANSWER_TIMEOUT)).unwrap();
            tally.connections.fetch_add(1, Ordering::Relaxed);
            return Some(stream);
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    tally.fail(format!("modbus: cannot connect to {address}"));
    None
}

/// Modbus client `k`, a round at a time (each after `pause`): FC 16 of its 4 holding registers and FC 3 of them
/// back; FC 15 of its 16 coils and FC 1 of them back; FC 6 of one register and FC 3 of it;
/// FC 3 of D00000–D00031 and FC 4 of the scan time words. Values change every round.
pub fn modbus_client(
    k: usize,
    address: SocketAddr,
    reconnect_every: u32,
    pause: Duration,
    stop: Arc<AtomicBool>,
    tally: Arc<Tally>,
) {
    let registers = MODBUS_REGISTERS + 4 * k as u16;
    let coils = COILS_PER_CLIENT * k as u16;
    let mut round = 0u32;
    let mut transaction = 0u16;
    'connection: while !stop.load(Ordering::Relaxed) {
        let Some(mut stream) = connect_modbus(address, &tally) else { return };
        for _ in 0..reconnect_every {
            if stop.load(Ordering::Relaxed) {
                break 'connection;
            }
            round = round.wrapping_add(1);
            std::thread::sleep(pause);
            let r = round as u16;
            let values = [r, r ^ 0x5a5a, (k as u16) << 8 | (r & 0xff), !r];
            let bits: Vec<bool> =
                (0..16).map(|i| (r >> (i % 16)) & 1 == 1 || i == k % 16).collect();
            let mut write_registers = vec![16];
            write_registers.extend_from_slice(&registers.to_be_bytes());
            write_registers.extend_from_slice(&[0, 4, 8]);
            for v in values {
                write_registers.extend_from_slice(&v.to_be_bytes());
            }
            let mut write_coils = vec![15];
            write_coils.extend_from_slice(&coils.to_be_bytes());
            write_coils.extend_from_slice(&[0, 16, 2]);
            let packed: u16 = bits.iter().enumerate().map(|(i, b)| u16::from(*b) << i).sum();
            write_coils.extend_from_slice(&packed.to_le_bytes());
            let single = r.rotate_left(3);
            let last = registers + 3;
            // (request, what the answer must be; None: any answer of that function)
            let mut expected_registers = vec![3, 8];
            for v in values {
                expected_registers.extend_from_slice(&v.to_be_bytes());
            }
            let mut expected_coils = vec![1, 2];
            expected_coils.extend_from_slice(&packed.to_le_bytes());
            let mut single_request = vec![6];
            single_request.extend_from_slice(&last.to_be_bytes());
            single_request.extend_from_slice(&single.to_be_bytes());
            let mut expected_single = vec![3, 2];
            expected_single.extend_from_slice(&single.to_be_bytes());
            let steps: [(Vec<u8>, Option<Vec<u8>>); 8] = [
                (write_registers.clone(), Some(write_registers[..5].to_vec())),
                (read(3, registers, 4), Some(expected_registers)),
                (write_coils.clone(), Some(write_coils[..5].to_vec())),
                (read(1, coils, 16), Some(expected_coils)),
                (single_request.clone(), Some(single_request)),
                (read(3, last, 1), Some(expected_single)),
                (read(3, 0, 32), None),
                (read(4, 0, 4), None),
            ];
            for (request, expected) in steps {
                loop {
                    transaction = transaction.wrapping_add(1);
                    match transact(&mut stream, transaction, &request) {
                        Ok(answer) if answer == [request[0] | 0x80, 6] => {
                            // Server busy: the command queue was full; nothing was queued.
                            tally.busy.fetch_add(1, Ordering::Relaxed);
                            std::thread::sleep(Duration::from_millis(1));
                            continue;
                        }
                        Ok(answer) => {
                            let good = match &expected {
                                Some(e) => &answer == e,
                                None => answer.first() == request.first(),
                            };
                            if good {
                                tally.ok();
                            } else {
                                tally.fail(format!(
                                    "modbus client {k}: {request:02x?} answered {answer:02x?}, \
                                     expected {expected:02x?}"
                                ));
                            }
                        }
                        Err(e) => {
                            tally.fail(format!("modbus client {k}: {request:02x?}: {e}"));
                            continue 'connection;
                        }
                    }
                    break;
                }
            }
        }
    }
}

fn read(fc: u8, start: u16, count: u16) -> Vec<u8> {
    let mut p = vec![fc];
    p.extend_from_slice(&start.to_be_bytes());
    p.extend_from_slice(&count.to_be_bytes());
    p
}

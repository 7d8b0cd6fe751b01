//! The links against scripted peers: a TCP server thread and the other end of a pseudo
//! terminal, each answering what the test says, to see every fault classified and the
//! connection kept or dropped as docs/REMOTE.md says.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use serialport::SerialPort;

use super::frame::{Ask, Fault};
use super::link::Link;
use crate::config::{ModbusTable, SerialLine};

/// What the peer does about one request.
enum Act {
    Send(Vec<u8>),
    Sleep(u64),
    Close,
}

/// An MBAP answer.
fn mbap(tid: u16, unit: u8, pdu: &[u8]) -> Vec<u8> {
    let mut out = tid.to_be_bytes().to_vec();
    out.extend([0, 0]);
    out.extend(((pdu.len() + 1) as u16).to_be_bytes());
    out.push(unit);
    out.extend(pdu);
    out
}

/// A TCP peer answering the `n`th request (from 0, over every connection) with
/// `script(n, tid, unit)`; returns its address and its count of connections.
fn tcp_peer(
    script: impl Fn(usize, u16, u8) -> Vec<Act> + Send + 'static,
    after: impl Fn(usize) + Send + 'static,
) -> (String, Arc<AtomicUsize>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let connections = Arc::new(AtomicUsize::new(0));
    let counted = Arc::clone(&connections);
    std::thread::spawn(move || {
        let mut n = 0;
        for stream in listener.incoming() {
            let mut stream: TcpStream = stream.unwrap();
            counted.fetch_add(1, Ordering::SeqCst);
            'connection: loop {
                let mut header = [0u8; 7];
                if stream.read_exact(&mut header).is_err() {
                    break;
                }
                let len = usize::from(u16::from_be_bytes([header[4], header[5]])) - 1;
                let mut pdu = vec![0u8; len];
                stream.read_exact(&mut pdu).unwrap();
                let tid = u16::from_be_bytes([header[0], header[1]]);
                n += 1;
                for act in script(n - 1, tid, header[6]) {
                    match act {
                        Act::Send(bytes) => stream.write_all(&bytes).unwrap(),
                        Act::Sleep(ms) => std::thread::sleep(Duration::from_millis(ms)),
                        Act::Close => break 'connection,
                    }
                }
                after(n - 1);
            }
        }
    });
    (address, connections)
}

const READ_2: [u8; 6] = [0x03, 4, 0x12, 0x34, 0xAB, 0xCD];

fn ask() -> Ask {
    Ask { table: ModbusTable::HoldingRegisters, address: 0, count: 2, write: false }
}

fn exchange(link: &mut Link, timeout_ms: u64) -> Result<[u16; 2], Fault> {
    let mut values = [0u16; 2];
    link.exchange(1, &ask(), &mut values, Duration::from_millis(timeout_ms)).map(|()| values)
}

#[test]
fn tcp_answers_faults_and_when_the_connection_is_dropped() {
    let (address, connections) = tcp_peer(
        |n, tid, unit| match n {
            0 => vec![Act::Send(mbap(tid, unit, &READ_2))],
            1 => vec![Act::Send(mbap(tid, unit, &[0x83, 0x02]))],
            2 => vec![Act::Send(mbap(tid, 9, &READ_2))],
            3 => vec![Act::Send(mbap(tid.wrapping_add(1000), unit, &READ_2))],
            // Garbage: a protocol id other than 0. The stream cannot be trusted: reconnect.
            4 => vec![Act::Send(vec![0, 5, 0, 1, 0, 3, 1, 0x83, 2])],
            5 => vec![Act::Send(mbap(tid, unit, &[0x03, 2, 0, 1]))],
            6 => vec![Act::Close],
            _ => vec![Act::Send(mbap(tid, unit, &READ_2))],
        },
        |_| {},
    );
    let mut link = Link::tcp(&address);
    assert_eq!(exchange(&mut link, 1000), Ok([0x1234, 0xABCD]));
    assert!(link.round_trip_ns().is_some());
    assert_eq!(exchange(&mut link, 1000), Err(Fault::Exception(2)));
    assert!(link.round_trip_ns().is_some(), "an exception is an answer");
    assert_eq!(exchange(&mut link, 1000), Err(Fault::WrongUnit(9)));
    assert_eq!(link.round_trip_ns(), None);
    assert!(matches!(exchange(&mut link, 1000), Err(Fault::WrongTransaction(_))));
    assert_eq!(connections.load(Ordering::SeqCst), 1, "those faults keep the connection");
    assert!(
        matches!(exchange(&mut link, 1000), Err(Fault::Garbage(m)) if m.contains("protocol id 1"))
    );
    let short = exchange(&mut link, 1000);
    assert!(matches!(&short, Err(Fault::Garbage(m)) if m.contains("4 bytes for 2")), "{short:?}");
    assert_eq!(exchange(&mut link, 1000), Err(Fault::Closed));
    assert_eq!(exchange(&mut link, 1000), Ok([0x1234, 0xABCD]), "reconnected");
    // Garbage twice (a protocol id, an answer that does not fit), a close: three new ones.
    assert_eq!(connections.load(Ordering::SeqCst), 4);
}

#[test]
fn a_late_tcp_answer_is_dropped_and_counted_and_the_next_one_is_awaited() {
    let (sent, late_sent) = std::sync::mpsc::channel();
    let sent = std::sync::Mutex::new(sent);
    let (address, connections) = tcp_peer(
        move |n, tid, unit| match n {
            // Too late for its request (timeout 100 ms) ...
            0 => {
                std::thread::sleep(Duration::from_millis(300));
                vec![Act::Send(mbap(tid, unit, &READ_2))]
            }
            // ... so it is waiting when the next request goes, before that one's own answer.
            _ => vec![Act::Send(mbap(tid, unit, &[0x03, 4, 0, 7, 0, 8]))],
        },
        move |n| {
            if n == 0 {
                sent.lock().unwrap().send(()).unwrap();
            }
        },
    );
    let mut link = Link::tcp(&address);
    assert_eq!(exchange(&mut link, 100), Err(Fault::Timeout));
    late_sent.recv_timeout(Duration::from_secs(10)).unwrap();
    assert_eq!(exchange(&mut link, 1000), Ok([7, 8]));
    assert_eq!(link.take_late(), 1);
    assert_eq!(link.take_late(), 0);
    assert_eq!(connections.load(Ordering::SeqCst), 1, "a timeout keeps the connection");
}

#[test]
fn an_answer_cut_short_after_its_header_drops_the_connection() {
    let (address, connections) = tcp_peer(
        |n, tid, unit| match n {
            // The header in time, the rest after the timeout.
            0 => {
                let answer = mbap(tid, unit, &READ_2);
                vec![
                    Act::Send(answer[..7].to_vec()),
                    Act::Sleep(300),
                    Act::Send(answer[7..].to_vec()),
                ]
            }
            _ => vec![Act::Send(mbap(tid, unit, &[0x03, 4, 0, 7, 0, 8]))],
        },
        |_| {},
    );
    let mut link = Link::tcp(&address);
    assert_eq!(exchange(&mut link, 100), Err(Fault::Timeout));
    // The rest of that answer is never read as the next answer's header.
    assert_eq!(exchange(&mut link, 2000), Ok([7, 8]));
    assert_eq!(connections.load(Ordering::SeqCst), 2);
}

#[test]
fn a_refused_tcp_connection_is_a_connect_fault() {
    let refused = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let mut link = Link::tcp(&refused.to_string());
    assert!(matches!(exchange(&mut link, 200), Err(Fault::Connect(_))));
    let mut link = Link::tcp("no-such-host.invalid:502");
    assert!(matches!(exchange(&mut link, 200), Err(Fault::Connect(m)) if m.contains("resolve")));
}

/// An RTU answer with its CRC (`crc_fix` XORed into the CRC to break it).
fn rtu(unit: u8, pdu: &[u8], crc_fix: u16) -> Vec<u8> {
    let mut out = vec![unit];
    out.extend(pdu);
    let crc = modbus_core::rtu::crc16(&out) ^ crc_fix;
    out.extend(crc.to_be_bytes());
    out
}

/// Reads one request at the device end. Until the link has opened its end, the pseudo
/// terminal reports a hangup: wait for the link.
fn read_request(device: &mut serialport::TTYPort, request: &mut [u8]) {
    for _ in 0..500 {
        match device.read_exact(request) {
            Ok(()) => return,
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                std::thread::sleep(Duration::from_millis(10))
            }
            Err(e) => panic!("device end: {e}"),
        }
    }
    panic!("the link never opened its end");
}

#[test]
fn rtu_answers_and_faults_over_a_pseudo_terminal() {
    let (mut device, line_end) = serialport::TTYPort::pair().unwrap();
    let path = line_end.name().unwrap();
    drop(line_end);
    let line = SerialLine { baud: 115_200, ..SerialLine::new(&path) };
    let answers: Vec<Vec<u8>> = vec![
        rtu(1, &READ_2, 0),
        rtu(1, &READ_2, 0x0101),
        rtu(2, &READ_2, 0),
        rtu(1, &[0x83, 0x04], 0),
        vec![0x01, 0x63, 0x00, 0x00, 0x00],
        Vec::new(),
        rtu(1, &READ_2, 0),
    ];
    let peer = std::thread::spawn(move || {
        device.set_timeout(Duration::from_secs(5)).unwrap();
        let mut requests = Vec::new();
        for answer in answers {
            let mut request = [0u8; 8];
            read_request(&mut device, &mut request);
            requests.push(request);
            device.write_all(&answer).unwrap();
        }
        // The device end stays open until the link has read: a closed end is a hangup.
        (requests, device)
    });
    let mut link = Link::rtu(&line);
    assert_eq!(exchange(&mut link, 500), Ok([0x1234, 0xABCD]));
    assert_eq!(exchange(&mut link, 500), Err(Fault::BadCrc));
    assert_eq!(exchange(&mut link, 500), Err(Fault::WrongUnit(2)));
    assert_eq!(exchange(&mut link, 500), Err(Fault::Exception(4)));
    assert!(
        matches!(exchange(&mut link, 500), Err(Fault::Garbage(m)) if m.contains("function code 63"))
    );
    assert_eq!(exchange(&mut link, 100), Err(Fault::Timeout));
    assert_eq!(exchange(&mut link, 500), Ok([0x1234, 0xABCD]));
    let (requests, _device) = peer.join().unwrap();
    assert!(requests.iter().all(|r| r[..] == rtu(1, &[0x03, 0, 0, 0, 2], 0)[..]), "{requests:x?}");
}

#[test]
fn bytes_left_on_the_line_are_dropped_before_the_next_request_as_a_late_answer() {
    let (mut device, line_end) = serialport::TTYPort::pair().unwrap();
    let path = line_end.name().unwrap();
    drop(line_end);
    let line = SerialLine { baud: 115_200, ..SerialLine::new(&path) };
    let (sent, late_sent) = std::sync::mpsc::channel();
    let peer = std::thread::spawn(move || {
        device.set_timeout(Duration::from_secs(5)).unwrap();
        let mut request = [0u8; 8];
        read_request(&mut device, &mut request);
        std::thread::sleep(Duration::from_millis(250));
        device.write_all(&rtu(1, &READ_2, 0)).unwrap();
        sent.send(()).unwrap();
        read_request(&mut device, &mut request);
        device.write_all(&rtu(1, &[0x03, 4, 0, 5, 0, 6], 0)).unwrap();
        // The device end stays open until the link has read: a closed end is a hangup.
        device
    });
    let mut link = Link::rtu(&line);
    assert_eq!(exchange(&mut link, 100), Err(Fault::Timeout));
    late_sent.recv_timeout(Duration::from_secs(10)).unwrap();
    // Written is not yet readable at this end: let the pseudo terminal pass the bytes on.
    std::thread::sleep(Duration::from_millis(50));
    assert_eq!(exchange(&mut link, 500), Ok([5, 6]));
    assert_eq!(link.take_late(), 1);
    let _device = peer.join().unwrap();
}

//! A byte stream from a Modbus TCP client: framed as the server frames it
//! (`server::frame_size`), each frame answered as the server answers it (`server::answer_frame`,
//! the PDU code both servers share) against device memory, until the stream ends or the server
//! would close the connection. Every answer must be a well-formed frame naming its request
//! (transaction, unit, function or its exception), a read must carry what memory holds, and a
//! write the server confirms must be in memory, as asked.

use std::path::Path;
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

use modbus_core::Exception;
use plcd::config::{self, ModbusConfig};
use plcd::device::Address;
use plcd::drivers::real_time::WordWrite;
use plcd::services::modbus::map::Map;
use plcd::services::modbus::pdu::{Plc, Scratch, HEADER};
use plcd::services::modbus::server;

/// The map: 32 writable coils on M, 16 discrete inputs on P, 32 writable holding registers on
/// D00000 and 8 read-only ones at 100 on D00100, 16 input registers on D00200.
pub const CONFIG: &str = r#"
[modbus]
unit_id = 1
max_request_bytes = 200
[[modbus.coils]]
start = 0
device = "M0000"
count = 32
writable = true
[[modbus.discrete_inputs]]
start = 0
device = "P0000"
count = 16
[[modbus.holding_registers]]
start = 0
device = "D00000"
count = 32
writable = true
[[modbus.holding_registers]]
start = 100
device = "D00100"
count = 8
[[modbus.input_registers]]
start = 0
device = "D00200"
count = 16
[[program]]
name = "main"
file = "main.il"
"#;

/// Device memory as a plain array: reads see every write before them.
pub struct Memory {
    pub map: Map,
    pub words: Mutex<Vec<u16>>,
}

impl Memory {
    pub fn new(map: Map) -> Memory {
        let mut words = vec![0u16; 1 << 16];
        // Something to read that is not all zeros.
        for (i, w) in words.iter_mut().enumerate() {
            *w = (i as u16).wrapping_mul(0x9E37);
        }
        Memory { map, words: Mutex::new(words) }
    }
}

impl Plc for Memory {
    fn read(&self, _: Instant, read: &mut dyn FnMut(&[u16])) -> Result<(), Exception> {
        let words = self.words.lock().unwrap();
        let ranges = self.map.mirror_ranges();
        let image: Vec<u16> = ranges
            .iter()
            .flat_map(|r| &words[usize::from(r.start)..usize::from(r.end)])
            .copied()
            .collect();
        read(&image);
        Ok(())
    }

    fn write(&self, writes: &[WordWrite], _: Instant) -> Result<(), Exception> {
        let mut words = self.words.lock().unwrap();
        for w in writes {
            let word = &mut words[usize::from(w.word)];
            *word = (*word & !w.mask) | (w.value & w.mask);
        }
        Ok(())
    }

    fn running(&self) -> bool {
        true
    }
}

pub fn config() -> &'static ModbusConfig {
    static CONFIG_: OnceLock<ModbusConfig> = OnceLock::new();
    CONFIG_.get_or_init(|| config::parse(CONFIG, Path::new("plcd.toml")).expect("config").modbus)
}

/// The word index of a device: a word, or the word a bit is in.
fn word_of(dev: &str) -> usize {
    let address = Address::parse(dev).expect("a device");
    let word = match address.as_word() {
        Ok(word) => word.0,
        Err(_) => address.as_bit().expect("a bit or a word").word,
    };
    usize::from(word)
}

/// Where a Modbus address of a table is in memory, as the target's map says (written out
/// here, not asked of the server's map): `(word, mask)` for a bit, `(word, 0xFFFF)` for a
/// register, and whether a client may write it.
pub fn place(fc_table: u8, address: u16) -> Option<(usize, u16, bool)> {
    let a = usize::from(address);
    match fc_table {
        // Coils.
        1 if a < 32 => Some((word_of("M0000") + a / 16, 1 << (a % 16), true)),
        // Discrete inputs.
        2 if a < 16 => Some((word_of("P0000"), 1 << a, false)),
        // Holding registers.
        3 if a < 32 => Some((word_of("D00000") + a, 0xFFFF, true)),
        3 if (100..108).contains(&a) => Some((word_of("D00100") + a - 100, 0xFFFF, false)),
        // Input registers.
        4 if a < 16 => Some((word_of("D00200") + a, 0xFFFF, false)),
        _ => None,
    }
}

pub fn run(data: &[u8]) {
    let config = config();
    let memory = Memory::new(Map::new(config));
    let mut scratch = Box::<Scratch>::default();
    let mut rest = data;
    while rest.len() >= HEADER {
        let header: &[u8; HEADER] = rest[..HEADER].try_into().unwrap();
        let Ok(size) = server::frame_size(header) else { return };
        if rest.len() < size {
            return;
        }
        let (frame, after) = rest.split_at(size);
        rest = after;
        let before = memory.words.lock().unwrap().clone();
        let deadline = Instant::now() + Duration::from_secs(1);
        let answer =
            server::answer_frame(&memory.map, &memory, config, frame, deadline, &mut scratch);
        let Ok(n) = answer else {
            assert!(frame[HEADER] >= 0x80, "closed on a request: {frame:02X?}");
            return;
        };
        let out = &scratch.out[..n];
        assert!(n >= HEADER + 2, "an answer of {n} bytes");
        assert_eq!(out[..2], frame[..2], "the transaction id");
        assert_eq!(out[2..4], [0, 0], "the protocol id");
        assert_eq!(usize::from(u16::from_be_bytes([out[4], out[5]])), n - 6, "the MBAP length");
        assert_eq!(out[6], frame[6], "the unit id");
        check_pdu(&frame[HEADER..], &out[HEADER..], &before, &memory.words.lock().unwrap());
    }
}

/// Checks an answer's PDU against the request's and memory before and after it. Shared with
/// the RTU target.
pub fn check_pdu(request: &[u8], answer: &[u8], before: &[u16], after: &[u16]) {
    let fc = request[0];
    if answer[0] == fc | 0x80 {
        assert_eq!(answer.len(), 2, "an exception answer of {} bytes", answer.len());
        let codes = [0x01, 0x02, 0x03, 0x04, 0x06, 0x0B];
        assert!(codes.contains(&answer[1]), "exception code {:#04x}", answer[1]);
        assert!(before == after, "memory changed by a refused request: {request:02X?}");
        return;
    }
    assert_eq!(answer[0], fc, "another function code in the answer");
    let be = |b: &[u8], at: usize| u16::from_be_bytes([b[at], b[at + 1]]);
    match fc {
        0x01 | 0x02 => {
            let (start, count) = (be(request, 1), be(request, 3));
            assert_eq!(usize::from(answer[1]), usize::from(count).div_ceil(8), "byte count");
            assert_eq!(answer.len(), 2 + usize::from(answer[1]));
            for i in 0..count {
                let bit = answer[2 + usize::from(i / 8)] >> (i % 8) & 1 == 1;
                let expected = place(fc, start + i).is_some_and(|(w, m, _)| after[w] & m != 0);
                assert_eq!(bit, expected, "bit {} of FC {fc}", start + i);
            }
        }
        0x03 | 0x04 => {
            let (start, count) = (be(request, 1), be(request, 3));
            assert_eq!(usize::from(answer[1]), 2 * usize::from(count), "byte count");
            assert_eq!(answer.len(), 2 + 2 * usize::from(count));
            for i in 0..count {
                let expected = place(fc, start + i).map_or(0, |(w, _, _)| after[w]);
                assert_eq!(be(answer, 2 + 2 * usize::from(i)), expected, "register {}", start + i);
            }
        }
        0x05 => {
            assert_eq!(answer, request, "FC 5 echoes its request");
            let (w, m, writable) = place(1, be(request, 1)).expect("a confirmed write is mapped");
            assert!(writable, "a read-only coil written");
            assert_eq!(after[w] & m != 0, be(request, 3) == 0xFF00, "the coil as written");
        }
        0x06 => {
            assert_eq!(answer, request, "FC 6 echoes its request");
            let (w, _, writable) = place(3, be(request, 1)).expect("a confirmed write is mapped");
            assert!(writable, "a read-only register written");
            assert_eq!(after[w], be(request, 3), "the register as written");
        }
        0x0F => {
            assert_eq!(answer, &request[..5], "FC 15 echoes address and quantity");
            let (start, count) = (be(request, 1), be(request, 3));
            for i in 0..count {
                let (w, m, writable) = place(1, start + i).expect("a confirmed write is mapped");
                assert!(writable);
                let on = request[6 + usize::from(i / 8)] >> (i % 8) & 1 == 1;
                assert_eq!(after[w] & m != 0, on, "coil {}", start + i);
            }
        }
        0x10 => {
            assert_eq!(answer, &request[..5], "FC 16 echoes address and quantity");
            let (start, count) = (be(request, 1), be(request, 3));
            for i in 0..count {
                let (w, _, writable) = place(3, start + i).expect("a confirmed write is mapped");
                assert!(writable);
                assert_eq!(after[w], be(request, 6 + 2 * usize::from(i)), "register {}", start + i);
            }
        }
        _ => {}
    }
}

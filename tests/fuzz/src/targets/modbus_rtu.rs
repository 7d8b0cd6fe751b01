//! Bytes on a Modbus RTU line, with the silences between them: framed by the RTU server's
//! framer (`rtu::Framer`: a frame by its function code's length or ended by a t1.5 silence)
//! and each frame handled as the server handles it (`rtu::answer_frame`) for unit 1 against
//! device memory. Only frames with a good CRC come out of the framer; only a frame to unit 1
//! gets an answer, which has a good CRC, names unit 1, and passes the checks of the TCP target
//! (the same PDU code); a broadcast is carried out unanswered, and only if it writes.
//!
//! The input is a sequence of `[silence] [n] [n bytes]`: a silence of `silence` × 100 µs
//! before the bytes (the target's line has a t1.5 of 750 µs).

use std::time::{Duration, Instant};

use plcd::services::modbus::map::Map;
use plcd::services::modbus::pdu::{self, Scratch};
use plcd::services::modbus::rtu::{
    self, Counters, Framer, Received, MAX_FRAME, MIN_FRAME, PIECE_GAP_NS,
};

use super::modbus_tcp::{check_pdu, config, Memory};
use crate::Bytes;

const CHAR_GAP_NS: u64 = 750_000;
const UNIT: u8 = 1;

pub fn run(data: &[u8]) {
    let config = config();
    let memory = Memory::new(Map::new(config));
    let mut scratch = Box::<Scratch>::default();
    let mut counters = Counters::default();
    let mut framer = Framer::new(CHAR_GAP_NS);
    let mut input = Bytes::new(data);
    let mut now = 1_000_000u64;
    let mut frame = [0u8; MAX_FRAME];
    let mut bad = 0u64;
    loop {
        let last = input.is_empty();
        if last {
            // The line falls silent: whatever is pending ends, even a frame announced longer
            // than what came (which waits `PIECE_GAP_NS` for its rest).
            now += 10 * CHAR_GAP_NS + PIECE_GAP_NS;
        } else {
            now += u64::from(input.u8()) * 100_000;
            let n = usize::from(input.u8());
            // What came before this silence is framed first, as the server's loop does.
            drain(&mut framer, now, &mut frame, &mut bad, |f| {
                handle(f, &memory, &mut scratch, &mut counters)
            });
            framer.push(input.take(n), now);
            now += 1;
        }
        drain(&mut framer, now, &mut frame, &mut bad, |f| {
            handle(f, &memory, &mut scratch, &mut counters)
        });
        if last {
            break;
        }
    }
    assert_eq!(framer.deadline(), None, "bytes left in the framer after a long silence");
    assert!(counters.answered == 0, "the target sends nothing: it counts no answers");
}

fn drain(
    framer: &mut Framer,
    now: u64,
    frame: &mut [u8; MAX_FRAME],
    bad: &mut u64,
    mut handle: impl FnMut(&[u8]),
) {
    while let Some(received) = framer.next(now, frame) {
        match received {
            Received::Bad => *bad += 1,
            Received::Frame(n) => {
                assert!((MIN_FRAME..=MAX_FRAME).contains(&n), "a frame of {n} bytes");
                assert!(rtu::crc_ok(&frame[..n]), "a frame with a bad CRC");
                handle(&frame[..n]);
            }
        }
    }
}

fn handle(frame: &[u8], memory: &Memory, scratch: &mut Scratch, counters: &mut Counters) {
    let before = memory.words.lock().unwrap().clone();
    let deadline = Instant::now() + Duration::from_secs(1);
    let answer = rtu::answer_frame(&memory.map, memory, UNIT, frame, deadline, scratch, counters);
    let after = memory.words.lock().unwrap().clone();
    let (unit, request) = (frame[0], &frame[1..frame.len() - 2]);
    match answer {
        Some(n) => {
            assert_eq!(unit, UNIT, "an answer to unit {unit}");
            let out = &scratch.out[..n];
            assert!(rtu::crc_ok(out), "an answer with a bad CRC");
            assert_eq!(out[0], UNIT, "an answer from another unit");
            check_pdu(request, &out[1..n - 2], &before, &after);
        }
        None if unit == 0 && request[0] < 0x80 && pdu::writes(request[0]) => {}
        None => assert!(before == after, "an unanswered frame changed memory: {frame:02X?}"),
    }
}

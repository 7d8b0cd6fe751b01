//! An answer to the remote I/O client (`[[remote]]`): a request made from the input (a table,
//! an address, a count, read or write), then the rest of the input as the server's answer over
//! TCP (MBAP header, then PDU) or RTU (address, PDU, CRC), checked by the client's own code
//! (`io::remote::frame`). What it accepts must hold exactly the values the frame carries, and
//! a confirmed write must name the request's address and count.

use plcd::config::{ModbusTable, RemoteTable};
use plcd::io::remote::frame::{self, Ask};

use crate::Bytes;

pub fn run(data: &[u8]) {
    let mut input = Bytes::new(data);
    let table = ModbusTable::ALL[usize::from(input.u8() % 4)];
    let write = input.bool() && matches!(table, ModbusTable::Coils | ModbusTable::HoldingRegisters);
    let max = RemoteTable::max_count(table, write);
    let count = 1 + input.u16() % max;
    let address = input.u16().min(u16::try_from(65536 - u32::from(count)).unwrap_or(u16::MAX));
    let ask = Ask { table, address, count, write };
    let tcp = input.bool();
    let unit = input.u8();
    let answer = input.rest();
    if tcp {
        let Some(header) = answer.get(..7) else { return };
        let Ok((_tid, len)) = frame::check_mbap(header.try_into().unwrap()) else { return };
        let Some(pdu) = answer.get(7..7 + len) else { return };
        check(&ask, pdu);
    } else {
        // The answer's length as the client reads it, then a good CRC in its last two bytes,
        // which the fuzzer could not make: past the CRC check into the PDU's.
        let with_unit: Vec<u8> = std::iter::once(unit).chain(answer.iter().copied()).collect();
        let Ok(Some(len)) = frame::rtu_answer_len(&with_unit) else { return };
        if len > with_unit.len() || len < 4 {
            return;
        }
        let mut whole = with_unit[..len - 2].to_vec();
        whole.extend_from_slice(&modbus_core::rtu::crc16(&whole).to_be_bytes());
        let pdu = frame::check_rtu(unit, &whole).expect("a good CRC and the unit asked");
        assert_eq!(pdu.len(), len - 3, "an RTU PDU of another length than announced");
        check(&ask, pdu);
    }
}

fn check(ask: &Ask, pdu: &[u8]) {
    let words = if ask.table.is_bits() {
        usize::from(ask.count).div_ceil(16)
    } else {
        usize::from(ask.count)
    };
    let mut values = vec![0xA5A5u16; words];
    if frame::check_answer(ask, pdu, &mut values).is_err() {
        return;
    }
    let count = usize::from(ask.count);
    assert_eq!(pdu[0], ask.function(), "accepted the answer of another function");
    if ask.write {
        let echo = [ask.address.to_be_bytes(), ask.count.to_be_bytes()].concat();
        assert_eq!(pdu[1..], echo[..], "accepted a confirmation of another write");
    } else if ask.table.is_bits() {
        assert_eq!(pdu.len(), 2 + count.div_ceil(8));
        for k in 0..count {
            let sent = pdu[2 + k / 8] >> (k % 8) & 1 == 1;
            assert_eq!(values[k / 16] >> (k % 16) & 1 == 1, sent, "bit {k}");
        }
        let last = count % 16;
        if last != 0 {
            assert_eq!(values[count / 16] >> last, 0, "bits past the count set");
        }
    } else {
        assert_eq!(pdu.len(), 2 + 2 * count);
        for (k, value) in values.iter().enumerate() {
            assert_eq!(
                *value,
                u16::from_be_bytes([pdu[2 + 2 * k], pdu[3 + 2 * k]]),
                "register {k}"
            );
        }
    }
}

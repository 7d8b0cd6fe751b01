//! Modbus client frames: a table's request encoded for TCP or RTU, and an answer checked
//! against the request it answers, strictly: the function code, the byte count, the exact
//! length, the echoed address and quantity, the unit id, the transaction id or the CRC.
//!
//! PDUs and ADUs are encoded and decoded by the `modbus-core` crate; what it leaves to the
//! application (does this answer fit this request?) is here. A table's values travel as
//! words: registers one per word, bits packed sixteen to a word, bit `k` of the table at bit
//! `k % 16` of word `k / 16`.

use std::fmt;

use modbus_core::{Coils, Data, Request, RequestPdu, Response};

use crate::config::{ModbusTable, RemoteTable};

/// The longest Modbus ADU (TCP: 7 header bytes and 253 PDU bytes; RTU: 256).
pub const MAX_ADU: usize = 260;
/// The MBAP header of Modbus TCP.
pub const MBAP: usize = 7;

/// Words a table's values take.
pub fn words_of(table: &RemoteTable) -> usize {
    if table.table.is_bits() {
        usize::from(table.count).div_ceil(16)
    } else {
        usize::from(table.count)
    }
}

/// What one exchange does: read a table, or write one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ask {
    pub table: ModbusTable,
    pub address: u16,
    pub count: u16,
    pub write: bool,
}

impl Ask {
    pub fn read(table: &RemoteTable) -> Ask {
        Ask { table: table.table, address: table.address, count: table.count, write: false }
    }

    pub fn write(table: &RemoteTable) -> Ask {
        Ask { table: table.table, address: table.address, count: table.count, write: true }
    }

    /// The function code: 1–4 to read, 15 or 16 to write.
    pub fn function(&self) -> u8 {
        match (self.table, self.write) {
            (ModbusTable::Coils, false) => 0x01,
            (ModbusTable::DiscreteInputs, _) => 0x02,
            (ModbusTable::HoldingRegisters, false) => 0x03,
            (ModbusTable::InputRegisters, _) => 0x04,
            (ModbusTable::Coils, true) => 0x0F,
            (ModbusTable::HoldingRegisters, true) => 0x10,
        }
    }
}

impl fmt::Display for Ask {
    /// `read of holding registers 0..=9`, for logs.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let last = u32::from(self.address) + u32::from(self.count) - 1;
        write!(
            f,
            "{} of {} {}..={last}",
            if self.write { "write" } else { "read" },
            self.table.key().replace('_', " "),
            self.address
        )
    }
}

/// Why an exchange failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Fault {
    /// TCP: the connection could not be made (refused, unreachable, timed out, a name that
    /// does not resolve). RTU: the port could not be opened.
    Connect(String),
    /// TCP: the device closed the connection.
    Closed,
    /// A read or write of the socket or port failed.
    Io(String),
    /// No complete answer within `timeout_ms`.
    Timeout,
    /// The device answered with an exception code.
    Exception(u8),
    /// The answer came from (or was addressed as) another unit.
    WrongUnit(u8),
    /// TCP: the answer carries a transaction id this client never sent, or not lately.
    WrongTransaction(u16),
    /// RTU: the answer's CRC does not match.
    BadCrc,
    /// The answer is not a Modbus answer to the request: the reason.
    Garbage(String),
}

/// A [`Fault`] without its details: what is counted, and logged once while it lasts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FaultKind {
    Connect,
    Closed,
    Io,
    Timeout,
    Exception,
    WrongUnit,
    WrongTransaction,
    BadCrc,
    Garbage,
}

impl FaultKind {
    pub const ALL: [FaultKind; 9] = [
        FaultKind::Connect,
        FaultKind::Closed,
        FaultKind::Io,
        FaultKind::Timeout,
        FaultKind::Exception,
        FaultKind::WrongUnit,
        FaultKind::WrongTransaction,
        FaultKind::BadCrc,
        FaultKind::Garbage,
    ];

    /// Its name in `plcctl status`: `timeout`, `wrong_unit`, …
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::Connect => "connect",
            FaultKind::Closed => "closed",
            FaultKind::Io => "io",
            FaultKind::Timeout => "timeout",
            FaultKind::Exception => "exception",
            FaultKind::WrongUnit => "wrong_unit",
            FaultKind::WrongTransaction => "wrong_transaction",
            FaultKind::BadCrc => "bad_crc",
            FaultKind::Garbage => "garbage",
        }
    }
}

impl Fault {
    pub fn kind(&self) -> FaultKind {
        match self {
            Fault::Connect(_) => FaultKind::Connect,
            Fault::Closed => FaultKind::Closed,
            Fault::Io(_) => FaultKind::Io,
            Fault::Timeout => FaultKind::Timeout,
            Fault::Exception(_) => FaultKind::Exception,
            Fault::WrongUnit(_) => FaultKind::WrongUnit,
            Fault::WrongTransaction(_) => FaultKind::WrongTransaction,
            Fault::BadCrc => FaultKind::BadCrc,
            Fault::Garbage(_) => FaultKind::Garbage,
        }
    }

    /// The condition that is logged once while it lasts: the kind, and an exception's code
    /// (a device that answers 02 and then 04 has changed its mind, which is news).
    pub fn condition(&self) -> (FaultKind, u8) {
        match self {
            Fault::Exception(code) => (FaultKind::Exception, *code),
            other => (other.kind(), 0),
        }
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::Connect(why) => write!(f, "cannot connect: {why}"),
            Fault::Closed => write!(f, "the device closed the connection"),
            Fault::Io(why) => write!(f, "{why}"),
            Fault::Timeout => write!(f, "no answer in time"),
            Fault::Exception(code) => {
                write!(f, "exception {code:02X}")?;
                match code {
                    1 => write!(f, " (illegal function)"),
                    2 => write!(f, " (illegal data address)"),
                    3 => write!(f, " (illegal data value)"),
                    4 => write!(f, " (server device failure)"),
                    6 => write!(f, " (server device busy)"),
                    0x0A => write!(f, " (gateway path unavailable)"),
                    0x0B => write!(f, " (gateway target device failed to respond)"),
                    _ => Ok(()),
                }
            }
            Fault::WrongUnit(unit) => write!(f, "an answer from unit {unit}"),
            Fault::WrongTransaction(tid) => write!(f, "an answer with transaction id {tid}"),
            Fault::BadCrc => write!(f, "an answer with a bad CRC"),
            Fault::Garbage(why) => write!(f, "not a Modbus answer: {why}"),
        }
    }
}

/// Encodes the request PDU of `ask` into `out` (the values of a write from `values`) and
/// returns its length.
pub fn encode_pdu(ask: &Ask, values: &[u16], out: &mut [u8]) -> usize {
    let mut scratch = [0u8; 256];
    let count = usize::from(ask.count);
    let request = match (ask.table, ask.write) {
        (ModbusTable::Coils, false) => Request::ReadCoils(ask.address, ask.count),
        (ModbusTable::DiscreteInputs, _) => Request::ReadDiscreteInputs(ask.address, ask.count),
        (ModbusTable::HoldingRegisters, false) => {
            Request::ReadHoldingRegisters(ask.address, ask.count)
        }
        (ModbusTable::InputRegisters, _) => Request::ReadInputRegisters(ask.address, ask.count),
        (ModbusTable::Coils, true) => {
            let mut bits = [false; 2000];
            for (k, bit) in bits[..count].iter_mut().enumerate() {
                *bit = values[k / 16] >> (k % 16) & 1 != 0;
            }
            let coils = Coils::from_bools(&bits[..count], &mut scratch[..count.div_ceil(8)])
                .expect("a write table's count is within FC 15's limit");
            Request::WriteMultipleCoils(ask.address, coils)
        }
        (ModbusTable::HoldingRegisters, true) => {
            let data = Data::from_words(&values[..count], &mut scratch[..2 * count])
                .expect("a write table's count is within FC 16's limit");
            Request::WriteMultipleRegisters(ask.address, data)
        }
    };
    modbus_core::Encode::encode(&RequestPdu(request), out)
        .expect("a table's request fits the largest PDU")
}

/// Encodes a whole Modbus TCP request (MBAP header and PDU); returns its length.
pub fn encode_tcp(tid: u16, unit: u8, ask: &Ask, values: &[u16], out: &mut [u8; MAX_ADU]) -> usize {
    let len = encode_pdu(ask, values, &mut out[MBAP..]);
    out[..2].copy_from_slice(&tid.to_be_bytes());
    out[2..4].fill(0);
    out[4..6].copy_from_slice(&(1 + len as u16).to_be_bytes());
    out[6] = unit;
    MBAP + len
}

/// Encodes a whole Modbus RTU request (unit, PDU, CRC); returns its length.
pub fn encode_rtu(unit: u8, ask: &Ask, values: &[u16], out: &mut [u8; MAX_ADU]) -> usize {
    let len = encode_pdu(ask, values, &mut out[1..]);
    out[0] = unit;
    let crc = modbus_core::rtu::crc16(&out[..1 + len]);
    out[1 + len..3 + len].copy_from_slice(&crc.to_be_bytes());
    len + 3
}

/// The MBAP header of an answer, checked: the transaction id and the PDU's length (the unit
/// id is checked with the PDU).
pub fn check_mbap(header: &[u8; MBAP]) -> Result<(u16, usize), Fault> {
    let tid = u16::from_be_bytes([header[0], header[1]]);
    let protocol = u16::from_be_bytes([header[2], header[3]]);
    let length = usize::from(u16::from_be_bytes([header[4], header[5]]));
    if protocol != 0 {
        return Err(Fault::Garbage(format!("protocol id {protocol}, not 0 (Modbus)")));
    }
    // The unit id and at least a function code and an exception code; at most 253 PDU bytes.
    if !(3..=254).contains(&length) {
        return Err(Fault::Garbage(format!("an MBAP length of {length}")));
    }
    Ok((tid, length - 1))
}

/// Checks an RTU answer whose expected length is complete in `frame`: the CRC and the unit
/// id; returns the PDU.
pub fn check_rtu(unit: u8, frame: &[u8]) -> Result<&[u8], Fault> {
    if frame.len() < 4 {
        return Err(Fault::Garbage(format!("a frame of {} bytes", frame.len())));
    }
    let (body, crc) = frame.split_at(frame.len() - 2);
    if modbus_core::rtu::crc16(body) != u16::from_be_bytes([crc[0], crc[1]]) {
        return Err(Fault::BadCrc);
    }
    if body[0] != unit {
        return Err(Fault::WrongUnit(body[0]));
    }
    Ok(&body[1..])
}

/// The length of the RTU answer that starts `buf`, once enough of it is there to tell
/// (`Ok(None)` until then); an error if it cannot be an answer at all.
pub fn rtu_answer_len(buf: &[u8]) -> Result<Option<usize>, Fault> {
    match modbus_core::rtu::response_pdu_len(buf) {
        // Unit id, PDU, CRC.
        Ok(Some(pdu)) => Ok(Some(pdu + 3)),
        Ok(None) => Ok(None),
        Err(_) => Err(Fault::Garbage(format!("function code {:02X}", buf[1]))),
    }
}

/// Checks an answer's PDU against `ask`; a read's values go to `values`
/// ([`words_of`] words).
pub fn check_answer(ask: &Ask, pdu: &[u8], values: &mut [u16]) -> Result<(), Fault> {
    let Some(&function) = pdu.first() else {
        return Err(Fault::Garbage("an empty PDU".into()));
    };
    if function == ask.function() | 0x80 {
        return match pdu {
            [_, code] => Err(Fault::Exception(*code)),
            _ => Err(Fault::Garbage(format!("an exception answer of {} bytes", pdu.len()))),
        };
    }
    if function != ask.function() {
        return Err(Fault::Garbage(format!(
            "function code {function:02X} in the answer to {:02X}",
            ask.function()
        )));
    }
    let count = usize::from(ask.count);
    let response =
        Response::try_from(pdu).map_err(|e| Fault::Garbage(format!("a malformed answer ({e})")))?;
    let expect_len = |expected: usize| {
        if pdu.len() == expected {
            Ok(())
        } else {
            Err(Fault::Garbage(format!(
                "{} bytes for {count} {}, not {expected}",
                pdu.len(),
                ask.table.key().replace('_', " ")
            )))
        }
    };
    // A read's byte count must be what the request asked for, not only the frame's length:
    // a wrong one with the right length would leave values unread (found by the fuzzer).
    let byte_count = |expected: usize| {
        if usize::from(pdu[1]) == expected {
            Ok(())
        } else {
            Err(Fault::Garbage(format!(
                "a byte count of {} for {count} {}, not {expected}",
                pdu[1],
                ask.table.key().replace('_', " ")
            )))
        }
    };
    match response {
        Response::ReadCoils(coils) | Response::ReadDiscreteInputs(coils) => {
            let bytes = count.div_ceil(8);
            expect_len(2 + bytes)?;
            byte_count(bytes)?;
            values[..count.div_ceil(16)].fill(0);
            for k in 0..count {
                if coils.get(k) == Some(true) {
                    values[k / 16] |= 1 << (k % 16);
                }
            }
            Ok(())
        }
        Response::ReadHoldingRegisters(data) | Response::ReadInputRegisters(data) => {
            expect_len(2 + 2 * count)?;
            byte_count(2 * count)?;
            for (k, value) in values[..count].iter_mut().enumerate() {
                *value = data.get(k).unwrap_or(0);
            }
            Ok(())
        }
        Response::WriteMultipleCoils(address, quantity)
        | Response::WriteMultipleRegisters(address, quantity) => {
            expect_len(5)?;
            if address != ask.address || quantity != ask.count {
                return Err(Fault::Garbage(format!(
                    "the answer confirms {quantity} from {address}, not {} from {}",
                    ask.count, ask.address
                )));
            }
            Ok(())
        }
        _ => Err(Fault::Garbage(format!("function code {function:02X}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(table: ModbusTable, address: u16, count: u16) -> RemoteTable {
        RemoteTable {
            table,
            address,
            count,
            device: crate::device::Address::parse("M0000").unwrap(),
            first: 0,
            swap_bytes: false,
            swap_words: false,
        }
    }

    #[test]
    fn requests_are_encoded_for_tcp_and_rtu() {
        let read = Ask::read(&table(ModbusTable::HoldingRegisters, 0x006B, 3));
        let mut out = [0u8; MAX_ADU];
        let n = encode_tcp(0x0102, 0x11, &read, &[], &mut out);
        assert_eq!(out[..n], [0x01, 0x02, 0, 0, 0, 6, 0x11, 0x03, 0x00, 0x6B, 0x00, 0x03]);
        // The example of the serial line specification: 11 03 006B 0003, CRC 7687.
        let n = encode_rtu(0x11, &read, &[], &mut out);
        assert_eq!(out[..n], [0x11, 0x03, 0x00, 0x6B, 0x00, 0x03, 0x76, 0x87]);
        let coils = Ask::write(&table(ModbusTable::Coils, 19, 10));
        let n = encode_tcp(1, 1, &coils, &[0b01_1100_1101], &mut out);
        assert_eq!(out[7..n], [0x0F, 0x00, 0x13, 0x00, 0x0A, 0x02, 0xCD, 0x01]);
        let registers = Ask::write(&table(ModbusTable::HoldingRegisters, 1, 2));
        let n = encode_tcp(1, 1, &registers, &[0x000A, 0x0102], &mut out);
        assert_eq!(out[7..n], [0x10, 0x00, 0x01, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01, 0x02]);
        assert_eq!(read.to_string(), "read of holding registers 107..=109");
    }

    #[test]
    fn answers_are_checked_against_their_request() {
        let mut values = [0u16; 2];
        let bits = Ask::read(&table(ModbusTable::DiscreteInputs, 0, 18));
        check_answer(&bits, &[0x02, 3, 0xCD, 0x6B, 0x01], &mut values).unwrap();
        assert_eq!(values, [0x6BCD, 0x0001]);
        let too_short = check_answer(&bits, &[0x02, 2, 0xCD, 0x6B], &mut values);
        assert!(matches!(too_short, Err(Fault::Garbage(_))), "{too_short:?}");
        assert_eq!(check_answer(&bits, &[0x82, 0x02], &mut values), Err(Fault::Exception(2)));
        let other = check_answer(&bits, &[0x01, 3, 0, 0, 0], &mut values);
        assert_eq!(other, Err(Fault::Garbage("function code 01 in the answer to 02".into())));
        let registers = Ask::read(&table(ModbusTable::InputRegisters, 8, 2));
        check_answer(&registers, &[0x04, 4, 0x12, 0x34, 0xAB, 0xCD], &mut values).unwrap();
        assert_eq!(values, [0x1234, 0xABCD]);
        let extra = check_answer(&registers, &[0x04, 4, 0x12, 0x34, 0xAB, 0xCD, 0], &mut values);
        assert!(matches!(extra, Err(Fault::Garbage(_))));
        // The right length with a byte count that is not the request's: refused (found by the
        // fuzzer; the registers past the byte count read as 0 and the bits as OFF before).
        let short_count = check_answer(&registers, &[0x04, 3, 0x12, 0x34, 0xAB, 0xCD], &mut values);
        assert!(matches!(short_count, Err(Fault::Garbage(m)) if m.contains("byte count of 3")));
        let coils = Ask::read(&table(ModbusTable::Coils, 0, 10));
        let short_bits = check_answer(&coils, &[0x01, 1, 0xFF, 0x03], &mut values);
        assert!(matches!(short_bits, Err(Fault::Garbage(m)) if m.contains("byte count of 1")));
        let write = Ask::write(&table(ModbusTable::HoldingRegisters, 1, 2));
        check_answer(&write, &[0x10, 0, 1, 0, 2], &mut values).unwrap();
        let wrong_echo = check_answer(&write, &[0x10, 0, 1, 0, 3], &mut values);
        assert!(matches!(wrong_echo, Err(Fault::Garbage(m)) if m.contains("confirms 3 from 1")));
        assert!(matches!(check_answer(&write, &[], &mut values), Err(Fault::Garbage(_))));
    }

    #[test]
    fn frames_are_checked_for_protocol_length_crc_and_unit() {
        assert_eq!(check_mbap(&[0, 7, 0, 0, 0, 5, 1]), Ok((7, 4)));
        assert!(matches!(check_mbap(&[0, 7, 0, 1, 0, 5, 1]), Err(Fault::Garbage(_))));
        assert!(matches!(check_mbap(&[0, 7, 0, 0, 1, 0, 1]), Err(Fault::Garbage(_))));
        let answer = [0x11, 0x03, 0x02, 0x00, 0x0A, 0, 0];
        let mut frame = answer;
        let crc = modbus_core::rtu::crc16(&frame[..5]);
        frame[5..].copy_from_slice(&crc.to_be_bytes());
        assert_eq!(check_rtu(0x11, &frame), Ok(&frame[1..5]));
        assert_eq!(check_rtu(0x12, &frame), Err(Fault::WrongUnit(0x11)));
        frame[4] ^= 1;
        assert_eq!(check_rtu(0x11, &frame), Err(Fault::BadCrc));
        assert_eq!(rtu_answer_len(&frame[..2]), Ok(None));
        assert_eq!(rtu_answer_len(&frame[..3]), Ok(Some(7)));
        assert_eq!(rtu_answer_len(&[0x11, 0x83]), Ok(Some(5)));
        assert!(rtu_answer_len(&[0x11, 0x63]).is_err());
    }
}

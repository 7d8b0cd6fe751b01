//! One Modbus request PDU in, one response ADU out, framed for TCP or RTU: the function codes,
//! their checks in the order of the Modbus application protocol (function → quantity and
//! structure → addresses → execution), and the exceptions. Decoding and encoding are
//! modbus-core's; what a request does to the PLC goes through [`Plc`], so that this is
//! testable without a scan thread.

use std::time::Instant;

use modbus_core::tcp::server::encode_response;
use modbus_core::tcp::{Header, ResponseAdu};
use modbus_core::{
    Coils, Data, Error as FrameError, Exception, ExceptionResponse, FunctionCode, Request,
    Response, ResponsePdu,
};

use super::map::{Map, MapError};
use crate::config::ModbusTable;
use crate::drivers::real_time::WordWrite;

/// The longest Modbus TCP frame: the 7-byte MBAP header and a PDU of at most 253 bytes.
pub const MAX_ADU: usize = 260;
/// The MBAP header: transaction id, protocol id, length, unit id.
pub const HEADER: usize = 7;
/// The Modbus TCP "no unit" identifiers, served as well as `unit_id`: 0xFF and 0 (the
/// Modbus TCP implementation guide, 4.4.1.2: a TCP device accepts both).
pub const ANY_UNIT: [u8; 2] = [0xFF, 0];

/// What FC 43/14 (read device identification) and FC 17 (report server id) tell a client.
const VENDOR_NAME: &str = "plcd";
const PRODUCT_CODE: &str = "plcd";
const REVISION: &str = env!("CARGO_PKG_VERSION");

/// The PLC as the server sees it: reads from the mirror image, writes at a scan boundary.
pub trait Plc {
    /// Calls `read` with a mirror image captured at a scan boundary after this call began.
    /// `Err` (exception 04) if none came before `deadline`.
    fn read(&self, deadline: Instant, read: &mut dyn FnMut(&[u16])) -> Result<(), Exception>;
    /// Applies `writes` together at one scan boundary and returns once they are applied:
    /// `Err(ServerDeviceBusy)` (06) when the command queue has no room (nothing was queued),
    /// `Err(ServerDeviceFailure)` (04) when they were not applied before `deadline`.
    fn write(&self, writes: &[WordWrite], deadline: Instant) -> Result<(), Exception>;
    /// True while the PLC is in RUN (FC 17's run indicator).
    fn running(&self) -> bool;
}

/// Scratch space for one response, kept by the connection.
pub struct Scratch {
    /// The response frame.
    pub out: [u8; MAX_ADU],
    buffers: Buffers,
}

struct Buffers {
    bits: [bool; 2000],
    packed: [u8; 250],
    words: [u16; 125],
    bytes: [u8; 250],
    writes: Vec<WordWrite>,
}

impl Default for Scratch {
    fn default() -> Self {
        Scratch {
            out: [0; MAX_ADU],
            buffers: Buffers {
                bits: [false; 2000],
                packed: [0; 250],
                words: [0; 125],
                bytes: [0; 250],
                writes: Vec::with_capacity(128),
            },
        }
    }
}

/// Answers one Modbus TCP request. `pdu` is not empty. Returns the response's length in
/// `scratch.out`, or `None` when the request is no Modbus request at all (a function code of
/// 128 or more, which only responses carry): the connection is then closed.
pub fn answer(
    map: &Map,
    plc: &dyn Plc,
    unit_id: u8,
    hdr: Header,
    pdu: &[u8],
    deadline: Instant,
    scratch: &mut Scratch,
) -> Option<usize> {
    let other_unit = hdr.unit_id != unit_id && !ANY_UNIT.contains(&hdr.unit_id);
    respond(map, plc, unit_id, other_unit, pdu, deadline, scratch, |pdu, out| {
        encode_response(ResponseAdu { hdr, pdu }, out)
    })
}

/// Answers one Modbus RTU request to `unit_id` (or a broadcast, whose answer the caller does
/// not send): the same handling as [`answer`], framed with the address and the CRC. `pdu` is
/// not empty. `None` for a function code of 128 or more.
pub fn answer_rtu(
    map: &Map,
    plc: &dyn Plc,
    unit_id: u8,
    pdu: &[u8],
    deadline: Instant,
    scratch: &mut Scratch,
) -> Option<usize> {
    respond(map, plc, unit_id, false, pdu, deadline, scratch, |pdu, out| {
        let hdr = modbus_core::rtu::Header { slave: unit_id };
        modbus_core::rtu::server::encode_response(modbus_core::rtu::ResponseAdu { hdr, pdu }, out)
    })
}

/// Serves `pdu` (exception 0B instead when `other_unit`) and encodes the response with
/// `encode`.
#[allow(clippy::too_many_arguments)]
fn respond(
    map: &Map,
    plc: &dyn Plc,
    unit_id: u8,
    other_unit: bool,
    pdu: &[u8],
    deadline: Instant,
    scratch: &mut Scratch,
    encode: impl FnOnce(ResponsePdu<'_>, &mut [u8]) -> Result<usize, FrameError>,
) -> Option<usize> {
    let fc = *pdu.first()?;
    if fc >= 0x80 {
        return None;
    }
    let result = if other_unit {
        Err(Exception::GatewayTargetDevice)
    } else {
        serve(map, plc, unit_id, pdu, deadline, &mut scratch.buffers)
    };
    let pdu = ResponsePdu(
        result
            .map_err(|exception| ExceptionResponse { function: FunctionCode::new(fc), exception }),
    );
    encode(pdu, &mut scratch.out).ok()
}

/// Whether function `fc` writes: the functions a broadcast (Modbus RTU address 0) may carry.
pub fn writes(fc: u8) -> bool {
    matches!(fc, 5 | 6 | 15 | 16 | 22 | 23)
}

/// An exception response to function `fc` (below 128).
pub fn exception(hdr: Header, fc: u8, exception: Exception, out: &mut [u8; MAX_ADU]) -> usize {
    let function = FunctionCode::new(fc & 0x7F);
    let pdu = ResponsePdu(Err(ExceptionResponse { function, exception }));
    encode_response(ResponseAdu { hdr, pdu }, out).unwrap_or(0)
}

fn address_error(_: MapError) -> Exception {
    Exception::IllegalDataAddress
}

/// Exception 03 unless `ok`.
fn value(ok: bool) -> Result<(), Exception> {
    if ok {
        Ok(())
    } else {
        Err(Exception::IllegalDataValue)
    }
}

fn serve<'s>(
    map: &Map,
    plc: &dyn Plc,
    unit_id: u8,
    pdu: &[u8],
    deadline: Instant,
    scratch: &'s mut Buffers,
) -> Result<Response<'s>, Exception> {
    let fc = pdu[0];
    // The function codes modbus-core leaves to the application, on the PDU's bytes.
    match fc {
        0x16 => return mask_write(map, plc, pdu, deadline, scratch),
        0x11 => return report_server_id(plc, unit_id, pdu, &mut scratch.bytes),
        0x2B => return device_identification(pdu, &mut scratch.bytes),
        _ => {}
    }
    let request = match Request::try_from(pdu) {
        Ok(request) => request,
        // A function served here whose PDU is too short for it, or whose byte count runs
        // past the PDU, or a coil value other than 0000/FF00: the structure is wrong (03).
        Err(FrameError::BufferSize | FrameError::ByteCount(_) | FrameError::CoilValue(_))
            if matches!(fc, 1..=6 | 15 | 16 | 23) =>
        {
            return Err(Exception::IllegalDataValue)
        }
        Err(_) => return Err(Exception::IllegalFunction),
    };
    let Buffers { bits, packed, words, bytes, writes } = scratch;
    writes.clear();
    match request {
        Request::ReadCoils(start, count) | Request::ReadDiscreteInputs(start, count) => {
            let table = if fc == 1 { ModbusTable::Coils } else { ModbusTable::DiscreteInputs };
            value(pdu.len() == 5 && (1..=2000).contains(&count))?;
            map.check(table, start, count, false).map_err(address_error)?;
            let bits = &mut bits[..usize::from(count)];
            plc.read(deadline, &mut |image| map.read_bits(table, start, image, bits))?;
            packed.fill(0);
            let coils =
                Coils::from_bools(bits, packed).map_err(|_| Exception::ServerDeviceFailure)?;
            Ok(if fc == 1 {
                Response::ReadCoils(coils)
            } else {
                Response::ReadDiscreteInputs(coils)
            })
        }
        Request::ReadHoldingRegisters(start, count) | Request::ReadInputRegisters(start, count) => {
            let table =
                if fc == 3 { ModbusTable::HoldingRegisters } else { ModbusTable::InputRegisters };
            value(pdu.len() == 5 && (1..=125).contains(&count))?;
            map.check(table, start, count, false).map_err(address_error)?;
            let words = &mut words[..usize::from(count)];
            plc.read(deadline, &mut |image| map.read_words(table, start, image, words))?;
            let data =
                Data::from_words(words, bytes).map_err(|_| Exception::ServerDeviceFailure)?;
            Ok(if fc == 3 {
                Response::ReadHoldingRegisters(data)
            } else {
                Response::ReadInputRegisters(data)
            })
        }
        Request::WriteSingleCoil(address, on) => {
            value(pdu.len() == 5)?;
            map.check(ModbusTable::Coils, address, 1, true).map_err(address_error)?;
            map.coil_writes(address, std::iter::once(on), writes);
            plc.write(writes, deadline)?;
            // The response echoes the request (modbus-core's WriteSingleCoil response carries
            // the address only).
            bytes[..4].copy_from_slice(&pdu[1..5]);
            Ok(Response::Custom(FunctionCode::WriteSingleCoil, &bytes[..4]))
        }
        Request::WriteSingleRegister(address, word) => {
            value(pdu.len() == 5)?;
            map.check(ModbusTable::HoldingRegisters, address, 1, true).map_err(address_error)?;
            map.register_writes(address, std::iter::once(word), writes);
            plc.write(writes, deadline)?;
            Ok(Response::WriteSingleRegister(address, word))
        }
        Request::WriteMultipleCoils(start, coils) => {
            let count = coils.len();
            let byte_count = usize::from(pdu[5]);
            value(
                (1..=1968).contains(&count)
                    && byte_count == count.div_ceil(8)
                    && pdu.len() == 6 + byte_count,
            )?;
            map.check(ModbusTable::Coils, start, count as u16, true).map_err(address_error)?;
            map.coil_writes(start, coils.into_iter(), writes);
            plc.write(writes, deadline)?;
            Ok(Response::WriteMultipleCoils(start, count as u16))
        }
        Request::WriteMultipleRegisters(start, data) => {
            let count = data.len();
            let byte_count = usize::from(pdu[5]);
            value(
                (1..=123).contains(&count)
                    && byte_count == 2 * count
                    && pdu.len() == 6 + byte_count,
            )?;
            map.check(ModbusTable::HoldingRegisters, start, count as u16, true)
                .map_err(address_error)?;
            map.register_writes(start, data.into_iter(), writes);
            plc.write(writes, deadline)?;
            Ok(Response::WriteMultipleRegisters(start, count as u16))
        }
        Request::ReadWriteMultipleRegisters(read_start, read_count, write_start, data) => {
            let write_count = data.len();
            let byte_count = usize::from(pdu[9]);
            value(
                (1..=125).contains(&read_count)
                    && (1..=121).contains(&write_count)
                    && byte_count == 2 * write_count
                    && pdu.len() == 10 + byte_count,
            )?;
            let table = ModbusTable::HoldingRegisters;
            map.check(table, write_start, write_count as u16, true).map_err(address_error)?;
            map.check(table, read_start, read_count, false).map_err(address_error)?;
            // The write first, then the read (Modbus application protocol, 6.17): the image
            // read is captured after the boundary that applied the write.
            map.register_writes(write_start, data.into_iter(), writes);
            plc.write(writes, deadline)?;
            let words = &mut words[..usize::from(read_count)];
            plc.read(deadline, &mut |image| map.read_words(table, read_start, image, words))?;
            let data =
                Data::from_words(words, bytes).map_err(|_| Exception::ServerDeviceFailure)?;
            Ok(Response::ReadWriteMultipleRegisters(data))
        }
        _ => Err(Exception::IllegalFunction),
    }
}

/// FC 22, mask write register: `(current AND and_mask) OR (or_mask AND NOT and_mask)`, applied
/// at one scan boundary as a masked word write (the program cannot change the word between a
/// read and the write). The response echoes the request.
fn mask_write<'s>(
    map: &Map,
    plc: &dyn Plc,
    pdu: &[u8],
    deadline: Instant,
    scratch: &'s mut Buffers,
) -> Result<Response<'s>, Exception> {
    value(pdu.len() == 7)?;
    let word = |at: usize| u16::from_be_bytes([pdu[at], pdu[at + 1]]);
    let (address, and_mask, or_mask) = (word(1), word(3), word(5));
    map.check(ModbusTable::HoldingRegisters, address, 1, true).map_err(address_error)?;
    scratch.writes.clear();
    map.register_writes(address, std::iter::once(or_mask), &mut scratch.writes);
    for write in scratch.writes.iter_mut() {
        write.mask = !and_mask;
    }
    plc.write(&scratch.writes, deadline)?;
    scratch.bytes[..6].copy_from_slice(&pdu[1..7]);
    Ok(Response::Custom(FunctionCode::new(0x16), &scratch.bytes[..6]))
}

/// FC 17, report server id: the byte count, the server id (device specific: the configured
/// unit id, then the product and its version as text, `plcd 0.1.0`), and the run indicator
/// last (FF in RUN, 00 otherwise), with no additional data: clients that read the indicator
/// as the last byte (pymodbus does) read it right.
fn report_server_id<'s>(
    plc: &dyn Plc,
    unit_id: u8,
    pdu: &[u8],
    out: &'s mut [u8; 250],
) -> Result<Response<'s>, Exception> {
    value(pdu.len() == 1)?;
    let run = if plc.running() { 0xFF } else { 0x00 };
    let mut end = 1;
    for part in [&[unit_id][..], PRODUCT_CODE.as_bytes(), b" ", REVISION.as_bytes(), &[run]] {
        out[end..end + part.len()].copy_from_slice(part);
        end += part.len();
    }
    out[0] = (end - 1) as u8;
    Ok(Response::Custom(FunctionCode::new(0x11), &out[..end]))
}

/// FC 43, MEI type 14: read device identification, the basic objects (0 vendor name, 1
/// product code, 2 major.minor revision), by stream (read codes 01, 02, 03: the basic
/// objects are all this server has) or one at a time (04). Conformity level 81: basic
/// identification, stream and individual access.
fn device_identification<'s>(
    pdu: &[u8],
    out: &'s mut [u8; 250],
) -> Result<Response<'s>, Exception> {
    const OBJECTS: [&str; 3] = [VENDOR_NAME, PRODUCT_CODE, REVISION];
    if pdu.get(1) != Some(&0x0E) {
        // Other MEI types (13, CANopen general reference) are not served.
        return Err(Exception::IllegalFunction);
    }
    value(pdu.len() == 4)?;
    let (code, object) = (pdu[2], usize::from(pdu[3]));
    let objects = match code {
        // A stream from `object`; an id past the basic ones starts over at 0 (MODBUS
        // application protocol 6.21).
        1..=3 => (if object < OBJECTS.len() { object } else { 0 })..OBJECTS.len(),
        4 if object < OBJECTS.len() => object..object + 1,
        4 => return Err(Exception::IllegalDataAddress),
        _ => return Err(Exception::IllegalDataValue),
    };
    out[..6].copy_from_slice(&[0x0E, code, 0x81, 0x00, 0x00, objects.len() as u8]);
    let mut at = 6;
    for id in objects {
        let text = OBJECTS[id].as_bytes();
        out[at] = id as u8;
        out[at + 1] = text.len() as u8;
        out[at + 2..at + 2 + text.len()].copy_from_slice(text);
        at += 2 + text.len();
    }
    Ok(Response::Custom(FunctionCode::new(0x2B), &out[..at]))
}

//! Device requests: `get` reads devices from a snapshot captured after the request arrived, so
//! that `set` then `get` shows the new value; `set` writes devices at the next scan boundary,
//! all of one request at the same END. Also how a device is found in its word of the
//! snapshot, which the debugger's device values use too.

use super::waiting::Then;
use super::{failure, RequestHandler, MAX_GET};
use crate::device::{Address, Area, Writer, WORD_VALUES};
use crate::drivers::real_time::snapshot::Snapshot;
use crate::drivers::real_time::{Applied, ControlCommand, WRITES_PER_COMMAND};
use crate::services::control::ClientId;
use plcd_ipc::{DeviceValue, ErrorKind as Kind, Failure, Reply, ResponseLine};

impl RequestHandler {
    pub(super) fn get(&mut self, client: ClientId, devices: &[String]) -> Option<ResponseLine> {
        if devices.is_empty() {
            return Some(failure(Kind::Invalid, "name at least one device"));
        }
        if devices.len() > MAX_GET {
            return Some(failure(Kind::Invalid, format!("at most {MAX_GET} devices per get")));
        }
        let mut parsed = Vec::with_capacity(devices.len());
        for text in devices {
            match parse_device(text) {
                Ok(address) => parsed.push(address),
                Err(f) => return Some(ResponseLine::failure(f)),
            }
        }
        self.park_for_snapshot(client, Then::Values { devices: parsed })
    }

    pub(super) fn set(&mut self, client: ClientId, writes: &[DeviceValue]) -> Option<ResponseLine> {
        if writes.is_empty() {
            return Some(failure(Kind::Invalid, "name at least one DEVICE=VALUE"));
        }
        let mut items = Vec::with_capacity(writes.len());
        for DeviceValue { dev, value } in writes {
            let address = match parse_device(dev) {
                Ok(address) => address,
                Err(f) => return Some(ResponseLine::failure(f)),
            };
            if !address.writable_by(Writer::Client) {
                return Some(failure(
                    Kind::Invalid,
                    format!("{address} is a system device; the PLC maintains it"),
                ));
            }
            if !WORD_VALUES.contains(value) {
                return Some(failure(
                    Kind::Invalid,
                    format!("{address}={value}: a value is 16 bits ({WORD_VALUES:?})"),
                ));
            }
            items.push((address, *value));
        }
        let count = items.len();
        let commands = items
            .chunks(WRITES_PER_COMMAND)
            .map(|chunk| {
                let mut fixed =
                    [(Address { area: Area::D, number: 0, bit: None }, 0); WRITES_PER_COMMAND];
                fixed[..chunk.len()].copy_from_slice(chunk);
                ControlCommand::Writes { items: fixed, len: chunk.len() }
            })
            .collect();
        self.park(client, commands, Then::Written { count })
    }
}

/// The answer to an applied `set`.
pub(super) fn written(applied: Applied, count: usize) -> ResponseLine {
    ResponseLine::ok(Reply::Written { scan: applied.scan, count })
}

/// The answer to a `get`, from a capture that holds every device it names.
pub(super) fn values(devices: &[Address], snapshot: &Snapshot) -> ResponseLine {
    let values = devices
        .iter()
        .map(|d| DeviceValue {
            dev: d.to_string(),
            value: value_in(d, snapshot.word(word_of(d)).unwrap_or(0)),
        })
        .collect();
    ResponseLine::ok(Reply::Values { scan: snapshot.scan.count, values })
}

pub(super) fn parse_device(text: &str) -> Result<Address, Failure> {
    Address::parse(text.trim()).map_err(|e| Failure::new(Kind::Invalid, e.to_string()))
}

/// The word a device lives in, and how to read it out of that word.
pub(super) fn word_of(address: &Address) -> u16 {
    match address.as_word() {
        Ok(word) => word.0,
        Err(_) => address.as_bit().map(|b| b.word).unwrap_or(0),
    }
}

pub(super) fn value_in(address: &Address, word: u16) -> i32 {
    match address.as_word() {
        Ok(_) => i32::from(word as i16),
        Err(_) => address.as_bit().map(|b| i32::from(word & b.mask != 0)).unwrap_or(0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_and_words_read_from_their_word() {
        let bit = Address::parse("P0043").unwrap();
        assert_eq!(value_in(&bit, 0b1000), 1);
        assert_eq!(value_in(&bit, 0b0111), 0);
        let word = Address::parse("D00001").unwrap();
        assert_eq!(value_in(&word, 0xFFFF), -1);
        assert_eq!(word_of(&bit), word_of(&Address::parse("P004").unwrap()));
    }
}

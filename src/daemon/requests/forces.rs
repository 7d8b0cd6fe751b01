//! Force requests: `force`, `unforce`, `unforce-all` change the force table at a scan boundary
//! (only P bits can be forced, named as devices or as the BOOL variables located at them);
//! each, and `forces`, answers with the table as a snapshot captured after it shows it.

use super::devices::parse_device;
use super::waiting::Then;
use super::{failure, RequestHandler};
use crate::device::{Address, BitRef};
use crate::drivers::real_time::snapshot::Snapshot;
use crate::drivers::real_time::ControlCommand;
use crate::engine::force;
use crate::project::{Project, Watched};
use crate::services::control::ClientId;
use plcd_ipc::{DeviceValue, ErrorKind as Kind, Failure, Reply, ResponseLine};

impl RequestHandler {
    pub(super) fn force(
        &mut self,
        client: ClientId,
        dev: &str,
        value: i32,
    ) -> Option<ResponseLine> {
        let found = self.io_bit(dev);
        let (shown, bit) = match found {
            Ok(found) => found,
            Err(f) => return Some(ResponseLine::failure(f)),
        };
        if !(0..=1).contains(&value) {
            return Some(failure(
                Kind::Invalid,
                format!("{shown}={value}: a bit is forced to 0 or 1"),
            ));
        }
        self.park(
            client,
            vec![ControlCommand::Force(bit, value == 1)],
            Then::Forces { unforced: None },
        )
    }

    pub(super) fn unforce(&mut self, client: ClientId, dev: &str) -> Option<ResponseLine> {
        let found = self.io_bit(dev);
        let (shown, bit) = match found {
            Ok(found) => found,
            Err(f) => return Some(ResponseLine::failure(f)),
        };
        self.park(
            client,
            vec![ControlCommand::Unforce(bit)],
            Then::Forces { unforced: Some(shown) },
        )
    }

    pub(super) fn unforce_all(&mut self, client: ClientId) -> Option<ResponseLine> {
        self.park(client, vec![ControlCommand::UnforceAll], Then::Forces { unforced: None })
    }

    pub(super) fn forces(&mut self, client: ClientId) -> Option<ResponseLine> {
        self.park_for_snapshot(client, Then::Forces { unforced: None })
    }

    /// The P bit `dev` names; a variable only once a `load` under way is answered.
    fn io_bit(&self, dev: &str) -> Result<(String, BitRef), Failure> {
        if Address::parse(dev.trim()).is_err() && self.loading() {
            return Err(super::devices::loading());
        }
        parse_io_bit(&self.running().project, dev)
    }
}

/// What can be forced: a P bit, or a BOOL variable located at one; how answers name it
/// (`P0040`, `main.lamp (P0040)`) and the bit.
fn parse_io_bit(project: &Project, text: &str) -> Result<(String, BitRef), Failure> {
    let invalid = |message: String| Failure::new(Kind::Invalid, message);
    let written = project.written_name(text.trim()).map_err(invalid)?;
    let text = &*written;
    if Address::parse(text.trim()).is_ok() {
        let address = parse_device(text)?;
        let bit = force::io_bit(&address).map_err(|e| invalid(e.to_string()))?;
        return Ok((address.to_string(), bit));
    }
    let found = project.resolve(text).map_err(invalid)?;
    match found.as_slice() {
        [Watched::Variable(symbol)] => match force::variable_io_bit(symbol) {
            Some((address, bit)) => Ok((format!("{} ({address})", symbol.name), bit)),
            None => Err(not_an_io_bit(&symbol.name)),
        },
        _ => Err(not_an_io_bit(text.trim())),
    }
}

fn not_an_io_bit(name: &str) -> Failure {
    Failure::new(
        Kind::Invalid,
        format!("{name} is not an I/O bit: only P bits, or BOOL variables located at one, can be forced"),
    )
}

/// The answer to an `unforce` of a bit that was not forced.
pub(super) fn not_forced(shown: &str) -> ResponseLine {
    failure(Kind::Invalid, format!("{shown} is not forced"))
}

/// The answer of every force request: the force table of `snapshot`.
pub(super) fn table(snapshot: &Snapshot) -> ResponseLine {
    ResponseLine::ok(Reply::Forces { forces: forces_of(snapshot) })
}

/// The forced bits and their values, as `status` and the force requests list them.
pub(super) fn forces_of(snapshot: &Snapshot) -> Vec<DeviceValue> {
    snapshot
        .forces
        .iter()
        .map(|(a, on)| DeviceValue { dev: a.to_string(), value: i32::from(on) })
        .collect()
}

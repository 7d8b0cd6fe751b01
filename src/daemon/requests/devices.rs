//! Device and variable requests: `get` reads devices and Structured Text variables from a
//! snapshot captured after the request arrived, so that `set` then `get` shows the new value;
//! `set` writes devices and variables at the next scan boundary, all of one request at the
//! same END. Names are resolved against the running project (a new one from the moment a
//! `load` is sent). Also how a device is found in its word of the snapshot, which the
//! debugger's device values use too.

use super::waiting::Then;
use super::{failure, RequestHandler, MAX_GET};
use crate::device::{Address, Writer, WORD_VALUES};
use crate::drivers::real_time::snapshot::{Snapshot, VarRead, MAX_READ_TEXT};
use crate::drivers::real_time::{
    Applied, ControlCommand, TextWrite, Write, MAX_TEXT_WRITE, WRITES_PER_COMMAND,
};
use crate::drivers::virtual_time::trace::push_json_value;
use crate::project::{Project, Step, Through, Watched};
use crate::services::control::ClientId;
use crate::symbols::Symbols;
use crate::value::{self, Elem, Symbol, ValueType};
use plcd_ipc::{ErrorKind as Kind, Failure, NamedValue, Reply, ResponseLine, Value};

/// What a `get` reads: a device, or one variable of an elementary type or a `STRING`, or
/// what a reference points to (`main.r^`): its reference is read by a first capture, the
/// variable there by the next ([`through_resolved`]).
pub(super) enum Item {
    Device(Address),
    Variable(Symbol),
    Through(Through),
}

impl Item {
    /// What the snapshot reads for a variable.
    pub(super) fn var_read(&self) -> Option<VarRead> {
        match self {
            Item::Device(_) => None,
            Item::Variable(symbol) => Some(var_read(symbol)),
            Item::Through(through) => Some(reference_read(through)),
        }
    }
}

/// The read of the reference a name through it goes through.
pub(super) fn reference_read(through: &Through) -> VarRead {
    VarRead::Value { at: through.reference.at, elem: Elem::U64 }
}

/// The reference `through` goes through followed as of `snapshot`, which read it: the
/// variable it names, named as the client named it, at the place the chain ends; or, for a
/// chain (`main.p^.next^.value`), the rest from the next reference, for the next capture to
/// read; an error naming it where the reference is `NULL` or points where no variable is.
fn through_step(
    through: &Through,
    snapshot: &Snapshot,
    project: &Project,
) -> Result<Item, Failure> {
    let VarRead::Value { at, elem } = reference_read(through) else { unreachable!() };
    let slot = snapshot.value(at, elem).unwrap_or(0);
    let step = through
        .step(slot, project.variables.initial.len())
        .map_err(|why| Failure::new(Kind::Invalid, through.nowhere(why, slot)))?;
    Ok(match step {
        Step::Target(place) => Item::Variable(Symbol {
            name: through.name.clone(),
            at: place,
            retain: false,
            ..through.target.clone()
        }),
        Step::Next(rest) => Item::Through(*rest),
    })
}

/// `items` with each name through a reference followed one reference further as of
/// `snapshot` (which read the references): the variable it points to, or the rest of its
/// chain, for a next capture to read; the first name whose reference points nowhere, as an
/// error.
pub(super) fn through_resolved(
    items: Vec<Item>,
    snapshot: &Snapshot,
    project: &Project,
) -> Result<Vec<Item>, Failure> {
    items
        .into_iter()
        .map(|item| match item {
            Item::Through(through) => through_step(&through, snapshot, project),
            item => Ok(item),
        })
        .collect()
}

fn var_read(symbol: &Symbol) -> VarRead {
    match symbol.ty {
        ValueType::String { cap } => {
            VarRead::Text { at: symbol.at, cap: cap.min(MAX_TEXT_WRITE as u32) as u8 }
        }
        ValueType::WString { cap } => VarRead::WideText { at: symbol.at, cap: cap.min(255) as u8 },
        ref ty => VarRead::Value { at: symbol.at, elem: ty.elem() },
    }
}

/// One write of a `set`, checked and typed.
enum Pending {
    Write(Write),
    Text(Box<TextWrite>),
}

impl RequestHandler {
    pub(super) fn get(&mut self, client: ClientId, names: &[String]) -> Option<ResponseLine> {
        if names.is_empty() {
            return Some(failure(Kind::Invalid, "name at least one device or variable"));
        }
        let items = match resolve_reads(&self.running().project, names) {
            Ok(items) => items,
            Err(f) => return Some(ResponseLine::failure(f)),
        };
        if items.iter().any(|i| !matches!(i, Item::Device(_))) && self.loading() {
            return Some(ResponseLine::failure(loading()));
        }
        self.park_for_snapshot(client, Then::Values { items })
    }

    pub(super) fn set(&mut self, client: ClientId, writes: &[NamedValue]) -> Option<ResponseLine> {
        if writes.is_empty() {
            return Some(failure(Kind::Invalid, "name at least one DEVICE=VALUE"));
        }
        let mut pending = Vec::with_capacity(writes.len());
        {
            let running = self.running();
            if writes.iter().any(|w| w.dev.contains('^')) {
                // What a reference points to is known once a capture has read it.
                let mut references = Vec::new();
                for write in writes {
                    if write.dev.contains('^') {
                        match one_through(&running.project, write.dev.trim()) {
                            Ok(through) => references.push(through),
                            Err(f) => return Some(ResponseLine::failure(f)),
                        }
                    }
                }
                drop(running);
                if self.loading() {
                    return Some(ResponseLine::failure(loading()));
                }
                let then = Then::SetThrough { writes: writes.to_vec(), references };
                return self.park_for_snapshot(client, then);
            }
            for write in writes {
                match checked_write(&running.project, write) {
                    Ok(p) => pending.push(p),
                    Err(f) => return Some(ResponseLine::failure(f)),
                }
            }
        }
        let variables = pending.iter().any(|p| !matches!(p, Pending::Write(Write::Device(..))));
        if variables && self.loading() {
            return Some(ResponseLine::failure(loading()));
        }
        let count = pending.len();
        self.park(client, commands(pending), Then::Written { count })
    }

    /// Whether a `load` is on its way to the scan thread: the running project is already the
    /// new one, the engine not yet, so a variable's place is not known for sure.
    pub(super) fn loading(&self) -> bool {
        self.waiting.iter().any(|w| matches!(w.then, Then::Loaded { .. }))
    }
}

/// What a `set` through references comes to once a capture read them.
pub(super) enum SetThrough {
    /// The commands to queue: every reference led to its variable.
    Commands(Vec<ControlCommand>),
    /// A chain goes on (`main.p^.next^.value`): the references for the next capture, in
    /// the order of the writes that name one.
    Again(Vec<Through>),
}

/// The writes of a `set` that names variables through `references` (`main.r^`, one for each
/// such write, in order), once a capture read the references: each such name written where
/// its reference points as of `snapshot`, or the chains followed one reference further for
/// the next capture; the first write refused.
pub(super) fn set_through(
    project: &Project,
    writes: &[NamedValue],
    references: &[Through],
    snapshot: &Snapshot,
) -> Result<SetThrough, Failure> {
    let stepped = references
        .iter()
        .map(|through| through_step(through, snapshot, project))
        .collect::<Result<Vec<Item>, Failure>>()?;
    if stepped.iter().any(|item| matches!(item, Item::Through(_))) {
        // a name through one reference reads it again at the next capture, with the rest
        let again = stepped
            .into_iter()
            .zip(references)
            .map(|(item, through)| match item {
                Item::Through(rest) => rest,
                _ => through.clone(),
            })
            .collect();
        return Ok(SetThrough::Again(again));
    }
    let mut targets = stepped.into_iter();
    let mut pending = Vec::with_capacity(writes.len());
    for write in writes {
        if write.dev.contains('^') {
            let Some(Item::Variable(symbol)) = targets.next() else {
                unreachable!("one reference for each write through one, each led to its variable")
            };
            pending.push(typed_write(&symbol, write)?);
        } else {
            pending.push(checked_write(project, write)?);
        }
    }
    Ok(SetThrough::Commands(commands(pending)))
}

/// The one variable a `set` names through a reference.
pub(super) fn one_through(project: &Project, name: &str) -> Result<Through, Failure> {
    let invalid = |message: String| Failure::new(Kind::Invalid, message);
    let mut leaves = project.through(name).map_err(invalid)?;
    if leaves.len() != 1 {
        return Err(invalid(format!(
            "`{name}` holds {} variables: write them one by one (`{}`, …)",
            leaves.len(),
            leaves[0].name
        )));
    }
    Ok(leaves.remove(0))
}

/// The answer to a request that names variables while a `load` is under way.
pub(super) fn loading() -> Failure {
    Failure::new(Kind::Busy, "a load is under way; name variables again once it is answered")
}

/// Every device and variable `names` stand for, in order, a prefix expanded in place; at most
/// [`MAX_GET`] of them, their `STRING`s within [`MAX_READ_TEXT`] characters, so that one
/// capture holds all of them.
pub(super) fn resolve_reads(project: &Project, names: &[String]) -> Result<Vec<Item>, Failure> {
    let invalid = |message: String| Failure::new(Kind::Invalid, message);
    let mut items = Vec::with_capacity(names.len());
    let mut text = 0;
    for name in names {
        for watched in project.resolve(name).map_err(invalid)? {
            let item = match watched {
                Watched::Device(address) => Item::Device(address),
                Watched::Variable(symbol) => Item::Variable(symbol),
                Watched::Through(through) => Item::Through(through),
            };
            text += item.var_read().map_or(0, |r| r.text_bytes());
            items.push(item);
        }
        if items.len() > MAX_GET {
            return Err(invalid(format!(
                "at most {MAX_GET} devices and variables per get: `{}` brings them to {}; name \
                 fewer, or parts of a structure",
                name.trim(),
                items.len()
            )));
        }
        if text > MAX_READ_TEXT {
            return Err(invalid(format!(
                "the STRING variables of one get may hold at most {MAX_READ_TEXT} characters: \
                 `{}` brings them to {text}",
                name.trim()
            )));
        }
    }
    Ok(items)
}

/// One `{"dev","value"}` of a `set`, checked against the running project: a device takes a
/// 16-bit integer and must be writable by a client; a variable takes a value of its type and
/// must not be `CONSTANT`.
fn checked_write(project: &Project, write: &NamedValue) -> Result<Pending, Failure> {
    let invalid = |message: String| Failure::new(Kind::Invalid, message);
    let written = project.written_name(write.dev.trim()).map_err(invalid)?;
    let name = &*written;
    if let Ok(address) = Address::parse(name) {
        if !address.writable_by(Writer::Client) {
            return Err(invalid(format!("{address} is a system device; the PLC maintains it")));
        }
        let value = write.value.as_i64().and_then(|v| i32::try_from(v).ok());
        return match value {
            Some(value) if WORD_VALUES.contains(&value) => {
                Ok(Pending::Write(Write::Device(address, value)))
            }
            _ => Err(invalid(format!(
                "{address}={}: a device value is an integer of 16 bits ({WORD_VALUES:?})",
                write.value
            ))),
        };
    }
    let symbol = match project.variable(name) {
        Some(symbol) => symbol,
        None => {
            return Err(invalid(match project.resolve(name) {
                Ok(leaves) => format!(
                    "`{name}` holds {} variables: write them one by one (`{}`, …)",
                    leaves.len(),
                    leaves.first().map(Watched::name).unwrap_or_default()
                ),
                Err(e) => e,
            }))
        }
    };
    typed_write(&symbol, write)
}

/// `write`'s value read against `symbol`'s type, as one write of a `set`.
fn typed_write(symbol: &Symbol, write: &NamedValue) -> Result<Pending, Failure> {
    let invalid = |message: String| Failure::new(Kind::Invalid, message);
    let ty = value::type_name(&symbol.ty);
    if symbol.constant {
        return Err(invalid(format!("{} is CONSTANT ({ty}): it cannot be written", symbol.name)));
    }
    let text = write.value.text();
    let bad = |e: String| invalid(format!("{} ({ty}): {e}", symbol.name));
    match symbol.ty {
        ValueType::String { cap } => {
            let chars = value::parse_string(&text, cap).map_err(bad)?;
            let mut write = TextWrite {
                at: symbol.at,
                cap: cap.min(MAX_TEXT_WRITE as u32) as u8,
                len: chars.len() as u8,
                chars: [0; MAX_TEXT_WRITE],
                wide: false,
            };
            write.chars[..chars.len()].copy_from_slice(&chars);
            Ok(Pending::Text(Box::new(write)))
        }
        ValueType::WString { cap } => {
            // 2 bytes a code unit in the command's buffer: at most half as many as a STRING's
            let cap = cap.min(MAX_TEXT_WRITE as u32 / 2);
            let units = value::parse_wstring(&text, cap).map_err(bad)?;
            let mut write = TextWrite {
                at: symbol.at,
                cap: cap as u8,
                len: units.len() as u8,
                chars: [0; MAX_TEXT_WRITE],
                wide: true,
            };
            for (at, unit) in write.chars.chunks_exact_mut(2).zip(&units) {
                at.copy_from_slice(&unit.to_le_bytes());
            }
            Ok(Pending::Text(Box::new(write)))
        }
        ref other => {
            let slot = value::parse(other, &text).map_err(bad)?;
            Ok(Pending::Write(Write::Value { at: symbol.at, elem: other.elem(), slot }))
        }
    }
}

/// The commands of one `set`, writes in request order: runs of elementary writes in
/// [`ControlCommand::Writes`] of at most [`WRITES_PER_COMMAND`], each `STRING` in a
/// [`ControlCommand::WriteText`]. They are queued together and applied at the same END.
fn commands(pending: Vec<Pending>) -> Vec<ControlCommand> {
    let mut commands = Vec::new();
    let mut items = [Write::default(); WRITES_PER_COMMAND];
    let mut len = 0;
    for p in pending {
        match p {
            Pending::Write(write) => {
                items[len] = write;
                len += 1;
                if len == WRITES_PER_COMMAND {
                    commands.push(ControlCommand::Writes { items, len });
                    len = 0;
                }
            }
            Pending::Text(text) => {
                if len > 0 {
                    commands.push(ControlCommand::Writes { items, len });
                    len = 0;
                }
                commands.push(ControlCommand::WriteText(*text));
            }
        }
    }
    if len > 0 {
        commands.push(ControlCommand::Writes { items, len });
    }
    commands
}

/// The answer to an applied `set`.
pub(super) fn written(applied: Applied, count: usize) -> ResponseLine {
    ResponseLine::ok(Reply::Written { scan: applied.scan, count })
}

/// Whether a capture holds everything `items` read.
pub(super) fn captured(items: &[Item], snapshot: &Snapshot) -> bool {
    items.iter().all(|item| match item {
        Item::Device(d) => snapshot.word(word_of(d)).is_some(),
        Item::Variable(symbol) => snapshot.has(&var_read(symbol)),
        Item::Through(through) => snapshot.has(&reference_read(through)),
    })
}

/// The answer to a `get`, from a capture that holds everything it reads; `symbols` name what
/// a reference points to.
pub(super) fn values(items: &[Item], snapshot: &Snapshot, symbols: &Symbols) -> ResponseLine {
    let values = items
        .iter()
        .map(|item| match item {
            Item::Device(d) => NamedValue::device(
                d.to_string(),
                value_in(d, snapshot.word(word_of(d)).unwrap_or(0)),
            ),
            Item::Variable(symbol) => variable_value(symbol, snapshot, symbols),
            // resolved before the capture that answers (`through_resolved`)
            Item::Through(through) => NamedValue::device(through.name.clone(), 0),
        })
        .collect();
    ResponseLine::ok(Reply::Values { scan: snapshot.scan.count, values })
}

/// A variable's value as the trace writes it (a number, 0/1, `"T#1s500ms"`, an enumeration
/// value's name, a `STRING`'s characters), with its type.
fn variable_value(symbol: &Symbol, snapshot: &Snapshot, symbols: &Symbols) -> NamedValue {
    let value = match var_read(symbol) {
        VarRead::Text { at, cap } => {
            let chars = snapshot.text(at, cap).unwrap_or_default();
            Value::Text(value::decode_str(chars))
        }
        VarRead::WideText { at, cap } => {
            let bytes = snapshot.wide_text(at, cap).unwrap_or_default();
            let units = bytes.chunks_exact(2).map(|u| u16::from_le_bytes([u[0], u[1]]));
            Value::Text(char::decode_utf16(units).map(|c| c.unwrap_or('\u{FFFD}')).collect())
        }
        VarRead::Value { at, elem } => {
            json_value(&symbol.ty, snapshot.value(at, elem).unwrap_or(0), symbols)
        }
    };
    NamedValue { dev: symbol.name.clone(), value, ty: Some(value::type_name(&symbol.ty)) }
}

/// A slot of `ty` as the protocol's value: the trace's JSON, read back.
pub(super) fn json_value(ty: &ValueType, slot: u64, symbols: &Symbols) -> Value {
    let mut json = String::new();
    push_json_value(&mut json, ty, slot, symbols);
    serde_json::from_str(&json).unwrap_or(Value::Text(json))
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
    use crate::value::Elem;

    fn json_value_of(ty: &ValueType, slot: u64) -> Value {
        json_value(ty, slot, &Symbols::default())
    }

    #[test]
    fn bits_and_words_read_from_their_word() {
        let bit = Address::parse("P0043").unwrap();
        assert_eq!(value_in(&bit, 0b1000), 1);
        assert_eq!(value_in(&bit, 0b0111), 0);
        let word = Address::parse("D00001").unwrap();
        assert_eq!(value_in(&word, 0xFFFF), -1);
        assert_eq!(word_of(&bit), word_of(&Address::parse("P004").unwrap()));
    }

    #[test]
    fn variable_values_are_the_traces() {
        let real = |x: f64| Value::Number(serde_json::Number::from_f64(x).unwrap());
        assert_eq!(json_value_of(&ValueType::Bool, 1), Value::from(1));
        assert_eq!(json_value_of(&ValueType::Signed(Elem::I16), 0xFFFF), Value::from(-1));
        assert_eq!(json_value_of(&ValueType::Unsigned(Elem::U64), u64::MAX), Value::from(u64::MAX));
        assert_eq!(json_value_of(&ValueType::Signed(Elem::I64), 1 << 63), Value::from(i64::MIN));
        assert_eq!(json_value_of(&ValueType::Real(Elem::F32), 0.1f32.to_bits().into()), real(0.1));
        assert_eq!(json_value_of(&ValueType::Real(Elem::F64), 1.0f64.to_bits()), real(1.0));
        assert_eq!(
            json_value_of(&ValueType::Real(Elem::F32), f32::NEG_INFINITY.to_bits().into()),
            Value::from("-inf")
        );
        assert_eq!(
            json_value_of(&ValueType::Real(Elem::F64), f64::NAN.to_bits()),
            Value::from("NaN")
        );
        assert_eq!(json_value_of(&ValueType::Time, 1_500_000_000), Value::from("T#1s500ms"));
        // A DATE counts seconds: 2024-03-01 is day 19783.
        let date = ValueType::Calendar(value::Calendar::Date);
        assert_eq!(json_value_of(&date, 19_783 * 86_400), Value::from("D#2024-03-01"));
        let mode = ValueType::Enum {
            type_name: "Mode".into(),
            values: vec![("Idle".into(), 0), ("Running".into(), 5)],
            base: crate::value::Elem::I32,
        };
        assert_eq!(json_value_of(&mode, 5), Value::from("Running"));
        // A number no value is named for: a JSON number (docs/ST.md), as in the trace.
        assert_eq!(json_value_of(&mode, 7), Value::from(7));
    }

    /// The handler without a scan thread: the test takes its commands and answers them.
    struct Bench {
        handler: RequestHandler,
        commands: rtrb::Consumer<crate::drivers::real_time::Command>,
        completions: rtrb::Producer<crate::drivers::real_time::Completion>,
        dir: std::path::PathBuf,
    }

    impl Drop for Bench {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }

    const MAIN: &str = "PROGRAM Main\nVAR\n    speed : INT;\n    s : STRING[4];\n\
        pos AT %D00200 : DINT;\n    flag : BOOL;\n    day : DATE;\nEND_VAR\nVAR CONSTANT\n    k : INT := 3;\n\
        END_VAR\n    speed := speed + 1;\nEND_PROGRAM\n";

    fn bench(name: &str) -> Bench {
        use crate::drivers::real_time::{Command, Completion, Shared};
        use std::sync::{Arc, Mutex};
        let dir = std::env::temp_dir().join(format!("plcd-requests-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let config = "[[program]]\nname = \"main\"\nfile = \"main.st\"\n";
        std::fs::write(dir.join("plcd.toml"), config).unwrap();
        std::fs::write(dir.join("main.st"), MAIN).unwrap();
        let project = crate::files::project(&dir.join("plcd.toml")).unwrap();
        let (producer, commands) = rtrb::RingBuffer::<Command>::new(64);
        let (completions, consumer) = rtrb::RingBuffer::<Completion>::new(64);
        let links = super::super::RequestLinks {
            shared: Arc::new(Shared::new().unwrap()),
            commands: Arc::new(Mutex::new(producer)),
            completions: consumer,
            snapshot: Arc::new(Mutex::new(Snapshot::new())),
            running: Arc::new(Mutex::new(super::super::Running::new(
                &dir.join("plcd.toml"),
                project,
            ))),
            remote: Default::default(),
            announce: None,
            mqtt: None,
        };
        Bench { handler: RequestHandler::new(links), commands, completions, dir }
    }

    fn failure_of(answer: Option<ResponseLine>) -> Failure {
        match answer.map(|a| a.outcome) {
            Some(plcd_ipc::Outcome::Error(f)) => f,
            other => panic!("not a failure: {other:?}"),
        }
    }

    fn set(dev: &str, value: &str) -> plcd_ipc::Request {
        plcd_ipc::Request::Set { writes: vec![NamedValue::write(dev, Value::from(value))] }
    }

    #[test]
    fn a_set_is_typed_and_checked_before_anything_is_queued() {
        use crate::drivers::real_time::Command;
        let mut b = bench("set");
        let f = failure_of(b.handler.handle(1, set("main.k", "1")));
        assert_eq!(
            (f.kind, f.message.as_str()),
            (Kind::Invalid, "main.k is CONSTANT (INT): it cannot be written")
        );
        let f = failure_of(b.handler.handle(1, set("main.speed", "1.5")));
        assert_eq!(f.message, "main.speed (INT): `1.5` is not an integer");
        let f = failure_of(b.handler.handle(1, set("D00010", "x")));
        assert!(
            f.message.starts_with("D00010=x: a device value is an integer of 16 bits"),
            "{}",
            f.message
        );
        assert!(b.commands.pop().is_err(), "nothing queued");

        // A located DINT is one typed write at its device word; a STRING a command of its own,
        // in request order, all pushed together.
        let writes = vec![
            NamedValue::write("MAIN.POS", Value::from(0x1234_5678)),
            NamedValue::write("main.s", Value::from("'a$'b'")),
            NamedValue::device("D00010", 7),
        ];
        assert!(b.handler.handle(1, plcd_ipc::Request::Set { writes }).is_none(), "parked");
        let d200 = Address::parse("D00200").unwrap().as_word().unwrap().0;
        let Ok(Command::Control(_, ControlCommand::Writes { items, len: 1 })) = b.commands.pop()
        else {
            panic!("the DINT first")
        };
        assert_eq!(
            items[0],
            Write::Value {
                at: value::Pointer { space: value::Space::Word, offset: u32::from(d200) },
                elem: value::Elem::I32,
                slot: 0x1234_5678
            }
        );
        let Ok(Command::Control(_, ControlCommand::WriteText(text))) = b.commands.pop() else {
            panic!("then the STRING")
        };
        assert_eq!((&text.chars[..usize::from(text.len)], text.cap), (&b"a'b"[..], 4));
        let Ok(Command::Control(_, ControlCommand::Writes { items, len: 1 })) = b.commands.pop()
        else {
            panic!("then the device")
        };
        assert_eq!(items[0], Write::Device(Address::parse("D00010").unwrap(), 7));
        let _ = &b.completions;
    }

    #[test]
    fn a_date_is_set_as_its_literal() {
        use crate::drivers::real_time::Command;
        let mut b = bench("date");
        let f = failure_of(b.handler.handle(1, set("main.day", "D#2024-13-01")));
        assert_eq!(
            f.message,
            "main.day (DATE): `D#2024-13-01` is not a DATE (month 13 is not 1 to 12; e.g. \
             D#2024-03-01)"
        );
        assert!(b.handler.handle(1, set("main.day", "D#2024-03-01")).is_none(), "parked");
        let Ok(Command::Control(_, ControlCommand::Writes { items, len: 1 })) = b.commands.pop()
        else {
            panic!("one typed write")
        };
        // 2024-03-01 is day 19783 after 1970-01-01, counted in seconds.
        let Write::Value { elem, slot, .. } = items[0] else { panic!("a value") };
        assert_eq!((elem, slot), (value::Elem::U32, 19_783 * 86_400));
    }

    #[test]
    fn names_wait_for_a_load_under_way() {
        use crate::drivers::real_time::{Command, Completion};
        use crate::engine::event::Mode;
        let mut b = bench("loading");
        let renamed = MAIN.replace("speed", "velocity");
        std::fs::write(b.dir.join("main2.st"), renamed).unwrap();
        let config = "[[program]]\nname = \"main\"\nfile = \"main2.st\"\n";
        std::fs::write(b.dir.join("new.toml"), config).unwrap();
        let new = b.dir.join("new.toml").to_str().unwrap().to_string();
        let load = plcd_ipc::Request::Load { config: new, online: false };
        assert!(b.handler.handle(1, load).is_none(), "the load waits for the scan thread");
        let get = |names: &[&str]| plcd_ipc::Request::Get {
            devices: names.iter().map(|n| n.to_string()).collect(),
        };
        // Devices go on; variables wait for the new engine.
        assert!(b.handler.handle(2, get(&["D00010"])).is_none());
        for request in [get(&["main.velocity"]), set("main.velocity", "1")] {
            let f = failure_of(b.handler.handle(3, request));
            assert_eq!(f.kind, Kind::Busy, "{}", f.message);
        }
        let f = failure_of(
            b.handler.handle(3, plcd_ipc::Request::Force { dev: "main.flag".into(), value: 1 }),
        );
        assert_eq!(f.kind, Kind::Busy);
        // The scan thread takes the load: names resolve against the new project.
        let Ok(Command::Control(ticket, ControlCommand::Load(_))) = b.commands.pop() else {
            panic!("the load")
        };
        let applied = Applied { mode: Mode::Stop, scan: 0, changed: true };
        assert!(b.completions.push(Completion { ticket, result: Ok(applied) }).is_ok());
        let mut ready = Vec::new();
        b.handler.collect_answers(&mut ready);
        assert_eq!(ready.len(), 1, "the load is answered");
        assert!(b.handler.handle(4, get(&["main.velocity"])).is_none(), "parked for a capture");
        let f = failure_of(b.handler.handle(5, get(&["main.speed"])));
        assert_eq!(f.message, "no device or variable `main.speed`", "nothing close");
        let f = failure_of(
            b.handler.handle(5, plcd_ipc::Request::Force { dev: "main.flag".into(), value: 1 }),
        );
        assert_eq!(
            f.message,
            "main.flag is not an I/O bit: only P bits, or BOOL variables located at one, can be forced"
        );
    }
}

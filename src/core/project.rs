//! A project: the config and every program it names, loaded and checked together, with the
//! rules that span programs (the DUTY limits of the FX5 manual, edge memory, `DI n` numbers).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use crate::config::{Config, Language, ProgramConfig, TaskRef, WritableName};
use crate::device::{layout, Address, AddressError, Area};
use crate::diag::{Diagnostic, Diagnostics, Warning};
use crate::lang::ops::{Op, SystemRequest, Written};
use crate::lang::{self, Context, DutySite, Program, Variables};
use crate::st;
pub(crate) use crate::symbols::names_match;
use crate::symbols::Symbols;
use crate::value::{Pointer, Space, Symbol, ValueType};

mod access;
mod namespaces;

/// FX5: "The DUTY instruction can be used up to 5 times (points)".
pub const MAX_DUTY: usize = 5;

/// The program variables the config names for the OPC UA server, by their full names with the
/// spelling of their declarations ([`Project::opcua_names`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct OpcuaNames {
    /// `[opcua] writable`: sessions of the operator role and up may write them.
    pub writable: BTreeSet<String>,
    /// `[[opcua.analog]]`: served as analog items with this engineering range.
    pub analog: BTreeMap<String, crate::config::EuRange>,
}

/// The program variables the config names for the MQTT edge node, by their full names with the
/// spelling of their declarations ([`Project::mqtt_names`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MqttNames {
    /// `[mqtt] writable`: a command (NCMD, DCMD) may write them.
    pub writable: BTreeSet<String>,
    /// `[[mqtt.deadbands]]`: sent only when they moved by at least this much.
    pub deadbands: BTreeMap<String, f64>,
    /// `[[mqtt.devices]]`: each device's name and its variables, in the order the config lists
    /// them, each once per device.
    pub devices: Vec<(String, Vec<String>)>,
}

// The deadbands are finite numbers (the config refuses NaN): equality is total.
impl Eq for MqttNames {}

/// A loaded, fully checked project.
#[derive(Debug, Clone)]
pub struct Project {
    /// The config, with the tasks and programs of a Structured Text `CONFIGURATION` in it.
    pub config: Config,
    /// The programs, in the order of the config's `[[program]]` entries.
    pub programs: Vec<Program>,
    /// The Structured Text programs' variable memory and every variable by name (empty
    /// without Structured Text).
    pub variables: Variables,
    /// What a `CONFIGURATION` was mapped to, the namespaces the `.plcproj` files name, where
    /// the `[iec]` layout puts the located variables and the access paths, a line each (`plcd
    /// check` and the log show them).
    pub notes: Vec<String>,
    /// What the Structured Text compiler accepted with a warning, in file and line order
    /// (`plcd check` prints them, the daemon logs them).
    pub warnings: Vec<Warning>,
}

impl Project {
    /// The frame area each task needs: the most any program asks for.
    pub fn frame_bytes(&self) -> u32 {
        self.programs.iter().map(|p| p.frame_bytes).max().unwrap_or(0)
    }

    /// The outputs, in address order: every P bit a program writes (a word written whole
    /// counts as its 16 bits) and every configured `[[io.output]]`. The default watch list of
    /// traces and logs.
    pub fn output_bits(&self) -> Vec<Address> {
        let mut words = [0u16; layout::P_WORDS as usize];
        let p_end = layout::P_WORDS as u16;
        for program in &self.programs {
            for op in program.code.iter() {
                match op.writes() {
                    Some(Written::Bit(b)) if b.word < p_end => words[b.word as usize] |= b.mask,
                    Some(written) => {
                        let Some((first, count)) = written.words() else { continue };
                        let written = (0..count).map(|i| first.0.saturating_add(i));
                        for word in written.filter(|&w| w < p_end) {
                            words[word as usize] = 0xFFFF;
                        }
                    }
                    None => {}
                }
            }
        }
        for line in &self.config.io.outputs {
            if let Some(bit) = line.device.bit {
                words[line.device.number as usize] |= 1 << bit;
            }
        }
        let mut bits = Vec::new();
        for (word, mask) in words.iter().enumerate() {
            for bit in 0..16u8 {
                if mask & 1 << bit != 0 {
                    bits.push(Address { area: Area::P, number: word as u32, bit: Some(bit) });
                }
            }
        }
        bits
    }
}

/// What a trace or a log watches: a device, or a Structured Text variable.
#[derive(Debug, Clone, PartialEq)]
pub enum Watched {
    Device(Address),
    Variable(Symbol),
    /// What a reference points to, found each time it is read (`main.r^`).
    Through(Through),
}

/// A name through a reference (`main.r^`, `main.p^.pos`, `main.refs[2]^`), or through a chain
/// of them (`main.p^.next^.value`): the leaf `target` of what the last reference points to,
/// found where each reference points each time it is read.
#[derive(Debug, Clone, PartialEq)]
pub struct Through {
    /// The name with the declarations' spelling: `main.p^.pos`.
    pub name: String,
    /// The reference variable (`main.p`).
    pub reference: Symbol,
    /// The references followed after `reference`, each placed from the start of what the one
    /// before points to (`.next` of `main.p^.next^.value`); empty for one `^`.
    pub hops: Vec<Hop>,
    /// The leaf read, placed from the start of what the last reference points to (`.pos`
    /// at 4).
    pub target: Symbol,
}

/// A reference inside what another points to (`.next` of `main.p^.next^.value`).
#[derive(Debug, Clone, PartialEq)]
pub struct Hop {
    /// The name up to it, with the declarations' spelling: `main.p^.next`.
    pub name: String,
    /// The reference, placed from the start of what the reference before points to.
    pub leaf: Symbol,
}

/// One reference of a [`Through`] followed: the target's place, or the chain's rest from the
/// next reference, now at a known place.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    Target(Pointer),
    Next(Box<Through>),
}

/// Why a reference leads to no variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Nowhere {
    Null,
    /// It went nowhere (`ADR` of an element out of bounds).
    Invalid,
    /// Into the frame area of the task that took it (a FUNCTION's variable, `VAR_TEMP`): the
    /// place is gone between scans.
    Frame,
    /// Past the end of variable memory (pointer arithmetic).
    Outside,
    /// To a device, where only a whole elementary value is named through it.
    Device,
}

/// Where `leaf` (placed from the start of a reference's target) is while the reference
/// holds `slot`, in variable memory of `var_bytes` bytes.
fn leaf_place(leaf: &Symbol, slot: u64, var_bytes: usize) -> Result<Pointer, Nowhere> {
    let start = Pointer::from_reference(slot).ok_or(Nowhere::Null)?;
    let offset = leaf.at.offset;
    match start.space {
        Space::Var => {
            let at = start.offset as usize + offset as usize;
            if at + leaf.ty.bytes() as usize > var_bytes {
                return Err(Nowhere::Outside);
            }
            Ok(Pointer { space: Space::Var, offset: start.offset + offset })
        }
        Space::Frame => Err(Nowhere::Frame),
        Space::Discard => Err(Nowhere::Invalid),
        // a reference is never a device's value: a chain goes on in variable memory only
        Space::Word | Space::Bit | Space::Byte
            if offset == 0 && !matches!(leaf.ty, ValueType::Reference { .. }) =>
        {
            Ok(start)
        }
        Space::Word | Space::Bit | Space::Byte => Err(Nowhere::Device),
    }
}

impl Through {
    /// Where the target is while the reference holds `slot`, in variable memory of
    /// `var_bytes` bytes, each further reference of the chain read with `read` (a
    /// reference's 64-bit slot at a place). Allocates nothing (the trace's watches call it at
    /// every scan).
    pub fn follow(
        &self,
        slot: u64,
        var_bytes: usize,
        mut read: impl FnMut(Pointer) -> u64,
    ) -> Result<Pointer, Nowhere> {
        let mut slot = slot;
        for hop in &self.hops {
            slot = read(leaf_place(&hop.leaf, slot, var_bytes)?);
        }
        leaf_place(&self.target, slot, var_bytes)
    }

    /// Where the target is while the reference holds `slot`, for a name through one
    /// reference; for a chain, where its second reference is (see [`Through::step`]).
    pub fn place(&self, slot: u64, var_bytes: usize) -> Result<Pointer, Nowhere> {
        match self.hops.first() {
            None => leaf_place(&self.target, slot, var_bytes),
            Some(hop) => leaf_place(&hop.leaf, slot, var_bytes),
        }
    }

    /// The first reference followed while it holds `slot`: the target's place, or the rest
    /// of the chain from the next reference (which a client then reads in turn).
    pub fn step(&self, slot: u64, var_bytes: usize) -> Result<Step, Nowhere> {
        let at = self.place(slot, var_bytes)?;
        let Some((hop, rest)) = self.hops.split_first() else {
            return Ok(Step::Target(at));
        };
        let reference = Symbol { name: hop.name.clone(), at, retain: false, ..hop.leaf.clone() };
        Ok(Step::Next(Box::new(Through {
            name: self.name.clone(),
            reference,
            hops: rest.to_vec(),
            target: self.target.clone(),
        })))
    }

    /// Why a client's read or write of it found no variable, naming it and the reference.
    pub fn nowhere(&self, why: Nowhere, slot: u64) -> String {
        let reference = &self.reference.name;
        let name = &self.name;
        let shown = crate::value::format_reference(slot);
        match why {
            Nowhere::Null => format!("`{name}`: `{reference}` is NULL"),
            Nowhere::Invalid => format!("`{name}`: `{reference}` points nowhere (invalid)"),
            Nowhere::Frame => format!(
                "`{name}`: `{reference}` points into a task's frame ({shown}: a FUNCTION's \
                 variable or a VAR_TEMP), which is gone between scans"
            ),
            Nowhere::Outside => {
                format!("`{name}`: `{reference}` points outside variable memory ({shown})")
            }
            Nowhere::Device => format!(
                "`{name}`: `{reference}` points to a device ({}): only its whole value is \
                 named through it (`{reference}^`)",
                crate::device::format_reference(slot)
            ),
        }
    }
}

impl Watched {
    /// The name traces and logs show: the device as written canonically (`P0040`), the
    /// variable with its declaration's spelling (`main.pid.out`).
    pub fn name(&self) -> String {
        match self {
            Watched::Device(address) => address.to_string(),
            Watched::Variable(symbol) => symbol.name.clone(),
            Watched::Through(through) => through.name.clone(),
        }
    }
}

impl From<Address> for Watched {
    fn from(address: Address) -> Watched {
        Watched::Device(address)
    }
}

impl From<&Watched> for Watched {
    fn from(watched: &Watched) -> Watched {
        watched.clone()
    }
}

impl From<&Address> for Watched {
    fn from(address: &Address) -> Watched {
        Watched::Device(*address)
    }
}

impl Project {
    /// The Structured Text variable `name` (case-insensitive), one leaf.
    pub fn variable(&self, name: &str) -> Option<Symbol> {
        self.variables.symbols.find(name)
    }

    /// What `name` watches: a device address, a variable, or every variable under a
    /// struct, array, FB instance or program instance (`main.pid` → `main.pid.out`, …).
    pub fn watched(&self, name: &str) -> Result<Vec<Watched>, String> {
        let name = name.trim();
        if let Ok(address) = Address::parse(name) {
            return Ok(vec![Watched::Device(address)]);
        }
        if name.contains('^') {
            return Ok(self.through(name)?.into_iter().map(Watched::Through).collect());
        }
        if let Some(symbol) = self.variable(name) {
            return Ok(vec![Watched::Variable(symbol)]);
        }
        if let Some(found) = self.access_watched(name) {
            return found;
        }
        let under: Vec<Watched> = self
            .variables
            .symbols
            .may_start_with(name)
            .filter(|s| is_under(&s.name, name))
            .map(Watched::Variable)
            .collect();
        if under.is_empty() {
            Err(match Address::parse(name) {
                Err(e) if !name.contains('.') => e.to_string(),
                _ => format!("`{name}` is neither a device nor a variable of the project"),
            })
        } else {
            Ok(under)
        }
    }
}

impl Project {
    /// What `name` names through a reference (`main.r^`, `main.p^.pos`, `main.refs[2]^`, a
    /// struct's or an FB's every leaf for `main.p^`), or through a chain of them
    /// (`main.p^.next^.value`): the part before the first `^` is a reference variable, each
    /// part between two `^` names a reference inside what the one before points to, and the
    /// part after the last names a leaf (or every leaf under it) of what the last points to.
    pub fn through(&self, name: &str) -> Result<Vec<Through>, String> {
        let name = name.trim();
        let mut parts = name.split('^');
        let base = parts.next().unwrap_or_default().trim();
        let mut parts: Vec<&str> = parts.collect();
        let Some(rest) = parts.pop() else {
            return Err(format!("`{name}` names no `^`"));
        };
        let Some(reference) = self.variable(base) else {
            return Err(match self.closest_variable(base) {
                Some(close) => format!("no variable `{base}` (did you mean `{close}`?)"),
                None => format!("no variable `{base}`"),
            });
        };
        let mut type_name = self.reference_type(base, &reference.ty)?.to_string();
        let mut spelled = reference.name.clone();
        let mut hops = Vec::new();
        for part in parts {
            let target = self.referent(&spelled, &type_name)?;
            let Some(leaf) = target.find(part) else {
                return Err(format!(
                    "no variable `{name}`: a {type_name} points to no reference `{part}`"
                ));
            };
            spelled = format!("{spelled}^{}", leaf.name);
            type_name = self.reference_type(&spelled, &leaf.ty)?.to_string();
            hops.push(Hop { name: spelled.clone(), leaf });
        }
        let target = self.referent(&spelled, &type_name)?;
        let mut found: Vec<Symbol> = target.find(rest).into_iter().collect();
        if found.is_empty() {
            found = target.may_start_with(rest).filter(|s| is_under(&s.name, rest)).collect();
        }
        if found.is_empty() {
            return Err(format!("no variable `{name}`: a {type_name} points to no `{rest}`"));
        }
        Ok(found
            .into_iter()
            .map(|leaf| Through {
                name: format!("{spelled}^{}", leaf.name),
                reference: reference.clone(),
                hops: hops.clone(),
                target: leaf,
            })
            .collect())
    }

    /// The reference type of `ty`, the type of `named`; an error when it is none.
    fn reference_type<'a>(&self, named: &str, ty: &'a ValueType) -> Result<&'a str, String> {
        match ty {
            ValueType::Reference { type_name } => Ok(type_name),
            _ => Err(format!(
                "`{named}` is not a reference ({}): `^` follows a REF_TO, POINTER TO or \
                 REFERENCE TO variable",
                crate::value::type_name(ty)
            )),
        }
    }

    /// The leaves of what a reference of type `type_name` (the type of `named`) points to.
    fn referent(&self, named: &str, type_name: &str) -> Result<&Symbols, String> {
        match self.variables.referents.iter().find(|(n, _)| n == type_name) {
            Some((_, target)) => Ok(target),
            None => Err(format!("`{named}` is a {type_name}: what it points to has no names")),
        }
    }

    /// What a client of the running PLC names (`plcctl get`, `set`, `force`): as
    /// [`Project::watched`], with an error for a name that is neither a device nor a variable
    /// that says so and suggests the closest variable name (`no device or variable
    /// `main.spede` (did you mean `main.speed`?)`), or, for a device out of range or an
    /// unknown flag, what is wrong with the address.
    pub fn resolve(&self, name: &str) -> Result<Vec<Watched>, String> {
        let name = name.trim();
        if name.contains('^') || self.access_of(name).is_some() {
            // `through`'s and an access path's errors already name what is wrong
            return self.watched(name);
        }
        self.watched(name).map_err(|_| match Address::parse(name) {
            Err(e @ (AddressError::OutOfRange { .. } | AddressError::UnknownFlag(_))) => {
                e.to_string()
            }
            _ => match self.closest_variable(name) {
                Some(close) => format!("no device or variable `{name}` (did you mean `{close}`?)"),
                None => format!("no device or variable `{name}`"),
            },
        })
    }

    /// The variables the config names for the OPC UA server: `[opcua] writable` and
    /// `[[opcua.analog]]`, every error of both at once.
    pub fn opcua_names(&self) -> Result<OpcuaNames, Vec<Diagnostic>> {
        let opcua = &self.config.opcua;
        let writable = self.writable_variables("opcua.writable", &opcua.writable);
        let ranges = opcua.analog.iter().map(|a| (&a.variable, a.range));
        match (writable, self.numeric_variables("opcua.analog", "an engineering range", ranges)) {
            (Ok(writable), Ok(analog)) => Ok(OpcuaNames { writable, analog }),
            (writable, analog) => {
                Err(writable.err().into_iter().chain(analog.err()).flatten().collect())
            }
        }
    }

    /// The variables the config names for the MQTT edge node: `[mqtt] writable`,
    /// `[[mqtt.deadbands]]` and `[[mqtt.devices]]`, every error of the three at once.
    pub fn mqtt_names(&self) -> Result<MqttNames, Vec<Diagnostic>> {
        let mqtt = &self.config.mqtt;
        let writable = self.writable_variables("mqtt.writable", &mqtt.writable);
        let deadbands = mqtt.deadbands.iter().map(|d| (&d.variable, d.value));
        let deadbands = self.numeric_variables("mqtt.deadbands", "a deadband", deadbands);
        let mut devices = Vec::new();
        let mut errors = Vec::new();
        let published = |s: &Symbol| !matches!(s.ty, ValueType::Reference { .. });
        let none = "variable that is not a reference (references are not published)";
        for device in &mqtt.devices {
            let entries = device.variables.iter().map(|v| (v, ()));
            match self.config_variables("mqtt.devices", entries, published, none) {
                Ok(found) => {
                    let mut seen = BTreeSet::new();
                    let names = found.into_iter().flat_map(|(names, ())| names);
                    let names = names.filter(|name| seen.insert(name.clone())).collect();
                    devices.push((device.name.clone(), names));
                }
                Err(e) => errors.extend(e),
            }
        }
        match (writable, deadbands) {
            (Ok(writable), Ok(deadbands)) if errors.is_empty() => {
                Ok(MqttNames { writable, deadbands, devices })
            }
            (writable, deadbands) => Err(writable
                .err()
                .into_iter()
                .chain(deadbands.err())
                .flatten()
                .chain(errors)
                .collect()),
        }
    }

    /// The variables a list of names (`[opcua] writable`, of `key`) makes writable, by their
    /// full names with the spelling of their declarations: each name as `plcctl set` resolves
    /// it, a struct, FB instance or array standing for its variables, less its `CONSTANT`s. A
    /// name that is a device, names through a reference, or names no variable (or
    /// `CONSTANT`s only) is an error at the config's line and column.
    fn writable_variables(
        &self,
        key: &str,
        names: &[WritableName],
    ) -> Result<BTreeSet<String>, Vec<Diagnostic>> {
        let written = |s: &Symbol| !s.constant && !matches!(s.ty, ValueType::Reference { .. });
        let none = "variable a client could write (CONSTANTs and references are never written)";
        let found = self.config_variables(key, names.iter().map(|n| (n, ())), written, none)?;
        Ok(found.into_iter().flat_map(|(names, ())| names).collect())
    }

    /// The numeric variables entries of the config (`[[opcua.analog]]`, of `key`) give a value
    /// (`what`: an engineering range), by their full names: each entry's name as `plcctl get`
    /// resolves it, a struct, FB instance or array standing for its numeric variables. A name
    /// that is a device, names through a reference, or holds no number (a `BOOL`, a `STRING`,
    /// an enumeration, a `TIME`) is an error at the config's line and column.
    fn numeric_variables<'a, T: Copy>(
        &self,
        key: &str,
        what: &str,
        entries: impl IntoIterator<Item = (&'a WritableName, T)>,
    ) -> Result<BTreeMap<String, T>, Vec<Diagnostic>> {
        let number = |s: &Symbol| {
            matches!(s.ty, ValueType::Signed(_) | ValueType::Unsigned(_) | ValueType::Real(_))
        };
        let none = format!("number (an integer or a REAL): {what} is for numbers");
        let found = self.config_variables(key, entries, number, &none)?;
        Ok(found
            .into_iter()
            .flat_map(|(names, value)| names.into_iter().map(move |name| (name, value)))
            .collect())
    }

    /// The full names of the variables each of `entries` (names of the config, of `key`)
    /// stands for, with the entry's value, as `plcctl` resolves them, that `keep` takes: every
    /// entry's error at once, at the name's line and column, for a device, a name through a
    /// reference (which changes as the program runs), one that resolves to nothing, or one
    /// that holds none that `keep` takes (it holds no `none`).
    fn config_variables<'a, T>(
        &self,
        key: &str,
        entries: impl IntoIterator<Item = (&'a WritableName, T)>,
        keep: impl Fn(&Symbol) -> bool,
        none: &str,
    ) -> Result<Vec<(Vec<String>, T)>, Vec<Diagnostic>> {
        let mut found = Vec::new();
        let mut errors = Vec::new();
        for (entry, value) in entries {
            match self.config_variable(key, entry, &keep, none) {
                Ok(names) => found.push((names, value)),
                Err(error) => errors.push(error),
            }
        }
        if errors.is_empty() {
            Ok(found)
        } else {
            Err(errors)
        }
    }

    /// [`Project::config_variables`] of one name.
    fn config_variable(
        &self,
        key: &str,
        entry: &WritableName,
        keep: impl Fn(&Symbol) -> bool,
        none: &str,
    ) -> Result<Vec<String>, Diagnostic> {
        let error = |message: String| {
            Diagnostic::new(&self.config.path, entry.line, entry.col, format!("{key}: {message}"))
        };
        let name = entry.name.as_str();
        if Address::parse(name).is_ok() {
            let serves = match key.split('.').next() {
                Some("mqtt") => "the MQTT edge node publishes",
                _ => "the OPC UA server serves",
            };
            return Err(error(format!("`{name}` is a device: {serves} the programs' variables")));
        }
        if name.contains('^') {
            return Err(error(format!(
                "`{name}` names a variable through a reference, which changes as the program \
                 runs: name the variable itself"
            )));
        }
        let variables: Vec<String> = self
            .resolve(name)
            .map_err(error)?
            .into_iter()
            .filter_map(|leaf| match leaf {
                Watched::Variable(symbol) if keep(&symbol) => Some(symbol.name),
                _ => None,
            })
            .collect();
        if variables.is_empty() {
            return Err(error(format!("`{name}` holds no {none}")));
        }
        Ok(variables)
    }

    /// The variable name nearest to `name` (case-insensitive edit distance, at most about a
    /// quarter of its length), with its declaration's spelling.
    pub fn closest_variable(&self, name: &str) -> Option<String> {
        let given: String =
            name.chars().filter(|c| !c.is_whitespace()).map(|c| c.to_ascii_lowercase()).collect();
        let limit = (given.len() / 4).clamp(1, 3);
        self.variables.symbols.closest(&given, limit).map(|(_, name)| name)
    }
}

/// Whether `name` is a variable inside `prefix` (`main.pid.out` is inside `main.pid` and
/// `main`; `main.buf[3]` inside `main.buf`).
fn is_under(name: &str, prefix: &str) -> bool {
    let prefix: String = prefix.chars().filter(|c| !c.is_whitespace()).collect();
    let compact: String = name.chars().filter(|c| !c.is_whitespace()).collect();
    compact.len() > prefix.len()
        && compact[..prefix.len()].eq_ignore_ascii_case(&prefix)
        && matches!(compact.as_bytes()[prefix.len()], b'.' | b'[')
}

/// Splits a watch list at the commas that are not inside `[…]` (`main.m[1,2],P0040`).
pub fn split_names(list: &str) -> Vec<&str> {
    let mut names = Vec::new();
    let (mut depth, mut start) = (0u32, 0);
    for (i, c) in list.char_indices() {
        match c {
            '[' => depth += 1,
            ']' => depth = depth.saturating_sub(1),
            ',' if depth == 0 => {
                names.push(list[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    names.push(list[start..].trim());
    names.retain(|n| !n.is_empty());
    names
}

/// Assembles the programs of an already parsed config; `read` supplies each program's text.
/// A project with `[st] library` folders needs [`from_config_with`]; this one reads no
/// `.plcproj` beside a TwinCAT program (it lists no folder).
pub fn from_config(
    config: Config,
    read: impl Fn(&Path) -> std::io::Result<String>,
) -> Result<Project, Diagnostics> {
    let no_folders =
        |dir: &Path| Err(std::io::Error::other(format!("{} is not listed here", dir.display())));
    from_config_with(config, read, no_folders, |_: &Path| Ok(Vec::new()))
}

/// [`from_config`], with `list` giving every file of an `[st] library` folder, in it and in its
/// subfolders (the caller walks the file system; the Structured Text sources and the
/// `.plcproj` files among them are read), and `files_in` every file directly in a folder (the
/// empty path: the current one), where the `.plcproj` of a `[[program]]`'s TwinCAT file is
/// looked for (docs/ST.md, "TwinCAT project files").
pub fn from_config_with(
    config: Config,
    read: impl Fn(&Path) -> std::io::Result<String>,
    list: impl Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
    files_in: impl Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
) -> Result<Project, Diagnostics> {
    let mut diags = Diagnostics::default();
    let mut config = config;
    let (mut notes, parsed) = expand_configurations(&mut config, &read, &mut diags);
    let task_numbers: Vec<u8> = config.tasks.iter().map(|t| t.number).collect();
    let timer_base = |n: u32| config.timers.base_ms(n);
    let mut programs: Vec<Option<Program>> = Vec::with_capacity(config.programs.len());
    let mut duty_sites = Vec::new();
    let mut edge_base = 0u32;
    let mut reader = Reader {
        config: &config,
        read: &read,
        list: &list,
        files_in: &files_in,
        diags: &mut diags,
    };
    for entry in &config.programs {
        if entry.language == Language::StructuredText {
            // Compiled below, all together: the files share their declarations.
            programs.push(None);
            continue;
        }
        let what = format!("program \"{}\"", entry.name);
        let Some(source) = reader.read(&entry.resolved, entry.line, entry.col, &what) else {
            continue;
        };
        let ctx = Context {
            is_init: entry.task == TaskRef::Init,
            task_numbers: &task_numbers,
            timer_base_ms: &timer_base,
            edge_base,
        };
        let (program, sites) =
            lang::assemble_with_duty_sites(&entry.name, &entry.resolved, &source, &ctx);
        duty_sites.push((entry.resolved.clone(), sites));
        match program {
            Ok(program) => {
                edge_base += program.edge_slots;
                programs.push(Some(program));
            }
            Err(d) => reader.diags.extend(d),
        }
    }
    let mut warnings = Vec::new();
    let variables = match compile_structured_text(&config, &mut reader, parsed) {
        Some((compiled, st_notes)) => {
            notes.extend(st_notes);
            notes.extend(compiled.variables.access.iter().map(access::note));
            warnings = compiled.warnings;
            check_task_numbers(&compiled.programs, &task_numbers, reader.diags);
            let mut st_programs = compiled.programs.into_iter();
            for slot in programs.iter_mut().filter(|p| p.is_none()) {
                *slot = st_programs.next().map(|mut program| {
                    program.edge_base = edge_base;
                    program
                });
            }
            compiled.variables
        }
        None => {
            if !config.programs.iter().any(|p| p.language == Language::StructuredText) {
                // no Structured Text: nothing names the addresses [iec.addresses] places
                let (_, unused) = st::iec_check::config_notes(&[], &config.iec, &config.path);
                warnings.extend(unused);
            }
            Variables::default()
        }
    };
    check_duty(&duty_sites, &mut diags);
    // Grouped by file, in line order, whatever the order they were found in.
    diags.0.sort();
    if !diags.is_empty() {
        return Err(diags);
    }
    let programs = programs.into_iter().flatten().collect();
    let project = Project { config, programs, variables, notes, warnings };
    let mut errors: Vec<Diagnostic> = [project.opcua_names().err(), project.mqtt_names().err()]
        .into_iter()
        .flatten()
        .flatten()
        .collect();
    if errors.is_empty() {
        Ok(project)
    } else {
        errors.sort();
        Err(Diagnostics(errors))
    }
}

/// A Structured Text file parsed before the compile, with its syntax errors (the compile
/// reports them).
type Parsed = (st::ast::File, Diagnostics);

/// Replaces each Structured Text `[[program]]` whose file holds a `CONFIGURATION` (and that
/// names no `pou`) by the configuration's program instances, and adds its tasks to the config
/// ([`st::configuration`]); what was mapped to what, a line each, and the files parsed to find
/// out, which the compile takes as they are. A file that cannot be read is left to the
/// compile, which reports it; an entry whose configuration has errors is dropped with them.
fn expand_configurations(
    config: &mut Config,
    read: &impl Fn(&Path) -> std::io::Result<String>,
    diags: &mut Diagnostics,
) -> (Vec<String>, Vec<Parsed>) {
    use st::configuration;
    let mut notes = Vec::new();
    let mut parsed: Vec<Parsed> = Vec::new();
    let mut i = 0;
    while i < config.programs.len() {
        let entry = &config.programs[i];
        let candidate = entry.language == Language::StructuredText
            && entry.pou.is_none()
            && !crate::config::is_twincat_source(&entry.resolved);
        let text = candidate.then(|| read(&entry.resolved).ok()).flatten();
        let Some(text) = text.filter(|t| configuration::may_hold_one(t)) else {
            i += 1;
            continue;
        };
        if !parsed.iter().any(|(f, _)| f.path == entry.resolved) {
            parsed.push(st::parse_file_with(&entry.resolved, &text, &config.st.defines));
        }
        let (file, _) = parsed.iter().find(|(f, _)| f.path == entry.resolved).expect("parsed");
        let conf = match configuration::of_file(file, &entry.resolved) {
            Ok(Some(conf)) => conf,
            Ok(None) => {
                i += 1;
                continue;
            }
            Err(d) => {
                diags.push(d);
                config.programs.remove(i);
                continue;
            }
        };
        let others: Vec<&ProgramConfig> =
            config.programs.iter().enumerate().filter(|&(j, _)| j != i).map(|(_, p)| p).collect();
        match configuration::map(
            conf,
            file,
            entry,
            &config.tasks,
            &others,
            config.plc.scan_period_ms,
            &config.iec.layout,
        ) {
            Ok(mapped) => {
                notes.extend(mapped.notes);
                config.tasks.extend(mapped.tasks);
                if let Some(ms) = mapped.scan_period_ms {
                    config.plc.scan_period_ms = ms;
                }
                let n = mapped.programs.len();
                config.programs.splice(i..=i, mapped.programs);
                i += n;
            }
            Err(errors) => {
                diags.extend(Diagnostics(errors));
                config.programs.remove(i);
            }
        }
    }
    (notes, parsed)
}

/// Reads program files, a diagnostic at the config entry that names a file it cannot read.
struct Reader<'a, R, L, F> {
    config: &'a Config,
    read: &'a R,
    list: &'a L,
    files_in: &'a F,
    diags: &'a mut Diagnostics,
}

impl<R, L, F> Reader<'_, R, L, F>
where
    R: Fn(&Path) -> std::io::Result<String>,
    L: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
    F: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
{
    /// The source files of a library folder, sorted, and its `.plcproj` files, sorted; no
    /// sources (after a diagnostic) when it cannot be listed or holds none.
    fn list(
        &mut self,
        dir: &Path,
        line: u32,
        col: u32,
        what: &str,
    ) -> (Vec<PathBuf>, Vec<PathBuf>) {
        match (self.list)(dir) {
            Ok(files) => {
                let (mut projects, mut files): (Vec<PathBuf>, Vec<PathBuf>) =
                    files.into_iter().partition(|f| crate::config::is_plcproj(f));
                files.retain(|f| crate::config::is_st_source(f));
                files.sort();
                projects.sort();
                if files.is_empty() {
                    let msg = format!(
                        "{what}: folder `{}` holds no `.st`, `.TcPOU`, `.TcDUT`, `.TcGVL` or `.TcIO` file",
                        dir.display()
                    );
                    self.diags.push(Diagnostic::new(&self.config.path, line, col, msg));
                }
                (files, projects)
            }
            Err(e) => {
                let msg = format!("{what}: cannot list folder `{}`: {e}", dir.display());
                self.diags.push(Diagnostic::new(&self.config.path, line, col, msg));
                (Vec::new(), Vec::new())
            }
        }
    }

    fn read(&mut self, path: &Path, line: u32, col: u32, what: &str) -> Option<String> {
        match (self.read)(path) {
            Ok(text) => Some(text),
            Err(e) => {
                self.diags.push(Diagnostic::new(
                    &self.config.path,
                    line,
                    col,
                    format!("{what}: cannot read `{}`: {e}", path.display()),
                ));
                None
            }
        }
    }
}

/// Parses every `.st` file of the project (its Structured Text programs and `[st] library`),
/// but those `parsed` already, reads the namespaces of its `.plcproj` files
/// ([`namespaces`]), and compiles one instance per Structured Text `[[program]]`, in config
/// order, with what `plcd check` shows of the namespaces learnt and of the `[iec]` layout the
/// files use. `None` when there is none, or on errors (in `reader.diags`): the syntax errors of
/// every file and the errors of the `.plcproj` files, or, when there are none, every error the
/// compiler finds.
fn compile_structured_text<R, L, F>(
    config: &Config,
    reader: &mut Reader<'_, R, L, F>,
    mut parsed: Vec<Parsed>,
) -> Option<(st::Compiled, Vec<String>)>
where
    R: Fn(&Path) -> std::io::Result<String>,
    L: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
    F: Fn(&Path) -> std::io::Result<Vec<PathBuf>>,
{
    let entries: Vec<_> =
        config.programs.iter().filter(|p| p.language == Language::StructuredText).collect();
    if entries.is_empty() {
        // what [iec.variables] binds is a Structured Text program's
        for v in &config.iec.variables {
            let msg = format!(
                "{}: `{}` is not a PROGRAM instance of the project: it has no Structured Text program",
                v.subject(),
                v.path[0]
            );
            reader.diags.push(Diagnostic::new(&config.path, v.line, v.col, msg));
        }
        return None;
    }
    let base = config.path.parent().unwrap_or(Path::new(""));
    // each file, the config entry that names it, and whether it is a program's
    let mut paths: Vec<(PathBuf, u32, u32, String, bool)> = Vec::new();
    for entry in &entries {
        let what = format!("program \"{}\"", entry.name);
        paths.push((entry.resolved.clone(), entry.line, entry.col, what, true));
    }
    let mut ok = true;
    let mut learnt = namespaces::Learnt::default();
    for library in &config.st.library {
        let (line, col) = (library.line, library.col);
        let what = "st.library".to_string();
        if library.folder {
            let (files, projects) = reader.list(&library.resolved, line, col, &what);
            ok &= !files.is_empty();
            if projects.is_empty() {
                learnt.folder(reader, &library.resolved, base);
            }
            for project in projects {
                ok &= learnt.read(reader, &project, (line, col), &what);
            }
            paths.extend(files.into_iter().map(|f| (f, line, col, what.clone(), false)));
        } else {
            paths.push((library.resolved.clone(), line, col, what, false));
        }
    }
    let mut files = Vec::new();
    for (path, line, col, what, program) in paths {
        if files.iter().any(|f: &st::ast::File| f.path == path) {
            continue;
        }
        if let Some(k) = parsed.iter().position(|(f, _)| f.path == path) {
            let (file, errors) = parsed.swap_remove(k);
            ok &= errors.is_empty();
            reader.diags.extend(errors);
            files.push(file);
            continue;
        }
        let Some(mut text) = reader.read(&path, line, col, &what) else {
            ok = false;
            continue;
        };
        let mut list_name = None;
        if crate::config::is_twincat_source(&path) {
            if program {
                // the project the program belongs to names the libraries it uses
                ok &= learnt.nearest(reader, &path, base, (line, col), &what);
            }
            list_name = st::twincat::gvl_name(&text);
            match st::twincat::st_text(&text) {
                Ok(st) => text = st,
                Err(e) => {
                    let d = Diagnostic::new(&path, e.span.line, e.span.col, e.message);
                    reader.diags.push(d);
                    ok = false;
                    continue;
                }
            }
        }
        let (mut file, errors) = st::parse_file_with(&path, &text, &config.st.defines);
        file.list_name = list_name;
        ok &= errors.is_empty();
        reader.diags.extend(errors);
        files.push(file);
    }
    if !ok {
        return None;
    }
    let instances: Vec<st::Instance<'_>> = entries
        .iter()
        .map(|entry| st::Instance {
            name: &entry.name,
            pou: entry.pou.as_deref(),
            file: &entry.resolved,
            config: &config.path,
            line: entry.line,
            col: entry.col,
        })
        .collect();
    let configured: Vec<Option<&st::ast::ProgramDecl>> =
        entries.iter().map(|entry| configured_declaration(entry, &files)).collect();
    let dialect = st::dialect::Dialect {
        strict: config.st.strict,
        iec: config.iec.layout.clone(),
        heap_bytes: config.st.heap_bytes,
        libraries: config.st.system_libraries,
        variable_memory_bytes: config.st.variable_memory_bytes,
    };
    let shown = |path: &Path| path.strip_prefix(base).unwrap_or(path).display().to_string();
    let mut notes = learnt.notes(shown, config.st.system_libraries);
    notes.extend(st::iec_check::check_notes(&files, &config.iec.layout, shown));
    let namespaces = learnt.with(&config.st.namespaces);
    let bindings = st::ConfigBindings { path: &config.path, variables: &config.iec.variables };
    let compiled =
        st::compile_project(&files, &instances, &configured, dialect, &namespaces, Some(bindings));
    match compiled {
        Ok(mut compiled) => {
            let (iec_notes, warnings) =
                st::iec_check::config_notes(&files, &config.iec, &config.path);
            notes.extend(iec_notes);
            compiled.warnings.extend(warnings);
            Some((compiled, notes))
        }
        Err(errors) => {
            reader.diags.extend(errors);
            None
        }
    }
}

/// The declaration of the configuration's program instance (`PROGRAM i : P (a := x);`) that
/// `entry` stands for; none for another `[[program]]`.
fn configured_declaration<'f>(
    entry: &ProgramConfig,
    files: &'f [st::ast::File],
) -> Option<&'f st::ast::ProgramDecl> {
    let file = files.iter().find(|f| entry.configured && f.path == entry.resolved)?;
    let conf = st::configuration::of_file(file, &file.path).ok().flatten()?;
    conf.resources.iter().flat_map(|r| &r.programs).find(|d| d.name.is(&entry.name))
}

/// `DI(n)` and `EI(n)` of Structured Text name a configured task, as the instruction list's
/// `DI n` must (its assembler checks it; the ST compiler does not know the config).
fn check_task_numbers(programs: &[Program], task_numbers: &[u8], diags: &mut Diagnostics) {
    for program in programs {
        for (pc, op) in program.code.iter().enumerate() {
            let (name, n) = match op {
                Op::System(SystemRequest::DisableTasks(Some(n))) => ("DI", *n),
                Op::System(SystemRequest::EnableTasks(Some(n))) => ("EI", *n),
                _ => continue,
            };
            if !task_numbers.contains(&n) {
                diags.push(Diagnostic::new(
                    program.file_of(pc),
                    program.line_of(pc),
                    1,
                    format!("`{name}({n})`: no task has number {n} in the configuration"),
                ));
            }
        }
    }
}

/// At most five DUTY instructions, and one per clock relay, across the whole project. Five
/// relays with one DUTY each make five; the limit of five bites when a relay is named twice as
/// well (six DUTYs, one of them a duplicate: both errors).
fn check_duty(files: &[(PathBuf, Vec<DutySite>)], diags: &mut Diagnostics) {
    let mut seen: Vec<(u8, &Path, u32)> = Vec::new();
    for (path, sites) in files {
        for site in sites {
            let relay = 420 + u32::from(site.channel);
            if let Some((_, first_path, first_line)) =
                seen.iter().find(|(c, _, _)| *c == site.channel)
            {
                diags.push(Diagnostic::new(
                    path,
                    site.line,
                    site.col,
                    format!(
                        "SM{relay} is already the clock relay of the DUTY at {}:{first_line}: one DUTY per relay",
                        first_path.display()
                    ),
                ));
            } else if seen.len() >= MAX_DUTY {
                diags.push(Diagnostic::new(
                    path,
                    site.line,
                    site.col,
                    format!("more than {MAX_DUTY} DUTY instructions in the project"),
                ));
            }
            seen.push((site.channel, path, site.line));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn project(st: &str) -> Project {
        let config = crate::config::parse(
            "[[program]]\nname = \"main\"\nfile = \"main.st\"\n",
            Path::new("/p/plcd.toml"),
        )
        .unwrap();
        from_config(config, |_| Ok(st.to_string())).unwrap()
    }

    #[test]
    fn a_configuration_file_is_read_and_parsed_once() {
        let config =
            crate::config::parse("[[program]]\nfile = \"plc.st\"\n", Path::new("/p/plcd.toml"))
                .unwrap();
        let text = "PROGRAM p\nVAR n : INT; END_VAR\nn := n + 1;\nEND_PROGRAM\n\
                    CONFIGURATION c\n  PROGRAM a : p;\n  PROGRAM b : p;\nEND_CONFIGURATION\n";
        let reads = std::cell::Cell::new(0);
        let project = from_config(config, |_| {
            reads.set(reads.get() + 1);
            Ok(text.to_string())
        })
        .unwrap();
        assert_eq!(reads.get(), 1);
        let names: Vec<&str> = project.programs.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
    }

    #[test]
    fn names_resolve_or_say_what_is_close() {
        let p = project(
            "PROGRAM Main\nVAR\n  Speed : INT;\n  buf : ARRAY [1..2] OF INT;\nEND_VAR\nEND_PROGRAM\n",
        );
        let names = |text: &str| -> Vec<String> {
            p.resolve(text).unwrap().iter().map(Watched::name).collect()
        };
        assert_eq!(names("MAIN.SPEED"), ["main.Speed"]);
        assert_eq!(names("main.buf"), ["main.buf[1]", "main.buf[2]"]);
        assert_eq!(names("d10"), ["D00010"]);
        assert_eq!(
            p.resolve("main.spede").unwrap_err(),
            "no device or variable `main.spede` (did you mean `main.Speed`?)"
        );
        assert_eq!(
            p.resolve("main.buf[3]").unwrap_err(),
            "no device or variable `main.buf[3]` (did you mean `main.buf[1]`?)"
        );
        assert_eq!(
            p.resolve("nothing_like_it").unwrap_err(),
            "no device or variable `nothing_like_it`"
        );
        assert!(p.resolve("D99999").unwrap_err().contains("out of range"));
        assert_eq!(p.resolve("_NOPE").unwrap_err(), "unknown flag `_NOPE`");
        assert_eq!(crate::symbols::edit_distance(b"Speed", b"spede"), 2);
        assert_eq!(crate::symbols::edit_distance(b"", b"ab"), 2);
    }

    const MQTT_MAIN: &str = "TYPE Axis : STRUCT pos : REAL; on : BOOL; END_STRUCT END_TYPE
    PROGRAM Main
    VAR
        axis : Axis;
        speed : INT;
        name : STRING;
        r : REF_TO INT;
    END_VAR
    VAR CONSTANT
        limit : INT := 100;
    END_VAR
        speed := speed;
    END_PROGRAM
    ";

    /// A project of [`MQTT_MAIN`] and `config` (its `[[program]]` added).
    fn with_mqtt(config: &str) -> Result<Project, String> {
        let text = format!("{config}\n[[program]]\nname = \"main\"\nfile = \"main.st\"\n");
        let config =
            crate::config::parse(&text, Path::new("/p/plcd.toml")).map_err(|e| e.to_string())?;
        from_config(config, |_| Ok(MQTT_MAIN.to_string())).map_err(|e| e.to_string())
    }

    #[test]
    fn mqtt_names_resolve_to_full_variable_names() {
        let project = with_mqtt(
            "[mqtt]\nwritable = [\"main.axis\", \"MAIN.SPEED\"]\n\
             [[mqtt.devices]]\nname = \"press\"\nvariables = [\"main.speed\", \"main.axis\", \"main.axis.pos\"]\n\
             [[mqtt.devices]]\nname = \"all\"\nvariables = [\"main\"]\n\
             [[mqtt.deadbands]]\nvariable = \"main.axis\"\nvalue = 0.5\n\
             [[mqtt.deadbands]]\nvariable = \"main.speed\"\nvalue = 2\n",
        )
        .unwrap();
        let names = project.mqtt_names().unwrap();
        // A struct stands for its variables.
        let writable: Vec<&str> = names.writable.iter().map(String::as_str).collect();
        assert_eq!(writable, ["main.axis.on", "main.axis.pos", "main.speed"]);
        // Numbers only: the struct's BOOL has no deadband.
        let deadbands: Vec<(&str, f64)> =
            names.deadbands.iter().map(|(name, value)| (name.as_str(), *value)).collect();
        assert_eq!(deadbands, [("main.axis.pos", 0.5), ("main.speed", 2.0)]);
        // In the order listed, each once; a program instance stands for every variable but the
        // reference, its CONSTANTs included.
        let devices: Vec<(&str, Vec<&str>)> = names
            .devices
            .iter()
            .map(|(device, names)| (device.as_str(), names.iter().map(String::as_str).collect()))
            .collect();
        assert_eq!(
            devices,
            [
                ("press", vec!["main.speed", "main.axis.pos", "main.axis.on"]),
                (
                    "all",
                    vec!["main.limit", "main.axis.pos", "main.axis.on", "main.speed", "main.name"]
                ),
            ]
        );
        let none = with_mqtt("").unwrap().mqtt_names().unwrap();
        assert_eq!(none, MqttNames::default());
    }

    #[test]
    fn mqtt_names_report_every_error_at_its_name() {
        let errors = with_mqtt(
            "[mqtt]\nwritable = [\"D00100\", \"main.limit\"]\n\
             [[mqtt.devices]]\nname = \"d\"\nvariables = [\"main.r^\", \"main.r\", \"main.nope\"]\n\
             [[mqtt.deadbands]]\nvariable = \"main.name\"\nvalue = 1\n",
        )
        .unwrap_err();
        assert_eq!(
            errors,
            "/p/plcd.toml:2:13: error: mqtt.writable: `D00100` is a device: the MQTT edge node \
             publishes the programs' variables\n\
             /p/plcd.toml:2:23: error: mqtt.writable: `main.limit` holds no variable a client could \
             write (CONSTANTs and references are never written)\n\
             /p/plcd.toml:5:14: error: mqtt.devices: `main.r^` names a variable through a reference, \
             which changes as the program runs: name the variable itself\n\
             /p/plcd.toml:5:25: error: mqtt.devices: `main.r` holds no variable that is not a \
             reference (references are not published)\n\
             /p/plcd.toml:5:35: error: mqtt.devices: no device or variable `main.nope` (did \
             you mean `main.name`?)\n\
             /p/plcd.toml:7:12: error: mqtt.deadbands: `main.name` holds no number (an integer or a \
             REAL): a deadband is for numbers\n"
        );
    }
}

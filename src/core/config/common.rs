//! The machinery every section shares: what a diagnostic is about ([`Ctx`]), a table with its
//! span ([`Located`]), pass 1's deserializing of a section or an array of tables with every bad
//! key reported, and pass 2's number checks worded one way for every key.

use std::ops::{Range, RangeInclusive};
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use toml::de::{DeTable, DeValue, ValueDeserializer};
use toml::Spanned;

use super::Sink;

/// What a diagnostic is about: a section (`plc`) or one entry of an array of tables
/// (`task "fast"`, `io.input #2`).
#[derive(Debug, Clone)]
pub(super) enum Ctx {
    Section(&'static str),
    Entry(String),
}

impl Ctx {
    /// The thing as a whole: `[plc]`, `task "fast"`.
    pub fn subject(&self) -> String {
        match self {
            Ctx::Section(name) => format!("[{name}]"),
            Ctx::Entry(entry) => entry.clone(),
        }
    }

    /// One of its keys: `plc.watchdog_ms`, `task "fast": priority`.
    pub fn key(&self, key: &str) -> String {
        match self {
            Ctx::Section(name) => format!("{name}.{key}"),
            Ctx::Entry(entry) => format!("{entry}: {key}"),
        }
    }
}

/// A deserialized table with the span of its header and what it is called in messages.
#[derive(Debug)]
pub(super) struct Located<T> {
    pub span: Range<usize>,
    pub ctx: Ctx,
    pub value: T,
}

/// A top-level table: its default when absent, `None` when it cannot be deserialized. Its
/// malformed keys are left out (taking their defaults) and noted in `failed` as `name.key`.
pub(super) fn section<T: DeserializeOwned + Default>(
    sink: &mut Sink,
    value: Option<Spanned<DeValue<'_>>>,
    name: &'static str,
    failed: &mut Vec<String>,
) -> Option<T> {
    let Some(value) = value else {
        return Some(T::default());
    };
    let span = value.span();
    match value.into_inner() {
        DeValue::Table(table) => {
            let (value, removed) = deserialize(sink, table, span, &Ctx::Section(name))?;
            failed.extend(removed.into_iter().map(|key| format!("{name}.{key}")));
            Some(value)
        }
        _ => {
            sink.error(span.start, format!("`{name}` must be a table, written [{name}]"));
            None
        }
    }
}

/// An array of tables, entry by entry. A failed entry is `Err` with its peeked name.
///
/// `name_of` peeks at an entry's raw table for what to call it in messages (`task "fast"`);
/// without one the entry is called by its position (`task #2`).
pub(super) fn entries<T: DeserializeOwned>(
    sink: &mut Sink,
    value: Option<Spanned<DeValue<'_>>>,
    name: &str,
    name_of: impl Fn(&DeTable) -> Option<String>,
) -> Vec<Result<Located<T>, Option<String>>> {
    entries_as(sink, value, name, name, name_of)
}

/// [`entries`] of an array whose entries are called `label "x"` or `label #2` rather than by
/// the array's dotted `name` (the tables of one `[[remote]]`: `remote "rack1" read #2`).
pub(super) fn entries_as<T: DeserializeOwned>(
    sink: &mut Sink,
    value: Option<Spanned<DeValue<'_>>>,
    name: &str,
    label: &str,
    name_of: impl Fn(&DeTable) -> Option<String>,
) -> Vec<Result<Located<T>, Option<String>>> {
    let Some(value) = value else {
        return Vec::new();
    };
    let not_an_array = format!("`{name}` must be an array of tables, written [[{name}]]");
    let span = value.span();
    let DeValue::Array(array) = value.into_inner() else {
        sink.error(span.start, not_an_array);
        return vec![Err(None)];
    };
    let mut out = Vec::new();
    for (index, entry) in array.into_iter().enumerate() {
        let span = entry.span();
        let DeValue::Table(table) = entry.into_inner() else {
            sink.error(span.start, not_an_array.clone());
            out.push(Err(None));
            continue;
        };
        let peeked = name_of(&table);
        let ctx = match &peeked {
            Some(entry_name) => Ctx::Entry(format!("{label} {entry_name:?}")),
            None => Ctx::Entry(format!("{label} #{}", index + 1)),
        };
        out.push(match deserialize(sink, table, span.clone(), &ctx) {
            Some((value, removed)) if removed.is_empty() => Ok(Located { span, ctx, value }),
            _ => Err(peeked),
        });
    }
    out
}

pub(super) fn peek_str(table: &DeTable, key: &str) -> Option<String> {
    table.get(key).and_then(|v| v.get_ref().as_str()).map(str::to_string)
}

/// Deserializes a table, reporting every bad key rather than only the first.
///
/// serde stops at the first error, so after each error the key it is about is taken out and
/// the table is tried again, until it deserializes (the value and the keys taken out) or an
/// error is about no key in particular, such as a missing key (`None`).
fn deserialize<T: DeserializeOwned>(
    sink: &mut Sink,
    mut table: DeTable<'_>,
    span: Range<usize>,
    ctx: &Ctx,
) -> Option<(T, Vec<String>)> {
    let mut removed: Vec<String> = Vec::new();
    loop {
        let attempt = Spanned::new(span.clone(), DeValue::Table(table.clone()));
        let error = match T::deserialize(ValueDeserializer::from(attempt)) {
            Ok(value) => return Some((value, removed)),
            Err(error) => error,
        };
        let at = error.span().unwrap_or(span.clone());
        let message = tidy(error.message());
        // A required key taken out for being malformed is not missing as well.
        if removed.iter().any(|key| message == format!("missing key `{key}`")) {
            return None;
        }
        // serde's messages name the unexpected type or value, not the key: the span does.
        let key = table
            .iter()
            .find(|(k, v)| v.span().contains(&at.start) || k.span() == at)
            .map(|(k, _)| k.get_ref().to_string());
        let message = match &key {
            // "unknown key `x`" and "missing key `x`" name the key already.
            _ if message.contains("key `") => format!("{}: {message}", ctx.subject()),
            Some(key) => format!("{}: {message}", ctx.key(key)),
            None => format!("{}: {message}", ctx.subject()),
        };
        let unknown = message.contains("unknown key `");
        sink.error(at.start, message);
        let key = key?;
        table.remove(key.as_str());
        // An unknown key carries nothing the rest depends on: the entry is still checked.
        if !unknown {
            removed.push(key);
        }
    }
}

/// serde's wording for users who write TOML, not Rust.
fn tidy(message: &str) -> String {
    let message = message.lines().next().unwrap_or_default();
    [
        ("unknown field `", "unknown key `"),
        ("missing field `", "missing key `"),
        ("expected i64", "expected an integer"),
        ("wanted string or table", "expected a string"),
    ]
    .iter()
    .fold(message.to_string(), |m, (from, to)| m.replace(from, to))
}

/// `value` if it is within `range` (and so fits `T`); otherwise reports it, naming the key.
pub(super) fn int<T: TryFrom<i64>>(
    sink: &mut Sink,
    ctx: &Ctx,
    key: &str,
    value: &Spanned<i64>,
    range: RangeInclusive<i64>,
) -> Option<T> {
    let v = *value.get_ref();
    if range.contains(&v) {
        if let Ok(v) = T::try_from(v) {
            return Some(v);
        }
    }
    let message = if *range.end() == i64::MAX {
        format!("{} {v} must be at least {}", ctx.key(key), range.start())
    } else {
        format!("{} {v} out of range {}..={}", ctx.key(key), range.start(), range.end())
    };
    sink.error(value.span().start, message);
    None
}

/// [`int`] for an optional key with a default.
pub(super) fn int_or<T: TryFrom<i64>>(
    sink: &mut Sink,
    ctx: &Ctx,
    key: &str,
    value: Option<Spanned<i64>>,
    range: RangeInclusive<i64>,
    default: T,
) -> Option<T> {
    match value {
        Some(value) => int(sink, ctx, key, &value, range),
        None => Some(default),
    }
}

pub(super) fn widen<T: Copy + Into<i64>>(range: RangeInclusive<T>) -> RangeInclusive<i64> {
    (*range.start()).into()..=(*range.end()).into()
}

/// `file` relative to the config file's directory (unchanged if absolute).
pub(super) fn resolve(config: &Path, file: &str) -> PathBuf {
    match config.parent() {
        Some(dir) => dir.join(file),
        None => PathBuf::from(file),
    }
}

pub(super) fn start<T>(value: &Option<Spanned<T>>) -> Option<usize> {
    value.as_ref().map(|v| v.span().start)
}

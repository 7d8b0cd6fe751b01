//! `[iec]`: what the IEC 61131-3 direct addresses of Structured Text (`%IX0.0`, `%QW3`,
//! `%MD10`) name in device memory: a preset layout (OpenPLC's, CODESYS's, plcd's own) and the
//! device words its images start at (docs/CONFIG.md, `[iec]`); where Beremiz's multi-level
//! addresses are (`[iec.addresses]`, placed in the layout); and the variables at partly
//! specified addresses the config binds (`[iec.variables]`, which the Structured Text compiler
//! applies as it applies a configuration's `VAR_CONFIG … AT`). The layouts themselves are
//! `device::iec`'s.

use serde::de::IgnoredAny;
use serde::Deserialize;
use toml::de::DeValue;
use toml::Spanned;

use super::common::{int, section, Ctx};
use super::Sink;
use crate::device::iec::{IecLayout, Image, MultiLevel, Preset, Start};
use crate::diag::Diagnostic;

/// `[iec]`.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct IecConfig {
    /// The preset with the starts the config moved: default OpenPLC's numbering with its
    /// images at their default words, and the multi-level addresses `[iec.addresses]` places.
    pub layout: IecLayout,
    /// `[iec.addresses]`, in file order: where each entry is written (the layout places them).
    pub addresses: Vec<IecAddress>,
    /// `[iec.variables]`, in file order.
    pub variables: Vec<IecVariable>,
}

/// One entry of `[iec.addresses]`: `"%IX100.0.0" = "%IX4.0"`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IecAddress {
    /// The multi-level address.
    pub key: MultiLevel,
    /// The key as written (`%ix100.0.0`).
    pub written: String,
    /// Where it is, as written (`%IX4.0`, `P0100`).
    pub target: String,
    /// Where the key is written.
    pub line: u32,
    pub col: u32,
}

/// One entry of `[iec.variables]`: `"main.fb.lvl" = "%MW5"`, a variable at a partly specified
/// address (`AT %MW*`) bound to a full one, as a configuration's `VAR_CONFIG` entry
/// `main.fb.lvl AT %MW5 : INT;` binds it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IecVariable {
    /// The key as written: `main.fb.lvl`.
    pub key: String,
    /// Its names: the program instance (or `Resource.instance`), then variables and function
    /// block instances.
    pub path: Vec<String>,
    /// The address without its `%`: `MW5`, `P0040`.
    pub address: String,
    /// Where the key is written.
    pub line: u32,
    pub col: u32,
    /// Where the address is written.
    pub value_line: u32,
    pub value_col: u32,
}

impl IecVariable {
    /// How messages name it: `iec.variables "main.lamp"`.
    pub fn subject(&self) -> String {
        format!("iec.variables {:?}", self.key)
    }
}

/// One `"key" = "value"` of a table of `[iec]`, with where each is written (byte offsets).
#[derive(Debug)]
pub(super) struct Pair {
    key: String,
    key_at: usize,
    value: String,
    value_at: usize,
}

/// `[iec]` as written: the preset, where each image starts, and the tables of addresses and
/// variables (taken out of the section before serde reads it: `_variables` and `_addresses`
/// are declared only so that an unknown key's message lists them).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawIec {
    pub preset: Option<Spanned<String>>,
    pub input: Option<Spanned<String>>,
    pub output: Option<Spanned<String>>,
    pub memory: Option<Spanned<String>>,
    pub input_words: Option<Spanned<String>>,
    pub output_words: Option<Spanned<String>>,
    pub memory_words: Option<Spanned<String>>,
    pub memory_dwords: Option<Spanned<String>>,
    pub memory_lwords: Option<Spanned<String>>,
    pub byte_input: Option<Spanned<String>>,
    pub byte_output: Option<Spanned<String>>,
    pub input_bytes: Option<Spanned<i64>>,
    pub output_bytes: Option<Spanned<i64>>,
    pub memory_bytes: Option<Spanned<i64>>,
    #[serde(rename = "variables")]
    _variables: Option<IgnoredAny>,
    #[serde(rename = "addresses")]
    _addresses: Option<IgnoredAny>,
    #[serde(skip)]
    variables: Vec<Pair>,
    #[serde(skip)]
    addresses: Vec<Pair>,
}

/// Pass 1 of `[iec]`: the section, with `[iec.variables]` and `[iec.addresses]` read as
/// strings by strings (their keys are paths and addresses, not names serde could know). `None`
/// when it cannot be read (reported).
pub(super) fn read(
    sink: &mut Sink,
    value: Option<Spanned<DeValue<'_>>>,
    failed: &mut Vec<String>,
) -> Option<RawIec> {
    let Some(value) = value else { return Some(RawIec::default()) };
    if !matches!(value.get_ref(), DeValue::Table(_)) {
        // what any section that is not a table is told
        return section(sink, Some(value), "iec", failed);
    }
    let span = value.span();
    let DeValue::Table(mut table) = value.into_inner() else { return None };
    let variables = table.remove("variables");
    let addresses = table.remove("addresses");
    let mut raw: RawIec =
        section(sink, Some(Spanned::new(span, DeValue::Table(table))), "iec", failed)?;
    raw.variables = pairs(sink, variables, "variables");
    raw.addresses = pairs(sink, addresses, "addresses");
    Some(raw)
}

/// The string values of the table `[iec.name]`, in file order; each other value reported.
fn pairs(sink: &mut Sink, value: Option<Spanned<DeValue<'_>>>, name: &str) -> Vec<Pair> {
    let Some(value) = value else { return Vec::new() };
    let span = value.span();
    let DeValue::Table(table) = value.into_inner() else {
        sink.error(span.start, format!("`iec.{name}` must be a table, written [iec.{name}]"));
        return Vec::new();
    };
    let mut out = Vec::new();
    for (key, value) in table {
        let (key_at, value_at) = (key.span().start, value.span().start);
        match value.get_ref().as_str() {
            Some(text) => out.push(Pair {
                key: key.get_ref().to_string(),
                key_at,
                value: text.to_string(),
                value_at,
            }),
            None => sink.error(
                value_at,
                format!("iec.{name} {:?}: expected a string, an address", key.get_ref()),
            ),
        }
    }
    out.sort_by_key(|p| p.key_at);
    out
}

impl RawIec {
    /// The start written for `image`, if any.
    fn start(&self, image: Image) -> Option<&Spanned<String>> {
        match image {
            Image::Input => self.input.as_ref(),
            Image::Output => self.output.as_ref(),
            Image::Memory => self.memory.as_ref(),
            Image::InputWords => self.input_words.as_ref(),
            Image::OutputWords => self.output_words.as_ref(),
            Image::MemoryWords => self.memory_words.as_ref(),
            Image::MemoryDwords => self.memory_dwords.as_ref(),
            Image::MemoryLwords => self.memory_lwords.as_ref(),
            Image::InputBytes => self.byte_input.as_ref(),
            Image::OutputBytes => self.byte_output.as_ref(),
        }
    }

    /// The size written for the byte image `image`, if any.
    fn bytes(&self, image: Image) -> Option<&Spanned<i64>> {
        match image {
            Image::Input => self.input_bytes.as_ref(),
            Image::Output => self.output_bytes.as_ref(),
            Image::Memory => self.memory_bytes.as_ref(),
            _ => None,
        }
    }
}

pub(super) fn validate(sink: &mut Sink, raw: RawIec) -> Option<IecConfig> {
    let ctx = Ctx::Section("iec");
    let mut ok = true;
    let preset = match &raw.preset {
        None => Preset::default(),
        Some(name) => match Preset::from_name(name.get_ref()) {
            Some(preset) => preset,
            None => {
                let names: Vec<String> =
                    Preset::ALL.iter().map(|p| format!("\"{}\"", p.name())).collect();
                sink.error(
                    name.span().start,
                    format!(
                        "{}: {:?} is not a layout, one of {}",
                        ctx.key("preset"),
                        name.get_ref(),
                        names.join(", ")
                    ),
                );
                return None;
            }
        },
    };
    let mut layout = IecLayout::of(preset);
    // where each image's start was written, for the layout's problems
    let mut written: Vec<(Image, usize)> = Vec::new();
    for image in Image::ALL {
        let Some(text) = raw.start(image) else { continue };
        let at = text.span().start;
        if !preset.images().contains(&image) {
            sink.error(
                at,
                format!(
                    "{}: the {} layout has no such image ({})",
                    ctx.key(image.key()),
                    preset.name(),
                    match preset {
                        Preset::Plcd => "its addresses are P and M words: `%IX4.0` is P0040",
                        _ => "only `preset = \"openplc\"` has images of words and bytes apart",
                    }
                ),
            );
            ok = false;
            continue;
        }
        match Start::parse(text.get_ref()) {
            Ok(start) => {
                layout = layout.with_start(image, start);
                written.push((image, at));
            }
            Err(why) => {
                sink.error(at, format!("{}: {why}", ctx.key(image.key())));
                ok = false;
            }
        }
    }
    // the sizes of the byte images: at least a byte, at most a whole device area (two bytes a
    // word); whether they fit where they start is the layout's problems' to say
    for image in [Image::Input, Image::Output, Image::Memory] {
        let (Some(key), Some(value)) = (image.bytes_key(), raw.bytes(image)) else { continue };
        if preset == Preset::Plcd {
            sink.error(
                value.span().start,
                format!("{}: the plcd layout has no byte images to size", ctx.key(key)),
            );
            ok = false;
            continue;
        }
        match int::<u32>(sink, &ctx, key, value, 1..=2 * 32768) {
            Some(bytes) => {
                layout = layout.with_bytes(image, bytes);
                written.push((image, value.span().start));
            }
            None => ok = false,
        }
    }
    if ok {
        for (image, problem) in layout.problems() {
            // at the start written for it, or at the one of the image it overlaps
            let at = written.iter().find(|(i, _)| *i == image).map(|&(_, at)| at);
            let at = at.or_else(|| written.first().map(|&(_, at)| at)).unwrap_or(0);
            sink.error(at, format!("{}: {problem}", ctx.key(image.key())));
            ok = false;
        }
    }
    if !ok {
        return None;
    }
    // the variables checked whatever the addresses' errors, against the entries that are right
    let (layout, addresses) = place_addresses(sink, layout, &raw.addresses);
    let variables = variables(sink, &layout, &raw.variables);
    Some(IecConfig { layout, addresses: addresses?, variables: variables? })
}

/// `[iec.addresses]`: each multi-level address placed in `layout` at its target (those that
/// are right), and the entries, `None` when one is wrong (reported).
fn place_addresses(
    sink: &mut Sink,
    mut layout: IecLayout,
    pairs: &[Pair],
) -> (IecLayout, Option<Vec<IecAddress>>) {
    let mut ok = true;
    let mut entries: Vec<IecAddress> = Vec::new();
    for pair in pairs {
        let subject = format!("iec.addresses {:?}", pair.key);
        let key = match MultiLevel::parse(&pair.key) {
            Ok(key) => key,
            Err(why) => {
                sink.error(pair.key_at, format!("{subject}: {why}"));
                ok = false;
                continue;
            }
        };
        let (line, col) = Diagnostic::line_col(sink.text, pair.key_at);
        if let Some(first) = entries.iter().find(|e| e.key == key) {
            let msg = format!(
                "{subject}: `{key}` is placed already (line {}): an address is in one place",
                first.line
            );
            sink.error(pair.key_at, msg);
            ok = false;
            continue;
        }
        // the layout without the entries: a target is an address of the layout's own
        match layout.place(&key, &pair.value) {
            Ok(direct) => {
                layout = layout.with_placed(key.clone(), direct);
                let (written, target) = (pair.key.clone(), pair.value.clone());
                entries.push(IecAddress { key, written, target, line, col });
            }
            Err(why) => {
                sink.error(pair.value_at, format!("{subject}: {why}"));
                ok = false;
            }
        }
    }
    (layout, ok.then_some(entries))
}

/// `[iec.variables]`: each key a variable path, each value a full address of `layout` (a
/// multi-level one `[iec.addresses]` places included) or a device of P, M, K or D. Whether
/// the variable is at a partly specified address the value fits is the compiler's to say.
fn variables(sink: &mut Sink, layout: &IecLayout, pairs: &[Pair]) -> Option<Vec<IecVariable>> {
    let mut ok = true;
    let mut out = Vec::new();
    for pair in pairs {
        let subject = format!("iec.variables {:?}", pair.key);
        let path: Vec<String> = pair.key.split('.').map(|p| p.trim().to_string()).collect();
        let name = |p: &String| {
            p.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
                && p.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        };
        if path.len() < 2 || !path.iter().all(name) {
            let msg = format!(
                "{subject}: not a variable path: a program instance, then its variables and function block instances, names joined by dots (`main.lamp`, `main.fb.level`, `Res0.inst.lamp`)"
            );
            sink.error(pair.key_at, msg);
            ok = false;
            continue;
        }
        let address = pair.value.strip_prefix('%').unwrap_or(&pair.value).to_string();
        if let Err(why) = layout.full(&address) {
            sink.error(pair.value_at, format!("{subject}: {why}"));
            ok = false;
            continue;
        }
        let (line, col) = Diagnostic::line_col(sink.text, pair.key_at);
        let (value_line, value_col) = Diagnostic::line_col(sink.text, pair.value_at);
        out.push(IecVariable {
            key: pair.key.clone(),
            path,
            address,
            line,
            col,
            value_line,
            value_col,
        });
    }
    ok.then_some(out)
}

//! `[iec]`: what the IEC 61131-3 direct addresses of Structured Text (`%IX0.0`, `%QW3`,
//! `%MD10`) name in device memory: a preset layout (OpenPLC's, CODESYS's, plcd's own) and the
//! device words its images start at (docs/CONFIG.md, `[iec]`). The layouts themselves are
//! `device::iec`'s.

use serde::Deserialize;
use toml::Spanned;

use super::common::{int, Ctx};
use super::Sink;
use crate::device::iec::{IecLayout, Image, Preset, Start};

/// `[iec]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IecConfig {
    /// The preset with the starts the config moved: default OpenPLC's numbering with its
    /// images at their default words.
    pub layout: IecLayout,
}

/// `[iec]` as written: the preset, and where each image starts.
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
    ok.then_some(IecConfig { layout })
}

//! IEC 61131-3 direct addresses (`%IX0.0`, `%QW3`, `%MD10`) and the plcd devices they name:
//! the layout `[iec]` chooses (docs/ST.md, "Direct addresses"; docs/CONFIG.md, `[iec]`).
//!
//! IEC 61131-3 leaves the meaning of `%I`, `%Q` and `%M` to the implementation, and the
//! editors a program comes from disagree:
//!
//! - [`Preset::OpenPlc`] (the default, OpenPLC Editor and Beremiz programs): `%IX`, `%QX` and
//!   `%MX` are bits numbered by byte and bit (`%IX1.0` is the bit after `%IX0.7`); `%IW`,
//!   `%QW`, `%MW`, `%MD`, `%ML`, and the bytes `%IB` and `%QB` (OpenPLC's `byte_input` and
//!   `byte_output`) are seven more areas of their own, overlapping nothing;
//! - [`Preset::Codesys`]: one byte image for each of `%I`, `%Q` and `%M`, every size a view of
//!   the same bytes (`%IW0` is bytes 0 and 1, `%IX1.0` bit 0 of byte 1, so bit 8 of `%IW0`);
//! - [`Preset::Plcd`]: plcd's own numbering before images existed, `%IXa.b` and `%QXa.b` both
//!   bit `b` (0..15) of P word `a`, `%MWa` M word `a`.
//!
//! Each image starts at a device word the config may move. A byte image is laid out two bytes
//! to a plcd word, the even byte in the low half (CODESYS's `%IW0` has `%IB0` in its low byte on
//! x86 and ARM): byte `b` of an image that starts at word `s` is word `s + b/2`, bits
//! `8 * (b mod 2)` to `8 * (b mod 2) + 7`. A byte address names that half of the word alone
//! ([`Direct::is_byte`]): the compiler places it as a device byte, which a store writes
//! without the other half.
//!
//! This module owns the layouts, their defaults and their checks, and the resolution of an
//! address text. The Structured Text compiler resolves its programs' addresses with it
//! (`st::compile::decl::iec_address`), `config::iec` reads `[iec]` into one, and
//! `st::iec_check` says what `plcd check` shows of it.

use super::{Address, Area};

/// The editor whose numbering `%I`, `%Q` and `%M` follow: `[iec] preset`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Preset {
    /// OpenPLC v3's numbering (OpenPLC Editor, Beremiz).
    #[default]
    OpenPlc,
    /// CODESYS's (and TwinCAT's) byte images.
    Codesys,
    /// plcd's own: P and M words and bits 0..15.
    Plcd,
}

impl Preset {
    /// Every preset, in the order the docs list them.
    pub const ALL: [Preset; 3] = [Preset::OpenPlc, Preset::Codesys, Preset::Plcd];

    /// The name `[iec] preset` gives it.
    pub fn name(self) -> &'static str {
        match self {
            Preset::OpenPlc => "openplc",
            Preset::Codesys => "codesys",
            Preset::Plcd => "plcd",
        }
    }

    /// The preset of that name (any case).
    pub fn from_name(name: &str) -> Option<Preset> {
        Preset::ALL.into_iter().find(|p| p.name().eq_ignore_ascii_case(name))
    }

    /// The images the preset lays out, in the order `plcd check` shows them.
    pub fn images(self) -> &'static [Image] {
        match self {
            Preset::OpenPlc => &Image::ALL,
            Preset::Codesys => &[Image::Input, Image::Output, Image::Memory],
            Preset::Plcd => &[],
        }
    }
}

/// One image of IEC addresses, at consecutive device words.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Image {
    /// `%I`: under codesys every size; under openplc the `%IX` bits.
    Input,
    /// `%Q`, as [`Image::Input`].
    Output,
    /// `%M`, as [`Image::Input`] (`%MX` under openplc).
    Memory,
    /// openplc's `%IW` (analog inputs).
    InputWords,
    /// openplc's `%QW` (analog outputs).
    OutputWords,
    /// openplc's `%MW`.
    MemoryWords,
    /// openplc's `%MD`.
    MemoryDwords,
    /// openplc's `%ML`.
    MemoryLwords,
    /// openplc's `%IB` (OpenPLC's `byte_input`): bytes apart from the `%IX` bits.
    InputBytes,
    /// openplc's `%QB` (OpenPLC's `byte_output`).
    OutputBytes,
}

impl Image {
    pub const ALL: [Image; 10] = [
        Image::Input,
        Image::Output,
        Image::Memory,
        Image::InputWords,
        Image::OutputWords,
        Image::MemoryWords,
        Image::MemoryDwords,
        Image::MemoryLwords,
        Image::InputBytes,
        Image::OutputBytes,
    ];

    /// Its key in `[iec]`: where it starts.
    pub fn key(self) -> &'static str {
        match self {
            Image::Input => "input",
            Image::Output => "output",
            Image::Memory => "memory",
            Image::InputWords => "input_words",
            Image::OutputWords => "output_words",
            Image::MemoryWords => "memory_words",
            Image::MemoryDwords => "memory_dwords",
            Image::MemoryLwords => "memory_lwords",
            Image::InputBytes => "byte_input",
            Image::OutputBytes => "byte_output",
        }
    }

    fn index(self) -> usize {
        Image::ALL.iter().position(|&i| i == self).unwrap_or(0)
    }

    /// The addresses it holds, as the editors write them.
    fn prefix(self, preset: Preset) -> &'static str {
        match (self, preset) {
            (Image::Input, Preset::Codesys) => "%I",
            (Image::Output, Preset::Codesys) => "%Q",
            (Image::Memory, Preset::Codesys) => "%M",
            (Image::Input, _) => "%IX",
            (Image::Output, _) => "%QX",
            (Image::Memory, _) => "%MX",
            (Image::InputWords, _) => "%IW",
            (Image::OutputWords, _) => "%QW",
            (Image::MemoryWords, _) => "%MW",
            (Image::MemoryDwords, _) => "%MD",
            (Image::MemoryLwords, _) => "%ML",
            (Image::InputBytes, _) => "%IB",
            (Image::OutputBytes, _) => "%QB",
        }
    }

    /// Its default size: bytes for a byte image (the config may change those of `%I`, `%Q`,
    /// `%M`), elements (words, double words, long words) for the word images of openplc
    /// (OpenPLC's 1024, as its bytes `%IB` and `%QB`).
    fn default_units(self) -> u32 {
        match self {
            Image::Input | Image::Output => 128,
            Image::Memory => 512,
            _ => 1024,
        }
    }

    /// Its key in `[iec]` for its size in bytes: a byte image's.
    pub fn bytes_key(self) -> Option<&'static str> {
        match self {
            Image::Input => Some("input_bytes"),
            Image::Output => Some("output_bytes"),
            Image::Memory => Some("memory_bytes"),
            _ => None,
        }
    }

    /// The device words of one unit ([`Image::units`]): a byte is half a word.
    fn unit_words(self) -> u32 {
        match self {
            Image::MemoryDwords => 2,
            Image::MemoryLwords => 4,
            _ => 1,
        }
    }

    /// Whether it holds bytes, two to a device word.
    fn byte_image(self) -> bool {
        self.bit_image() || matches!(self, Image::InputBytes | Image::OutputBytes)
    }

    /// Whether its bytes are numbered by byte and bit too (`%IX`, `%QX`, `%MX`).
    fn bit_image(self) -> bool {
        matches!(self, Image::Input | Image::Output | Image::Memory)
    }
}

/// The first device word of an image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Start {
    pub area: Area,
    pub word: u32,
}

impl Start {
    /// The device word `n` words after the start.
    fn at(self, n: u32) -> Address {
        Address { area: self.area, number: self.word + n, bit: None }
    }

    /// The start a device word names (`P064`, `D10000`): a word address of P, M, K or D.
    pub fn parse(text: &str) -> Result<Start, String> {
        let address = Address::parse(text).map_err(|e| e.to_string())?;
        if !matches!(address.area, Area::P | Area::M | Area::K | Area::D) || address.bit.is_some() {
            return Err(format!(
                "`{text}` is not a word of P, M, K or D (an image starts at a word: `P064`, `D10000`)"
            ));
        }
        Ok(Start { area: address.area, word: address.number })
    }
}

/// What an IEC direct address names: a device, and how many bits the address says it has
/// (1 for `X`, 8, 16, 32, 64 for `B`, `W`, `D`, `L`). A byte of a byte image (`%QB1`) is a bit
/// address, its first bit (0 or 8 of its word), with 8 bits: one half of the word, never the
/// whole (under the plcd layout a `B` address is a whole word, as every size is).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Direct {
    pub address: Address,
    pub bits: u32,
}

impl Direct {
    /// Whether it names one half of a device word (`%QB1` in a byte image).
    pub fn is_byte(&self) -> bool {
        self.bits == 8 && self.address.bit.is_some()
    }
}

impl std::fmt::Display for Direct {
    /// The device as `plcd check` shows it: `P0640`, `D10000`, `P064 (high byte)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_byte() {
            let word = Address { bit: None, ..self.address };
            let high = self.address.bit == Some(8);
            write!(f, "{word} ({})", super::half_name(high))
        } else {
            write!(f, "{}", self.address)
        }
    }
}

/// The layout in effect: `[iec]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IecLayout {
    pub preset: Preset,
    /// Where each image starts, by [`Image::ALL`]'s order (the preset's defaults unless the
    /// config moves one; those of images the preset has no use for are ignored).
    starts: [Start; 10],
    /// The sizes in bytes of the byte images `%I`, `%Q`, `%M` (`%IX`, `%QX`, `%MX`).
    bytes: [u32; 3],
    /// The multi-level addresses the config places (`[iec.addresses]`), each at its device.
    placed: Vec<(MultiLevel, Direct)>,
}

impl Default for IecLayout {
    fn default() -> Self {
        IecLayout::of(Preset::default())
    }
}

impl IecLayout {
    /// The preset with its images at their default words (docs/CONFIG.md, `[iec]`).
    pub fn of(preset: Preset) -> IecLayout {
        let p = |word| Start { area: Area::P, word };
        let m = |word| Start { area: Area::M, word };
        let d = |word| Start { area: Area::D, word };
        IecLayout {
            preset,
            starts: [
                p(0),
                p(64),
                m(0),
                d(10000),
                d(12000),
                d(14000),
                d(16000),
                d(20000),
                // openplc's %IB and %QB, after %IW's and %QW's 1024 words
                d(11024),
                d(13024),
            ],
            bytes: [128, 128, 512],
            placed: Vec::new(),
        }
    }

    /// Where `image` starts.
    pub fn start(&self, image: Image) -> Start {
        self.starts[image.index()]
    }

    /// The layout with `image` moved to `start`.
    pub fn with_start(mut self, image: Image, start: Start) -> IecLayout {
        self.starts[image.index()] = start;
        self
    }

    /// The layout with the byte image `image` (`Input`, `Output`, `Memory`) `bytes` long.
    pub fn with_bytes(mut self, image: Image, bytes: u32) -> IecLayout {
        if let Some(n) = self.bytes.get_mut(image.index()) {
            *n = bytes;
        }
        self
    }

    /// The layout with the multi-level address `key` at `direct` (`[iec.addresses]`, checked
    /// by [`IecLayout::place`]).
    pub fn with_placed(mut self, key: MultiLevel, direct: Direct) -> IecLayout {
        self.placed.push((key, direct));
        self
    }

    /// The multi-level addresses placed, each with its device, in the config's order.
    pub fn placed(&self) -> &[(MultiLevel, Direct)] {
        &self.placed
    }

    /// What a full address the config writes names (`target` with or without its `%`): an
    /// address of this layout (a multi-level one it places included), or a plcd device of P,
    /// M, K or D, which means itself; why it names nothing.
    pub fn full(&self, target: &str) -> Result<Full, String> {
        let text = target.strip_prefix('%').unwrap_or(target);
        if let Some(direct) = self.resolve(text)? {
            return Ok(Full::Iec(direct));
        }
        let address = Address::parse(text).map_err(|e| e.to_string())?;
        if !matches!(address.area, Area::P | Area::M | Area::K | Area::D) {
            return Err(format!(
                "`{text}` is not a device of P, M, K or D: an address is one of the [iec] layout or one of those devices"
            ));
        }
        Ok(Full::Device(address))
    }

    /// Where the config places the multi-level address `key` (`[iec.addresses]`): at `target`,
    /// an address of this layout (not multi-level) of the key's size, or a device of P, M, K
    /// or D that fits it (a bit for an `X` key, a word and the words after it for the others,
    /// an 8-bit type at a whole word as at any word device); why not.
    pub fn place(&self, key: &MultiLevel, target: &str) -> Result<Direct, String> {
        let text = target.strip_prefix('%').unwrap_or(target);
        if MultiLevel::of(text).is_some() {
            return Err(format!(
                "`%{text}` is itself a multi-level address: an entry places one at an address of the [iec] layout or at a device of P, M, K or D"
            ));
        }
        let bits = key.bits();
        match self.full(text)? {
            Full::Iec(direct) if direct.bits == bits => Ok(direct),
            Full::Iec(direct) => Err(format!(
                "`%{text}` is {} {}-bit location, `{key}` {} {bits}-bit one",
                sized(direct.bits),
                direct.bits,
                sized(bits)
            )),
            Full::Device(address) => {
                if key.size == 'X' {
                    address.as_bit().map_err(|e| e.to_string())?;
                    return Ok(Direct { address, bits });
                }
                address.as_word().map_err(|e| e.to_string())?;
                let words = (bits / 16).max(1);
                if address.number + words > address.area.word_count() {
                    return Err(format!(
                        "`{address}` and the {} word(s) after it hold `{key}`: past the end of {:?} ({})",
                        words - 1,
                        address.area,
                        address.area.range_text()
                    ));
                }
                Ok(Direct { address, bits })
            }
        }
    }

    /// The size of `image`: bytes for a byte image, elements for a word image.
    fn units(&self, image: Image) -> u32 {
        self.bytes.get(image.index()).copied().unwrap_or(image.default_units())
    }

    /// The device words `image` takes (the last one half used by an odd count of bytes).
    pub fn words(&self, image: Image) -> u32 {
        if image.byte_image() {
            self.units(image).div_ceil(2)
        } else {
            self.units(image) * image.unit_words()
        }
    }

    /// The first and the last device word of `image`.
    pub fn span(&self, image: Image) -> (Address, Address) {
        let start = self.start(image);
        (start.at(0), start.at(self.words(image) - 1))
    }

    /// What is wrong with the layout, by image: one that runs past the end of its device area,
    /// two that overlap. The images the preset has no use for are not checked.
    pub fn problems(&self) -> Vec<(Image, String)> {
        let mut out = Vec::new();
        let images = self.preset.images();
        for (k, &image) in images.iter().enumerate() {
            let start = self.start(image);
            let (first, _) = self.span(image);
            if start.word + self.words(image) > start.area.word_count() {
                out.push((
                    image,
                    format!(
                        "the {} image needs {} words from `{first}`: past the end of {:?} ({})",
                        image.prefix(self.preset),
                        self.words(image),
                        start.area,
                        start.area.range_text()
                    ),
                ));
                continue;
            }
            for &other in &images[..k] {
                let o = self.start(other);
                let overlap = o.area == start.area
                    && start.word < o.word + self.words(other)
                    && o.word < start.word + self.words(image);
                if overlap {
                    let (a, b) = self.span(other);
                    out.push((
                        image,
                        format!(
                            "the {} image (`{first}`, {} words) overlaps the {} image (`{a}` to `{b}`, `iec.{}`)",
                            image.prefix(self.preset),
                            self.words(image),
                            other.prefix(self.preset),
                            other.key()
                        ),
                    ));
                }
            }
        }
        out
    }

    /// The layout in words, one line per image, for `plcd check`: `%IX0.0..%IX127.7 →
    /// P0000..P063F`.
    pub fn describe(&self) -> Vec<String> {
        let preset = self.preset;
        if preset == Preset::Plcd {
            return vec![
                "%IXa.b, %QXa.b → bit b (0..15) of P word a; %IWa, %QWa → P word a".to_string(),
                "%MXa.b → bit b of M word a; %MWa, %MDa, %MLa → M word a".to_string(),
            ];
        }
        preset
            .images()
            .iter()
            .map(|&image| {
                let (first, last) = self.span(image);
                let p = image.prefix(preset);
                let n = self.units(image) - 1;
                let what = match (image.byte_image(), preset) {
                    (true, Preset::Codesys) => {
                        let bytes = self.units(image);
                        format!(
                            "{p}X0.0..{p}X{n}.7, {p}B0..{p}B{n}, {p}W0..{p}W{}, {p}D0..{p}D{}, {p}L0..{p}L{}",
                            bytes / 2 - 1,
                            bytes / 4 - 1,
                            bytes / 8 - 1
                        )
                    }
                    (true, _) if image.bit_image() => format!("{p}0.0..{p}{n}.7"),
                    _ => format!("{p}0..{p}{n}"),
                };
                format!("{what} → {first}..{last} (iec.{})", image.key())
            })
            .collect()
    }

    /// The device an IEC direct address names (`text` is what follows the `%`: `IX0.3`,
    /// `QW5`), `Ok(None)` for a text that is no IEC address (a plcd device, `P0040`), or why
    /// the address is none of this layout's.
    pub fn resolve(&self, text: &str) -> Result<Option<Direct>, String> {
        let upper = text.to_ascii_uppercase();
        let mut chars = upper.chars();
        let Some(letter @ ('I' | 'Q' | 'M')) = chars.next() else { return Ok(None) };
        let rest = chars.as_str();
        // No size prefix is a bit (IEC 61131-3, "Directly represented variables": `%I0.0` is
        // `%IX0.0`). plcd has no device I or Q; an `M` without a size is plcd's M device
        // (`%M0003`) unless it has the bit level, which plcd's addresses never have (`%M1.2`).
        let bare =
            rest.starts_with(|c: char| c.is_ascii_digit()) && (letter != 'M' || rest.contains('.'));
        let size = if bare { 'X' } else { chars.next().unwrap_or(' ') };
        if !matches!(size, 'X' | 'B' | 'W' | 'D' | 'L') {
            return Ok(None);
        }
        let digits = chars.as_str();
        if !digits.starts_with(|c: char| c.is_ascii_digit()) {
            return Ok(None);
        }
        let bits = match size {
            'X' => 1,
            'B' => 8,
            'W' => 16,
            'D' => 32,
            _ => 64,
        };
        let bad = || format!("`%{text}` is not a valid direct address");
        // a bit has two levels, byte and bit; any other size one
        let levels = digits.split('.').count();
        let most = if bits == 1 { 2 } else { 1 };
        if levels > most {
            if let Some(key) = MultiLevel::of(text) {
                return match self.placed.iter().find(|(k, _)| *k == key) {
                    Some(&(_, direct)) => Ok(Some(direct)),
                    None => Err(multi_level(text, letter, size, levels)),
                };
            }
        }
        let number = |s: &str| s.parse::<u32>().map_err(|_| bad());
        let (index, bit) = if bits == 1 {
            match digits.split_once('.') {
                Some((i, b)) => (number(i)?, Some(number(b)?)),
                // one level (IEC 61131-3 allows it, `%IX1`): the bits counted on from bit 0 of
                // the first byte (of the first P word in plcd's numbering), `%IX9` = `%IX1.1`
                None => {
                    let per = if self.preset == Preset::Plcd { 16 } else { 8 };
                    let n = number(digits)?;
                    (n / per, Some(n % per))
                }
            }
        } else {
            (number(digits)?, None)
        };
        if self.preset == Preset::Plcd {
            return plcd_address(text, letter, bits, index, bit).map(Some);
        }
        let preset = self.preset.name();
        let image = match (self.preset, letter, size) {
            (Preset::Codesys, 'I', _) | (Preset::OpenPlc, 'I', 'X') => Image::Input,
            (Preset::Codesys, 'Q', _) | (Preset::OpenPlc, 'Q', 'X') => Image::Output,
            (Preset::Codesys, 'M', _) | (Preset::OpenPlc, 'M', 'X') => Image::Memory,
            (_, 'I', 'W') => Image::InputWords,
            (_, 'Q', 'W') => Image::OutputWords,
            (_, 'M', 'W') => Image::MemoryWords,
            (_, 'M', 'D') => Image::MemoryDwords,
            (_, 'M', 'L') => Image::MemoryLwords,
            (_, 'I', 'B') => Image::InputBytes,
            (_, 'Q', 'B') => Image::OutputBytes,
            _ => {
                return Err(format!(
                    "`%{text}`: the openplc layout has no `%{letter}{size}` (OpenPLC's inputs are %IX bits, %IB bytes and %IW words, its outputs %QX, %QB and %QW; `[iec] preset = \"codesys\"` has every size)"
                ))
            }
        };
        let start = self.start(image);
        let p = image.prefix(self.preset);
        let past_end = |what: String| {
            let (first, last) = self.span(image);
            format!(
                "`%{text}` is past the end of the {p} image: the {preset} layout's {what} (`{first}` to `{last}`; `[iec] {}` moves it)",
                image.key()
            )
        };
        if image.byte_image() {
            let bytes = self.units(image);
            let last = bytes - 1;
            match size {
                'X' => {
                    let bit = bit.unwrap_or(0);
                    if bit > 7 {
                        return Err(format!(
                            "`%{text}`: bit {bit} of a byte: the {preset} layout numbers %{letter}X by byte and bit, the bit 0 to 7 (`%{letter}X{}.0` is the bit after `%{letter}X{index}.7`; `[iec] preset = \"plcd\"` numbers P words and their bits 0 to 15)",
                            index + 1
                        ));
                    }
                    if index >= bytes {
                        return Err(past_end(format!("%{letter}X bytes are 0 to {last}")));
                    }
                    let address =
                        Address { bit: Some((index % 2 * 8 + bit) as u8), ..start.at(index / 2) };
                    Ok(Some(Direct { address, bits }))
                }
                'B' => {
                    if index >= bytes {
                        return Err(past_end(format!("%{letter}B are 0 to {last}")));
                    }
                    // the byte's first bit: the low or the high half of its word
                    let address =
                        Address { bit: Some((index % 2 * 8) as u8), ..start.at(index / 2) };
                    Ok(Some(Direct { address, bits }))
                }
                _ => {
                    let words = bits / 16;
                    if u64::from(index) * u64::from(words) + u64::from(words) > u64::from(bytes / 2)
                    {
                        let n = bytes / 2 / words - 1;
                        return Err(past_end(format!("%{letter}{size} are 0 to {n}")));
                    }
                    Ok(Some(Direct { address: start.at(index * words), bits }))
                }
            }
        } else {
            if index >= self.units(image) {
                return Err(past_end(format!("{p} are 0 to {}", self.units(image) - 1)));
            }
            Ok(Some(Direct { address: start.at(index * image.unit_words()), bits }))
        }
    }
}

/// Why a multi-level address (`%IX1.2.3`, `%QW2.1`) the config does not place is refused:
/// Beremiz numbers the I/O of its extensions so, the extension's channel path (`IEC_Channel`
/// of each node of its tree) then the extension's own items, and what it names is that
/// extension's runtime code, which plcd does not have; `[iec.addresses]` says where it is
/// (docs/ST.md, "Direct addresses").
fn multi_level(text: &str, letter: char, size: char, levels: usize) -> String {
    format!(
        "`%{text}` is a multi-level address ({levels} levels), as Beremiz numbers an extension's I/O (its channel, then the extension's own items), and the config does not place it: add `\"%{text}\" = \"…\"` to `[iec.addresses]` in the config, an address of the [iec] layout or a device of P, M, K or D (docs/CONFIG.md), or declare the variable `AT %{letter}{size}*` and bind it with VAR_CONFIG or `[iec.variables]`"
    )
}

/// What a full address the config writes names ([`IecLayout::full`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Full {
    /// An address of the layout: its device and size.
    Iec(Direct),
    /// A plcd device of P, M, K or D (`P0040`, `D00100`), which means itself.
    Device(Address),
}

/// A multi-level address (`%IX100.0.0`, `%QW2.1`): an area letter, a size letter and more
/// numbers than an address of a layout has (two for `X`, byte and bit; one for the other
/// sizes), as Beremiz numbers the I/O of its extensions. Two are the same address when their
/// letters and numbers are (`%ix100.00.0` is `%IX100.0.0`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MultiLevel {
    /// `I`, `Q` or `M`.
    pub letter: char,
    /// `X`, `B`, `W`, `D` or `L`.
    pub size: char,
    pub levels: Vec<u32>,
}

impl MultiLevel {
    /// The multi-level address `text` (what follows the `%`, any case) is; `None` for any other
    /// text, an address of a layout's own (`IX0.1`) or a device (`P0040`) among them.
    pub fn of(text: &str) -> Option<MultiLevel> {
        let upper = text.to_ascii_uppercase();
        let mut chars = upper.chars();
        let letter @ ('I' | 'Q' | 'M') = chars.next()? else { return None };
        let size @ ('X' | 'B' | 'W' | 'D' | 'L') = chars.next()? else { return None };
        let levels = chars
            .as_str()
            .split('.')
            .map(|n| n.bytes().all(|b| b.is_ascii_digit()).then(|| n.parse::<u32>().ok()).flatten())
            .collect::<Option<Vec<u32>>>()?;
        let most = if size == 'X' { 2 } else { 1 };
        (levels.len() > most).then_some(MultiLevel { letter, size, levels })
    }

    /// [`MultiLevel::of`] for a key of `[iec.addresses]` (with or without its `%`), or why it
    /// is none.
    pub fn parse(text: &str) -> Result<MultiLevel, String> {
        let bare = text.strip_prefix('%').unwrap_or(text);
        MultiLevel::of(bare).ok_or_else(|| {
            format!(
                "`%{bare}` is not a multi-level address: an area letter (I, Q, M), a size letter (X, B, W, D, L), then numbers joined by dots, more than an address of the [iec] layout has (`%IX100.0.0`, `%IW100.0.1`, `%QW2.1`)"
            )
        })
    }

    /// The bits its size letter says: 1, 8, 16, 32 or 64.
    pub fn bits(&self) -> u32 {
        match self.size {
            'X' => 1,
            'B' => 8,
            'W' => 16,
            'D' => 32,
            _ => 64,
        }
    }
}

impl std::fmt::Display for MultiLevel {
    /// As the config and `plcd check` write it: `%IX100.0.0`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let levels: Vec<String> = self.levels.iter().map(u32::to_string).collect();
        write!(f, "%{}{}{}", self.letter, self.size, levels.join("."))
    }
}

/// plcd's own numbering (`[iec] preset = "plcd"`): `%IXa.b` and `%QXa.b` bit `b` (0..15) of P
/// word `a`, `%IWa` and `%QWa` (and the other sizes) P word `a`, `%M…` the same in M.
fn plcd_address(
    text: &str,
    letter: char,
    bits: u32,
    index: u32,
    bit: Option<u32>,
) -> Result<Direct, String> {
    let bad = || format!("`%{text}` is not a valid direct address");
    let area = if letter == 'M' { Area::M } else { Area::P };
    if index > 999 || bit.is_some_and(|b| b > 15) {
        return Err(bad());
    }
    // the range of the word (P000..P127) is Address::parse's to check, as for `%P` addresses
    let device = match bit {
        Some(b) => format!("{area:?}{index:03}{b:X}"),
        None => format!("{area:?}{index:03}"),
    };
    let address = Address::parse(&device).map_err(|e| e.to_string())?;
    Ok(Direct { address, bits })
}

/// The article of a size in bits, for messages: "an 8-bit location", "a 16-bit location".
pub fn sized(bits: u32) -> &'static str {
    if bits == 8 {
        "an"
    } else {
        "a"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn device(layout: &IecLayout, text: &str) -> String {
        match layout.resolve(text) {
            Ok(Some(d)) => format!("{} {}", d.address, d.bits),
            Ok(None) => "none".to_string(),
            Err(e) => format!("error: {e}"),
        }
    }

    #[test]
    fn openplc_bits_are_bytes_and_bits_with_inputs_and_outputs_apart() {
        let l = IecLayout::of(Preset::OpenPlc);
        assert_eq!(device(&l, "IX0.0"), "P0000 1");
        assert_eq!(device(&l, "QX0.0"), "P0640 1");
        assert_eq!(device(&l, "IX0.7"), "P0007 1");
        assert_eq!(device(&l, "IX1.0"), "P0008 1");
        assert_eq!(device(&l, "IX2.3"), "P0013 1");
        assert_eq!(device(&l, "ix127.7"), "P063F 1");
        assert_eq!(device(&l, "MX3.1"), "M0019 1");
    }

    #[test]
    fn a_bit_of_one_level_counts_bits_from_the_first() {
        let l = IecLayout::of(Preset::OpenPlc);
        assert_eq!(device(&l, "IX1"), device(&l, "IX0.1"));
        assert_eq!(device(&l, "QX9"), device(&l, "QX1.1"));
        assert_eq!(device(&l, "MX0"), device(&l, "MX0.0"));
        let p = IecLayout::of(Preset::Plcd);
        assert_eq!(device(&p, "IX17"), device(&p, "IX1.1"));
    }

    #[test]
    fn openplc_words_are_areas_of_their_own() {
        let l = IecLayout::of(Preset::OpenPlc);
        assert_eq!(device(&l, "IW0"), "D10000 16");
        assert_eq!(device(&l, "QW5"), "D12005 16");
        assert_eq!(device(&l, "MW1023"), "D15023 16");
        assert_eq!(device(&l, "MD5"), "D16010 32");
        assert_eq!(device(&l, "ML5"), "D20020 64");
        assert!(device(&l, "MW1024").contains("past the end of the %MW image"));
        assert!(device(&l, "ID0").contains("openplc layout has no `%ID`"));
    }

    #[test]
    fn bytes_are_halves_of_words() {
        // openplc: %IB and %QB are areas of their own (OpenPLC's byte_input, byte_output),
        // from D11024 and D13024, two bytes a word; a byte is its first bit, 8 bits, shown as
        // the word's half
        let l = IecLayout::of(Preset::OpenPlc);
        assert_eq!(device(&l, "IB0"), "D11024.0 8");
        assert_eq!(device(&l, "IB1"), "D11024.8 8");
        assert_eq!(device(&l, "QB3"), "D13025.8 8");
        assert_eq!(device(&l, "QB1023"), "D13535.8 8");
        assert!(device(&l, "QB1024").contains("%QB are 0 to 1023"));
        assert!(device(&l, "MB0").contains("openplc layout has no `%MB`"));
        let direct = |text| l.resolve(text).unwrap().unwrap();
        assert_eq!(direct("QB3").to_string(), "D13025 (high byte)");
        assert_eq!(direct("IB0").to_string(), "D11024 (low byte)");
        assert!(direct("QB3").is_byte());
        assert!(!direct("QX1.0").is_byte());
        assert_eq!(direct("QX1.0").to_string(), "P0648");
        assert!(l.problems().is_empty(), "{:?}", l.problems());
        // codesys: the same bytes %IX and %IW view
        let l = IecLayout::of(Preset::Codesys);
        assert_eq!(device(&l, "IB1"), "P0008 8");
        assert_eq!(device(&l, "QB1"), "P0648 8");
        assert_eq!(l.resolve("QB2").unwrap().unwrap().to_string(), "P065 (low byte)");
        assert_eq!(device(&l, "MB511"), "M2558 8");
        assert!(device(&l, "MB512").contains("%MB are 0 to 511"));
        // plcd: a B address is a word, as every size
        assert_eq!(device(&IecLayout::of(Preset::Plcd), "QB3"), "P003 8");
    }

    #[test]
    fn codesys_sizes_are_views_of_one_byte_image() {
        let l = IecLayout::of(Preset::Codesys);
        assert_eq!(device(&l, "IX0.0"), "P0000 1");
        assert_eq!(device(&l, "IX1.0"), "P0008 1");
        assert_eq!(device(&l, "IW0"), "P000 16");
        assert_eq!(device(&l, "IW1"), "P001 16");
        assert_eq!(device(&l, "ID1"), "P002 32");
        assert_eq!(device(&l, "IL1"), "P004 64");
        assert_eq!(device(&l, "QW0"), "P064 16");
        assert_eq!(device(&l, "MD10"), "M020 32");
        assert_eq!(device(&l, "IW63"), "P063 16");
        assert!(device(&l, "IW64").contains("%IW are 0 to 63"));
        assert!(device(&l, "IL16").contains("%IL are 0 to 15"));
        assert!(device(&l, "IX128.0").contains("%IX bytes are 0 to 127"));
    }

    #[test]
    fn byte_images_refuse_bit_eight() {
        for preset in [Preset::OpenPlc, Preset::Codesys] {
            let e = device(&IecLayout::of(preset), "QX0.8");
            assert!(e.contains("bit 8 of a byte"), "{e}");
            assert!(e.contains("`%QX1.0` is the bit after `%QX0.7`"), "{e}");
        }
    }

    #[test]
    fn multi_level_addresses_are_refused_in_every_layout() {
        for preset in Preset::ALL {
            let l = IecLayout::of(preset);
            for (text, levels) in [("IX1.2.3", 3), ("QW2.1", 2), ("IW0.0.4096.0", 4), ("MB1.0", 2)]
            {
                let e = device(&l, text);
                assert!(e.contains(&format!("is a multi-level address ({levels} levels)")), "{e}");
            }
            assert!(device(&l, "QX1.0").starts_with('P'), "{preset:?}");
            // not numbers at each level: no address at all
            assert!(device(&l, "IX1.a.3").contains("not a valid direct address"));
        }
        let e = device(&IecLayout::default(), "QW2.1");
        assert!(e.contains("`AT %QW*`"), "{e}");
    }

    #[test]
    fn an_unplaced_multi_level_address_names_the_key_to_add() {
        let e = device(&IecLayout::default(), "IX100.0.0");
        assert!(e.contains("add `\"%IX100.0.0\" = \"…\"` to `[iec.addresses]`"), "{e}");
    }

    #[test]
    fn multi_level_addresses_are_letters_then_more_levels_than_the_layouts() {
        let key = MultiLevel::parse("%ix100.00.0").unwrap();
        assert_eq!(key, MultiLevel { letter: 'I', size: 'X', levels: vec![100, 0, 0] });
        assert_eq!(key.to_string(), "%IX100.0.0");
        assert_eq!(key.bits(), 1);
        assert_eq!(MultiLevel::parse("QW2.1").unwrap().bits(), 16);
        assert_eq!(MultiLevel::parse("%ML0.0.4096.0").unwrap().levels, [0, 0, 4096, 0]);
        for text in ["%IX4.0", "%IW3", "%IX100.a.0", "%I100.0.0", "%P0040", "%IX1..0", "", "%"] {
            let e = MultiLevel::parse(text).unwrap_err();
            assert!(e.contains("is not a multi-level address"), "{text}: {e}");
        }
    }

    #[test]
    fn placed_multi_level_addresses_resolve_to_their_device() {
        let l = IecLayout::default();
        let key = |t| MultiLevel::parse(t).unwrap();
        // an address of the layout of the key's size, or a device that fits it
        let bit = l.place(&key("%IX100.0.0"), "%IX4.0").unwrap();
        assert_eq!(bit.address.to_string(), "P0020");
        let word = l.place(&key("%IW100.0.1"), "D00100").unwrap();
        assert_eq!((word.address.to_string(), word.bits), ("D00100".to_string(), 16));
        let dword = l.place(&key("%QD2.1"), "%D32766").unwrap();
        assert_eq!(dword.bits, 32);
        let byte = l.place(&key("%QB2.1.0"), "%QB3").unwrap();
        assert!(byte.is_byte());
        let l = l
            .with_placed(key("%IX100.0.0"), bit)
            .with_placed(key("%IW100.0.1"), word)
            .with_placed(key("%QB2.1.0"), byte);
        assert_eq!(device(&l, "ix100.0.0"), "P0020 1");
        assert_eq!(device(&l, "IW100.0.01"), "D00100 16");
        assert_eq!(l.resolve("QB2.1.0").unwrap().unwrap().to_string(), "D13025 (high byte)");
        assert!(device(&l, "IX100.0.1").contains("is a multi-level address (3 levels)"));
        assert_eq!(l.placed().len(), 3);
        // each way a target does not fit
        let e = |k, t| l.place(&key(k), t).unwrap_err();
        assert!(e("%IX1.2.3", "%IX100.0.0").contains("is itself a multi-level address"));
        assert!(
            e("%IX1.2.3", "%IW4").contains("`%IW4` is a 16-bit location, `%IX1.2.3` a 1-bit one")
        );
        assert!(e("%IX1.2.3", "%D00100").contains("is a word device, a bit is needed here"));
        assert!(e("%IW1.2", "%P0040").contains("is a bit device, a word is needed here"));
        assert!(e("%IW1.2", "%T0001").contains("is not a device of P, M, K or D"));
        assert!(e("%IW1.2", "%IX*").contains("is not a device address"));
        assert!(e("%ML1.2", "%D32766").contains("past the end of D"));
        assert!(e("%IX1.2.3", "%IX200.0").contains("past the end of the %IX image"));
    }

    #[test]
    fn plcd_keeps_words_and_bits_0_to_15() {
        let l = IecLayout::of(Preset::Plcd);
        assert_eq!(device(&l, "IX0.3"), "P0003 1");
        assert_eq!(device(&l, "QX12.15"), "P012F 1");
        assert_eq!(device(&l, "IW5"), "P005 16");
        assert_eq!(device(&l, "MD10"), "M010 32");
        assert!(device(&l, "IX0.16").starts_with("error"));
    }

    #[test]
    fn plcd_devices_are_no_iec_address() {
        for preset in Preset::ALL {
            let l = IecLayout::of(preset);
            for text in ["D00100", "M0010", "P0040", "MX", "IXA.0", "_ON"] {
                assert_eq!(device(&l, text), "none", "{preset:?} {text}");
            }
        }
    }

    #[test]
    fn moved_images_follow_their_start() {
        let l = IecLayout::of(Preset::OpenPlc)
            .with_start(Image::Output, Start::parse("P100").unwrap())
            .with_start(Image::InputWords, Start::parse("D00000").unwrap());
        // byte 3 is the high byte of the second word: P101, bit 8 + 2
        assert_eq!(device(&l, "QX3.2"), "P101A 1");
        assert_eq!(device(&l, "IW7"), "D00007 16");
        // the %QX image now runs past P127
        let problems = l.problems();
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert_eq!(problems[0].0, Image::Output);
        assert!(problems[0].1.contains("past the end of P"), "{}", problems[0].1);
    }

    #[test]
    fn byte_images_take_the_bytes_given() {
        // eight bytes of %IX (P000..P003), %QX from P004: plcd's habit of outputs at P0040
        let l = IecLayout::of(Preset::OpenPlc)
            .with_bytes(Image::Input, 8)
            .with_start(Image::Output, Start::parse("P004").unwrap());
        assert!(l.problems().is_empty(), "{:?}", l.problems());
        assert_eq!(device(&l, "IX7.7"), "P003F 1");
        assert!(device(&l, "IX8.0").contains("%IX bytes are 0 to 7"));
        assert_eq!(device(&l, "QX0.0"), "P0040 1");
        // an odd count of bytes: the last word half used, a word there refused
        let l = IecLayout::of(Preset::Codesys).with_bytes(Image::Input, 5);
        assert_eq!(l.span(Image::Input).1.to_string(), "P002");
        assert_eq!(device(&l, "IX4.7"), "P0027 1");
        assert!(device(&l, "IW2").contains("%IW are 0 to 1"));
    }

    #[test]
    fn overlapping_images_are_a_problem() {
        let l =
            IecLayout::of(Preset::Codesys).with_start(Image::Output, Start::parse("P032").unwrap());
        let problems = l.problems();
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert!(problems[0].1.contains("overlaps the %I image"), "{}", problems[0].1);
        assert!(IecLayout::of(Preset::OpenPlc).problems().is_empty());
        assert!(IecLayout::of(Preset::Codesys).problems().is_empty());
    }

    #[test]
    fn starts_are_words_of_p_m_k_or_d() {
        assert_eq!(Start::parse("D10000"), Ok(Start { area: Area::D, word: 10000 }));
        assert!(Start::parse("P0040").is_err());
        assert!(Start::parse("T0005").is_err());
        assert!(Start::parse("P200").is_err());
    }
}

//! The generation file, and which of the two generations wins at start. Pure: bytes in,
//! values out.
//!
//! All integers little-endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `PLCDRTN\0` |
//! | 8 | 2 | format version, 4 (versions 1 to 3 are read too) |
//! | 10 | 2 | n: the number of word ranges |
//! | 12 | 4 | w: the number of payload words |
//! | 16 | 8 | sequence number, one more for every write, across restarts |
//! | 24 | 8 | when the snapshot was taken, ms since the Unix epoch (for the log only) |
//! | 32 | 4 | words of device memory in the build that wrote it (the device layout) |
//! | 36 | 4 | v: bytes of the variables section (version 1: reserved, 0, and no section) |
//! | 40 | 6·n | the ranges: first word index, word count, bit mask (u16 each) |
//! | 40+6n | 2·w | the payload: the words of every range, range after range |
//! | 40+6n+2w | v | the variables section: the retained Structured Text variables |
//! | end−4 | 4 | CRC-32C (Castagnoli) of every byte before it |
//!
//! The variables section: a u32 count, then for each variable its name, its type text and its
//! bytes, each a u32 length followed by that many bytes (the name and the type in UTF-8). A
//! variable is a leaf or, since version 4, a whole array: `main.buf`, `ARRAY[1..3] OF INT`, its
//! elements' bytes one after the other; an array of structs or FB instances states its
//! element's retained leaves and their positions: `ARRAY[0..1] OF {.x@0:INT;.on@2:BOOL;@3}`
//! ([`crate::vm::retained`], docs/RETAIN.md "The file"). An array's type text must account for
//! exactly its bytes, or the section is malformed.
//!
//! Version 3 wrote an array element by element (`main.buf[3]`, restored into the element
//! since). Version 3 stores a `STRING`'s bytes as the VM does since: its characters, then NULs.
//! A version 2 file stored a length byte, then the characters; they are read and converted.
//!
//! The ranges are the layout: a file is restored only if they and the device layout equal the
//! configured ones exactly. Variables are restored by name and type
//! ([`crate::vm::retained::RetainedVariables::plan_restore`]).

use crate::device::layout;
use crate::device::retained::{difference, RetainedWords};
use crate::vm::retained::{well_formed, RetainedVariables, SavedVariable};

pub const MAGIC: [u8; 8] = *b"PLCDRTN\0";
/// The version this build writes: arrays as one record each.
pub const VERSION: u16 = 4;
/// The version that wrote an array element by element, still read (into the arrays).
pub const VERSION_3: u16 = 3;
/// The first version, without variables, still read.
pub const VERSION_1: u16 = 1;
/// The version whose `STRING`s had a length byte first, still read (and converted).
pub const VERSION_2: u16 = 2;
pub const HEADER: usize = 40;
const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);

/// A decoded generation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Generation {
    pub seq: u64,
    pub written_unix_ms: u64,
    /// Words of device memory of the build that wrote it.
    pub device_words: u32,
    pub ranges: Vec<RetainedWords>,
    pub words: Vec<u16>,
    /// The format version of the file.
    pub version: u16,
    /// The retained Structured Text variables (none in a version 1 file), in the order written.
    pub variables: Vec<SavedVariable>,
}

/// Why bytes are not a generation.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    #[error("truncated: {0} bytes, shorter than a header")]
    TooShort(usize),
    #[error("not a retain file (bad magic)")]
    Magic,
    #[error("format version {0}, this build reads versions {VERSION_1} to {VERSION}")]
    Version(u16),
    #[error("{len} bytes where the header announces {expected} (truncated or extended)")]
    Length { len: usize, expected: usize },
    #[error("CRC mismatch: stored {stored:08x}, computed {computed:08x}")]
    Crc { stored: u32, computed: u32 },
    #[error("the ranges hold {ranges} words, the payload {words}")]
    Inconsistent { ranges: usize, words: usize },
    #[error("the variables section is malformed at byte {0} of it")]
    Variables(usize),
    #[error("a range of {len} words from word {start} goes past the end of device memory")]
    RangePastEnd { start: u16, len: u16 },
    #[error("sequence number {0}: the last there is, which no write reaches")]
    LastSequence(u64),
}

/// The variables section of a file holding `variables` (name, type text, bytes each), into
/// `out`, which is grown once to the section's size (a 16 MB array is not copied into 32 MB of
/// doublings).
pub fn encode_variables<'v>(
    variables: impl ExactSizeIterator<Item = (&'v str, &'v str, &'v [u8])> + Clone,
    out: &mut Vec<u8>,
) {
    out.clear();
    let size = variables.clone().map(|(n, t, b)| 12 + n.len() + t.len() + b.len()).sum::<usize>();
    out.reserve(4 + size);
    out.extend_from_slice(&(variables.len() as u32).to_le_bytes());
    for (name, ty, bytes) in variables {
        for field in [name.as_bytes(), ty.as_bytes(), bytes] {
            out.extend_from_slice(&(field.len() as u32).to_le_bytes());
            out.extend_from_slice(field);
        }
    }
}

/// The variables section of `layout`'s records, their bytes taken from `copy` (as
/// [`RetainedVariables::copy`] made it), into `out`.
pub fn encode_records(layout: &RetainedVariables, copy: &[u8], out: &mut Vec<u8>) {
    let records = layout.records().iter();
    let records = records.map(|r| (r.name.as_str(), r.ty.as_str(), layout.record_in(r, copy)));
    encode_variables(records, out)
}

/// The variables section of saved variables (what a file held), into `out`.
pub fn encode_saved(saved: &[SavedVariable], out: &mut Vec<u8>) {
    let saved = saved.iter();
    encode_variables(saved.map(|v| (v.name.as_str(), v.ty.as_str(), &v.bytes[..])), out)
}

/// The bytes of a file holding `words` (of `ranges`, as [`super::RetainSet::capture`] made
/// them) and the variables section `variables` (as [`encode_variables`] made it), into `out`.
pub fn encode(
    seq: u64,
    written_unix_ms: u64,
    ranges: &[RetainedWords],
    words: &[u16],
    variables: &[u8],
    out: &mut Vec<u8>,
) {
    out.clear();
    out.reserve(HEADER + 6 * ranges.len() + 2 * words.len() + variables.len() + 4);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(ranges.len() as u16).to_le_bytes());
    out.extend_from_slice(&(words.len() as u32).to_le_bytes());
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&written_unix_ms.to_le_bytes());
    out.extend_from_slice(&layout::TOTAL_WORDS.to_le_bytes());
    out.extend_from_slice(&(variables.len() as u32).to_le_bytes());
    for r in ranges {
        for v in [r.start, r.end - r.start, r.mask] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for w in words {
        out.extend_from_slice(&w.to_le_bytes());
    }
    out.extend_from_slice(variables);
    let crc = CRC.checksum(out);
    out.extend_from_slice(&crc.to_le_bytes());
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// Decodes and checks a file's bytes (not its layout: see [`layout_difference`]).
pub fn decode(bytes: &[u8]) -> Result<Generation, DecodeError> {
    if bytes.len() < HEADER + 4 {
        return Err(DecodeError::TooShort(bytes.len()));
    }
    if bytes[..8] != MAGIC {
        return Err(DecodeError::Magic);
    }
    let version = u16_at(bytes, 8);
    if ![VERSION, VERSION_1, VERSION_2, VERSION_3].contains(&version) {
        return Err(DecodeError::Version(version));
    }
    let n = usize::from(u16_at(bytes, 10));
    let w = u32_at(bytes, 12) as usize;
    let v = if version == VERSION_1 { 0 } else { u32_at(bytes, 36) as usize };
    let expected = HEADER + 6 * n + 2 * w + v + 4;
    if bytes.len() != expected {
        return Err(DecodeError::Length { len: bytes.len(), expected });
    }
    let body = &bytes[..bytes.len() - 4];
    let stored = u32_at(bytes, body.len());
    let computed = CRC.checksum(body);
    if stored != computed {
        return Err(DecodeError::Crc { stored, computed });
    }
    // Past the CRC, what a writer of this format cannot have written is refused all the same
    // (a file made by hand, or a CRC that matched by chance): a range past the end of the
    // memory, a sequence number with none after it. Found writing the invariants of the fuzz
    // target `retain` (tests/fuzz).
    let seq = u64_at(bytes, 16);
    if seq == u64::MAX {
        return Err(DecodeError::LastSequence(seq));
    }
    let ranges = (0..n)
        .map(|i| {
            let at = HEADER + 6 * i;
            let (start, len) = (u16_at(bytes, at), u16_at(bytes, at + 2));
            let end = start.checked_add(len).ok_or(DecodeError::RangePastEnd { start, len })?;
            Ok(RetainedWords { start, end, mask: u16_at(bytes, at + 4) })
        })
        .collect::<Result<Vec<RetainedWords>, DecodeError>>()?;
    let in_ranges: usize = ranges.iter().map(RetainedWords::len).sum();
    if in_ranges != w {
        return Err(DecodeError::Inconsistent { ranges: in_ranges, words: w });
    }
    let payload = HEADER + 6 * n;
    let words = (0..w).map(|i| u16_at(bytes, payload + 2 * i)).collect();
    let section = payload + 2 * w;
    let mut variables = if version == VERSION_1 {
        Vec::new()
    } else {
        decode_variables(&bytes[section..section + v])?
    };
    if version == VERSION_2 {
        for var in variables.iter_mut().filter(|v| v.ty.starts_with("STRING")) {
            var.bytes = string_from_version_2(&var.bytes);
        }
    }
    Ok(Generation {
        seq,
        written_unix_ms: u64_at(bytes, 24),
        device_words: u32_at(bytes, 32),
        ranges,
        words,
        version,
        variables,
    })
}

/// A `STRING` as version 2 stored it (a length byte, then the characters) as version 3 stores
/// it (the characters, then NULs), in as many bytes.
fn string_from_version_2(bytes: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8; bytes.len()];
    if let Some((&len, chars)) = bytes.split_first() {
        let n = usize::from(len).min(chars.len());
        out[..n].copy_from_slice(&chars[..n]);
    }
    out
}

/// The variables of a variables section, checked: every length within the section, names and
/// types UTF-8, an array's type text accounting for its bytes, nothing left over.
pub fn decode_variables(section: &[u8]) -> Result<Vec<SavedVariable>, DecodeError> {
    let mut at = 0;
    let take = |at: &mut usize, len: usize| -> Result<&[u8], DecodeError> {
        let field = section.get(*at..at.checked_add(len).ok_or(DecodeError::Variables(*at))?);
        let field = field.ok_or(DecodeError::Variables(*at))?;
        *at += len;
        Ok(field)
    };
    let length = |at: &mut usize| -> Result<usize, DecodeError> {
        let b = take(at, 4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    let text = |at: &mut usize| -> Result<String, DecodeError> {
        let start = *at;
        let len = length(at)?;
        let b = take(at, len)?;
        String::from_utf8(b.to_vec()).map_err(|_| DecodeError::Variables(start))
    };
    let count = length(&mut at)?;
    // At least 12 bytes a variable: a count beyond that is garbage, not an allocation.
    if count > section.len() / 12 {
        return Err(DecodeError::Variables(0));
    }
    let mut variables = Vec::with_capacity(count);
    for _ in 0..count {
        let start = at;
        let name = text(&mut at)?;
        let ty = text(&mut at)?;
        let len = length(&mut at)?;
        if !well_formed(&ty, len) {
            return Err(DecodeError::Variables(start));
        }
        let bytes = take(&mut at, len)?.to_vec();
        variables.push(SavedVariable { name, ty, bytes });
    }
    if at != section.len() {
        return Err(DecodeError::Variables(at));
    }
    Ok(variables)
}

/// `None` if `generation` can be restored into the configured `ranges`; else what differs.
pub fn layout_difference(generation: &Generation, ranges: &[RetainedWords]) -> Option<String> {
    if generation.device_words != layout::TOTAL_WORDS {
        return Some(format!(
            "written for a device layout of {} words, this build has {}",
            generation.device_words,
            layout::TOTAL_WORDS
        ));
    }
    (generation.ranges != ranges).then(|| difference(&generation.ranges, ranges))
}

/// What one of the two generation files held at start.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Slot {
    Missing,
    Corrupt(DecodeError),
    Intact(Generation),
}

/// What to do with the two slots at start.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Choice {
    /// The slot to restore: the newest intact generation, if its layout matches.
    pub restore: Option<usize>,
    /// Intact slots written for other ranges, with what differs: to be set aside, never
    /// overwritten.
    pub mismatched: Vec<(usize, String)>,
    /// The slot the first write goes to (never the restored one).
    pub next_slot: usize,
    /// The sequence number of the first write: above every sequence number seen.
    pub next_seq: u64,
}

/// Which generation wins: the intact one with the highest sequence number (the first slot on a
/// tie). If that one was written for other ranges, nothing is restored: an older matching
/// generation would silently go back in time.
pub fn choose(slots: &[Slot; 2], ranges: &[RetainedWords]) -> Choice {
    let intact = |i: usize| match &slots[i] {
        Slot::Intact(g) => Some(g),
        _ => None,
    };
    let mut newest: Option<(usize, &Generation)> = None;
    for (i, g) in (0..2).filter_map(|i| intact(i).map(|g| (i, g))) {
        if newest.is_none_or(|(_, best)| g.seq > best.seq) {
            newest = Some((i, g));
        }
    }
    let mismatched: Vec<(usize, String)> = (0..2)
        .filter_map(|i| intact(i).and_then(|g| layout_difference(g, ranges)).map(|d| (i, d)))
        .collect();
    let restore = newest.map(|(i, _)| i).filter(|i| !mismatched.iter().any(|(m, _)| m == i));
    let next_seq = newest.map_or(1, |(_, g)| g.seq + 1);
    let next_slot = match restore {
        Some(i) => 1 - i,
        // A slot that holds no intact matching generation (a set-aside one is renamed away).
        None => (0..2)
            .find(|&i| intact(i).is_none() || mismatched.iter().any(|(m, _)| *m == i))
            .unwrap_or(0),
    };
    Choice { restore, mismatched, next_slot, next_seq }
}

#[cfg(test)]
mod tests {
    use super::*;

    const K: RetainedWords = RetainedWords { start: 384, end: 386, mask: 0xFFFF };

    fn file(seq: u64, words: &[u16]) -> Vec<u8> {
        file_with(seq, words, &[])
    }

    fn file_with(seq: u64, words: &[u16], variables: &[SavedVariable]) -> Vec<u8> {
        let mut out = Vec::new();
        let ranges =
            [RetainedWords { start: K.start, end: K.start + words.len() as u16, mask: !0 }];
        let mut section = Vec::new();
        encode_saved(variables, &mut section);
        encode(seq, 1_700_000_000_000, &ranges, words, &section, &mut out);
        out
    }

    /// [`file_with`] labelled an earlier `version`, its CRC made again: the layout of versions
    /// 2 and 3, which differ from this build's in how a record's bytes are read.
    fn file_of_version(version: u8, variables: &[SavedVariable]) -> Vec<u8> {
        let mut bytes = file_with(5, &[9], variables);
        bytes[8] = version;
        let body = bytes.len() - 4;
        let crc = CRC.checksum(&bytes[..body]);
        bytes[body..].copy_from_slice(&crc.to_le_bytes());
        bytes
    }

    /// A version 1 file, as the builds before variables wrote it.
    fn version_1_file(seq: u64, words: &[u16]) -> Vec<u8> {
        let mut bytes = file(seq, words);
        bytes.truncate(bytes.len() - 8); // the CRC and the empty variables section
        bytes[8] = 1;
        bytes[36..40].copy_from_slice(&[0, 0, 0, 0]);
        let crc = CRC.checksum(&bytes);
        bytes.extend_from_slice(&crc.to_le_bytes());
        bytes
    }

    fn saved(name: &str, ty: &str, bytes: &[u8]) -> SavedVariable {
        SavedVariable { name: name.into(), ty: ty.into(), bytes: bytes.into() }
    }

    fn generation(seq: u64, words: &[u16]) -> Generation {
        decode(&file(seq, words)).unwrap()
    }

    /// A file with a correct CRC whose range goes past the end of device memory, or whose
    /// sequence number has none after it, is refused: one was read as a shorter range (and did
    /// not encode back to its bytes), the other made the next write's number wrap to 0, below
    /// the stale file's, for ever (an overflow panic in a debug build).
    #[test]
    fn what_no_writer_writes_is_refused_even_with_a_good_crc() {
        let with_crc = |mut body: Vec<u8>| {
            body.truncate(body.len() - 4);
            body.extend(CRC.checksum(&body).to_le_bytes());
            body
        };
        let mut past_end = file(5, &[1, 2]);
        past_end[40..42].copy_from_slice(&0xFFFFu16.to_le_bytes());
        let past_end = with_crc(past_end);
        assert_eq!(decode(&past_end), Err(DecodeError::RangePastEnd { start: 0xFFFF, len: 2 }));
        let last = file(u64::MAX, &[1, 2]);
        assert_eq!(decode(&last), Err(DecodeError::LastSequence(u64::MAX)));
        assert_eq!(decode(&file(u64::MAX - 1, &[1, 2])).map(|g| g.seq), Ok(u64::MAX - 1));
    }

    #[test]
    fn the_bytes_of_a_small_file() {
        let bytes = file_with(5, &[0x1234, 0xBEEF], &[saved("main.n", "INT", &[7, 0])]);
        let total = layout::TOTAL_WORDS.to_le_bytes();
        let mut expected: Vec<u8> = Vec::new();
        expected.extend(b"PLCDRTN\0");
        expected.extend([4, 0, 1, 0, 2, 0, 0, 0]);
        expected.extend([5, 0, 0, 0, 0, 0, 0, 0]);
        expected.extend(1_700_000_000_000u64.to_le_bytes());
        expected.extend(total);
        expected.extend([27, 0, 0, 0]);
        expected.extend([0x80, 0x01, 2, 0, 0xFF, 0xFF]);
        expected.extend([0x34, 0x12, 0xEF, 0xBE]);
        expected.extend([1, 0, 0, 0]);
        expected.extend([6, 0, 0, 0]);
        expected.extend(b"main.n");
        expected.extend([3, 0, 0, 0]);
        expected.extend(b"INT");
        expected.extend([2, 0, 0, 0, 7, 0]);
        assert_eq!(&bytes[..bytes.len() - 4], &expected[..]);
        assert_eq!(bytes.len(), HEADER + 6 + 4 + 27 + 4);
        let decoded = decode(&bytes).unwrap();
        assert_eq!((decoded.seq, &decoded.words[..]), (5, &[0x1234, 0xBEEF][..]));
        assert_eq!(decoded.ranges, [K]);
        assert_eq!(decoded.version, 4);
        assert_eq!(decoded.variables, [saved("main.n", "INT", &[7, 0])]);
        assert_eq!(layout_difference(&decoded, &[K]), None);
    }

    #[test]
    fn variables_round_trip() {
        let variables = [
            saved("main.count", "DINT", &[1, 2, 3, 4]),
            saved("main.s", "STRING[3]", &[b'a', b'b', 0, 0]),
            saved("Größe", "Color(Red:=0,Green:=1)", &[1, 0, 0, 0]),
            saved("main.empty", "STRING[0]", &[0]),
        ];
        let decoded = decode(&file_with(3, &[9], &variables)).unwrap();
        assert_eq!(decoded.variables, variables);
        assert_eq!(decoded.words, [9]);
        assert!(decode(&file(3, &[9])).unwrap().variables.is_empty());
    }

    #[test]
    fn a_version_2_files_strings_are_converted_to_characters_then_nuls() {
        let variables = [
            saved("main.s", "STRING[3]", &[2, b'a', b'b', 0]),
            saved("main.full", "STRING[2]", &[2, b'x', b'y']),
            saved("main.n", "INT", &[2, 0]),
        ];
        let decoded = decode(&file_of_version(2, &variables)).unwrap();
        assert_eq!(decoded.version, 2);
        let got: Vec<&[u8]> = decoded.variables.iter().map(|v| &v.bytes[..]).collect();
        assert_eq!(got, [&b"ab\0\0"[..], &b"xy\0"[..], &[2, 0][..]]);
    }

    #[test]
    fn a_version_1_file_restores_devices_and_no_variables() {
        let bytes = version_1_file(4, &[0x1234, 0xBEEF]);
        assert_eq!(bytes.len(), HEADER + 6 + 4 + 4, "the size of a version 1 file");
        let decoded = decode(&bytes).unwrap();
        assert_eq!(decoded.version, 1);
        assert_eq!((decoded.seq, &decoded.words[..]), (4, &[0x1234, 0xBEEF][..]));
        assert!(decoded.variables.is_empty());
        assert_eq!(layout_difference(&decoded, &[K]), None);
        for len in 0..bytes.len() {
            assert!(decode(&bytes[..len]).is_err(), "truncated at {len}");
        }
        for bit in 0..bytes.len() * 8 {
            let mut flipped = bytes.clone();
            flipped[bit / 8] ^= 1 << (bit % 8);
            assert!(decode(&flipped).is_err(), "bit {bit} flipped went unnoticed");
        }
    }

    #[test]
    fn a_malformed_variables_section_is_rejected_even_with_its_crc() {
        let good = file_with(1, &[1], &[saved("main.n", "INT", &[7, 0])]);
        let section = HEADER + 6 + 2;
        let with_crc = |mut bytes: Vec<u8>| {
            let len = bytes.len();
            let crc = CRC.checksum(&bytes[..len - 4]);
            bytes[len - 4..].copy_from_slice(&crc.to_le_bytes());
            bytes
        };
        // A name longer than the section.
        let mut bytes = good.clone();
        bytes[section + 4] = 200;
        assert_eq!(decode(&with_crc(bytes)), Err(DecodeError::Variables(8)));
        // A count of more variables than the section can hold.
        let mut bytes = good.clone();
        bytes[section] = 9;
        assert_eq!(decode(&with_crc(bytes)), Err(DecodeError::Variables(0)));
        // A name that is not UTF-8.
        let mut bytes = good.clone();
        bytes[section + 8] = 0xFF;
        assert_eq!(decode(&with_crc(bytes)), Err(DecodeError::Variables(4)));
        // Bytes left over after the last variable.
        let mut bytes = good.clone();
        bytes[section + 21] = 1; // the value's length 2 → 1
        assert_eq!(decode(&with_crc(bytes)), Err(DecodeError::Variables(26)));
        assert!(decode(&good).is_ok());
    }

    #[test]
    fn a_known_crc() {
        // CRC-32C check value of the catalogue: "123456789" → e3069283.
        assert_eq!(CRC.checksum(b"123456789"), 0xE306_9283);
    }

    /// A file with a leaf and an array of blocks, as version 4 writes them.
    fn with_an_array() -> Vec<u8> {
        let pts = saved("main.pts", "ARRAY[1..2] OF {.x@0:INT;.on@2:BOOL;@3}", &[1, 0, 1, 2, 0, 0]);
        file_with(9, &[1, 2], &[saved("main.n", "INT", &[7, 0]), pts])
    }

    /// `VAR RETAIN buf : ARRAY[1..3] OF INT; END_VAR` in `main`, byte for byte: one record,
    /// its elements' bytes whole; what docs/RETAIN.md shows.
    #[test]
    fn the_bytes_of_an_array_record() {
        let buf = saved("main.buf", "ARRAY[1..3] OF INT", &[1, 0, 2, 0, 0xFF, 0xFF]);
        let bytes = file_with(5, &[0x1234, 0xBEEF], std::slice::from_ref(&buf));
        let mut section: Vec<u8> = vec![1, 0, 0, 0, 8, 0, 0, 0];
        section.extend(b"main.buf");
        section.extend([18, 0, 0, 0]);
        section.extend(b"ARRAY[1..3] OF INT");
        section.extend([6, 0, 0, 0, 1, 0, 2, 0, 0xFF, 0xFF]);
        assert_eq!(section.len(), 48);
        assert_eq!(&bytes[36..40], &48u32.to_le_bytes());
        assert_eq!(&bytes[HEADER + 6 + 4..bytes.len() - 4], &section[..]);
        let decoded = decode(&bytes).unwrap();
        assert_eq!((decoded.version, &decoded.variables[..]), (4, &[buf][..]));
    }

    #[test]
    fn arrays_round_trip() {
        let variables = [
            saved("main.buf", "ARRAY[1..4] OF DINT", &[1; 16]),
            saved("main.m", "ARRAY[1..2,-1..0] OF ARRAY[1..2] OF INT", &[2; 16]),
            saved("main.pts", "ARRAY[0..1] OF {.x@0:INT;.m@2:ARRAY[1..2] OF BYTE;@4}", &[3; 8]),
            saved("main.n", "INT", &[7, 0]),
        ];
        let decoded = decode(&file_with(3, &[9], &variables)).unwrap();
        assert_eq!(decoded.variables, variables);
        assert!(decode(&with_an_array()).is_ok());
    }

    /// A version 3 file (an array element by element) is read as it was written; the restore
    /// puts each element record into its element (crate::vm::retained).
    #[test]
    fn a_version_3_file_is_still_read() {
        let variables =
            [saved("main.buf[1]", "DINT", &[1, 0, 0, 0]), saved("main.n", "INT", &[7, 0])];
        let decoded = decode(&file_of_version(3, &variables)).unwrap();
        assert_eq!((decoded.version, &decoded.variables[..]), (3, &variables[..]));
    }

    /// An array record whose type text does not account for its bytes is refused under a good
    /// CRC: no writer writes one.
    #[test]
    fn an_array_record_of_other_bytes_than_its_text_states_is_rejected() {
        for (ty, bytes) in [
            ("ARRAY[1..4] OF DINT", &[0u8; 15][..]),
            ("ARRAY[1..2] OF {.x@0:INT;@3}", &[0; 4][..]),
            ("ARRAY[1..2] OF {.x@1:INT;@2}", &[0; 4][..]),
            ("ARRAY[2..1] OF INT", &[][..]),
        ] {
            let file =
                file_with(1, &[1], &[saved("main.n", "INT", &[7, 0]), saved("main.a", ty, bytes)]);
            assert_eq!(decode(&file), Err(DecodeError::Variables(4 + 23)), "{ty}");
        }
    }

    #[test]
    fn every_truncation_is_rejected() {
        let bytes = with_an_array();
        for len in 0..bytes.len() {
            let error = decode(&bytes[..len]).unwrap_err();
            if len < HEADER + 4 {
                assert_eq!(error, DecodeError::TooShort(len));
            } else {
                assert_eq!(error, DecodeError::Length { len, expected: bytes.len() });
            }
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(matches!(decode(&longer), Err(DecodeError::Length { .. })));
    }

    #[test]
    fn every_single_bit_flip_is_rejected() {
        let bytes = with_an_array();
        for bit in 0..bytes.len() * 8 {
            let mut flipped = bytes.clone();
            flipped[bit / 8] ^= 1 << (bit % 8);
            assert!(decode(&flipped).is_err(), "bit {bit} flipped went unnoticed");
        }
    }

    #[test]
    fn other_magic_and_versions() {
        let mut bytes = file(1, &[1]);
        bytes[0] = b'X';
        assert_eq!(decode(&bytes), Err(DecodeError::Magic));
        let mut bytes = file(1, &[1]);
        bytes[8] = 5;
        assert_eq!(decode(&bytes), Err(DecodeError::Version(5)));
        let mut bytes = file(1, &[1]);
        bytes[8] = 0;
        assert_eq!(decode(&bytes), Err(DecodeError::Version(0)));
    }

    #[test]
    fn the_newest_intact_matching_generation_wins() {
        let two = [K];
        let a = Slot::Intact(generation(7, &[1, 1]));
        let b = Slot::Intact(generation(8, &[2, 2]));
        let choice = choose(&[a.clone(), b.clone()], &two);
        assert_eq!((choice.restore, choice.next_slot, choice.next_seq), (Some(1), 0, 9));
        assert!(choice.mismatched.is_empty());
        let choice = choose(&[b.clone(), a.clone()], &two);
        assert_eq!((choice.restore, choice.next_slot, choice.next_seq), (Some(0), 1, 9));
        // A corrupt newer file falls back to the other one.
        let corrupt = Slot::Corrupt(DecodeError::Crc { stored: 0, computed: 1 });
        let choice = choose(&[a.clone(), corrupt.clone()], &two);
        assert_eq!((choice.restore, choice.next_slot, choice.next_seq), (Some(0), 1, 8));
        let choice = choose(&[Slot::Missing, a.clone()], &two);
        assert_eq!((choice.restore, choice.next_slot), (Some(1), 0));
        let choice = choose(&[Slot::Missing, Slot::Missing], &two);
        assert_eq!((choice.restore, choice.next_slot, choice.next_seq), (None, 0, 1));
        let choice = choose(&[corrupt.clone(), corrupt], &two);
        assert_eq!((choice.restore, choice.next_slot, choice.next_seq), (None, 0, 1));
    }

    #[test]
    fn a_newest_generation_of_other_ranges_restores_nothing_and_is_set_aside() {
        let three = RetainedWords { start: 384, end: 387, mask: !0 };
        let old_matching = Slot::Intact(generation(4, &[1, 1, 1]));
        let newer_other = Slot::Intact(generation(5, &[2, 2]));
        let choice = choose(&[old_matching.clone(), newer_other.clone()], &[three]);
        assert_eq!(choice.restore, None, "restoring seq 4 would go back in time");
        assert_eq!(choice.mismatched.len(), 1);
        assert_eq!(choice.mismatched[0].0, 1);
        assert_eq!(
            choice.mismatched[0].1,
            "the file retains K000-K001; the config retains K000-K002"
        );
        assert_eq!((choice.next_slot, choice.next_seq), (1, 6));
        // An older mismatched one is set aside too; the newer matching one is restored.
        let choice = choose(&[newer_other, Slot::Intact(generation(6, &[3, 3, 3]))], &[three]);
        assert_eq!((choice.restore, choice.next_slot, choice.next_seq), (Some(1), 0, 7));
        assert_eq!(choice.mismatched.len(), 1);
    }
}

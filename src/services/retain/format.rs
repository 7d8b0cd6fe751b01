//! The generation file, and which of the two generations wins at start. Pure: bytes in,
//! values out.
//!
//! All integers little-endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `PLCDRTN\0` |
//! | 8 | 2 | format version, 1 |
//! | 10 | 2 | n: the number of word ranges |
//! | 12 | 4 | w: the number of payload words |
//! | 16 | 8 | sequence number, one more for every write, across restarts |
//! | 24 | 8 | when the snapshot was taken, ms since the Unix epoch (for the log only) |
//! | 32 | 4 | words of device memory in the build that wrote it (the device layout) |
//! | 36 | 4 | reserved, 0 |
//! | 40 | 6·n | the ranges: first word index, word count, bit mask (u16 each) |
//! | 40+6n | 2·w | the payload: the words of every range, range after range |
//! | end−4 | 4 | CRC-32C (Castagnoli) of every byte before it |
//!
//! The ranges are the layout: a file is restored only if they and the device layout equal the
//! configured ones exactly.

use crate::device::layout;
use crate::device::retained::{difference, RetainedWords};

pub const MAGIC: [u8; 8] = *b"PLCDRTN\0";
pub const VERSION: u16 = 1;
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
}

/// Why bytes are not a generation.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    #[error("truncated: {0} bytes, shorter than a header")]
    TooShort(usize),
    #[error("not a retain file (bad magic)")]
    Magic,
    #[error("format version {0}, this build reads version {VERSION}")]
    Version(u16),
    #[error("{len} bytes where the header announces {expected} (truncated or extended)")]
    Length { len: usize, expected: usize },
    #[error("CRC mismatch: stored {stored:08x}, computed {computed:08x}")]
    Crc { stored: u32, computed: u32 },
    #[error("the ranges hold {ranges} words, the payload {words}")]
    Inconsistent { ranges: usize, words: usize },
}

/// The bytes of a file holding `words` (of `ranges`, as [`super::RetainSet::capture`] made
/// them), into `out`.
pub fn encode(
    seq: u64,
    written_unix_ms: u64,
    ranges: &[RetainedWords],
    words: &[u16],
    out: &mut Vec<u8>,
) {
    out.clear();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(ranges.len() as u16).to_le_bytes());
    out.extend_from_slice(&(words.len() as u32).to_le_bytes());
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&written_unix_ms.to_le_bytes());
    out.extend_from_slice(&layout::TOTAL_WORDS.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    for r in ranges {
        for v in [r.start, r.end - r.start, r.mask] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    for w in words {
        out.extend_from_slice(&w.to_le_bytes());
    }
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
    if version != VERSION {
        return Err(DecodeError::Version(version));
    }
    let n = usize::from(u16_at(bytes, 10));
    let w = u32_at(bytes, 12) as usize;
    let expected = HEADER + 6 * n + 2 * w + 4;
    if bytes.len() != expected {
        return Err(DecodeError::Length { len: bytes.len(), expected });
    }
    let body = &bytes[..bytes.len() - 4];
    let stored = u32_at(bytes, body.len());
    let computed = CRC.checksum(body);
    if stored != computed {
        return Err(DecodeError::Crc { stored, computed });
    }
    let ranges: Vec<RetainedWords> = (0..n)
        .map(|i| {
            let at = HEADER + 6 * i;
            let start = u16_at(bytes, at);
            let len = u16_at(bytes, at + 2);
            RetainedWords { start, end: start.saturating_add(len), mask: u16_at(bytes, at + 4) }
        })
        .collect();
    let in_ranges: usize = ranges.iter().map(RetainedWords::len).sum();
    if in_ranges != w {
        return Err(DecodeError::Inconsistent { ranges: in_ranges, words: w });
    }
    let payload = HEADER + 6 * n;
    let words = (0..w).map(|i| u16_at(bytes, payload + 2 * i)).collect();
    Ok(Generation {
        seq: u64_at(bytes, 16),
        written_unix_ms: u64_at(bytes, 24),
        device_words: u32_at(bytes, 32),
        ranges,
        words,
    })
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
        let mut out = Vec::new();
        let ranges =
            [RetainedWords { start: K.start, end: K.start + words.len() as u16, mask: !0 }];
        encode(seq, 1_700_000_000_000, &ranges, words, &mut out);
        out
    }

    fn generation(seq: u64, words: &[u16]) -> Generation {
        decode(&file(seq, words)).unwrap()
    }

    #[test]
    fn the_bytes_of_a_small_file() {
        let bytes = file(5, &[0x1234, 0xBEEF]);
        let total = layout::TOTAL_WORDS.to_le_bytes();
        let mut expected: Vec<u8> = Vec::new();
        expected.extend(b"PLCDRTN\0");
        expected.extend([1, 0, 1, 0, 2, 0, 0, 0]);
        expected.extend([5, 0, 0, 0, 0, 0, 0, 0]);
        expected.extend(1_700_000_000_000u64.to_le_bytes());
        expected.extend(total);
        expected.extend([0, 0, 0, 0]);
        expected.extend([0x80, 0x01, 2, 0, 0xFF, 0xFF]);
        expected.extend([0x34, 0x12, 0xEF, 0xBE]);
        assert_eq!(&bytes[..bytes.len() - 4], &expected[..]);
        assert_eq!(bytes.len(), HEADER + 6 + 4 + 4);
        let decoded = decode(&bytes).unwrap();
        assert_eq!((decoded.seq, &decoded.words[..]), (5, &[0x1234, 0xBEEF][..]));
        assert_eq!(decoded.ranges, [K]);
        assert_eq!(layout_difference(&decoded, &[K]), None);
    }

    #[test]
    fn a_known_crc() {
        // CRC-32C check value of the catalogue: "123456789" → e3069283.
        assert_eq!(CRC.checksum(b"123456789"), 0xE306_9283);
    }

    #[test]
    fn every_truncation_is_rejected() {
        let bytes = file(9, &[1, 2]);
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
        let bytes = file(9, &[1, 2]);
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
        bytes[8] = 2;
        assert_eq!(decode(&bytes), Err(DecodeError::Version(2)));
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

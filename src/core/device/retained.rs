//! Which device words are retained (survive a restart, docs/RETAIN.md): the K area, then each
//! `[retain]` range in the order written. A D range is its words; a T or C range is its current values plus the words of
//! done contacts holding its bits, masked to those bits (16 contacts share a word).

use std::ops::Range;

use super::layout;
use super::{Address, Area};

/// An area whose ranges `[retain] ranges` may name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RetainArea {
    D,
    /// Timers: current value and done contact.
    T,
    /// Counters: current value and done contact.
    C,
}

/// An inclusive range of one area, `D00000-D00099`, `C0000-C0015`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RetainRange {
    pub area: RetainArea,
    pub first: u16,
    pub last: u16,
}

impl RetainRange {
    /// Parses `D00000-D00099` (first ≤ last, one area of D, T, C; word devices only).
    pub fn parse(text: &str) -> Result<RetainRange, String> {
        let Some((a, b)) = text.split_once('-') else {
            return Err(format!("`{text}` is not a range: write it `D00000-D00099`"));
        };
        let (a, b) = (a.trim(), b.trim());
        let first = Address::parse(a).map_err(|e| e.to_string())?;
        let last = Address::parse(b).map_err(|e| e.to_string())?;
        let area = match first.area {
            Area::D => RetainArea::D,
            Area::T => RetainArea::T,
            Area::C => RetainArea::C,
            Area::K => return Err(format!("`{text}`: the K area is always retained")),
            other => {
                return Err(format!(
                    "`{text}`: {other:?} cannot be retained; D, T and C ranges can (K always is)"
                ))
            }
        };
        if last.area != first.area {
            return Err(format!("`{text}`: both ends must be of one area"));
        }
        if first.bit.is_some() || last.bit.is_some() {
            return Err(format!("`{text}`: a range of words, not of bits"));
        }
        if first.number > last.number {
            return Err(format!("`{text}`: the first device is after the last"));
        }
        Ok(RetainRange { area, first: first.number as u16, last: last.number as u16 })
    }

    /// True if the two share a device.
    pub fn overlaps(&self, other: &RetainRange) -> bool {
        self.area == other.area && self.first <= other.last && other.first <= self.last
    }
}

impl std::fmt::Display for RetainRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.area {
            RetainArea::D => write!(f, "D{:05}-D{:05}", self.first, self.last),
            RetainArea::T => write!(f, "T{:04}-T{:04}", self.first, self.last),
            RetainArea::C => write!(f, "C{:04}-C{:04}", self.first, self.last),
        }
    }
}

/// A run of retained device words; of each word only the bits of `mask` are retained.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct RetainedWords {
    /// Word indices of device memory.
    pub start: u16,
    pub end: u16,
    pub mask: u16,
}

impl RetainedWords {
    pub fn len(&self) -> usize {
        usize::from(self.end - self.start)
    }

    pub fn is_empty(&self) -> bool {
        self.start == self.end
    }

    pub fn range(&self) -> Range<u16> {
        self.start..self.end
    }
}

/// Everything retained, as the engine, the mirror and the file format need it.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RetainSet {
    /// K first, then the configured ranges; the order of the words in the file.
    pub words: Box<[RetainedWords]>,
    /// Timer numbers of T ranges.
    pub timers: Box<[Range<u16>]>,
    /// Counter numbers of C ranges.
    pub counters: Box<[Range<u16>]>,
}

const fn word(index: u32) -> u16 {
    index as u16
}

impl RetainSet {
    /// K only: what is retained without a `[retain]` section.
    pub fn k_only() -> RetainSet {
        RetainSet::new(&[])
    }

    /// K and `ranges` (the `[retain] ranges` of the config).
    pub fn new(ranges: &[RetainRange]) -> RetainSet {
        let mut words = vec![RetainedWords {
            start: word(layout::K),
            end: word(layout::K + layout::MK_WORDS),
            mask: 0xFFFF,
        }];
        let (mut timers, mut counters) = (Vec::new(), Vec::new());
        for range in ranges {
            let (first, last) = (u32::from(range.first), u32::from(range.last));
            let (values, bits) = match range.area {
                RetainArea::D => {
                    let start = word(layout::D + first);
                    words.push(RetainedWords { start, end: word(layout::D + last + 1), mask: !0 });
                    continue;
                }
                RetainArea::T => {
                    timers.push(range.first..range.last + 1);
                    (layout::TV, layout::TB)
                }
                RetainArea::C => {
                    counters.push(range.first..range.last + 1);
                    (layout::CV, layout::CB)
                }
            };
            words.push(RetainedWords {
                start: word(values + first),
                end: word(values + last + 1),
                mask: !0,
            });
            // Done contacts: a partial first and last word, full words between.
            let (first_word, last_word) = (first / 16, last / 16);
            for w in first_word..=last_word {
                let low = if w == first_word { first % 16 } else { 0 };
                let high = if w == last_word { last % 16 } else { 15 };
                let mask = ((0xFFFF_u32 >> (15 - high)) & (0xFFFF_u32 << low)) as u16;
                let start = word(bits + w);
                match words.last_mut() {
                    Some(prev) if prev.mask == 0xFFFF && mask == 0xFFFF && prev.end == start => {
                        prev.end += 1
                    }
                    _ => words.push(RetainedWords { start, end: start + 1, mask }),
                }
            }
        }
        RetainSet {
            words: words.into_boxed_slice(),
            timers: timers.into_boxed_slice(),
            counters: counters.into_boxed_slice(),
        }
    }

    /// Retained words in all.
    pub fn word_count(&self) -> usize {
        self.words.iter().map(RetainedWords::len).sum()
    }

    /// The retained words of device memory `memory`, range after range (as the mirror copies
    /// them), masked.
    pub fn capture(&self, memory: &[u16], into: &mut Vec<u16>) {
        into.clear();
        for w in self.words.iter() {
            let words = &memory[usize::from(w.start)..usize::from(w.end)];
            into.extend(words.iter().map(|v| v & w.mask));
        }
    }

    /// Writes `payload` (as [`RetainSet::capture`] made it) back into device memory: the
    /// retained bits only. `payload` must have [`RetainSet::word_count`] words.
    pub fn restore(&self, payload: &[u16], memory: &mut [u16]) {
        let mut at = 0;
        for w in self.words.iter() {
            let target = &mut memory[usize::from(w.start)..usize::from(w.end)];
            for (t, v) in target.iter_mut().zip(&payload[at..at + w.len()]) {
                *t = (*t & !w.mask) | (v & w.mask);
            }
            at += w.len();
        }
    }

    /// True if device word `index` has retained bits; those bits.
    pub fn mask_of(&self, index: usize) -> u16 {
        self.words
            .iter()
            .filter(|w| usize::from(w.start) <= index && index < usize::from(w.end))
            .fold(0, |mask, w| mask | w.mask)
    }

    /// Counter `n` is in a retained C range.
    pub fn retains_counter(&self, n: usize) -> bool {
        self.counters.iter().any(|r| usize::from(r.start) <= n && n < usize::from(r.end))
    }
}

/// The configured ranges in words, for messages: `K000-K255, D00000-D00099, C0000-C0015`.
pub fn describe(words: &[RetainedWords]) -> String {
    let names: Vec<String> = words.iter().filter_map(describe_one).collect();
    names.join(", ")
}

fn describe_one(w: &RetainedWords) -> Option<String> {
    let (start, last) = (u32::from(w.start), u32::from(w.end).checked_sub(1)?);
    let in_area = |base: u32, count: u32| (base..base + count).contains(&start);
    Some(if in_area(layout::K, layout::MK_WORDS) {
        format!("K{:03}-K{:03}", start - layout::K, last - layout::K)
    } else if in_area(layout::D, layout::D_WORDS) {
        format!("D{:05}-D{:05}", start - layout::D, last - layout::D)
    } else if in_area(layout::TV, layout::TC_COUNT) {
        format!("T{:04}-T{:04}", start - layout::TV, last - layout::TV)
    } else if in_area(layout::CV, layout::TC_COUNT) {
        format!("C{:04}-C{:04}", start - layout::CV, last - layout::CV)
    } else if in_area(layout::TB, layout::TC_COUNT / 16)
        || in_area(layout::CB, layout::TC_COUNT / 16)
    {
        // Done contacts follow their values; they add nothing a reader needs.
        return None;
    } else {
        format!("words {start}..={last}")
    })
}

/// What differs between the ranges of a file and the configured ones, in words a user reads.
pub fn difference(file: &[RetainedWords], configured: &[RetainedWords]) -> String {
    let (in_file, in_config) = (describe(file), describe(configured));
    if in_file == in_config {
        // Same names, other masks or order of done-contact words: say it plainly.
        format!("the file's word layout differs from the configured one ({in_config})")
    } else {
        format!("the file retains {in_file}; the config retains {in_config}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn range(text: &str) -> RetainRange {
        RetainRange::parse(text).unwrap()
    }

    #[test]
    fn k_always_then_the_ranges_with_done_bits_masked() {
        let set = RetainSet::new(&[range("D00010-D00012"), range("C0014-C0033")]);
        let (k, d, cv, cb) =
            (layout::K as u16, layout::D as u16, layout::CV as u16, layout::CB as u16);
        assert_eq!(
            &*set.words,
            &[
                RetainedWords { start: k, end: k + 256, mask: 0xFFFF },
                RetainedWords { start: d + 10, end: d + 13, mask: 0xFFFF },
                RetainedWords { start: cv + 14, end: cv + 34, mask: 0xFFFF },
                RetainedWords { start: cb, end: cb + 1, mask: 0xC000 },
                RetainedWords { start: cb + 1, end: cb + 2, mask: 0xFFFF },
                RetainedWords { start: cb + 2, end: cb + 3, mask: 0x0003 },
            ]
        );
        assert_eq!(set.counters.len(), 1);
        assert_eq!(set.counters[0], 14..34);
        assert!(set.timers.is_empty());
        assert_eq!(set.word_count(), 256 + 3 + 20 + 3);
        assert_eq!(describe(&set.words), "K000-K255, D00010-D00012, C0014-C0033");
    }

    #[test]
    fn full_done_words_merge() {
        let set = RetainSet::new(&[range("T0000-T0047")]);
        let tb = layout::TB as u16;
        assert_eq!(set.words[2], RetainedWords { start: tb, end: tb + 3, mask: 0xFFFF });
        assert_eq!(set.words.len(), 3);
    }

    #[test]
    fn capture_and_restore_touch_the_retained_bits_only() {
        let set = RetainSet::new(&[range("C0001-C0001")]);
        let mut memory = vec![0u16; layout::TOTAL_WORDS as usize];
        memory[layout::K as usize] = 7;
        memory[(layout::CV + 1) as usize] = 42;
        memory[layout::CB as usize] = 0b111;
        let mut payload = Vec::new();
        set.capture(&memory, &mut payload);
        assert_eq!(payload.len(), set.word_count());
        assert_eq!((payload[0], payload[256], payload[257]), (7, 42, 0b010));
        let mut fresh = vec![0u16; memory.len()];
        fresh[layout::CB as usize] = 0b100;
        set.restore(&payload, &mut fresh);
        assert_eq!(fresh[layout::CB as usize], 0b110, "C0002's bit is not C0001's to restore");
        assert_eq!(fresh[(layout::CV + 1) as usize], 42);
        assert!(set.retains_counter(1) && !set.retains_counter(2));
        assert_eq!(set.mask_of(layout::CB as usize), 0b010);
    }
}

//! The retain files on a real directory: two generations written by the writer, then the newer
//! one truncated at every byte offset, and damaged by random bit flips: the start always falls
//! back to the older intact generation, never restores garbage. A file of other ranges is set
//! aside under a name the writer never uses, and nothing is restored.

mod harness;

use std::path::PathBuf;

use plcd::config::{Restart, RetainRange};
use plcd::device::RetainSet;
use plcd::services::retain::store::SLOT_NAMES;
use plcd::services::retain::writer::Writer;
use plcd::services::retain::{self, Store};

use harness::tempdir::TempDir;

fn set() -> RetainSet {
    RetainSet::new(&[
        RetainRange::parse("D00000-D00009").unwrap(),
        RetainRange::parse("C0000-C0003").unwrap(),
    ])
}

/// The retained words with every word `value`.
fn words(set: &RetainSet, value: u16) -> Vec<u16> {
    let mut words = vec![value; set.word_count()];
    // The last word is C0000-C0003's done contacts: only bits 0..=3 are kept.
    *words.last_mut().unwrap() = value & 0xF;
    words
}

/// Writes generation `old` then `new` (values 1 then 2) with a fresh writer; the newer file.
fn two_generations(dir: &TempDir, set: &RetainSet) -> PathBuf {
    let start = retain::startup(&Store::open(dir.path()).unwrap(), set, Restart::Warm);
    let mut writer = Writer::new(
        Store::open(dir.path()).unwrap(),
        &set.words,
        start.next_slot,
        start.next_seq,
        None,
    );
    assert!(writer.write_if_changed(&mut words(set, 1)).unwrap());
    assert!(!writer.write_if_changed(&mut words(set, 1)).unwrap(), "unchanged: not written");
    assert!(writer.write_if_changed(&mut words(set, 2)).unwrap());
    let newest = retain::newest_in(dir.path()).unwrap();
    assert_eq!((newest.seq, newest.words[0]), (2, 2));
    dir.join(SLOT_NAMES[1])
}

#[test]
fn the_newest_generation_is_restored_and_the_writer_goes_on_in_the_other_slot() {
    let dir = TempDir::new("retain-newest");
    let set = set();
    two_generations(&dir, &set);
    let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
    assert_eq!(start.words, Some(words(&set, 2)));
    assert_eq!((start.next_slot, start.next_seq), (0, 3));
    let cold = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Cold);
    assert_eq!(cold.words, None, "restart = cold restores nothing");
    assert_eq!(cold.next_seq, 3, "and still never reuses a sequence number");
}

#[test]
fn a_newer_generation_truncated_at_any_byte_falls_back_to_the_older_one() {
    let dir = TempDir::new("retain-truncated");
    let set = set();
    let newer = two_generations(&dir, &set);
    let bytes = std::fs::read(&newer).unwrap();
    for len in 0..bytes.len() {
        std::fs::write(&newer, &bytes[..len]).unwrap();
        let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
        assert_eq!(start.words, Some(words(&set, 1)), "truncated to {len} bytes");
        assert_eq!((start.next_slot, start.next_seq), (1, 2), "the broken slot is written next");
    }
}

#[test]
fn random_bit_flips_fall_back_to_the_older_generation() {
    let dir = TempDir::new("retain-flips");
    let set = set();
    let newer = two_generations(&dir, &set);
    let bytes = std::fs::read(&newer).unwrap();
    let mut rng = 0x2545_F491_4F6C_DD1D_u64;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    for round in 0..1000 {
        let mut damaged = bytes.clone();
        let flips = 1 + next() % 8;
        for _ in 0..flips {
            let bit = (next() % (bytes.len() as u64 * 8)) as usize;
            damaged[bit / 8] ^= 1 << (bit % 8);
        }
        if damaged == bytes {
            continue; // the flips cancelled out
        }
        std::fs::write(&newer, &damaged).unwrap();
        let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
        assert_eq!(start.words, Some(words(&set, 1)), "round {round}: {flips} bits flipped");
    }
}

#[test]
fn both_generations_broken_restores_nothing() {
    let dir = TempDir::new("retain-both");
    let set = set();
    two_generations(&dir, &set);
    for name in SLOT_NAMES {
        std::fs::write(dir.join(name), b"PLCDRTN\0 garbage").unwrap();
    }
    let start = retain::startup(&Store::open(dir.path()).unwrap(), &set, Restart::Warm);
    assert_eq!(start.words, None);
}

#[test]
fn files_of_other_ranges_are_set_aside_not_restored_and_never_overwritten() {
    let dir = TempDir::new("retain-mismatch");
    let old_set = set();
    two_generations(&dir, &old_set);
    let a = std::fs::read(dir.join(SLOT_NAMES[0])).unwrap();
    let b = std::fs::read(dir.join(SLOT_NAMES[1])).unwrap();
    let new_set = RetainSet::new(&[RetainRange::parse("D00000-D00019").unwrap()]);
    let start = retain::startup(&Store::open(dir.path()).unwrap(), &new_set, Restart::Warm);
    assert_eq!(start.words, None, "restored nothing");
    assert_eq!(start.next_seq, 3);
    assert!(!dir.join(SLOT_NAMES[0]).exists() && !dir.join(SLOT_NAMES[1]).exists());
    let kept_a = dir.join(format!("{}.mismatch", SLOT_NAMES[0]));
    let kept_b = dir.join(format!("{}.mismatch", SLOT_NAMES[1]));
    assert_eq!(std::fs::read(&kept_a).unwrap(), a, "kept byte for byte");
    assert_eq!(std::fs::read(&kept_b).unwrap(), b);

    // The writer goes on with the new ranges and leaves the set-aside files alone; a second
    // mismatch later gets a name of its own.
    let mut writer = Writer::new(
        Store::open(dir.path()).unwrap(),
        &new_set.words,
        start.next_slot,
        start.next_seq,
        None,
    );
    assert!(writer.write_if_changed(&mut vec![5; new_set.word_count()]).unwrap());
    let again = retain::startup(&Store::open(dir.path()).unwrap(), &old_set, Restart::Warm);
    assert_eq!(again.words, None);
    assert!(dir.join(format!("{}.mismatch.2", SLOT_NAMES[start.next_slot])).exists());
    assert_eq!(std::fs::read(&kept_a).unwrap(), a);
    assert_eq!(std::fs::read(&kept_b).unwrap(), b);
}

//! Line names: a config's `line = "GPIO17"` looked up among the names of a chip's lines, and,
//! when the chip has no line of that name, the names near it, for the error to suggest.
//!
//! Pure: the chip's names come in as a list by offset (`""` for a line without a name), as
//! `plcd run` reads them from the chip's line info. The kernel compares nothing itself; names
//! are matched exactly, as the kernel reports them (case included).

use std::cmp::Ordering;
use std::fmt;

/// The most near names an error suggests.
pub const NEAR_NAMES_MAX: usize = 5;

/// The most of the chip's names an error lists when none is near the one asked for.
const LISTED_NAMES_MAX: usize = 8;

/// How far (edits: a character inserted, removed, replaced, or two neighbours swapped) a
/// name may be from the one asked for to be suggested.
const NEAR_DISTANCE_MAX: usize = 2;

/// Why a name is no line of the chip.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Lookup {
    /// No line has it; what the chip's names suggest instead.
    Missing(NameHint),
    /// Several lines have it: their offsets.
    Shared(Vec<u32>),
}

/// What an error about a name no line has says about the chip's names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NameHint {
    /// The names near the one asked for, nearest first, with their offsets (at most
    /// [`NEAR_NAMES_MAX`]).
    Near(Vec<(String, u32)>),
    /// None is near: the first of the chip's names, in offset order, and how many lines have
    /// one.
    Listed { first: Vec<String>, named: usize },
    /// None of the chip's `lines` lines has a name.
    Unnamed { lines: usize },
}

impl fmt::Display for NameHint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NameHint::Near(near) => {
                f.write_str("near names: ")?;
                for (i, (name, offset)) in near.iter().enumerate() {
                    let sep = if i == 0 { "" } else { ", " };
                    write!(f, "{sep}{name:?} (line {offset})")?;
                }
                Ok(())
            }
            NameHint::Listed { first, named } => {
                write!(f, "no name is near it; the chip names {named} of its lines: ")?;
                for (i, name) in first.iter().enumerate() {
                    let sep = if i == 0 { "" } else { ", " };
                    write!(f, "{sep}{name:?}")?;
                }
                if *named > first.len() {
                    f.write_str(", …")?;
                }
                Ok(())
            }
            NameHint::Unnamed { lines } => {
                write!(f, "none of the chip's {lines} lines has a name: give the line's offset")
            }
        }
    }
}

/// The offset of the one line of the chip named `name`.
pub fn lookup(name: &str, chip: &[String]) -> Result<u32, Lookup> {
    let offsets: Vec<u32> =
        offsets(chip).filter(|(_, n)| !n.is_empty() && *n == name).map(|(o, _)| o).collect();
    match offsets[..] {
        [offset] => Ok(offset),
        [] => Err(Lookup::Missing(hint(name, chip))),
        _ => Err(Lookup::Shared(offsets)),
    }
}

/// What to say about the chip's names when none is `name`.
fn hint(name: &str, chip: &[String]) -> NameHint {
    let near = near_names(name, chip);
    if !near.is_empty() {
        return NameHint::Near(near);
    }
    let named: Vec<&str> = offsets(chip).map(|(_, n)| n).filter(|n| !n.is_empty()).collect();
    if named.is_empty() {
        return NameHint::Unnamed { lines: chip.len() };
    }
    let first = named.iter().take(LISTED_NAMES_MAX).map(|n| n.to_string()).collect();
    NameHint::Listed { first, named: named.len() }
}

/// The chip's names with their offsets.
fn offsets(chip: &[String]) -> impl Iterator<Item = (u32, &str)> {
    (0..).zip(chip.iter().map(String::as_str))
}

/// The names of the chip near `name` (never `name` itself), nearest first, each once with its
/// first offset, at most [`NEAR_NAMES_MAX`]. Nearest are:
///
/// 1. the same name in another case (`gpio17` → `GPIO17`);
/// 2. the same letters with the same digits in another order (`GPIO71` → `GPIO17`);
/// 3. a name that begins the one asked for, or that it begins, at most two characters apart
///    (`GPIO71` → `GPIO7`);
/// 4. any name at most two edits away, ignoring case (`GPIO71` → `GPIO11`, `GPIO70`).
///
/// Within each, the fewer edits the nearer, then the lower offset.
pub fn near_names(name: &str, chip: &[String]) -> Vec<(String, u32)> {
    let asked = Folded::new(name);
    let mut near: Vec<(Rank, &str, u32)> = Vec::new();
    for (offset, candidate) in offsets(chip) {
        if candidate.is_empty() || candidate == name || near.iter().any(|(_, n, _)| *n == candidate)
        {
            continue;
        }
        if let Some(rank) = rank(&asked, &Folded::new(candidate)) {
            near.push((rank, candidate, offset));
        }
    }
    near.sort_by(|a, b| a.0.cmp(&b.0).then(a.2.cmp(&b.2)));
    near.into_iter().take(NEAR_NAMES_MAX).map(|(_, n, o)| (n.to_string(), o)).collect()
}

/// How near a candidate is: its kind (1..=4 of [`near_names`], as 0..=3), then its distance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Rank(u8, usize);

/// A name in lower case, as characters, with its letters and digits apart.
struct Folded {
    chars: Vec<char>,
    /// Everything but the digits, in order.
    letters: Vec<char>,
    /// The digits, sorted.
    digits: Vec<char>,
}

impl Folded {
    fn new(name: &str) -> Folded {
        let chars: Vec<char> = name.chars().flat_map(char::to_lowercase).collect();
        let letters = chars.iter().copied().filter(|c| !c.is_ascii_digit()).collect();
        let mut digits: Vec<char> = chars.iter().copied().filter(char::is_ascii_digit).collect();
        digits.sort_unstable();
        Folded { chars, letters, digits }
    }
}

fn rank(asked: &Folded, candidate: &Folded) -> Option<Rank> {
    if asked.chars == candidate.chars {
        return Some(Rank(0, 0));
    }
    let distance = distance(&asked.chars, &candidate.chars);
    if !asked.digits.is_empty()
        && asked.letters == candidate.letters
        && asked.digits == candidate.digits
    {
        return Some(Rank(1, distance));
    }
    if distance > NEAR_DISTANCE_MAX {
        return None;
    }
    let (short, long) = match asked.chars.len().cmp(&candidate.chars.len()) {
        Ordering::Less => (&asked.chars, &candidate.chars),
        _ => (&candidate.chars, &asked.chars),
    };
    if long.starts_with(short) {
        return Some(Rank(2, distance));
    }
    Some(Rank(3, distance))
}

/// The optimal string alignment distance: how many characters to insert, remove or replace,
/// or pairs of neighbours to swap, to make `a` into `b` (no substring edited twice).
fn distance(a: &[char], b: &[char]) -> usize {
    // Three rows of the table: two back (for swaps), the last, and this one.
    let mut before: Vec<usize> = vec![0; b.len() + 1];
    let mut last: Vec<usize> = (0..=b.len()).collect();
    let mut row: Vec<usize> = vec![0; b.len() + 1];
    for i in 1..=a.len() {
        row[0] = i;
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            row[j] = (last[j] + 1).min(row[j - 1] + 1).min(last[j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                row[j] = row[j].min(before[j - 2] + 1);
            }
        }
        std::mem::swap(&mut before, &mut last);
        std::mem::swap(&mut last, &mut row);
    }
    last[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The header chip of a Raspberry Pi 4 on Raspberry Pi's kernel (since 2024): 58 lines,
    /// 0 and 1 the HAT EEPROM's, 2..=27 named after their GPIO number, the rest the board's.
    fn pi4() -> Vec<String> {
        let mut names = vec!["ID_SDA".to_string(), "ID_SCL".to_string()];
        names.extend((2..=27).map(|n| format!("GPIO{n}")));
        names.extend(
            [
                "RGMII_MDIO",
                "RGMIO_MDC",
                "CTS0",
                "RTS0",
                "TXD0",
                "RXD0",
                "SD1_CLK",
                "SD1_CMD",
                "SD1_DATA0",
                "SD1_DATA1",
                "SD1_DATA2",
                "SD1_DATA3",
                "PWM0_MISO",
                "PWM1_MOSI",
                "STATUS_LED_G_CLK",
                "SPIFLASH_CE_N",
                "SDA0",
                "SCL0",
                "RGMII_RXCLK",
                "RGMII_RXCTL",
                "RGMII_RXD0",
                "RGMII_RXD1",
                "RGMII_RXD2",
                "RGMII_RXD3",
                "RGMII_TXCLK",
                "RGMII_TXCTL",
                "RGMII_TXD0",
                "RGMII_TXD1",
                "RGMII_TXD2",
                "RGMII_TXD3",
            ]
            .map(String::from),
        );
        assert_eq!(names.len(), 58);
        names
    }

    fn chip(names: &[&str]) -> Vec<String> {
        names.iter().map(|n| n.to_string()).collect()
    }

    fn near(name: &str, chip: &[String]) -> Vec<String> {
        near_names(name, chip).into_iter().map(|(n, _)| n).collect()
    }

    #[test]
    fn a_name_is_its_lines_offset() {
        let pi4 = pi4();
        assert_eq!(lookup("GPIO17", &pi4), Ok(17));
        assert_eq!(lookup("ID_SDA", &pi4), Ok(0));
        assert_eq!(lookup("RGMII_TXD3", &pi4), Ok(57));
        // Names are the kernel's, case and all.
        assert!(matches!(lookup("gpio17", &pi4), Err(Lookup::Missing(_))));
    }

    #[test]
    fn a_name_of_several_lines_names_them_all() {
        // As on a Raspberry Pi 5, whose RP1 chip names several spare lines "-".
        let chip = chip(&["GPIO0", "-", "GPIO2", "-", "-", "GPIO5"]);
        assert_eq!(lookup("-", &chip), Err(Lookup::Shared(vec![1, 3, 4])));
        assert_eq!(lookup("GPIO5", &chip), Ok(5));
    }

    #[test]
    fn unnamed_lines_match_no_name() {
        let chip = chip(&["", "", "LED"]);
        assert_eq!(lookup("LED", &chip), Ok(2));
        // An empty name is refused by the config; it would be no line here either.
        assert_eq!(
            lookup("", &chip),
            Err(Lookup::Missing(NameHint::Listed { first: vec!["LED".into()], named: 1 }))
        );
    }

    #[test]
    fn near_names_of_a_typo() {
        let pi4 = pi4();
        // Swapped digits first, then the name that begins it, then one edit away.
        assert_eq!(near("GPIO71", &pi4), ["GPIO17", "GPIO7", "GPIO11", "GPIO21", "GPIO2"]);
        // Another case first.
        assert_eq!(near("gpio17", &pi4)[0], "GPIO17");
        assert_eq!(near("Gpio17", &pi4)[0], "GPIO17");
        // One edit away, by offset: a letter left out, or a digit for a letter.
        assert_eq!(near("GPI17", &pi4)[..2], ["GPIO7", "GPIO17"]);
        assert_eq!(near("ID_SD", &pi4), ["ID_SDA", "ID_SCL"]);
        assert!(near("BUTTON", &pi4).is_empty());
        // The offsets come along.
        assert_eq!(near_names("GPIO271", &pi4)[0], ("GPIO27".to_string(), 27));
        assert!(near("GPIO17", &pi4).iter().all(|n| n != "GPIO17"), "never the name itself");
    }

    #[test]
    fn near_names_are_at_most_five_each_once() {
        let pi4 = pi4();
        assert_eq!(near("GPIO", &pi4).len(), NEAR_NAMES_MAX);
        let chip = chip(&["-", "-", "A-", "-"]);
        assert_eq!(near_names("--", &chip), [("-".to_string(), 0), ("A-".to_string(), 2)]);
    }

    #[test]
    fn what_a_missing_name_says_about_the_chip() {
        let pi4 = pi4();
        let Err(Lookup::Missing(hint)) = lookup("GPIO71", &pi4) else { panic!() };
        assert_eq!(
            hint.to_string(),
            "near names: \"GPIO17\" (line 17), \"GPIO7\" (line 7), \"GPIO11\" (line 11), \
             \"GPIO21\" (line 21), \"GPIO2\" (line 2)"
        );
        let Err(Lookup::Missing(hint)) = lookup("START_BUTTON", &pi4) else { panic!() };
        assert_eq!(
            hint.to_string(),
            "no name is near it; the chip names 58 of its lines: \"ID_SDA\", \"ID_SCL\", \
             \"GPIO2\", \"GPIO3\", \"GPIO4\", \"GPIO5\", \"GPIO6\", \"GPIO7\", …"
        );
        let few = chip(&["", "LED", ""]);
        let Err(Lookup::Missing(hint)) = lookup("START", &few) else { panic!() };
        assert_eq!(hint.to_string(), "no name is near it; the chip names 1 of its lines: \"LED\"");
        let unnamed = chip(&["", "", "", ""]);
        let Err(Lookup::Missing(hint)) = lookup("GPIO17", &unnamed) else { panic!() };
        assert_eq!(
            hint.to_string(),
            "none of the chip's 4 lines has a name: give the line's offset"
        );
        assert_eq!(lookup("GPIO17", &[]), Err(Lookup::Missing(NameHint::Unnamed { lines: 0 })));
    }

    #[test]
    fn the_distance_counts_edits_and_swaps() {
        let d = |a: &str, b: &str| {
            distance(&a.chars().collect::<Vec<_>>(), &b.chars().collect::<Vec<_>>())
        };
        assert_eq!(d("GPIO17", "GPIO17"), 0);
        assert_eq!(d("GPIO17", "GPIO71"), 1, "a swap");
        assert_eq!(d("GPIO17", "GPIO7"), 1);
        assert_eq!(d("GPIO17", "GPIO170"), 1);
        assert_eq!(d("GPIO17", "GPIO28"), 2);
        assert_eq!(d("", "abc"), 3);
        assert_eq!(d("abc", ""), 3);
        assert_eq!(d("ID_SDA", "ID_SCL"), 2);
        assert_eq!(d("ca", "abc"), 3, "no substring edited twice");
    }
}

//! Durations as the command line and the stimulus files write them (`34ms`, `1.5s`, `250us`),
//! in exact integer nanoseconds.

/// The units a duration may end with, and their length in nanoseconds, largest first.
const UNITS: [(&str, u64); 4] = [("s", 1_000_000_000), ("ms", 1_000_000), ("us", 1_000), ("ns", 1)];

const UNIT_LIST: &str = "ns, us, ms or s";

/// Parses a duration (`34ms`, `1.5s`, `250us`, `0.000001ms`) into nanoseconds.
///
/// The number is unsigned, integer or decimal (`1.5`, not `.5` or `1.`), and must be followed
/// by a unit: `ns`, `us` (or `µs`), `ms` or `s`. Whitespace around the whole and between the
/// number and the unit is allowed. The arithmetic is exact: a value that is not a whole number
/// of nanoseconds, or that does not fit in 64 bits, is an error.
pub fn parse_duration(text: &str) -> Result<u64, String> {
    let trimmed = text.trim();
    if trimmed.is_empty() {
        return Err(format!("missing duration (a number followed by {UNIT_LIST}, e.g. `34ms`)"));
    }
    let number_len =
        trimmed.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(trimmed.len());
    let (number, rest) = trimmed.split_at(number_len);
    let unit = rest.trim_start();
    if number.is_empty() {
        return Err(format!("`{trimmed}` is not a duration (a number followed by {UNIT_LIST})"));
    }
    let (int_part, frac_part) = match number.split_once('.') {
        Some((int_part, frac_part)) => (int_part, Some(frac_part)),
        None => (number, None),
    };
    let bad_number = || format!("`{number}` in `{trimmed}` is not a number");
    if int_part.is_empty() || frac_part.is_some_and(|f| f.is_empty() || f.contains('.')) {
        return Err(bad_number());
    }
    if unit.is_empty() {
        return Err(format!("`{trimmed}` has no unit (use {UNIT_LIST})"));
    }
    let scale = match unit {
        "µs" | "μs" => 1_000,
        _ => match UNITS.iter().find(|(name, _)| *name == unit) {
            Some(&(_, scale)) => scale,
            None => return Err(format!("unknown unit `{unit}` in `{trimmed}` (use {UNIT_LIST})")),
        },
    };
    let too_large = || format!("`{trimmed}` is too large (at most {} ns)", u64::MAX);

    let mut whole: u64 = 0;
    for digit in int_part.bytes() {
        whole = whole
            .checked_mul(10)
            .and_then(|w| w.checked_add(u64::from(digit - b'0')))
            .ok_or_else(too_large)?;
    }
    let mut ns = whole.checked_mul(scale).ok_or_else(too_large)?;

    if let Some(frac) = frac_part {
        let frac = frac.trim_end_matches('0');
        // A unit is at most 10^9 ns, so more than nine significant decimals is always finer
        // than a nanosecond.
        let finer = || format!("`{trimmed}` is finer than 1 ns");
        if frac.len() > 9 {
            return Err(finer());
        }
        let digits: u64 =
            if frac.is_empty() { 0 } else { frac.parse().map_err(|_| bad_number())? };
        let divisor = 10u64.pow(frac.len() as u32);
        // digits < 10^9 and scale <= 10^9, so the product fits.
        let scaled = digits * scale;
        if scaled % divisor != 0 {
            return Err(finer());
        }
        ns = ns.checked_add(scaled / divisor).ok_or_else(too_large)?;
    }
    Ok(ns)
}

/// The shortest exact text of a duration that [`parse_duration`] reads back: `6.5ms` for
/// 6 500 000, `1.5us` for 1 500, `0s` for 0. Only units in which the value is at least 1 are
/// considered (`500us`, never `0.5ms`); on equal length the larger unit wins.
pub fn format_ns(ns: u64) -> String {
    if ns == 0 {
        return "0s".to_string();
    }
    let mut best: Option<String> = None;
    for (name, scale) in UNITS {
        if ns < scale {
            continue;
        }
        let whole = ns / scale;
        let frac = ns % scale;
        let text = if frac == 0 {
            format!("{whole}{name}")
        } else {
            let digits = scale.ilog10() as usize;
            let frac_text = format!("{frac:0digits$}");
            format!("{whole}.{}{name}", frac_text.trim_end_matches('0'))
        };
        if best.as_ref().is_none_or(|b| text.len() < b.len()) {
            best = Some(text);
        }
    }
    best.expect("ns >= 1 has a representation in ns")
}

/// Milliseconds as a client writes them (a Double: OPC UA's Duration, a Sparkplug metric) in
/// whole nanoseconds, rounded; `None` for what is not a number or does not fit an `i64`.
pub fn ms_to_ns(ms: f64) -> Option<i64> {
    let ns = (ms * 1e6).round();
    // i64::MAX as f64 rounds up to 2^63, itself out of range: hence the strict bound.
    (ns.is_finite() && ns >= i64::MIN as f64 && ns < i64::MAX as f64).then_some(ns as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contract_examples() {
        assert_eq!(parse_duration("34ms"), Ok(34_000_000));
        assert_eq!(parse_duration("1.5s"), Ok(1_500_000_000));
        assert_eq!(parse_duration("250us"), Ok(250_000));
        assert_eq!(parse_duration("6ms"), Ok(6_000_000));
        assert_eq!(parse_duration("40ms"), Ok(40_000_000));
        assert_eq!(parse_duration("7ns"), Ok(7));
    }

    #[test]
    fn decimals_are_exact() {
        assert_eq!(parse_duration("6.5ms"), Ok(6_500_000));
        assert_eq!(parse_duration("0.000001ms"), Ok(1));
        assert_eq!(parse_duration("0.1s"), Ok(100_000_000));
        assert_eq!(parse_duration("0.3s"), Ok(300_000_000));
        assert_eq!(parse_duration("1.000000001s"), Ok(1_000_000_001));
        assert_eq!(parse_duration("2.50000000000us"), Ok(2_500));
        assert_eq!(parse_duration("3.0ns"), Ok(3));
        assert_eq!(parse_duration("007ms"), Ok(7_000_000));
    }

    #[test]
    fn whitespace_and_micro_sign() {
        assert_eq!(parse_duration("  6.5ms\t"), Ok(6_500_000));
        assert_eq!(parse_duration("6 ms"), Ok(6_000_000));
        assert_eq!(parse_duration("5µs"), Ok(5_000));
    }

    #[test]
    fn finer_than_a_nanosecond_is_an_error() {
        let err = parse_duration("0.5ns").unwrap_err();
        assert!(err.contains("finer than 1 ns"), "{err}");
        assert!(parse_duration("0.0000001ms").is_err());
        assert!(parse_duration("1.0000000001s").is_err());
        assert!(parse_duration("1.00000000000000000001s").is_err());
    }

    #[test]
    fn overflow_is_an_error() {
        assert_eq!(parse_duration("18446744073709551615ns"), Ok(u64::MAX));
        assert!(parse_duration("18446744073709551616ns").unwrap_err().contains("too large"));
        assert!(parse_duration("18446744074s").unwrap_err().contains("too large"));
        assert!(parse_duration("99999999999999999999999999s").unwrap_err().contains("too large"));
        assert!(parse_duration("18446744073.709551616s").unwrap_err().contains("too large"));
        assert_eq!(parse_duration("18446744073.709551615s"), Ok(u64::MAX));
    }

    #[test]
    fn malformed_input() {
        let no_unit = parse_duration("34").unwrap_err();
        assert!(no_unit.contains("no unit") && no_unit.contains("ns, us, ms or s"), "{no_unit}");
        let unknown = parse_duration("3min").unwrap_err();
        assert!(unknown.contains("unknown unit `min`") && unknown.contains("ns, us, ms"));
        for bad in ["", " ", "ms", "-5ms", "+5ms", ".5ms", "5.ms", "1.2.3ms", "1e3ms", "5 m s"] {
            assert!(parse_duration(bad).is_err(), "{bad:?}");
        }
        assert!(parse_duration("5MS").is_err());
    }

    #[test]
    fn format_is_shortest_exact() {
        assert_eq!(format_ns(0), "0s");
        assert_eq!(format_ns(6_500_000), "6.5ms");
        assert_eq!(format_ns(1_500), "1.5us");
        assert_eq!(format_ns(1), "1ns");
        assert_eq!(format_ns(999), "999ns");
        assert_eq!(format_ns(500_000), "500us");
        assert_eq!(format_ns(10_000_000), "10ms");
        assert_eq!(format_ns(1_000_000_000), "1s");
        assert_eq!(format_ns(90_000_000_000), "90s");
        assert_eq!(format_ns(1_000_001), "1000001ns");
        assert_eq!(format_ns(1_234_500), "1.2345ms");
        assert_eq!(format_ns(1_000_000_001), "1.000000001s");
    }

    #[test]
    fn format_round_trips() {
        for ns in [0, 1, 7, 1_000, 1_001, 123_456_789, 6_500_000, 34_000_000, u64::MAX] {
            assert_eq!(parse_duration(&format_ns(ns)), Ok(ns), "{}", format_ns(ns));
        }
    }
}

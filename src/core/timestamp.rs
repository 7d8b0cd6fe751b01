//! Time stamps as plcd writes them: `YYYY-MM-DDTHH:MM:SS.mmmZ`, UTC, rounded down to the
//! millisecond. The daemon's log lines (where nothing else adds a time), `plcctl watch` and the
//! benchmark reports share this one form. Computed here to avoid a date crate for fifteen lines.

use std::time::{SystemTime, UNIX_EPOCH};

/// Appends `now` as `YYYY-MM-DDTHH:MM:SS.mmmZ`, rounded down to the millisecond.
pub fn write_timestamp(out: &mut String, now: SystemTime) {
    use std::fmt::Write as _;

    // A clock set before 1970 is wrong, but still deserves a well-formed line.
    let nanos: i128 = match now.duration_since(UNIX_EPOCH) {
        Ok(d) => d.as_nanos() as i128,
        Err(e) => -(e.duration().as_nanos() as i128),
    };
    let millis = nanos.div_euclid(1_000_000);
    let secs = millis.div_euclid(1000) as i64;
    let (year, month, day) = civil_from_days(secs.div_euclid(86_400));
    let sec_of_day = secs.rem_euclid(86_400);
    let _ = write!(
        out,
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{:03}Z",
        sec_of_day / 3600,
        sec_of_day / 60 % 60,
        sec_of_day % 60,
        millis.rem_euclid(1000)
    );
}

/// The proleptic Gregorian (year, month, day) of `days` since 1970-01-01, after Howard Hinnant's
/// `civil_from_days` (<https://howardhinnant.github.io/date_algorithms.html>). It counts in
/// 400-year eras starting on March 1st, so that the leap day falls at the end of a year.
fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let z = days + 719_468; // days since 0000-03-01
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097); // day of era, [0, 146096]
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365; // year of era, [0, 399]
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100); // day of year from March 1st, [0, 365]
    let mp = (5 * doy + 2) / 153; // month from March, [0, 11]
    let day = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let month = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn civil_dates() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
        assert_eq!(civil_from_days(11_017), (2000, 3, 1));
        assert_eq!(civil_from_days(19_782), (2024, 2, 29));
        assert_eq!(civil_from_days(47_541), (2100, 3, 1));
        assert_eq!(civil_from_days(20_778), (2026, 11, 21));
    }

    #[test]
    fn timestamps() {
        let stamp = |t: SystemTime| {
            let mut out = String::new();
            write_timestamp(&mut out, t);
            out
        };
        assert_eq!(stamp(UNIX_EPOCH), "1970-01-01T00:00:00.000Z");
        // 2026-11-21T10:46:48.123999Z
        let at = UNIX_EPOCH + Duration::from_millis(1_795_258_008_123) + Duration::from_micros(999);
        assert_eq!(stamp(at), "2026-11-21T10:46:48.123Z");
        assert_eq!(stamp(UNIX_EPOCH - Duration::from_micros(1)), "1969-12-31T23:59:59.999Z");
        let leap_day_end = UNIX_EPOCH + Duration::from_secs(11_017 * 86_400 - 1);
        assert_eq!(stamp(leap_day_end), "2000-02-29T23:59:59.000Z");
    }
}

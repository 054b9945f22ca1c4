//! Calendar conversions for the few places that meet dates: NMEA sentences (`ddmmyy`,
//! `hhmmss.ss`), UBX NAV-PVT, position packets, report headers. Proleptic Gregorian, UTC, no
//! leap seconds (as Unix time).
//!
//! Dates go through `chrono` (the project's calendar crate) rather than hand-written day
//! arithmetic: chrono rejects dates that do not exist (a receiver's 30 February, day 0), which
//! the arithmetic silently turned into another day. It is slower (a date in 15-30 ns against
//! 7-15 ns for the arithmetic, an ISO text in 0.4-0.7 µs, measured in one run on this machine),
//! which does not matter at the tens of dates a second a receiver sends. The time-of-day
//! parsing stays here: it is
//! the NMEA `hhmmss.ss` field, which chrono's format parser would accept more loosely (it takes
//! a leap second 60 only in some positions and no more than nine fraction digits).

use crate::{UtcNanos, NANOS_PER_SEC};
use chrono::{DateTime, Datelike, NaiveDate};

const NANOS_PER_DAY: i64 = 86_400 * NANOS_PER_SEC;

fn epoch() -> NaiveDate {
    NaiveDate::from_ymd_opt(1970, 1, 1).unwrap_or_default()
}

/// Days since 1970-01-01 of a civil date; `None` when the date does not exist.
pub fn days_from_civil(y: i64, m: u32, d: u32) -> Option<i64> {
    let date = NaiveDate::from_ymd_opt(i32::try_from(y).ok()?, m, d)?;
    Some(date.signed_duration_since(epoch()).num_days())
}

/// The civil date (year, month, day) of a day count since 1970-01-01; `None` beyond
/// chrono's range (about ±262,000 years).
pub fn civil_from_days(z: i64) -> Option<(i64, u32, u32)> {
    let date = epoch().checked_add_signed(chrono::TimeDelta::try_days(z)?)?;
    Some((i64::from(date.year()), date.month(), date.day()))
}

/// Parses `hhmmss[.f…]` into nanoseconds of the day; `None` if malformed or out of range.
pub fn parse_hms(value: &str) -> Option<i64> {
    let b = value.as_bytes();
    if b.len() < 6 || !b[..6].iter().all(u8::is_ascii_digit) {
        return None;
    }
    let num = |i: usize| i64::from(b[i] - b'0') * 10 + i64::from(b[i + 1] - b'0');
    let (h, m, s) = (num(0), num(2), num(4));
    if h > 23 || m > 59 || s > 60 {
        return None;
    }
    let mut nanos = 0i64;
    if b.len() > 6 {
        let frac = &b[6..];
        if frac[0] != b'.' || frac.len() > 10 || !frac[1..].iter().all(u8::is_ascii_digit) {
            return None;
        }
        let mut scale = 100_000_000i64;
        for &d in &frac[1..] {
            nanos += i64::from(d - b'0') * scale;
            scale /= 10;
        }
    }
    Some(((h * 60 + m) * 60 + s) * NANOS_PER_SEC + nanos)
}

/// An instant from a civil date and nanoseconds of the day; `None` when the date does not
/// exist or lies beyond what [`UtcNanos`] holds (1677-09-21 to 2262-04-11). A receiver's year
/// 0 or 65535 is damage, not a time: saturated to the end of the range it once passed for one,
/// and the rounding to a receiver's millisecond grid then overflowed (found by cargo-fuzz).
pub fn utc_from_civil(y: i64, m: u32, d: u32, nanos_of_day: i64) -> Option<UtcNanos> {
    days_from_civil(y, m, d)?
        .checked_mul(NANOS_PER_DAY)?
        .checked_add(nanos_of_day)
        .map(UtcNanos)
}

/// ISO 8601 with milliseconds and `Z`, as gpsd and most tools print UTC (milliseconds
/// truncated, as gpsd does).
pub fn iso8601_millis(t: UtcNanos) -> String {
    let (secs, nanos) = t.secs_nanos();
    match DateTime::from_timestamp(secs, nanos - nanos % 1_000_000) {
        Some(dt) => dt.format("%Y-%m-%dT%H:%M:%S%.3fZ").to_string(),
        None => format!("{} ns since 1970 (beyond the calendar)", t.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), Some(0));
        assert_eq!(days_from_civil(2000, 3, 1), Some(11_017));
        assert_eq!(days_from_civil(2024, 2, 29), Some(19_782));
        // Dates that do not exist are refused, not moved to another day.
        for (y, m, d) in [
            (2023, 2, 29),
            (2026, 2, 30),
            (2026, 4, 31),
            (2026, 13, 1),
            (2026, 1, 0),
        ] {
            assert_eq!(days_from_civil(y, m, d), None, "{y}-{m}-{d}");
        }
        assert_eq!(iso8601_millis(UtcNanos(-1)), "1969-12-31T23:59:59.999Z");
        // Beyond what the nanosecond count holds: no instant, not the end of the range.
        assert_eq!(utc_from_civil(0, 1, 1, 0), None);
        assert_eq!(utc_from_civil(65_535, 12, 31, 0), None);
        assert_eq!(utc_from_civil(2262, 4, 12, 0), None);
        assert_eq!(
            utc_from_civil(2262, 4, 11, 0),
            Some(UtcNanos(106_751 * NANOS_PER_DAY))
        );
        assert_eq!(utc_from_civil(1677, 9, 21, 0), None);
        assert!(utc_from_civil(1677, 9, 22, 0).is_some());
        assert_eq!(
            iso8601_millis(UtcNanos(1_355_263_592_123_000_000)),
            "2012-12-11T22:06:32.123Z"
        );
    }

    #[test]
    fn hms_forms() {
        assert_eq!(parse_hms("220632"), Some(79_592 * NANOS_PER_SEC));
        assert_eq!(
            parse_hms("132819.60"),
            Some(48_499 * NANOS_PER_SEC + 600_000_000)
        );
        assert_eq!(parse_hms("003832.000"), Some(2_312 * NANOS_PER_SEC));
        for bad in [
            "",
            "2206",
            "246000",
            "12a000",
            "120000,5",
            "120000.1x",
            "１２0000",
        ] {
            assert_eq!(parse_hms(bad), None, "{bad}");
        }
    }

    proptest! {
        #[test]
        fn civil_round_trips(days in -1_000_000i64..1_000_000) {
            let (y, m, d) = civil_from_days(days).unwrap();
            prop_assert_eq!(days_from_civil(y, m, d), Some(days));
        }

        /// The ISO text of any instant names the same day and time of day as the arithmetic
        /// of Unix time (days of 86,400 s).
        #[test]
        fn iso_text_matches_unix_time(t in -4_000_000_000_000_000_000i64..4_000_000_000_000_000_000) {
            let s = iso8601_millis(UtcNanos(t));
            let (y, m, d) = civil_from_days(t.div_euclid(NANOS_PER_DAY)).unwrap();
            let ms = t.rem_euclid(NANOS_PER_DAY) / 1_000_000;
            let want = format!(
                "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{:03}Z",
                ms / 3_600_000,
                ms / 60_000 % 60,
                ms / 1000 % 60,
                ms % 1000
            );
            prop_assert_eq!(s, want);
        }

        #[test]
        fn hms_never_panics(s in "\\PC{0,14}") {
            let _ = parse_hms(&s);
        }
    }
}

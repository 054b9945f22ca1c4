//! Calendar conversions for the few places that meet dates: NMEA sentences (`ddmmyy`,
//! `hhmmss.ss`), position packets, report headers. Proleptic Gregorian, UTC, no leap seconds
//! (as Unix time); chrono is kept out of the drivers on purpose: this is all they need.

use crate::{UtcNanos, NANOS_PER_SEC};

/// Days since 1970-01-01 of a civil date (H. Hinnant's `days_from_civil`).
pub fn days_from_civil(y: i64, m: u32, d: u32) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let m = i64::from(m);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The civil date (year, month, day) of a day count since 1970-01-01.
pub fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let y = yoe + era * 400;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (if m <= 2 { y + 1 } else { y }, m, d)
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

/// An instant from a civil date and nanoseconds of the day.
pub fn utc_from_civil(y: i64, m: u32, d: u32, nanos_of_day: i64) -> UtcNanos {
    UtcNanos(
        days_from_civil(y, m, d)
            .saturating_mul(86_400 * NANOS_PER_SEC)
            .saturating_add(nanos_of_day),
    )
}

/// ISO 8601 with milliseconds and `Z`, as gpsd and most tools print UTC.
pub fn iso8601_millis(t: UtcNanos) -> String {
    let days = t.0.div_euclid(86_400 * NANOS_PER_SEC);
    let nod = t.0.rem_euclid(86_400 * NANOS_PER_SEC);
    let (y, m, d) = civil_from_days(days);
    let ms = nod / 1_000_000;
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{:03}Z",
        ms / 3_600_000,
        ms / 60_000 % 60,
        ms / 1000 % 60,
        ms % 1000
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        assert_eq!(days_from_civil(2024, 2, 29), 19_782);
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
            let (y, m, d) = civil_from_days(days);
            prop_assert_eq!(days_from_civil(y, m, d), days);
        }

        #[test]
        fn hms_never_panics(s in "\\PC{0,14}") {
            let _ = parse_hms(&s);
        }
    }
}

//! Time types shared by every hilrig driver.
//!
//! All instants in hilrig are UTC nanoseconds since the Unix epoch in an `i64` (DESIGN.md, "Time").
//! A signed 64-bit count reaches to the year 2262, which outlives any test vehicle, and keeps
//! arithmetic exact where floating-point seconds would lose sub-microsecond resolution after 1970
//! + 100 days. Conversions to calendar time happen at the edges (CLI, reports), not here.
//!
//! The crate is deliberately tiny and has no I/O: drivers depend on it so that they agree on what a
//! timestamp is without depending on each other or on the rig.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

use serde::{Deserialize, Serialize};
use std::fmt;
use std::ops::{Add, Sub};

pub mod civil;

/// Nanoseconds in one second.
pub const NANOS_PER_SEC: i64 = 1_000_000_000;
/// Nanoseconds in one hour.
pub const NANOS_PER_HOUR: i64 = 3_600 * NANOS_PER_SEC;

/// An instant: UTC nanoseconds since 1970-01-01T00:00:00Z (leap seconds are not counted, as in
/// Unix time).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct UtcNanos(pub i64);

impl UtcNanos {
    /// The Unix epoch.
    pub const EPOCH: UtcNanos = UtcNanos(0);

    /// The system clock, for I/O shells that stamp what they receive (cores never read the
    /// clock: time is passed in).
    pub fn now() -> Self {
        let d = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        UtcNanos(i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
    }

    /// From whole seconds and a nanosecond fraction (as capture files store them).
    pub fn from_secs_nanos(secs: i64, nanos: u32) -> Self {
        UtcNanos(
            secs.saturating_mul(NANOS_PER_SEC)
                .saturating_add(i64::from(nanos)),
        )
    }

    /// Seconds since the epoch as a float; for output only (loses precision below ~0.2 µs).
    pub fn as_secs_f64(self) -> f64 {
        // Split to keep the fractional part exact before the final addition.
        let secs = self.0.div_euclid(NANOS_PER_SEC);
        let frac = self.0.rem_euclid(NANOS_PER_SEC);
        secs as f64 + frac as f64 * 1e-9
    }

    /// The start of the UTC hour that contains this instant.
    pub fn hour_floor(self) -> UtcNanos {
        UtcNanos(self.0.saturating_sub(self.0.rem_euclid(NANOS_PER_HOUR)))
    }

    /// Nanoseconds past the start of the UTC hour.
    pub fn nanos_past_hour(self) -> i64 {
        self.0.rem_euclid(NANOS_PER_HOUR)
    }

    /// Whole seconds and nanosecond fraction, the way pcap and ROS stamps store an instant.
    pub fn secs_nanos(self) -> (i64, u32) {
        (
            self.0.div_euclid(NANOS_PER_SEC),
            self.0.rem_euclid(NANOS_PER_SEC) as u32,
        )
    }
}

impl fmt::Display for UtcNanos {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (s, n) = self.secs_nanos();
        write!(f, "{s}.{n:09}")
    }
}

/// A signed span of time in nanoseconds.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Nanos(pub i64);

impl Nanos {
    /// From microseconds.
    pub const fn from_micros(us: i64) -> Self {
        Nanos(us * 1_000)
    }
    /// In seconds, for output and for floating-point physics.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }
}

// Arithmetic saturates: stamps come from files and sensors, and a corrupt one must not panic
// (debug) or wrap into a plausible-looking time (release).
impl Add<Nanos> for UtcNanos {
    type Output = UtcNanos;
    fn add(self, rhs: Nanos) -> UtcNanos {
        UtcNanos(self.0.saturating_add(rhs.0))
    }
}

impl Sub<Nanos> for UtcNanos {
    type Output = UtcNanos;
    fn sub(self, rhs: Nanos) -> UtcNanos {
        UtcNanos(self.0.saturating_sub(rhs.0))
    }
}

impl Sub<UtcNanos> for UtcNanos {
    type Output = Nanos;
    fn sub(self, rhs: UtcNanos) -> Nanos {
        Nanos(self.0.saturating_sub(rhs.0))
    }
}

/// An item as a driver delivers it: when the logger received it (`host`), when the sensor says it
/// was measured (`sensor`, where the sensor has a clock) and the decoded value.
///
/// `host` is the socket's kernel receive stamp live, or the capture record's stamp when reading a
/// file; the clock models of the rig map both onto one UTC base.
#[derive(Clone, Debug, PartialEq)]
pub struct Stamped<T> {
    /// Receive time on the logger.
    pub host: UtcNanos,
    /// Measurement time by the sensor's own clock, when it has one.
    pub sensor: Option<UtcNanos>,
    /// The item.
    pub value: T,
}

impl<T> Stamped<T> {
    /// An item with a host stamp only.
    pub fn host(host: UtcNanos, value: T) -> Self {
        Stamped {
            host,
            sensor: None,
            value,
        }
    }

    /// Keep the stamps, change the value.
    pub fn map<U>(self, f: impl FnOnce(T) -> U) -> Stamped<U> {
        Stamped {
            host: self.host,
            sensor: self.sensor,
            value: f(self.value),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn hour_floor_handles_negative_instants() {
        let t = UtcNanos(-1);
        assert_eq!(t.hour_floor(), UtcNanos(-NANOS_PER_HOUR));
        assert_eq!(t.nanos_past_hour(), NANOS_PER_HOUR - 1);
    }

    #[test]
    fn extremes_saturate_instead_of_overflowing() {
        assert_eq!(UtcNanos(i64::MIN).hour_floor(), UtcNanos(i64::MIN));
        assert_eq!(UtcNanos(i64::MAX) + Nanos(1), UtcNanos(i64::MAX));
        assert_eq!(UtcNanos(i64::MIN) - UtcNanos(1), Nanos(i64::MIN));
    }

    #[test]
    fn display_is_seconds_with_nine_decimals() {
        assert_eq!(
            UtcNanos::from_secs_nanos(1_355_263_594, 293_504_000).to_string(),
            "1355263594.293504000"
        );
    }

    proptest! {
        #[test]
        fn secs_nanos_round_trips(t in -4_000_000_000_000_000_000i64..4_000_000_000_000_000_000i64) {
            let (s, n) = UtcNanos(t).secs_nanos();
            prop_assert_eq!(UtcNanos::from_secs_nanos(s, n), UtcNanos(t));
            prop_assert!(n < 1_000_000_000);
        }
    }
}

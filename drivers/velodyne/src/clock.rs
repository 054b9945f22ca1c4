//! Absolute time of Velodyne timestamps.
//!
//! Sensors count microseconds past the top of the hour; the hour itself must come from
//! elsewhere. The best source is the RMC sentence of the position packets (GPS time, when the
//! sensor is PPS-synchronised); otherwise the logger's host clock, which only needs to be right
//! within ±30 minutes. The hour is chosen so that the result is nearest the reference, which is
//! correct across the top of the hour in both directions.

use crate::position::{PositionPacket, Rmc};
use hilrig_stamp::{UtcNanos, NANOS_PER_HOUR};

/// Host times before this (2000-01-01) are taken as an unset clock, not as a reference.
const PLAUSIBLE_HOST: UtcNanos = UtcNanos(946_684_800 * 1_000_000_000);

/// Where the hour of a resolved time came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HourSource {
    /// From the RMC sentence of a position packet.
    Rmc,
    /// From the logger's receive time.
    Host,
}

/// The instant `toh_us` past some hour that is nearest to `reference`.
pub fn resolve_toh(toh_us: u32, reference: UtcNanos) -> UtcNanos {
    // Saturating: a corrupt capture may carry a reference near the ends of the i64 range.
    let past = i64::from(toh_us) * 1_000;
    let hour = reference.hour_floor().0;
    let candidates = [
        hour.saturating_sub(NANOS_PER_HOUR),
        hour,
        hour.saturating_add(NANOS_PER_HOUR),
    ];
    let best = candidates
        .iter()
        .map(|h| h.saturating_add(past))
        .min_by_key(|t| t.abs_diff(reference.0))
        .unwrap_or(hour.saturating_add(past));
    UtcNanos(best)
}

/// Resolves the hour of data-packet timestamps from position packets and host time.
///
/// Sans-IO: feed position packets with their host receive time, ask for data packet times.
#[derive(Clone, Debug, Default)]
pub struct HourResolver {
    /// Last valid RMC: (its UTC, host time when its packet arrived).
    rmc: Option<(UtcNanos, UtcNanos)>,
    /// RMC sentences that failed to parse (checksum, fields).
    pub rmc_errors: u64,
}

impl HourResolver {
    /// Takes a position packet received at `host`.
    pub fn handle_position(&mut self, pkt: &PositionPacket, host: UtcNanos) -> Option<Rmc> {
        match pkt.rmc() {
            Some(Ok(rmc)) => {
                if let (true, Some(utc)) = (rmc.valid, rmc.utc()) {
                    // The RMC refers to the last PPS; the position packet's own timestamp is
                    // the sensor time it was sent at, so resolve that against the RMC time.
                    let sent = resolve_toh(pkt.timestamp_us, utc);
                    self.rmc = Some((sent, host));
                }
                Some(rmc)
            }
            Some(Err(_)) => {
                self.rmc_errors += 1;
                None
            }
            None => None,
        }
    }

    /// Whether a valid RMC has been seen: from then on every timestamp resolves.
    pub fn has_rmc(&self) -> bool {
        self.rmc.is_some()
    }

    /// Absolute time of a data packet stamped `toh_us`, received at `host`, or `None` when
    /// neither an RMC nor a plausible host clock gives the hour.
    pub fn resolve(&self, toh_us: u32, host: UtcNanos) -> Option<(UtcNanos, HourSource)> {
        if let Some((sensor_at, host_at)) = self.rmc {
            // Carry the RMC-based sensor time forward by host time elapsed: good to seconds,
            // which is all the hour choice needs.
            let reference = UtcNanos(sensor_at.0.saturating_add(host.0.saturating_sub(host_at.0)));
            return Some((resolve_toh(toh_us, reference), HourSource::Rmc));
        }
        if host >= PLAUSIBLE_HOST {
            return Some((resolve_toh(toh_us, host), HourSource::Host));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn hour_boundary_in_both_directions() {
        let h = UtcNanos(1_700_000_000 * 1_000_000_000).hour_floor();
        // Sensor just past the hour, host still just before it.
        let host = UtcNanos(h.0 + NANOS_PER_HOUR - 2_000_000);
        assert_eq!(
            resolve_toh(1_000, host),
            UtcNanos(h.0 + NANOS_PER_HOUR + 1_000_000)
        );
        // Sensor just before the hour, host just after.
        let host = UtcNanos(h.0 + 3_000_000);
        assert_eq!(resolve_toh(3_599_999_000, host), UtcNanos(h.0 - 1_000_000));
    }

    #[test]
    fn extreme_references_do_not_overflow() {
        for r in [i64::MIN, i64::MIN + 1, -1, i64::MAX - 1, i64::MAX] {
            let _ = resolve_toh(3_599_999_999, UtcNanos(r));
            let h = HourResolver {
                rmc: Some((UtcNanos(r), UtcNanos(-r.saturating_add(1)))),
                ..HourResolver::default()
            };
            let _ = h.resolve(0, UtcNanos(r));
        }
    }

    proptest! {
        #[test]
        fn resolution_recovers_any_true_time_within_half_an_hour(
            truth in 946_684_800_000_000_000i64..4_000_000_000_000_000_000,
            skew in -1_799_000_000_000i64..1_799_000_000_000,
        ) {
            let truth = UtcNanos(truth / 1000 * 1000);
            let toh = (truth.nanos_past_hour() / 1000) as u32;
            prop_assert_eq!(resolve_toh(toh, UtcNanos(truth.0 + skew)), truth);
        }
    }
}

//! The recorded lidar scans (`/velodyne_packets`) as re-simulation and comparison read them:
//! each scan's stamps and its packets' bytes, and the sensor time of a packet.

use super::cdr::CdrReader;
use super::read::{read, Event};
use super::topics;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::DATA_PACKET_SIZE;

/// One `/velodyne_packets` message.
#[derive(Clone, Debug)]
pub struct Scan {
    /// The message's log time, ns.
    pub log_time: u64,
    /// The message's publish time, ns.
    pub publish_time: u64,
    /// The scan header's stamp.
    pub stamp: UtcNanos,
    /// Every packet with its receive stamp.
    pub packets: Vec<(UtcNanos, [u8; DATA_PACKET_SIZE])>,
}

impl Scan {
    /// Its first and last packet's receive stamps (the scan's stamp for a scan without
    /// packets).
    pub fn span(&self) -> (UtcNanos, UtcNanos) {
        let last = self.packets.last().map_or(self.stamp, |p| p.0);
        (self.stamp.min(last), self.stamp.max(last))
    }
}

/// The scans of an MCAP's bytes, in file order, and what stopped the reading early (damage), if
/// anything. A scan that does not decode is an error naming the topic.
pub fn read_scans(bytes: &[u8]) -> (Vec<Scan>, Option<String>) {
    let mut scans = Vec::new();
    let damage = read(bytes, &mut |e| {
        if let Event::Message(m) = e {
            if m.channel.topic != topics::VELODYNE_PACKETS {
                return Ok(());
            }
            let bad = || format!("{}: a scan does not decode", m.channel.topic);
            let mut c = CdrReader::new(m.data).ok_or_else(bad)?;
            let stamp = c.header().ok_or_else(bad)?;
            let n = c.u32().ok_or_else(bad)?;
            let mut packets = Vec::with_capacity((n as usize).min(m.data.len() / DATA_PACKET_SIZE));
            for _ in 0..n {
                let t = c.time().ok_or_else(bad)?;
                let b = c.bytes(DATA_PACKET_SIZE).ok_or_else(bad)?;
                let mut a = [0u8; DATA_PACKET_SIZE];
                a.copy_from_slice(b);
                packets.push((t, a));
            }
            scans.push(Scan {
                log_time: m.log_time,
                publish_time: m.publish_time,
                stamp,
                packets,
            });
        }
        Ok(())
    })
    .err();
    (scans, damage)
}

/// The sensor time of a packet stamp (µs past the hour) near `near` (the recorder's time of it).
pub fn sensor_time(timestamp_us: u32, near: UtcNanos) -> UtcNanos {
    let hour = 3_600_000_000_000i64;
    let t = near.hour_floor().0 + i64::from(timestamp_us) * 1000;
    if t - near.0 > hour / 2 {
        UtcNanos(t - hour)
    } else if near.0 - t > hour / 2 {
        UtcNanos(t + hour)
    } else {
        UtcNanos(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drive across the full hour: a packet stamped 0.1 s past the hour but recorded (scan
    /// time) 0.1 s before it belongs to the new hour, and the other way round; both directions
    /// are needed, or the packets after the hour are cast an hour away from the trajectory.
    #[test]
    fn sensor_times_follow_the_recording_across_the_full_hour() {
        let s = 1_000_000_000i64;
        let ten = UtcNanos(1_795_356_000 * s - 1_795_356_000 * s % (3600 * s) + 3600 * s);
        // 0.1 s past ten, recorded at 9:59:59.9.
        let near = UtcNanos(ten.0 - s / 10);
        assert_eq!(sensor_time(100_000, near), UtcNanos(ten.0 + s / 10));
        // 0.1 s before ten (3599.9 s past nine), recorded at 10:00:00.1.
        let near = UtcNanos(ten.0 + s / 10);
        assert_eq!(sensor_time(3_599_900_000, near), UtcNanos(ten.0 - s / 10));
        // Within the hour: as stamped.
        let near = UtcNanos(ten.0 + 1800 * s);
        assert_eq!(sensor_time(1_800_000_000, near), UtcNanos(ten.0 + 1800 * s));
    }
}

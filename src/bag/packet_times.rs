//! When a recorded data packet's firings happened: the one reading of a scan's packets that
//! re-simulation, comparison and the gap workflow share, so that a firing is cast, decoded and
//! paired at one time whichever step looks at it.
//!
//! A packet's first firing is at its stamp: the sensor's microseconds past the hour, which are
//! GNSS time when the lidar is PPS-locked (placed in the hour of the recorder's receive time,
//! [`sensor_time`]); otherwise the recorder's receive time, whose clock model maps it onto the
//! logger clock. The rotation a packet belongs to starts at the scan's first packet that
//! decodes. A dual-return VLS-128 packet holds a single firing sequence, so its firings'
//! azimuths need the rate the sensor turned at since the packet before; that packet is
//! carried from scan to scan for a reader that walks the scans in order.

use super::scans::{sensor_time, Scan};
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::DataPacket;

/// When a packet's firings happened.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PacketTime {
    /// Reference (UTC) time of the packet stamp, i.e. of its first firing.
    pub first_firing: UtcNanos,
    /// Reference time of the first firing of the rotation the packet belongs to (the single pose
    /// used when `motion_distortion` is disabled).
    pub rotation_start: UtcNanos,
    /// The sensor's rotation rate, hundredths of a degree per µs, where the packet alone does
    /// not give it (a dual-return VLS-128 packet holds one firing sequence): the spin's for
    /// synthesized packets, the rate since the previous packet for recorded ones.
    pub rotation_rate: Option<f64>,
}

/// A recorded packet of a scan, read.
#[derive(Clone, Debug)]
pub enum Timed {
    /// A data packet, decoded, with its firing times.
    Packet {
        /// Its place in the scan.
        index: usize,
        /// The packet.
        packet: Box<DataPacket>,
        /// When its firings happened.
        time: PacketTime,
    },
    /// Bytes that are no data packet (counted by the caller, kept or left out as it needs).
    Undecodable {
        /// Its place in the scan.
        index: usize,
    },
}

/// Reads scans' packets with their firing times, carrying the packet before from one scan to
/// the next (use one per run, scan after scan in order; a reader that takes scans out of
/// order, on several cores, makes one per scan and loses only the first packet's rate).
#[derive(Clone, Debug, Default)]
pub struct PacketTimes {
    pps_locked: bool,
    previous: Option<DataPacket>,
}

impl PacketTimes {
    /// A reader for a run whose lidar is (`pps_locked`) or is not locked to GNSS time.
    pub fn new(pps_locked: bool) -> PacketTimes {
        PacketTimes {
            pps_locked,
            previous: None,
        }
    }

    /// The packets of `scan`, in order.
    pub fn of<'a>(&'a mut self, scan: &'a Scan) -> ScanPackets<'a> {
        ScanPackets {
            times: self,
            packets: scan.packets.iter().enumerate(),
            rotation_start: None,
        }
    }
}

/// The packets of one scan with their times ([`PacketTimes::of`]).
pub struct ScanPackets<'a> {
    times: &'a mut PacketTimes,
    packets: std::iter::Enumerate<
        std::slice::Iter<'a, (UtcNanos, [u8; hilrig_velodyne::DATA_PACKET_SIZE])>,
    >,
    rotation_start: Option<UtcNanos>,
}

impl Iterator for ScanPackets<'_> {
    type Item = Timed;

    fn next(&mut self) -> Option<Timed> {
        let (index, (received, bytes)) = self.packets.next()?;
        let Ok(packet) = DataPacket::decode(&bytes[..]) else {
            return Some(Timed::Undecodable { index });
        };
        let first_firing = if self.times.pps_locked {
            sensor_time(packet.timestamp_us, *received)
        } else {
            *received
        };
        let rotation_start = *self.rotation_start.get_or_insert(first_firing);
        let rotation_rate = self
            .times
            .previous
            .as_ref()
            .and_then(|q| hilrig_velodyne::decode::rate_between(q, &packet));
        self.times.previous = Some(packet.clone());
        Some(Timed::Packet {
            index,
            packet: Box::new(packet),
            time: PacketTime {
                first_firing,
                rotation_start,
                rotation_rate,
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hilrig_velodyne::packet::{Block, Channel, ReturnMode};
    use hilrig_velodyne::Model;

    /// A VLP-16 data packet stamped `us` past the hour with block azimuths from `azimuth`.
    fn packet(us: u32, azimuth: u16) -> [u8; hilrig_velodyne::DATA_PACKET_SIZE] {
        DataPacket {
            blocks: std::array::from_fn(|k| Block {
                flag: 0xEEFF,
                azimuth: (azimuth + 40 * k as u16) % 36000,
                channels: [Channel::default(); 32],
            }),
            timestamp_us: us,
            return_mode: ReturnMode::Strongest.byte(),
            product: Model::Vlp16.product(),
        }
        .encode()
    }

    /// The first decodable packet starts the rotation, the rate comes from the packet before
    /// (across scans too), and bytes that are no packet are named by their place.
    #[test]
    fn packets_carry_their_times_the_rotation_start_and_the_rate_since_the_one_before() {
        let hour = UtcNanos(3_600_000_000_000 * 400_000);
        let at = |us: i64| UtcNanos(hour.0 + us * 1000);
        let scan = |packets: Vec<(UtcNanos, [u8; 1206])>| Scan {
            log_time: 0,
            publish_time: 0,
            stamp: packets[0].0,
            packets,
        };
        let mut junk = [0u8; 1206];
        junk[0] = 1;
        let first = scan(vec![
            (at(1000), junk),
            (at(1100), packet(1000, 100)),
            (at(2430), packet(2327, 300)),
        ]);
        let second = scan(vec![(at(3700), packet(3654, 500))]);
        for pps in [true, false] {
            let mut times = PacketTimes::new(pps);
            let got: Vec<Timed> = times.of(&first).collect();
            assert!(matches!(got[0], Timed::Undecodable { index: 0 }));
            let Timed::Packet { index, time, .. } = &got[1] else {
                panic!("{got:?}")
            };
            assert_eq!(*index, 1);
            // PPS-locked: the sensor's stamp; else the receive time.
            let want = if pps { at(1000) } else { at(1100) };
            assert_eq!(time.first_firing, want);
            assert_eq!(time.rotation_start, want);
            assert_eq!(time.rotation_rate, None, "no packet before");
            let Timed::Packet { time: t2, .. } = &got[2] else {
                panic!("{got:?}")
            };
            assert_eq!(t2.rotation_start, want, "the scan's first decodable packet");
            let rate = t2.rotation_rate.expect("a rate since the packet before");
            assert!((rate - 200.0 / 1327.0).abs() < 1e-9, "{rate}");
            // The next scan: its own rotation, the rate since the last packet of the one before.
            let next: Vec<Timed> = times.of(&second).collect();
            let Timed::Packet { time: t3, .. } = &next[0] else {
                panic!("{next:?}")
            };
            assert_eq!(t3.rotation_start, t3.first_firing);
            assert!(t3.rotation_rate.is_some());
        }
    }
}

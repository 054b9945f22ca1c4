//! Packets into rotations, with loss accounting.
//!
//! A rotation ends where the azimuth passes the cut angle. The cut is at packet granularity
//! (the packet whose first block passes the cut starts the next rotation), which is what a
//! `VelodyneScan` message holds. Loss is counted from the sensor timestamps: every packet covers a
//! fixed time (the firing cycle times the columns per packet), so a gap of n periods is n - 1
//! lost packets. Time jumps (sensor re-synchronised, clock reset) are counted apart, not as loss.

use crate::model::Model;
use crate::packet::{DataPacket, DATA_PACKET_SIZE};
use hilrig_stamp::Stamped;

/// What rotation assembly needs of a packet: the azimuth of its first block and its sensor
/// timestamp. Implemented for decoded packets and for raw payloads, so that the recorder can
/// keep the bytes it will write without decoding and re-encoding every packet.
pub trait RotationPacket {
    /// Azimuth of the first block, hundredths of a degree.
    fn first_azimuth(&self) -> u16;
    /// Timestamp, microseconds past the hour.
    fn timestamp_us(&self) -> u32;
}

impl RotationPacket for DataPacket {
    fn first_azimuth(&self) -> u16 {
        self.blocks[0].azimuth
    }
    fn timestamp_us(&self) -> u32 {
        self.timestamp_us
    }
}

/// A data packet's payload as received, checked to be a packet of the rig's model.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RawDataPacket(pub Box<[u8; DATA_PACKET_SIZE]>);

impl RawDataPacket {
    /// Wraps a payload after checking that it is a data packet `model` sends
    /// ([`crate::check::data_packet`]).
    pub fn new(bytes: &[u8], model: Model) -> Result<RawDataPacket, crate::DecodeError> {
        let arr = RawDataPacket::check(bytes, model)?;
        Ok(RawDataPacket(Box::new(*arr)))
    }

    /// The checks of [`RawDataPacket::new`] without copying; gives the payload as an array.
    pub fn check(
        bytes: &[u8],
        model: Model,
    ) -> Result<&[u8; DATA_PACKET_SIZE], crate::DecodeError> {
        crate::check::data_packet(bytes, model)
    }

    /// Sensor timestamp of a checked payload, microseconds past the hour.
    pub fn timestamp_of(arr: &[u8; DATA_PACKET_SIZE]) -> u32 {
        u32::from_le_bytes([arr[1200], arr[1201], arr[1202], arr[1203]])
    }
}

impl RotationPacket for RawDataPacket {
    fn first_azimuth(&self) -> u16 {
        u16::from_le_bytes([self.0[2], self.0[3]])
    }
    fn timestamp_us(&self) -> u32 {
        u32::from_le_bytes([self.0[1200], self.0[1201], self.0[1202], self.0[1203]])
    }
}

/// Microseconds in an hour, where sensor timestamps wrap.
const HOUR_US: i64 = 3_600_000_000;
/// Gaps longer than this are a clock jump, not loss.
const MAX_PLAUSIBLE_GAP_US: i64 = 2_000_000;

/// Counts lost packets from consecutive sensor timestamps.
#[derive(Clone, Debug)]
pub struct LossCounter {
    period_us: f64,
    last_us: Option<u32>,
    /// Packets missing between received ones.
    pub lost: u64,
    /// Timestamps that went backwards or jumped by more than two seconds.
    pub time_jumps: u64,
    /// Packets seen.
    pub packets: u64,
}

impl LossCounter {
    /// For a stream whose packets each cover `period_us`.
    pub fn new(period_us: f64) -> Self {
        LossCounter {
            period_us,
            last_us: None,
            lost: 0,
            time_jumps: 0,
            packets: 0,
        }
    }

    /// Takes the next packet's timestamp; returns how many packets were lost before it.
    pub fn observe(&mut self, timestamp_us: u32) -> u64 {
        self.packets += 1;
        let Some(last) = self.last_us.replace(timestamp_us) else {
            return 0;
        };
        let gap = (i64::from(timestamp_us) - i64::from(last)).rem_euclid(HOUR_US);
        if gap == 0 || gap > MAX_PLAUSIBLE_GAP_US {
            self.time_jumps += 1;
            return 0;
        }
        let periods = (gap as f64 / self.period_us).round() as i64;
        if periods >= 2 {
            let lost = (periods - 1) as u64;
            self.lost += lost;
            lost
        } else {
            0
        }
    }
}

/// One rotation's packets.
#[derive(Clone, Debug, PartialEq)]
pub struct Rotation<P = DataPacket> {
    /// Packets in order of arrival.
    pub packets: Vec<Stamped<P>>,
    /// Packets lost inside this rotation (from timestamp gaps).
    pub lost_packets: u64,
    /// Whether the rotation began at the cut (false for the first, partial one).
    pub starts_at_cut: bool,
}

/// Groups packets into rotations.
#[derive(Clone, Debug)]
pub struct RotationAssembler<P = DataPacket> {
    cut: u16,
    current: Vec<Stamped<P>>,
    last_rel: Option<u16>,
    lost_in_current: u64,
    started_at_cut: bool,
    loss: LossCounter,
}

impl<P: RotationPacket> RotationAssembler<P> {
    /// Cuts at `cut_centideg` (hundredths of a degree, 0..36000); `period_us` is the time one
    /// packet covers ([`crate::decode::Decoder::packet_period_us`]).
    pub fn new(cut_centideg: u16, period_us: f64) -> Self {
        RotationAssembler {
            cut: cut_centideg % 36_000,
            current: Vec::new(),
            last_rel: None,
            lost_in_current: 0,
            started_at_cut: false,
            loss: LossCounter::new(period_us),
        }
    }

    /// Loss and time-jump totals.
    pub fn loss(&self) -> &LossCounter {
        &self.loss
    }

    /// Adds a packet; returns the rotation it completed, if any.
    pub fn push(&mut self, pkt: Stamped<P>) -> Option<Rotation<P>> {
        let lost = self.loss.observe(pkt.value.timestamp_us());
        let az = pkt.value.first_azimuth();
        let rel = ((i32::from(az) - i32::from(self.cut)).rem_euclid(36_000)) as u16;
        let crossed = matches!(self.last_rel, Some(prev) if rel < prev);
        self.last_rel = Some(rel);
        let mut done = None;
        if crossed && !self.current.is_empty() {
            done = Some(Rotation {
                packets: std::mem::take(&mut self.current),
                lost_packets: self.lost_in_current,
                starts_at_cut: self.started_at_cut,
            });
            self.lost_in_current = 0;
            self.started_at_cut = true;
        }
        self.lost_in_current += lost;
        self.current.push(pkt);
        done
    }

    /// The last, possibly partial, rotation.
    pub fn finish(&mut self) -> Option<Rotation<P>> {
        if self.current.is_empty() {
            return None;
        }
        Some(Rotation {
            packets: std::mem::take(&mut self.current),
            lost_packets: std::mem::take(&mut self.lost_in_current),
            starts_at_cut: self.started_at_cut,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ProductId;
    use crate::packet::{Block, Channel, ReturnModeByte, FLAG_UPPER};
    use hilrig_stamp::UtcNanos;

    fn pkt(az: u16, ts: u32) -> Stamped<DataPacket> {
        let b = Block {
            flag: FLAG_UPPER,
            azimuth: az,
            channels: [Channel::default(); 32],
        };
        Stamped::host(
            UtcNanos(i64::from(ts) * 1000),
            DataPacket {
                blocks: [b; 12],
                timestamp_us: ts,
                return_mode: ReturnModeByte(0x37),
                product: ProductId(0x22),
            },
        )
    }

    #[test]
    fn rotations_cut_at_the_angle_and_count_loss() {
        let period = 1327.104;
        let mut r = RotationAssembler::new(0, period);
        let mut rotations = Vec::new();
        let mut ts = 0.0f64;
        for i in 0..300u32 {
            ts += period;
            if i == 100 || i == 101 || i == 250 {
                continue; // lost
            }
            let az = ((i as f64 * 477.8) % 36_000.0) as u16;
            if let Some(rot) = r.push(pkt(az, ts as u32)) {
                rotations.push(rot);
            }
        }
        rotations.extend(r.finish());
        assert_eq!(r.loss().lost, 3);
        assert_eq!(rotations.iter().map(|r| r.lost_packets).sum::<u64>(), 3);
        assert_eq!(
            rotations.iter().map(|r| r.packets.len()).sum::<usize>(),
            297
        );
        assert!(!rotations[0].starts_at_cut);
        assert!(rotations[1].starts_at_cut);
        // 300 packets x 4.778° = 1433°: the cut is passed 3 times.
        assert_eq!(rotations.len(), 4);
    }

    #[test]
    fn hour_wrap_is_not_loss() {
        let mut c = LossCounter::new(552.96);
        c.observe(3_599_999_800);
        assert_eq!(c.observe(353), 0);
        assert_eq!(c.lost, 0);
        assert_eq!(c.time_jumps, 0);
        c.observe(100); // backwards
        assert_eq!(c.time_jumps, 1);
    }
}

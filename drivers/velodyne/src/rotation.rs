//! Packets into rotations, with loss accounting.
//!
//! A rotation ends where the azimuth passes the cut angle. The cut is at packet granularity
//! (the packet whose first block passes the cut starts the next rotation), which is what a
//! `VelodyneScan` message holds. Loss is counted from the sensor timestamps: every packet covers a
//! fixed time (the firing cycle times the columns per packet), so a gap of n periods is n - 1
//! lost packets. Time jumps (sensor re-synchronised, clock reset) are counted apart, not as loss;
//! an outage longer than the timestamps can bridge is told from a jump by the receive times
//! ([`LossCounter`]).

use crate::model::Model;
use crate::packet::{DataPacket, DATA_PACKET_SIZE};
use hilrig_stamp::{Stamped, UtcNanos};

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
/// Sensor timestamp gaps longer than this are a clock jump or an outage, not a few lost
/// packets; the receive times tell which.
const MAX_PLAUSIBLE_GAP_US: i64 = 2_000_000;

/// Counts lost packets from consecutive sensor timestamps, and from the receive times where the
/// sensor's clock cannot say.
///
/// A gap of up to two seconds in the sensor's timestamps is `n` periods, `n - 1` packets lost.
/// Beyond that, or backwards, the sensor's clock alone cannot tell an outage (a cable pulled,
/// a switch rebooting: the clock ran on, nothing came) from a jump of the clock itself (the
/// sensor locked to PPS, or was reset). The receive times can: when the receiver too saw
/// nothing for more than two seconds, it is an outage, and the packets that would have come
/// in that time are lost (counted from the receive times, which hold whether or not the
/// sensor's clock jumped as well). Otherwise the clock jumped, nothing is counted lost, and
/// the jump is counted.
///
/// Two things the receiver saw are not loss. A packet that arrived but was rejected (counted
/// by the caller, per reason, through [`LossCounter::rejected`]) is not counted lost again: a
/// second of damaged packets would otherwise read as a second of rejects *and* an outage. And
/// the pause between two inputs (captures of separate sessions, [`LossCounter::next_input`])
/// is not an outage: nothing was listening then. Captures cut from one session (a rotating
/// capture) follow each other within a packet period, and a packet missing at the cut still
/// counts; but an outage that spans a time-rotated capture's cut (`tcpdump -G` opens the next
/// file at the first packet after it) ends at the cut, and is taken for a pause.
///
/// Whether the receiver was silent is told by every packet heard, accepted or rejected: the
/// longest silence between them counts, so that one rejected packet after an outage does not
/// hide it (and at an input's start, the silence before its first packet heard).
#[derive(Clone, Debug)]
pub struct LossCounter {
    period_us: f64,
    last: Option<(u32, UtcNanos)>,
    /// When the receiver last heard a packet of the stream, accepted or rejected.
    last_heard: Option<UtcNanos>,
    /// The longest silence between packets heard since the last one observed, µs.
    longest_silence_us: i64,
    /// After [`LossCounter::next_input`], the silence before the input's first packet heard,
    /// µs (`None` until one is).
    boundary_silence_us: Option<i64>,
    /// Packets rejected since the last one observed.
    rejected_since: u64,
    /// The next packet observed begins another input.
    input_begins: bool,
    /// Packets missing between received ones (outages included).
    pub lost: u64,
    /// Gaps of more than two seconds in which nothing was received, their packets counted in
    /// `lost`.
    pub outages: u64,
    /// Timestamps that went backwards or jumped by more than two seconds while the packets
    /// kept coming.
    pub time_jumps: u64,
    /// Packets seen.
    pub packets: u64,
    /// Pauses of more than two seconds between inputs (not counted lost).
    pub input_pauses: u64,
}

impl LossCounter {
    /// For a stream whose packets each cover `period_us`.
    pub fn new(period_us: f64) -> Self {
        LossCounter {
            period_us,
            last: None,
            last_heard: None,
            longest_silence_us: 0,
            boundary_silence_us: None,
            rejected_since: 0,
            input_begins: false,
            lost: 0,
            outages: 0,
            time_jumps: 0,
            packets: 0,
            input_pauses: 0,
        }
    }

    /// A packet of the stream arrived at `received` but was not accepted (the caller counts
    /// it, by reason): not lost, and the receiver was not silent. Only a packet that may be
    /// this sensor's (damaged, its hour unknown), not another sensor's traffic on the port,
    /// whose packets would stand in for this one's lost ones.
    pub fn rejected(&mut self, received: UtcNanos) {
        self.rejected_since += 1;
        let silent = self.heard(received);
        if self.input_begins && self.boundary_silence_us.is_none() {
            self.boundary_silence_us = Some(silent);
        } else {
            self.longest_silence_us = self.longest_silence_us.max(silent);
        }
    }

    /// A packet heard at `received`: the silence before it, µs.
    fn heard(&mut self, received: UtcNanos) -> i64 {
        let silent = self
            .last_heard
            .map_or(0, |h| received.0.saturating_sub(h.0) / 1_000);
        self.last_heard = Some(self.last_heard.map_or(received, |h| h.max(received)));
        silent
    }

    /// The packets that follow come from another input (the next capture file).
    pub fn next_input(&mut self) {
        self.input_begins = true;
    }

    /// Takes the next packet's sensor timestamp and the time it was received; returns how
    /// many packets were lost before it.
    pub fn observe(&mut self, timestamp_us: u32, received: UtcNanos) -> u64 {
        self.packets += 1;
        let rejected = i64::try_from(std::mem::take(&mut self.rejected_since)).unwrap_or(i64::MAX);
        let input_begins = std::mem::take(&mut self.input_begins);
        let now = self.heard(received);
        let boundary_us = self.boundary_silence_us.take().unwrap_or(now);
        let silent_us = std::mem::take(&mut self.longest_silence_us)
            .max(now)
            .max(boundary_us);
        let Some((last, last_received)) = self.last.replace((timestamp_us, received)) else {
            return 0;
        };
        let gap = (i64::from(timestamp_us) - i64::from(last)).rem_euclid(HOUR_US);
        let periods = |gap_us: i64| (gap_us as f64 / self.period_us).round() as i64;
        // Since the last accepted packet, µs.
        let since_us = received.0.saturating_sub(last_received.0) / 1_000;
        let lost = if input_begins && boundary_us > MAX_PLAUSIBLE_GAP_US {
            // Between the inputs' sessions, whatever the sensor's clock did (a pause of a
            // whole number of hours leaves its timestamps near where they were).
            self.input_pauses += 1;
            0
        } else if gap == 0 || gap > MAX_PLAUSIBLE_GAP_US {
            if silent_us > MAX_PLAUSIBLE_GAP_US {
                self.outages += 1;
                periods(since_us) - 1 - rejected
            } else if rejected > 0 && gap > 0 && (gap - since_us).abs() <= MAX_PLAUSIBLE_GAP_US {
                // Packets kept coming but were rejected, and the sensor's clock moved on with
                // the receiver's: a run of rejected packets, not a jump.
                periods(gap) - 1 - rejected
            } else {
                self.time_jumps += 1;
                0
            }
        } else {
            periods(gap) - 1 - rejected
        };
        let lost = lost.max(0) as u64;
        self.lost += lost;
        lost
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

    /// The loss counter, to tell it of packets rejected ([`LossCounter::rejected`]) and of
    /// the next input ([`LossCounter::next_input`]).
    pub fn loss_mut(&mut self) -> &mut LossCounter {
        &mut self.loss
    }

    /// Adds a packet; returns the rotation it completed, if any.
    pub fn push(&mut self, pkt: Stamped<P>) -> Option<Rotation<P>> {
        let lost = self.loss.observe(pkt.value.timestamp_us(), pkt.host);
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
        let at = |us: i64| UtcNanos(us * 1_000);
        c.observe(3_599_999_800, at(0));
        assert_eq!(c.observe(353, at(553)), 0);
        assert_eq!(c.lost, 0);
        assert_eq!(c.time_jumps, 0);
        c.observe(100, at(1_106)); // backwards
        assert_eq!(c.time_jumps, 1);
        assert_eq!((c.lost, c.outages), (0, 0));
    }

    /// An outage longer than two seconds is loss, counted from the receive times; a jump of
    /// the sensor's clock while the packets keep coming is not.
    #[test]
    fn an_outage_is_loss_and_a_clock_jump_is_not() {
        let period = 552.96;
        let at = |us: f64| UtcNanos((us * 1_000.0) as i64);
        // Five seconds without a packet, the sensor's clock running on.
        let mut c = LossCounter::new(period);
        c.observe(1_000_000, at(0.0));
        let lost = c.observe(6_000_000, at(5_000_000.0));
        assert_eq!(lost, (5_000_000.0 / period).round() as u64 - 1);
        assert_eq!((c.outages, c.time_jumps), (1, 0));
        // The clock jumps by half an hour between two packets one period apart.
        let mut c = LossCounter::new(period);
        c.observe(1_000_000, at(0.0));
        assert_eq!(c.observe(1_801_000_000, at(period)), 0);
        assert_eq!((c.lost, c.outages, c.time_jumps), (0, 0, 1));
        // An outage of three seconds during which the clock was reset (backwards): the
        // receive times still count it.
        let mut c = LossCounter::new(period);
        c.observe(2_000_000_000, at(0.0));
        let lost = c.observe(50, at(3_000_000.0));
        assert_eq!(lost, (3_000_000.0 / period).round() as u64 - 1);
        assert_eq!((c.outages, c.time_jumps), (1, 0));
        // A gap within two seconds is counted from the sensor's timestamps, whatever the
        // receive times (the network delivers in bursts).
        let mut c = LossCounter::new(period);
        c.observe(0, at(0.0));
        assert_eq!(c.observe((4.0 * period) as u32, at(10.0)), 3);
    }

    /// Packets that arrived but were rejected are not lost as well, whether one or three
    /// seconds of them; a pause between two inputs is not an outage, but a packet missing
    /// where one capture of a session ends and the next begins is lost.
    #[test]
    fn rejected_packets_and_pauses_between_inputs_are_not_loss() {
        let period = 552.96;
        let at = |us: f64| UtcNanos((us * 1_000.0) as i64);
        let ts = |k: u32| (f64::from(k) * period) as u32;
        // One packet rejected between two accepted ones; then one missing outright.
        let mut c = LossCounter::new(period);
        c.observe(ts(0), at(0.0));
        c.rejected(at(period));
        assert_eq!(c.observe(ts(2), at(2.0 * period)), 0);
        assert_eq!(c.observe(ts(4), at(4.0 * period)), 1);
        assert_eq!((c.lost, c.outages, c.time_jumps), (1, 0, 0));
        // Three seconds of rejected packets (every one of them), then good ones again.
        let mut c = LossCounter::new(period);
        c.observe(ts(0), at(0.0));
        let run = (3_000_000.0 / period) as u32;
        for k in 1..=run {
            c.rejected(at(f64::from(k) * period));
        }
        assert_eq!(c.observe(ts(run + 1), at(f64::from(run + 1) * period)), 0);
        assert_eq!((c.lost, c.outages, c.time_jumps), (0, 0, 0));
        // The same run with three packets missing among the rejected ones: three lost.
        let mut c = LossCounter::new(period);
        c.observe(ts(0), at(0.0));
        for k in (1..=run).filter(|k| ![10, 500, 4000].contains(k)) {
            c.rejected(at(f64::from(k) * period));
        }
        assert_eq!(c.observe(ts(run + 1), at(f64::from(run + 1) * period)), 3);
        assert_eq!((c.outages, c.time_jumps), (0, 0));
        // A second capture of another session, 40 min or exactly an hour later (its
        // timestamps then near the first's): a pause, nothing lost.
        for (pause_us, ts_after) in [(2_400_000_000.0, 2_400_000_000), (3_600_000_000.0, ts(7))] {
            let mut c = LossCounter::new(period);
            c.observe(ts(0), at(0.0));
            c.next_input();
            assert_eq!(c.observe(ts_after, at(pause_us + 7.0 * period)), 0);
            assert_eq!(
                (c.lost, c.outages, c.time_jumps, c.input_pauses),
                (0, 0, 0, 1)
            );
        }
        // Without the second input, the same silence is an outage.
        let mut c = LossCounter::new(period);
        c.observe(ts(0), at(0.0));
        assert!(c.observe(3_000_000 + ts(7), at(3_000_000.0 + 7.0 * period)) > 5000);
        assert_eq!((c.outages, c.input_pauses), (1, 0));
        // The next session's first packet is rejected: still a pause, nothing lost.
        let mut c = LossCounter::new(period);
        c.observe(ts(0), at(0.0));
        c.next_input();
        c.rejected(at(2_400_000_000.0));
        assert_eq!(
            c.observe(2_400_000_000 + ts(1), at(2_400_000_000.0 + period)),
            0
        );
        assert_eq!(
            (c.lost, c.outages, c.time_jumps, c.input_pauses),
            (0, 0, 0, 1)
        );
        // Five seconds of silence ended by a rejected packet: an outage all the same, whether
        // the sensor's clock ran on or was reset.
        for after in [2_005_000_000 + ts(2), 50] {
            let mut c = LossCounter::new(period);
            c.observe(2_000_000_000, at(0.0));
            c.rejected(at(5_000_000.0 + period));
            assert!(c.observe(after, at(5_000_000.0 + 2.0 * period)) > 3000);
            assert_eq!((c.outages, c.time_jumps), (1, 0), "{after}");
        }
        // The next capture of a rotating capture: one packet missing at the cut is lost.
        let mut c = LossCounter::new(period);
        c.observe(ts(0), at(0.0));
        c.observe(ts(1), at(period));
        c.next_input();
        assert_eq!(c.observe(ts(3), at(3.0 * period)), 1);
        assert_eq!((c.lost, c.input_pauses), (1, 0));
    }
}

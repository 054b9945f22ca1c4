//! A spinning sensor's packet schedule: when each data packet's first firing happens and at
//! which azimuths its blocks start, for synthesis (re-simulation takes both from the recording).

use super::lidar::PacketTime;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::decode::firing_offset_us;
use hilrig_velodyne::packet::{Block, ReturnMode, BLOCKS, FLAGS_BANK};
use hilrig_velodyne::{Channel, DataPacket, Model};

/// A sensor spinning at a constant rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spin {
    /// Model.
    pub model: Model,
    /// Return mode.
    pub mode: ReturnMode,
    /// Rotations per minute (300..1200 on Velodyne sensors).
    pub rpm: f64,
    /// Azimuth at `t0`, degrees.
    pub phase_deg: f64,
    /// Reference time of the first packet's first firing.
    pub t0: UtcNanos,
}

/// A packet without returns, and when it fired.
#[derive(Clone, Debug, PartialEq)]
pub struct Skeleton {
    /// The packet (channels empty; stamp in the sensor's clock).
    pub packet: DataPacket,
    /// Its timing in reference time.
    pub time: PacketTime,
}

impl Spin {
    /// Time one packet covers, nanoseconds.
    pub fn packet_period_ns(&self) -> f64 {
        if self.model == Model::Vls128 || self.model.is_hdl64e() {
            return hilrig_velodyne::Decoder::new(self.model).packet_period_us(self.mode) * 1000.0;
        }
        let t = self.model.timing();
        let columns = if self.mode == ReturnMode::Dual {
            BLOCKS / 2
        } else {
            BLOCKS
        };
        columns as f64 * t.sequences_per_block as f64 * t.sequence_us * 1000.0
    }

    fn azimuth_deg(&self, t: f64) -> f64 {
        self.phase_deg + self.rpm * 6.0 * (t - self.t0.0 as f64) * 1e-9
    }

    /// Packet `k` of the schedule; `sensor_clock` maps reference time to the sensor's own clock
    /// (its stamps).
    pub fn packet(&self, k: u64, sensor_clock: impl Fn(UtcNanos) -> UtcNanos) -> Skeleton {
        let first = self.t0.0 as f64 + k as f64 * self.packet_period_ns();
        let dual = self.mode == ReturnMode::Dual;
        let vls = self.model == Model::Vls128;
        let hdl64 = self.model.is_hdl64e();
        let blocks = std::array::from_fn(|b| {
            // The VLS-128 spreads a sequence over four blocks (one per bank), and a dual packet
            // holds a single sequence; the HDL-64E over a block pair (two in dual mode).
            let column = match (vls, hdl64, dual) {
                (true, _, true) => 0,
                (true, _, false) => b / 4,
                (false, true, true) => b / 4,
                (false, true, false) => b / 2,
                (false, false, true) => b / 2,
                (false, false, false) => b,
            };
            let t = first + firing_offset_us(self.model, column, 0) * 1000.0;
            let az = (self.azimuth_deg(t) * 100.0).round().rem_euclid(36_000.0) as u16;
            let bank = if hdl64 {
                b % 2
            } else if !vls {
                0
            } else if dual {
                (b / 2) % 4
            } else {
                b % 4
            };
            Block {
                flag: FLAGS_BANK[bank],
                azimuth: az % 36_000,
                channels: [Channel::default(); 32],
            }
        });
        // The sensor defines a packet's firings by its stamp (whole microseconds): the first
        // firing is taken at the stamp's microsecond, so that re-simulation, which only has the
        // stamp, casts at the very same instants.
        let first_firing = UtcNanos(first.round() as i64);
        let first_firing = UtcNanos(first_firing.0 - sensor_clock(first_firing).0.rem_euclid(1000));
        let turns = (self.azimuth_deg(first) / 360.0).floor();
        let rotation_start =
            self.t0.0 as f64 + (turns * 360.0 - self.phase_deg) / (self.rpm * 6.0) * 1e9;
        let stamp = sensor_clock(first_firing);
        Skeleton {
            packet: DataPacket {
                blocks,
                timestamp_us: (stamp.nanos_past_hour() / 1000) as u32,
                return_mode: self.mode.byte(),
                product: self.model.product(),
            },
            time: PacketTime {
                first_firing,
                rotation_start: UtcNanos(rotation_start.round() as i64),
                rotation_rate: Some(self.rpm * 6.0 * 100.0 * 1e-6),
            },
        }
    }

    /// Number of packets in `seconds`.
    pub fn packets_in(&self, seconds: f64) -> u64 {
        (seconds * 1e9 / self.packet_period_ns()).floor() as u64
    }
}

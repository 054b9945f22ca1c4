//! From a data packet to points: firing times, interpolated azimuths, return pairing, geometry.
//!
//! Three packet layouts (the 16/32-laser models' blocks, the VLS-128's four banks, the HDL-64E's
//! block pairs) share one point geometry and one decoder, which this file holds: the
//! [`Decoder`], the [`Point`] it makes, the two-point pass and the helpers every layout uses.
//! Each layout's firing table sits beside the code that reads it, one file per layout:
//! `vlp_hdl32.rs` (VLP-16, Puck Hi-Res, VLP-32A/B/C, HDL-32E), `vls128.rs` and `hdl64e.rs`.
//!
//! Conventions (those of ros-drivers and velodyne-decoder, so clouds line up in every tool):
//! x forward, y left, z up in the sensor frame; the ring is the laser's index sorted by
//! elevation; distance 0 means no return and yields no point.
//!
//! Azimuth of each firing: the block azimuth plus the packet's mean rotation rate times the
//! firing's time after the block's first firing. The mean over the packet (first to last block)
//! rather than block-to-block differences is used because single block azimuths jitter by an
//! encoder count, which a per-block rate would amplify; it needs no guess for the last block and
//! is exact across the 359.99° -> 0° wrap.

use crate::calibration::Calibration;
use crate::error::DecodeError;
use crate::model::Model;
use crate::packet::{Channel, DataPacket, ReturnMode, BLOCKS, CHANNELS, FLAGS_BANK};

mod hdl64e;
mod vlp_hdl32;
mod vls128;

pub use hdl64e::{hdl64e_dual, hdl64e_firing, hdl64e_offset_us, hdl64e_rate};
pub use vlp_hdl32::firing_offset_us;
pub use vls128::{vls128_firing, vls128_offset_us, vls128_rate};

/// A laser's id in firing order (what the calibration is indexed by).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct LaserId(pub u8);

/// Which return a point is, numbered as velodyne-decoder does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum ReturnType {
    /// Strongest return, or the only return in single-return modes.
    Strongest = 1,
    /// Last return.
    Last = 2,
    /// Dual mode where last and strongest are the same echo.
    Both = 3,
}

/// One decoded return.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Laser id (firing order).
    pub laser: LaserId,
    /// Ring (elevation order, lowest 0).
    pub ring: u8,
    /// Block index in the packet (0-11) the return came from.
    pub block: u8,
    /// Interpolated azimuth of the firing in degrees, [0, 360).
    pub azimuth_deg: f32,
    /// Raw distance count (resolution per model).
    pub distance_raw: u16,
    /// Measured distance in metres (raw × resolution + calibration correction).
    pub distance_m: f32,
    /// Calibrated reflectivity.
    pub intensity: u8,
    /// Which return.
    pub return_type: ReturnType,
    /// Firing time after the packet timestamp, in nanoseconds.
    pub time_offset_ns: u32,
    /// Forward, metres.
    pub x: f32,
    /// Left, metres.
    pub y: f32,
    /// Up, metres.
    pub z: f32,
}

/// Decodes data packets of one sensor into points.
#[derive(Clone, Debug)]
pub struct Decoder {
    model: Model,
    calibration: Calibration,
    /// Firing time after the packet stamp (µs) by column and channel.
    offsets_us: [[f64; CHANNELS]; BLOCKS],
    /// Per channel: laser id.
    laser_of_channel: [u8; CHANNELS],
}
/// Rotation in hundredths of a degree from `a` to `b`, across the wrap at 360°.
fn azimuth_span(a: u16, b: u16) -> f64 {
    f64::from((i32::from(b % 36_000) - i32::from(a % 36_000)).rem_euclid(36_000))
}

/// Why block `block`'s flag does not fit `model`: another model's bank flag, or no Velodyne
/// flag at all.
fn flag_error(model: Model, block: usize, flag: u16) -> DecodeError {
    let offset = block * crate::packet::BLOCK_SIZE;
    if FLAGS_BANK.contains(&flag) {
        DecodeError::ForeignBankFlag {
            block,
            offset,
            got: flag,
            model,
        }
    } else {
        DecodeError::BadBlockFlag {
            block,
            offset,
            got: flag,
        }
    }
}

/// The rotation rate between two packets, hundredths of a degree per µs, from their first
/// blocks' azimuths and their stamps; `None` when the stamps are not a few ms apart in order
/// (a gap, a new hour, packets from different spins).
pub fn rate_between(previous: &DataPacket, pkt: &DataPacket) -> Option<f64> {
    let span = azimuth_span(previous.blocks[0].azimuth, pkt.blocks[0].azimuth);
    let dt = f64::from(pkt.timestamp_us.wrapping_sub(previous.timestamp_us));
    (dt > 0.0 && dt < 10_000.0).then(|| span / dt)
}

impl Decoder {
    /// A decoder with the model's built-in geometry.
    pub fn new(model: Model) -> Decoder {
        Decoder::with_calibration(model, Calibration::builtin(model))
    }

    /// A decoder with a calibration (which must have the model's laser count).
    pub fn with_calibration(model: Model, calibration: Calibration) -> Decoder {
        let mut offsets_us = [[0.0; CHANNELS]; BLOCKS];
        for (col, row) in offsets_us.iter_mut().enumerate() {
            for (ch, v) in row.iter_mut().enumerate() {
                *v = firing_offset_us(model, col, ch);
            }
        }
        let n = model.lasers();
        let mut laser_of_channel = [0u8; CHANNELS];
        for (ch, l) in laser_of_channel.iter_mut().enumerate() {
            *l = (ch % n) as u8;
        }
        Decoder {
            model,
            calibration,
            offsets_us,
            laser_of_channel,
        }
    }

    /// The model decoded.
    pub fn model(&self) -> Model {
        self.model
    }

    /// The geometry used.
    pub fn calibration(&self) -> &Calibration {
        &self.calibration
    }

    /// Duration covered by one packet in this return mode, in µs (the expected packet period).
    pub fn packet_period_us(&self, mode: ReturnMode) -> f64 {
        let t = self.model.timing();
        if self.model == Model::Vls128 {
            // Four blocks per sequence: three sequences, or one in dual mode.
            let sequences = if mode == ReturnMode::Dual { 1.0 } else { 3.0 };
            return sequences * t.sequence_us;
        }
        if self.model.is_hdl64e() {
            // A block pair per sequence: six, or three in dual mode.
            let sequences = if mode == ReturnMode::Dual { 3.0 } else { 6.0 };
            return sequences * t.sequence_us;
        }
        let columns = match mode {
            ReturnMode::Dual => BLOCKS / 2,
            _ => BLOCKS,
        };
        columns as f64 * t.sequence_us * t.sequences_per_block as f64
    }

    /// Appends the packet's returns to `out`, in packet order (for dual return: per channel the
    /// last return, then the strongest, or one point of type `Both` when they coincide).
    pub fn decode_into(&self, pkt: &DataPacket, out: &mut Vec<Point>) -> Result<(), DecodeError> {
        self.with_two_point(out, |out| self.decode_into_plain(pkt, out))
    }

    /// Runs `decode` and then the two-point pass over the points it appended, when the
    /// calibration has near-point corrections.
    fn with_two_point(
        &self,
        out: &mut Vec<Point>,
        decode: impl FnOnce(&mut Vec<Point>) -> Result<(), DecodeError>,
    ) -> Result<(), DecodeError> {
        let start = out.len();
        let r = decode(out);
        if !self.calibration.two_point.is_empty() {
            self.apply_two_point(&mut out[start..]);
        }
        r
    }
    /// Like [`Decoder::decode_into`], with the rotation rate (hundredths of a degree per µs)
    /// taken from the packet before when the packet itself cannot give it: a dual-return
    /// VLS-128 packet holds a single firing sequence, so its firings' azimuths need the rate
    /// the sensor turned at since the previous packet (as velodyne-decoder and VeloView
    /// interpolate). `previous` is that packet; without it such a packet is decoded at its
    /// block azimuths, uninterpolated.
    pub fn decode_into_after(
        &self,
        pkt: &DataPacket,
        previous: Option<&DataPacket>,
        out: &mut Vec<Point>,
    ) -> Result<(), DecodeError> {
        self.decode_into_at_rate(pkt, previous.and_then(|p| rate_between(p, pkt)), out)
    }

    /// Like [`Decoder::decode_into_after`], with the rotation rate since the packet before
    /// already known (`None`: unknown): for a caller that keeps the rate rather than the
    /// packet (hilrig's packet-times iterator).
    pub fn decode_into_at_rate(
        &self,
        pkt: &DataPacket,
        rate: Option<f64>,
        out: &mut Vec<Point>,
    ) -> Result<(), DecodeError> {
        let mode = pkt.return_mode.mode();
        if self.model == Model::Vls128 && mode == Some(ReturnMode::Dual) {
            return self.with_two_point(out, |out| {
                self.decode_vls128(pkt, ReturnMode::Dual, rate, out)
            });
        }
        self.decode_into(pkt, out)
    }

    /// Decodes a packet into a new vector.
    pub fn decode(&self, pkt: &DataPacket) -> Result<Vec<Point>, DecodeError> {
        let mut v = Vec::with_capacity(BLOCKS * CHANNELS);
        self.decode_into(pkt, &mut v)?;
        Ok(v)
    }
    /// The point of laser `laser`'s return `channel`, fired at azimuth `az` (hundredths of a
    /// degree) `t` µs after the packet's first firing.
    #[inline(always)]
    fn point_at(
        &self,
        laser: usize,
        block: usize,
        az: f64,
        t: f64,
        channel: Channel,
        return_type: ReturnType,
    ) -> Point {
        let cal = &self.calibration.lasers[laser];
        let (raw, reflectivity) = (channel.distance, channel.reflectivity);
        let d = f64::from(raw) * self.calibration.distance_resolution_m + cal.distance_correction_m;
        let (sin_a, cos_a) = crate::calibration::azimuth_sin_cos(az, cal.rot_correction_rad);
        let vo = cal.vertical_offset_m;
        let xy = d * cal.cos_vert - vo * cal.sin_vert;
        let ho = cal.horizontal_offset_m;
        Point {
            laser: LaserId(laser as u8),
            ring: cal.ring,
            block: block as u8,
            azimuth_deg: (az * 0.01) as f32,
            distance_raw: raw,
            distance_m: d as f32,
            intensity: reflectivity,
            return_type,
            time_offset_ns: (t * 1000.0).round() as u32,
            x: (xy * cos_a + ho * sin_a) as f32,
            y: (-xy * sin_a + ho * cos_a) as f32,
            z: (d * cal.sin_vert + vo * cal.cos_vert + cal.z_offset_m) as f32,
        }
    }

    /// Moves the points of lasers with a two-point distance calibration (HDL-64E; the formulas
    /// in [`crate::calibration`]'s docs) to where x, y and z each take their own corrected
    /// distance. A second pass over the packet's points, so that the common path (no two-point
    /// laser) stays the small inlined loop it is: a branch on each point there halved the
    /// VLS-128's decoding speed.
    fn apply_two_point(&self, points: &mut [Point]) {
        let table = &self.calibration.two_point;
        for p in points {
            let laser = usize::from(p.laser.0);
            let Some(Some(tp)) = table.get(laser) else {
                continue;
            };
            let cal = &self.calibration.lasers[laser];
            let d = self.calibration.metres(laser, p.distance_raw);
            let az = f64::from(p.azimuth_deg) * 100.0;
            let (sin_a, cos_a) = crate::calibration::azimuth_sin_cos(az, cal.rot_correction_rad);
            let (vo, ho) = (cal.vertical_offset_m, cal.horizontal_offset_m);
            let xy = d * cal.cos_vert - vo * cal.sin_vert;
            // Velodyne's frame: x sideways (ours is -y), y forward (ours is x).
            let (xx, yy) = (
                (xy * sin_a - ho * cos_a).abs(),
                (xy * cos_a + ho * sin_a).abs(),
            );
            let (cx, cy) = tp.corrections(cal.distance_correction_m, xx, yy);
            let xy_x = (d + cx) * cal.cos_vert - vo * cal.sin_vert;
            let xy_y = (d + cy) * cal.cos_vert - vo * cal.sin_vert;
            p.x = (xy_y * cos_a + ho * sin_a) as f32;
            p.y = (-xy_x * sin_a + ho * cos_a) as f32;
            p.z = ((d + cy) * cal.sin_vert + vo * cal.cos_vert + cal.z_offset_m) as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ProductId;
    use crate::packet::{Block, FLAGS_BANK};
    use proptest::prelude::*;

    #[test]
    fn two_point_calibration_moves_near_points_by_the_near_corrections() {
        let mut cal = Calibration::builtin(Model::Hdl64eS3);
        let l = &mut cal.lasers[0];
        *l = crate::calibration::LaserCalibration {
            vertical_rad: 0.0,
            rot_correction_rad: 0.0,
            sin_vert: 0.0,
            cos_vert: 1.0,
            distance_correction_m: 1.0,
            ..*l
        };
        cal.two_point = vec![None; 64];
        cal.two_point[0] = Some(crate::calibration::TwoPointCorrection {
            x_m: 1.05,
            y_m: 0.97,
        });
        let d = Decoder::with_calibration(Model::Hdl64eS3, cal.clone());
        let at = |raw: u16, az: f64| {
            let ch = Channel {
                distance: raw,
                reflectivity: 1,
            };
            let mut p = [d.point_at(0, 0, az, 0.0, ch, ReturnType::Strongest)];
            d.apply_two_point(&mut p);
            p[0]
        };
        // Straight ahead at |y| = 1.93 m (Velodyne's y is forward): the near y correction.
        let p = at(465, 0.0);
        assert!((p.distance_m - 1.93).abs() < 1e-6);
        assert!((p.x - (465.0 * 0.002 + 0.97)).abs() < 1e-6, "{}", p.x);
        assert!(p.y.abs() < 1e-6 && p.z.abs() < 1e-6);
        // To the right at |x| = 2.4 m: the near x correction.
        let p = at(700, 9000.0);
        assert!((p.y + (700.0 * 0.002 + 1.05)).abs() < 1e-5, "{}", p.y);
        // At the far point the far correction alone.
        let p = at(12_020, 0.0);
        assert!((p.x - 25.04).abs() < 1e-5, "{}", p.x);
        // Without the near values: the far correction everywhere.
        cal.two_point.clear();
        let plain = Decoder::with_calibration(Model::Hdl64eS3, cal);
        let ch = Channel {
            distance: 465,
            reflectivity: 1,
        };
        let p = plain.point_at(0, 0, 0.0, 0.0, ch, ReturnType::Strongest);
        assert!((p.x - 1.93).abs() < 1e-6);
    }

    pub(super) fn arb_vls_packet() -> impl Strategy<Value = DataPacket> {
        let channel = (any::<u16>(), any::<u8>()).prop_map(|(distance, reflectivity)| Channel {
            distance,
            reflectivity,
        });
        let block = (
            prop_oneof![4 => (0usize..4).prop_map(|b| FLAGS_BANK[b]), 1 => any::<u16>()],
            0u16..=36_000,
            proptest::array::uniform32(channel),
        )
            .prop_map(|(flag, azimuth, channels)| Block {
                flag,
                azimuth,
                channels,
            });
        (
            proptest::collection::vec(block, BLOCKS),
            any::<u32>(),
            prop_oneof![Just(0x37u8), Just(0x38), Just(0x39), any::<u8>()],
        )
            .prop_map(|(blocks, timestamp_us, rm)| DataPacket {
                blocks: blocks.try_into().expect("12 blocks"),
                timestamp_us,
                return_mode: crate::packet::ReturnModeByte(rm),
                product: ProductId::VLS128,
            })
    }

    proptest! {
        /// Any HDL-64E packet with any plausible two-point calibration: the same points as
        /// without it (count, lasers, raw distances, azimuths), each finite and moved by no
        /// more than the corrections allow: |near - far| times 1.11 at the sensor (the near
        /// point lies 2.4 m out), growing linearly with distance as the manual's formula
        /// extrapolates.
        #[test]
        fn two_point_pass_moves_points_only_as_the_corrections_allow(
            pkt in arb_vls_packet().prop_map(|mut p| {
                // The 64E's layout: upper and lower bank blocks in pairs.
                for (i, b) in p.blocks.iter_mut().enumerate() {
                    b.flag = FLAGS_BANK[i % 2];
                }
                p
            }),
            near in proptest::collection::vec((-0.05f64..0.05, -0.05f64..0.05), 64),
            far in -0.5f64..2.0,
        ) {
            let mut cal = Calibration::builtin(Model::Hdl64eS3);
            for l in &mut cal.lasers {
                l.distance_correction_m = far;
            }
            let plain = Decoder::with_calibration(Model::Hdl64eS3, cal.clone());
            cal.two_point = near
                .iter()
                .map(|&(x, y)| Some(crate::calibration::TwoPointCorrection { x_m: far + x, y_m: far + y }))
                .collect();
            let two = Decoder::with_calibration(Model::Hdl64eS3, cal);
            let (a, b) = (plain.decode(&pkt), two.decode(&pkt));
            prop_assert!(a.is_ok() && b.is_ok(), "a 64E packet decodes");
            if let (Ok(a), Ok(b)) = (a, b) {
                prop_assert_eq!(a.len(), b.len());
                for (p, q) in a.iter().zip(&b) {
                    prop_assert_eq!((p.laser, p.distance_raw, p.azimuth_deg), (q.laser, q.distance_raw, q.azimuth_deg));
                    prop_assert!(q.x.is_finite() && q.y.is_finite() && q.z.is_finite());
                    let (dx, dy) = near[usize::from(p.laser.0)];
                    let worst = dx.abs().max(dy.abs()) * (1.11 + f64::from(p.distance_m).abs() / 22.0);
                    let moved = f64::from((p.x - q.x).abs().max((p.y - q.y).abs()).max((p.z - q.z).abs()));
                    prop_assert!(moved <= worst + 1e-3, "moved {} m, at most {} m", moved, worst);
                }
            }
        }
    }
}

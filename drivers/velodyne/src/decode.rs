//! From a data packet to points: firing times, interpolated azimuths, return pairing, geometry.
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
use crate::packet::{Channel, DataPacket, ReturnMode, BLOCKS, CHANNELS};

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

/// Time of a channel's firing after the first firing of its column, in µs, per model.
pub fn firing_offset_us(model: Model, column: usize, channel: usize) -> f64 {
    let t = model.timing();
    let per_seq = CHANNELS / t.sequences_per_block;
    let lasers_per_seq = per_seq;
    let seq_in_block = channel / lasers_per_seq;
    let within = channel % lasers_per_seq;
    let firing_index = within / t.simultaneous;
    column as f64 * t.sequence_us * t.sequences_per_block as f64
        + seq_in_block as f64 * t.sequence_us
        + firing_index as f64 * t.firing_us
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
        let columns = match mode {
            ReturnMode::Dual => BLOCKS / 2,
            _ => BLOCKS,
        };
        columns as f64 * t.sequence_us * t.sequences_per_block as f64
    }

    /// Appends the packet's returns to `out`, in packet order (for dual return: per channel the
    /// last return, then the strongest, or one point of type `Both` when they coincide).
    pub fn decode_into(&self, pkt: &DataPacket, out: &mut Vec<Point>) -> Result<(), DecodeError> {
        let mode = match pkt.return_mode.mode() {
            Some(m) => m,
            // HDL-32E firmware before 2.2.20 (2016) leaves the byte at 0 and has no dual mode.
            None if self.model == Model::Hdl32e && pkt.return_mode.0 == 0 => ReturnMode::Strongest,
            None => return Err(DecodeError::UnsupportedReturnMode(pkt.return_mode.0)),
        };
        let dual = mode == ReturnMode::Dual;
        let columns = if dual { BLOCKS / 2 } else { BLOCKS };
        let rate = self.rotation_rate(pkt, columns);
        out.reserve(CHANNELS * BLOCKS);
        let mut emit = |block: usize, column: usize, ch: usize, c: Channel, rt: ReturnType| {
            out.push(self.point(pkt, block, column, ch, rate, c, rt));
        };
        if dual {
            for col in 0..columns {
                let (lb, sb) = (&pkt.blocks[2 * col], &pkt.blocks[2 * col + 1]);
                for ch in 0..CHANNELS {
                    let (l, s) = (lb.channels[ch], sb.channels[ch]);
                    if l.distance == s.distance {
                        if s.distance > 0 {
                            emit(2 * col + 1, col, ch, s, ReturnType::Both);
                        }
                        continue;
                    }
                    if l.distance > 0 {
                        emit(2 * col, col, ch, l, ReturnType::Last);
                    }
                    if s.distance > 0 {
                        emit(2 * col + 1, col, ch, s, ReturnType::Strongest);
                    }
                }
            }
        } else {
            let rt = if mode == ReturnMode::Last {
                ReturnType::Last
            } else {
                ReturnType::Strongest
            };
            for (b, block) in pkt.blocks.iter().enumerate() {
                for (ch, &c) in block.channels.iter().enumerate() {
                    if c.distance > 0 {
                        emit(b, b, ch, c, rt);
                    }
                }
            }
        }
        Ok(())
    }

    /// The packet's mean rotation rate in hundredths of a degree per microsecond, over `columns`
    /// firing columns (12, or 6 in dual mode).
    pub fn rotation_rate(&self, pkt: &DataPacket, columns: usize) -> f64 {
        let first = pkt.blocks[0].azimuth % 36_000;
        let last = pkt.blocks[BLOCKS - 1].azimuth % 36_000;
        let span = (i32::from(last) - i32::from(first)).rem_euclid(36_000);
        let duration = self.offsets_us[columns.clamp(1, BLOCKS) - 1][0];
        if duration > 0.0 {
            f64::from(span) / duration
        } else {
            0.0
        }
    }

    /// Interpolated azimuth (hundredths of a degree, [0, 36000)) of the firing of channel `ch`
    /// in `column`, whose azimuth is stored in `block`, at rotation `rate`
    /// ([`Decoder::rotation_rate`]); and its time after the packet stamp in µs.
    #[inline]
    pub fn firing(
        &self,
        pkt: &DataPacket,
        block: usize,
        column: usize,
        ch: usize,
        rate: f64,
    ) -> (f64, f64) {
        let t = self.offsets_us[column][ch];
        let t0 = self.offsets_us[column][0];
        let mut az = f64::from(pkt.blocks[block].azimuth % 36_000) + rate * (t - t0);
        if az >= 36_000.0 {
            az -= 36_000.0;
        }
        (az, t)
    }

    /// Laser id of a channel.
    #[inline]
    pub fn laser_of_channel(&self, ch: usize) -> usize {
        usize::from(self.laser_of_channel[ch % CHANNELS])
    }

    /// Decodes a packet into a new vector.
    pub fn decode(&self, pkt: &DataPacket) -> Result<Vec<Point>, DecodeError> {
        let mut v = Vec::with_capacity(BLOCKS * CHANNELS);
        self.decode_into(pkt, &mut v)?;
        Ok(v)
    }

    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn point(
        &self,
        pkt: &DataPacket,
        block: usize,
        column: usize,
        ch: usize,
        rate: f64,
        channel: Channel,
        return_type: ReturnType,
    ) -> Point {
        let (az, t) = self.firing(pkt, block, column, ch, rate);
        let laser = self.laser_of_channel[ch];
        let cal = &self.calibration.lasers[usize::from(laser)];
        let (raw, reflectivity) = (channel.distance, channel.reflectivity);
        let d = f64::from(raw) * self.calibration.distance_resolution_m + cal.distance_correction_m;
        let (sin_a, cos_a) = crate::calibration::azimuth_sin_cos(az, cal.rot_correction_rad);
        let xy = d * cal.cos_vert - cal.vertical_offset_m * cal.sin_vert;
        let ho = cal.horizontal_offset_m;
        Point {
            laser: LaserId(laser),
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
            z: (d * cal.sin_vert + cal.vertical_offset_m * cal.cos_vert + cal.z_offset_m) as f32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ProductId;
    use crate::packet::{Block, Channel, ReturnMode, FLAG_UPPER};

    fn packet(model: Model, mode: ReturnMode, az0: u16, step: u16) -> DataPacket {
        let blocks = std::array::from_fn(|i| {
            let col = if mode == ReturnMode::Dual { i / 2 } else { i };
            Block {
                flag: FLAG_UPPER,
                azimuth: ((u32::from(az0) + col as u32 * u32::from(step)) % 36_000) as u16,
                channels: [Channel {
                    distance: 5000,
                    reflectivity: 10,
                }; CHANNELS],
            }
        });
        DataPacket {
            blocks,
            timestamp_us: 0,
            return_mode: mode.byte(),
            product: model.product(),
        }
    }

    #[test]
    fn vlp16_timing_matches_the_manual() {
        // Manual: block n, sequence s, laser l fires at 110.592 n + 55.296 s + 2.304 l µs.
        assert!(
            (firing_offset_us(Model::Vlp16, 3, 16 + 5) - (3.0 * 110.592 + 55.296 + 5.0 * 2.304))
                .abs()
                < 1e-9
        );
        // VLP-32C fires lasers in pairs.
        assert!((firing_offset_us(Model::Vlp32c, 0, 31) - 15.0 * 2.304).abs() < 1e-9);
        assert!(
            (firing_offset_us(Model::Hdl32e, 11, 31) - (11.0 * 46.08 + 31.0 * 1.152)).abs() < 1e-9
        );
    }

    #[test]
    fn azimuth_is_continuous_across_the_wrap() {
        let d = Decoder::new(Model::Hdl32e);
        let p = packet(Model::Hdl32e, ReturnMode::Strongest, 35_950, 17);
        let pts = d.decode(&p).unwrap();
        for w in pts.windows(2) {
            let diff = (w[1].azimuth_deg - w[0].azimuth_deg).rem_euclid(360.0);
            // Consecutive firings are at most one recharge gap apart (~0.04° here), never 360°.
            assert!(diff < 0.05, "{} -> {}", w[0].azimuth_deg, w[1].azimuth_deg);
            assert!(w[1].azimuth_deg < 360.0 && w[1].azimuth_deg >= 0.0);
        }
    }

    #[test]
    fn dual_pairs_last_then_strongest_and_merges_equal_returns() {
        let d = Decoder::new(Model::Vlp16);
        let mut p = packet(Model::Vlp16, ReturnMode::Dual, 0, 40);
        p.blocks[0].channels[0] = Channel {
            distance: 700,
            reflectivity: 5,
        };
        p.blocks[1].channels[0] = Channel {
            distance: 600,
            reflectivity: 90,
        };
        p.blocks[0].channels[1] = Channel {
            distance: 0,
            reflectivity: 0,
        };
        p.blocks[1].channels[1] = Channel {
            distance: 0,
            reflectivity: 0,
        };
        let pts = d.decode(&p).unwrap();
        assert_eq!(pts[0].return_type, ReturnType::Last);
        assert_eq!(pts[0].distance_raw, 700);
        assert_eq!(pts[1].return_type, ReturnType::Strongest);
        assert_eq!(pts[1].intensity, 90);
        assert_eq!(pts[2].return_type, ReturnType::Both);
        assert_eq!(pts[2].laser, LaserId(2));
        // 6 columns x 32 channels: one pair split into two points, one empty, 190 merged.
        assert_eq!(pts.len(), 192);
    }

    #[test]
    fn vlp32c_distance_uses_4mm_counts_and_azimuth_offsets() {
        let d = Decoder::new(Model::Vlp32c);
        let p = packet(Model::Vlp32c, ReturnMode::Strongest, 0, 20);
        let pts = d.decode(&p).unwrap();
        assert!((pts[0].distance_m - 20.0).abs() < 1e-6);
        // Laser 0 points 1.4° clockwise of the block azimuth: y < 0 at azimuth ~0.
        let expected_y = -(20.0 * (-25f64).to_radians().cos() * 1.4f64.to_radians().sin());
        assert!(
            (f64::from(pts[0].y) - expected_y).abs() < 1e-4,
            "{} vs {expected_y}",
            pts[0].y
        );
    }

    #[test]
    fn unknown_return_mode_is_an_error() {
        let mut p = packet(Model::Hdl32e, ReturnMode::Strongest, 0, 20);
        p.return_mode = crate::packet::ReturnModeByte(0x00);
        p.product = ProductId(0x21);
        // Old HDL-32E firmware writes 0: single return.
        assert_eq!(Decoder::new(Model::Hdl32e).decode(&p).unwrap().len(), 384);
        p.return_mode = crate::packet::ReturnModeByte(0x42);
        assert_eq!(
            Decoder::new(Model::Hdl32e).decode(&p),
            Err(DecodeError::UnsupportedReturnMode(0x42))
        );
    }
}

//! The 16/32-laser layouts (VLP-16, Puck Hi-Res, VLP-32A/B/C, HDL-32E): one bank of lasers
//! (every block flagged `FF EE`), a firing column per block, or per block pair in dual return;
//! their firing table, by model, and the code that reads them.
//!
//! A file of its own beside `vls128.rs` and `hdl64e.rs`: this layout's firing table is the
//! default of [`firing_offset_us`], and its reader the default of the decoder, from which the
//! two banked layouts branch off first.

use super::hdl64e::hdl64e_offset_us;
use super::vls128::vls128_offset_us;
use super::{flag_error, Decoder, Point, ReturnType};
use crate::error::DecodeError;
use crate::model::Model;
use crate::packet::{Channel, DataPacket, ReturnMode, BLOCKS, CHANNELS, FLAG_UPPER};

/// Time of a channel's firing after the first firing of its column, in µs, per model.
pub fn firing_offset_us(model: Model, column: usize, channel: usize) -> f64 {
    if model.is_hdl64e() {
        return hdl64e_offset_us(model, 2 * column, channel % CHANNELS);
    }
    if model == Model::Vls128 {
        return vls128_offset_us(column, channel);
    }
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
    /// [`Decoder::decode_into`] without the two-point pass.
    pub(super) fn decode_into_plain(
        &self,
        pkt: &DataPacket,
        out: &mut Vec<Point>,
    ) -> Result<(), DecodeError> {
        if self.model.is_hdl64e() {
            // Bytes 1204-1205 are status bytes on the HDL-64E, not a return mode.
            return self.decode_hdl64e(pkt, out);
        }
        let mode = match pkt.return_mode.mode() {
            Some(m) => m,
            // HDL-32E firmware before 2.2.20 (2016) leaves the byte at 0 and has no dual mode.
            None if self.model == Model::Hdl32e && pkt.return_mode.0 == 0 => ReturnMode::Strongest,
            None => return Err(DecodeError::UnsupportedReturnMode(pkt.return_mode.0)),
        };
        if self.model == Model::Vls128 {
            return self.decode_vls128(pkt, mode, None, out);
        }
        if self.model.is_hdl64e() {
            return self.decode_hdl64e(pkt, out);
        }
        if let Some((block, b)) = pkt
            .blocks
            .iter()
            .enumerate()
            .find(|(_, b)| b.flag != FLAG_UPPER)
        {
            // Only the VLS-128 (and the HDL-64E) use the other banks' flags.
            return Err(flag_error(self.model, block, b.flag));
        }
        let dual = mode == ReturnMode::Dual;
        let columns = if dual { BLOCKS / 2 } else { BLOCKS };
        let rate = self.rotation_rate(pkt, columns);
        out.reserve(CHANNELS * BLOCKS);
        // Points are pushed here directly: through a closure, the compiler stopped inlining
        // the point computation (13 % of the HDL-32E's decode speed, measured).
        if dual {
            for col in 0..columns {
                let (lb, sb) = (&pkt.blocks[2 * col], &pkt.blocks[2 * col + 1]);
                for ch in 0..CHANNELS {
                    let (l, s) = (lb.channels[ch], sb.channels[ch]);
                    if l.distance == s.distance {
                        if s.distance > 0 {
                            out.push(self.point(
                                pkt,
                                2 * col + 1,
                                col,
                                ch,
                                rate,
                                s,
                                ReturnType::Both,
                            ));
                        }
                        continue;
                    }
                    if l.distance > 0 {
                        out.push(self.point(pkt, 2 * col, col, ch, rate, l, ReturnType::Last));
                    }
                    if s.distance > 0 {
                        out.push(self.point(
                            pkt,
                            2 * col + 1,
                            col,
                            ch,
                            rate,
                            s,
                            ReturnType::Strongest,
                        ));
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
                        out.push(self.point(pkt, b, b, ch, rate, c, rt));
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
        let laser = usize::from(self.laser_of_channel[ch]);
        self.point_at(laser, block, az, t, channel, return_type)
    }
}

#[cfg(test)]
mod tests {
    use super::super::LaserId;
    use super::*;
    use crate::model::ProductId;
    use crate::packet::Block;

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

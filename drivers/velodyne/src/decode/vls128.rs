//! The VLS-128's layout: four blocks per firing sequence, one per bank of 32 lasers (the
//! block's flag names the bank), three sequences per packet or one in dual return; its firing
//! table (groups of 8 lasers one slot apart) and the code that reads it.
//!
//! A file of its own because the layout shares nothing with the others but the point geometry:
//! its timing, its rotation rate and its dual-return pairing are read here alone (and by the
//! simulator, which fires the same table).

use super::{azimuth_span, Decoder, Point, ReturnType};
use crate::error::DecodeError;
use crate::model::Model;
use crate::packet::{Channel, DataPacket, ReturnMode, BLOCKS, CHANNELS, FLAGS_BANK};

/// When the VLS-128's laser `laser` (0..128) fires in firing sequence `column` of a packet, µs
/// after the packet's first firing: sequences of 20 slots, laser groups of 8 one slot apart,
/// and 2 idle slots after the eighth group (lasers 64.. fire two slots later).
pub fn vls128_offset_us(column: usize, laser: usize) -> f64 {
    let t = Model::Vls128.timing();
    column as f64 * t.sequence_us + (laser / 8 + laser / 64 * 2) as f64 * t.firing_us
}
/// Where and when the VLS-128's laser `laser` fires in block `block` of `pkt`: the azimuth
/// (hundredths of a degree, 0..36000) and the time after the packet's first firing (µs), with
/// `rate` the rotation rate (hundredths of a degree per µs). Strongest/last packets hold three
/// sequences (block / 4), `dual` ones one.
pub fn vls128_firing(
    pkt: &DataPacket,
    block: usize,
    laser: usize,
    rate: f64,
    dual: bool,
) -> (f64, f64) {
    let column = if dual { 0 } else { block / 4 };
    let t = vls128_offset_us(column, laser);
    let mut az =
        f64::from(pkt.blocks[block].azimuth % 36_000) + rate * (t - vls128_offset_us(column, 0));
    if az >= 36_000.0 {
        az -= 36_000.0;
    }
    (az, t)
}

/// The rotation rate a VLS-128 strongest/last packet shows within itself (its first and third
/// sequences' azimuths), hundredths of a degree per µs.
pub fn vls128_rate(pkt: &DataPacket) -> f64 {
    azimuth_span(pkt.blocks[0].azimuth, pkt.blocks[8].azimuth)
        / (vls128_offset_us(2, 0) - vls128_offset_us(0, 0))
}
impl Decoder {
    /// The VLS-128 layout: each block holds one bank of 32 lasers (its flag names the bank),
    /// four blocks make a firing sequence; strongest or last: three sequences per packet;
    /// dual: one sequence in eight blocks (last, then strongest return per bank) and four
    /// unused blocks.
    pub(super) fn decode_vls128(
        &self,
        pkt: &DataPacket,
        mode: ReturnMode,
        rate_hint: Option<f64>,
        out: &mut Vec<Point>,
    ) -> Result<(), DecodeError> {
        let dual = mode == ReturnMode::Dual;
        let used = if dual { 8 } else { BLOCKS };
        let mut banks = [0usize; BLOCKS];
        for (b, bank) in banks.iter_mut().enumerate().take(used) {
            let flag = pkt.blocks[b].flag;
            *bank =
                FLAGS_BANK
                    .iter()
                    .position(|f| *f == flag)
                    .ok_or(DecodeError::BadBlockFlag {
                        block: b,
                        offset: b * crate::packet::BLOCK_SIZE,
                        got: flag,
                    })?;
        }
        // Single modes: the first blocks of the first and third sequence span two sequences.
        let rate = if dual {
            rate_hint.unwrap_or(0.0)
        } else {
            vls128_rate(pkt)
        };
        out.reserve(used * CHANNELS);
        let mut emit = |block: usize, laser: usize, c: Channel, rt: ReturnType| {
            let (az, t) = vls128_firing(pkt, block, laser, rate, dual);
            out.push(self.point_at(laser, block, az, t, c, rt));
        };
        if dual {
            for pair in 0..4 {
                let (lb, sb) = (2 * pair, 2 * pair + 1);
                if banks[lb] != banks[sb] {
                    return Err(DecodeError::BankPairMismatch {
                        block: sb,
                        offset: sb * crate::packet::BLOCK_SIZE,
                        got: pkt.blocks[sb].flag,
                        pair: pkt.blocks[lb].flag,
                    });
                }
                for ch in 0..CHANNELS {
                    let laser = banks[lb] * CHANNELS + ch;
                    let (l, s) = (pkt.blocks[lb].channels[ch], pkt.blocks[sb].channels[ch]);
                    if l.distance == s.distance {
                        if s.distance > 0 {
                            emit(sb, laser, s, ReturnType::Both);
                        }
                        continue;
                    }
                    if l.distance > 0 {
                        emit(lb, laser, l, ReturnType::Last);
                    }
                    if s.distance > 0 {
                        emit(sb, laser, s, ReturnType::Strongest);
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
                        emit(b, banks[b] * CHANNELS + ch, c, rt);
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::arb_vls_packet;
    use super::*;
    use crate::packet::FLAG_UPPER;
    use proptest::prelude::*;

    proptest! {
        /// Any VLS-128 packet, alone or after any other, and the same bytes read as an
        /// HDL-64E: an error or points of real lasers
        /// at azimuths in [0°, 360°), never a panic; every point is a non-zero return of a
        /// block whose flag names its bank.
        #[test]
        fn any_packet_decodes_or_errors_without_panicking(
            pkt in arb_vls_packet(),
            prev in arb_vls_packet(),
        ) {
            let d = Decoder::new(Model::Vls128);
            for previous in [None, Some(&prev)] {
                let mut out = Vec::new();
                if d.decode_into_after(&pkt, previous, &mut out).is_ok() {
                    prop_assert!(out.len() <= BLOCKS * CHANNELS);
                    for p in &out {
                        prop_assert!(usize::from(p.laser.0) < 128);
                        prop_assert!((0.0..=360.0).contains(&p.azimuth_deg));
                        prop_assert!(p.distance_raw > 0);
                        let block = &pkt.blocks[usize::from(p.block)];
                        prop_assert_eq!(FLAGS_BANK[usize::from(p.laser.0) / 32], block.flag);
                    }
                }
            }
            // The other models refuse the other banks' flags.
            if pkt.blocks.iter().any(|b| b.flag != FLAG_UPPER) {
                prop_assert!(Decoder::new(Model::Vlp16).decode(&pkt).is_err());
            }
            // The same bytes as an HDL-64E packet: an error or lasers of its two banks.
            for m in [Model::Hdl64eS2, Model::Hdl64eS3] {
                if let Ok(points) = Decoder::new(m).decode(&pkt) {
                    prop_assert!(points.len() <= BLOCKS * CHANNELS);
                    for p in &points {
                        prop_assert!(p.laser.0 < 64 && p.distance_raw > 0);
                        prop_assert!((0.0..=360.0).contains(&p.azimuth_deg));
                        let block = &pkt.blocks[usize::from(p.block)];
                        prop_assert_eq!(FLAGS_BANK[usize::from(p.laser.0) / 32], block.flag);
                    }
                }
            }
        }
    }
    /// The firing table: groups of 8 one slot apart, two idle slots after the eighth group,
    /// 20 slots a sequence.
    #[test]
    fn firing_table_follows_the_manual() {
        let slot = crate::model::VLS128_SLOT_US;
        assert!((vls128_offset_us(0, 7) - 0.0).abs() < 1e-12);
        assert!((vls128_offset_us(0, 8) - slot).abs() < 1e-12);
        assert!((vls128_offset_us(0, 63) - 7.0 * slot).abs() < 1e-12);
        assert!((vls128_offset_us(0, 64) - 10.0 * slot).abs() < 1e-12);
        assert!((vls128_offset_us(0, 127) - 17.0 * slot).abs() < 1e-12);
        assert!((vls128_offset_us(2, 0) - 40.0 * slot).abs() < 1e-12);
        assert!(
            (Decoder::new(Model::Vls128).packet_period_us(ReturnMode::Strongest) - 60.0 * slot)
                .abs()
                < 1e-9
        );
    }
}

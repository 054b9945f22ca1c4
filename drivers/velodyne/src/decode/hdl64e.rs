//! The HDL-64E's layout (S2, S3): blocks in pairs, the upper bank's then the lower bank's, one
//! pair per firing sequence; its firing table (the manuals' "laser firing time table"), its
//! dual-return detection and the code that reads it.
//!
//! A file of its own because the layout shares nothing with the others but the point geometry
//! and the two-point calibration pass (which the decoder applies to every layout, in
//! `mod.rs`).

use super::{azimuth_span, flag_error, Decoder, Point, ReturnType};
use crate::error::DecodeError;
use crate::model::Model;
use crate::packet::{DataPacket, ReturnMode, BLOCKS, CHANNELS, FLAGS_BANK};

/// The HDL-64E's firing table (its manuals' "laser firing time table"): when channel `j` of
/// block `block` fires, µs after the packet's first firing, in the strongest-return layout (a
/// block pair per firing sequence: the upper bank's laser j and the lower bank's laser 32 + j
/// fire together; four lasers per group, the groups 6 µs (S2) or 7.2 µs (S3) apart).
pub fn hdl64e_offset_us(model: Model, block: usize, j: usize) -> f64 {
    let (sequence, group, pattern) = match model {
        Model::Hdl64eS2 => (48.0, 6.0, [0.0, 1.26, 2.46, 3.66]),
        _ => (57.6, 7.2, [0.0, 1.3, 2.5, 3.7]),
    };
    sequence * (block / 2) as f64 + group * (j / 4) as f64 + pattern[j % 4]
}

/// Whether an HDL-64E packet is dual return: its return-mode byte when it carries one (hilrig's
/// synthesizer writes it), else the azimuths (the S3 repeats a sequence's azimuth in its
/// last-return blocks, as velodyne-decoder and VeloView detect it).
pub fn hdl64e_dual(pkt: &DataPacket) -> bool {
    match pkt.return_mode.mode() {
        Some(m) => m == ReturnMode::Dual,
        None => pkt.blocks[0].azimuth == pkt.blocks[2].azimuth,
    }
}

/// Where and when the HDL-64E's laser `laser` (bank × 32 + channel) in block `block` of `pkt`
/// fires, as [`vls128_firing`](super::vls128_firing) does for the VLS-128; `dual` is
/// [`hdl64e_dual`] of the packet (found once per packet, not per firing).
pub fn hdl64e_firing(
    model: Model,
    pkt: &DataPacket,
    block: usize,
    laser: usize,
    rate: f64,
    dual: bool,
) -> (f64, f64) {
    let j = laser % CHANNELS;
    let (t0, t) = if dual {
        let column = block / 4 * 2;
        (
            hdl64e_offset_us(model, column, 0),
            hdl64e_offset_us(model, column + block % 2, j),
        )
    } else {
        (
            hdl64e_offset_us(model, block / 2 * 2, 0),
            hdl64e_offset_us(model, block, j),
        )
    };
    let mut az = f64::from(pkt.blocks[block].azimuth % 36_000) + rate * (t - t0);
    if az >= 36_000.0 {
        az -= 36_000.0;
    }
    (az, t)
}

/// The rotation rate an HDL-64E packet shows from its first to its last block.
pub fn hdl64e_rate(model: Model, pkt: &DataPacket) -> f64 {
    let last = if hdl64e_dual(pkt) { 5 } else { 11 };
    azimuth_span(pkt.blocks[0].azimuth, pkt.blocks[11].azimuth)
        / (hdl64e_offset_us(model, last, 0) - hdl64e_offset_us(model, 0, 0))
}
impl Decoder {
    /// The HDL-64E layout: blocks in pairs, upper bank (lasers 0..32, flag `FF EE`) then lower
    /// (32..64, `FF DD`), one pair per firing sequence: six per packet; in dual return (S3)
    /// three sequences, each as strongest upper, strongest lower, last upper, last lower.
    pub(super) fn decode_hdl64e(
        &self,
        pkt: &DataPacket,
        out: &mut Vec<Point>,
    ) -> Result<(), DecodeError> {
        let bank = |b: usize| -> Result<usize, DecodeError> {
            let flag = pkt.blocks[b].flag;
            FLAGS_BANK[..2]
                .iter()
                .position(|f| *f == flag)
                .ok_or_else(|| flag_error(self.model, b, flag))
        };
        let rate = hdl64e_rate(self.model, pkt);
        let dual = hdl64e_dual(pkt);
        out.reserve(BLOCKS * CHANNELS);
        if dual {
            for i in (0..BLOCKS).filter(|i| i % 4 < 2) {
                let k = bank(i)?;
                if bank(i + 2)? != k {
                    return Err(DecodeError::BankPairMismatch {
                        block: i + 2,
                        offset: (i + 2) * crate::packet::BLOCK_SIZE,
                        got: pkt.blocks[i + 2].flag,
                        pair: pkt.blocks[i].flag,
                    });
                }
                for j in 0..CHANNELS {
                    let laser = k * CHANNELS + j;
                    let (s, l) = (pkt.blocks[i].channels[j], pkt.blocks[i + 2].channels[j]);
                    let (az, t) = hdl64e_firing(self.model, pkt, i, laser, rate, dual);
                    if l.distance == s.distance {
                        if s.distance > 0 {
                            out.push(self.point_at(laser, i, az, t, s, ReturnType::Both));
                        }
                        continue;
                    }
                    if l.distance > 0 {
                        out.push(self.point_at(laser, i + 2, az, t, l, ReturnType::Last));
                    }
                    if s.distance > 0 {
                        out.push(self.point_at(laser, i, az, t, s, ReturnType::Strongest));
                    }
                }
            }
        } else {
            // The S3 can report the last return alone; the byte says so when it is there.
            let rt = if pkt.return_mode.mode() == Some(ReturnMode::Last) {
                ReturnType::Last
            } else {
                ReturnType::Strongest
            };
            for i in 0..BLOCKS {
                let k = bank(i)?;
                for (j, &c) in pkt.blocks[i].channels.iter().enumerate() {
                    if c.distance > 0 {
                        let laser = k * CHANNELS + j;
                        let (az, t) = hdl64e_firing(self.model, pkt, i, laser, rate, dual);
                        out.push(self.point_at(laser, i, az, t, c, rt));
                    }
                }
            }
        }
        Ok(())
    }
}

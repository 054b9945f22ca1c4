//! From a data packet to points: firing times, interpolated azimuths, return pairing, geometry.
//!
//! Long file: three packet layouts (the 16/32-laser models' blocks, the VLS-128's four banks,
//! the HDL-64E's block pairs) share one point geometry and one decoder; each layout's firing
//! table sits beside the code that reads it.
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
use crate::packet::{Channel, DataPacket, ReturnMode, BLOCKS, CHANNELS, FLAGS_BANK, FLAG_UPPER};

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

/// When the VLS-128's laser `laser` (0..128) fires in firing sequence `column` of a packet, µs
/// after the packet's first firing: sequences of 20 slots, laser groups of 8 one slot apart,
/// and 2 idle slots after the eighth group (lasers 64.. fire two slots later).
pub fn vls128_offset_us(column: usize, laser: usize) -> f64 {
    let t = Model::Vls128.timing();
    column as f64 * t.sequence_us + (laser / 8 + laser / 64 * 2) as f64 * t.firing_us
}

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
/// fires, as [`vls128_firing`] does for the VLS-128; `dual` is [`hdl64e_dual`] of the packet
/// (found once per packet, not per firing).
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

    /// [`Decoder::decode_into`] without the two-point pass.
    fn decode_into_plain(&self, pkt: &DataPacket, out: &mut Vec<Point>) -> Result<(), DecodeError> {
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
        let mode = pkt.return_mode.mode();
        if self.model == Model::Vls128 && mode == Some(ReturnMode::Dual) {
            let rate = previous.and_then(|p| rate_between(p, pkt));
            return self.with_two_point(out, |out| {
                self.decode_vls128(pkt, ReturnMode::Dual, rate, out)
            });
        }
        self.decode_into(pkt, out)
    }

    /// The HDL-64E layout: blocks in pairs, upper bank (lasers 0..32, flag `FF EE`) then lower
    /// (32..64, `FF DD`), one pair per firing sequence: six per packet; in dual return (S3)
    /// three sequences, each as strongest upper, strongest lower, last upper, last lower.
    fn decode_hdl64e(&self, pkt: &DataPacket, out: &mut Vec<Point>) -> Result<(), DecodeError> {
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

    /// The VLS-128 layout: each block holds one bank of 32 lasers (its flag names the bank),
    /// four blocks make a firing sequence; strongest or last: three sequences per packet;
    /// dual: one sequence in eight blocks (last, then strongest return per bank) and four
    /// unused blocks.
    fn decode_vls128(
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
        let laser = usize::from(self.laser_of_channel[ch]);
        self.point_at(laser, block, az, t, channel, return_type)
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

    mod vls128 {
        use super::*;
        use crate::packet::FLAGS_BANK;
        use proptest::prelude::*;

        fn arb_vls_packet() -> impl Strategy<Value = DataPacket> {
            let channel =
                (any::<u16>(), any::<u8>()).prop_map(|(distance, reflectivity)| Channel {
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
}

//! From firing sequences to data packets: what the simulator and the fixture synthesizer use to
//! produce packets indistinguishable from a sensor's.
//!
//! A firing sequence is every laser once, at one azimuth. 32-laser models store one sequence per
//! block, 16-laser models two (only the first sequence's azimuth is stored, as on the sensor). In
//! dual-return mode each sequence fills two blocks: last return, then strongest. The VLS-128
//! spreads a sequence over four blocks, one per bank of 32 lasers (three sequences per packet),
//! or in dual mode over eight (last, then strongest, per bank) and leaves the last four blocks
//! unused. The HDL-64E writes a block pair per sequence (upper bank, lower bank), and in dual
//! mode the strongest pair, then the last.

use crate::model::Model;
use crate::packet::{
    Block, Channel, DataPacket, ReturnMode, BLOCKS, CHANNELS, FLAGS_BANK, FLAG_UPPER,
};

/// One firing sequence: returns per laser id.
#[derive(Clone, Debug, PartialEq)]
pub struct Sequence {
    /// Azimuth of the sequence's first firing, hundredths of a degree (0..36000).
    pub azimuth: u16,
    /// Strongest (or only) return per laser id; distance 0 for no return.
    pub strongest: Vec<Channel>,
    /// Last return per laser id (dual mode only).
    pub last: Option<Vec<Channel>>,
}

/// Why a sequence cannot be encoded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// Wrong number of returns for the model.
    #[error("a {model} sequence needs {expected} returns per laser, got {got}")]
    LaserCount {
        /// Model.
        model: Model,
        /// Expected.
        expected: usize,
        /// Given.
        got: usize,
    },
    /// Azimuth outside 0..36000.
    #[error("azimuth {0} is outside 0..36000 hundredths of a degree")]
    Azimuth(u16),
    /// Dual mode needs `last`, single modes must not have it.
    #[error("return mode {mode:?} and the presence of last returns disagree")]
    Mode {
        /// The encoder's mode.
        mode: ReturnMode,
    },
}

/// Packs sequences into data packets.
#[derive(Clone, Debug)]
pub struct PacketEncoder {
    model: Model,
    mode: ReturnMode,
    blocks: Vec<Block>,
    pending_second_half: bool,
    timestamp_us: u32,
}

impl PacketEncoder {
    /// An encoder for a model and return mode.
    pub fn new(model: Model, mode: ReturnMode) -> Self {
        PacketEncoder {
            model,
            mode,
            blocks: Vec::with_capacity(BLOCKS),
            pending_second_half: false,
            timestamp_us: 0,
        }
    }

    /// Appends the block of bank `bank` (its flag, lasers bank·32 .. bank·32 + 32 of `set`).
    fn push_bank(&mut self, azimuth: u16, bank: usize, set: &[Channel]) {
        let mut channels = [Channel::default(); CHANNELS];
        channels.copy_from_slice(&set[bank * CHANNELS..(bank + 1) * CHANNELS]);
        self.blocks.push(Block {
            flag: FLAGS_BANK[bank],
            azimuth,
            channels,
        });
    }

    /// Sequences that fill one packet.
    pub fn sequences_per_packet(&self) -> usize {
        if self.model == Model::Vls128 {
            return if self.mode == ReturnMode::Dual { 1 } else { 3 };
        }
        if self.model.is_hdl64e() {
            return if self.mode == ReturnMode::Dual { 3 } else { 6 };
        }
        let per_block = self.model.timing().sequences_per_block;
        let blocks_per_seq = if self.mode == ReturnMode::Dual { 2 } else { 1 };
        BLOCKS * per_block / blocks_per_seq
    }

    /// Adds a sequence fired at `timestamp_us` (µs past the hour; only the first sequence of a
    /// packet sets the packet's stamp). Returns a packet when one is full.
    pub fn push(
        &mut self,
        seq: &Sequence,
        timestamp_us: u32,
    ) -> Result<Option<DataPacket>, EncodeError> {
        let n = self.model.lasers();
        if seq.strongest.len() != n {
            return Err(EncodeError::LaserCount {
                model: self.model,
                expected: n,
                got: seq.strongest.len(),
            });
        }
        if seq.azimuth >= 36_000 {
            return Err(EncodeError::Azimuth(seq.azimuth));
        }
        match (&seq.last, self.mode) {
            (Some(l), ReturnMode::Dual) if l.len() != n => {
                return Err(EncodeError::LaserCount {
                    model: self.model,
                    expected: n,
                    got: l.len(),
                })
            }
            (Some(_), ReturnMode::Dual) | (None, ReturnMode::Strongest | ReturnMode::Last) => {}
            _ => return Err(EncodeError::Mode { mode: self.mode }),
        }
        if self.blocks.is_empty() && !self.pending_second_half {
            self.timestamp_us = timestamp_us;
        }
        let halves = self.model.timing().sequences_per_block;
        let sets: Vec<&Vec<Channel>> = match &seq.last {
            Some(last) => vec![last, &seq.strongest],
            None => vec![&seq.strongest],
        };
        if self.model.is_hdl64e() {
            // A block pair (upper, lower bank) per return: strongest first, then last.
            for set in sets.iter().rev() {
                for bank in 0..2 {
                    self.push_bank(seq.azimuth, bank, set);
                }
            }
        } else if self.model == Model::Vls128 {
            // Per bank: last, then strongest.
            for bank in 0..FLAGS_BANK.len() {
                for set in &sets {
                    self.push_bank(seq.azimuth, bank, set);
                }
            }
            if self.mode == ReturnMode::Dual {
                // The four unused blocks: bank flags, the sequence's azimuth, no returns
                // (decoders skip them; velodyne-decoder reads only the first eight).
                let none = vec![Channel::default(); self.model.lasers()];
                for bank in 0..FLAGS_BANK.len() {
                    self.push_bank(seq.azimuth, bank, &none);
                }
            }
        } else if halves == 1 || !self.pending_second_half {
            // A new block per return set; 16-laser models fill its second half next time.
            for set in sets {
                let mut channels = [Channel::default(); CHANNELS];
                channels[..n].copy_from_slice(set);
                self.blocks.push(Block {
                    flag: FLAG_UPPER,
                    azimuth: seq.azimuth,
                    channels,
                });
            }
            self.pending_second_half = halves == 2;
        } else {
            // Second sequence of the block(s) just pushed: fill channels 16..32.
            let k = sets.len();
            let start = self.blocks.len() - k;
            for (i, set) in sets.into_iter().enumerate() {
                self.blocks[start + i].channels[n..2 * n].copy_from_slice(set);
            }
            self.pending_second_half = false;
        }
        if self.blocks.len() == BLOCKS && !self.pending_second_half {
            let blocks: [Block; BLOCKS] = std::mem::take(&mut self.blocks)
                .try_into()
                .map_err(|_| EncodeError::Mode { mode: self.mode })?;
            return Ok(Some(DataPacket {
                blocks,
                timestamp_us: self.timestamp_us,
                return_mode: self.mode.byte(),
                product: self.model.product(),
            }));
        }
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::{Decoder, ReturnType};
    use proptest::prelude::*;

    fn arb_channel() -> impl Strategy<Value = Channel> {
        (prop_oneof![Just(0u16), 1u16..60_000], any::<u8>()).prop_map(|(distance, reflectivity)| {
            Channel {
                distance,
                reflectivity,
            }
        })
    }

    fn arb_case() -> impl Strategy<Value = (Model, ReturnMode, Vec<Sequence>)> {
        (
            prop::sample::select(Model::ALL.to_vec()),
            prop::sample::select(vec![
                ReturnMode::Strongest,
                ReturnMode::Last,
                ReturnMode::Dual,
            ]),
        )
            .prop_flat_map(|(model, mode)| {
                let n = model.lasers();
                let per_packet = PacketEncoder::new(model, mode).sequences_per_packet();
                let seq = (
                    0u16..36_000,
                    proptest::collection::vec(arb_channel(), n),
                    proptest::collection::vec(arb_channel(), n),
                )
                    .prop_map(move |(azimuth, strongest, last)| Sequence {
                        azimuth,
                        strongest,
                        last: (mode == ReturnMode::Dual).then_some(last),
                    });
                (
                    Just(model),
                    Just(mode),
                    proptest::collection::vec(seq, per_packet),
                )
            })
    }

    proptest! {
        /// Random firings -> packet -> points: every return comes back on its laser with its
        /// distance, reflectivity and return type.
        #[test]
        fn random_firings_survive_encode_and_decode((model, mode, seqs) in arb_case()) {
            let mut enc = PacketEncoder::new(model, mode);
            let mut packet = None;
            for (i, s) in seqs.iter().enumerate() {
                let out = enc.push(s, 1_000).unwrap();
                prop_assert_eq!(out.is_some(), i + 1 == seqs.len());
                packet = out;
            }
            let packet = packet.unwrap();
            let bytes = packet.encode();
            prop_assert_eq!(&DataPacket::decode(&bytes).unwrap(), &packet);
            let points = Decoder::new(model).decode(&packet).unwrap();
            let mut expected = Vec::new();
            let n = model.lasers();
            let per_block = model.timing().sequences_per_block;
            // Expected order: by column, then channel (sequence-major inside a block).
            let columns: Vec<&[Sequence]> = seqs.chunks(per_block).collect();
            for col in columns {
                for (half, s) in col.iter().enumerate() {
                    for laser in 0..n {
                        let _ = half;
                        let st = s.strongest[laser];
                        match &s.last {
                            Some(last) => {
                                let l = last[laser];
                                if l.distance == 0 && st.distance == 0 { continue; }
                                if l.distance == st.distance {
                                    expected.push((laser as u8, st.distance, st.reflectivity, ReturnType::Both));
                                } else {
                                    if l.distance > 0 { expected.push((laser as u8, l.distance, l.reflectivity, ReturnType::Last)); }
                                    if st.distance > 0 { expected.push((laser as u8, st.distance, st.reflectivity, ReturnType::Strongest)); }
                                }
                            }
                            None if st.distance > 0 => {
                                let rt = if mode == ReturnMode::Last { ReturnType::Last } else { ReturnType::Strongest };
                                expected.push((laser as u8, st.distance, st.reflectivity, rt));
                            }
                            None => {}
                        }
                    }
                }
            }
            let got: Vec<_> = points.iter().map(|p| (p.laser.0, p.distance_raw, p.intensity, p.return_type)).collect();
            prop_assert_eq!(got, expected);
        }
    }

    #[test]
    fn wrong_laser_count_is_refused() {
        let mut e = PacketEncoder::new(Model::Vlp16, ReturnMode::Strongest);
        let s = Sequence {
            azimuth: 0,
            strongest: vec![Channel::default(); 32],
            last: None,
        };
        assert!(matches!(
            e.push(&s, 0),
            Err(EncodeError::LaserCount {
                expected: 16,
                got: 32,
                ..
            })
        ));
    }
}

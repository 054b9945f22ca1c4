//! The 1206-byte data packet as it is on the wire, decoded losslessly.
//!
//! Layout (all Velodyne 16/32/128-laser models): 12 blocks of 100 bytes (flag `FF EE`, or the
//! VLS-128's bank flags `FF DD`, `FF CC`, `FF BB`, azimuth in
//! hundredths of a degree, 32 × (distance u16, reflectivity u8)), then a 4-byte timestamp
//! (microseconds past the hour), the return-mode byte and the product byte. All little-endian.
//!
//! `decode(encode(p)) == p` and `encode(decode(b)) == b` for every valid packet: this layer keeps
//! every bit, so recordings can be replayed byte-identically and the simulator can produce packets
//! that any other decoder accepts.

use crate::error::DecodeError;
use crate::model::ProductId;

/// Size of a data packet's UDP payload.
pub const DATA_PACKET_SIZE: usize = 1206;
/// Blocks per packet.
pub const BLOCKS: usize = 12;
/// Channels (distance + reflectivity) per block.
pub const CHANNELS: usize = 32;
/// Bytes per block.
pub const BLOCK_SIZE: usize = 100;
// The block flags: which model writes which is a fact of the models (`Model::block_flags`),
// so they are defined there.
pub use crate::model::{FLAGS_BANK, FLAGS_BANK_64E, FLAG_UPPER};

/// The return mode byte (1204).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ReturnModeByte(pub u8);

/// How the sensor reports returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ReturnMode {
    /// One block per firing sequence, strongest return.
    Strongest,
    /// One block per firing sequence, last return.
    Last,
    /// Blocks in pairs: last return, then strongest (or second strongest).
    Dual,
}

impl ReturnModeByte {
    /// The mode, if the byte is one of 0x37, 0x38, 0x39.
    pub fn mode(self) -> Option<ReturnMode> {
        match self.0 {
            0x37 => Some(ReturnMode::Strongest),
            0x38 => Some(ReturnMode::Last),
            0x39 => Some(ReturnMode::Dual),
            _ => None,
        }
    }
}

impl ReturnMode {
    /// The byte a sensor writes for this mode.
    pub fn byte(self) -> ReturnModeByte {
        ReturnModeByte(match self {
            ReturnMode::Strongest => 0x37,
            ReturnMode::Last => 0x38,
            ReturnMode::Dual => 0x39,
        })
    }
}

/// One channel of a block: a raw distance count and the calibrated reflectivity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Channel {
    /// Distance in the model's resolution (2 mm or 4 mm); 0 means no return.
    pub distance: u16,
    /// Calibrated reflectivity 0-255.
    pub reflectivity: u8,
}

/// One block: a flag, the azimuth of its first firing and 32 channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Block {
    /// Block flag (0xEEFF on the wire as `FF EE`).
    pub flag: u16,
    /// Azimuth in hundredths of a degree, 0..=36000 (36000, written by HDL-32E firmware for 0°,
    /// is kept as sent so that packets re-encode byte-identically; decoding reads it as 0°).
    pub azimuth: u16,
    /// Channels in firing order.
    pub channels: [Channel; CHANNELS],
}

/// A decoded data packet.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct DataPacket {
    /// The twelve blocks.
    pub blocks: [Block; BLOCKS],
    /// Time of the first firing of the first block, microseconds past the hour.
    pub timestamp_us: u32,
    /// Return mode byte.
    pub return_mode: ReturnModeByte,
    /// Product (factory) byte.
    pub product: ProductId,
}

impl DataPacket {
    /// Decodes a UDP payload. Fails on a wrong size, a block flag other than `FF EE`, or an azimuth
    /// above 36000; the error names the block and byte offset.
    pub fn decode(bytes: &[u8]) -> Result<DataPacket, DecodeError> {
        if bytes.len() != DATA_PACKET_SIZE {
            return Err(DecodeError::WrongSize {
                expected: DATA_PACKET_SIZE,
                got: bytes.len(),
            });
        }
        let empty = Block {
            flag: 0,
            azimuth: 0,
            channels: [Channel::default(); CHANNELS],
        };
        let mut blocks = [empty; BLOCKS];
        for (i, block) in blocks.iter_mut().enumerate() {
            let b = &bytes[i * BLOCK_SIZE..(i + 1) * BLOCK_SIZE];
            let flag = u16::from_le_bytes([b[0], b[1]]);
            if !FLAGS_BANK.contains(&flag) {
                return Err(DecodeError::BadBlockFlag {
                    block: i,
                    offset: i * BLOCK_SIZE,
                    got: flag,
                });
            }
            let azimuth = u16::from_le_bytes([b[2], b[3]]);
            // 36000 is what HDL-32E firmware writes for 0° now and then (seen in real captures);
            // it is kept as sent and read as 0°. Anything above is corrupt.
            if azimuth > 36_000 {
                return Err(DecodeError::AzimuthOutOfRange {
                    block: i,
                    offset: i * BLOCK_SIZE + 2,
                    got: azimuth,
                });
            }
            block.flag = flag;
            block.azimuth = azimuth;
            for (c, ch) in block.channels.iter_mut().enumerate() {
                let o = 4 + c * 3;
                ch.distance = u16::from_le_bytes([b[o], b[o + 1]]);
                ch.reflectivity = b[o + 2];
            }
        }
        let t = &bytes[1200..1204];
        Ok(DataPacket {
            blocks,
            timestamp_us: u32::from_le_bytes([t[0], t[1], t[2], t[3]]),
            return_mode: ReturnModeByte(bytes[1204]),
            product: ProductId(bytes[1205]),
        })
    }

    /// Encodes to the 1206-byte wire format.
    pub fn encode(&self) -> [u8; DATA_PACKET_SIZE] {
        let mut out = [0u8; DATA_PACKET_SIZE];
        for (i, block) in self.blocks.iter().enumerate() {
            let b = &mut out[i * BLOCK_SIZE..(i + 1) * BLOCK_SIZE];
            b[0..2].copy_from_slice(&block.flag.to_le_bytes());
            b[2..4].copy_from_slice(&block.azimuth.to_le_bytes());
            for (c, ch) in block.channels.iter().enumerate() {
                let o = 4 + c * 3;
                b[o..o + 2].copy_from_slice(&ch.distance.to_le_bytes());
                b[o + 2] = ch.reflectivity;
            }
        }
        out[1200..1204].copy_from_slice(&self.timestamp_us.to_le_bytes());
        out[1204] = self.return_mode.0;
        out[1205] = self.product.0;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    pub(crate) fn arb_packet() -> impl Strategy<Value = DataPacket> {
        let channel = (any::<u16>(), any::<u8>()).prop_map(|(distance, reflectivity)| Channel {
            distance,
            reflectivity,
        });
        let block =
            (0u16..=36_000, proptest::array::uniform32(channel)).prop_map(|(azimuth, channels)| {
                Block {
                    flag: FLAG_UPPER,
                    azimuth,
                    channels,
                }
            });
        (
            proptest::collection::vec(block, BLOCKS),
            0u32..3_600_000_000,
            any::<u8>(),
            any::<u8>(),
        )
            .prop_map(|(blocks, timestamp_us, rm, prod)| DataPacket {
                blocks: blocks.try_into().expect("12 blocks"),
                timestamp_us,
                return_mode: ReturnModeByte(rm),
                product: ProductId(prod),
            })
    }

    proptest! {
        #[test]
        fn decode_encode_round_trips(p in arb_packet()) {
            let bytes = p.encode();
            prop_assert_eq!(DataPacket::decode(&bytes).unwrap(), p);
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..1300)) {
            let _ = DataPacket::decode(&bytes);
        }
    }

    #[test]
    fn bad_flag_names_block_and_offset() {
        let mut b = [0u8; DATA_PACKET_SIZE];
        for i in 0..BLOCKS {
            b[i * BLOCK_SIZE] = 0xFF;
            b[i * BLOCK_SIZE + 1] = 0xEE;
        }
        b[300] = 0x00;
        let e = DataPacket::decode(&b).unwrap_err();
        assert_eq!(
            e,
            DecodeError::BadBlockFlag {
                block: 3,
                offset: 300,
                got: 0xEE00
            }
        );
        b[300] = 0xFF;
        b[702..704].copy_from_slice(&36_000u16.to_le_bytes());
        assert_eq!(DataPacket::decode(&b).unwrap().blocks[7].azimuth, 36_000);
        b[702..704].copy_from_slice(&36_001u16.to_le_bytes());
        let e = DataPacket::decode(&b).unwrap_err();
        assert_eq!(
            e,
            DecodeError::AzimuthOutOfRange {
                block: 7,
                offset: 702,
                got: 36_001
            }
        );
        assert!(e.to_string().contains("byte 702"), "{e}");
    }
}

//! Is this payload a data packet the rig's sensor sends? Validation without decoding.
//!
//! The recorder writes packets as received and decodes none of them, so it needs a check that
//! costs a few byte comparisons per block, yet accepts exactly what the model legitimately
//! sends: the block flags of its banks (the VLS-128 writes `FF EE`, `FF DD`, `FF CC`, `FF BB`;
//! the HDL-64E `FF EE`, `FF DD`; every other model `FF EE` only), azimuths up to 36000, a
//! product byte the model writes ([`Model::sends_product`]) and a return-mode byte its decoder
//! reads. A packet it accepts is one [`DataPacket::decode`](crate::DataPacket::decode) reads.
//!
//! The order of the checks decides the reason a bad packet is counted under: bytes that are no
//! Velodyne packet at all fail on their flags or azimuths (malformed); a well-formed packet of
//! another model fails on its product byte, which names the sensor it came from.

use crate::error::DecodeError;
use crate::model::{Model, ProductId};
use crate::packet::{ReturnModeByte, BLOCKS, BLOCK_SIZE, DATA_PACKET_SIZE, FLAGS_BANK};

/// Checks that `bytes` is a data packet that `model` sends; gives the payload as an array.
pub fn data_packet(bytes: &[u8], model: Model) -> Result<&[u8; DATA_PACKET_SIZE], DecodeError> {
    let arr: &[u8; DATA_PACKET_SIZE] = bytes.try_into().map_err(|_| DecodeError::WrongSize {
        expected: DATA_PACKET_SIZE,
        got: bytes.len(),
    })?;
    let own = model.block_flags();
    // The first block whose (valid Velodyne) flag is another model's: reported only after the
    // product byte, which names the sensor better than a flag does.
    let mut foreign = None;
    for block in 0..BLOCKS {
        let o = block * BLOCK_SIZE;
        let flag = u16::from_le_bytes([arr[o], arr[o + 1]]);
        if !own.contains(&flag) {
            if !FLAGS_BANK.contains(&flag) {
                return Err(DecodeError::BadBlockFlag {
                    block,
                    offset: o,
                    got: flag,
                });
            }
            foreign.get_or_insert(DecodeError::ForeignBankFlag {
                block,
                offset: o,
                got: flag,
                model,
            });
        }
        let azimuth = u16::from_le_bytes([arr[o + 2], arr[o + 3]]);
        // 36000 is an HDL-32E's 0° (kept as sent); above is corrupt.
        if azimuth > 36_000 {
            return Err(DecodeError::AzimuthOutOfRange {
                block,
                offset: o + 2,
                got: azimuth,
            });
        }
    }
    let product = arr[1205];
    if !model.sends_product(ProductId(product)) {
        return Err(DecodeError::OtherSensor {
            got: product,
            expected: model,
        });
    }
    if let Some(e) = foreign {
        return Err(e);
    }
    // The HDL-64E has status bytes there; the HDL-32E's older firmware leaves the byte at 0.
    let mode = arr[1204];
    let readable = model.is_hdl64e()
        || ReturnModeByte(mode).mode().is_some()
        || (model == Model::Hdl32e && mode == 0);
    if !readable {
        return Err(DecodeError::UnsupportedReturnMode(mode));
    }
    Ok(arr)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::Decoder;
    use crate::encode::{PacketEncoder, Sequence};
    use crate::packet::{Channel, DataPacket, ReturnMode};
    use proptest::prelude::*;

    /// A packet of `model` in `mode` as its encoder writes it (every laser at 10 m).
    fn packet(model: Model, mode: ReturnMode) -> [u8; DATA_PACKET_SIZE] {
        let mut enc = PacketEncoder::new(model, mode);
        let ch = vec![
            Channel {
                distance: 2500,
                reflectivity: 7
            };
            model.lasers()
        ];
        for k in 0..enc.sequences_per_packet() {
            let seq = Sequence {
                azimuth: (k * 20) as u16,
                strongest: ch.clone(),
                last: (mode == ReturnMode::Dual).then(|| ch.clone()),
            };
            if let Some(p) = enc.push(&seq, 1_000).expect("a valid sequence") {
                return p.encode();
            }
        }
        unreachable!("a packet is full after sequences_per_packet sequences")
    }

    /// Every model's packets, in every return mode it has, pass as that model; the VLS-128's
    /// (all four bank flags) and the HDL-64E's (two) among them.
    #[test]
    fn every_model_s_own_packets_pass() {
        for m in Model::ALL {
            for mode in [ReturnMode::Strongest, ReturnMode::Last, ReturnMode::Dual] {
                let p = packet(m, mode);
                assert_eq!(
                    data_packet(&p, m).map(|a| &a[..]),
                    Ok(&p[..]),
                    "{m} {mode:?}"
                );
            }
        }
        let vls = packet(Model::Vls128, ReturnMode::Strongest);
        let flags: std::collections::BTreeSet<u8> = (0..BLOCKS).map(|b| vls[b * 100 + 1]).collect();
        assert_eq!(flags.len(), 4, "the VLS-128 packet has all four bank flags");
    }

    /// Another model's packet is refused as another sensor's, naming both, whatever its flags.
    #[test]
    fn another_model_s_packets_are_another_sensor_s() {
        let vlp16 = packet(Model::Vlp16, ReturnMode::Strongest);
        let e = data_packet(&vlp16, Model::Vls128).unwrap_err();
        assert_eq!(
            e,
            DecodeError::OtherSensor {
                got: 0x22,
                expected: Model::Vls128
            }
        );
        let text = e.to_string();
        assert!(
            text.contains("product byte 0x22 at byte 1205 is a vlp16's, not the vls128's (0xa1)"),
            "{text}"
        );
        // The VLS-128's bank flags on a VLP-32C rig: named by the product byte.
        let vls = packet(Model::Vls128, ReturnMode::Dual);
        assert!(matches!(
            data_packet(&vls, Model::Vlp32c),
            Err(DecodeError::OtherSensor { got: 0xA1, .. })
        ));
        // Early VLP-16 firmware writes the HDL-32E's byte: still a VLP-16's packet.
        let mut early = vlp16;
        early[1205] = 0x21;
        assert!(data_packet(&early, Model::Vlp16).is_ok());
        assert!(data_packet(&vlp16, Model::Hdl32e).is_err());
        // The HDL-64E writes no product byte: the bank flags tell its packets from others.
        let vls = packet(Model::Vls128, ReturnMode::Strongest);
        let e = data_packet(&vls, Model::Hdl64eS3).unwrap_err();
        assert!(
            matches!(
                e,
                DecodeError::ForeignBankFlag {
                    block: 2,
                    offset: 200,
                    got: 0xCCFF,
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("it sends FF EE, FF DD"), "{e}");
    }

    #[test]
    fn malformed_packets_name_what_and_where() {
        let good = packet(Model::Vls128, ReturnMode::Strongest);
        assert_eq!(
            data_packet(&good[..1205], Model::Vls128),
            Err(DecodeError::WrongSize {
                expected: 1206,
                got: 1205
            })
        );
        let mut bad = good;
        bad[501] = 0x00;
        assert_eq!(
            data_packet(&bad, Model::Vls128),
            Err(DecodeError::BadBlockFlag {
                block: 5,
                offset: 500,
                got: 0x00FF
            })
        );
        let mut bad = good;
        bad[702..704].copy_from_slice(&36_001u16.to_le_bytes());
        assert_eq!(
            data_packet(&bad, Model::Vls128),
            Err(DecodeError::AzimuthOutOfRange {
                block: 7,
                offset: 702,
                got: 36_001
            })
        );
        let mut bad = good;
        bad[1204] = 0x42;
        assert_eq!(
            data_packet(&bad, Model::Vls128),
            Err(DecodeError::UnsupportedReturnMode(0x42))
        );
        // The HDL-32E's old firmware (return mode 0, factory bytes unset) and the HDL-64E's
        // status bytes pass.
        let mut old = packet(Model::Hdl32e, ReturnMode::Strongest);
        old[1204] = 0;
        old[1205] = 0;
        assert!(data_packet(&old, Model::Hdl32e).is_ok());
        let mut s3 = packet(Model::Hdl64eS3, ReturnMode::Strongest);
        s3[1204] = 0xA7;
        s3[1205] = 0x5C;
        assert!(data_packet(&s3, Model::Hdl64eS3).is_ok());
    }

    /// Bytes of a data packet: mostly well-formed, with the block flags of one model's layout
    /// (`FF EE` only, the VLS-128's banks in order, the HDL-64E's pairs) or banks at random,
    /// known return modes and product bytes; sometimes one flag, azimuth or the size broken.
    fn arb_bytes() -> impl Strategy<Value = Vec<u8>> {
        (
            proptest::collection::vec(any::<u8>(), DATA_PACKET_SIZE),
            0usize..4,
            proptest::collection::vec(0usize..4, BLOCKS),
            proptest::collection::vec(0u16..=36_000, BLOCKS),
            prop_oneof![Just(0x37u8), Just(0x38), Just(0x39), Just(0), any::<u8>()],
            prop_oneof![
                3 => proptest::sample::select(vec![0x21u8, 0x22, 0x23, 0x24, 0x28, 0xA1, 0]),
                1 => any::<u8>()
            ],
            (0usize..8, 0usize..BLOCKS, any::<u16>(), 0usize..1300),
        )
            .prop_map(
                |(mut b, layout, banks, azimuths, mode, product, (broken, at, junk, len))| {
                    for i in 0..BLOCKS {
                        let flag = match layout {
                            0 => FLAGS_BANK[0],
                            1 => FLAGS_BANK[i % 4],
                            2 => FLAGS_BANK[i % 2],
                            _ => FLAGS_BANK[banks[i]],
                        };
                        b[i * BLOCK_SIZE..i * BLOCK_SIZE + 2].copy_from_slice(&flag.to_le_bytes());
                        b[i * BLOCK_SIZE + 2..i * BLOCK_SIZE + 4]
                            .copy_from_slice(&azimuths[i].to_le_bytes());
                    }
                    b[1204] = mode;
                    b[1205] = product;
                    match broken {
                        0 => b[at * BLOCK_SIZE..at * BLOCK_SIZE + 2]
                            .copy_from_slice(&junk.to_le_bytes()),
                        1 => b[at * BLOCK_SIZE + 2..at * BLOCK_SIZE + 4]
                            .copy_from_slice(&junk.to_le_bytes()),
                        2 => b.resize(len, 0),
                        _ => {}
                    }
                    b
                },
            )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2048))]
        /// For every model: whatever the check accepts, the packet layer decodes and the model's
        /// decoder reads (dual-return VLS-128 and HDL-64E packets need matching bank pairs,
        /// which the check leaves to the decoder); whatever the model's decoder reads from a packet with a product
        /// byte the model sends, the check accepts. Never a panic.
        #[test]
        fn accepts_exactly_what_the_model_s_decoder_reads(bytes in arb_bytes()) {
            for m in Model::ALL {
                let checked = data_packet(&bytes, m);
                let decoded = DataPacket::decode(&bytes);
                if checked.is_ok() {
                    prop_assert!(decoded.is_ok(), "{m}: accepted but the packet layer refuses it");
                }
                let Ok(pkt) = decoded else { continue };
                let reads = Decoder::new(m).decode(&pkt).is_ok();
                let pairs_only = (m == Model::Vls128 && pkt.return_mode.mode() == Some(ReturnMode::Dual))
                    || (m.is_hdl64e() && crate::decode::hdl64e_dual(&pkt));
                if checked.is_ok() && !pairs_only {
                    prop_assert!(reads, "{m}: accepted but the decoder refuses it");
                }
                if reads && m.sends_product(pkt.product) {
                    prop_assert!(checked.is_ok(), "{m}: decoded but refused: {:?}", checked);
                }
            }
        }
    }
}

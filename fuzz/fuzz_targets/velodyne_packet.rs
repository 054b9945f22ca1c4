//! Any bytes as a Velodyne data or position packet, decoded as every model (the VLS-128 also
//! after a previous packet, as its dual mode decodes) and checked as every model the way the
//! recorder checks them: errors are fine, panics are not, whatever decodes re-encodes to the
//! same bytes, and whatever the recorder's check accepts the packet layer decodes.
#![no_main]
use hilrig_velodyne::{DataPacket, Decoder, Model, PositionPacket};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // Make full-size packets likely: pad or cut the input to 1206 bytes when the first byte is odd.
    let mut buf = data.to_vec();
    if data.first().is_some_and(|b| b & 1 == 1) {
        buf.resize(hilrig_velodyne::DATA_PACKET_SIZE, 0);
        // The first byte's other bits choose the flags: the upper bank's only, the VLS-128's
        // four banks in order, or banks picked by the input.
        let banks = [0xEEu8, 0xDD, 0xCC, 0xBB];
        for i in 0..12 {
            buf[i * 100] = 0xFF;
            buf[i * 100 + 1] = match data[0] >> 1 & 3 {
                0 => 0xEE,
                1 => banks[i % 4],
                _ => banks[usize::from(data.get(i + 1).copied().unwrap_or(0)) % 4],
            };
        }
        if data[0] & 8 != 0 {
            buf[1204] = 0x39; // dual return
        }
    }
    let decoded = DataPacket::decode(&buf);
    for m in Model::ALL {
        if hilrig_velodyne::check::data_packet(&buf, m).is_ok() {
            assert!(decoded.is_ok(), "{m}: the recorder would keep a packet nothing decodes");
        }
    }
    if let Ok(p) = decoded {
        assert_eq!(&p.encode()[..], &buf[..]);
        for m in Model::ALL {
            let d = Decoder::new(m);
            let _ = d.decode(&p);
            let mut out = Vec::new();
            let _ = d.decode_into_after(&p, Some(&p), &mut out);
            let mut earlier = p.clone();
            earlier.timestamp_us = earlier.timestamp_us.wrapping_sub(u32::from(data[0]) * 7);
            earlier.blocks[0].azimuth = ((u32::from(p.blocks[0].azimuth) + 35_000) % 36_000) as u16;
            let _ = d.decode_into_after(&p, Some(&earlier), &mut out);
        }
    }
    if let Ok(p) = PositionPacket::decode(data) {
        let _ = p.rmc();
        assert_eq!(&p.encode()[..], data);
    }
    if let Ok(s) = std::str::from_utf8(data) {
        let _ = hilrig_velodyne::Rmc::parse(s);
    }
});

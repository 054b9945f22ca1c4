//! Any bytes as a Velodyne data or position packet, decoded as every model: errors are fine,
//! panics are not, and whatever decodes re-encodes to the same bytes.
#![no_main]
use hilrig_velodyne::{DataPacket, Decoder, Model, PositionPacket};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // Make full-size packets likely: pad or cut the input to 1206 bytes when the first byte is odd.
    let mut buf = data.to_vec();
    if data.first().is_some_and(|b| b & 1 == 1) {
        buf.resize(hilrig_velodyne::DATA_PACKET_SIZE, 0);
        for i in 0..12 {
            buf[i * 100] = 0xFF;
            buf[i * 100 + 1] = 0xEE;
        }
    }
    if let Ok(p) = DataPacket::decode(&buf) {
        assert_eq!(&p.encode()[..], &buf[..]);
        for m in Model::ALL {
            let _ = Decoder::new(m).decode(&p);
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

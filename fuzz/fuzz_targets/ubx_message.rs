//! Any payload as every decoded UBX message: decoded or rejected by length/version, never a
//! panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.len() < 2 {
        return;
    }
    let payload = &data[2..];
    let _ = hilrig_gnss::ubx::decode(data[0], data[1], payload);
    for (class, id) in [
        (0x01, 0x07),
        (0x01, 0x14),
        (0x01, 0x3C),
        (0x01, 0x05),
        (0x01, 0x17),
        (0x28, 0x00),
        (0x28, 0x01),
        (0x10, 0x14),
    ] {
        let _ = hilrig_gnss::ubx::decode(class, id, payload);
    }
});

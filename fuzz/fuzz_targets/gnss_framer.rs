//! Any bytes as a serial stream, in fuzzer-chosen chunks, through the framer and the whole GNSS
//! pipeline: frames, rejects and fixes, never a panic; every byte is accounted for.
#![no_main]
use hilrig_gnss::GnssStream;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let chunk = usize::from(data.first().copied().unwrap_or(1)).max(1);
    let mut s = GnssStream::for_gpsd_log();
    let mut out = Vec::new();
    for c in data.chunks(chunk) {
        s.push(c, &mut out);
    }
    s.finish(&mut out);
    assert_eq!(s.framer.position(), data.len() as u64);
});

//! Any text as an NMEA sentence (with a valid checksum added half of the time so that field
//! parsing is reached): decoded or rejected, never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(s) = std::str::from_utf8(data) else {
        return;
    };
    let _ = hilrig_gnss::nmea::parse(s);
    let body = s.trim_start_matches('$');
    if !body.contains('*') {
        let _ = hilrig_gnss::nmea::parse(&hilrig_gnss::framer::nmea_sentence(body));
    }
});

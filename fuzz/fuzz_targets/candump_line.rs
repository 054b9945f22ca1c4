//! Any text as candump log lines: parsed or rejected with a line number, never a panic; every
//! parsed frame is written back to a line that parses to the same frame.
#![no_main]
use hilrig_can::candump::{format_line, parse_line};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(s) = std::str::from_utf8(data) else {
        return;
    };
    for (i, l) in s.lines().enumerate() {
        if let Ok(Some(f)) = parse_line(l, i + 1) {
            let again = parse_line(&format_line(&f), 1).expect("written line parses");
            let again = again.expect("not a comment");
            // The log keeps microseconds.
            assert_eq!(again.frame, f.frame);
        }
    }
});

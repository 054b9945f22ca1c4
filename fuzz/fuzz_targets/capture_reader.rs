//! Any bytes as a pcap/pcapng file: the reader and demultiplexer must end with packets, counted
//! skips or an error, never a panic or unbounded memory.
#![no_main]
use hilrig_capture::{CaptureReader, Demux};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(reader) = CaptureReader::new(std::io::Cursor::new(data.to_vec())) else {
        return;
    };
    let mut demux = Demux::new(reader);
    let mut n = 0usize;
    while let Some(item) = demux.next_item() {
        if item.is_err() {
            break;
        }
        n += 1;
        assert!(n <= data.len(), "more packets than bytes");
    }
    let _ = demux.stats();
});

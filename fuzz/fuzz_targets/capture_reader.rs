//! Any bytes as a capture file, through the whole `hilrig decode` pipeline: capture reader,
//! demultiplexer, Velodyne packet decoding, hour resolution and point geometry. It must end with
//! points, counted skips or an error, never a panic (built with debug assertions: no overflow).
#![no_main]
use hilrig::decode::lidar::{decode_capture, CountSink, LidarOptions};
use hilrig::velodyne::Model;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // The first byte picks the model so that unknown product bytes still reach the decoder.
    let model = data
        .first()
        .map(|b| Model::ALL[usize::from(*b) % Model::ALL.len()]);
    let options = LidarOptions {
        model,
        ..LidarOptions::default()
    };
    let mut sink = CountSink::default();
    if let Ok(summary) = decode_capture(std::io::Cursor::new(data.to_vec()), &options, &mut sink) {
        assert_eq!(summary.points, sink.points);
        assert!(summary.data_packets as usize <= data.len() / 1206 + 1);
    }
});

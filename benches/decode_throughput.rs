//! Single-thread, in-memory throughput of `hilrig decode`'s pipeline (capture demux, packet
//! decode, point geometry) on one capture; prints one JSON line. Driven by
//! `benches/compare_velodyne_decoder.py`, which times velodyne-decoder on the same bytes in the
//! same run:
//!
//! `cargo bench --bench decode_throughput -- FILE [REPEATS]`

use hilrig::decode::lidar::{decode_capture, CountSink, LidarOptions};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let Some(path) = args.first() else {
        eprintln!("usage: decode_throughput FILE [REPEATS]");
        return;
    };
    let repeats: usize = args.get(1).and_then(|r| r.parse().ok()).unwrap_or(5);
    let bytes = std::fs::read(path).expect("read capture");
    let mut best = f64::INFINITY;
    let mut points = 0;
    for _ in 0..repeats {
        let data = bytes.clone();
        let start = Instant::now();
        let mut sink = CountSink::default();
        let s = decode_capture(
            std::io::Cursor::new(data),
            &LidarOptions::default(),
            &mut sink,
        )
        .expect("decode");
        let secs = start.elapsed().as_secs_f64();
        best = best.min(secs);
        points = s.points;
    }
    println!(
        "{{\"points\": {points}, \"best_seconds\": {best:.6}, \"points_per_second\": {:.0}}}",
        points as f64 / best
    );
}

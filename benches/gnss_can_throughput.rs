//! Single-thread throughput of the GNSS and CAN drivers, one JSON line per run. Driven by
//! `benches/compare_gnss_can.py`, which times pynmea2 and cantools on the same input in the same
//! run:
//!
//! `cargo bench --bench gnss_can_throughput -- gnss LOG [REPEATS]`
//! `cargo bench --bench gnss_can_throughput -- can DBC FRAMES.jsonl [REPEATS]`

use hilrig::can::{CanFrame, Database};
use hilrig::gnss::GnssStream;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    match args.first().map(String::as_str) {
        Some("gnss") => {
            let bytes = std::fs::read(&args[1]).expect("read log");
            let repeats: usize = args.get(2).and_then(|r| r.parse().ok()).unwrap_or(20);
            // Repeat the log to ~8 MB so that one pass takes long enough to time.
            let copies = (8_000_000 / bytes.len().max(1)).max(1);
            let data = bytes.repeat(copies);
            let mut best = f64::INFINITY;
            let mut fixes = 0;
            for _ in 0..repeats {
                let start = Instant::now();
                let mut s = GnssStream::for_gpsd_log();
                let mut out = Vec::new();
                for c in data.chunks(4096) {
                    s.push(c, &mut out);
                }
                s.finish(&mut out);
                best = best.min(start.elapsed().as_secs_f64());
                fixes = out.len();
            }
            println!("{{\"bytes\": {}, \"fixes\": {fixes}, \"best_seconds\": {best:.6}, \"mb_per_second\": {:.2}}}", data.len(), data.len() as f64 / best / 1e6);
        }
        Some("can") => {
            let db = Database::from_file(std::path::Path::new(&args[1])).expect("dbc");
            let text = std::fs::read_to_string(&args[2]).expect("frames");
            let repeats: usize = args.get(3).and_then(|r| r.parse().ok()).unwrap_or(20);
            let frames: Vec<CanFrame> = text
                .lines()
                .map(|l| {
                    let v: serde_json::Value = serde_json::from_str(l).unwrap();
                    let data: Vec<u8> = (0..v["data"].as_str().unwrap().len() / 2)
                        .map(|i| {
                            u8::from_str_radix(&v["data"].as_str().unwrap()[2 * i..2 * i + 2], 16)
                                .unwrap()
                        })
                        .collect();
                    CanFrame::new(
                        v["id"].as_u64().unwrap() as u32,
                        v["extended"].as_bool().unwrap(),
                        &data,
                    )
                    .unwrap()
                })
                .collect();
            let mut best = f64::INFINITY;
            let mut values = 0usize;
            let mut buf = Vec::with_capacity(64);
            for _ in 0..repeats {
                let start = Instant::now();
                values = 0;
                for f in &frames {
                    if let Some(m) = db.message(f.id, f.extended) {
                        buf.clear();
                        m.decode_into(f.data(), &mut buf);
                        values += buf.len();
                    }
                }
                best = best.min(start.elapsed().as_secs_f64());
            }
            std::hint::black_box(values);
            println!("{{\"frames\": {}, \"signal_values\": {values}, \"best_seconds\": {best:.6}, \"frames_per_second\": {:.0}}}", frames.len(), frames.len() as f64 / best);
        }
        _ => eprintln!(
            "usage: gnss_can_throughput gnss LOG [REPEATS] | can DBC FRAMES.jsonl [REPEATS]"
        ),
    }
}

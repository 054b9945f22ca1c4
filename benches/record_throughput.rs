//! Captures -> MCAP throughput (issue 4, item 7), in one run: `hilrig record --from`'s pipeline
//! against the bare `mcap` crate writing the same lidar payloads (one message per packet, zstd
//! level 1, same chunk size), both from a capture in the page cache. Prints MB/s of capture for
//! both and the ratio.
//!
//! `cargo bench --bench record_throughput -- [SIZE_MB]`

use hilrig::capture::{CaptureReader, Demux, Packet};
use std::io::Write;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let size_mb: usize = args.first().and_then(|s| s.parse().ok()).unwrap_or(200);
    let dir = tempfile::tempdir().unwrap();
    // A capture of the VLP-16 fixture's packets repeated with advancing times (pcap).
    let fixture = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/vlp16_room.pcapng"
    ))
    .unwrap();
    let mut frames = Vec::new();
    let mut d = Demux::new(CaptureReader::new(std::io::Cursor::new(fixture)).unwrap());
    while let Some(i) = d.next_item() {
        if let Packet::Udp { src, dst, payload } = i.unwrap().packet {
            if payload.len() == 1206 {
                frames.push(hilrig::capture::writer::udp_ethernet_frame(
                    src, dst, payload,
                ));
            }
        }
    }
    let capture = dir.path().join("big.pcap");
    let mut payloads_bytes = 0usize;
    {
        let f = std::io::BufWriter::new(std::fs::File::create(&capture).unwrap());
        let mut w =
            hilrig::capture::PcapWriter::new(f, hilrig::capture::LinkType::ETHERNET, false, true)
                .unwrap();
        let mut t = 1_700_000_000_000_000_000i64;
        let mut k = 0usize;
        let mut written = 0usize;
        while written < size_mb * 1_000_000 {
            let mut fr = frames[k % frames.len()].clone();
            // Keep the sensor timestamps advancing so rotations and clocks behave.
            let ts = ((k as u64 * 1327) % 3_600_000_000) as u32;
            let n = fr.len();
            fr[n - 6..n - 2].copy_from_slice(&ts.to_le_bytes());
            w.write_packet(hilrig::stamp::UtcNanos(t), &fr).unwrap();
            t += 1_327_104;
            written += 16 + fr.len();
            payloads_bytes += 1206;
            k += 1;
        }
        w.finish().unwrap().flush().unwrap();
    }
    let bytes = std::fs::metadata(&capture).unwrap().len() as f64;
    let rig_path = concat!(env!("CARGO_MANIFEST_DIR"), "/rigs/demo.toml");
    let mut rig = hilrig::rig::Rig::load(std::path::Path::new(rig_path)).unwrap();
    rig.can = None; // lidar only: the same payloads as the bare writer
    rig.recording.points = false; // and no decoded clouds (the bare writer has none)
    let text = std::fs::read_to_string(rig_path).unwrap();
    let _ = std::fs::read(&capture).unwrap(); // warm the page cache
    let mut best_h = f64::INFINITY;
    let mut best_m = f64::INFINITY;
    for _ in 0..3 {
        let out = dir.path().join("h.mcap");
        let t0 = Instant::now();
        hilrig::record::record_from(&rig, &text, std::slice::from_ref(&capture), &out).unwrap();
        best_h = best_h.min(t0.elapsed().as_secs_f64());

        // Bare mcap: read the same capture, write each payload as a message.
        let out = dir.path().join("m.mcap");
        let t0 = Instant::now();
        let mut w = mcap::WriteOptions::new()
            .profile("ros2")
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
            .chunk_size(Some(4 * 1024 * 1024))
            .create(std::io::BufWriter::with_capacity(
                1 << 20,
                std::fs::File::create(&out).unwrap(),
            ))
            .unwrap();
        let schema = w
            .add_schema("hilrig_msgs/msg/RawPacket", "ros2msg", b"uint8[] data\n")
            .unwrap();
        let channel = w
            .add_channel(schema, "/velodyne_packets", "cdr", &Default::default())
            .unwrap();
        let mut r = Demux::new(
            CaptureReader::new(std::io::BufReader::with_capacity(
                1 << 20,
                std::fs::File::open(&capture).unwrap(),
            ))
            .unwrap(),
        );
        let mut seq = 0;
        while let Some(i) = r.next_item() {
            let i = i.unwrap();
            if let Packet::Udp { payload, .. } = i.packet {
                seq += 1;
                let h = mcap::records::MessageHeader {
                    channel_id: channel,
                    sequence: seq,
                    log_time: i.time.0 as u64,
                    publish_time: i.time.0 as u64,
                };
                w.write_to_known_channel(&h, payload).unwrap();
            }
        }
        w.finish().unwrap();
        best_m = best_m.min(t0.elapsed().as_secs_f64());
    }
    println!(
        "capture: {:.0} MB pcap ({:.0} MB of lidar payload)",
        bytes / 1e6,
        payloads_bytes as f64 / 1e6
    );
    println!(
        "hilrig record --from (zstd 1): {:8.1} MB/s of capture",
        bytes / best_h / 1e6
    );
    println!(
        "bare mcap crate    (zstd 1):  {:8.1} MB/s of capture",
        bytes / best_m / 1e6
    );
    println!("ratio hilrig / bare mcap: {:.2}", best_m / best_h);
}

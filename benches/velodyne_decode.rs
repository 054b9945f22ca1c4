//! Criterion benchmarks of the Velodyne decoder on the bundled fixtures: raw packet parsing,
//! point geometry per packet (single and dual return), and a whole capture in memory.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hilrig::capture::{CaptureReader, Demux, Packet};
use hilrig::decode::lidar::{decode_capture, CountSink, LidarOptions};
use hilrig::velodyne::{DataPacket, Decoder, Model};
use std::hint::black_box;

fn data_packets(name: &str) -> Vec<Vec<u8>> {
    let path = format!("{}/fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    let mut d = Demux::new(CaptureReader::new(std::fs::File::open(path).unwrap()).unwrap());
    let mut out = Vec::new();
    while let Some(item) = d.next_item() {
        if let Packet::Udp { payload, .. } = item.unwrap().packet {
            if payload.len() == 1206 {
                out.push(payload.to_vec());
            }
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    for (name, model) in [
        ("vlp16_room.pcapng", Model::Vlp16),
        ("vlp32c_dual_room.pcapng", Model::Vlp32c),
    ] {
        let packets = data_packets(name);
        let decoded: Vec<DataPacket> = packets
            .iter()
            .map(|p| DataPacket::decode(p).unwrap())
            .collect();
        let decoder = Decoder::new(model);
        let points: usize = decoded
            .iter()
            .map(|p| decoder.decode(p).unwrap().len())
            .sum();
        let mut g = c.benchmark_group(name);
        g.throughput(Throughput::Elements(packets.len() as u64));
        g.bench_function("parse packets", |b| {
            b.iter(|| {
                for p in &packets {
                    black_box(DataPacket::decode(black_box(p)).unwrap());
                }
            })
        });
        g.throughput(Throughput::Elements(points as u64));
        g.bench_function("points from parsed packets", |b| {
            let mut out = Vec::with_capacity(800);
            b.iter(|| {
                for p in &decoded {
                    out.clear();
                    decoder.decode_into(black_box(p), &mut out).unwrap();
                    black_box(&out);
                }
            })
        });
        let bytes =
            std::fs::read(format!("{}/fixtures/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap();
        g.bench_function("whole capture in memory", |b| {
            b.iter(|| {
                let mut sink = CountSink::default();
                decode_capture(
                    std::io::Cursor::new(bytes.clone()),
                    &LidarOptions::default(),
                    &mut sink,
                )
                .unwrap();
                black_box(sink.points)
            })
        });
        g.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Criterion benchmarks of the GNSS framer/decoder and the CAN signal decoder on generated input
//! (so they run without the real data): a 10 Hz NMEA + UBX stream and an ego-data DBC.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use hilrig::can::{CanFrame, Database};
use hilrig::gnss::framer::{nmea_sentence, rtcm3_frame, ubx_frame};
use hilrig::gnss::GnssStream;
use std::hint::black_box;

fn gnss_stream() -> Vec<u8> {
    let mut s = Vec::new();
    for i in 0..2000u32 {
        let t = format!("12{:02}{:02}.{}0", (i / 600) % 60, (i / 10) % 60, i % 10);
        s.extend(
            nmea_sentence(&format!(
                "GNGGA,{t},4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.2,0042"
            ))
            .bytes(),
        );
        s.extend(
            nmea_sentence(&format!(
                "GNRMC,{t},A,4807.0380000,N,01131.0000000,E,10.0,90.0,211126,,,R"
            ))
            .bytes(),
        );
        s.extend(nmea_sentence(&format!("GNGST,{t},0.5,0.02,0.01,0.0,0.011,0.012,0.025")).bytes());
        s.extend(
            nmea_sentence("GPGSV,3,1,12,01,40,083,46,02,17,308,41,12,07,344,39,14,22,228,45")
                .bytes(),
        );
        s.extend(ubx_frame(1, 7, &[0u8; 92]));
        s.extend(rtcm3_frame(&[
            0x43, 0x50, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        ]));
    }
    s
}

const DBC: &str = "VERSION \"\"\n\nBO_ 291 Ego: 8 X\n SG_ Speed : 0|16@1+ (0.01,0) [0|655.35] \"m/s\" X\n SG_ YawRate : 23|16@0- (0.001,0) [-32|32] \"rad/s\" X\n SG_ Page M : 32|8@1+ (1,0) [0|255] \"\" X\n SG_ Steer m1 : 40|16@1- (0.1,0) [-3276.8|3276.7] \"deg\" X\n SG_ Wheel m2 : 40|16@1+ (0.01,0) [0|655.35] \"m/s\" X\n";

fn bench(c: &mut Criterion) {
    let stream = gnss_stream();
    let mut g = c.benchmark_group("gnss");
    g.throughput(Throughput::Bytes(stream.len() as u64));
    g.bench_function("frame + decode + epochs, 4 KiB chunks", |b| {
        b.iter(|| {
            let mut s = GnssStream::default();
            let mut out = Vec::new();
            for c in stream.chunks(4096) {
                s.push(c, &mut out);
            }
            s.finish(&mut out);
            black_box(out.len())
        })
    });
    g.finish();

    let db = Database::from_dbc_text(DBC).unwrap();
    let frames: Vec<CanFrame> = (0..10_000u32)
        .map(|i| {
            CanFrame::new(
                0x123,
                false,
                &[
                    i as u8,
                    (i >> 8) as u8,
                    0xFE,
                    0x0C,
                    (i % 3) as u8,
                    0x85,
                    0xFF,
                    0,
                ],
            )
            .unwrap()
        })
        .collect();
    let mut g = c.benchmark_group("can");
    g.throughput(Throughput::Elements(frames.len() as u64));
    g.bench_function("decode frames (Intel, Motorola, multiplexed)", |b| {
        let mut buf = Vec::with_capacity(8);
        b.iter(|| {
            let mut n = 0;
            for f in &frames {
                let m = db.message(f.id, f.extended).unwrap();
                buf.clear();
                m.decode_into(f.data(), &mut buf);
                n += buf.len();
            }
            black_box(n)
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

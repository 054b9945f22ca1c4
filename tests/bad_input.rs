//! Bad input (issue 2, item 6): truncated files, wrong magic, wrong payload sizes, bad block
//! flags, azimuth above 36000, non-UDP traffic, VLAN tags. Each gives a clear error with a byte
//! offset or a counted skip; nothing panics and nothing read before the problem is lost.

use crate::common;

use common::*;
use hilrig::capture::writer::{ethernet_frame, udp_ethernet_frame, udp_ipv4_packets};
use hilrig::capture::{LinkType, PcapngWriter, UtcNanos};
use hilrig::decode::lidar::{decode_capture, CountSink, LidarOptions};
use proptest::prelude::*;
use std::net::{Ipv4Addr, SocketAddrV4};
use std::path::{Path, PathBuf};

fn fixture() -> PathBuf {
    common::fixture("vlp16_room.pcapng")
}

fn run(args: &[&str]) -> (Option<i32>, String, String) {
    hilrig_decode(args)
}

fn rows(csv: &str) -> usize {
    csv.lines().count().saturating_sub(1)
}

#[test]
fn truncated_capture_keeps_every_point_before_the_cut_and_names_the_offset() {
    let full = std::fs::read(fixture()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (_, all_csv, _) = run(&[fixture().to_str().unwrap()]);
    let cut_at = full.len() / 2 + 333;
    let cut = dir.path().join("cut.pcapng");
    std::fs::write(&cut, &full[..cut_at]).unwrap();
    let (code, csv, stderr) = run(&[cut.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("the capture is truncated: the record at byte"),
        "{stderr}"
    );
    assert!(
        stderr.contains("every record before it was read"),
        "{stderr}"
    );
    // Every point of every complete record before the cut is there, identical.
    assert!(
        rows(&csv) > rows(&all_csv) / 3,
        "{} of {}",
        rows(&csv),
        rows(&all_csv)
    );
    assert!(
        all_csv.starts_with(&csv),
        "points before the cut must be identical"
    );
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn wrong_kind_of_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in [
        ("image.png", &b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR"[..]),
        ("empty.pcap", &b""[..]),
        ("notes.txt", &b"velodyne capture from monday\n"[..]),
    ] {
        let p = write(dir.path(), name, bytes);
        let (code, stdout, stderr) = run(&[p.to_str().unwrap()]);
        assert_eq!(code, Some(2), "{name}: {stderr}");
        assert!(
            stderr.contains("not a pcap or pcapng file"),
            "{name}: {stderr}"
        );
        assert!(
            stderr.contains(name),
            "{name}: the error names the file: {stderr}"
        );
        assert!(
            stdout.is_empty(),
            "nothing written for the wrong kind of file: {stdout}"
        );
    }
    let (code, _, stderr) = run(&["/nonexistent/drive.pcap"]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("cannot open /nonexistent/drive.pcap"),
        "{stderr}"
    );
}

/// A capture with one good packet and one of every kind of trouble, then another good packet.
fn troubled_capture() -> (Vec<u8>, usize) {
    let good = std::fs::read(fixture()).unwrap();
    // Take two good data packets from the fixture.
    let f = std::io::Cursor::new(good);
    let mut d = hilrig::capture::Demux::new(hilrig::capture::CaptureReader::new(f).unwrap());
    let mut data = Vec::new();
    while let Some(item) = d.next_item() {
        if let hilrig::capture::Packet::Udp { payload, .. } = item.unwrap().packet {
            if payload.len() == 1206 {
                data.push(payload.to_vec());
            }
        }
    }
    let ep = |port| SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 201), port);
    let mut w = PcapngWriter::new(Vec::new(), "bad input test").unwrap();
    let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
    let mut t = 1_700_000_000_000_000_000i64;
    let mut put = |w: &mut PcapngWriter<Vec<u8>>, frame: &[u8]| {
        t += 1_000_000;
        w.write_packet(eth, UtcNanos(t), frame).unwrap();
    };
    put(&mut w, &udp_ethernet_frame(ep(2368), ep(2368), &data[0]));
    // Wrong payload size on the data port.
    put(
        &mut w,
        &udp_ethernet_frame(ep(2368), ep(2368), &data[1][..1000]),
    );
    // Bad block flag in block 3.
    let mut bad = data[1].clone();
    bad[300] = 0x00;
    put(&mut w, &udp_ethernet_frame(ep(2368), ep(2368), &bad));
    // Azimuth above 36000 in block 7.
    let mut bad = data[1].clone();
    bad[702..704].copy_from_slice(&40_000u16.to_le_bytes());
    put(&mut w, &udp_ethernet_frame(ep(2368), ep(2368), &bad));
    // Non-UDP: ARP, and a TCP segment.
    let mut arp = vec![0xff; 12];
    arp.extend_from_slice(&[0x08, 0x06]);
    arp.extend_from_slice(&[0; 28]);
    put(&mut w, &arp);
    let mut tcp = udp_ipv4_packets(ep(5000), ep(80), &[0; 20], 9, 1500).remove(0);
    tcp[9] = 6;
    put(&mut w, &ethernet_frame(&tcp, None));
    // Truncated IPv4 inside a valid frame.
    put(&mut w, &ethernet_frame(&[0x45, 0, 0, 200, 0, 0], None));
    // A VLAN-tagged good packet (decodes).
    let vlan = udp_ipv4_packets(ep(2368), ep(2368), &data[2], 10, 1500).remove(0);
    put(&mut w, &ethernet_frame(&vlan, Some(0x0064)));
    put(&mut w, &udp_ethernet_frame(ep(2368), ep(2368), &data[3]));
    (w.finish().unwrap(), 3)
}

#[test]
fn packet_problems_are_counted_with_offsets_and_good_packets_still_decode() {
    let (bytes, good_packets) = troubled_capture();
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "troubled.pcapng", &bytes);
    let (code, csv, stderr) = run(&[p.to_str().unwrap(), "--model", "vlp16"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains("data packets: 3"), "{stderr}");
    assert!(
        stderr.contains("wrong payload size: expected 1206 bytes, got 1000"),
        "{stderr}"
    );
    assert!(
        stderr.contains("block 3 at byte 300 has flag 0xee00"),
        "{stderr}"
    );
    assert!(
        stderr.contains("block 7 azimuth at byte 702 is 40000"),
        "{stderr}"
    );
    assert!(stderr.contains("packet at byte "), "{stderr}");
    assert!(stderr.contains("not IPv4: 1"), "{stderr}");
    assert!(stderr.contains("IPv4 protocol 6, not UDP: 1"), "{stderr}");
    assert!(stderr.contains("truncated IPv4 packet: 1"), "{stderr}");
    let summary = {
        let mut sink = CountSink::default();
        decode_capture(
            std::io::Cursor::new(bytes),
            &LidarOptions::default(),
            &mut sink,
        )
        .unwrap()
    };
    assert_eq!(summary.data_packets, good_packets as u64);
    assert_eq!(summary.rejected.values().sum::<u64>(), 3);
    assert_eq!(summary.points as usize, rows(&csv));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Random byte flips, cuts and insertions anywhere in a capture never panic, and what decodes
    /// is never more than the file holds.
    #[test]
    fn corrupted_captures_never_panic(flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..40), cut in any::<usize>()) {
        let mut bytes = std::fs::read(fixture()).unwrap();
        for (at, v) in flips {
            let i = at % bytes.len();
            bytes[i] ^= v | 1;
        }
        bytes.truncate(bytes.len() - cut % (bytes.len() / 2));
        let mut sink = CountSink::default();
        if let Ok(s) = decode_capture(std::io::Cursor::new(bytes), &LidarOptions { model: Some(hilrig::velodyne::Model::Vlp16), ..LidarOptions::default() }, &mut sink) {
            prop_assert!(s.data_packets <= 160);
            prop_assert_eq!(s.points, sink.points);
        }
    }
}

/// The method's commands on a file that is not a recording (as a measured run, as a
/// re-simulation, as a study's run): exit 2, the file named and said not to be MCAP, and no
/// output written.
#[test]
fn the_method_commands_name_a_file_that_is_not_a_recording() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (run, _) = record_and_resim(d, 1, &[]);
    let bogus = write(d, "notes.mcap", b"velodyne drive of monday\n");
    let scene = common::fixture("parking/rep-01/scene.toml");
    let model = common::fixture("parking/idealized.toml");
    let out = d.join("out");
    let p = |x: &Path| x.to_str().unwrap().to_owned();
    let cases: Vec<Vec<String>> = vec![
        vec!["check".into(), p(&bogus), "--json".into(), p(&out)],
        vec![
            "resim".into(),
            p(&bogus),
            "--scene".into(),
            p(&scene),
            "--model".into(),
            p(&model),
            "-o".into(),
            p(&out),
        ],
        vec![
            "compare".into(),
            p(&bogus),
            p(&run),
            "--scene".into(),
            p(&scene),
            "--json".into(),
            p(&out),
        ],
        vec![
            "compare".into(),
            p(&run),
            p(&bogus),
            "--scene".into(),
            p(&scene),
            "--json".into(),
            p(&out),
        ],
        vec![
            "validate".into(),
            "--real".into(),
            p(&bogus),
            "--sim".into(),
            p(&run),
            "--json".into(),
            p(&out),
        ],
        vec![
            "gap".into(),
            "--real".into(),
            p(&bogus),
            "--validate".into(),
            p(&run),
            "--scene".into(),
            p(&scene),
            "--model".into(),
            p(&model),
            "-o".into(),
            p(&out),
        ],
    ];
    for args in cases {
        let o = std::process::Command::new(hilrig_bin())
            .args(&args)
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(o.status.code(), Some(2), "{args:?}: {text}");
        assert!(text.contains("notes.mcap: not an MCAP"), "{args:?}: {text}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
}

//! Captures this project makes itself (fixtures/), regenerated and checked byte for byte, and
//! decoded back to the geometry they were made from.
//!
//! The scene is a round room: a static sensor 1.8 m above a flat floor, inside a cylindrical wall
//! of radius 8 m, with a doorway (no return) between 90° and 100° azimuth. Ranges are analytic,
//! so the decoded points can be checked against closed-form values. The generator is in
//! `tests/room/`; after an intended change of it, `cargo run --example bless_room_fixtures`
//! rewrites the files (a test never does).

use crate::common;
use crate::room;

use hilrig::velodyne::{DataPacket, PositionPacket, PpsStatus, ReturnMode};
use room::*;

#[test]
fn fixtures_are_reproducible() {
    for (name, model, mode, packets) in FIXTURES {
        let bytes = generate(model, mode, packets);
        let path = fixture_path(name);
        let committed = std::fs::read(&path).unwrap_or_else(|e| {
            panic!(
                "{}: {e} (after an intended change: cargo run --example bless_room_fixtures)",
                path.display()
            )
        });
        assert!(
            committed == bytes,
            "{name} differs from what the generator makes now (after an intended change of the \
             generator: cargo run --example bless_room_fixtures)"
        );
    }
}

#[test]
fn fixture_points_match_the_analytic_room_and_packets_re_encode() {
    for (name, model, mode, packets) in FIXTURES {
        let path = fixture_path(name);
        let (summary, points) =
            common::decode_file(&path, &hilrig::decode::lidar::LidarOptions::default());
        assert_eq!(summary.model, Some(model));
        assert_eq!(summary.data_packets, packets as u64);
        assert_eq!(summary.lost_packets, 0, "{name}");
        assert_eq!(
            summary.hour_source,
            Some(hilrig::velodyne::clock::HourSource::Rmc)
        );
        assert_eq!(summary.pps, Some(PpsStatus::Locked));
        let res = model.distance_resolution_m();
        let cal = hilrig::velodyne::Calibration::builtin(model);
        let mut checked = 0;
        for (_, p) in &points {
            let l = &cal.lasers[usize::from(p.laser.0)];
            if p.return_type == hilrig::velodyne::ReturnType::Strongest && mode == ReturnMode::Dual
            {
                assert!(
                    (f64::from(p.distance_m) - 1.5).abs() <= res,
                    "{name}: early echo"
                );
                continue;
            }
            let az_beam =
                (f64::from(p.azimuth_deg) - l.rot_correction_rad.to_degrees()).rem_euclid(360.0);
            // Away from the floor/wall edge and the doorway's sides the range is analytic.
            if (89.0..101.0).contains(&az_beam) {
                continue;
            }
            let expected = room_range(l.vertical_rad, az_beam).expect("a return");
            assert!(
                (f64::from(p.distance_m) - expected).abs() <= res / 2.0 + 1e-6,
                "{name}: {p:?} vs {expected}"
            );
            // The geometry closes: the point lies on the floor or on the wall.
            let (x, y, z) = (
                f64::from(p.x),
                f64::from(p.y),
                f64::from(p.z) - l.z_offset_m,
            );
            let on_floor = (z + HEIGHT).abs() < 0.01;
            let on_wall = ((x * x + y * y).sqrt() - RADIUS).abs() < 0.01;
            assert!(
                on_floor || on_wall,
                "{name}: ({x}, {y}, {z}) is on neither floor nor wall"
            );
            checked += 1;
        }
        assert!(
            checked > packets * 100,
            "{name}: only {checked} points checked"
        );
        // Every data and position packet re-encodes to its bytes.
        let f = std::fs::File::open(&path).unwrap();
        let mut d = hilrig::capture::Demux::new(hilrig::capture::CaptureReader::new(f).unwrap());
        let mut n = 0;
        while let Some(item) = d.next_item() {
            if let hilrig::capture::Packet::Udp { payload, .. } = item.unwrap().packet {
                if payload.len() == 1206 {
                    assert_eq!(&DataPacket::decode(payload).unwrap().encode()[..], payload);
                } else {
                    assert_eq!(
                        &PositionPacket::decode(payload).unwrap().encode()[..],
                        payload
                    );
                }
                n += 1;
            }
        }
        assert!(n > packets);
    }
}

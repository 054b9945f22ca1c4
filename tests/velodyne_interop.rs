//! Interop: hilrig's Velodyne decoder against the PyPI package velodyne-decoder 3.1.0 on every
//! real capture in ../shared/data/velodyne (issue 2, "must hold" 1).
//!
//! Point by point: same count, same ring, same return type, same intensity, distance within
//! 1 mm, x/y/z within 1 cm. Two systematic differences are explained and checked here rather than
//! hidden by a looser tolerance:
//!
//! 1. velodyne-decoder adds a constant z shift per laser for the HDL-32E and VLP-32C: an offset of
//!    the form `-r tan(ω)` (the beam origin sits at radius r from the rotation axis; 28.9 mm and
//!    42.4 mm from its output). hilrig's built-in tables carry the manuals' vertical corrections
//!    only for the VLP-16 and Puck Hi-Res (where both decoders agree), so for the other two the
//!    test measures the per-laser shift, asserts it is constant per laser and of that `r tan ω`
//!    form with one r, and compares z after removing it. VeloView has no such shift either
//!    (shared/data/README.md), so hilrig agrees with VeloView's z on the HDL-32E.
//! 2. velodyne-decoder rounds each interpolated azimuth to 0.01°; hilrig keeps it exact. At 100 m
//!    that is up to 8.7 mm sideways, inside the 1 cm bound (checked, not loosened).

mod common;

use common::*;
use hilrig::decode::lidar::LidarOptions;
use std::collections::BTreeMap;
use std::process::Command;

struct Ref {
    x: f64,
    y: f64,
    z: f64,
    intensity: u8,
    ring: u8,
    return_type: u8,
}

fn reference_points(capture: &std::path::Path) -> Vec<Ref> {
    let out = tempfile::NamedTempFile::new().unwrap();
    let status = Command::new(python())
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/interop/velodyne_decoder_points.py"
        ))
        .arg(capture)
        .arg(out.path())
        .status()
        .expect("run the velodyne-decoder helper");
    assert!(
        status.success(),
        "velodyne-decoder failed on {}",
        capture.display()
    );
    let text = std::fs::read_to_string(out.path()).unwrap();
    text.lines()
        .filter(|l| !l.is_empty())
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            Ref {
                x: f[0],
                y: f[1],
                z: f[2],
                intensity: f[3] as u8,
                ring: f[4] as u8,
                return_type: f[5] as u8,
            }
        })
        .collect()
}

fn compare(name: &str) {
    compare_file(
        name,
        &real_data().join("velodyne").join(format!("{name}.pcap")),
    );
}

fn compare_file(name: &str, path: &std::path::Path) {
    let path = path.to_owned();
    let reference = reference_points(&path);
    let (summary, ours) = decode_file(&path, &LidarOptions::default());
    let model = summary.model.expect("model");
    println!(
        "{name}: {} points (velodyne-decoder {})",
        ours.len(),
        reference.len()
    );
    assert_eq!(ours.len(), reference.len(), "{name}: point count");

    // Per-ring z shift of velodyne-decoder relative to hilrig.
    let mut dz: BTreeMap<u8, Vec<f64>> = BTreeMap::new();
    for ((_, p), r) in ours.iter().zip(&reference) {
        assert_eq!(p.ring, r.ring, "{name}: ring");
        assert_eq!(p.return_type as u8, r.return_type, "{name}: return type");
        assert_eq!(p.intensity, r.intensity, "{name}: intensity");
        dz.entry(p.ring).or_default().push(r.z - f64::from(p.z));
    }
    let cal = hilrig::velodyne::Calibration::builtin(model);
    let mut shift = BTreeMap::new();
    let mut levers = Vec::new();
    for (ring, v) in &mut dz {
        v.sort_by(f64::total_cmp);
        let median = v[v.len() / 2];
        let spread = v[v.len() - 1] - v[0];
        assert!(
            spread < 0.0015,
            "{name}: ring {ring}: z difference is not a constant shift (spread {spread} m)"
        );
        let omega = cal
            .lasers
            .iter()
            .find(|l| l.ring == *ring)
            .unwrap()
            .vertical_rad;
        if omega.abs() > 3f64.to_radians() {
            levers.push(-median / omega.tan());
        }
        shift.insert(*ring, median);
    }
    levers.sort_by(f64::total_cmp);
    let (lo, hi) = (levers[0], levers[levers.len() - 1]);
    println!(
        "{name}: velodyne-decoder z shift = -r tan(ω) with r in [{:.1}, {:.1}] mm",
        lo * 1e3,
        hi * 1e3
    );
    match model {
        hilrig::velodyne::Model::Vlp16 | hilrig::velodyne::Model::PuckHiRes => {
            assert!(
                hi.abs() < 0.0015 && lo.abs() < 0.0015,
                "{name}: both decoders apply the manual's corrections"
            );
        }
        _ => {
            assert!(
                hi - lo < 0.0015,
                "{name}: the shift is one lever arm for all lasers"
            );
            // velodyne-decoder 3.1.0 places every beam's origin at the "focal point where all
            // laser beams intersect", a documented distance from the sensor's axis (its
            // calibration.cpp: HDL-32E 28.83 mm, VLP-32A/C 42.4 mm), and so lowers each point by
            // that distance times tan(ω); hilrig, like VeloView, casts from the axis. The lever
            // fitted here must be that distance (half a millimetre covers the f32 z of its output
            // divided by tan 3°).
            let focal = match model {
                hilrig::velodyne::Model::Hdl32e => 0.028_83,
                hilrig::velodyne::Model::Vlp32c => 0.042_4,
                other => panic!("{name}: no documented focal distance for {other}"),
            };
            assert!(
                (lo - focal).abs() < 0.0005 && (hi - focal).abs() < 0.0005,
                "{name}: lever [{lo}, {hi}] m, velodyne-decoder's focal distance {focal} m"
            );
        }
    }

    let (mut max_xy, mut max_z, mut max_d) = (0f64, 0f64, 0f64);
    for ((_, p), r) in ours.iter().zip(&reference) {
        let z_ref = r.z - shift[&p.ring];
        // Without the z shift the reference norm is the distance up to the manual's z correction.
        let cal_l = cal.lasers.iter().find(|l| l.ring == p.ring).unwrap();
        let d_ours = {
            let z0 = f64::from(p.z) - cal_l.z_offset_m;
            (f64::from(p.x).powi(2) + f64::from(p.y).powi(2) + z0 * z0).sqrt()
        };
        let d_ref_unshifted = {
            let z0 = z_ref - cal_l.z_offset_m;
            (r.x * r.x + r.y * r.y + z0 * z0).sqrt()
        };
        max_d = max_d.max((f64::from(p.distance_m) - d_ref_unshifted).abs());
        assert!((d_ours - f64::from(p.distance_m)).abs() < 1e-3);
        max_xy = max_xy
            .max((f64::from(p.x) - r.x).abs())
            .max((f64::from(p.y) - r.y).abs());
        max_z = max_z.max((f64::from(p.z) - z_ref).abs());
    }
    println!(
        "{name}: max |Δdistance| {:.2} mm, max |Δx|,|Δy| {:.2} mm, max |Δz| {:.2} mm",
        max_d * 1e3,
        max_xy * 1e3,
        max_z * 1e3
    );
    assert!(max_d < 0.001, "{name}: distance within 1 mm");
    assert!(max_xy < 0.01, "{name}: x, y within 1 cm");
    assert!(max_z < 0.01, "{name}: z within 1 cm");
}

macro_rules! interop {
    ($($name:ident),*) => {$(
        #[test]
        #[cfg_attr(not(all(hilrig_real_data, hilrig_python)), ignore = "needs HILRIG_REAL_DATA and HILRIG_PYTHON (set by .ci/run): did not run")]
        fn $name() {
            compare(stringify!($name));
        }
    )*};
}

interop!(hdl32e_monterey, vlp16_single, vlp16_dual, vlp32c);

/// Must-hold 2 of issue 5: packets the simulator wrote (the committed parking drive, truth model
/// with noise, beam divergence and Lambertian intensity) decode to the same points with hilrig
/// and with velodyne-decoder. velodyne-decoder reads classic pcap, so the lidar frames are copied
/// out of the zstd-compressed pcapng first.
#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn simulated_parking_drive() {
    use hilrig::capture::{CaptureReader, LinkType, PcapWriter};
    let src = fixture("parking/rep-01/drive.pcapng.zst");
    let mut reader = CaptureReader::new(std::fs::File::open(&src).unwrap()).unwrap();
    let mut w = PcapWriter::new(Vec::new(), LinkType::ETHERNET, false, true).unwrap();
    let mut frames = 0;
    while let Some(r) = reader.next_record() {
        let r = r.unwrap();
        if r.link == LinkType::ETHERNET {
            w.write_packet(r.time, r.data).unwrap();
            frames += 1;
        }
    }
    assert!(frames > 10_000, "{frames} lidar frames");
    let dir = tempfile::tempdir().unwrap();
    let pcap = dir.path().join("parking_rep01.pcap");
    std::fs::write(&pcap, w.finish().unwrap()).unwrap();
    compare_file("parking rep-01 (simulated)", &pcap);
}

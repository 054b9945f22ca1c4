//! Interop: hilrig's Velodyne decoder against the PyPI package velodyne-decoder 3.1.0 on every
//! real capture in ../shared/data/velodyne (issue 2, "must hold" 1).
//!
//! Point by point: same count, same ring, same return type, same intensity, distance within
//! 1 mm, x/y/z within 1 cm. Two systematic differences are explained and checked here rather than
//! hidden by a looser tolerance:
//!
//! 1. velodyne-decoder adds a constant z shift per laser for the HDL-32E and VLP-32C: an offset of
//!    the form `-r tan(ω)` (the beam origin sits at radius r from the rotation axis; 28.9 mm and
//!    42.4 mm from its output; 58.6 mm for the VLS-128). hilrig's built-in tables carry the manuals' vertical corrections
//!    only for the VLP-16 and Puck Hi-Res (where both decoders agree), so for the other two the
//!    test measures the per-laser shift, asserts it is constant per laser and of that `r tan ω`
//!    form with one r, and compares z after removing it. VeloView has no such shift either
//!    (shared/data/README.md), so hilrig agrees with VeloView's z on the HDL-32E.
//! 2. velodyne-decoder rounds each interpolated azimuth to 0.01°; hilrig keeps it exact. At 100 m
//!    that is up to 8.7 mm sideways, inside the 1 cm bound; the VLS-128 sees to 240 m, where it
//!    is up to 2.1 cm: there the bound is the rounding's, and every azimuth must agree to 0.0055°.
//! 3. VLS-128: velodyne-decoder takes the rotation rate from the packet before (173.4 µs back),
//!    so it does not interpolate the first packet of a file; those points are compared in
//!    azimuth to the rotation of one firing sequence (0.2°). hilrig takes the rate within the
//!    packet, from its first to its third sequence (115.6 µs), so it needs no state. Both rates
//!    come from block azimuths quantised to 0.01°, so they may differ by 0.01° over either span;
//!    times a firing's delay in its sequence (up to 55 µs) that is up to 0.008° more, growing
//!    over the sequence. The bound per point is 0.0055° plus that share.

use crate::common;

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

fn reference_points(capture: &std::path::Path, forced: &[&std::ffi::OsStr]) -> Vec<Ref> {
    let out = tempfile::NamedTempFile::new().unwrap();
    let status = Command::new(python())
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/interop/velodyne_decoder_points.py"
        ))
        .arg(capture)
        .arg(out.path())
        .args(forced)
        .status()
        .expect("run the velodyne-decoder helper");
    assert!(
        status.success(),
        "velodyne-decoder failed on {}",
        capture.display()
    );
    // Eight little-endian float64 per point (the helper's doc).
    let bytes = std::fs::read(out.path()).unwrap();
    assert_eq!(bytes.len() % 64, 0, "{}: a partial row", capture.display());
    bytes
        .chunks_exact(64)
        .map(|row| {
            let f = |i: usize| f64::from_le_bytes(row[8 * i..8 * i + 8].try_into().unwrap());
            Ref {
                x: f(0),
                y: f(1),
                z: f(2),
                intensity: f(3) as u8,
                ring: f(4) as u8,
                return_type: f(5) as u8,
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
    compare_file_as(name, path, None);
}

/// Compares with the model (and the calibration file) given to both decoders when the packets
/// do not name them (the HDL-64E).
fn compare_file_as(
    name: &str,
    path: &std::path::Path,
    forced: Option<(hilrig::velodyne::Model, &str, Option<&std::path::Path>)>,
) {
    let path = path.to_owned();
    let (reference, options) = match forced {
        Some((model, vd_model, calibration)) => {
            let mut args: Vec<&std::ffi::OsStr> = vec![vd_model.as_ref()];
            args.extend(calibration.map(|c| c.as_os_str()));
            (
                reference_points(&path, &args),
                LidarOptions {
                    model: Some(model),
                    calibration: calibration
                        .map(|c| hilrig::velodyne::Calibration::from_file(c, model).unwrap()),
                    ..LidarOptions::default()
                },
            )
        }
        None => (reference_points(&path, &[]), LidarOptions::default()),
    };
    let (summary, ours) = decode_file(&path, &options);
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
    let cal = options
        .calibration
        .clone()
        .unwrap_or_else(|| hilrig::velodyne::Calibration::builtin(model));
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
    // With a calibration file both decoders take the file's offsets (none here).
    let from_file = options.calibration.is_some();
    match model {
        _ if from_file => {
            assert!(
                hi.abs() < 0.0015 && lo.abs() < 0.0015,
                "{name}: both decoders apply the file's geometry"
            );
        }
        hilrig::velodyne::Model::Vlp16
        | hilrig::velodyne::Model::PuckHiRes
        | hilrig::velodyne::Model::Hdl64eS2
        | hilrig::velodyne::Model::Hdl64eS3 => {
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
            // calib_db.cpp: HDL-32E 28.83 mm, VLP-32A/C 42.4 mm, VLS-128 58.63 mm), and so lowers each point by
            // that distance times tan(ω); hilrig, like VeloView, casts from the axis. The lever
            // fitted here must be that distance (half a millimetre covers the f32 z of its output
            // divided by tan 3°).
            let focal = match model {
                hilrig::velodyne::Model::Hdl32e => 0.028_83,
                hilrig::velodyne::Model::Vlp32c | hilrig::velodyne::Model::Vlp32b => 0.042_4,
                hilrig::velodyne::Model::Vls128 => 0.058_63,
                other => panic!("{name}: no documented focal distance for {other}"),
            };
            assert!(
                (lo - focal).abs() < 0.0005 && (hi - focal).abs() < 0.0005,
                "{name}: lever [{lo}, {hi}] m, velodyne-decoder's focal distance {focal} m"
            );
        }
    }

    // velodyne-decoder interpolates the VLS-128's firing azimuths with the rotation rate since
    // the previous packet, so it cannot interpolate the file's first packet (it places its
    // firings at their blocks' azimuths). Those points are compared in count, ring, return type,
    // intensity and distance above, and in azimuth here: they may differ by no more than the
    // rotation during one firing sequence.
    let first_packet = if model == hilrig::velodyne::Model::Vls128 {
        ours.iter().take_while(|(t, _)| *t == ours[0].0).count()
    } else {
        0
    };
    let azimuth = |x: f64, y: f64| y.atan2(x).to_degrees();
    let (mut max_xy, mut max_z, mut max_d, mut max_az) = (0f64, 0f64, 0f64, 0f64);
    for (i, ((_, p), r)) in ours.iter().zip(&reference).enumerate() {
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
        max_z = max_z.max((f64::from(p.z) - z_ref).abs());
        let daz = (azimuth(f64::from(p.x), f64::from(p.y)) - azimuth(r.x, r.y) + 540.0)
            .rem_euclid(360.0)
            - 180.0;
        if i < first_packet {
            assert!(daz.abs() < 0.2, "{name}: first packet, point {i}: {daz}°");
            continue;
        }
        // The reference rounds azimuths to 0.01°: up to 0.005° sideways, which beyond 115 m
        // (the VLS-128 sees to 240 m) is more than 1 cm. On the VLS-128 the two decoders also
        // take the rotation rate from different spans of 0.01°-quantised block azimuths (see
        // the module's note 3), which may add up to 0.008° at the end of a firing sequence.
        // Where these alone can exceed 1 cm, the bound is what they allow.
        let allowed_deg = 0.0055
            + if model == hilrig::velodyne::Model::Vls128 {
                let sequence_ns = 20.0 * hilrig::velodyne::model::VLS128_SLOT_US * 1000.0;
                0.008 * (f64::from(p.time_offset_ns) % sequence_ns) / (19.0 / 20.0 * sequence_ns)
            } else {
                0.0
            };
        assert!(
            daz.abs() <= allowed_deg,
            "{name}: point {i}: azimuths differ by {daz}°, more than {allowed_deg}°"
        );
        let exy = (f64::from(p.x) - r.x)
            .abs()
            .max((f64::from(p.y) - r.y).abs());
        let sideways = f64::from(p.distance_m) * allowed_deg.to_radians();
        if exy > 0.01 {
            assert!(
                exy <= sideways + 1e-3,
                "{name}: point {i} at {} m: {exy} m sideways, more than the azimuth bound allows",
                p.distance_m
            );
        } else {
            max_xy = max_xy.max(exy);
        }
        max_az = max_az.max(daz.abs());
    }
    println!(
        "{name}: max |Δdistance| {:.2} mm, max |Δx|,|Δy| {:.2} mm (where the rounding stays below 1 cm), max |Δz| {:.2} mm, max |Δazimuth| {:.4}°{}",
        max_d * 1e3,
        max_xy * 1e3,
        max_z * 1e3,
        max_az,
        if first_packet > 0 {
            format!(" ({first_packet} points of the first packet compared in azimuth only)")
        } else {
            String::new()
        }
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

interop!(hdl32e_monterey, vlp16_single, vlp16_dual, vlp32c, vls128);

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

/// The x, y, z of a binary PCD file (fields x y z, f32).
fn read_pcd_xyz(path: &std::path::Path) -> Vec<[f64; 3]> {
    let bytes = std::fs::read(path).unwrap();
    let marker = b"DATA binary\n";
    let at = bytes
        .windows(marker.len())
        .position(|w| w == marker)
        .expect("a binary PCD")
        + marker.len();
    bytes[at..]
        .chunks_exact(12)
        .map(|c| {
            let f = |i: usize| f64::from(f32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]));
            [f(0), f(4), f(8)]
        })
        .collect()
}

/// Median distance from each of `points` to the nearest of `cloud`.
fn median_nearest(cloud: &[[f64; 3]], points: &[[f64; 3]]) -> f64 {
    let tree: kiddo::ImmutableKdTree<f64, 3> =
        kiddo::ImmutableKdTree::new_from_slice(cloud).unwrap();
    let mut d: Vec<f64> = points
        .iter()
        .map(|p| {
            tree.query(p)
                .nearest_one::<kiddo::SquaredEuclidean<f64>>()
                .execute()
                .distance
                .sqrt()
        })
        .collect();
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

/// Issue 14, must-hold 1, second half: nebula's decoded VLS-128 cloud. Its file comes from
/// another instant of the drive than the packets in the capture (shared/data/README.md), so
/// points cannot be paired; what can be checked is that every surface nebula saw is where hilrig
/// puts it. The median distance from nebula's points to hilrig's cloud (all four scans) is at
/// the centimetre level, and the check can fail: the same cloud turned by 0.2° about the
/// sensor's axis, or lifted by 2 cm, is measurably farther.
#[test]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
fn vls128_agrees_with_nebulas_cloud_at_the_cm_level() {
    let dir = real_data().join("velodyne");
    let nebula = read_pcd_xyz(&dir.join("vls128.nebula-points.pcd"));
    assert_eq!(nebula.len(), 208_680);
    let (_, ours) = decode_file(&dir.join("vls128.pcap"), &LidarOptions::default());
    let cloud: Vec<[f64; 3]> = ours
        .iter()
        .map(|(_, p)| [f64::from(p.x), f64::from(p.y), f64::from(p.z)])
        .collect();
    let median = median_nearest(&cloud, &nebula);
    let (s, c) = 0.2f64.to_radians().sin_cos();
    let turned: Vec<[f64; 3]> = cloud
        .iter()
        .map(|p| [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]])
        .collect();
    let lifted: Vec<[f64; 3]> = cloud.iter().map(|p| [p[0], p[1], p[2] + 0.02]).collect();
    let (m_turned, m_lifted) = (
        median_nearest(&turned, &nebula),
        median_nearest(&lifted, &nebula),
    );
    println!(
        "vls128 vs nebula: median nearest distance {:.1} mm (turned 0.2°: {:.1} mm, lifted 2 cm: {:.1} mm)",
        median * 1e3,
        m_turned * 1e3,
        m_lifted * 1e3
    );
    assert!(median < 0.015, "median {median} m");
    assert!(m_turned > median + 0.008 && m_lifted > median + 0.008);
}

/// A drive `synth` makes with the demo rig's lidar swapped for `model` (with `calibration`, a
/// rig line, if any) in return mode `mode`: the first 2 m of the short parking-aisle drive of
/// fixtures/efast (about 2.9 s with the lead-in and out, 29 rotations: thousands of packets of
/// every block layout of a rotation; the whole 10 m, 6.3 s, took a minute and a half of the
/// test run for the 64- and 128-laser sensors alone, and decoded nothing new), with the parking
/// truth model (noise, beam divergence, dropout, Lambertian intensity). Returns the lidar
/// frames as a classic pcap (what velodyne-decoder reads).
fn synthesized_lidar_pcap(
    dir: &std::path::Path,
    model: &str,
    calibration: &str,
    mode: &str,
) -> std::path::PathBuf {
    use hilrig::capture::{CaptureReader, LinkType, PcapWriter};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let rig = std::fs::read_to_string(root.join("rigs/demo.toml"))
        .unwrap()
        .replace(
            "model = \"vlp16\"",
            &format!("model = {model:?}\n{calibration}"),
        )
        .replace(
            "dbc = \"hilrig-ego.dbc\"",
            &format!("dbc = {:?}", root.join("rigs/hilrig-ego.dbc")),
        );
    let rig_path = dir.join(format!("{model}.toml"));
    std::fs::write(&rig_path, rig).unwrap();
    let drive = std::fs::read_to_string(root.join("fixtures/efast/drive.toml"))
        .unwrap()
        .replace(
            "rig = \"../../rigs/demo.toml\"",
            &format!("rig = {rig_path:?}"),
        )
        .replace(
            "return_mode = \"strongest\"",
            &format!("return_mode = {mode:?}"),
        )
        .replace(
            "waypoints = [[-16.0, 0.0], [-6.0, 0.0]]",
            "waypoints = [[-16.0, 0.0], [-14.0, 0.0]]",
        );
    assert!(drive.contains("[-14.0, 0.0]"), "{drive}");
    let drive_path = dir.join(format!("drive-{model}-{mode}.toml"));
    std::fs::write(&drive_path, drive).unwrap();
    let out = dir.join(format!("{model}-{mode}"));
    hilrig_ok(&[
        "synth".as_ref(),
        "--scene".as_ref(),
        root.join("fixtures/parking/scene.toml").as_os_str(),
        "--drive".as_ref(),
        drive_path.as_os_str(),
        "--truth".as_ref(),
        root.join("fixtures/parking/truth-model.toml").as_os_str(),
        "--reps".as_ref(),
        "1".as_ref(),
        "--seed".as_ref(),
        "11".as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    let capture = out.join("rep-01/drive.pcapng");
    let mut reader = CaptureReader::new(std::fs::File::open(&capture).unwrap()).unwrap();
    let mut w = PcapWriter::new(Vec::new(), LinkType::ETHERNET, false, true).unwrap();
    let mut frames = 0;
    while let Some(r) = reader.next_record() {
        let r = r.unwrap();
        if r.link == LinkType::ETHERNET && r.data.len() > 1200 {
            w.write_packet(r.time, r.data).unwrap();
            frames += 1;
        }
    }
    assert!(frames > 1000, "{model} {mode}: {frames} lidar frames");
    let pcap = dir.join(format!("{model}-{mode}.pcap"));
    std::fs::write(&pcap, w.finish().unwrap()).unwrap();
    pcap
}

/// Issue 14, must-hold 2 (VLS-128): drives `synth` makes with a VLS-128 rig, strongest and dual
/// return, decode equal to velodyne-decoder.
#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn simulated_vls128_drives_strongest_and_dual() {
    let dir = tempfile::tempdir().unwrap();
    for mode in ["strongest", "dual"] {
        let pcap = synthesized_lidar_pcap(dir.path(), "vls128", "", mode);
        compare_file(&format!("synthesized VLS-128 {mode}"), &pcap);
    }
}

/// Issue 14, must-hold 2 (HDL-64E S3): with a calibration file, as a 64E needs; every laser's
/// angles moved off the nominal table so that a decoder ignoring the file would fail. Both
/// decoders are told the model (the 64E writes no product byte) and the file.
#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn simulated_hdl64e_s3_drives_with_a_calibration_file_strongest_and_dual() {
    let dir = tempfile::tempdir().unwrap();
    let model = hilrig::velodyne::Model::Hdl64eS3;
    let nominal = hilrig::velodyne::Calibration::builtin(model);
    let mut yaml = String::from("distance_resolution: 0.002\nnum_lasers: 64\nlasers:\n");
    for (i, l) in nominal.lasers.iter().enumerate() {
        let k = i as f64;
        yaml.push_str(&format!(
            "- {{laser_id: {i}, rot_correction: {}, vert_correction: {}}}\n",
            0.08 * (0.7 * k).sin(),
            l.vertical_rad + 0.004 * (1.3 * k).cos()
        ));
    }
    let calibration = dir.path().join("hdl64e-s3.yml");
    std::fs::write(&calibration, yaml).unwrap();
    for mode in ["strongest", "dual"] {
        let pcap = synthesized_lidar_pcap(
            dir.path(),
            "hdl64e-s3",
            &format!("calibration = {calibration:?}"),
            mode,
        );
        compare_file_as(
            &format!("synthesized HDL-64E S3 {mode}"),
            &pcap,
            Some((model, "HDL64E_S3", Some(&calibration))),
        );
    }
}

/// Issue 14 (VLP-32A/B, product byte 0x23): drives `synth` makes with a VLP-32B rig (the
/// VLP-32C's geometry, which VeloView's VLP-32B calibration equals) and with a VLP-32A rig and
/// its unit's calibration file (the VLP-32A has no published table) decode equal to
/// velodyne-decoder told the same model; without a model the byte is refused as ambiguous.
#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn simulated_vlp32a_and_vlp32b_drives() {
    let dir = tempfile::tempdir().unwrap();
    let pcap = synthesized_lidar_pcap(dir.path(), "vlp32b", "", "dual");
    compare_file_as(
        "synthesized VLP-32B dual",
        &pcap,
        Some((hilrig::velodyne::Model::Vlp32b, "VLP32B", None)),
    );
    let (code, _, err) = hilrig_decode(&[pcap.to_str().unwrap(), "--format", "summary"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("product byte 0x23")
            && err.contains("--model (vlp32a or vlp32b)")
            && err.lines().count() == 1,
        "{err}"
    );

    let model = hilrig::velodyne::Model::Vlp32a;
    let nominal = hilrig::velodyne::Calibration::builtin(model);
    let mut yaml = String::from("distance_resolution: 0.004\nnum_lasers: 32\nlasers:\n");
    for (i, l) in nominal.lasers.iter().enumerate() {
        let k = i as f64;
        yaml.push_str(&format!(
            "- {{laser_id: {i}, rot_correction: {}, vert_correction: {}}}\n",
            l.rot_correction_rad + 0.01 * (0.7 * k).sin(),
            l.vertical_rad + 0.003 * (1.3 * k).cos()
        ));
    }
    let calibration = dir.path().join("vlp32a.yml");
    std::fs::write(&calibration, yaml).unwrap();
    let pcap = synthesized_lidar_pcap(
        dir.path(),
        "vlp32a",
        &format!("calibration = {calibration:?}"),
        "strongest",
    );
    compare_file_as(
        "synthesized VLP-32A strongest",
        &pcap,
        Some((model, "VLP32A", Some(&calibration))),
    );
}

/// One HDL-64E laser as a unit's calibration gives it (metres, radians).
struct Laser64 {
    rot: f64,
    vert: f64,
    vo: f64,
    ho: f64,
    dc: f64,
    dcx: f64,
    dcy: f64,
}

/// Issue 14 (HDL-64E calibration as Velodyne delivers it): a VeloView XML file with every
/// correction a real unit has (centimetre offsets, far corrections over a metre, near-point
/// corrections a few centimetres off) goes through `synth`'s rig and `decode`. hilrig's points
/// follow the HDL-64E manual's formulas as ros-drivers and VeloView implement them; those
/// formulas are written out again here and hilrig must meet them to 1 mm, which checks the
/// XML's units and signs. velodyne-decoder, given the same calibration in its YAML form, must
/// meet its own published variant (`packet_decoder.cpp`, 3.1.0), which differs in three
/// documented ways: the vertical offset added to z only (not perpendicular to the beam), the
/// near-point correction applied only below 25.04 m (the manual extrapolates it), and z
/// corrected by the mean of the x and y corrections (the manual takes y's). The test prints how
/// far apart the two decoders' points are because of that.
#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn simulated_hdl64e_s3_with_a_veloview_xml_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let model = hilrig::velodyne::Model::Hdl64eS3;
    let nominal = hilrig::velodyne::Calibration::builtin(model);
    let lasers: Vec<Laser64> = nominal
        .lasers
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let k = i as f64;
            let dc = 1.3 + 0.1 * (0.9 * k).sin();
            Laser64 {
                rot: 0.08 * (0.7 * k).sin(),
                vert: l.vertical_rad + 0.004 * (1.3 * k).cos(),
                vo: 0.2 + 0.01 * (0.3 * k).cos(),
                ho: if i % 2 == 0 { 0.026 } else { -0.026 },
                dc,
                dcx: dc + 0.04 * (1.1 * k).cos(),
                dcy: dc - 0.03 * (0.5 * k).sin(),
            }
        })
        .collect();
    // VeloView's db.xml: degrees and centimetres.
    let mut xml = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\" ?>\n<!DOCTYPE boost_serialization>\n<boost_serialization signature=\"serialization::archive\" version=\"4\">\n<DB class_id=\"0\" tracking_level=\"0\" version=\"0\">\n<distLSB_>0.2</distLSB_>\n<points_ class_id=\"5\" tracking_level=\"0\" version=\"0\">\n<count>64</count>\n");
    // The same numbers as ros-drivers' gen_calibration.py writes them (radians, metres).
    let mut yaml = String::from("distance_resolution: 0.002\nnum_lasers: 64\nlasers:\n");
    for (i, l) in lasers.iter().enumerate() {
        xml.push_str(&format!(
            "<item class_id=\"6\" tracking_level=\"0\" version=\"1\"><px class_id=\"7\" tracking_level=\"0\" version=\"1\"><id_>{i}</id_><rotCorrection_>{}</rotCorrection_><vertCorrection_>{}</vertCorrection_><distCorrection_>{}</distCorrection_><distCorrectionX_>{}</distCorrectionX_><distCorrectionY_>{}</distCorrectionY_><vertOffsetCorrection_>{}</vertOffsetCorrection_><horizOffsetCorrection_>{}</horizOffsetCorrection_><focalDistance_>1500</focalDistance_><focalSlope_>1.2</focalSlope_></px></item>\n",
            l.rot.to_degrees(),
            l.vert.to_degrees(),
            l.dc * 100.0,
            l.dcx * 100.0,
            l.dcy * 100.0,
            l.vo * 100.0,
            l.ho * 100.0
        ));
        yaml.push_str(&format!(
            "- {{laser_id: {i}, rot_correction: {}, vert_correction: {}, vert_offset_correction: {}, horiz_offset_correction: {}, dist_correction: {}, dist_correction_x: {}, dist_correction_y: {}, two_pt_correction_available: true}}\n",
            l.rot, l.vert, l.vo, l.ho, l.dc, l.dcx, l.dcy
        ));
    }
    xml.push_str("</points_>\n</DB>\n</boost_serialization>\n");
    let xml_path = dir.path().join("db.xml");
    let yaml_path = dir.path().join("hdl64e-s3.yml");
    std::fs::write(&xml_path, &xml).unwrap();
    std::fs::write(&yaml_path, &yaml).unwrap();

    let pcap = synthesized_lidar_pcap(
        dir.path(),
        "hdl64e-s3",
        &format!("calibration = {xml_path:?}"),
        "strongest",
    );
    let from_xml = hilrig::velodyne::Calibration::from_file(&xml_path, model).unwrap();
    let options = LidarOptions {
        model: Some(model),
        calibration: Some(from_xml),
        ..LidarOptions::default()
    };
    let (_, ours) = decode_file(&pcap, &options);
    // The YAML form decodes to the very same points.
    let (_, ours_yaml) = decode_file(
        &pcap,
        &LidarOptions {
            calibration: Some(hilrig::velodyne::Calibration::from_file(&yaml_path, model).unwrap()),
            ..options.clone()
        },
    );
    assert_eq!(ours.len(), ours_yaml.len());
    assert!(ours.iter().zip(&ours_yaml).all(|(a, b)| a.1 == b.1));
    let reference = reference_points(&pcap, &["HDL64E_S3".as_ref(), yaml_path.as_os_str()]);
    assert_eq!(ours.len(), reference.len(), "point count");
    println!("HDL-64E S3 with a VeloView XML: {} points", ours.len());

    let (near_x, near_y, far) = (2.4, 1.93, 25.04);
    let (mut max_ours, mut max_ref, mut max_apart) = (0f64, 0f64, 0f64);
    let mut near_points = 0;
    for (i, ((_, p), r)) in ours.iter().zip(&reference).enumerate() {
        assert_eq!(p.ring, r.ring, "point {i}: ring");
        assert_eq!(p.intensity, r.intensity, "point {i}: intensity");
        let l = &lasers[usize::from(p.laser.0)];
        let d = f64::from(p.distance_raw) * 0.002 + l.dc;
        assert!(
            (f64::from(p.distance_m) - d).abs() < 1e-4,
            "point {i}: distance"
        );
        let a = f64::from(p.azimuth_deg).to_radians() - l.rot;
        let (sa, ca) = a.sin_cos();
        let (sw, cw) = l.vert.sin_cos();
        // The manual (ros-drivers' rawdata.cc, VeloView): Velodyne's frame, x sideways, y ahead.
        let xy = d * cw - l.vo * sw;
        let xx = (xy * sa - l.ho * ca).abs();
        let yy = (xy * ca + l.ho * sa).abs();
        let cx = (l.dc - l.dcx) * (xx - near_x) / (far - near_x) + l.dcx - l.dc;
        let cy = (l.dc - l.dcy) * (yy - near_y) / (far - near_y) + l.dcy - l.dc;
        let vx = ((d + cx) * cw - l.vo * sw) * sa - l.ho * ca;
        let vy = ((d + cy) * cw - l.vo * sw) * ca + l.ho * sa;
        let manual = [vy, -vx, (d + cy) * sw + l.vo * cw];
        // velodyne-decoder 3.1.0's variant.
        let measured = d - l.dc;
        let (kx, ky, kz) = if measured < far {
            let xy = d * cw;
            let fx = ((xy * sa).abs() - near_x) / (far - near_x);
            let fy = ((xy * ca).abs() - near_y) / (far - near_y);
            let kx = fx * l.dc + (1.0 - fx) * l.dcx;
            let ky = fy * l.dc + (1.0 - fy) * l.dcy;
            (kx, ky, (kx + ky) / 2.0)
        } else {
            (l.dc, l.dc, l.dc)
        };
        let wx = (measured + kx) * cw * sa - l.ho * ca;
        let wy = (measured + ky) * cw * ca + l.ho * sa;
        let theirs = [wy, -wx, (measured + kz) * sw + l.vo];
        let got = [f64::from(p.x), f64::from(p.y), f64::from(p.z)];
        let refp = [r.x, r.y, r.z];
        for k in 0..3 {
            max_ours = max_ours.max((got[k] - manual[k]).abs());
            max_apart = max_apart.max((got[k] - refp[k]).abs());
        }
        // velodyne-decoder rounds azimuths to 0.01° (module note 2): sideways up to d·0.005°.
        let e_ref = ((refp[0] - theirs[0]).powi(2) + (refp[1] - theirs[1]).powi(2)).sqrt();
        assert!(
            e_ref <= 0.001 + d * 0.0055f64.to_radians() && (refp[2] - theirs[2]).abs() < 0.001,
            "point {i} at {d} m: velodyne-decoder {refp:?}, its formulas {theirs:?}"
        );
        max_ref = max_ref.max(e_ref);
        near_points += usize::from(measured < far);
    }
    println!(
        "HDL-64E S3 with a VeloView XML: hilrig meets the manual's formulas to {:.3} mm; velodyne-decoder meets its variant to {:.2} mm in x/y (its azimuth rounding); the two decoders' points lie up to {:.1} mm apart; {near_points} points nearer than 25.04 m",
        max_ours * 1e3,
        max_ref * 1e3,
        max_apart * 1e3
    );
    assert!(max_ours < 0.001, "hilrig against the manual's formulas");
    assert!(
        near_points > 1000,
        "the near-point corrections are exercised"
    );
    assert!(
        max_apart > 0.01,
        "the calibration's corrections make a visible difference"
    );
}

//! `hilrig decode` options beyond the defaults: calibration files and output formats.

use crate::common;

use std::path::PathBuf;

fn fixture() -> PathBuf {
    common::fixture("vlp16_room.pcapng")
}

fn decode(args: &[&str]) -> (Option<i32>, String, String) {
    common::hilrig_decode(args)
}

fn parse(csv: &str) -> Vec<Vec<f64>> {
    csv.lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

#[test]
fn a_ros_drivers_calibration_file_is_applied() {
    let dir = tempfile::tempdir().unwrap();
    let fx = fixture();
    let fx = fx.to_str().unwrap();
    // The built-in table written as a calibration file decodes to the same points: its z
    // corrections become ros-drivers vertical offsets, which keep z and shift the horizontal
    // distance by dz tan(ω), at most 11.2 mm x tan(15°) = 3.0 mm on the VLP-16 (plus 0.1 mm of CSV rounding).
    let same = dir.path().join("vlp16.yaml");
    let builtin = hilrig::velodyne::Calibration::builtin(hilrig::velodyne::Model::Vlp16);
    std::fs::write(&same, builtin.to_yaml()).unwrap();
    let (code, reference, stderr) = decode(&[fx]);
    assert_eq!(code, Some(0), "{stderr}");
    let (code, with_file, stderr) = decode(&[
        fx,
        "--model",
        "vlp16",
        "--calibration",
        same.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let (a, b) = (parse(&reference), parse(&with_file));
    // One row per point: as many as the summary counts, and the same with the file.
    let (code, _, summary) = decode(&[fx, "--format", "summary"]);
    assert_eq!(code, Some(0), "{summary}");
    let points: usize = summary
        .lines()
        .find_map(|l| l.split("points: ").nth(1))
        .and_then(|n| n.trim().parse().ok())
        .expect("the summary counts points");
    assert!(points > 10_000, "{points} points");
    assert_eq!(a.len(), points);
    assert_eq!(b.len(), points);
    for (r, f) in a.iter().zip(&b) {
        assert_eq!(
            &r[..6],
            &f[..6],
            "time, ring, azimuth, distance, intensity, return type"
        );
        assert!(
            (r[6] - f[6]).abs() <= 0.0032 && (r[7] - f[7]).abs() <= 0.0032,
            "{r:?} vs {f:?}"
        );
        assert!((r[8] - f[8]).abs() <= 0.0001, "{r:?} vs {f:?}");
    }
    // A calibration that turns every laser by 1° moves every point by 1° of azimuth.
    let mut turned = builtin.clone();
    for l in &mut turned.lasers {
        l.rot_correction_rad -= 1f64.to_radians();
    }
    let path = dir.path().join("turned.yaml");
    std::fs::write(&path, turned.to_yaml()).unwrap();
    let (code, out, stderr) = decode(&[
        fx,
        "--model",
        "vlp16",
        "--calibration",
        path.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let turned_points = parse(&out);
    assert_eq!(turned_points.len(), a.len());
    for (r, f) in a.iter().zip(turned_points) {
        let (ar, af) = (r[7].atan2(r[6]), f[7].atan2(f[6]));
        let d = (af - ar).to_degrees().rem_euclid(360.0);
        if r[3] > 1.0 {
            assert!((d - 359.0).abs() < 0.01, "turned by {d}°");
        }
    }
    // Errors name the problem.
    let (code, _, stderr) = decode(&[fx, "--calibration", same.to_str().unwrap()]);
    assert_eq!(code, Some(2));
    assert!(stderr.contains("--calibration needs --model"), "{stderr}");
    let (code, _, stderr) = decode(&[
        fx,
        "--model",
        "hdl32e",
        "--calibration",
        same.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("16 lasers listed, but a hdl32e has 32"),
        "{stderr}"
    );
    let (code, _, stderr) = decode(&[fx, "--model", "velarray"]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("unknown Velodyne model 'velarray'"),
        "{stderr}"
    );
    // The HDL-64E is known, but needs the unit's calibration file.
    let (code, _, stderr) = decode(&[fx, "--model", "hdl64e-s3"]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("needs its unit's own calibration") && stderr.contains("--calibration"),
        "{stderr}"
    );
}

#[test]
fn jsonl_carries_the_same_points_as_csv() {
    let fx = fixture();
    let (_, csv, _) = decode(&[fx.to_str().unwrap()]);
    let (code, jsonl, _) = decode(&[fx.to_str().unwrap(), "--format", "jsonl"]);
    assert_eq!(code, Some(0));
    let rows = parse(&csv);
    let objs: Vec<serde_json::Value> = jsonl
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), objs.len());
    for (r, o) in rows.iter().zip(&objs) {
        assert_eq!(o["ring"].as_f64().unwrap(), r[1]);
        assert_eq!(o["distance_m"].as_f64().unwrap(), r[3]);
        assert_eq!(o["x"].as_f64().unwrap(), r[6]);
    }
}

#[test]
fn gnss_jsonl_has_the_documented_keys_and_values() {
    use hilrig::gnss::framer::nmea_sentence;
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("rx.log");
    let mut s = String::from("# a gpsd-style comment\n");
    s += &nmea_sentence(
        "GNGGA,120000.00,4807.0380000,N,01131.0000000,E,4,12,0.8,545.40,M,46.90,M,1.2,0042",
    );
    s += &nmea_sentence("GNRMC,120000.00,A,4807.0380000,N,01131.0000000,E,10.0,90.0,211126,,,R");
    s += &nmea_sentence("GNGST,120000.00,0.5,0.02,0.01,0.0,0.011,0.012,0.025");
    s += &nmea_sentence(
        "GNGGA,120000.10,4807.0390000,N,01131.0000000,E,5,12,0.8,545.41,M,46.90,M,1.3,0042",
    );
    std::fs::write(&log, s).unwrap();
    let (code, out, stderr) =
        decode(&[log.to_str().unwrap(), "--kind", "gnss", "--format", "jsonl"]);
    assert_eq!(code, Some(0), "{stderr}");
    let fixes: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(fixes.len(), 2);
    let f = &fixes[0];
    let mut keys: Vec<&str> = f.as_object().unwrap().keys().map(String::as_str).collect();
    keys.sort();
    assert_eq!(
        keys,
        [
            "alt_msl",
            "correction_age_s",
            "heading_deg",
            "lat",
            "lon",
            "quality",
            "rtk",
            "sigma_alt_m",
            "sigma_lat_m",
            "sigma_lon_m",
            "source",
            "speed_mps",
            "time"
        ]
    );
    assert_eq!(f["time"], "2026-11-21T12:00:00.000Z");
    assert!((f["lat"].as_f64().unwrap() - (48.0 + 7.038 / 60.0)).abs() < 1e-12);
    assert_eq!(f["quality"], 4);
    assert_eq!(f["rtk"], "fixed");
    assert_eq!(f["sigma_alt_m"], 0.025);
    assert_eq!(f["correction_age_s"], 1.2);
    assert!((f["speed_mps"].as_f64().unwrap() - 10.0 * 1852.0 / 3600.0).abs() < 1e-12);
    assert_eq!(f["heading_deg"], 90.0);
    // The second epoch has no RMC of its own: the date carries over; no GST: sigmas null.
    assert_eq!(fixes[1]["time"], "2026-11-21T12:00:00.100Z");
    assert_eq!(fixes[1]["rtk"], "float");
    assert!(fixes[1]["sigma_lat_m"].is_null());
}

#[test]
fn can_jsonl_decodes_with_the_dbc_and_shows_only_active_multiplexed_signals() {
    let dir = tempfile::tempdir().unwrap();
    let dbc = dir.path().join("ego.dbc");
    std::fs::write(
        &dbc,
        "VERSION \"\"\n\nBO_ 291 Ego: 8 X\n SG_ Speed : 0|16@1+ (0.01,0) [0|655.35] \"m/s\" X\n SG_ YawRate : 23|16@0- (0.001,0) [-32|32] \"rad/s\" X\n SG_ Page M : 32|8@1+ (1,0) [0|255] \"\" X\n SG_ Steer m1 : 40|16@1- (0.1,0) [-3276.8|3276.7] \"deg\" X\n SG_ Wheel m2 : 40|16@1+ (0.01,0) [0|655.35] \"m/s\" X\n",
    )
    .unwrap();
    let log = dir.path().join("can.log");
    // Speed 12.34 m/s (1234 = 0x04D2, Intel), yaw rate -0.5 rad/s (-500 = 0xFE0C, Motorola from bit
    // 23: bytes 2-3), page 1: steering -12.3 deg (-123 = 0xFF85, Intel).
    std::fs::write(
        &log,
        "(1700000000.000100) can0 123#D204FE0C0185FF00\n(1700000000.000200) can0 456#00\n",
    )
    .unwrap();
    let (code, out, stderr) = decode(&[
        log.to_str().unwrap(),
        "--kind",
        "can",
        "--dbc",
        dbc.to_str().unwrap(),
        "--format",
        "jsonl",
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("frames: 2, decoded: 1, ids not in the DBC: 1"),
        "{stderr}"
    );
    let v: serde_json::Value = serde_json::from_str(out.lines().next().unwrap()).unwrap();
    assert_eq!(v["id"], 0x123);
    assert_eq!(v["name"], "Ego");
    assert!((v["time"].as_f64().unwrap() - 1_700_000_000.000_1).abs() < 1e-6);
    let s = v["signals"].as_object().unwrap();
    assert_eq!(s.len(), 4, "{s:?}");
    assert!((s["Speed"].as_f64().unwrap() - 12.34).abs() < 1e-9);
    assert!((s["YawRate"].as_f64().unwrap() + 0.5).abs() < 1e-9);
    assert!((s["Steer"].as_f64().unwrap() + 12.3).abs() < 1e-9);
    assert!(!s.contains_key("Wheel"));
    let (code, _, stderr) = decode(&[log.to_str().unwrap(), "--kind", "can", "--format", "jsonl"]);
    assert_eq!(code, Some(2));
    assert!(stderr.contains("--kind can needs --dbc"), "{stderr}");
}

#[test]
fn can_frames_on_a_socketcan_interface_of_a_pcapng_decode_too() {
    use hilrig::capture::{LinkType, PcapngWriter, UtcNanos};
    let dir = tempfile::tempdir().unwrap();
    let dbc = dir.path().join("ego.dbc");
    std::fs::write(&dbc, "VERSION \"\"\n\nBO_ 2566844672 Ext: 8 X\n SG_ Speed : 0|16@1+ (0.01,0) [0|655.35] \"m/s\" X\n").unwrap();
    let mut w = PcapngWriter::new(Vec::new(), "test").unwrap();
    let can = w.add_interface(LinkType::CAN_SOCKETCAN, "can0").unwrap();
    let frame =
        hilrig::can::CanFrame::new(0x18FE_F100, true, &[0xD2, 0x04, 0, 0, 0, 0, 0, 0]).unwrap();
    w.write_packet(
        can,
        UtcNanos(1_700_000_000_500_000_000),
        &frame.encode_socketcan(),
    )
    .unwrap();
    let cap = dir.path().join("drive.pcapng");
    std::fs::write(&cap, w.finish().unwrap()).unwrap();
    let (code, out, stderr) = decode(&[
        cap.to_str().unwrap(),
        "--kind",
        "can",
        "--dbc",
        dbc.to_str().unwrap(),
        "--format",
        "jsonl",
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(v["name"], "Ext");
    assert_eq!(v["id"], 0x18FE_F100);
    assert_eq!(v["time"], 1_700_000_000.5);
    assert!((v["signals"]["Speed"].as_f64().unwrap() - 12.34).abs() < 1e-9);
}

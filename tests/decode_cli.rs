//! `hilrig decode` options beyond the defaults: calibration files and output formats.

mod common;

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
    let (_, reference, _) = decode(&[fx]);
    let (code, with_file, stderr) = decode(&[
        fx,
        "--model",
        "vlp16",
        "--calibration",
        same.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let (a, b) = (parse(&reference), parse(&with_file));
    assert_eq!(a.len(), b.len());
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
    let (_, out, _) = decode(&[
        fx,
        "--model",
        "vlp16",
        "--calibration",
        path.to_str().unwrap(),
    ]);
    for (r, f) in a.iter().zip(parse(&out)) {
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
    let (code, _, stderr) = decode(&[fx, "--model", "hdl64"]);
    assert_eq!(code, Some(2));
    assert!(
        stderr.contains("unknown Velodyne model 'hdl64'"),
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

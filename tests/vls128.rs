//! A 128-beam sensor through every step after `synth` (issue 28): a short VLS-128 drive through
//! the parking scene, single and dual return, is recorded with every packet, passes `check`,
//! re-simulates packet for packet, and compares with the OCR its own model must reach.

use crate::common;

use common::*;
use hilrig::bag::scans::ScanStream;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The demo rig with a VLS-128 in place of the VLP-16 (its DBC by absolute path).
fn vls128_rig(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(demo_rig())
        .unwrap()
        .replace("model = \"vlp16\"", "model = \"vls128\"")
        .replace(
            "dbc = \"hilrig-ego.dbc\"",
            &format!(
                "dbc = {:?}",
                demo_rig()
                    .parent()
                    .unwrap()
                    .join("hilrig-ego.dbc")
                    .display()
                    .to_string()
            ),
        );
    assert!(text.contains("model = \"vls128\""));
    let rig = dir.join("rig-vls128.toml");
    std::fs::write(&rig, text).unwrap();
    rig
}

/// The parking drive cut to its first ten metres (about six seconds), driven with `rig`'s
/// sensor in `return_mode`, synthesized with the idealized model and realistic reference
/// errors, and recorded.
fn short_drive(dir: &Path, rig: &Path, return_mode: &str) -> (PathBuf, PathBuf) {
    let runs = short_drives(dir, rig, return_mode, &fixture("parking/idealized.toml"), 1);
    runs.into_iter().next().unwrap()
}

/// [`short_drive`] synthesized `reps` times with the model `truth`: each repetition's folder
/// and its recording.
fn short_drives(
    dir: &Path,
    rig: &Path,
    return_mode: &str,
    truth: &Path,
    reps: usize,
) -> Vec<(PathBuf, PathBuf)> {
    let text = std::fs::read_to_string(fixture("parking/drive.toml"))
        .unwrap()
        .replace(
            "rig = \"../../rigs/demo.toml\"",
            &format!("rig = {:?}", rig.display().to_string()),
        )
        .replace(
            "waypoints = [[-16.0, 0.0], [-6.0, 0.0], [-1.0, 0.4], [1.6, 1.8], [2.5, 3.6], [2.55, 4.8]]",
            "waypoints = [[-16.0, 0.0], [-11.0, 0.0], [-6.0, 0.0]]",
        )
        .replace("return_mode = \"strongest\"", &format!("return_mode = {return_mode:?}"));
    assert!(text.contains("[-11.0, 0.0]") && text.contains(return_mode));
    // Without the walker's stop, which lies beyond the cut.
    let text = match text.find("[yield_to]") {
        Some(i) => {
            let end = text[i..].find("\n\n").map_or(text.len(), |e| i + e);
            format!("{}{}", &text[..i], &text[end..])
        }
        None => text,
    };
    let drive = dir.join("drive.toml");
    std::fs::write(&drive, text).unwrap();
    let out = Command::new(hilrig_bin())
        .args(["synth", "--scene"])
        .arg(fixture("parking/scene.toml"))
        .arg("--drive")
        .arg(&drive)
        .arg("--truth")
        .arg(truth)
        .args(["--reps", &reps.to_string(), "--seed", "128", "-o"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (1..=reps)
        .map(|k| {
            let rep = dir.join(format!("out/rep-{k:02}"));
            let run = dir.join(format!("run-{k}.mcap"));
            let rec = record_from(rig, &[&rep.join("drive.pcapng")], &run);
            assert!(
                rec.status.success(),
                "record: {}",
                String::from_utf8_lossy(&rec.stderr)
            );
            (rep, run)
        })
        .collect()
}

/// Data packets in `/velodyne_packets`, and the scans.
fn recorded(path: &Path) -> (usize, usize) {
    let mut stream = ScanStream::open(path).unwrap();
    let (mut scans, mut packets) = (0, 0);
    for s in stream.by_ref() {
        scans += 1;
        packets += s.packets.len();
    }
    assert_eq!(stream.finish(), None);
    (scans, packets)
}

fn end_to_end(return_mode: &str) {
    let dir = tempfile::tempdir().unwrap();
    let rig = vls128_rig(dir.path());
    let (rep, run) = short_drive(dir.path(), &rig, return_mode);
    // Every data packet of the capture is in the recording.
    let captured = lidar_data(&rep.join("drive.pcapng")).len();
    let (scans, packets) = recorded(&run);
    assert!(captured > 10_000, "{captured} packets captured");
    assert_eq!(packets, captured, "{return_mode}: packets recorded");
    assert!(scans >= 50, "{scans} scans");

    // The reference passes.
    let scene = rep.join("scene.toml");
    let check_json = dir.path().join("check.json");
    let out = Command::new(hilrig_bin())
        .arg("check")
        .arg(&run)
        .arg("--scene")
        .arg(&scene)
        .arg("--json")
        .arg(&check_json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "check: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let check: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&check_json).unwrap()).unwrap();
    assert_eq!(check["verdict"], "pass", "{check}");

    // Every packet re-simulated, scan for scan.
    let sim = dir.path().join("sim.mcap");
    hilrig_ok(&[
        "resim".as_ref(),
        run.as_os_str(),
        "--scene".as_ref(),
        scene.as_os_str(),
        "--model".as_ref(),
        fixture("parking/idealized.toml").as_os_str(),
        "-o".as_ref(),
        sim.as_os_str(),
    ]);
    assert_eq!(recorded(&sim), (scans, packets), "{return_mode}: resim");

    // The model that made the data, re-simulated on the checked trajectory: its points cover
    // the measured cells at the admissible cell size (the trajectory's error is a tenth of
    // it), and every scan pairs.
    let compare_json = dir.path().join("compare.json");
    hilrig_ok(&[
        "compare".as_ref(),
        run.as_os_str(),
        sim.as_os_str(),
        "--scene".as_ref(),
        scene.as_os_str(),
        "--json".as_ref(),
        compare_json.as_os_str(),
    ]);
    let c: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&compare_json).unwrap()).unwrap();
    let s = &c["summary"];
    assert_eq!(s["unpaired_run_scans"], 0, "{s}");
    assert_eq!(s["scans"].as_u64().unwrap() as usize, scans, "{s}");
    let ocr = s["ocr_mean"].as_f64().unwrap();
    assert!(ocr > 0.85, "{return_mode}: OCR {ocr}");
    // The same firings return in both, at the same range on average (the rms is the tail of
    // grazing rays, where a centimetre of pose moves the hit by metres).
    let bias = s["range_diff_mean_m"].as_f64().unwrap();
    assert!(bias.abs() < 0.1, "{return_mode}: range bias {bias}: {s}");
    for share in ["only_real_share", "only_sim_share"] {
        let v = s[share].as_f64().unwrap();
        assert!(v < 0.05, "{return_mode}: {share} {v}: {s}");
    }
}

#[test]
fn a_short_vls128_drive_records_checks_resimulates_and_compares() {
    end_to_end("strongest");
}

#[test]
fn a_short_dual_return_vls128_drive_records_checks_resimulates_and_compares() {
    end_to_end("dual");
}

/// The gap workflow on a dual-return VLS-128, whose packets hold one firing sequence each: a
/// hidden range noise is found and fitted. Its fit compares each firing with the same laser's
/// firing before it; within such a packet a laser fires once, so the sample takes packets in
/// pairs (the fit was 0 and no noise, not even 0.4 m, could have been seen).
#[test]
fn a_dual_return_vls128s_hidden_range_noise_is_found_by_the_gap_workflow() {
    let dir = tempfile::tempdir().unwrap();
    let rig = vls128_rig(dir.path());
    let truth = dir.path().join("truth.toml");
    let sigma = 0.02;
    std::fs::write(
        &truth,
        format!("name = \"noisy\"\n[[effect]]\nname = \"range_noise\"\nsigma_m = {sigma}\n"),
    )
    .unwrap();
    let runs = short_drives(dir.path(), &rig, "dual", &truth, 3);
    let runs: Vec<(PathBuf, PathBuf)> = runs
        .into_iter()
        .map(|(rep, run)| (run, rep.join("scene.toml")))
        .collect();
    let study_path = common::gap::study(dir.path(), &fixture("parking/idealized.toml"), &runs);
    let out = common::gap::gap(
        &[
            study_path.as_os_str(),
            "--max-rounds".as_ref(),
            "1".as_ref(),
            "--no-full-metrics".as_ref(),
        ],
        &dir.path().join("gap"),
    );
    assert_eq!(out.code, Some(0), "{}\n{}", out.stdout, out.stderr);
    let f = common::gap::found(out.report.as_ref().unwrap());
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some("range_noise"),
        "{}",
        out.stdout
    );
    let fitted = common::gap::param(&f[0].1, "sigma_m");
    assert!(
        (fitted - sigma).abs() <= 0.2 * sigma,
        "range noise {fitted} m for {sigma} m: {}",
        out.stdout
    );
}

//! The method's commands on runs that lack what they need (issue 29): a run without lidar
//! scans, a run without the RTK and CAN streams its trajectory is built from, a run whose
//! lidar measured nothing (a covered sensor), a region no measured point lies in, and a
//! re-simulation cut in the middle. Each is refused with exit 2 and a message that names the
//! file and what is missing, and writes no output; or, where the input is still usable, the
//! result says how little there was. Never a number that looks like a measurement.

use crate::common;

use common::{demo_rig, fixture, hilrig_bin, record_and_resim, record_from};
use std::path::{Path, PathBuf};

/// Copies the MCAP `src` to `dst` without the channels whose topic starts with one of `drop`
/// (attachments and metadata kept): the run as a recorder would have written it with those
/// sensors unplugged.
fn without_topics(src: &Path, dst: &Path, drop: &[&str]) {
    let bytes = std::fs::read(src).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a summary");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(std::io::BufWriter::new(std::fs::File::create(dst).unwrap()))
        .unwrap();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        if !drop.iter().any(|t| m.channel.topic.starts_with(t)) {
            w.write(&m).unwrap();
        }
    }
    for i in &summary.attachment_indexes {
        w.attach(&mcap::read::attachment(&bytes, i).unwrap())
            .unwrap();
    }
    for i in &summary.metadata_indexes {
        w.write_metadata(&mcap::read::metadata(&bytes, i).unwrap())
            .unwrap();
    }
    w.finish().unwrap();
}

/// Runs `hilrig ARGS`: exit code and stdout + stderr.
fn hilrig(args: &[&str]) -> (Option<i32>, String) {
    let o = std::process::Command::new(hilrig_bin())
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
    )
}

fn p(x: &Path) -> String {
    x.to_str().unwrap().to_owned()
}

/// The commands that read a measured run, each with `run` in that place, writing into `out`,
/// with the exit status each must give. `resim` and `gap` first run `check` on the run: one
/// that fails it is refused (`resim` exit 1, as for every failed check; `gap` exit 2, a study
/// input it cannot use); with `--force` the missing part itself is named (exit 2).
fn method_commands(run: &Path, sim: &Path, scene: &Path, out: &Path) -> Vec<(Vec<String>, i32)> {
    let model = fixture("parking/idealized.toml");
    let resim = |force: bool| {
        let mut a: Vec<String> = vec![
            "resim".into(),
            p(run),
            "--scene".into(),
            p(scene),
            "--model".into(),
            p(&model),
            "-o".into(),
            p(out),
        ];
        if force {
            a.push("--force".into());
        }
        (a, if force { 2 } else { 1 })
    };
    let gap = |force: bool| {
        let mut a: Vec<String> = vec![
            "gap".into(),
            "--real".into(),
            p(run),
            "--scene".into(),
            p(scene),
            "--model".into(),
            p(&model),
            "--no-full-metrics".into(),
            "-o".into(),
            p(out),
        ];
        if force {
            a.push("--force".into());
        }
        (a, 2)
    };
    vec![
        resim(false),
        resim(true),
        (
            vec![
                "compare".into(),
                p(run),
                p(sim),
                "--scene".into(),
                p(scene),
                "--json".into(),
                p(out),
            ],
            2,
        ),
        gap(false),
        gap(true),
    ]
}

/// Every command in `cases` exits with its status, says each of `says` (one of the
/// alternatives of each inner list) and writes nothing at `out`.
fn refused(cases: Vec<(Vec<String>, i32)>, out: &Path, says: &[&[&str]]) {
    for (args, status) in cases {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let (code, text) = hilrig(&a);
        assert_eq!(code, Some(status), "{args:?}: {text}");
        for alternatives in says {
            assert!(
                alternatives.iter().any(|s| text.contains(s)),
                "{args:?} does not say any of {alternatives:?}: {text}"
            );
        }
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
}

#[test]
fn a_run_without_lidar_scans_is_refused_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (run, sims) = record_and_resim(d, 1, &["idealized"]);
    let scene = fixture("parking/rep-01/scene.toml");
    let blind = d.join("no-lidar.mcap");
    without_topics(&run, &blind, &["/points", "/velodyne"]);
    let out = d.join("out");
    let mut cases = method_commands(&blind, &sims[0], &scene, &out);
    cases.push((
        vec![
            "validate".into(),
            "--real".into(),
            p(&blind),
            "--sim".into(),
            p(&sims[0]),
            "--json".into(),
            p(&out),
        ],
        2,
    ));
    refused(
        cases,
        &out,
        &[
            &["no-lidar.mcap"],
            &["no lidar scans", "no_lidar_data", "no /velodyne_packets"],
        ],
    );
}

#[test]
fn a_run_without_rtk_and_can_names_the_missing_trajectory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (run, sims) = record_and_resim(d, 1, &["idealized"]);
    let scene = fixture("parking/rep-01/scene.toml");
    let out = d.join("out");
    for (name, drop) in [
        ("no-gnss.mcap", &["/gnss"][..]),
        ("no-can.mcap", &["/can", "/ego"][..]),
        ("no-trajectory.mcap", &["/gnss", "/can", "/ego"][..]),
    ] {
        let cut = d.join(name);
        without_topics(&run, &cut, drop);
        refused(
            method_commands(&cut, &sims[0], &scene, &out),
            &out,
            &[
                &[name],
                &["no RTK+CAN trajectory", "no_gnss_fixes", "no_ego_motion"],
            ],
        );
    }
}

/// A drive synthesized with a model that returns nothing (a sensor under a cover, or a
/// threshold no target in the scene reaches), recorded as the rig records it.
fn covered_sensor_run(d: &Path) -> (PathBuf, PathBuf) {
    let text = std::fs::read_to_string(fixture("parking/drive.toml"))
        .unwrap()
        .replace(
            "rig = \"../../rigs/demo.toml\"",
            &format!("rig = {:?}", demo_rig().display().to_string()),
        );
    std::fs::write(d.join("drive.toml"), text).unwrap();
    std::fs::write(
        d.join("covered.toml"),
        "name = \"covered\"\n[[effect]]\nname = \"detection_threshold\"\nreference_range_m = 0.2\nreference_reflectivity = 0.1\n",
    )
    .unwrap();
    let synth = std::process::Command::new(hilrig_bin())
        .args(["synth", "--scene"])
        .arg(fixture("parking/scene.toml"))
        .arg("--drive")
        .arg(d.join("drive.toml"))
        .arg("--truth")
        .arg(d.join("covered.toml"))
        .args(["--reps", "1", "--seed", "41", "-o"])
        .arg(d.join("synth"))
        .output()
        .unwrap();
    assert!(
        synth.status.success(),
        "{}",
        String::from_utf8_lossy(&synth.stderr)
    );
    let rep = d.join("synth/rep-01");
    let run = d.join("covered.mcap");
    let rec = record_from(&demo_rig(), &[&rep.join("drive.pcapng")], &run);
    assert!(
        rec.status.success(),
        "{}",
        String::from_utf8_lossy(&rec.stderr)
    );
    (run, rep.join("scene.toml"))
}

#[test]
fn a_run_whose_lidar_measured_nothing_gives_no_number_that_looks_measured() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (run, scene) = covered_sensor_run(d);
    let sim = d.join("sim.mcap");
    common::resim(&run, &scene, &fixture("parking/idealized.toml"), &sim);
    let out = d.join("out");
    // resim of such a run is legitimate: the model's answer does not need the measurement.
    let cases = method_commands(&run, &sim, &scene, &out)
        .into_iter()
        .filter(|(a, _)| a[0] != "resim")
        .collect();
    refused(cases, &out, &[&["covered.mcap"], &["no measured point"]]);
}

#[test]
fn a_region_without_measured_points_is_refused_naming_the_region() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (run, sims) = record_and_resim(d, 1, &["idealized"]);
    // The surveyed scene with a shed far out of range: in the scene, never in view.
    let src = fixture("parking/rep-01");
    for f in std::fs::read_dir(&src).unwrap() {
        let f = f.unwrap().path();
        if f.extension().is_some_and(|e| e == "csv") {
            std::fs::copy(&f, d.join(f.file_name().unwrap())).unwrap();
        }
    }
    let scene = d.join("scene.toml");
    std::fs::write(
        &scene,
        std::fs::read_to_string(src.join("scene.toml")).unwrap()
            + "\n[[object]]\nname = \"far shed\"\nreflectivity = 0.5\naccuracy_m = 0.1\n\
               [object.pose]\nx = 400.0\ny = 400.0\nz = 0.0\nyaw_deg = 0.0\npitch_deg = 0.0\nroll_deg = 0.0\n\
               [[object.parts]]\nshape = \"box\"\nsize = [2.0, 2.0, 2.0]\n\
               [object.parts.at]\nx = 0.0\ny = 0.0\nz = 1.0\nyaw_deg = 0.0\npitch_deg = 0.0\nroll_deg = 0.0\n",
    )
    .unwrap();
    let out = d.join("out.json");
    refused(
        vec![(
            vec![
                "compare".into(),
                p(&run),
                p(&sims[0]),
                "--scene".into(),
                p(&scene),
                "--roi".into(),
                "object:far shed".into(),
                "--json".into(),
                p(&out),
            ],
            2,
        )],
        &out,
        &[
            &["run1.mcap"],
            &["no measured point"],
            &["region object:far shed "],
        ],
    );
}

/// validate on a re-simulation cut in the middle: its scans up to the damage are taken, and
/// the damage is said on the terminal.
#[test]
fn validate_reads_a_damaged_simulation_up_to_the_damage_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, sims1) = record_and_resim(d, 1, &["idealized"]);
    let (_, sims2) = record_and_resim(d, 2, &["idealized"]);
    let bytes = std::fs::read(&sims2[0]).unwrap();
    let cut = d.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let (run1, run2) = (d.join("run1.mcap"), d.join("run2.mcap"));
    let json = d.join("v.json");
    let (code, text) = hilrig(&[
        "validate",
        "--real",
        &p(&run1),
        "--real",
        &p(&run2),
        "--sim",
        &p(&sims1[0]),
        "--sim",
        &p(&cut),
        "--json",
        &p(&json),
    ]);
    assert!(matches!(code, Some(0 | 1)), "{text}");
    assert!(
        text.contains("warning:") && text.contains("cut.mcap: read up to damage"),
        "{text}"
    );
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert!(
        v.to_string().contains("cut.mcap"),
        "the damaged file is named in the JSON: {v}"
    );
}

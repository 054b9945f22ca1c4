//! NaN and infinity in every TOML file hilrig reads (rig thresholds and mountings, a model's
//! `[limits]` and effect parameters, a scene, a drive, a study's model): TOML accepts `nan` and `inf`,
//! and a NaN threshold compares false with everything (a check that fails "when above the
//! limit" would pass every run). Each is refused with exit 2, a message naming the key, and
//! nothing written.

use crate::common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

/// A copy of `src` in `dir` with the first line starting with `key = ` set to `value`.
fn edited(src: &Path, dir: &Path, name: &str, key: &str, value: &str) -> PathBuf {
    let text = std::fs::read_to_string(src).unwrap();
    let mut done = false;
    let out: Vec<String> = text
        .lines()
        .map(|l| {
            if !done && l.trim_start().starts_with(&format!("{key} = ")) {
                done = true;
                format!("{key} = {value}")
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(done, "{} has no {key}", src.display());
    let path = dir.join(name);
    std::fs::write(&path, out.join("\n") + "\n").unwrap();
    path
}

/// Runs hilrig and asserts exit 2, the message, and that `output` was not written.
fn refused(args: &[std::ffi::OsString], says: &str, output: &Path) {
    let out = Command::new(hilrig_bin()).args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(err.contains(says), "{args:?}: expected '{says}' in: {err}");
    assert!(!output.exists(), "{args:?} wrote {}", output.display());
}

#[test]
fn nan_and_infinity_are_refused_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (run, _) = record_and_resim(d, 1, &[]);
    let scene = fixture("parking/rep-01/scene.toml");
    std::fs::copy(
        fixture("parking/rep-01/pedestrian.csv"),
        d.join("pedestrian.csv"),
    )
    .unwrap();
    let out = d.join("out.json");
    let sim = d.join("sim.mcap");
    let os = |s: &str| std::ffi::OsString::from(s);

    // The rig's thresholds and mounting, given to check.
    let rig = std::fs::read_to_string(demo_rig()).unwrap().replace(
        "dbc = \"",
        &format!("dbc = \"{}/", demo_rig().parent().unwrap().display()),
    );
    let rig_path = d.join("rig.toml");
    std::fs::write(&rig_path, rig).unwrap();
    for (key, value, says) in [
        ("max_jump_sigma", "nan", "thresholds.max_jump_sigma = NaN"),
        (
            "max_sigma_horizontal_m",
            "inf",
            "thresholds.max_sigma_horizontal_m = inf",
        ),
        (
            "min_rtk_fixed_share",
            "-nan",
            "thresholds.min_rtk_fixed_share = NaN",
        ),
    ] {
        let bad = edited(&rig_path, d, "bad-rig.toml", key, value);
        refused(
            &[
                os("check"),
                run.clone().into(),
                os("--rig"),
                bad.into(),
                os("--json"),
                out.clone().into(),
            ],
            says,
            &out,
        );
    }

    // A model's limits and effect parameters, given to resim.
    for (body, says) in [
        ("[limits]\nmax_range_m = nan\n", "limits.max_range_m = NaN"),
        ("[limits]\nmin_range_m = -inf\n", "limits.min_range_m = -inf"),
        (
            "[[effect]]\nname = \"detection_threshold\"\nreference_range_m = inf\nreference_reflectivity = 0.1\n",
            "effect[1].reference_range_m = inf",
        ),
        (
            "[[effect]]\nname = \"detection_threshold\"\nreference_range_m = 80.0\nreference_reflectivity = 0.1\n[[effect]]\nname = \"weather\"\nextinction_per_m = 0.01\nclutter_max_range_m = nan\n",
            "effect[2].clutter_max_range_m = NaN",
        ),
    ] {
        let model = d.join("model.toml");
        std::fs::write(&model, format!("name = \"bad\"\n{body}")).unwrap();
        refused(
            &[
                os("resim"),
                run.clone().into(),
                os("--scene"),
                scene.clone().into(),
                os("--model"),
                model.into(),
                os("-o"),
                sim.clone().into(),
            ],
            says,
            &sim,
        );
    }

    // The scene, given to compare (an object's position) and to resim (the ground).
    for (key, value, says) in [
        ("x", "nan", "object[1].pose.x = NaN"),
        ("half_size_m", "inf", "ground.half_size_m = inf"),
    ] {
        let bad = edited(&scene, d, "scene.toml", key, value);
        refused(
            &[
                os("resim"),
                run.clone().into(),
                os("--scene"),
                bad.into(),
                os("--model"),
                fixture("parking/idealized.toml").into(),
                os("-o"),
                sim.clone().into(),
            ],
            says,
            &sim,
        );
    }

    // A drive, given to synth.
    let drive = std::fs::read_to_string(fixture("parking/drive.toml"))
        .unwrap()
        .replace(
            "rig = \"../../rigs/demo.toml\"",
            &format!("rig = \"{}\"", demo_rig().display()),
        );
    let drive_path = d.join("drive-src.toml");
    std::fs::write(&drive_path, drive).unwrap();
    let bad = edited(&drive_path, d, "drive.toml", "cruise_speed_mps", "nan");
    let synth_out = d.join("synth");
    refused(
        &[
            os("synth"),
            os("--scene"),
            fixture("parking/scene.toml").into(),
            os("--drive"),
            bad.into(),
            os("--truth"),
            fixture("parking/idealized.toml").into(),
            os("-o"),
            synth_out.clone().into(),
        ],
        "path.cruise_speed_mps = NaN",
        &synth_out,
    );

    // The phases of a validation.
    let phases = d.join("phases.toml");
    std::fs::write(
        &phases,
        "[[phase]]\nname = \"all\"\nfrom_s = 0.0\nto_s = inf\n",
    )
    .unwrap();
    refused(
        &[
            os("validate"),
            os("--real"),
            run.clone().into(),
            os("--sim"),
            run.clone().into(),
            os("--phases"),
            phases.into(),
            os("--json"),
            out.clone().into(),
        ],
        "phase[1].to_s = inf",
        &out,
    );

    // A study's start model, given to gap.
    let model = d.join("start.toml");
    std::fs::write(
        &model,
        "name = \"start\"\n[[effect]]\nname = \"range_noise\"\nsigma_m = nan\n",
    )
    .unwrap();
    let study = d.join("study.toml");
    std::fs::write(
        &study,
        format!(
            "model = \"{}\"\n[[run]]\nrecording = \"{}\"\nscene = \"{}\"\nrole = \"fit\"\n",
            model.display(),
            run.display(),
            scene.display()
        ),
    )
    .unwrap();
    let gap_out = d.join("gap");
    refused(
        &[os("gap"), study.into(), os("-o"), gap_out.clone().into()],
        "effect[1].sigma_m = NaN",
        &gap_out,
    );
}

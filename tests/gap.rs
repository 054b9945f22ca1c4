//! `hilrig gap` on drives with a hidden effect (issue 15): three drives of fixtures/gap/drive.toml
//! synthesized with the idealized model plus the effect (and the drive's reference errors: RTK
//! noise, GNSS latency and jitter, lidar clock jitter, CAN noise, survey error), two to fit and
//! one to validate; the workflow starts from the idealized model and is not told what was
//! hidden. The full table of the catalogue (every effect, random parameters, the null and
//! two-effect cases, the look-alikes) is `benches/gap_hidden.py`; here a selection that runs in
//! the test suite, with other speeds and seeds than the fixture's, and the bad inputs.

use crate::common;

use common::fixture;
use common::gap::{
    drive_at, found, gap, gap_with_limits, hidden, param, run_hidden, seed_of, validation_improved,
    FRAME_BASED, IDEALIZED,
};
use std::path::{Path, PathBuf};

#[test]
fn a_hidden_range_bias_is_named_first_and_fitted_within_20_percent() {
    let truth = 0.047;
    let (_d, out) = run_hidden(
        &format!("name = \"t\"\n[[effect]]\nname = \"range_bias\"\nbias_m = {truth}\n"),
        IDEALIZED,
        7,
        // A slower drive than the fixture's.
        &|t| {
            t.replace("cruise_speed_mps = 6.0", "cruise_speed_mps = 4.0")
                .replace("start_speed_mps = 6.0", "start_speed_mps = 4.0")
        },
    );
    let report = out.report.unwrap();
    let f = found(&report);
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some("range_bias"),
        "{}",
        out.stdout
    );
    let b = param(&f[0].1, "bias_m");
    assert!((b - truth).abs() < 0.2 * truth, "fitted {b}");
    assert!(
        out.stdout.contains("found: range_bias bias_m = 0.04"),
        "{}",
        out.stdout
    );
    validation_improved(&report, &["avm:mean_range_m"]);
    // The fitted model loads as a model file.
    let fitted = _d.path().join("out/model.fitted.toml");
    let m = hilrig::sim::ModelFile::load(&fitted).unwrap();
    assert!(m.effects.iter().any(|e| e.name() == "range_bias"));
}

/// A late lidar clock turns each scan by the yaw the car makes in the offset, as a mount yaw
/// would, but only while turning. (The idealized start model already fires each laser at its
/// own pose, so motion distortion cannot be added here: the frame-based tests below are the
/// ones where a time offset and motion distortion compete.)
#[test]
fn a_hidden_time_offset_is_not_taken_for_mount_yaw() {
    let truth = -23.0;
    let (_d, out) = run_hidden(
        &format!("name = \"t\"\n[[effect]]\nname = \"time_offset\"\noffset_ms = {truth}\n"),
        IDEALIZED,
        31,
        &|t| t,
    );
    let report = out.report.unwrap();
    let f = found(&report);
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some("time_offset"),
        "{}",
        out.stdout
    );
    let t = param(&f[0].1, "offset_ms");
    assert!((t - truth).abs() < 0.2 * truth.abs(), "fitted {t}");
    assert!(
        !f.iter().any(|x| x.0 == "mount_misalignment"),
        "{}",
        out.stdout
    );
    validation_improved(&report, &["ocr"]);
}

#[test]
fn a_frame_based_start_model_finds_motion_distortion_not_a_time_offset() {
    let (_d, out) = run_hidden(IDEALIZED, FRAME_BASED, 5, &|t| t);
    let report = out.report.unwrap();
    let f = found(&report);
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some("motion_distortion"),
        "{}",
        out.stdout
    );
    assert!(!f.iter().any(|x| x.0 == "time_offset"), "{}", out.stdout);
    validation_improved(&report, &["ocr"]);
}

/// The same at 3 m/s from standstill (`benches/gap_hidden.py --speed 3 --standing --seed 2`):
/// there a time offset explains the parameterization runs as well as motion distortion does
/// (both shift a scan along the motion; gains 44 252 and 44 076 nats, each inside the other's
/// bootstrap interval), and the workflow once added the time offset because it ranked first.
/// The validation runs now decide between such candidates, and the summary says they were
/// confounded.
#[test]
fn at_walking_pace_motion_distortion_wins_on_the_validation_runs_and_the_confound_is_named() {
    let (_d, out) = run_hidden(IDEALIZED, FRAME_BASED, 2862, &|t| {
        t.replace("cruise_speed_mps = 6.0", "cruise_speed_mps = 3.0")
            .replace("start_speed_mps = 6.0\n", "")
    });
    let report = out.report.unwrap();
    let f = found(&report);
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some("motion_distortion"),
        "{}",
        out.stdout
    );
    assert!(!f.iter().any(|x| x.0 == "time_offset"), "{}", out.stdout);
    let trials: Vec<&str> = report["rounds"][0]["trials"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|t| t["effect"].as_str())
        .collect();
    assert!(
        trials.contains(&"time_offset") && trials.contains(&"motion_distortion"),
        "both tried on the validation runs: {trials:?}"
    );
    assert!(
        report["summary"]
            .as_array()
            .unwrap()
            .iter()
            .any(|l| l.as_str().is_some_and(
                |l| l.starts_with("confounded: motion_distortion") && l.contains("time_offset")
            )),
        "{}",
        out.stdout
    );
    validation_improved(&report, &["ocr"]);
}

#[test]
fn a_hidden_detection_threshold_is_not_taken_for_dropout() {
    // Range at 10 % reflectivity 25 m (reference reflectivity 0.3: 43.3 m).
    let (_d, out) = run_hidden(
        "name = \"t\"\n[[effect]]\nname = \"detection_threshold\"\nreference_range_m = 43.3\nreference_reflectivity = 0.3\n",
        IDEALIZED,
        19,
        &|t| t,
    );
    let report = out.report.unwrap();
    let f = found(&report);
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some("detection_threshold"),
        "{}",
        out.stdout
    );
    // The fit is expressed at 10 % reflectivity: 43.3 m · sqrt(0.1 / 0.3) = 25.0 m.
    let r = param(&f[0].1, "reference_range_m");
    assert!((r - 25.0).abs() < 0.2 * 25.0, "fitted {r}");
    assert!(!f.iter().any(|x| x.0 == "random_dropout"), "{}", out.stdout);
}

#[test]
fn hidden_rain_is_fitted_with_its_clutter_and_the_threshold_refitted() {
    let threshold =
        "[[effect]]\nname = \"detection_threshold\"\nreference_range_m = 35.0\nreference_reflectivity = 0.1\n";
    let (_d, out) = run_hidden(
        &format!("name = \"rain\"\n{threshold}[[effect]]\nname = \"weather\"\nextinction_per_m = 0.012\nclutter_probability = 0.02\n"),
        &format!("name = \"known threshold\"\n{threshold}"),
        77,
        &|t| t,
    );
    let report = out.report.unwrap();
    let f = found(&report);
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some("weather"),
        "{}",
        out.stdout
    );
    let alpha = param(&f[0].1, "extinction_per_m");
    let p = param(&f[0].1, "clutter_probability");
    assert!((alpha - 0.012).abs() < 0.2 * 0.012, "extinction {alpha}");
    assert!((p - 0.02).abs() < 0.2 * 0.02, "clutter {p}");
    // The droplets' span: uniform from the blind zone to the model's default 3 m.
    let reach = param(&f[0].1, "clutter_max_range_m");
    assert!((reach - 3.0).abs() < 0.1 * 3.0, "clutter reach {reach} m");
    validation_improved(&report, &["avm:returns_per_scan"]);
}

#[test]
fn reference_noise_alone_adds_no_effect() {
    let (_d, out) = run_hidden(IDEALIZED, IDEALIZED, 23, &|t| t);
    let report = out.report.unwrap();
    assert!(found(&report).is_empty(), "{}", out.stdout);
    assert!(
        out.stdout.contains("no missing effect found"),
        "{}",
        out.stdout
    );
    assert_eq!(report["finished"], true);
    // The evidence: every candidate listed with its score.
    assert!(report["rounds"][0]["candidates"].as_array().unwrap().len() >= 7);
    assert!(report["split"].is_null());
    // One run alone is split in time, and the output says so.
    let d = _d.path();
    let one = gap(
        &[
            "--real".as_ref(),
            d.join("run-1.mcap").as_os_str(),
            "--scene".as_ref(),
            d.join("rep-01/scene.toml").as_os_str(),
            "--model".as_ref(),
            d.join("start.toml").as_os_str(),
            "--no-full-metrics".as_ref(),
        ],
        &d.join("one"),
    );
    assert_eq!(one.code, Some(0), "{}", one.stderr);
    assert!(
        one.stderr.contains("a single run: scans 0.."),
        "{}",
        one.stderr
    );
    let report = one.report.unwrap();
    assert!(report["split"].as_str().unwrap().contains("validate"));
    let runs = report["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    assert_eq!(runs[0]["role"], "fit");
    assert_eq!(runs[1]["role"], "validate");
}

/// Detection limits (issue 33): on a drive with nothing hidden, every effect the model lacks
/// gets the smallest size the runs would have shown, searched by injecting it into them; then
/// the same drive synthesized with a hidden mount yaw at twice that size is found, at half of
/// it missed. At 8 m/s, a speed the fixture does not drive.
/// (Named to sort first of its file: the test harness starts tests in the order of their
/// names, and this one, three studies long, had started last and run alone for a minute.)
#[test]
fn a_detection_limit_is_printed_for_what_was_not_found_and_twice_it_is_found_half_missed() {
    let seed = seed_of("detection limits");
    let drive = drive_at(8.0, false);
    let null = tempfile::tempdir().unwrap();
    let study = hidden(null.path(), IDEALIZED, IDEALIZED, seed, &drive);
    let out = gap_with_limits(
        &[study.as_os_str(), "--no-full-metrics".as_ref()],
        &null.path().join("out"),
    );
    assert_eq!(out.code, Some(0), "{}\n{}", out.stdout, out.stderr);
    eprintln!("{}", out.stdout);
    let report = out.report.unwrap();
    assert!(found(&report).is_empty(), "{}", out.stdout);
    let limits = report["limits"].as_array().unwrap();
    let mut effects: Vec<&str> = limits
        .iter()
        .map(|l| l["effect"].as_str().unwrap())
        .collect();
    effects.sort_unstable();
    // Every effect the idealized model lacks (motion distortion is on in it; weather acts
    // through a detection threshold, which it has not).
    assert_eq!(
        effects,
        [
            "beam_divergence",
            "detection_threshold",
            "intensity",
            "mount_misalignment",
            "random_dropout",
            "range_bias",
            "range_noise",
            "time_offset"
        ]
    );
    let limit = |name: &str| limits.iter().find(|l| l["effect"] == name).unwrap();
    assert!(limit("intensity")["note"]
        .as_str()
        .unwrap()
        .contains("not searched"));
    for l in limits.iter().filter(|l| l["note"].is_null()) {
        let name = l["effect"].as_str().unwrap();
        let seen = l["seen_at"]
            .as_f64()
            .unwrap_or_else(|| panic!("{name}: no size seen: {l}"));
        let tries = l["tries"].as_array().unwrap();
        // The limit is a size tried and seen; the size missed below it was tried and missed,
        // and lies on the weaker side.
        assert!(
            tries.iter().any(|t| t["size"] == seen && t["seen"] == true),
            "{l}"
        );
        if let Some(m) = l["missed_at"].as_f64() {
            assert!(
                tries.iter().any(|t| t["size"] == m && t["seen"] == false),
                "{l}"
            );
            let weaker = if l["at_most"] == true {
                m > seen
            } else {
                m < seen
            };
            assert!(weaker, "{l}");
        }
        assert!(
            out.stdout
                .contains(&format!("{name}: none found; would have seen")),
            "{}",
            out.stdout
        );
    }
    // The mount yaw the runs would have shown, hidden at twice and at half of it (the same
    // seed: the same reference errors and noise, the effect made by the simulator).
    let yaw = limit("mount_misalignment");
    let at = yaw["seen_at"].as_f64().unwrap();
    assert!(
        yaw["missed_at"].as_f64().unwrap() > at / 2.0,
        "half the limit lies below the size missed: {yaw}"
    );
    for (factor, expect) in [(2.0, true), (0.5, false)] {
        let d = tempfile::tempdir().unwrap();
        let size = factor * at;
        let truth = format!(
            "name = \"t\"\n[[effect]]\nname = \"mount_misalignment\"\nroll_deg = 0.0\npitch_deg = 0.0\nyaw_deg = {size}\n"
        );
        let study = hidden(d.path(), &truth, IDEALIZED, seed, &drive);
        let o = gap(
            &[study.as_os_str(), "--no-full-metrics".as_ref()],
            &d.path().join("out"),
        );
        assert_eq!(o.code, Some(0), "{}\n{}", o.stdout, o.stderr);
        let f = found(o.report.as_ref().unwrap());
        assert_eq!(
            f.iter().any(|(e, _)| e == "mount_misalignment"),
            expect,
            "a mount yaw of {size:.3}° ({factor} x the limit {at:.3}°): {}",
            o.stdout
        );
    }
}

#[test]
fn bad_studies_are_refused_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let study = hidden(d, IDEALIZED, IDEALIZED, 3, &|t| {
        t.replace(
            "[survey]",
            "[faults]\nrtk = [{ from_s = 2.0, to_s = 5.0, quality = 5 }]\n\n[survey]",
        )
    });
    // Runs that fail `check` (an RTK dropout to float for 3 s in every run): refused.
    let out = gap(&[study.as_os_str()], &d.join("o1"));
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    assert!(
        out.stderr.contains("fail the check") && out.stderr.contains("--force"),
        "{}",
        out.stderr
    );
    // With --force they are taken, and said to have failed; --max-rounds caps the rounds.
    let out = gap(
        &[
            study.as_os_str(),
            "--force".as_ref(),
            "--max-rounds".as_ref(),
            "1".as_ref(),
            "--no-full-metrics".as_ref(),
            // A round, not its numbers, is what this asserts: a small sample is enough.
            "--firings".as_ref(),
            "100000".as_ref(),
        ],
        &d.join("forced"),
    );
    assert_eq!(out.code, Some(0), "{}", out.stderr);
    let report = out.report.expect("gap.json");
    let runs = report["runs"].as_array().unwrap();
    assert!(
        runs.len() == 3 && runs.iter().all(|r| r["check"] == "fail"),
        "{runs:?}"
    );
    assert_eq!(report["rounds"].as_array().unwrap().len(), 1, "{report}");
    // A damaged recording (cut at 60 %): used as far as it can be read, and said so, on the
    // terminal and in gap.json.
    let run3 = d.join("run-3.mcap");
    let bytes = std::fs::read(&run3).unwrap();
    std::fs::write(&run3, &bytes[..bytes.len() * 3 / 5]).unwrap();
    let out = gap(
        &[
            study.as_os_str(),
            "--force".as_ref(),
            "--max-rounds".as_ref(),
            "1".as_ref(),
            "--no-full-metrics".as_ref(),
            // A round, not its numbers, is what this asserts: a small sample is enough.
            "--firings".as_ref(),
            "100000".as_ref(),
        ],
        &d.join("damaged"),
    );
    assert_eq!(out.code, Some(0), "{}", out.stderr);
    assert!(
        out.stderr
            .contains("warning: run-3.mcap: read up to damage"),
        "{}",
        out.stderr
    );
    let report = out.report.expect("gap.json");
    let damage = &report["runs"][2]["damage"];
    assert!(damage.as_array().is_some_and(|d| !d.is_empty()), "{damage}");
    assert!(report["runs"][0]["damage"]
        .as_array()
        .is_some_and(Vec::is_empty));
    std::fs::write(&run3, &bytes).unwrap();
    // A model with an unknown effect.
    std::fs::write(
        d.join("start.toml"),
        "name = \"x\"\n[[effect]]\nname = \"sparkle\"\n",
    )
    .unwrap();
    let out = gap(&[study.as_os_str()], &d.join("o2"));
    assert_eq!(out.code, Some(2));
    assert!(
        out.stderr.contains("start model") && out.stderr.contains("sparkle"),
        "{}",
        out.stderr
    );
    std::fs::write(d.join("start.toml"), IDEALIZED).unwrap();
    // Runs of different scenes.
    let other = std::fs::read_to_string(d.join("rep-02/scene.toml"))
        .unwrap()
        .replacen("name = \"parking\"", "name = \"test track\"", 1);
    std::fs::write(d.join("rep-02/scene.toml"), other).unwrap();
    let out = gap(&[study.as_os_str()], &d.join("o3"));
    assert_eq!(out.code, Some(2));
    assert!(
        out.stderr.contains("runs of different scenes"),
        "{}",
        out.stderr
    );
    // The shorthand with a run listed as both fit and validation.
    let run = d.join("run-1.mcap");
    let out = gap(
        &[
            "--real".as_ref(),
            run.as_os_str(),
            "--validate".as_ref(),
            run.as_os_str(),
            "--scene".as_ref(),
            fixture("parking/scene.toml").as_os_str(),
            "--model".as_ref(),
            fixture("parking/idealized.toml").as_os_str(),
        ],
        &d.join("o4"),
    );
    assert_eq!(out.code, Some(2));
    assert!(out.stderr.contains("listed twice"), "{}", out.stderr);
}

/// One study for the tests of a workflow cut short or fed the wrong scene: a hidden 5 cm range
/// bias (so that the first round adds it and a second begins) on a drive from standstill at
/// 5 m/s, synthesized once per test binary into cargo's directory for test data.
fn shared_study() -> &'static Path {
    static STUDY: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    STUDY.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gap-shared-study");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        hidden(
            &dir,
            "name = \"t\"\n[[effect]]\nname = \"range_bias\"\nbias_m = 0.05\n",
            IDEALIZED,
            seed_of("shared study"),
            &drive_at(5.0, true),
        )
    })
}

/// `gap` writes `gap.json` and `model.fitted.toml` after every round; killed (SIGKILL) as soon
/// as the first round's files appear, the output holds that round whole: both files parse, the
/// model is the start model plus the round's effect, and the report says it did not finish.
/// While it runs, every version of `gap.json` a reader meets parses, and each is a new file
/// (written beside and renamed over the old one): a file rewritten in place can be met, or
/// left by a crash, half written.
#[test]
fn an_interrupted_study_leaves_the_last_rounds_files_whole() {
    use std::os::unix::fs::MetadataExt;
    use std::os::unix::process::ExitStatusExt;
    let study = shared_study();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let mut child = std::process::Command::new(common::hilrig_bin())
        .arg("gap")
        .arg(study)
        .args(["--no-full-metrics", "-o"])
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // (rounds, inode) of each version of gap.json seen.
    let mut versions: Vec<(usize, u64)> = Vec::new();
    let started = std::time::Instant::now();
    loop {
        if let Ok(bytes) = std::fs::read(out.join("gap.json")) {
            let inode = std::fs::metadata(out.join("gap.json")).map_or(0, |m| m.ino());
            let report: serde_json::Value = serde_json::from_slice(&bytes).unwrap_or_else(|e| {
                panic!(
                    "a reader met gap.json half written ({e}): {}",
                    String::from_utf8_lossy(&bytes)
                )
            });
            let rounds = report["rounds"].as_array().map_or(0, Vec::len);
            if versions.last() != Some(&(rounds, inode)) {
                versions.push((rounds, inode));
            }
            if rounds >= 1 {
                break;
            }
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "gap ended before its first round was written"
        );
        // Not a timing assertion: a bound on a hung test.
        assert!(started.elapsed().as_secs() < 600, "no round after 10 min");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.signal(), Some(9), "killed mid-study: {status:?}");
    // The version before the first round (written once the runs are loaded) and the round's.
    assert!(
        versions.len() >= 2 && versions[0].0 == 0,
        "versions seen: {versions:?}"
    );
    let inodes: std::collections::HashSet<u64> = versions.iter().map(|v| v.1).collect();
    assert_eq!(
        inodes.len(),
        versions.len(),
        "gap.json rewritten in place, not replaced: {versions:?}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("gap.json")).unwrap()).unwrap();
    assert_eq!(report["finished"], false, "{report}");
    let f = found(&report);
    assert_eq!(f.len(), 1, "{report}");
    assert_eq!(f[0].0, "range_bias");
    let model = hilrig::sim::ModelFile::load(&out.join("model.fitted.toml")).unwrap();
    assert_eq!(
        model.effects,
        vec![hilrig::sim::model::Effect::RangeBias {
            bias_m: param(&f[0].1, "bias_m")
        }],
        "model.fitted.toml holds the start model and the round's effect"
    );
}

/// A run checked against a scene it was not recorded in is refused before any effect is
/// fitted: the ground plane agrees with any trajectory over it, so the objects decide.
#[test]
fn a_run_and_a_scene_that_do_not_belong_together_are_refused() {
    let study = shared_study();
    let d = study.parent().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let scene = std::fs::read_to_string(d.join("rep-01/scene.toml")).unwrap();
    // The same site 30 m further east (0.0004° of longitude at 48.8° N).
    let elsewhere = scene.replace("longitude_deg = 11.47291", "longitude_deg = 11.47331");
    assert_ne!(elsewhere, scene);
    // The objects mirrored across the drive (y -> -y): the cars, columns and wall moved.
    let mut in_pose = false;
    let mirrored: String = scene
        .lines()
        .map(|l| {
            if l.starts_with('[') {
                in_pose = l.trim() == "[object.pose]";
            }
            match l.strip_prefix("y = ") {
                Some(y) if in_pose => format!("y = {:?}\n", -y.parse::<f64>().unwrap()),
                _ => format!("{l}\n"),
            }
        })
        .collect();
    assert_ne!(mirrored, scene);
    for (name, text) in [("elsewhere", elsewhere), ("mirrored", mirrored)] {
        let path = dir.path().join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        let out = gap(
            &[
                "--real".as_ref(),
                d.join("run-1.mcap").as_os_str(),
                d.join("run-2.mcap").as_os_str(),
                "--validate".as_ref(),
                d.join("run-3.mcap").as_os_str(),
                "--scene".as_ref(),
                path.as_os_str(),
                "--model".as_ref(),
                d.join("start.toml").as_os_str(),
                "--no-full-metrics".as_ref(),
            ],
            &dir.path().join(name),
        );
        assert_eq!(out.code, Some(2), "{name}: {}\n{}", out.stdout, out.stderr);
        assert!(
            out.stderr
                .contains("the run and the scene do not belong together")
                && out.stderr.contains(&format!("{name}.toml")),
            "{name}: {}",
            out.stderr
        );
        assert!(out.report.is_none(), "{name}: nothing written");
    }
}

/// Runs whose lidar covers a few scans (the lidar silent but for a quarter of a second, the
/// reference data whole, so that `check` passes): refused, saying how many usable scans each
/// run holds and how many are needed, not fitted on the sign of one number.
#[test]
fn runs_of_a_few_scans_are_refused_naming_their_scans_and_the_minimum() {
    let dir = tempfile::tempdir().unwrap();
    let study = hidden(
        dir.path(),
        "name = \"t\"\n[[effect]]\nname = \"range_bias\"\nbias_m = 0.05\n",
        IDEALIZED,
        seed_of("a few scans"),
        &|t| {
            t.replace(
                "[survey]",
                "[faults]\nlidar_gap = [{ from_s = 0.0, to_s = 4.0 }, { from_s = 4.25, to_s = 60.0 }]\n\n[survey]",
            )
        },
    );
    let out = gap(&[study.as_os_str()], &dir.path().join("out"));
    assert_eq!(out.code, Some(2), "{}\n{}", out.stdout, out.stderr);
    let scans = |run: &str| -> usize {
        let at = out
            .stderr
            .find(&format!("{run}: "))
            .unwrap_or_else(|| panic!("{run} not named: {}", out.stderr));
        let rest = &out.stderr[at + run.len() + 2..];
        rest[..rest.find(|c: char| !c.is_ascii_digit()).unwrap()]
            .parse()
            .unwrap()
    };
    for run in ["run-1.mcap", "run-2.mcap", "run-3.mcap"] {
        let n = scans(run);
        assert!((1..=4).contains(&n), "{run}: {n} scans\n{}", out.stderr);
    }
    assert!(
        out.stderr.contains("too few scans")
            && out.stderr.contains("parameterization runs hold")
            && out.stderr.contains("validation runs hold")
            && out.stderr.contains("each needs at least 40"),
        "{}",
        out.stderr
    );
    assert!(out.report.is_none(), "nothing written");
}

/// A detection threshold and random dropout hidden together: both remove returns, so the one
/// fitted first takes some of the other's share. When the second joins, the first is fitted
/// again with it (the joint re-fit): both end within 20 % of the truth, the re-fit is
/// reported with the parameters before and after, and it moves the first effect toward the
/// truth, not away.
#[test]
fn a_threshold_and_dropout_hidden_together_are_fitted_jointly() {
    // 25 m at 10 % reflectivity (43.3 m at 0.3), and 2 % of the returns lost at random.
    let (_d, out) = run_hidden(
        "name = \"t\"\n[[effect]]\nname = \"detection_threshold\"\nreference_range_m = 43.3\nreference_reflectivity = 0.3\n[[effect]]\nname = \"random_dropout\"\nprobability = 0.02\n",
        IDEALIZED,
        23,
        &|t| t,
    );
    let report = out.report.unwrap();
    eprintln!("{}", out.stdout);
    let f = found(&report);
    let truth = |name: &str| match name {
        "detection_threshold" => ("reference_range_m", 25.0),
        _ => ("probability", 0.02),
    };
    for hidden in ["detection_threshold", "random_dropout"] {
        let (_, params) = f
            .iter()
            .rev()
            .find(|x| x.0 == hidden)
            .unwrap_or_else(|| panic!("{hidden} not found:\n{}", out.stdout));
        let (name, want) = truth(hidden);
        // The last word on it: the joint re-fit of a later round, else its own round's fit.
        let last = report["rounds"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|r| r["refits"].as_array().cloned().unwrap_or_default())
            .rfind(|x| x["effect"] == hidden)
            .map_or_else(|| param(params, name), |x| param(&x["after"], name));
        assert!(
            (last - want).abs() < 0.2 * want,
            "{hidden}: {name} {last}, truth {want}:\n{}",
            out.stdout
        );
    }
    // The round that added the second re-fitted the first, toward its truth.
    let second = report["rounds"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["chosen"].is_string())
        .nth(1)
        .expect("two effects added");
    let refit = second["refits"]
        .as_array()
        .and_then(|r| r.first())
        .unwrap_or_else(|| panic!("no re-fit reported: {second}"));
    let first = refit["effect"].as_str().unwrap();
    let (name, want) = truth(first);
    let (before, after) = (param(&refit["before"], name), param(&refit["after"], name));
    assert!(
        (after - want).abs() <= (before - want).abs() + 0.01 * want,
        "{first}: {name} {before} -> {after}, truth {want}"
    );
}

/// The benches' synthesis seeds (issue 33, must-hold 1): every null study of
/// `benches/gap_null.py` and every case of `benches/gap_hidden.py` at bench seeds 1-20 draws its
/// own noise; none shares a seed with another (a sum of the case name's characters and the
/// seed once made null-1 at seed 2 the drives of null-2 at seed 1), and the null studies cover
/// three drives (two scene layouts) and speeds from 2 to 12 m/s.
#[test]
fn the_benches_synthesis_seeds_never_collide() {
    let out = std::process::Command::new(common::python())
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/gap_null.py"))
        .args(["--seeds", "--studies", "30"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(' ').collect()).collect();
    let nulls: Vec<&Vec<&str>> = rows.iter().filter(|r| r[0] == "null").collect();
    assert_eq!(nulls.len(), 30);
    let hidden = rows.iter().filter(|r| r[0] == "hidden").count();
    assert!(hidden >= 20 * 10, "{hidden} hidden-effect cases");
    let mut seeds: Vec<u64> = rows
        .iter()
        .map(|r| r[r.len() - 1].parse().unwrap())
        .collect();
    seeds.sort_unstable();
    let n = seeds.len();
    seeds.dedup();
    assert_eq!(seeds.len(), n, "a synthesis seed is shared");
    for drive in ["gap", "parking", "street"] {
        let speeds: Vec<f64> = nulls
            .iter()
            .filter(|r| r[2] == drive)
            .map(|r| r[3].parse().unwrap())
            .collect();
        assert_eq!(speeds.len(), 10, "{drive}");
        if drive != "parking" {
            let (lo, hi) = speeds
                .iter()
                .fold((f64::MAX, f64::MIN), |a, &s| (a.0.min(s), a.1.max(s)));
            assert!(lo <= 2.0 && hi >= 12.0, "{speeds:?}");
        }
    }
}

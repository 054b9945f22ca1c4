//! The harness of the gap workflow's tests (tests/gap.rs, tests/gap_effects.rs): a study of
//! drives of fixtures/gap/drive.toml synthesized with a hidden effect, `hilrig gap` run on it,
//! and readers of what it found.

use super::{demo_rig, fixture, hilrig_bin, record_from};
use std::path::{Path, PathBuf};

/// A study of three synthesized drives with `truth` hidden; returns the study file.
pub fn hidden(
    dir: &Path,
    truth: &str,
    start: &str,
    seed: u64,
    edit: &dyn Fn(String) -> String,
) -> PathBuf {
    hidden_captured(dir, truth, start, seed, edit, &|rep| {
        rep.join("drive.pcapng")
    })
}

/// [`hidden`], recording for each repetition (its folder given) the capture `capture` returns:
/// the synthesized one, or one a test made from it.
pub fn hidden_captured(
    dir: &Path,
    truth: &str,
    start: &str,
    seed: u64,
    edit: &dyn Fn(String) -> String,
    capture: &dyn Fn(&Path) -> PathBuf,
) -> PathBuf {
    let drive_text = edit(std::fs::read_to_string(fixture("gap/drive.toml")).unwrap()).replace(
        "rig = \"../../rigs/demo.toml\"",
        &format!("rig = {:?}", demo_rig().display().to_string()),
    );
    let drive = dir.join("drive.toml");
    std::fs::write(&drive, drive_text).unwrap();
    std::fs::write(dir.join("truth.toml"), truth).unwrap();
    std::fs::write(dir.join("start.toml"), start).unwrap();
    let out = std::process::Command::new(hilrig_bin())
        .args(["synth", "--scene"])
        .arg(fixture("parking/scene.toml"))
        .arg("--drive")
        .arg(&drive)
        .arg("--truth")
        .arg(dir.join("truth.toml"))
        .args(["--reps", "3", "--seed", &seed.to_string(), "-o"])
        .arg(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let runs: Vec<(PathBuf, PathBuf)> = (1..=3)
        .map(|i| {
            let run = dir.join(format!("run-{i}.mcap"));
            let rec = record_from(
                &demo_rig(),
                &[&capture(&dir.join(format!("rep-{i:02}")))],
                &run,
            );
            assert!(
                rec.status.success(),
                "{}",
                String::from_utf8_lossy(&rec.stderr)
            );
            (run, dir.join(format!("rep-{i:02}/scene.toml")))
        })
        .collect();
    study(dir, &dir.join("start.toml"), &runs)
}

/// Writes `dir/study.toml`: the start model and the runs (recording, scene), the last one
/// validating and the others fitting, each path relative to `dir` where it lies within it (as
/// a user writes a study); returns its path.
pub fn study(dir: &Path, model: &Path, runs: &[(PathBuf, PathBuf)]) -> PathBuf {
    let rel = |p: &Path| p.strip_prefix(dir).unwrap_or(p).display().to_string();
    let mut study = format!("model = {:?}\n", rel(model));
    for (k, (run, scene)) in runs.iter().enumerate() {
        study.push_str(&format!(
            "[[run]]\nrecording = {:?}\nscene = {:?}\nrole = \"{}\"\n",
            rel(run),
            rel(scene),
            if k + 1 == runs.len() {
                "validate"
            } else {
                "fit"
            }
        ));
    }
    let path = dir.join("study.toml");
    std::fs::write(&path, study).unwrap();
    path
}

/// What a `hilrig gap` run left: its exit code, its output and the `gap.json` it wrote.
pub struct Outcome {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
    pub report: Option<serde_json::Value>,
}

/// Runs `hilrig gap ARGS -o OUT` to the end, without the search for detection limits (it
/// adds a few seconds per effect; [`gap_with_limits`] runs it).
pub fn gap(args: &[&std::ffi::OsStr], out: &Path) -> Outcome {
    let mut all = args.to_vec();
    all.push("--no-detection-limits".as_ref());
    gap_with_limits(&all, out)
}

/// Runs `hilrig gap ARGS -o OUT` to the end as a user would: detection limits searched.
pub fn gap_with_limits(args: &[&std::ffi::OsStr], out: &Path) -> Outcome {
    let o = std::process::Command::new(hilrig_bin())
        .arg("gap")
        .args(args)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    Outcome {
        code: o.status.code(),
        stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
        report: std::fs::read(out.join("gap.json"))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok()),
    }
}

/// The effects the workflow added, in order, with their fitted parameters.
pub fn found(report: &serde_json::Value) -> Vec<(String, serde_json::Value)> {
    report["rounds"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|r| {
            let name = r["chosen"].as_str()?;
            Some((name.to_owned(), r["parameters"].clone()))
        })
        .collect()
}

/// The value of the fitted parameter `name` in a round's `parameters`.
pub fn param(params: &serde_json::Value, name: &str) -> f64 {
    params
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == name)
        .and_then(|p| p["value"].as_f64())
        .unwrap_or_else(|| panic!("no parameter {name} in {params}"))
}

/// The idealized model: ray casting with a perfect beam, no effect.
pub const IDEALIZED: &str = "name = \"idealized\"\n";
/// A start model that places each rotation at the pose of its first firing.
pub const FRAME_BASED: &str =
    "name = \"frame-based\"\n[[effect]]\nname = \"motion_distortion\"\nenabled = false\n";

/// [`hidden`] in a new temporary folder and `hilrig gap` on it, which must succeed.
pub fn run_hidden(
    truth: &str,
    start: &str,
    seed: u64,
    edit: &dyn Fn(String) -> String,
) -> (tempfile::TempDir, Outcome) {
    run_hidden_with(truth, start, seed, edit, &[])
}

/// [`run_hidden`] with `args` given to `hilrig gap` after the study.
pub fn run_hidden_with(
    truth: &str,
    start: &str,
    seed: u64,
    edit: &dyn Fn(String) -> String,
    args: &[&str],
) -> (tempfile::TempDir, Outcome) {
    let dir = tempfile::tempdir().unwrap();
    let study = hidden(dir.path(), truth, start, seed, edit);
    let mut all = vec![study.as_os_str()];
    all.extend(args.iter().map(std::ffi::OsStr::new));
    let out = gap(&all, &dir.path().join("out"));
    assert_eq!(out.code, Some(0), "{}\n{}", out.stdout, out.stderr);
    (dir, out)
}

/// What the first added effect did on the validation runs: [`validation_improved_in`] round 1.
pub fn validation_improved(report: &serde_json::Value, improves: &[&str]) {
    validation_improved_in(report, 1, improves);
}

/// What the effect added in `round` (from 1) did on the validation runs, judged on numbers the workflow did
/// not use to decide (its keep rule is the likelihood gain's interval, so asserting that again
/// would be circular): the full re-simulation's metrics before and after, each named in
/// `improves` (`"ocr"`, `"precision"` or `"avm:FEATURE"`) must move the right way, and no
/// traffic light may turn worse.
pub fn validation_improved_in(report: &serde_json::Value, round: usize, improves: &[&str]) {
    let round = &report["rounds"][round - 1];
    let (before, after) = (&round["metrics_before"], &round["metrics_after"]);
    assert!(
        before.is_object() && after.is_object(),
        "the full re-simulation's metrics: {round}"
    );
    let avm = |m: &serde_json::Value, name: &str| -> f64 {
        m["avm"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["metric"] == name)
            .and_then(|p| p["avm"].as_f64())
            .unwrap_or_else(|| panic!("no AVM of {name} in {m}"))
    };
    for what in improves {
        let (b, a, higher_is_better) = match what.strip_prefix("avm:") {
            Some(f) => (avm(before, f), avm(after, f), false),
            None => (
                before[*what].as_f64().unwrap(),
                after[*what].as_f64().unwrap(),
                true,
            ),
        };
        assert!(
            if higher_is_better { a > b } else { a < b },
            "{what}: {b} -> {a}\nbefore {before}\nafter {after}"
        );
    }
    let rank = |l: &serde_json::Value| match l.as_str() {
        Some("green") => 0,
        Some("yellow") => 1,
        Some("red") => 2,
        _ => 3,
    };
    let lights = |m: &serde_json::Value| -> Vec<(String, i32)> {
        m["lights"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| (p["metric"].as_str().unwrap().to_owned(), rank(&p["light"])))
            .collect()
    };
    for ((name, b), (_, a)) in lights(before).into_iter().zip(lights(after)) {
        assert!(a <= b, "light of {name} turned worse: {before} -> {after}");
    }
}

/// The seed of a test case: a hash (64-bit FNV-1a) of its name, so that seeds are not picked by
/// trial and no two cases share their noise.
pub fn seed_of(case: &str) -> u64 {
    case.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    }) % 1_000_000
}

/// An edit of the gap drive: cruise at `speed_mps` instead of the fixture's 6 m/s, and start
/// from standstill when `standing` (the fixture starts at cruise speed).
pub fn drive_at(speed_mps: f64, standing: bool) -> impl Fn(String) -> String {
    move |t: String| {
        let t = t.replace(
            "cruise_speed_mps = 6.0",
            &format!("cruise_speed_mps = {speed_mps:?}"),
        );
        if standing {
            t.replace("start_speed_mps = 6.0\n", "")
        } else {
            t.replace(
                "start_speed_mps = 6.0",
                &format!("start_speed_mps = {speed_mps:?}"),
            )
        }
    }
}

/// Asserts that the workflow added the hidden effects and nothing else, each once, with
/// `first` added first; returns what it found.
pub fn found_only(out: &Outcome, first: &str, hidden: &[&str]) -> Vec<(String, serde_json::Value)> {
    let f = found(out.report.as_ref().expect("gap.json"));
    // Shown with --nocapture: what was found, for the record.
    eprintln!("{}", out.stdout);
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some(first),
        "{}",
        out.stdout
    );
    for (i, (name, params)) in f.iter().enumerate() {
        assert!(
            hidden.contains(&name.as_str()) && !f[..i].iter().any(|x| &x.0 == name),
            "{name} added, hidden were {hidden:?}:\n{}",
            out.stdout
        );
        // A re-fitted parameter ("detection_threshold.reference_range_m (re-fitted)") belongs
        // to an effect added before: re-fitting must not bring in an effect of its own.
        for p in params.as_array().into_iter().flatten() {
            let Some(refit) = p["name"]
                .as_str()
                .and_then(|n| n.strip_suffix(" (re-fitted)"))
            else {
                continue;
            };
            let effect = refit.split('.').next().unwrap_or_default();
            assert!(
                f[..i].iter().any(|x| x.0 == effect),
                "{name} re-fitted {refit}, an effect not in the model:\n{}",
                out.stdout
            );
        }
    }
    f
}

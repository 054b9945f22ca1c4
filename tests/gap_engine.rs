//! The gap workflow's full re-simulations as tasks of a plan per round (`gap trial`, one per
//! validation run): on the campaigns' local executor (`--jobs`) and on a real Ray cluster
//! (`--engine "python -m hilrig_ray ..."`, PyPI `ray`), each giving the study the workflow
//! gives in its own process, `gap.json` and every kept simulation byte for byte.
//!
//! The study: three drives of the gap fixture with a range bias and range noise hidden, one
//! to fit and two to validate (so that a round's plan has two tasks to run side by side), one
//! round, and the truth as the reference model: its noise makes the reference's simulations
//! cast its deterministic part too, the path a task must reproduce as well.

use crate::common;

use common::gap::{drive_at, hidden, seed_of, IDEALIZED};
use std::path::{Path, PathBuf};
use std::process::Command;

const TRUTH: &str = "name = \"t\"\n[[effect]]\nname = \"range_bias\"\nbias_m = 0.04\n\
                     [[effect]]\nname = \"range_noise\"\nsigma_m = 0.02\n";

/// The study, made once per test binary: the drives of [`hidden`], the second and third
/// validating.
fn study() -> &'static Path {
    static STUDY: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    STUDY.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gap-engine-study");
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = hidden(
            &dir,
            TRUTH,
            IDEALIZED,
            seed_of("gap engine"),
            &drive_at(5.0, false),
        );
        let text = std::fs::read_to_string(&path).unwrap();
        let second = text.find("role = \"fit\"").and_then(|first| {
            text[first + 1..]
                .find("role = \"fit\"")
                .map(|k| first + 1 + k)
        });
        let second = second.expect("two runs to fit in the study hidden() writes");
        let text = format!(
            "{}role = \"validate\"{}",
            &text[..second],
            &text[second + "role = \"fit\"".len()..]
        );
        std::fs::write(&path, text).unwrap();
        path
    })
}

/// `hilrig gap STUDY` of one round with the truth as reference model and `extra` arguments,
/// into `out`; it must succeed. Its log (stderr).
fn gap(out: &Path, extra: &[&str], env: &[(&str, &Path)]) -> String {
    let study = study();
    let mut cmd = Command::new(common::hilrig_bin());
    cmd.arg("gap")
        .arg(study)
        .args([
            "--max-rounds",
            "1",
            "--no-detection-limits",
            "--reference-model",
        ])
        .arg(study.with_file_name("truth.toml"))
        .args(extra)
        .arg("-o")
        .arg(out);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let o = cmd.output().unwrap();
    assert!(
        o.status.success(),
        "gap {extra:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The study made in this process, once per test binary, and its log at `-v`.
fn in_process_with_log() -> &'static (PathBuf, String) {
    static OUT: std::sync::OnceLock<(PathBuf, String)> = std::sync::OnceLock::new();
    OUT.get_or_init(|| {
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("gap-engine-in-process");
        let _ = std::fs::remove_dir_all(&out);
        let log = gap(&out, &["-v"], &[]);
        (out, log)
    })
}

fn in_process() -> &'static Path {
    &in_process_with_log().0
}

/// In one process, the validation runs' re-simulations after round 0 (the trial's, the
/// reference's: models that cast the start model's rays) traverse none of their centre rays
/// again: the hits round 0 kept are reused (and the study is the one the tasks make, which
/// reuse nothing: the tests above).
#[test]
fn in_one_process_the_rounds_reuse_the_centre_hits_round_0_kept() {
    let (_, log) = in_process_with_log();
    let counts: Vec<(u64, u64)> = log
        .lines()
        .filter(|l| l.contains("centre rays' static hits reused"))
        .map(|l| {
            let n: Vec<u64> = l
                .split(|c: char| !c.is_ascii_digit())
                .filter(|w| !w.is_empty())
                .map(|w| w.parse().unwrap())
                .collect();
            // The last two numbers: hits reused, rays cast.
            (n[n.len() - 2], n[n.len() - 1])
        })
        .collect();
    // Round 0's two runs, the trial's two, the reference's two.
    assert!(counts.len() >= 6, "{counts:?}\n{log}");
    assert!(
        counts[..2]
            .iter()
            .all(|&(reused, cast)| reused == 0 && cast > 100_000),
        "{counts:?}"
    );
    assert!(
        counts[2..]
            .iter()
            .all(|&(reused, cast)| reused > 100_000 && cast == 0),
        "{counts:?}"
    );
}

/// The simulations a study kept (`sim/*.mcap`), by name.
fn simulations(out: &Path) -> Vec<(String, Vec<u8>)> {
    let mut found: Vec<(String, Vec<u8>)> = std::fs::read_dir(out.join("sim"))
        .unwrap()
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "mcap"))
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    found.sort();
    found
}

/// `gap.json` with the output folder's own path taken out (the two studies write to two).
fn report(out: &Path) -> String {
    std::fs::read_to_string(out.join("gap.json"))
        .unwrap()
        .replace(&out.display().to_string(), "OUT")
}

/// The study made in one process, and again with each round's re-simulations as tasks on
/// `engine`: the same `gap.json`, the same simulations; `tasks` is what shows they ran as
/// tasks (at least one per validation run and round).
fn same_as_in_process(engine_out: &Path, tasks: usize) {
    let here = in_process();
    let sims = simulations(here);
    // The start model's two, the trial's two, the reference's two.
    assert!(
        sims.len() >= 6,
        "{:?}",
        sims.iter().map(|s| &s.0).collect::<Vec<_>>()
    );
    let theirs = simulations(engine_out);
    assert_eq!(
        sims.iter().map(|s| &s.0).collect::<Vec<_>>(),
        theirs.iter().map(|s| &s.0).collect::<Vec<_>>()
    );
    for (a, b) in sims.iter().zip(&theirs) {
        assert!(a.1 == b.1, "{} differs from the one made in process", a.0);
    }
    assert_eq!(report(here), report(engine_out));
    let results: Vec<PathBuf> = std::fs::read_dir(engine_out.join("sim"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension().is_some_and(|x| x == "json")
                && p.file_name()
                    .is_some_and(|n| n.to_string_lossy().contains("-validation-"))
        })
        .collect();
    assert!(
        results.len() >= tasks,
        "{} task results: {results:?}",
        results.len()
    );
    for r in &results {
        let text = std::fs::read_to_string(r).unwrap();
        assert!(text.contains("\"kind\": \"gap_trial\""), "{}", r.display());
    }
}

/// Modification times of the files under `dir`, by path.
fn times(dir: &Path) -> Vec<(PathBuf, std::time::SystemTime)> {
    let mut found = Vec::new();
    let mut todo = vec![dir.to_owned()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            if e.path().is_dir() {
                todo.push(e.path());
            } else {
                found.push((e.path(), e.metadata().unwrap().modified().unwrap()));
            }
        }
    }
    found.sort();
    found
}

/// The study with `--jobs 2`: the same as in one process; each trial stamped as the campaigns'
/// executor stamps its tasks, its log beside its result. Made again into the same folder,
/// every trial is up to date: no simulation, result or stamp is written again, and the study
/// is the same.
#[test]
fn a_rounds_re_simulations_as_tasks_on_the_local_executor_give_the_same_study() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("local");
    gap(&out, &["--jobs", "2"], &[]);
    // round 0, the trial, the reference: two validation runs each.
    same_as_in_process(&out, 6);
    let stamps = out.join("sim/campaign/done/gap/round-0");
    for i in 1..=2 {
        assert!(
            stamps.join(format!("validation-{i:02}.json")).exists(),
            "no stamp of round 0's validation run {i} in {}",
            stamps.display()
        );
        assert!(out
            .join(format!("sim/round-0-validation-{i:02}.log"))
            .exists());
    }
    let trials = |out: &Path| -> Vec<(PathBuf, std::time::SystemTime)> {
        times(&out.join("sim"))
            .into_iter()
            .filter(|(p, _)| {
                let name = p.file_name().unwrap().to_string_lossy();
                name.contains("-validation-")
                    && (name.ends_with(".mcap") || name.ends_with(".json"))
            })
            .collect()
    };
    let before = trials(&out);
    assert!(before.len() >= 12, "{before:?}");
    gap(&out, &["--jobs", "2"], &[]);
    assert_eq!(trials(&out), before, "a trial up to date was made again");
    assert_eq!(report(in_process()), report(&out));
}

#[test]
fn a_rounds_re_simulations_as_tasks_on_a_ray_cluster_give_the_same_study() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ray");
    let cluster = common::ray::Cluster::start();
    let engine = format!(
        "{} -m hilrig_ray --address {} --hilrig {}",
        common::python().display(),
        cluster.address,
        common::hilrig_bin().display()
    );
    let python = Path::new(env!("CARGO_MANIFEST_DIR")).join("python");
    gap(
        &out,
        &["--engine", &engine],
        &[
            ("PYTHONPATH", &python),
            ("RAY_USAGE_STATS_ENABLED", Path::new("0")),
        ],
    );
    // The tasks ran on the cluster's workers: the plan each round handed the engine, and the
    // engine's summary of its outcomes in the log beside it.
    let log = std::fs::read_to_string(out.join("sim/round-0.plan.log")).unwrap();
    assert!(log.contains("\"outcomes\""), "{log}");
    assert!(!log.contains("\"failed\""), "{log}");
    drop(cluster);
    same_as_in_process(&out, 6);
}

/// An engine that cannot be started, one that fails, and one that ends well but left no
/// result stop the study with exit 2, saying which command or which trial and where to look;
/// what the study wrote before (its runs, read and checked) stays.
#[test]
fn an_engine_that_cannot_run_the_plan_is_named_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    for (engine, says) in [
        ("/no/such/engine --flag", "cannot start /no/such/engine"),
        ("false", "the engine `false` ended with"),
        ("true", "the round-0 trial of"),
        ("", "--engine \"\": not a command"),
    ] {
        let out = dir.path().join("out");
        let o = Command::new(common::hilrig_bin())
            .arg("gap")
            .arg(study())
            .args([
                "--max-rounds",
                "1",
                "--no-detection-limits",
                "--engine",
                engine,
                "-o",
            ])
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{engine}: {stderr}");
        assert!(stderr.contains(says), "{engine}: {stderr}");
        if !engine.is_empty() {
            // The plan it was given, and the log the error points to.
            assert!(out.join("sim/round-0.plan.json").exists(), "{engine}");
            let log = if engine == "true" {
                "round-0-validation-01.json"
            } else {
                "round-0.plan.log"
            };
            assert!(stderr.contains(log), "{engine}: {stderr}");
            let report: serde_json::Value =
                serde_json::from_slice(&std::fs::read(out.join("gap.json")).unwrap()).unwrap();
            assert_eq!(report["finished"], false);
        }
        let _ = std::fs::remove_dir_all(&out);
    }
}

//! `hilrig efast` against SALib (PyPI): on the same Ishigami samples (a = 7, b = 0.1, N = 1000,
//! M = 4, sampled by hilrig), SALib's `fast.analyze` and `hilrig efast analyze` give the same S1
//! and ST to 1e-6, and S1 is within 0.03 of the analytic 0.3139, 0.4424, 0; on noisy outputs
//! their confidence half-widths agree within 10 %. A parameter file with an unknown
//! distribution is refused with exit 2.

use crate::common;

use common::{hilrig_bin, hilrig_ok, interop_script};
use serde_json::Value;
use std::process::Command;

const PARAMS: &str = "[[parameter]]\nname = \"x1\"\ndistribution = \"uniform\"\nlow = -3.141592653589793\nhigh = 3.141592653589793\n\
[[parameter]]\nname = \"x2\"\ndistribution = \"uniform\"\nlow = -3.141592653589793\nhigh = 3.141592653589793\n\
[[parameter]]\nname = \"x3\"\ndistribution = \"uniform\"\nlow = -3.141592653589793\nhigh = 3.141592653589793\n";

/// hilrig's and SALib's indices of the Ishigami function on hilrig's samples (N = 1000, M = 4),
/// with `noise` (a standard deviation) added to every output as a stochastic simulation would,
/// and the confidence half-widths from `resamples` bootstrap windows on either side.
fn ishigami(noise: f64, resamples: usize) -> Vec<(Value, Value)> {
    use rand::SeedableRng;
    use rand_distr::Distribution;
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("ishigami.toml");
    std::fs::write(&params, PARAMS).unwrap();
    let out = hilrig_ok(&[
        "efast".as_ref(),
        "sample".as_ref(),
        "--params".as_ref(),
        params.as_os_str(),
        "-N".as_ref(),
        "1000".as_ref(),
        "-M".as_ref(),
        "4".as_ref(),
        "--seed".as_ref(),
        "5".as_ref(),
    ]);
    let text = String::from_utf8(out.stdout).unwrap();
    let samples = dir.path().join("x.csv");
    std::fs::write(&samples, &text).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x1,x2,x3"));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let normal = rand_distr::Normal::new(0.0, noise.max(1e-300)).unwrap();
    let y: Vec<f64> = lines
        .map(|l| {
            let x: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            let e = if noise > 0.0 {
                normal.sample(&mut rng)
            } else {
                0.0
            };
            x[0].sin() + 7.0 * x[1].sin().powi(2) + 0.1 * x[2].powi(4) * x[0].sin() + e
        })
        .collect();
    assert_eq!(y.len(), 3000);
    let outputs = dir.path().join("y.csv");
    let body: Vec<String> = y.iter().map(|v| format!("{v:?}")).collect();
    std::fs::write(&outputs, format!("y\n{}\n", body.join("\n"))).unwrap();
    let json = dir.path().join("si.json");
    let resamples = resamples.to_string();
    hilrig_ok(&[
        "efast".as_ref(),
        "analyze".as_ref(),
        "--params".as_ref(),
        params.as_os_str(),
        samples.as_os_str(),
        outputs.as_os_str(),
        "--resamples".as_ref(),
        resamples.as_ref(),
        "--json".as_ref(),
        json.as_os_str(),
    ]);
    let ours: Vec<Value> = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let stdout = interop_script(
        "salib_fast.py",
        &[
            outputs.as_os_str(),
            "x1,x2,x3".as_ref(),
            "4".as_ref(),
            resamples.as_ref(),
        ],
    );
    let salib: Vec<Value> = serde_json::from_slice(&stdout).unwrap();
    assert_eq!((ours.len(), salib.len()), (3, 3));
    ours.into_iter().zip(salib).collect()
}

#[test]
fn ishigami_indices_equal_salib_s_on_the_same_samples() {
    for ((o, s), analytic) in ishigami(0.0, 10).iter().zip([0.3139, 0.4424, 0.0]) {
        let (s1, st) = (o["s1"].as_f64().unwrap(), o["st"].as_f64().unwrap());
        assert!(
            (s1 - s["S1"].as_f64().unwrap()).abs() < 1e-6,
            "{o} vs SALib {s}"
        );
        assert!(
            (st - s["ST"].as_f64().unwrap()).abs() < 1e-6,
            "{o} vs SALib {s}"
        );
        assert!((s1 - analytic).abs() < 0.03, "{o}: analytic S1 {analytic}");
    }
}

/// The confidence half-widths: both sides draw half-length windows of the same outputs at
/// random starts, each with its own generator, so they agree only statistically; the spread of
/// the windows' indices is one quantity, estimated from 4000 draws on either side (a relative
/// standard error of about 1 % each). The outputs carry noise: without it every window of an
/// eFAST curve is a circular shift of the same period and gives the same indices, and both
/// report a half-width of about 1e-15.
#[test]
fn the_confidence_half_widths_agree_with_salib_s_on_noisy_outputs() {
    for (o, s) in ishigami(1.0, 4000) {
        for (ours, theirs) in [("s1_conf", "S1_conf"), ("st_conf", "ST_conf")] {
            let (a, b) = (o[ours].as_f64().unwrap(), s[theirs].as_f64().unwrap());
            assert!(
                b > 1e-3 && (a / b - 1.0).abs() < 0.1,
                "{ours} {a} vs SALib's {b}: {o} {s}"
            );
        }
    }
}

#[test]
fn an_unknown_distribution_is_refused_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("p.toml");
    std::fs::write(&params, PARAMS.replacen("uniform", "weibull", 1)).unwrap();
    let out = Command::new(hilrig_bin())
        .args(["efast", "sample", "--params"])
        .arg(&params)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown distribution 'weibull'") && err.contains("p.toml"),
        "{err}"
    );
}

/// `hilrig coverage` on a hand-made case: of four validation samples one shares a cell with a
/// parameterization sample; it alone is listed, and the exit code says so (1).
#[test]
fn coverage_lists_the_one_validation_sample_in_a_parameterization_cell() {
    let dir = tempfile::tempdir().unwrap();
    let w = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let params = w(
        "p.toml",
        "[[parameter]]\nname = \"speed\"\ndistribution = \"uniform\"\nlow = 0.0\nhigh = 10.0\n\
         [[parameter]]\nname = \"distance\"\ndistribution = \"uniform\"\nlow = 0.0\nhigh = 50.0\n",
    );
    let par = w("par.csv", "speed,distance\n1.0,5.0\n4.2,27.0\n9.0,35.0\n");
    let val = w(
        "val.csv",
        "speed,distance\n3.9,5.0\n5.5,23.0\n10.0,50.0\n7.0,31.0\n",
    );
    let json = dir.path().join("c.json");
    let out = Command::new(hilrig_bin())
        .args(["coverage", "--parts", "5", "--params"])
        .arg(&params)
        .arg(&par)
        .arg(&val)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let shared = v["shared"].as_array().unwrap();
    assert_eq!(shared.len(), 1, "{v}");
    // Rows counted from 1 in the JSON as in the text: the second data row of each file.
    assert_eq!(shared[0]["validation_row"], 2);
    assert_eq!(shared[0]["parameterization_rows"], serde_json::json!([2]));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("validation row 2 shares cell") && text.contains("parameterization rows [2]"),
        "{text}"
    );
    // Without the shared sample, nothing is listed and the exit code is 0.
    let val = w("val2.csv", "speed,distance\n3.9,5.0\n10.0,50.0\n7.0,31.0\n");
    let out = Command::new(hilrig_bin())
        .args(["coverage", "--parts", "5", "--params"])
        .arg(&params)
        .arg(&par)
        .arg(&val)
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
}

/// The arguments as `hilrig_ok` takes them.
fn args(a: &[std::ffi::OsString]) -> Vec<&std::ffi::OsStr> {
    a.iter().map(std::ffi::OsString::as_os_str).collect()
}

/// A scenario file with the fixture's files named absolutely, and the given metric and knobs.
fn scenario(dir: &std::path::Path, metric: &str, knobs: &[(&str, &str)]) -> std::path::PathBuf {
    scenario_on(
        dir,
        &common::fixture("efast").join("drive.toml"),
        metric,
        knobs,
    )
}

/// [`scenario`] on another drive file.
fn scenario_on(
    dir: &std::path::Path,
    drive: &std::path::Path,
    metric: &str,
    knobs: &[(&str, &str)],
) -> std::path::PathBuf {
    let fx = common::fixture("efast");
    let park = common::fixture("parking");
    let mut s = format!(
        "scene = {:?}\ndrive = {:?}\nreality = {:?}\nmodel = {:?}\nmetric = {metric:?}\ncell_m = 0.3\n",
        park.join("scene.toml"),
        drive,
        fx.join("reality.toml"),
        park.join("idealized.toml"),
    );
    for (p, set) in knobs {
        s.push_str(&format!("[[knob]]\nparameter = {p:?}\nset = {set:?}\n"));
    }
    let path = dir.join("scenario.toml");
    std::fs::write(&path, s).unwrap();
    path
}

/// `efast run` makes one drive per parameter set and ranks the parameters. The physics it must
/// find: rain's two-way extinction takes the far returns out of the sensor's scans while the
/// idealized model keeps them, so the share of returns only the model has grows with the
/// extinction; the ego's speed on a 6 m drive through a static scene changes little of what is
/// seen. A ranking by how `synth` numbers its samples, or a stub, would not put rain first with
/// most of the variance.
#[test]
fn efast_run_ranks_rain_extinction_above_ego_speed() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("p.toml");
    std::fs::write(
        &params,
        "[[parameter]]\nname = \"ego_speed\"\ndistribution = \"uniform\"\nlow = 1.0\nhigh = 5.0\n\
         [[parameter]]\nname = \"rain\"\ndistribution = \"uniform\"\nlow = 0.0\nhigh = 0.08\n",
    )
    .unwrap();
    // The fixture's aisle, 6 m of it instead of 10 (the design's 68 drives are most of the
    // test suite's longest test): rain still takes the far returns out.
    let drive = dir.path().join("drive.toml");
    std::fs::write(
        &drive,
        std::fs::read_to_string(common::fixture("efast").join("drive.toml"))
            .unwrap()
            .replace(
                "waypoints = [[-16.0, 0.0], [-6.0, 0.0]]",
                "waypoints = [[-16.0, 0.0], [-10.0, 0.0]]",
            )
            .replace(
                "rig = \"../../rigs/demo.toml\"",
                &format!("rig = {:?}", common::demo_rig().display().to_string()),
            ),
    )
    .unwrap();
    let sc = scenario_on(
        dir.path(),
        &drive,
        "only_sim_share",
        &[
            ("ego_speed", "drive.path.cruise_speed_mps"),
            ("rain", "reality.effect[weather].extinction_per_m"),
        ],
    );
    let out = dir.path().join("out");
    let design = |command: &str, out: &std::path::Path| -> Vec<std::ffi::OsString> {
        let mut a: Vec<std::ffi::OsString> =
            vec!["efast".into(), command.into(), "--params".into()];
        a.push(params.clone().into());
        a.push("--scenario".into());
        a.push(sc.clone().into());
        for x in ["-N", "17", "-M", "2", "--seed", "3", "-o"] {
            a.push(x.into());
        }
        a.push(out.into());
        a
    };
    let run = design("run", &out);
    let o = common::hilrig_ok(&args(&run));
    let text = String::from_utf8_lossy(&o.stdout);
    let idx: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("indices.json")).unwrap()).unwrap();
    let get = |name: &str, k: &str| {
        idx.as_array()
            .unwrap()
            .iter()
            .find(|i| i["name"] == name)
            .unwrap()[k]
            .as_f64()
            .unwrap()
    };
    assert!(get("rain", "s1") > 0.6, "{text}");
    assert!(get("rain", "st") > get("ego_speed", "st") + 0.3, "{text}");
    assert!(get("ego_speed", "s1") < 0.2, "{text}");
    // 34 drives, one metric each, in the samples' order; the work directory is gone.
    let outputs = std::fs::read_to_string(out.join("outputs.csv")).unwrap();
    assert_eq!(outputs.lines().count(), 35);
    assert_eq!(
        std::fs::read_to_string(out.join("samples.csv"))
            .unwrap()
            .lines()
            .count(),
        35
    );
    assert!(!out.join("work").exists());
    // The share really grows with the extinction: the driest and wettest drives differ.
    let x: Vec<Vec<f64>> = std::fs::read_to_string(out.join("samples.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let y: Vec<f64> = outputs
        .lines()
        .skip(1)
        .map(|l| l.parse().unwrap())
        .collect();
    let (dry, wet) = (0..x.len()).fold((0, 0), |(d, w), i| {
        (
            if x[i][1] < x[d][1] { i } else { d },
            if x[i][1] > x[w][1] { i } else { w },
        )
    });
    assert!(y[wet] > y[dry] + 0.05, "dry {} wet {}", y[dry], y[wet]);

    // The drives are tasks of a plan (34 sets, 4 to a task: 9, and the analysis). A second run
    // finds every task's outputs up to date and makes no drive again.
    let files = |dir: &std::path::Path| -> Vec<Vec<u8>> {
        ["samples.csv", "outputs.csv", "indices.json"]
            .iter()
            .map(|f| std::fs::read(dir.join(f)).unwrap())
            .collect()
    };
    let first = files(&out);
    let again = common::hilrig_ok(&args(&run));
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(err.contains("0 tasks ran, 10 up to date"), "{err}");
    assert!(files(&out) == first);

    // The same design on a Ray cluster (PyPI `ray`: a head and two worker nodes), from its
    // plan, gives the same files byte for byte.
    let on_ray = dir.path().join("out-ray");
    let mut plan_args = design("plan", &on_ray);
    plan_args.push("--json".into());
    let plan = common::hilrig_ok(&args(&plan_args));
    let plan_path = dir.path().join("plan.json");
    std::fs::write(&plan_path, &plan.stdout).unwrap();
    let cluster = common::ray::Cluster::start();
    let exec = Command::new(common::python())
        .args(["-m", "hilrig_ray"])
        .arg(&plan_path)
        .args(["--address", &cluster.address, "--hilrig"])
        .arg(hilrig_bin())
        .current_dir(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("python"))
        .env("RAY_USAGE_STATS_ENABLED", "0")
        .output()
        .unwrap();
    drop(cluster);
    let stdout = String::from_utf8_lossy(&exec.stdout);
    assert!(
        exec.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&exec.stderr)
    );
    let summary: Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    assert_eq!(summary["counts"]["ran"], 10, "{summary}");
    assert!(
        files(&on_ray) == first,
        "Ray's files differ from the local executor's"
    );
}

/// An evaluation task depends on everything its drives read, not only the scenario's four
/// documents: the scene's actor trajectory, the drive's rig and the rig's DBC. Those are its
/// plan inputs, whose hashes decide whether a rerun may skip it (a changed mesh or DBC must
/// make the drives again).
#[test]
fn an_evaluation_task_depends_on_the_files_the_scenario_s_documents_name() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("p.toml");
    std::fs::write(
        &params,
        "[[parameter]]\nname = \"ego_speed\"\ndistribution = \"uniform\"\nlow = 1.0\nhigh = 5.0\n",
    )
    .unwrap();
    let sc = scenario(
        dir.path(),
        "only_sim_share",
        &[("ego_speed", "drive.path.cruise_speed_mps")],
    );
    let mut a: Vec<std::ffi::OsString> = vec!["efast".into(), "plan".into(), "--params".into()];
    a.push(params.into());
    a.push("--scenario".into());
    a.push(sc.into());
    for x in ["-N", "17", "-M", "2", "--json", "-o"] {
        a.push(x.into());
    }
    a.push(dir.path().join("out").into());
    let plan: Value = serde_json::from_slice(&common::hilrig_ok(&args(&a)).stdout).unwrap();
    let canonical = |p: std::path::PathBuf| std::fs::canonicalize(p).unwrap();
    let wanted = [
        canonical(common::fixture("parking").join("pedestrian.csv")),
        canonical(common::fixture("parking").join("scene.toml")),
        canonical(common::demo_rig()),
        canonical(common::demo_rig().parent().unwrap().join("hilrig-ego.dbc")),
    ];
    let evaluations: Vec<&Value> = plan["tasks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["args"][1] == "evaluate")
        .collect();
    assert!(!evaluations.is_empty(), "{plan}");
    for t in evaluations {
        let inputs: Vec<std::path::PathBuf> = t["inputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|i| std::path::PathBuf::from(i.as_str().unwrap()))
            .collect();
        for w in &wanted {
            assert!(inputs.contains(w), "{} not among {inputs:?}", w.display());
        }
    }

    // A scenario reached through a link names its documents from its own folder, as the
    // tasks (given the file's real path) read them: the plan checks and hashes those.
    let real = dir.path().join("real");
    std::fs::create_dir(&real).unwrap();
    let drive = std::fs::read_to_string(common::fixture("efast").join("drive.toml")).unwrap();
    assert!(drive.contains("rig = \"../../rigs/demo.toml\""), "{drive}");
    std::fs::write(
        real.join("drive.toml"),
        drive.replace(
            "rig = \"../../rigs/demo.toml\"",
            &format!("rig = {:?}", common::demo_rig()),
        ),
    )
    .unwrap();
    let own = std::fs::read_to_string(dir.path().join("scenario.toml")).unwrap();
    let drive_line = own.lines().find(|l| l.starts_with("drive = ")).unwrap();
    std::fs::write(
        real.join("scenario.toml"),
        own.replace(drive_line, "drive = \"drive.toml\""),
    )
    .unwrap();
    let linked = dir.path().join("linked");
    std::fs::create_dir(&linked).unwrap();
    std::os::unix::fs::symlink(real.join("scenario.toml"), linked.join("scenario.toml")).unwrap();
    let scenario_at = a.iter().position(|x| x == "--scenario").unwrap() + 1;
    a[scenario_at] = linked.join("scenario.toml").into();
    let plan: Value = serde_json::from_slice(&common::hilrig_ok(&args(&a)).stdout).unwrap();
    let real_drive = canonical(real.join("drive.toml"));
    for t in plan["tasks"].as_array().unwrap() {
        if t["args"][1] == "evaluate" {
            let inputs = t["inputs"].as_array().unwrap();
            assert!(
                inputs.iter().any(|i| i.as_str() == real_drive.to_str()),
                "{} not among {inputs:?}",
                real_drive.display()
            );
        }
    }

    // A design writes to a folder: a bucket is refused (not taken for a folder named `s3:`).
    let last = a.len() - 1;
    a[last] = "s3://bucket/design".into();
    let o = Command::new(hilrig_bin()).args(&a).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("not to object storage"), "{err}");
    assert!(!std::path::Path::new("s3:").exists());
}

/// A knob for a parameter the file lacks, a misspelt key, a metric compare does not have: exit
/// 2 with the reason, before any drive, and no output directory.
#[test]
fn efast_run_refuses_bad_scenarios_before_any_drive() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("p.toml");
    std::fs::write(
        &params,
        "[[parameter]]\nname = \"rain\"\ndistribution = \"uniform\"\nlow = 0.0\nhigh = 0.08\n",
    )
    .unwrap();
    let good = [("rain", "reality.effect[weather].extinction_per_m")];
    for (metric, knobs, want) in [
        (
            "ocr_maen",
            &good[..],
            "metric 'ocr_maen' is not one of compare's",
        ),
        (
            "ocr_mean",
            &[("rain", "reality.effect[wether].extinction_per_m")][..],
            "no table named 'wether'",
        ),
        (
            "ocr_mean",
            &[("rain", "drive.path.cruise_sped_mps")][..],
            "unknown field `cruise_sped_mps`",
        ),
        (
            "ocr_mean",
            &[
                ("rain", "reality.effect[weather].extinction_per_m"),
                ("speed", "drive.path.cruise_speed_mps"),
            ][..],
            "knob for 'speed', which the parameter file does not have",
        ),
        ("ocr_mean", &[][..], "no knob for parameter 'rain'"),
    ] {
        let sc = scenario(dir.path(), metric, knobs);
        let out = dir.path().join("out");
        let o = Command::new(hilrig_bin())
            .args(["efast", "run", "-N", "17", "-M", "2", "--params"])
            .arg(&params)
            .arg("--scenario")
            .arg(&sc)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{metric} {knobs:?}: {err}");
        assert!(err.contains(want), "{metric} {knobs:?}: {err}");
        assert!(!out.exists(), "{metric} {knobs:?}");
    }
}

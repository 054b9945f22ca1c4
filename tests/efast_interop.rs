//! `hilrig efast` against SALib (PyPI): on the same Ishigami samples (a = 7, b = 0.1, N = 1000,
//! M = 4, sampled by hilrig), SALib's `fast.analyze` and `hilrig efast analyze` give the same S1
//! and ST to 1e-6, and S1 is within 0.03 of the analytic 0.3139, 0.4424, 0. A parameter file
//! with an unknown distribution is refused with exit 2.

mod common;

use common::{hilrig_bin, interop_script};
use serde_json::Value;
use std::process::Command;

const PARAMS: &str = "[[parameter]]\nname = \"x1\"\ndistribution = \"uniform\"\nlow = -3.141592653589793\nhigh = 3.141592653589793\n\
[[parameter]]\nname = \"x2\"\ndistribution = \"uniform\"\nlow = -3.141592653589793\nhigh = 3.141592653589793\n\
[[parameter]]\nname = \"x3\"\ndistribution = \"uniform\"\nlow = -3.141592653589793\nhigh = 3.141592653589793\n";

#[test]
fn ishigami_indices_equal_salib_s_on_the_same_samples() {
    let dir = tempfile::tempdir().unwrap();
    let params = dir.path().join("ishigami.toml");
    std::fs::write(&params, PARAMS).unwrap();
    let out = Command::new(hilrig_bin())
        .args(["efast", "sample", "--params"])
        .arg(&params)
        .args(["-N", "1000", "-M", "4", "--seed", "5"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let samples = dir.path().join("x.csv");
    std::fs::write(&samples, &text).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x1,x2,x3"));
    let y: Vec<f64> = lines
        .map(|l| {
            let x: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            x[0].sin() + 7.0 * x[1].sin().powi(2) + 0.1 * x[2].powi(4) * x[0].sin()
        })
        .collect();
    assert_eq!(y.len(), 3000);
    let outputs = dir.path().join("y.csv");
    let body: Vec<String> = y.iter().map(|v| format!("{v:?}")).collect();
    std::fs::write(&outputs, format!("y\n{}\n", body.join("\n"))).unwrap();
    let json = dir.path().join("si.json");
    let out = Command::new(hilrig_bin())
        .args(["efast", "analyze", "--params"])
        .arg(&params)
        .arg(&samples)
        .arg(&outputs)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ours: Vec<Value> = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let stdout = interop_script(
        "salib_fast.py",
        &[outputs.as_os_str(), "x1,x2,x3".as_ref(), "4".as_ref()],
    );
    let salib: Vec<Value> = serde_json::from_slice(&stdout).unwrap();
    for ((o, s), analytic) in ours.iter().zip(&salib).zip([0.3139, 0.4424, 0.0]) {
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
    assert_eq!(shared[0]["validation_row"], 1);
    assert_eq!(shared[0]["parameterization_rows"], serde_json::json!([1]));
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

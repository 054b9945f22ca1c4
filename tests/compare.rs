//! `hilrig compare` on the parking fixtures: a run against itself scores perfectly, against its
//! re-simulation it gives the per-scan series, the calibration curve and the Fig. 5 trend; runs
//! and simulations that do not belong together, and cells that are bad or too small, are
//! refused with exit 2 and nothing written.

use crate::common;

use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Records fixture repetition `rep` and re-simulates it with the idealized model: the run, the
/// simulation and the scene.
fn run_and_sim(dir: &Path, rep: u32) -> (PathBuf, PathBuf, PathBuf) {
    let (run, sims) = record_and_resim(dir, rep, &["idealized"]);
    let scene = fixture(&format!("parking/rep-{rep:02}/scene.toml"));
    (run, sims[0].clone(), scene)
}

fn compare(run: &Path, sim: &Path, scene: &Path, extra: &[&str], json: &Path) -> Output {
    Command::new(hilrig_bin())
        .arg("compare")
        .arg(run)
        .arg(sim)
        .arg("--scene")
        .arg(scene)
        .arg("--json")
        .arg(json)
        .args(extra)
        .output()
        .unwrap()
}

fn read(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn a_run_against_itself_and_against_its_re_simulation() {
    let dir = tempfile::tempdir().unwrap();
    let (run, sim, scene) = run_and_sim(dir.path(), 1);

    // Against itself: every cell, point and firing agrees.
    let json = dir.path().join("self.json");
    let out = compare(
        &run,
        &run,
        &scene,
        &["--cell", "0.1", "--allow-small-cell", "-K", "3"],
        &json,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = read(&json);
    let s = &v["summary"];
    assert_eq!(s["ocr_mean"], 1.0);
    assert_eq!(s["iou_mean"], 1.0);
    assert_eq!(s["chamfer_mean_m"], 0.0);
    assert_eq!(s["range_diff_rms_m"], 0.0);
    assert_eq!(s["only_real_share"], 0.0);
    // K = 3: the first two scans have no grid.
    let scans = v["scans"].as_array().unwrap();
    assert!(
        scans[0]["grid"].is_null() && scans[1]["grid"].is_null() && !scans[2]["grid"].is_null()
    );

    // Against the idealized re-simulation, at the admissible cell.
    let json = dir.path().join("sim.json");
    let csv = dir.path().join("sim.csv");
    let out = compare(&run, &sim, &scene, &["--csv", csv.to_str().unwrap()], &json);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("Fig. 5"), "{stdout}");
    let v = read(&json);
    let s = &v["summary"];
    let ocr = s["ocr_mean"].as_f64().unwrap();
    assert!(ocr > 0.5 && ocr < 1.0, "OCR {ocr}");
    // The model that made the data (the truth model: noise, dropout, beam divergence, the
    // detection threshold) must agree with it firing by firing better than the idealized one,
    // re-simulated along the same poses: fewer returns only in the simulation (the idealized
    // model returns where the sensor's threshold let nothing through) and a smaller range
    // residual. (Not OCR: it is the share of measured cells the simulation covers, which a
    // model that returns more points raises; on a street with far facades the idealized model
    // scores the higher OCR.)
    let truth_sim = dir.path().join("truth1.mcap");
    resim(&run, &scene, &fixture("parking/truth.toml"), &truth_sim);
    let truth_json = dir.path().join("truth.json");
    let out = compare(&run, &truth_sim, &scene, &[], &truth_json);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let t = read(&truth_json)["summary"].clone();
    let num = |v: &Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    for k in ["only_sim_share", "range_diff_rms_m"] {
        assert!(
            num(&t, k) < num(s, k),
            "{k}: truth model {}, idealized {}",
            num(&t, k),
            num(s, k)
        );
    }
    assert_eq!(v["cell_m"], v["admissible_cell_m"]);
    assert_eq!(s["scans"].as_u64().unwrap() as usize, scans.len());
    assert_eq!(s["unpaired_run_scans"], 0);
    // The calibration curve: every size from 5 cm to 2 m, the admissible ones marked, OCR
    // higher at 2 m than at 5 cm.
    let curve = v["calibration"].as_array().unwrap();
    let at = |c: f64| {
        curve
            .iter()
            .find(|p| (p["cell_m"].as_f64().unwrap() - c).abs() < 1e-9)
            .unwrap()
    };
    let ocr_at = |c: f64| {
        at(c)["ocr_mean"]
            .as_f64()
            .expect("an OCR at every cell size")
    };
    assert!(
        ocr_at(2.0) > ocr_at(0.05),
        "{} {}",
        ocr_at(2.0),
        ocr_at(0.05)
    );
    let admissible = v["admissible_cell_m"].as_f64().unwrap();
    for p in curve {
        assert_eq!(
            p["admissible"].as_bool().unwrap(),
            p["cell_m"].as_f64().unwrap() >= admissible - 1e-9
        );
    }
    // The Fig. 5 columns: one CSV row per scan; objects in view and their distance where any.
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text.lines().count(), scans.len() + 1);
    assert!(text.starts_with("t_s,stamp_ns,ego_speed_mps,objects_in_view,mean_distance_m,ocr,"));
    // Fig. 5: OCR falls as the objects get farther (fewer points on them, each cell's
    // occupancy less certain); ρ must be there, inside its interval, and negative.
    let r = &s["ocr_vs_distance"];
    let f = |k: &str| {
        r[k].as_f64()
            .unwrap_or_else(|| panic!("ocr_vs_distance.{k}: {r}"))
    };
    let (rho, low, high) = (f("rho"), f("low"), f("high"));
    assert!(low <= rho && rho <= high, "{low} {rho} {high}");
    assert!(rho < 0.0, "OCR against distance: ρ = {rho} [{low}, {high}]");

    // The region and the ground change what they should: keeping the ground adds points to
    // every scan, the objects' region keeps a part of them, one object a part of that; in the
    // sensor frame the scans are the same points, so the run against itself still scores 1.
    let points = |extra: &[&str]| -> Vec<u64> {
        let json = dir.path().join("roi.json");
        let out = compare(&run, &sim, &scene, extra, &json);
        assert!(
            out.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        read(&json)["scans"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["real_points"].as_u64().unwrap())
            .collect()
    };
    let all = points(&[]);
    let ground = points(&["--keep-ground"]);
    let objects = points(&["--roi", "objects"]);
    let one = points(&["--roi", "object:wall"]);
    let total = |v: &[u64]| v.iter().sum::<u64>();
    assert!(
        ground.iter().zip(&all).all(|(g, a)| g > a),
        "ground adds points"
    );
    assert!(objects.iter().zip(&all).all(|(o, a)| o <= a) && total(&objects) < total(&all));
    assert!(
        one.iter().zip(&objects).all(|(x, o)| x <= o)
            && total(&one) > 0
            && total(&one) < total(&objects)
    );
    let json = dir.path().join("sensor.json");
    let out = compare(
        &run,
        &run,
        &scene,
        &[
            "--sensor-frame",
            "--keep-ground",
            "--cell",
            "0.1",
            "--allow-small-cell",
        ],
        &json,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = read(&json);
    assert_eq!(
        (v["frame"].as_str(), v["summary"]["ocr_mean"].as_f64()),
        (Some("sensor"), Some(1.0))
    );
}

#[test]
fn inputs_that_do_not_belong_together_and_bad_cells_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (run1, _, scene) = run_and_sim(dir.path(), 1);
    let (_, sim2, _) = run_and_sim(dir.path(), 2);
    let json = dir.path().join("out.json");
    let cases: Vec<(PathBuf, Vec<&str>, &str)> = vec![
        (sim2.clone(), vec![], "share no scan"),
        (run1.clone(), vec!["--cell", "0"], "positive finite"),
        (run1.clone(), vec!["--cell", "NaN"], "positive finite"),
        (run1.clone(), vec!["--cell", "0.1"], "--allow-small-cell"),
        (
            run1.clone(),
            vec!["--cell", "1e-9", "--allow-small-cell"],
            "the smallest cell for this drive is",
        ),
        (run1.clone(), vec!["-K", "0"], "at least one scan"),
        (
            run1.clone(),
            vec!["--grid-phases", "0"],
            "at least one grid",
        ),
        (
            run1.clone(),
            vec!["--roi", "object:unicorn"],
            "no object of that name",
        ),
    ];
    // A simulation cut in the middle: compared as far as it can be read, and said so.
    let bytes = std::fs::read(&sim2).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let run2 = dir.path().join("run2.mcap");
    let scene2 = fixture("parking/rep-02/scene.toml");
    let out = compare(&run2, &cut, &scene2, &[], &json);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains("warning:") && err.contains("cut.mcap: read up to damage"),
        "{err}"
    );
    let v = read(&json);
    assert_eq!(v["damage"].as_array().unwrap().len(), 1);
    assert!(v["summary"]["unpaired_run_scans"].as_u64().unwrap() > 0);
    std::fs::remove_file(&json).unwrap();
    for (sim, extra, says) in cases {
        let out = compare(&run1, &sim, &scene, &extra, &json);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(says), "{extra:?}: {err}");
        assert!(!json.exists(), "{extra:?}: wrote {}", json.display());
    }
}

/// The residuals and the only-real share on pairs where they are known in closed form: the same
/// run re-simulated with the idealized model and with it plus a range bias `b` (every simulated
/// range `b` farther, nothing else changed) or plus a random dropout `p`. On the same firings,
/// the mean residual (simulated minus measured) moves by exactly `b`, the mean square to
/// `rms² + 2 b mean + b²`; a dropout leaves a share `p` of the returns both had to the
/// measurement alone: `only_real(p) = only_real + p (1 - only_real)` within the binomial noise.
/// A sign error in the residual, a pairing by the wrong firing or a share over the wrong total
/// fails one of them.
#[test]
fn residuals_and_shares_move_as_a_known_bias_and_dropout_say() {
    let dir = tempfile::tempdir().unwrap();
    let (run, sim, scene) = run_and_sim(dir.path(), 1);
    let resim_with = |name: &str, effect: &str| -> PathBuf {
        let model = dir.path().join(format!("{name}.toml"));
        std::fs::write(&model, format!("name = \"{name}\"\n[[effect]]\n{effect}\n")).unwrap();
        let out = dir.path().join(format!("{name}.mcap"));
        resim(&run, &scene, &model, &out);
        out
    };
    let summary = |sim: &Path| -> Value {
        let json = dir.path().join("s.json");
        let out = compare(
            &run,
            sim,
            &scene,
            &["--no-point-metrics", "--curve-every", "0"],
            &json,
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        read(&json)["summary"].clone()
    };
    let num = |v: &Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("{k}: {v}"));
    let ideal = summary(&sim);
    let (m0, r0) = (
        num(&ideal, "range_diff_mean_m"),
        num(&ideal, "range_diff_rms_m"),
    );

    // A bias of 50 range quanta (VLP-16: 2 mm), so that quantization shifts by whole counts.
    let b = 0.1;
    let biased = summary(&resim_with("biased", "name = \"range_bias\"\nbias_m = 0.1"));
    let (m1, r1) = (
        num(&biased, "range_diff_mean_m"),
        num(&biased, "range_diff_rms_m"),
    );
    // Returns that cross the region's border by the shift change the set a little: 1 mm.
    assert!((m1 - (m0 + b)).abs() < 1e-3, "mean {m0} -> {m1}, bias {b}");
    let expect = (r0 * r0 + 2.0 * b * m0 + b * b).sqrt();
    assert!(
        (r1 - expect).abs() < 2e-3,
        "rms {r0} -> {r1}, expected {expect}"
    );
    assert!(
        (num(&biased, "only_real_share") - num(&ideal, "only_real_share")).abs() < 2e-3,
        "a bias moves points, it does not lose them"
    );

    let p = 0.2;
    let dropped = summary(&resim_with(
        "dropout",
        "name = \"random_dropout\"\nprobability = 0.2",
    ));
    let (o0, o1) = (
        num(&ideal, "only_real_share"),
        num(&dropped, "only_real_share"),
    );
    let expect = o0 + p * (1.0 - o0);
    // Binomial: at least 10^5 returns in the run, sd below 0.0013; allow 4 sd.
    assert!(
        (o1 - expect).abs() < 0.005,
        "only-real share {o0} -> {o1}, expected {expect}"
    );
    // Dropout takes whole firings: what remains is paired as before.
    assert!((num(&dropped, "range_diff_mean_m") - m0).abs() < 1e-3);
}

//! `hilrig validate` on the five parking repetitions (Rosenberger et al. 2019, Fig. 7): the
//! captures against their re-simulations with the idealized model and with the truth model
//! (which has the effects the idealized one lacks), per phase. The truth model must score better:
//! no more red cells, fewer than the idealized model, and a smaller area validation metric in
//! every cell. A simulation of another drive fails the measurement block: not evaluable, exit 2.

use crate::common;

use common::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn validate(
    reals: &[PathBuf],
    sims: &[PathBuf],
    phases: &Path,
    json: &Path,
) -> (i32, Option<Value>) {
    let mut cmd = Command::new(hilrig_bin());
    cmd.arg("validate");
    for r in reals {
        cmd.arg("--real").arg(r);
    }
    for s in sims {
        cmd.arg("--sim").arg(s);
    }
    let out = cmd
        .arg("--phases")
        .arg(phases)
        .arg("--json")
        .arg(json)
        .output()
        .unwrap();
    println!("{}", String::from_utf8_lossy(&out.stdout));
    let v = std::fs::read_to_string(json)
        .ok()
        .map(|t| serde_json::from_str(&t).unwrap());
    let _ = std::fs::remove_file(json);
    (out.status.code().unwrap_or(-1), v)
}

#[test]
fn the_truth_model_scores_better_than_the_idealized_one_in_every_phase() {
    let dir = tempfile::tempdir().unwrap();
    let phases = dir.path().join("phases.toml");
    std::fs::write(
        &phases,
        "[[phase]]\nname = \"approach\"\nfrom_s = 0.0\nto_s = 5.0\n\
         [[phase]]\nname = \"yield\"\nfrom_s = 5.0\nto_s = 11.0\n\
         [[phase]]\nname = \"park\"\nfrom_s = 11.0\nto_s = 20.0\n",
    )
    .unwrap();
    let (mut reals, mut ideal, mut truth) = (Vec::new(), Vec::new(), Vec::new());
    for rep in 1..=5 {
        let (r, sims) = record_and_resim(dir.path(), rep, &["idealized", "truth"]);
        reals.push(r);
        ideal.push(sims[0].clone());
        truth.push(sims[1].clone());
    }
    let json = dir.path().join("v.json");
    let (code_i, vi) = validate(&reals, &ideal, &phases, &json);
    let (code_t, vt) = validate(&reals, &truth, &phases, &json);
    let (vi, vt) = (vi.unwrap(), vt.unwrap());
    assert_eq!(vi["measurement_pass"], true);
    assert!(
        vi["scenario_problems"].as_array().unwrap().is_empty(),
        "{}",
        vi["scenario_problems"]
    );
    let cells = |v: &Value| v["cells"].as_array().unwrap().clone();
    let (ci, ct) = (cells(&vi), cells(&vt));
    assert_eq!(ci.len(), 3 * 4, "three phases, four metrics");
    let count = |c: &[Value], l: &str| c.iter().filter(|x| x["light"] == l).count();
    assert!(
        count(&ct, "red") < count(&ci, "red"),
        "red: truth {} idealized {}",
        count(&ct, "red"),
        count(&ci, "red")
    );
    assert!(
        count(&ct, "green") + count(&ct, "yellow") > count(&ci, "green") + count(&ci, "yellow")
    );
    for (a, b) in ci.iter().zip(&ct) {
        assert_eq!((&a["sample"], &a["metric"]), (&b["sample"], &b["metric"]));
        let avm = |c: &Value| c["avm"].as_f64().unwrap_or_else(|| panic!("no AVM in {c}"));
        assert!(
            avm(b) < avm(a),
            "{}/{}: truth AVM {} idealized {}",
            a["sample"],
            a["metric"],
            b["avm"],
            a["avm"]
        );
    }
    assert_eq!(vi["verdict"], "invalid");
    assert_eq!(code_i, 1);
    // The generating model must not be judged invalid. With five values a side drawn from one
    // distribution, the two intervals are disjoint (red) with probability 2 / C(10, 5) = 1/126
    // per cell, and the simulated one lies inside the measured one (green) only with
    // probability (5/10)(4/9) = 2/9: a correct implementation gives no red cell and, over twelve
    // cells, almost surely a yellow one, so the verdict is "partly valid" (exit 1).
    assert_eq!(
        count(&ct, "red"),
        0,
        "the truth model has red cells: {ct:?}"
    );
    assert_eq!(vt["verdict"], "partly_valid", "{}", vt["verdict"]);
    assert_eq!(code_t, 1);

    // A simulation that re-simulates none of the real runs: the measurement block fails.
    let (code, v) = validate(&reals[1..], &ideal[..1], &phases, &json);
    let v = v.unwrap();
    assert_eq!(v["measurement_pass"], false);
    assert_eq!(v["verdict"], "not_evaluable");
    assert_eq!(code, 2);
}

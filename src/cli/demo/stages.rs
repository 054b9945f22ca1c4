//! The demo's stages, one table row each: the commands a stage runs and the line it prints
//! from their outputs, read through the types that wrote them.

use super::{arg, read_json, Inputs, Step};
use anyhow::{Context, Result};
use hilrig::metrics::report::Comparison;
use std::path::PathBuf;

/// What every stage knows: the inputs and where the outputs go.
pub(super) struct Demo {
    pub(super) inputs: Inputs,
    pub(super) out: PathBuf,
    pub(super) quick: bool,
}

/// The two models every run is re-simulated with.
const MODELS: [(&str, &str); 2] = [
    ("idealized", "idealized.toml"),
    ("truth", "truth-model.toml"),
];

impl Demo {
    fn rec(&self, rep: &str) -> PathBuf {
        self.out.join("rec").join(format!("{rep}.mcap"))
    }

    fn check_json(&self, rep: &str) -> PathBuf {
        self.out.join("check").join(format!("{rep}.json"))
    }

    fn sim(&self, model: &str, rep: &str) -> PathBuf {
        self.out.join("sim").join(model).join(format!("{rep}.mcap"))
    }

    /// A file of the parking fixture (a model, the phases).
    fn fixture(&self, file: &str) -> PathBuf {
        self.inputs.root.join(file)
    }

    /// The comparison of the first run, by name (`idealized`, `idealized-10cm`, `truth`).
    fn compare_json(&self, name: &str) -> PathBuf {
        let first = &self.inputs.reps[0];
        self.out
            .join("compare")
            .join(format!("{first}-{name}.json"))
    }

    fn validate_json(&self, model: &str) -> PathBuf {
        self.out.join("validate").join(format!("{model}.json"))
    }

    fn gap_dir(&self) -> PathBuf {
        self.out.join("gap")
    }

    pub(super) fn report(&self) -> PathBuf {
        self.out.join("report.html")
    }
}

/// A stage's line: its verdict, its key figure, and a note below it if any.
pub(super) struct Outcome {
    pub(super) verdict: &'static str,
    pub(super) figure: String,
    pub(super) note: Option<String>,
}

impl Outcome {
    fn new(verdict: &'static str, figure: String) -> Outcome {
        Outcome {
            verdict,
            figure,
            note: None,
        }
    }
}

/// One stage of the method: the batches of commands it runs (a batch after the one before it,
/// the commands of a batch two at a time) and its line, made from their outputs and exit
/// codes.
pub(super) struct Stage {
    pub(super) name: &'static str,
    pub(super) steps: fn(&Demo) -> Result<Vec<Vec<Step>>>,
    pub(super) outcome: fn(&Demo, &[i32]) -> Result<Outcome>,
}

/// The stages in the method's order (Rosenberger et al. 2019, Fig. 6): each reads what the
/// ones before wrote.
pub(super) const STAGES: [Stage; 7] = [
    Stage {
        name: "record",
        steps: record_steps,
        outcome: record_outcome,
    },
    Stage {
        name: "check",
        steps: check_steps,
        outcome: check_outcome,
    },
    Stage {
        name: "resim",
        steps: resim_steps,
        outcome: resim_outcome,
    },
    Stage {
        name: "compare",
        steps: compare_steps,
        outcome: compare_outcome,
    },
    Stage {
        name: "validate",
        steps: validate_steps,
        outcome: validate_outcome,
    },
    Stage {
        name: "gap",
        steps: gap_steps,
        outcome: gap_outcome,
    },
    Stage {
        name: "report",
        steps: report_steps,
        outcome: report_outcome,
    },
];

/// A command line from its words.
fn words(w: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<String> {
    w.iter()
        .map(|a| a.as_ref().to_string_lossy().into_owned())
        .collect()
}

/// Record the captures as they came off the vehicle, then list each recording.
fn record_steps(d: &Demo) -> Result<Vec<Vec<Step>>> {
    let reps = &d.inputs.reps;
    let record = reps
        .iter()
        .map(|rep| Step {
            log: format!("record-{rep}"),
            args: words(&[
                &"record",
                &"--rig",
                &d.inputs.rig(),
                &"--from",
                &d.inputs.capture(rep),
                &"-o",
                &d.rec(rep),
            ]),
            accept: &[],
        })
        .collect();
    let info = reps
        .iter()
        .map(|rep| Step {
            log: format!("info-{rep}"),
            args: words(&[
                &"info",
                &d.rec(rep),
                &"--json",
                &d.out.join("rec").join(format!("{rep}.info.json")),
            ]),
            accept: &[],
        })
        .collect();
    Ok(vec![record, info])
}

fn record_outcome(d: &Demo, _: &[i32]) -> Result<Outcome> {
    let reps = &d.inputs.reps;
    let bytes: u64 = reps
        .iter()
        .filter_map(|rep| std::fs::metadata(d.rec(rep)).ok())
        .map(|m| m.len())
        .sum();
    Ok(Outcome::new(
        "ok",
        format!(
            "{} capture(s) -> MCAP, {:.1} MB (lidar, GNSS, CAN, one clock)",
            reps.len(),
            bytes as f64 / 1e6
        ),
    ))
}

/// Check the reference data of every run (Rosenberger et al. 2019, §6); a failed check
/// (exit 1) is a result.
fn check_steps(d: &Demo) -> Result<Vec<Vec<Step>>> {
    Ok(vec![d
        .inputs
        .reps
        .iter()
        .map(|rep| Step {
            log: format!("check-{rep}"),
            args: words(&[
                &"check",
                &d.rec(rep),
                &"--scene",
                &d.inputs.scene(rep),
                &"--json",
                &d.check_json(rep),
            ]),
            accept: &[1],
        })
        .collect()])
}

fn check_outcome(d: &Demo, codes: &[i32]) -> Result<Outcome> {
    let reps = &d.inputs.reps;
    let checks: Vec<hilrig::reference::check::Report> = reps
        .iter()
        .map(|rep| read_json(&d.check_json(rep)))
        .collect::<Result<_>>()?;
    let cell = checks
        .iter()
        .map(|c| c.accuracy.grid_cell_m)
        .fold(0.0f64, f64::max);
    let ego = checks
        .iter()
        .map(|c| c.accuracy.ego_m)
        .fold(0.0f64, f64::max);
    let passed = codes.iter().filter(|&&c| c == 0).count();
    Ok(Outcome {
        verdict: if passed == reps.len() { "pass" } else { "FAIL" },
        figure: format!(
            "{passed}/{} runs pass; ego accuracy <= {ego:.3} m; admissible cell {cell:.2} m",
            reps.len()
        ),
        note: (passed != reps.len()).then(|| {
            format!(
                "a run failed its check: see {}",
                d.out.join("check").display()
            )
        }),
    })
}

/// Re-simulate every run with the idealized model and with the truth model.
fn resim_steps(d: &Demo) -> Result<Vec<Vec<Step>>> {
    let mut steps = Vec::new();
    for (name, file) in MODELS {
        for rep in &d.inputs.reps {
            steps.push(Step {
                log: format!("resim-{name}-{rep}"),
                args: words(&[
                    &"resim",
                    &d.rec(rep),
                    &"--scene",
                    &d.inputs.scene(rep),
                    &"--model",
                    &d.fixture(file),
                    &"-o",
                    &d.sim(name, rep),
                ]),
                accept: &[],
            });
        }
    }
    Ok(vec![steps])
}

fn resim_outcome(d: &Demo, _: &[i32]) -> Result<Outcome> {
    Ok(Outcome::new(
        "ok",
        format!(
            "{} runs x 2 models (idealized, truth) along the checked trajectories",
            d.inputs.reps.len()
        ),
    ))
}

/// Compare the first run with its re-simulations, at the admissible cell and, for the
/// idealized model, at the paper's 10 cm (Fig. 5).
fn compare_steps(d: &Demo) -> Result<Vec<Vec<Step>>> {
    let first = &d.inputs.reps[0];
    let steps = [
        ("idealized", "idealized", false),
        ("idealized-10cm", "idealized", true),
        ("truth", "truth", false),
    ]
    .into_iter()
    .map(|(name, model, small)| {
        let mut args = words(&[
            &"compare",
            &d.rec(first),
            &d.sim(model, first),
            &"--scene",
            &d.inputs.scene(first),
            &"--json",
            &d.compare_json(name),
        ]);
        if small {
            args.extend(words(&[&"--cell", &"0.1", &"--allow-small-cell"]));
        }
        Step {
            log: format!("compare-{first}-{name}"),
            args,
            accept: &[],
        }
    })
    .collect();
    Ok(vec![steps])
}

fn compare_outcome(d: &Demo, _: &[i32]) -> Result<Outcome> {
    let ci: Comparison = read_json(&d.compare_json("idealized"))?;
    let c10: Comparison = read_json(&d.compare_json("idealized-10cm"))?;
    let ct: Comparison = read_json(&d.compare_json("truth"))?;
    let nan = |x: Option<f64>| x.unwrap_or(f64::NAN);
    Ok(Outcome::new(
        "ok",
        format!(
            "OCR^K {:.2} idealized, {:.2} truth at {:.2} m; Spearman(OCR, distance) {:+.2} at 10 cm",
            nan(ci.summary.ocr_mean),
            nan(ct.summary.ocr_mean),
            ci.cell_m,
            nan(c10.summary.ocr_vs_distance.map(|r| r.rho))
        ),
    ))
}

/// Statistical validation over the repetitions, per phase (Rosenberger et al. 2019, §8);
/// a model that is not valid (exit 1) is a result.
fn validate_steps(d: &Demo) -> Result<Vec<Vec<Step>>> {
    let reps = &d.inputs.reps;
    let steps = MODELS
        .iter()
        .map(|(name, _)| {
            let mut args = vec!["validate".to_string()];
            for rep in reps {
                args.extend(words(&[&"--real", &d.rec(rep)]));
            }
            for rep in reps {
                args.extend(words(&[&"--sim", &d.sim(name, rep)]));
            }
            args.extend(words(&[
                &"--phases",
                &d.fixture("phases.toml"),
                &"--json",
                &d.validate_json(name),
            ]));
            Step {
                log: format!("validate-{name}"),
                args,
                accept: &[1],
            }
        })
        .collect();
    Ok(vec![steps])
}

fn validate_outcome(d: &Demo, _: &[i32]) -> Result<Outcome> {
    let mut figure = Vec::new();
    for (name, _) in MODELS {
        let v: hilrig::stats::repetitions::Validation = read_json(&d.validate_json(name))?;
        let [g, y, red, b] = hilrig::report::plots::lights(&v);
        figure.push(format!(
            "{name}: {g} green {y} yellow {red} red {b} black, {}",
            v.verdict.name()
        ));
    }
    Ok(Outcome::new("done", figure.join("; ")))
}

/// The gap workflow: the idealized model against the measurement. A study file, so that each
/// run keeps its own scene (each repetition has its own survey and its own pedestrian walk;
/// the shorthand would give them all the first one's): the first half of the runs fit, the
/// others validate.
fn gap_steps(d: &Demo) -> Result<Vec<Vec<Step>>> {
    let reps = &d.inputs.reps;
    let study = d.out.join("gap-study.toml");
    let fit = reps.len().div_ceil(2);
    let file = hilrig::gap::study::StudyFile {
        model: std::path::absolute(d.fixture("idealized.toml"))?,
        scene: None,
        rig: None,
        runs: reps
            .iter()
            .enumerate()
            .map(|(k, rep)| {
                Ok(hilrig::gap::study::RunEntry {
                    recording: std::path::absolute(d.rec(rep))?,
                    scene: Some(std::path::absolute(d.inputs.scene(rep))?),
                    role: if k < fit {
                        hilrig::gap::study::Role::Fit
                    } else {
                        hilrig::gap::study::Role::Validate
                    },
                })
            })
            .collect::<Result<_>>()?,
    };
    let text = format!(
        "# The demo's gap study: the first runs fit, the others validate.\n{}",
        file.to_toml()?
    );
    std::fs::write(&study, text).with_context(|| format!("cannot write {}", study.display()))?;
    // The demo knows what made its data: the fitted model is set beside it.
    let truth = std::path::absolute(d.fixture("truth-model.toml"))?;
    let mut args = words(&[
        &"gap",
        &study,
        &"-o",
        &d.gap_dir(),
        &"--reference-model",
        &truth,
    ]);
    if d.quick {
        args.extend(words(&[&"--firings", &"200000"]));
    }
    Ok(vec![vec![Step {
        log: "gap".into(),
        args,
        accept: &[],
    }]])
}

fn gap_outcome(d: &Demo, _: &[i32]) -> Result<Outcome> {
    let gap: hilrig::gap::report::GapReport = read_json(&d.gap_dir().join("gap.json"))?;
    let added: Vec<&str> = gap
        .rounds
        .iter()
        .filter_map(|r| r.chosen.map(|c| c.name()))
        .collect();
    let limits: Vec<String> = gap.limits.iter().map(|l| l.short()).collect();
    Ok(Outcome::new(
        "done",
        format!(
            "effects found: {}{}",
            if added.is_empty() {
                "none".to_string()
            } else {
                added.join(", ")
            },
            if limits.is_empty() {
                String::new()
            } else {
                format!(
                    "; not found, would have been seen at: {}",
                    limits.join(", ")
                )
            }
        ),
    ))
}

/// The report, from every JSON the stages wrote.
fn report_steps(d: &Demo) -> Result<Vec<Vec<Step>>> {
    Ok(vec![vec![Step {
        log: "report".into(),
        args: words(&[&"report", &d.out, &"-o", &d.report()]),
        accept: &[],
    }]])
}

fn report_outcome(d: &Demo, _: &[i32]) -> Result<Outcome> {
    Ok(Outcome::new("ok", arg(&d.report())))
}

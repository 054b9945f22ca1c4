//! `hilrig demo`: the whole method on the bundled parking-lot drives (Rosenberger et al. 2019,
//! Fig. 4), as a new user's first look and as a worked example of the commands.
//!
//! Each stage runs this same binary as a subprocess with the arguments an engineer would type,
//! so the demo shows nothing that the commands do not do on their own: the commands are written
//! to `DIR/commands.sh` (run it to reproduce every file), each stage's output to `DIR/logs/`,
//! and one line per stage with its key figure and verdict to the terminal. The last stage is
//! `hilrig report`, which builds the HTML report from the JSON the stages wrote.

use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::Instant;

use hilrig::metrics::report::Comparison;

#[derive(clap::Args)]
pub struct DemoArgs {
    /// Output directory (recordings, re-simulations, JSON, logs, report.html).
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
    /// Two repetitions instead of five (the fewest an interval, and so a traffic light, needs)
    /// and a smaller sample in the gap workflow: a first look in under a minute.
    #[arg(long)]
    quick: bool,
    /// The parking fixture (default: the one in this source tree).
    #[arg(long, hide = true)]
    fixtures: Option<PathBuf>,
}

/// The demo's inputs: the five repetitions of the parking drive and its models.
struct Inputs {
    root: PathBuf,
    reps: Vec<String>,
}

impl Inputs {
    fn locate(given: Option<&Path>, quick: bool) -> Result<Inputs> {
        let candidates = [
            given.map(Path::to_path_buf),
            Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/parking")),
            Some(PathBuf::from("fixtures/parking")),
        ];
        let root = candidates
            .into_iter()
            .flatten()
            .find(|p| p.join("rep-01/drive.pcapng.zst").is_file())
            .context("the parking fixture (fixtures/parking) is not here: run the demo from the hilrig source tree")?;
        let n = if quick { 2 } else { 5 };
        Ok(Inputs {
            reps: (1..=n).map(|i| format!("rep-{i:02}")).collect(),
            root,
        })
    }

    fn capture(&self, rep: &str) -> PathBuf {
        self.root.join(rep).join("drive.pcapng.zst")
    }

    fn scene(&self, rep: &str) -> PathBuf {
        self.root.join(rep).join("scene.toml")
    }

    fn rig(&self) -> PathBuf {
        self.root.join("../../rigs/demo.toml")
    }
}

/// Runs the stages' commands, logging each and keeping the script.
struct Runner {
    exe: PathBuf,
    out: PathBuf,
    script: String,
}

/// One command of a stage: its log name and arguments.
struct Step {
    log: String,
    args: Vec<String>,
    /// Exit codes that are results, not failures (`check` exits 1 for a failed check).
    accept: &'static [i32],
}

fn arg(p: &Path) -> String {
    p.display().to_string()
}

impl Runner {
    /// Runs `steps`, two at a time (the machines this runs on have at least two cores), and
    /// fails with the log's tail when one exits with a code it does not accept.
    fn run(&mut self, steps: Vec<Step>) -> Result<Vec<i32>> {
        let mut codes = vec![0; steps.len()];
        let mut running: Vec<(usize, std::process::Child)> = Vec::new();
        let mut next = 0;
        while next < steps.len() || !running.is_empty() {
            while running.len() < 2 && next < steps.len() {
                let s = &steps[next];
                let shown: Vec<String> = s.args.iter().map(|a| shell_word(a)).collect();
                self.script
                    .push_str(&format!("hilrig {}\n", shown.join(" ")));
                let log = self.out.join("logs").join(format!("{}.log", s.log));
                let file = std::fs::File::create(&log)
                    .with_context(|| format!("cannot create {}", log.display()))?;
                let child = Command::new(&self.exe)
                    .args(&s.args)
                    .stdout(file.try_clone()?)
                    .stderr(file)
                    .stdin(std::process::Stdio::null())
                    .spawn()
                    .with_context(|| format!("cannot start {}", self.exe.display()))?;
                running.push((next, child));
                next += 1;
            }
            let (k, mut child) = running.remove(0);
            let status = child.wait()?;
            let code = status.code().unwrap_or(-1);
            codes[k] = code;
            if code != 0 && !steps[k].accept.contains(&code) {
                for (_, mut c) in running.drain(..) {
                    let _ = c.kill();
                    let _ = c.wait();
                }
                let log = self.out.join("logs").join(format!("{}.log", steps[k].log));
                let text = std::fs::read_to_string(&log).unwrap_or_default();
                let tail: Vec<&str> = text.lines().rev().take(12).collect();
                let tail: Vec<&str> = tail.into_iter().rev().collect();
                bail!(
                    "`hilrig {}` exited with {code}; the end of {}:\n{}",
                    steps[k].args.join(" "),
                    log.display(),
                    tail.join("\n")
                );
            }
        }
        Ok(codes)
    }
}

fn shell_word(a: &str) -> String {
    if a.chars()
        .all(|c| c.is_ascii_alphanumeric() || "-_./=:".contains(c))
    {
        a.to_owned()
    } else {
        format!("'{}'", a.replace('\'', "'\\''"))
    }
}

/// A command's output, read through the type that wrote it.
fn read_json<T: hilrig::output::Output>(p: &Path) -> Result<T> {
    Ok(hilrig::output::read(p)?)
}

/// Prints a stage's line: name, key figure, verdict, time.
fn line(stage: &str, figure: &str, verdict: &str, started: Instant) {
    println!(
        "{stage:<9} {verdict:<5} {:>6.1} s  {figure}",
        started.elapsed().as_secs_f64()
    );
}

pub fn run(args: DemoArgs) -> Result<ExitCode> {
    let inputs = Inputs::locate(args.fixtures.as_deref(), args.quick)?;
    let out = args.out.clone();
    for d in [
        "rec",
        "check",
        "sim/idealized",
        "sim/truth",
        "compare",
        "validate",
        "logs",
    ] {
        std::fs::create_dir_all(out.join(d))
            .with_context(|| format!("cannot create {}", out.join(d).display()))?;
    }
    let mut r = Runner {
        exe: std::env::current_exe().context("cannot find the hilrig executable")?,
        out: out.clone(),
        script: String::from(
            "#!/bin/sh\n# The commands `hilrig demo` ran, in order (stages ran two at a time).\nset -e\n",
        ),
    };
    let all = Instant::now();
    let reps = inputs.reps.clone();
    let rec = |rep: &str| out.join("rec").join(format!("{rep}.mcap"));
    println!(
        "hilrig demo: the parking-lot drive of Rosenberger et al. 2019, Fig. 4, {} repetition{} (fixtures/parking)",
        reps.len(),
        if reps.len() == 1 { "" } else { "s" }
    );

    // 1. Record the captures as they came off the vehicle.
    let t = Instant::now();
    r.run(
        reps.iter()
            .map(|rep| Step {
                log: format!("record-{rep}"),
                args: vec![
                    "record".into(),
                    "--rig".into(),
                    arg(&inputs.rig()),
                    "--from".into(),
                    arg(&inputs.capture(rep)),
                    "-o".into(),
                    arg(&rec(rep)),
                ],
                accept: &[],
            })
            .collect(),
    )?;
    r.run(
        reps.iter()
            .map(|rep| Step {
                log: format!("info-{rep}"),
                args: vec![
                    "info".into(),
                    arg(&rec(rep)),
                    "--json".into(),
                    arg(&out.join("rec").join(format!("{rep}.info.json"))),
                ],
                accept: &[],
            })
            .collect(),
    )?;
    let bytes: u64 = reps
        .iter()
        .filter_map(|rep| std::fs::metadata(rec(rep)).ok())
        .map(|m| m.len())
        .sum();
    line(
        "record",
        &format!(
            "{} capture(s) -> MCAP, {:.1} MB (lidar, GNSS, CAN, one clock)",
            reps.len(),
            bytes as f64 / 1e6
        ),
        "ok",
        t,
    );

    // 2. Check the reference data of every run (Rosenberger et al. 2019, §6).
    let t = Instant::now();
    let check_json = |rep: &str| out.join("check").join(format!("{rep}.json"));
    let codes = r.run(
        reps.iter()
            .map(|rep| Step {
                log: format!("check-{rep}"),
                args: vec![
                    "check".into(),
                    arg(&rec(rep)),
                    "--scene".into(),
                    arg(&inputs.scene(rep)),
                    "--json".into(),
                    arg(&check_json(rep)),
                ],
                accept: &[1],
            })
            .collect(),
    )?;
    let checks: Vec<hilrig::reference::check::Report> = reps
        .iter()
        .map(|rep| read_json(&check_json(rep)))
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
    line(
        "check",
        &format!(
            "{passed}/{} runs pass; ego accuracy <= {:.3} m; admissible cell {cell:.2} m",
            reps.len(),
            ego
        ),
        if passed == reps.len() { "pass" } else { "FAIL" },
        t,
    );
    if passed != reps.len() {
        println!(
            "          a run failed its check: see {}",
            out.join("check").display()
        );
    }

    // 3. Re-simulate every run with the idealized model and with the truth model.
    let t = Instant::now();
    let sim = |model: &str, rep: &str| out.join("sim").join(model).join(format!("{rep}.mcap"));
    let models = [
        ("idealized", inputs.root.join("idealized.toml")),
        ("truth", inputs.root.join("truth-model.toml")),
    ];
    let mut steps = Vec::new();
    for (name, model) in &models {
        for rep in &reps {
            steps.push(Step {
                log: format!("resim-{name}-{rep}"),
                args: vec![
                    "resim".into(),
                    arg(&rec(rep)),
                    "--scene".into(),
                    arg(&inputs.scene(rep)),
                    "--model".into(),
                    arg(model),
                    "-o".into(),
                    arg(&sim(name, rep)),
                ],
                accept: &[],
            });
        }
    }
    r.run(steps)?;
    line(
        "resim",
        &format!(
            "{} runs x 2 models (idealized, truth) along the checked trajectories",
            reps.len()
        ),
        "ok",
        t,
    );

    // 4. Compare the first run with its idealized re-simulation, at the admissible cell and at
    //    the paper's 10 cm (Fig. 5).
    let t = Instant::now();
    let first = &reps[0];
    let cmp = |name: &str| out.join("compare").join(format!("{first}-{name}.json"));
    let mut steps = Vec::new();
    for (name, small) in [
        ("idealized", false),
        ("idealized-10cm", true),
        ("truth", false),
    ] {
        let model = if name == "truth" {
            "truth"
        } else {
            "idealized"
        };
        let mut a = vec![
            "compare".into(),
            arg(&rec(first)),
            arg(&sim(model, first)),
            "--scene".into(),
            arg(&inputs.scene(first)),
            "--json".into(),
            arg(&cmp(name)),
        ];
        if small {
            a.extend(["--cell".into(), "0.1".into(), "--allow-small-cell".into()]);
        }
        steps.push(Step {
            log: format!("compare-{first}-{name}"),
            args: a,
            accept: &[],
        });
    }
    r.run(steps)?;
    let ci: Comparison = read_json(&cmp("idealized"))?;
    let c10: Comparison = read_json(&cmp("idealized-10cm"))?;
    let ct: Comparison = read_json(&cmp("truth"))?;
    let nan = |x: Option<f64>| x.unwrap_or(f64::NAN);
    line(
        "compare",
        &format!(
            "OCR^K {:.2} idealized, {:.2} truth at {:.2} m; Spearman(OCR, distance) {:+.2} at 10 cm",
            nan(ci.summary.ocr_mean),
            nan(ct.summary.ocr_mean),
            ci.cell_m,
            nan(c10.summary.ocr_vs_distance.map(|r| r.rho))
        ),
        "ok",
        t,
    );

    // 5. Statistical validation over the repetitions, per phase (Rosenberger et al. 2019, §8).
    let t = Instant::now();
    let val = |name: &str| out.join("validate").join(format!("{name}.json"));
    let steps = models
        .iter()
        .map(|(name, _)| {
            let mut a = vec!["validate".to_string()];
            for rep in &reps {
                a.extend(["--real".into(), arg(&rec(rep))]);
            }
            for rep in &reps {
                a.extend(["--sim".into(), arg(&sim(name, rep))]);
            }
            a.extend([
                "--phases".into(),
                arg(&inputs.root.join("phases.toml")),
                "--json".into(),
                arg(&val(name)),
            ]);
            Step {
                log: format!("validate-{name}"),
                args: a,
                accept: &[1],
            }
        })
        .collect();
    r.run(steps)?;
    let mut figure = Vec::new();
    for (name, _) in &models {
        let v: hilrig::stats::repetitions::Validation = read_json(&val(name))?;
        let [g, y, red, b] = hilrig::report::plots::lights(&v);
        figure.push(format!(
            "{name}: {g} green {y} yellow {red} red {b} black, {}",
            v.verdict.name()
        ));
    }
    line("validate", &figure.join("; "), "done", t);

    // 6. The gap workflow: the idealized model against the measurement.
    let t = Instant::now();
    let gap_dir = out.join("gap");
    // A study file, so that each run keeps its own scene (each repetition has its own survey
    // and its own pedestrian walk; the shorthand would give them all the first one's).
    let study = out.join("gap-study.toml");
    let mut text = format!(
        "# The demo's gap study: the first runs fit, the others validate.\nmodel = {:?}\n",
        arg(&std::path::absolute(inputs.root.join("idealized.toml"))?)
    );
    let fit = if reps.len() >= 2 {
        reps.len().div_ceil(2)
    } else {
        1
    };
    for (k, rep) in reps.iter().enumerate() {
        text.push_str(&format!(
            "\n[[run]]\nrecording = {:?}\nscene = {:?}\nrole = \"{}\"\n",
            arg(&std::path::absolute(rec(rep))?),
            arg(&std::path::absolute(inputs.scene(rep))?),
            if k < fit { "fit" } else { "validate" }
        ));
    }
    std::fs::write(&study, text).with_context(|| format!("cannot write {}", study.display()))?;
    // One run alone is split in time by the workflow (first half fits, second validates).
    let mut a = vec!["gap".to_string(), arg(&study), "-o".into(), arg(&gap_dir)];
    if args.quick {
        a.extend(["--firings".into(), "200000".into()]);
    }
    r.run(vec![Step {
        log: "gap".into(),
        args: a,
        accept: &[],
    }])?;
    let gap: hilrig::gap::report::GapReport = read_json(&gap_dir.join("gap.json"))?;
    let added: Vec<&str> = gap
        .rounds
        .iter()
        .filter_map(|r| r.chosen.map(|c| c.name()))
        .collect();
    line(
        "gap",
        &format!(
            "effects found: {}",
            if added.is_empty() {
                "none".to_string()
            } else {
                added.join(", ")
            }
        ),
        "done",
        t,
    );

    // 7. The report.
    let t = Instant::now();
    let report = out.join("report.html");
    r.run(vec![Step {
        log: "report".into(),
        args: vec!["report".into(), arg(&out), "-o".into(), arg(&report)],
        accept: &[],
    }])?;
    line("report", &arg(&report), "ok", t);
    std::fs::write(out.join("commands.sh"), &r.script)
        .with_context(|| format!("cannot write {}", out.join("commands.sh").display()))?;
    println!(
        "done in {:.0} s: open {} (the commands are in {})",
        all.elapsed().as_secs_f64(),
        report.display(),
        out.join("commands.sh").display()
    );
    Ok(ExitCode::SUCCESS)
}

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

mod stages;
use stages::{Demo, STAGES};

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
    let demo = Demo {
        inputs: Inputs::locate(args.fixtures.as_deref(), args.quick)?,
        out: args.out.clone(),
        quick: args.quick,
    };
    let out = &demo.out;
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
    let n = demo.inputs.reps.len();
    println!(
        "hilrig demo: the parking-lot drive of Rosenberger et al. 2019, Fig. 4, {n} repetition{} (fixtures/parking)",
        if n == 1 { "" } else { "s" }
    );
    for stage in &STAGES {
        let t = Instant::now();
        let mut codes = Vec::new();
        for batch in (stage.steps)(&demo)? {
            codes.extend(r.run(batch)?);
        }
        let o = (stage.outcome)(&demo, &codes)?;
        line(stage.name, &o.figure, o.verdict, t);
        if let Some(note) = o.note {
            println!("          {note}");
        }
    }
    std::fs::write(out.join("commands.sh"), &r.script)
        .with_context(|| format!("cannot write {}", out.join("commands.sh").display()))?;
    println!(
        "done in {:.0} s: open {} (the commands are in {})",
        all.elapsed().as_secs_f64(),
        demo.report().display(),
        out.join("commands.sh").display()
    );
    Ok(ExitCode::SUCCESS)
}

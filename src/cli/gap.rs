//! `hilrig gap`: the gap workflow over a study file or the shorthand, with a progress spinner
//! per round and the one-line findings on the terminal. Exit 0 when it ran (an effect found or
//! not), 2 on bad input or a run that fails `check` without --force.

use anyhow::{Context, Result};
use hilrig::campaign::gap_rounds::{engine_argv, Runner};
use hilrig::gap::engine::RoundEngine;
use hilrig::gap::study::Study;
use hilrig::gap::trial::TrialTask;
use hilrig::gap::workflow::{run, Options, Progress};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct GapArgs {
    #[command(subcommand)]
    sub: Option<Sub>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(clap::Subcommand)]
enum Sub {
    /// One validation run re-simulated with a round's model and measured (OCR^K, precision,
    /// IoU, the scans' features): the task a study's round plans per validation run when its
    /// full re-simulations run on an engine (`gap --jobs` or `--engine`). Writes the result
    /// as JSON (kind `gap_trial`); exit 0 when written, 2 when not.
    Trial(TrialArgs),
}

#[derive(clap::Args)]
struct TrialArgs {
    /// The recording.
    #[arg(long)]
    recording: PathBuf,
    /// Its scene.
    #[arg(long)]
    scene: PathBuf,
    /// The rig file; default: the one attached to the recording.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// The model (model.toml).
    #[arg(long)]
    model: PathBuf,
    /// The model's deterministic part, simulated from the same casts (not written).
    #[arg(long)]
    deterministic: Option<PathBuf>,
    /// Seed of the model's randomness.
    #[arg(long)]
    seed: u64,
    /// Where the simulation goes (MCAP).
    #[arg(long)]
    simulation: PathBuf,
    /// Remove the simulation once it is measured.
    #[arg(long)]
    scratch: bool,
    /// Also measure the recorded scans' features.
    #[arg(long)]
    measured: bool,
    /// Use a run that fails `check`.
    #[arg(long)]
    force: bool,
    /// The result (JSON).
    #[arg(short, long)]
    output: PathBuf,
}

#[derive(clap::Args)]
struct RunArgs {
    /// The study file (TOML: `model`, `scene`, `[[run]]` with recording, scene, role).
    study: Option<PathBuf>,
    /// Parameterization runs (.mcap), when no study file is given: all share --scene.
    #[arg(long, num_args = 1.., conflicts_with = "study")]
    real: Vec<PathBuf>,
    /// Validation runs (.mcap) for the shorthand.
    #[arg(long, num_args = 1.., conflicts_with = "study")]
    validate: Vec<PathBuf>,
    /// The scene of the shorthand's runs.
    #[arg(long, conflicts_with = "study")]
    scene: Option<PathBuf>,
    /// The start model of the shorthand (model.toml).
    #[arg(long, conflicts_with = "study")]
    model: Option<PathBuf>,
    /// The rig file; default: the one attached to each recording.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Output directory: model.fitted.toml, gap.json, sim/ (full re-simulations).
    #[arg(short, long, required = true)]
    output: Option<PathBuf>,
    /// Use runs that fail `check` (their trajectory errors may then pass for lidar effects).
    #[arg(long)]
    force: bool,
    /// Firings sampled for fitting and scoring, shared equally by the runs (fewer runs: a
    /// denser sample of each).
    #[arg(long, default_value_t = 600_000)]
    firings: usize,
    /// At most this many effects are added (the catalogue has ten).
    #[arg(long, default_value_t = 10)]
    max_rounds: usize,
    /// Skip the full re-simulation of the validation runs for OCR^K and the traffic light
    /// (the decision rests on the per-firing likelihood either way).
    #[arg(long)]
    no_full_metrics: bool,
    /// A model known to have made the data (a synthesized drive's truth): the fitted model's
    /// validation metrics are set beside its, and judged against its noise.
    #[arg(long)]
    reference_model: Option<PathBuf>,
    /// Skip the search for the detection limits of the effects not found (the smallest size
    /// of each that the runs would have shown, found by injecting it into them).
    #[arg(long)]
    no_detection_limits: bool,
    /// Run the full re-simulations as `gap trial` tasks (one per validation run, a model at
    /// a time) on the campaigns' local executor, this many processes at a time (default: in
    /// this process, one validation run after the other, each scene loaded once).
    #[arg(
        short,
        long,
        conflicts_with_all = ["engine", "no_full_metrics"],
        value_parser = clap::value_parser!(u16).range(1..)
    )]
    jobs: Option<u16>,
    /// Run the full re-simulations as `gap trial` tasks on an engine: a command that takes a
    /// plan file as its last argument, split into words as a POSIX shell splits them (quotes
    /// and backslashes; no `~` or `$VAR` expansion), e.g. "python -m hilrig_ray --address
    /// auto --hilrig /path/to/hilrig". Its workers must see the study's files and the output
    /// folder at the same paths, and run the same hilrig build.
    #[arg(long, conflicts_with = "no_full_metrics")]
    engine: Option<String>,
}

struct Bars {
    current: Mutex<Option<(usize, indicatif::ProgressBar)>>,
    /// The phase under way and when it began: its time is logged when the next one begins
    /// (`-v`), so a slow study says where its time goes.
    started: Mutex<Option<(std::time::Instant, String)>>,
}

impl Progress for Bars {
    fn phase(&self, round: usize, what: &str) {
        if let Ok(mut started) = self.started.lock() {
            let now = std::time::Instant::now();
            if let Some((t, prev)) = started.replace((now, format!("round {round}: {what}"))) {
                tracing::info!("gap: {prev}: {:.1} s", (now - t).as_secs_f64());
            }
        }
        let Ok(mut cur) = self.current.lock() else {
            return;
        };
        if cur.as_ref().is_none_or(|(r, _)| *r != round) {
            if let Some((_, bar)) = cur.take() {
                bar.finish();
            }
            let bar = indicatif::ProgressBar::new_spinner();
            bar.set_style(
                indicatif::ProgressStyle::with_template("{prefix} {spinner} {msg} ({elapsed})")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
            );
            bar.set_prefix(if round == 0 {
                "gap: setup".to_owned()
            } else {
                format!("gap: round {round}")
            });
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
            *cur = Some((round, bar));
        }
        if let Some((_, bar)) = cur.as_ref() {
            bar.set_message(what.to_owned());
        }
    }
}

pub fn run_cli(args: GapArgs) -> Result<ExitCode> {
    match args.sub {
        Some(Sub::Trial(t)) => trial(t),
        None => run_study(args.run),
    }
}

fn trial(t: TrialArgs) -> Result<ExitCode> {
    let task = TrialTask {
        recording: t.recording,
        scene: t.scene,
        rig: t.rig,
        model: t.model,
        deterministic: t.deterministic,
        seed: t.seed,
        simulation: t.simulation,
        scratch: t.scratch,
        measured: t.measured,
        force: t.force,
        output: t.output,
    };
    match hilrig::gap::trial::trial(&task) {
        Ok(_) => Ok(ExitCode::SUCCESS),
        Err(e) => {
            eprintln!("error: {e}");
            Ok(ExitCode::from(2))
        }
    }
}

fn run_study(args: RunArgs) -> Result<ExitCode> {
    let output = args
        .output
        .clone()
        .expect("clap requires --output without a subcommand");
    let fail = |e: &dyn std::fmt::Display| {
        eprintln!("error: {e}");
        Ok(ExitCode::from(2))
    };
    let study = match (&args.study, &args.scene, &args.model) {
        (Some(p), _, _) => Study::load(p),
        (None, Some(scene), Some(model)) => {
            if args.real.is_empty() {
                return fail(&"give a study file, or --real RUN... with --scene and --model");
            }
            Study::from_lists(
                &args.real,
                &args.validate,
                scene,
                model,
                args.rig.as_deref(),
            )
        }
        _ => return fail(
            &"give a study file, or --real RUN... [--validate RUN...] --scene SCENE --model MODEL",
        ),
    };
    let mut study = match study {
        Ok(s) => s,
        Err(e) => return fail(&e),
    };
    if args.rig.is_some() {
        study.rig.clone_from(&args.rig);
    }
    let bars = Bars {
        current: Mutex::new(None),
        started: Mutex::new(None),
    };
    let engine = match (&args.jobs, &args.engine) {
        (Some(jobs), _) => Some(Runner::Local {
            exe: std::env::current_exe().context("cannot find the hilrig executable")?,
            jobs: usize::from(*jobs),
        }),
        (None, Some(command)) => match engine_argv(command) {
            Ok(argv) => Some(Runner::Command(argv)),
            Err(why) => return fail(&format!("--engine {command:?}: {why}")),
        },
        (None, None) => None,
    }
    .map(|r| std::sync::Arc::new(r) as std::sync::Arc<dyn RoundEngine>);
    let opts = Options {
        out: output.clone(),
        firings: args.firings,
        force: args.force,
        max_rounds: args.max_rounds,
        full_metrics: !args.no_full_metrics,
        reference_model: args.reference_model.clone(),
        detection_limits: !args.no_detection_limits,
        engine,
    };
    let result = run(&study, &opts, &bars);
    if let Ok(mut started) = bars.started.lock() {
        if let Some((t, prev)) = started.take() {
            tracing::info!("gap: {prev}: {:.1} s", t.elapsed().as_secs_f64());
        }
    }
    if let Ok(mut cur) = bars.current.lock() {
        if let Some((_, bar)) = cur.take() {
            bar.finish_and_clear();
        }
    }
    match result {
        Ok(report) => {
            if let Some(s) = &report.split {
                eprintln!("note: {s}");
            }
            for r in &report.runs {
                for d in &r.damage {
                    eprintln!("warning: {}: {d}", r.name);
                }
            }
            for line in &report.summary {
                println!("{line}");
            }
            eprintln!(
                "{}: fitted model; {}: every round",
                output.join("model.fitted.toml").display(),
                output.join("gap.json").display()
            );
            Ok(ExitCode::SUCCESS)
        }
        // Every error names its file and cause in its own text (exit 2, as for bad input).
        Err(e) => fail(&e),
    }
}

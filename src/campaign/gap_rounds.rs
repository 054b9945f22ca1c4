//! The gap workflow's full re-simulations on the engines that run campaigns: the trials of a
//! model (`hilrig gap trial`, one per validation run) as a plan, run by the local executor
//! (`gap --jobs N`) or handed to an engine command that runs a plan file (`gap --engine
//! "python -m hilrig_ray ..."`). The tasks are stamped as a campaign's are, so a study run
//! again into its folder skips the trials whose files are as it left them. A campaign's gap
//! step says where with its `[gap]` table (gap_trials.rs).

use super::file::Step;
pub use super::gap_trials::engine_argv;
use super::local::{self, Outcome, Progress};
use super::plan::{Plan, Task};
use super::resolve::{named_files, Names};
use crate::gap::engine::RoundEngine;
use crate::gap::trial::TrialTask;
use crate::gap::GapError;
use std::path::Path;

/// What runs the plan of a model's trials.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Runner {
    /// The campaigns' local executor: `jobs` tasks at a time, each a process of `exe`.
    Local {
        /// The `hilrig` executable the tasks run.
        exe: std::path::PathBuf,
        /// Tasks at a time.
        jobs: usize,
    },
    /// A command that runs a plan file given as its last argument, and ends, with 0 when
    /// every task passed, once all have ended: e.g. `python -m hilrig_ray --address auto
    /// --hilrig /opt/hilrig/bin/hilrig` (the command says which `hilrig` its workers run).
    Command(Vec<String>),
}

impl RoundEngine for Runner {
    fn run(&self, tag: &str, dir: &Path, trials: &[TrialTask]) -> Result<(), GapError> {
        let plan = plan(tag, dir, trials)?;
        match self {
            Runner::Local { exe, jobs } => {
                let options = local::Options {
                    exe: exe.clone(),
                    jobs: *jobs,
                    force: false,
                };
                let summary =
                    local::run(&plan, &options, &Quiet).map_err(|e| GapError::Engine {
                        task: plan.campaign.clone(),
                        why: e.to_string(),
                        log: None,
                    })?;
                for ((id, outcome), t) in summary.outcomes.iter().zip(&plan.tasks) {
                    let (why, log) = match outcome {
                        Outcome::Ran { exit: 0, .. } | Outcome::UpToDate { exit: 0 } => continue,
                        Outcome::Ran { exit, .. } | Outcome::UpToDate { exit } => {
                            (format!("exit {exit}"), Some(t.log.clone()))
                        }
                        // The executor's reason names the log already.
                        Outcome::Failed { why } => (why.clone(), None),
                        Outcome::NotRun { because } => (format!("not run: {because}"), None),
                    };
                    return Err(GapError::Engine {
                        task: id.clone(),
                        why,
                        log,
                    });
                }
                Ok(())
            }
            Runner::Command(argv) => run_command(&plan, argv),
        }
    }
}

/// The trials tagged `tag` as a plan under `dir`: one task each, its inputs the files it reads
/// (a changed mesh, model or rig makes it run again).
fn plan(tag: &str, dir: &Path, trials: &[TrialTask]) -> Result<Plan, GapError> {
    let mut tasks = Vec::with_capacity(trials.len());
    for (i, t) in trials.iter().enumerate() {
        let id = format!("gap/{tag}/validation-{:02}", i + 1);
        let files_of = |p: &Path, names| {
            named_files(p, names).map_err(|e| GapError::Engine {
                task: id.clone(),
                why: e.to_string(),
                log: None,
            })
        };
        let mut inputs = vec![t.recording.clone(), t.model.clone()];
        inputs.extend(files_of(&t.scene, Names::Scene)?);
        inputs.push(t.scene.clone());
        inputs.extend(t.deterministic.iter().cloned());
        if let Some(rig) = &t.rig {
            inputs.extend(files_of(rig, Names::Rig)?);
            inputs.push(rig.clone());
        }
        let mut outputs = vec![t.output.clone()];
        if !t.scratch {
            outputs.push(t.simulation.clone());
        }
        tasks.push(Task::new(
            id,
            Step::Gap,
            t.args(),
            (inputs, outputs),
            t.log(),
        ));
    }
    Ok(Plan {
        campaign: format!("gap: {tag}"),
        campaign_file: dir.join(format!("{tag}.plan.json")),
        out: dir.to_owned(),
        files: Vec::new(),
        tasks,
    })
}

/// Tells nobody: the trials are one phase of the workflow's own progress.
struct Quiet;

impl Progress for Quiet {
    fn started(&self, _: &Task) {}
    fn finished(&self, _: &Task, _: &Outcome) {}
}

/// Runs `plan` with the engine command `argv` (the plan's path appended), its output to a log
/// beside the plan; an error when it cannot start or does not end with 0.
fn run_command(plan: &Plan, argv: &[String]) -> Result<(), GapError> {
    let path = plan.campaign_file.clone();
    let log = path.with_extension("log");
    let engine_error = |why: String| GapError::Engine {
        task: plan.campaign.clone(),
        why,
        log: Some(log.clone()),
    };
    let Some((program, args)) = argv.split_first() else {
        return Err(engine_error("no engine command".into()));
    };
    crate::output::write(&path, plan)?;
    let io = |source| GapError::Output {
        path: log.clone(),
        source,
    };
    let file = std::fs::File::create(&log).map_err(io)?;
    let err = file.try_clone().map_err(io)?;
    let status = std::process::Command::new(program)
        .args(args)
        .arg(&path)
        .stdin(std::process::Stdio::null())
        .stdout(file)
        .stderr(err)
        .status()
        .map_err(|e| engine_error(format!("cannot start {program}: {e}")))?;
    if !status.success() {
        return Err(engine_error(format!(
            "the engine `{}` ended with {status}",
            argv.join(" ")
        )));
    }
    Ok(())
}

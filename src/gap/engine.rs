//! Where the gap workflow's full re-simulations run: in this process, one validation run after
//! the other (the default: each scene is loaded once), or as trials (`hilrig gap trial`, one
//! per validation run) that a [`RoundEngine`] runs: the campaigns' local executor, or any
//! engine that runs a plan (the Ray executor of `python/`), so that a study with many
//! validation runs fans out over a cluster like a campaign or an eFAST design.
//!
//! A round is one call, not the study: a round's trial is the model its fit found, and the fit
//! waits for the rounds before it; within a round the validation runs are independent
//! (Rosenberger et al. 2019, §4: repetitions). A trial writes what the round needs of its run
//! ([`TrialRun`], JSON), and the workflow reads it back: the same numbers, bit for bit, as the
//! run re-simulated in this process (tests/gap_engine.rs).

use super::observe::RunData;
use super::trial::{seed_of, simulation_path, RoundEngine, TrialTask};
use super::GapError;
use crate::sim::model::ModelFile;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use super::trial::TrialRun;

/// Where a study's full re-simulations run.
#[derive(Clone, Debug, Default)]
pub enum Engine {
    /// Here, one run after the other.
    #[default]
    InProcess,
    /// As trials that `engine` runs, a round at a time.
    Planned {
        /// What runs them.
        engine: Arc<dyn RoundEngine>,
        /// The study's rig file, when it overrides the recordings' own.
        rig: Option<PathBuf>,
        /// The study uses runs that fail `check`.
        force: bool,
    },
}

/// A path as a task in another folder or on another node finds it: absolute, as given
/// otherwise (links are not resolved, so that an absolute path reaches the simulation's
/// metadata as the workflow's own process writes it).
fn absolute(p: &Path) -> Result<PathBuf, GapError> {
    std::path::absolute(p).map_err(|source| GapError::Output {
        path: p.to_owned(),
        source,
    })
}

impl Engine {
    /// The trials of `val` with `model` (and `det`) as the round `tag`, run, and their results
    /// read back in the runs' order.
    pub(super) fn run(
        &self,
        val: &[RunData],
        (model, det): (&ModelFile, Option<&ModelFile>),
        (dir, tag, keep_files): (&Path, &str, bool),
        measured: bool,
    ) -> Result<Vec<TrialRun>, GapError> {
        let Engine::Planned { engine, rig, force } = self else {
            unreachable!("the workflow re-simulates in its own process without an engine")
        };
        let dir = absolute(dir)?;
        // The models as files the trials read (their TOML reads back as the same model).
        let write = |name: String, m: &ModelFile| -> Result<PathBuf, GapError> {
            let path = dir.join(name);
            std::fs::write(&path, m.to_toml()).map_err(|source| GapError::Output {
                path: path.clone(),
                source,
            })?;
            Ok(path)
        };
        let model_path = write(format!("{tag}.model.toml"), model)?;
        let det_path = det
            .map(|d| write(format!("{tag}.deterministic.toml"), d))
            .transpose()?;
        let rig = rig.as_deref().map(absolute).transpose()?;
        let trials: Vec<TrialTask> = val
            .iter()
            .enumerate()
            .map(|(i, r)| {
                Ok(TrialTask {
                    recording: absolute(&r.path)?,
                    scene: absolute(&r.scene_path)?,
                    rig: rig.clone(),
                    model: model_path.clone(),
                    deterministic: det_path.clone(),
                    seed: seed_of(i),
                    simulation: simulation_path(&dir, tag, i),
                    scratch: !keep_files,
                    measured,
                    force: *force,
                    output: dir.join(format!("{tag}-validation-{:02}.json", i + 1)),
                })
            })
            .collect::<Result<_, GapError>>()?;
        engine.run(tag, &dir, &trials)?;
        // The results, each checked to be of its run and to hold what was asked.
        trials
            .iter()
            .zip(val)
            .enumerate()
            .map(|(i, (t, r))| {
                let bad = |why: String| GapError::Engine {
                    task: format!("the trial of {} ({tag})", r.name),
                    why,
                    log: t.output.clone(),
                };
                let mut result: TrialRun =
                    crate::output::read(&t.output).map_err(|e| bad(e.to_string()))?;
                if result.recording != t.recording {
                    return Err(bad(format!(
                        "its result is of {}, not of {}",
                        result.recording.display(),
                        t.recording.display()
                    )));
                }
                if result.deterministic.is_some() != det.is_some()
                    || (measured && result.measured.is_none())
                {
                    return Err(bad(
                        "its result lacks what the round asked for (written by another round?)"
                            .into(),
                    ));
                }
                // Named as the workflow names them in its own process.
                result.recording.clone_from(&r.path);
                result.simulation = simulation_path(&dir, tag, i);
                Ok(result)
            })
            .collect()
    }
}

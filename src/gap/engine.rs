//! Where the gap workflow's full re-simulations run: in this process, one validation run after
//! the other (the default: each scene is loaded once), or as trials (`hilrig gap trial`, one
//! per validation run) that a [`RoundEngine`] runs: the campaigns' local executor, or any
//! engine that runs a plan (the Ray executor of `python/`), so that a study with many
//! validation runs fans out over a cluster like a campaign or an eFAST design.
//!
//! The engine gets the trials of one model at a time (a round's start model, its trial, a
//! current model's deterministic part, the reference model): each is what the round's fit
//! found, and the fit waits for the rounds before it; the validation runs of one model are
//! independent (Rosenberger et al. 2019, §4: repetitions). A trial writes what the workflow
//! needs of its run ([`TrialRun`], JSON), and the workflow reads it back: the same numbers, bit
//! for bit, as the run re-simulated in this process (tests/gap_engine.rs).

use super::observe::RunData;
use super::study::anchored;
use super::trial::{model_sha256, one_run, seed_of, simulation_path, TrialTask};
use super::GapError;
use crate::sim::hit_log::HitLog;
use crate::sim::model::ModelFile;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use super::trial::TrialRun;

/// What runs a model's trials as tasks (`hilrig gap trial`, one per validation run): the
/// campaigns' local executor or an engine command ([`crate::campaign::gap_rounds`]). Defined
/// here and implemented there, so that the workflow does not depend on the campaigns that run
/// it.
pub trait RoundEngine: Send + Sync + std::fmt::Debug {
    /// Runs every trial of `trials`, the simulations tagged `tag` (their files under `dir`),
    /// and returns once all have ended; an error ([`GapError::Engine`]) names the trial or
    /// the engine that failed and its log. The caller reads the trials' results from their
    /// outputs.
    fn run(&self, tag: &str, dir: &Path, trials: &[TrialTask]) -> Result<(), GapError>;
}

/// Where a study's full re-simulations run.
#[derive(Clone, Debug, Default)]
pub enum Engine {
    /// Here, one run after the other.
    #[default]
    InProcess,
    /// As trials that `engine` runs, one model at a time.
    Planned {
        /// What runs them.
        engine: Arc<dyn RoundEngine>,
        /// The study's rig file, when it overrides the recordings' own.
        rig: Option<PathBuf>,
        /// The study uses runs that fail `check`.
        force: bool,
    },
}

/// The simulations of one model of the validation runs: their folder, their tag, and whether
/// they stay there (scratch ones, a model's deterministic part, are removed once measured).
#[derive(Clone, Copy, Debug)]
pub(super) struct Simulations<'a> {
    /// Where they go.
    pub dir: &'a Path,
    /// What their names start with (`round-0`, `round-2-range_noise`, `reference`).
    pub tag: &'a str,
    /// Whether they are kept for the user to open.
    pub keep: bool,
    /// Per validation run, its centre hits kept from one round's re-simulation for the next
    /// ([`crate::sim::hit_log`]; used where the runs are re-simulated in this process).
    pub hits: &'a [HitLog],
}

impl Engine {
    /// Every run of `val` re-simulated with `model` (and its deterministic part `det`, from
    /// the same casts) as `sims`, and measured: here, or as trials on the engine, whose
    /// results are checked to be of this run, seed, model and build. The measured scans'
    /// features only when `measured`.
    pub(super) fn run(
        &self,
        val: &[RunData],
        (model, det): (&ModelFile, Option<&ModelFile>),
        sims: Simulations<'_>,
        measured: bool,
    ) -> Result<Vec<TrialRun>, GapError> {
        let Engine::Planned { engine, rig, force } = self else {
            return val
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    one_run(
                        r,
                        seed_of(i),
                        (model, det),
                        &simulation_path(sims.dir, sims.tag, i),
                        sims.keep,
                        measured,
                        sims.hits.get(i),
                    )
                })
                .collect();
        };
        let Simulations { tag, keep, .. } = sims;
        // The trials run in other folders, perhaps on other nodes: every path absolute (the
        // study's own are, `Study::load`; the output folder may not be).
        let dir = anchored(sims.dir);
        let model_path = written(&dir.join(format!("{tag}.model.toml")), model)?;
        let det_path = det
            .map(|d| written(&dir.join(format!("{tag}.deterministic.toml")), d))
            .transpose()?;
        let trials: Vec<TrialTask> = val
            .iter()
            .enumerate()
            .map(|(i, r)| TrialTask {
                recording: r.path.clone(),
                scene: r.scene_path.clone(),
                rig: rig.clone(),
                model: model_path.clone(),
                deterministic: det_path.clone(),
                seed: seed_of(i),
                simulation: simulation_path(&dir, tag, i),
                scratch: !keep,
                measured,
                force: *force,
                output: dir.join(format!("{tag}-validation-{:02}.json", i + 1)),
            })
            .collect();
        engine.run(tag, &dir, &trials)?;
        let (model_hash, det_hash) = (model_sha256(model), det.map(model_sha256));
        trials
            .iter()
            .zip(val)
            .enumerate()
            .map(|(i, (t, r))| {
                let bad = |why: String| GapError::Engine {
                    task: format!("the {tag} trial of {}", r.name),
                    why,
                    // Named when the engine ran the task and left it.
                    log: Some(t.log()).filter(|l| l.exists()),
                };
                let mut result: TrialRun =
                    crate::output::read(&t.output).map_err(|e| bad(e.to_string()))?;
                let wrong = [
                    (result.recording != t.recording).then(|| {
                        format!(
                            "is of {}, not {}",
                            result.recording.display(),
                            t.recording.display()
                        )
                    }),
                    (result.seed != t.seed)
                        .then(|| format!("has seed {}, not {}", result.seed, t.seed)),
                    (result.model_sha256 != model_hash || result.deterministic_sha256 != det_hash)
                        .then(|| "was made with another model".to_owned()),
                    (result.build != crate::output::BUILD).then(|| {
                        format!(
                            "was made by {}, not by this {}",
                            result.build,
                            crate::output::BUILD
                        )
                    }),
                    (measured && result.measured.is_none())
                        .then(|| "lacks the measured scans' features".to_owned()),
                ];
                if let Some(w) = wrong.into_iter().flatten().next() {
                    return Err(bad(format!("its result {}: {}", t.output.display(), w)));
                }
                // Named as the workflow names it here, whatever folder the task saw.
                result.simulation = simulation_path(sims.dir, tag, i);
                Ok(result)
            })
            .collect()
    }
}

/// `model` written to `path` for a trial to read; an error unless the file reads back as this
/// very model (a model the TOML cannot hold would be simulated as another).
fn written(path: &Path, model: &ModelFile) -> Result<PathBuf, GapError> {
    let text = model.to_toml();
    if toml::from_str::<ModelFile>(&text).ok().as_ref() != Some(model) {
        return Err(GapError::Engine {
            task: format!("the model '{}'", model.name),
            why: format!("its TOML does not read back as the same model: {text:?}"),
            log: None,
        });
    }
    std::fs::write(path, text).map_err(|source| GapError::Output {
        path: path.to_owned(),
        source,
    })?;
    Ok(path.to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::model::Effect;

    /// A fitted model is written for the trials as the workflow holds it; one whose TOML
    /// would read back as another model (a NaN is not equal to itself) is refused, naming it,
    /// and no file is left for a trial to read.
    #[test]
    fn a_model_is_written_only_if_it_reads_back_as_itself() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = ModelFile::idealized();
        m.effects.push(Effect::RangeBias {
            bias_m: 0.1 + 0.2, // not a short decimal: its exact digits must survive
        });
        let path = dir.path().join("m.toml");
        written(&path, &m).unwrap();
        let back: ModelFile = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        assert_eq!(back, m);
        assert_eq!(model_sha256(&back), model_sha256(&m));

        m.effects = vec![Effect::RangeBias { bias_m: f64::NAN }];
        let nan = dir.path().join("nan.toml");
        let e = written(&nan, &m).unwrap_err().to_string();
        assert!(e.contains("does not read back"), "{e}");
        assert!(!nan.exists());
    }
}

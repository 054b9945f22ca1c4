//! The study file of `hilrig gap`: the start model and each run with its own scene and role.
//!
//! ```toml
//! model = "fixtures/parking/idealized.toml"
//! scene = "fixtures/parking/scene.toml"      # for runs that do not name their own
//! [[run]]
//! recording = "runs/rep-01.mcap"
//! scene = "fixtures/parking/rep-01/scene.toml"
//! role = "fit"                               # or "validate"
//! ```
//!
//! Relative paths are relative to the study file. Parameterization and validation runs are never
//! the same data (Rosenberger et al. 2019, §4): a recording listed twice is an error, and a
//! study with a single run is split in time (first half to fit, second half to validate).

use super::GapError;
use crate::scene::Scene;
use crate::sim::ModelFile;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// What a run is used for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Parameterization: candidates are scored and fitted on it.
    Fit,
    /// Validation: an added effect must improve the metrics on it.
    Validate,
}

/// A run as the study file lists it.
#[derive(Clone, Debug, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct RunEntry {
    /// The recording (MCAP).
    pub recording: PathBuf,
    /// Its scene, when it is not the study's default.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene: Option<PathBuf>,
    /// What it is used for.
    pub role: Role,
}

/// The study file, as written: what [`Study::load`] reads and a program (the demo) writes.
#[derive(Clone, Debug, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct StudyFile {
    /// The start model.
    pub model: PathBuf,
    /// The scene of runs that do not name their own.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene: Option<PathBuf>,
    /// A rig file overriding the ones attached to the recordings.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rig: Option<PathBuf>,
    /// The runs.
    #[serde(rename = "run", default)]
    pub runs: Vec<RunEntry>,
}

impl StudyFile {
    /// The file's text (TOML), to be read back by [`Study::load`].
    pub fn to_toml(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(self)
    }
}

/// One run of a study, paths resolved.
#[derive(Clone, Debug)]
pub struct StudyRun {
    /// The recording (MCAP).
    pub recording: PathBuf,
    /// Its scene file.
    pub scene_path: PathBuf,
    /// Its role.
    pub role: Role,
}

/// A study: the start model and the runs.
#[derive(Clone, Debug)]
pub struct Study {
    /// Where the start model came from.
    pub model_path: PathBuf,
    /// The start model.
    pub model: ModelFile,
    /// A rig file overriding the ones attached to the recordings.
    pub rig: Option<PathBuf>,
    /// The runs.
    pub runs: Vec<StudyRun>,
}

/// A run's file as an absolute path (links not resolved): the simulations name their run and
/// scene in their metadata, and a relative path there would be relative to a folder the file
/// does not record; a round's tasks, which may run in another folder or on another node,
/// name them the same way ([`super::engine`]).
pub(super) fn anchored(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_owned())
}

fn load_model(path: &Path) -> Result<ModelFile, GapError> {
    ModelFile::load(path).map_err(GapError::StartModel)
}

/// Why a study's runs do not make a study.
#[derive(Debug, thiserror::Error)]
pub enum StudyProblem {
    /// No run at all.
    #[error("the study lists no run")]
    NoRun,
    /// A recording listed twice.
    #[error("{} is listed twice: parameterization and validation runs must be different data (Rosenberger et al. 2019, §4)", .0.display())]
    Twice(PathBuf),
    /// Several runs, none of one role.
    #[error("no run has role \"{}\": give at least one run to fit and one to validate (or a single run, which is split in time)", if *.0 == Role::Fit { "fit" } else { "validate" })]
    NoRunOfRole(Role),
    /// A run without a scene, in a study without a default one.
    #[error("{}: run {index} ({}) names no scene and the study has no default `scene`", .study.display(), .recording.display())]
    NoScene {
        /// The study file.
        study: PathBuf,
        /// The run's place in it, from 1.
        index: usize,
        /// The run.
        recording: PathBuf,
    },
    /// Runs of different sites.
    #[error("runs of different scenes: {} is in scene '{first_scene}' ({}), {} in scene '{other_scene}' ({}); a study's runs are repetitions of one scenario", .first.display(), .first_scene_path.display(), .other.display(), .other_scene_path.display())]
    DifferentScenes {
        /// The first run.
        first: PathBuf,
        /// Its scene's name.
        first_scene: String,
        /// Its scene file.
        first_scene_path: PathBuf,
        /// A run of another scene.
        other: PathBuf,
        /// That scene's name.
        other_scene: String,
        /// That scene file.
        other_scene_path: PathBuf,
    },
}

impl Study {
    /// Reads a study file.
    pub fn load(path: &Path) -> Result<Study, GapError> {
        let file: StudyFile = crate::config::read_toml(path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        let at = |p: &Path| base.join(p);
        let runs = file
            .runs
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let scene = r.scene.as_ref().or(file.scene.as_ref()).ok_or_else(|| {
                    StudyProblem::NoScene {
                        study: path.to_owned(),
                        index: i + 1,
                        recording: r.recording.clone(),
                    }
                })?;
                Ok(StudyRun {
                    recording: anchored(&at(&r.recording)),
                    scene_path: anchored(&at(scene)),
                    role: r.role,
                })
            })
            .collect::<Result<Vec<_>, GapError>>()?;
        let model_path = at(&file.model);
        let study = Study {
            model: load_model(&model_path)?,
            model_path,
            rig: file.rig.as_deref().map(|r| anchored(&at(r))),
            runs,
        };
        study.check()?;
        Ok(study)
    }

    /// The shorthand of the command line: every run on one scene.
    pub fn from_lists(
        fit: &[PathBuf],
        validate: &[PathBuf],
        scene: &Path,
        model: &Path,
        rig: Option<&Path>,
    ) -> Result<Study, GapError> {
        let run = |p: &PathBuf, role| StudyRun {
            recording: anchored(p),
            scene_path: anchored(scene),
            role,
        };
        let study = Study {
            model: load_model(model)?,
            model_path: model.to_owned(),
            rig: rig.map(anchored),
            runs: fit
                .iter()
                .map(|p| run(p, Role::Fit))
                .chain(validate.iter().map(|p| run(p, Role::Validate)))
                .collect(),
        };
        study.check()?;
        Ok(study)
    }

    /// A study needs runs, no recording twice, and (with more than one run) at least one run
    /// of each role; all scenes must be of one site.
    fn check(&self) -> Result<(), GapError> {
        if self.runs.is_empty() {
            return Err(StudyProblem::NoRun.into());
        }
        let mut seen = std::collections::HashSet::new();
        for r in &self.runs {
            let key = std::fs::canonicalize(&r.recording).unwrap_or_else(|_| r.recording.clone());
            if !seen.insert(key) {
                return Err(StudyProblem::Twice(r.recording.clone()).into());
            }
        }
        if self.runs.len() > 1 {
            for role in [Role::Fit, Role::Validate] {
                if !self.runs.iter().any(|r| r.role == role) {
                    return Err(StudyProblem::NoRunOfRole(role).into());
                }
            }
        }
        Ok(())
    }

    /// Loads every run's scene and checks they are of one site (same scene name): the runs
    /// of a study are repetitions of one scenario.
    pub fn scenes(&self) -> Result<Vec<Scene>, GapError> {
        let scenes = self
            .runs
            .iter()
            .map(|r| {
                Scene::load(&r.scene_path).map_err(|source| GapError::Scene {
                    recording: r.recording.clone(),
                    source,
                })
            })
            .collect::<Result<Vec<_>, GapError>>()?;
        if let Some(first) = scenes.first() {
            for (s, r) in scenes.iter().zip(&self.runs).skip(1) {
                if s.file.name != first.file.name {
                    return Err(StudyProblem::DifferentScenes {
                        first: self.runs[0].recording.clone(),
                        first_scene: first.file.name.clone(),
                        first_scene_path: self.runs[0].scene_path.clone(),
                        other: r.recording.clone(),
                        other_scene: s.file.name.clone(),
                        other_scene_path: r.scene_path.clone(),
                    }
                    .into());
                }
            }
        }
        Ok(scenes)
    }
}

#[cfg(test)]
mod tests {
    use super::Study;
    use std::path::{Path, PathBuf};

    /// Several runs need one of each role; a single run is split in time instead.
    #[test]
    fn several_runs_need_a_run_of_each_role() {
        let model = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/fixtures/parking/idealized.toml"
        ));
        let scene = Path::new("scene.toml");
        let (a, b) = (PathBuf::from("a.mcap"), PathBuf::from("b.mcap"));
        let only_fit = Study::from_lists(&[a.clone(), b.clone()], &[], scene, model, None)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            only_fit.contains("no run has role \"validate\""),
            "{only_fit}"
        );
        let only_validate = Study::from_lists(&[], &[a.clone(), b.clone()], scene, model, None)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            only_validate.contains("no run has role \"fit\""),
            "{only_validate}"
        );
        assert!(Study::from_lists(std::slice::from_ref(&a), &[b], scene, model, None).is_ok());
        assert!(Study::from_lists(&[a], &[], scene, model, None).is_ok());
    }
}

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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RunEntry {
    recording: PathBuf,
    scene: Option<PathBuf>,
    role: Role,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StudyFile {
    model: PathBuf,
    scene: Option<PathBuf>,
    rig: Option<PathBuf>,
    #[serde(rename = "run", default)]
    runs: Vec<RunEntry>,
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

fn load_model(path: &Path) -> Result<ModelFile, GapError> {
    ModelFile::load(path).map_err(|e| GapError::Input(format!("start model: {e}")))
}

impl Study {
    /// Reads a study file.
    pub fn load(path: &Path) -> Result<Study, GapError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| GapError::Input(format!("cannot read {}: {e}", path.display())))?;
        crate::config::check_finite(&text)
            .map_err(|e| GapError::Input(format!("{}: {e}", path.display())))?;
        let file: StudyFile = toml::from_str(&text)
            .map_err(|e| GapError::Input(format!("{}: {e}", path.display())))?;
        let base = path.parent().unwrap_or(Path::new("."));
        let at = |p: &Path| base.join(p);
        let runs = file
            .runs
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let scene = r.scene.as_ref().or(file.scene.as_ref()).ok_or_else(|| {
                    GapError::Input(format!(
                        "{}: run {} ({}) names no scene and the study has no default `scene`",
                        path.display(),
                        i + 1,
                        r.recording.display()
                    ))
                })?;
                Ok(StudyRun {
                    recording: at(&r.recording),
                    scene_path: at(scene),
                    role: r.role,
                })
            })
            .collect::<Result<Vec<_>, GapError>>()?;
        let model_path = at(&file.model);
        let study = Study {
            model: load_model(&model_path)?,
            model_path,
            rig: file.rig.as_deref().map(at),
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
            recording: p.clone(),
            scene_path: scene.to_owned(),
            role,
        };
        let study = Study {
            model: load_model(model)?,
            model_path: model.to_owned(),
            rig: rig.map(Path::to_owned),
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
        let input = GapError::Input;
        if self.runs.is_empty() {
            return Err(input("the study lists no run".into()));
        }
        let mut seen = std::collections::HashSet::new();
        for r in &self.runs {
            let key = std::fs::canonicalize(&r.recording).unwrap_or_else(|_| r.recording.clone());
            if !seen.insert(key) {
                return Err(input(format!(
                    "{} is listed twice: parameterization and validation runs must be different data (Rosenberger et al. 2019, §4)",
                    r.recording.display()
                )));
            }
        }
        if self.runs.len() > 1 {
            for role in [Role::Fit, Role::Validate] {
                if !self.runs.iter().any(|r| r.role == role) {
                    return Err(input(format!(
                        "no run has role \"{}\": give at least one run to fit and one to validate (or a single run, which is split in time)",
                        if role == Role::Fit { "fit" } else { "validate" }
                    )));
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
                Scene::load(&r.scene_path).map_err(|e| {
                    GapError::Input(format!("scene of {}: {e}", r.recording.display()))
                })
            })
            .collect::<Result<Vec<_>, GapError>>()?;
        if let Some(first) = scenes.first() {
            for (s, r) in scenes.iter().zip(&self.runs).skip(1) {
                if s.file.name != first.file.name {
                    return Err(GapError::Input(format!(
                        "runs of different scenes: {} is in scene '{}' ({}), {} in scene '{}' ({}); a study's runs are repetitions of one scenario",
                        self.runs[0].recording.display(),
                        first.file.name,
                        self.runs[0].scene_path.display(),
                        r.recording.display(),
                        s.file.name,
                        r.scene_path.display()
                    )));
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

//! `hilrig efast run`: the sensitivity of a metric to scenario parameters, measured by making
//! one short drive per eFAST parameter set (Rosenberger et al. 2019, §4: the parameters that
//! move the metric are the ones a validation has to cover).
//!
//! A scenario file names a scene, a drive, the model that stands in for the real sensor
//! ("reality", e.g. a truth model with weather), the model under test and one metric of
//! `hilrig compare`'s summary. Each parameter of the eFAST parameter file is tied by a knob to
//! one number in one of those files:
//!
//! ```toml
//! scene = "../parking/scene.toml"          # paths relative to this file
//! drive = "drive.toml"
//! reality = "reality.toml"
//! model = "../parking/idealized.toml"
//! metric = "only_sim_share"                # a field of compare's summary
//! cell_m = 0.3                             # optional: compare's defaults otherwise
//!
//! [[knob]]
//! parameter = "ego_speed"                  # a name in the parameter file
//! set = "drive.path.cruise_speed_mps"      # file, then keys; [NAME] picks a named table
//! [[knob]]
//! parameter = "rain_extinction"
//! set = "reality.effect[weather].extinction_per_m"
//! ```
//!
//! Per parameter set the drive is synthesized through the scene with the reality model
//! (`synth`, without human variation or reference errors unless `errors = true`), recorded
//! (`record --from`), re-simulated with the model under test and compared (`resim`,
//! `compare`), both on the synthesizer's true trajectory and in the true scene: the question is
//! how the *model* reacts to the scenario, so the reference data's errors are kept out of it
//! (and any cell size may be used). The files are
//! written to a work directory and removed after each set.

use super::efast::Parameter;
use crate::metrics::compare::{compare, Options, Summary};
use crate::metrics::grid::Dims;
use crate::metrics::roi::Region;
use crate::record::from_capture::record_from;
use crate::rig::Rig;
use crate::scene::file::SceneFile;
use crate::scene::pose::Trajectory;
use crate::scene::Scene;
use crate::sim::drive::{parse_utc, DriveFile};
use crate::sim::resim::{resim, PoseSource, ViewingClouds};
use crate::sim::synth::{synth_rep, SynthJob};
use crate::sim::ModelFile;
use serde::Deserialize;
use std::path::{Path, PathBuf};

mod error;
pub use error::{KnobError, ScenarioError, StepError};

/// The scenario file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// The true scene.
    pub scene: PathBuf,
    /// The drive.
    pub drive: PathBuf,
    /// The model that makes the "measured" drive.
    pub reality: PathBuf,
    /// The model under test.
    pub model: PathBuf,
    /// A numeric field of `compare`'s summary.
    pub metric: String,
    /// Grid cell, m (default: the admissible one).
    #[serde(default)]
    pub cell_m: Option<f64>,
    /// Scans per occupancy grid.
    #[serde(default = "one")]
    pub k: usize,
    /// 3D voxels instead of bird's-eye cells.
    #[serde(default)]
    pub voxel: bool,
    /// Which points count: all, objects, object:NAME.
    #[serde(default)]
    pub roi: Option<String>,
    /// Keep the ground's points.
    #[serde(default)]
    pub keep_ground: bool,
    /// Synthesize with human variation and reference errors.
    #[serde(default)]
    pub errors: bool,
    /// Which number each parameter sets.
    #[serde(default)]
    pub knob: Vec<KnobSpec>,
}

fn one() -> usize {
    1
}

/// One parameter tied to one number.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KnobSpec {
    /// The parameter's name in the parameter file.
    pub parameter: String,
    /// `scene|drive|reality|model`, then keys separated by dots; `key[NAME]` picks the table
    /// named NAME in the array `key`, a number picks an array element.
    pub set: String,
}

/// Which of the four documents a knob changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Doc {
    Scene = 0,
    Drive = 1,
    Reality = 2,
    Model = 3,
}

/// One step of a knob's path.
#[derive(Clone, Debug, PartialEq)]
enum Step {
    Key(String),
    Index(usize),
    Named(String),
}

/// A parsed knob: the document, the path in it and the parameter's column.
#[derive(Clone, Debug)]
struct Knob {
    doc: Doc,
    path: Vec<Step>,
    column: usize,
    text: String,
}

fn parse_path(set: &str) -> Result<(Doc, Vec<Step>), KnobError> {
    let mut rest = set.trim();
    let mut steps = Vec::new();
    while !rest.is_empty() {
        let end = rest.find(['.', '[']).unwrap_or(rest.len());
        let key = &rest[..end];
        if !key.is_empty() {
            steps.push(match key.parse::<usize>() {
                Ok(i) => Step::Index(i),
                Err(_) => Step::Key(key.to_owned()),
            });
        }
        rest = &rest[end..];
        if let Some(r) = rest.strip_prefix('[') {
            let close = r.find(']').ok_or(KnobError::Unclosed)?;
            steps.push(Step::Named(r[..close].to_owned()));
            rest = &r[close + 1..];
        }
        rest = rest.strip_prefix('.').unwrap_or(rest);
    }
    let doc = match steps.first() {
        Some(Step::Key(k)) if k == "scene" => Doc::Scene,
        Some(Step::Key(k)) if k == "drive" => Doc::Drive,
        Some(Step::Key(k)) if k == "reality" => Doc::Reality,
        Some(Step::Key(k)) if k == "model" => Doc::Model,
        _ => return Err(KnobError::NoFile),
    };
    if steps.len() < 2 {
        return Err(KnobError::NoKey);
    }
    Ok((doc, steps.split_off(1)))
}

/// Sets the number at `path` in `doc` to `value`. Every step but the last must exist (a
/// misspelt key is an error, not a new key); the last key may be new, and the file's own
/// checks (unknown keys are rejected) judge it. An integer stays an integer.
fn set_number(doc: &mut toml::Value, path: &[Step], value: f64) -> Result<(), KnobError> {
    let mut at = doc;
    for (i, step) in path.iter().enumerate() {
        let last = i + 1 == path.len();
        at = match step {
            Step::Key(k) => {
                let table = at
                    .as_table_mut()
                    .ok_or_else(|| KnobError::NotInTable(k.clone()))?;
                if last && !table.contains_key(k) {
                    table.insert(k.clone(), toml::Value::Float(value));
                    return Ok(());
                }
                table
                    .get_mut(k)
                    .ok_or_else(|| KnobError::Missing(k.clone()))?
            }
            Step::Index(n) => {
                let array = at.as_array_mut().ok_or(KnobError::NotAnArray(*n))?;
                let len = array.len();
                array
                    .get_mut(*n)
                    .ok_or(KnobError::OutOfRange { index: *n, len })?
            }
            Step::Named(name) => {
                let array = at
                    .as_array_mut()
                    .ok_or_else(|| KnobError::NotTables(name.clone()))?;
                array
                    .iter_mut()
                    .find(|t| t.get("name").and_then(toml::Value::as_str) == Some(name))
                    .ok_or_else(|| KnobError::NoTableNamed(name.clone()))?
            }
        };
    }
    match at {
        toml::Value::Integer(_) => *at = toml::Value::Integer(value.round() as i64),
        toml::Value::Float(_) => *at = toml::Value::Float(value),
        other => return Err(KnobError::NotANumber(other.type_str())),
    }
    Ok(())
}

/// A loaded scenario, ready to evaluate parameter sets.
pub struct Scenario {
    file: ScenarioFile,
    docs: [toml::Value; 4],
    paths: [PathBuf; 4],
    knobs: Vec<Knob>,
    names: Vec<String>,
}

/// A TOML file of the scenario's (the scenario itself, or a document it names), read whole.
fn read_toml<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, ScenarioError> {
    Ok(crate::config::read_toml(path)?)
}

/// The numeric fields of `compare`'s summary, by name.
fn metrics_of(summary: &Summary) -> serde_json::Map<String, serde_json::Value> {
    match serde_json::to_value(summary) {
        Ok(serde_json::Value::Object(m)) => m,
        _ => serde_json::Map::new(),
    }
}

/// The summary fields a scenario can rank by.
pub fn metric_names() -> Vec<String> {
    metrics_of(&Summary::default())
        .into_iter()
        .filter(|(_, v)| !v.is_object())
        .map(|(k, _)| k)
        .collect()
}

impl Scenario {
    /// Reads the scenario at `path` for the parameters `params`: every parameter needs exactly
    /// one knob, every knob a parameter, and the metric must be one of [`metric_names`].
    pub fn load(path: &Path, params: &[Parameter]) -> Result<Scenario, ScenarioError> {
        let file: ScenarioFile = read_toml(path)?;
        let names = metric_names();
        if !names.contains(&file.metric) {
            return Err(ScenarioError::Metric {
                path: path.to_owned(),
                metric: file.metric.clone(),
                known: names,
            });
        }
        let base = path.parent().unwrap_or(Path::new("."));
        let paths = [&file.scene, &file.drive, &file.reality, &file.model].map(|p| base.join(p));
        let [scene, drive, reality, model] = &paths;
        let docs = [
            read_toml(scene)?,
            read_toml(drive)?,
            read_toml(reality)?,
            read_toml(model)?,
        ];
        let mut knobs = Vec::new();
        for k in &file.knob {
            let column = params
                .iter()
                .position(|p| p.name == k.parameter)
                .ok_or_else(|| ScenarioError::UnknownParameter {
                    path: path.to_owned(),
                    parameter: k.parameter.clone(),
                })?;
            let (doc, steps) = parse_path(&k.set).map_err(|source| ScenarioError::Knob {
                knob: format!("{}: {}", path.display(), k.set),
                source,
            })?;
            knobs.push(Knob {
                doc,
                path: steps,
                column,
                text: k.set.clone(),
            });
        }
        for p in params {
            let knobs = file.knob.iter().filter(|k| k.parameter == p.name).count();
            if knobs != 1 {
                return Err(ScenarioError::Knobs {
                    path: path.to_owned(),
                    parameter: p.name.clone(),
                    knobs,
                });
            }
        }
        Ok(Scenario {
            file,
            docs,
            paths,
            knobs,
            names: params.iter().map(|p| p.name.clone()).collect(),
        })
    }

    /// The four documents it reads (scene, drive, reality, model): what a drive of it depends
    /// on, besides the files they name (the scene's meshes, the drive's [`Scenario::rig`]).
    pub fn files(&self) -> &[PathBuf] {
        &self.paths
    }

    /// The rig the drive document names, resolved against the drive file's folder (`None`
    /// when the drive does not name one: it then fails to load, and says so).
    pub fn rig(&self) -> Option<PathBuf> {
        let rig = self.docs[Doc::Drive as usize].get("rig")?.as_str()?;
        let drive = &self.paths[Doc::Drive as usize];
        Some(drive.parent().unwrap_or(Path::new(".")).join(rig))
    }

    /// The metric ranked by.
    pub fn metric(&self) -> &str {
        &self.file.metric
    }

    /// Checks that the knobs reach their numbers and the changed files still load, with
    /// `values` (e.g. the first parameter set), before any drive is made.
    pub fn check(&self, values: &[f64]) -> Result<(), ScenarioError> {
        self.set_knobs(values)?;
        self.documents(values)
            .map(|_| ())
            .map_err(|e| ScenarioError::Documents(Box::new(e)))
    }

    /// The four documents with the knobs set to `values`.
    fn set_knobs(&self, values: &[f64]) -> Result<[toml::Value; 4], ScenarioError> {
        let mut docs = self.docs.clone();
        for k in &self.knobs {
            let v = values[k.column];
            set_number(&mut docs[k.doc as usize], &k.path, v).map_err(|source| {
                ScenarioError::Knob {
                    knob: k.text.clone(),
                    source,
                }
            })?;
        }
        Ok(docs)
    }

    fn documents(&self, values: &[f64]) -> Result<Docs, StepError> {
        let docs = self.set_knobs(values).map_err(|e| StepError::Step {
            step: "knobs".into(),
            source: Box::new(e),
        })?;
        let named = |d: Doc, what: String| StepError::Document {
            path: self.paths[d as usize].clone(),
            what,
        };
        let [scene, drive, reality, model] = docs;
        let scene: SceneFile = scene
            .try_into()
            .map_err(|e: toml::de::Error| named(Doc::Scene, e.to_string()))?;
        let drive: DriveFile = drive
            .try_into()
            .map_err(|e: toml::de::Error| named(Doc::Drive, e.to_string()))?;
        if parse_utc(&drive.start_utc).is_none() {
            return Err(named(
                Doc::Drive,
                format!(
                    "start_utc '{}' is not YYYY-MM-DDTHH:MM:SSZ",
                    drive.start_utc
                ),
            ));
        }
        let model_file = |v: toml::Value, d: Doc| -> Result<ModelFile, StepError> {
            let m: ModelFile = v
                .try_into()
                .map_err(|e: toml::de::Error| named(d, e.to_string()))?;
            m.validate().map_err(|e| named(d, e.to_string()))?;
            Ok(m)
        };
        Ok(Docs {
            scene,
            drive,
            reality: model_file(reality, Doc::Reality)?,
            model: model_file(model, Doc::Model)?,
        })
    }

    /// The metric for one parameter set (`row` is 1-based, for messages), made in `work`
    /// (created, and removed afterwards).
    pub fn evaluate(
        &self,
        row: usize,
        values: &[f64],
        seed: u64,
        work: &Path,
    ) -> Result<f64, ScenarioError> {
        let fail = |source: StepError| ScenarioError::Sample {
            row,
            values: self
                .names
                .iter()
                .zip(values)
                .map(|(n, v)| format!("{n}={v:.4}"))
                .collect::<Vec<_>>()
                .join(", "),
            source: Box::new(source),
        };
        std::fs::create_dir_all(work).map_err(|e| fail(step(work.display(), e)))?;
        let out = self.run_pipeline(values, seed, work).map_err(fail);
        let _ = std::fs::remove_dir_all(work);
        out
    }

    fn run_pipeline(&self, values: &[f64], seed: u64, work: &Path) -> Result<f64, StepError> {
        let docs = self.documents(values)?;
        if !docs.drive.lidar.returns {
            // An evaluation compares returns: a drive that casts none would score a model
            // against empty clouds.
            return Err(step(
                "synth",
                std::io::Error::other(
                    "the drive file sets [lidar] returns = false: an evaluation compares the lidar's returns",
                ),
            ));
        }
        let dir = |d: Doc| {
            self.paths[d as usize]
                .parent()
                .unwrap_or(Path::new("."))
                .to_owned()
        };
        let (scene_base, drive_base) = (dir(Doc::Scene), dir(Doc::Drive));
        let job = SynthJob {
            scene_file: &docs.scene,
            scene_base: &scene_base,
            drive: &docs.drive,
            drive_base: &drive_base,
            truth: &docs.reality,
            seed,
            compress: false,
            errors: self.file.errors,
        };
        let rep = synth_rep(&job, 1, work).map_err(|e| step("synth", e))?;
        let rig_path = drive_base.join(&docs.drive.rig);
        let rig = Rig::load(&rig_path).map_err(|e| step("rig", e))?;
        let rig_text =
            std::fs::read_to_string(&rig_path).map_err(|e| step(rig_path.display(), e))?;
        let run = work.join("run.mcap");
        record_from(&rig, &rig_text, &[work.join(&rep.capture)], &run)
            .map_err(|e| step("record", e))?;
        let scene_path = &self.paths[Doc::Scene as usize];
        let scene = Scene::from_file(docs.scene.clone(), &scene_base, scene_path)
            .map_err(|e| step("scene", e))?;
        let truth_path = work.join("truth.csv");
        let truth_text =
            std::fs::read_to_string(&truth_path).map_err(|e| step(truth_path.display(), e))?;
        let truth = Trajectory::from_csv(&truth_text).map_err(|e| step(truth_path.display(), e))?;
        let sim = work.join("sim.mcap");
        let quiet = |_: u64, _: u64| {};
        resim(
            &run,
            Some(&rig),
            &scene,
            scene_path,
            &docs.model,
            PoseSource::File(truth.clone(), "the synthesizer's true trajectory".into()),
            true,
            seed,
            // Only measured here: compare reads the VelodyneScans.
            ViewingClouds::LeaveOut,
            &sim,
            &quiet,
        )
        .map_err(|e| step("resim", e))?;
        let region = match &self.file.roi {
            Some(r) => r.parse::<Region>().map_err(|e| step("roi", e))?,
            None => Region::All,
        };
        let opts = Options {
            cell_m: self.file.cell_m,
            k: self.file.k,
            dims: if self.file.voxel {
                Dims::Voxel
            } else {
                Dims::Bev
            },
            region,
            exclude_ground: !self.file.keep_ground,
            // Poses and scene are the synthesizer's truth, not measured: the reference accuracy
            // that the admissible cell guards against (§6) does not enter.
            allow_small_cell: true,
            trajectory: Some(truth),
            sensor_frame: false,
            grid_phases: crate::metrics::compare::DEFAULT_GRID_PHASES,
            // Only the summary's metrics are read.
            curve_every: 0,
            point_metrics: true,
        };
        let c = compare(&run, &sim, Some(&rig), Some(&scene), opts, &quiet)
            .map_err(|e| step("compare", e))?;
        metrics_of(&c.summary)
            .get(&self.file.metric)
            .and_then(serde_json::Value::as_f64)
            .filter(|v| v.is_finite())
            .ok_or_else(|| StepError::NoMetric(self.file.metric.clone()))
    }
}

/// A failed step of the pipeline, named.
fn step(
    name: impl std::fmt::Display,
    e: impl std::error::Error + Send + Sync + 'static,
) -> StepError {
    StepError::Step {
        step: name.to_string(),
        source: Box::new(e),
    }
}

/// The four documents after the knobs.
struct Docs {
    scene: SceneFile,
    drive: DriveFile,
    reality: ModelFile,
    model: ModelFile,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knob_paths_parse_into_file_keys_names_and_indices() {
        let (doc, steps) = parse_path("scene.object[car 1].pose.x").unwrap();
        assert_eq!(doc, Doc::Scene);
        assert_eq!(
            steps,
            vec![
                Step::Key("object".into()),
                Step::Named("car 1".into()),
                Step::Key("pose".into()),
                Step::Key("x".into())
            ]
        );
        let (doc, steps) = parse_path("drive.path.waypoints.1.0").unwrap();
        assert_eq!(doc, Doc::Drive);
        assert_eq!(steps[2..], [Step::Index(1), Step::Index(0)]);
        assert!(parse_path("weather.rate").is_err());
        assert!(parse_path("scene").is_err());
        assert!(parse_path("scene.object[car").is_err());
    }

    #[test]
    fn numbers_are_set_where_the_path_says_and_typos_are_refused() {
        let mut doc: toml::Value = toml::from_str(
            "n = 3\n[path]\nspeed = 2.0\nw = [[0.0, 1.0], [2.0, 3.0]]\n[[effect]]\nname = \"weather\"\nextinction_per_m = 0.01\n",
        )
        .unwrap();
        let set = |doc: &mut toml::Value, p: &str, v: f64| {
            let (_, steps) = parse_path(&format!("model.{p}")).unwrap();
            set_number(doc, &steps, v)
        };
        set(&mut doc, "path.speed", 4.5).unwrap();
        set(&mut doc, "path.w.1.0", -7.0).unwrap();
        set(&mut doc, "effect[weather].extinction_per_m", 0.05).unwrap();
        set(&mut doc, "n", 4.6).unwrap();
        assert_eq!(doc["path"]["speed"].as_float(), Some(4.5));
        assert_eq!(doc["path"]["w"][1][0].as_float(), Some(-7.0));
        assert_eq!(doc["effect"][0]["extinction_per_m"].as_float(), Some(0.05));
        assert_eq!(doc["n"].as_integer(), Some(5));
        assert!(set(&mut doc, "pth.speed", 1.0)
            .unwrap_err()
            .to_string()
            .contains("no key 'pth'"));
        assert!(set(&mut doc, "effect[rain].x", 1.0)
            .unwrap_err()
            .to_string()
            .contains("no table named 'rain'"));
        assert!(set(&mut doc, "path.w.5.0", 1.0)
            .unwrap_err()
            .to_string()
            .contains("index 5"));
        assert!(set(&mut doc, "effect[weather].name", 1.0)
            .unwrap_err()
            .to_string()
            .contains("not a number"));
    }
}

//! The campaign file: which drives, of which scenarios, re-simulated with which models, through
//! which steps.
//!
//! ```toml
//! name = "parking"
//! steps = ["record", "check", "resim", "compare", "validate", "gap", "tables", "report"]
//! rig = "../../rigs/demo.toml"          # for `record` of captures
//!
//! [[drive]]
//! recordings = "rep-*/drive.pcapng.zst" # a glob: recordings (.mcap) or captures (.pcap, .pcapng, .zst)
//! scene = "{dir}/scene.toml"            # {dir}: the directory of each drive matched
//! scenario = "parking"
//!
//! [[scenario]]
//! name = "parking"
//! phases = "phases.toml"                # `validate --phases`
//! gap_model = "idealized"               # the gap workflow's start model (default: the first)
//!
//! [[model]]
//! name = "idealized"
//! file = "idealized.toml"
//!
//! [gap]                                 # optional: where the gap step's full re-simulations run
//! jobs = 2                              # `gap --jobs`: as local tasks, this many at a time
//! # engine = "python -m hilrig_ray --address auto --hilrig /opt/hilrig/bin/hilrig"  # `gap --engine`
//! ```
//!
//! Relative paths are relative to the campaign file. Any path may be an object's URL
//! (`s3://bucket/drives/rep-*/drive.pcapng.zst`), and a campaign file that is an object names
//! objects beside it with relative paths (store.rs). A drive's name (the stem of its file
//! names, and how the plan's task ids name it) is its file's stem; where stems repeat (every
//! repetition's capture is `drive.pcapng.zst`) it is its directory's name, and where those
//! repeat too, its path. Everything a step will need is looked for here, so that a campaign
//! that cannot run fails before its first task, not an hour into it.

use super::mirror;
use super::resolve::{existing_in, joined, matching, named_files, parent_of, read_text, Names};
use super::CampaignError;
use serde::Deserialize;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

pub use super::gap_trials::{GapEntry, GapTrials};
pub use super::step::Step;

/// The campaign file as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CampaignFile {
    /// The campaign's name.
    pub name: String,
    /// The steps to run.
    pub steps: Vec<Step>,
    /// The rig file `record` takes for captures.
    #[serde(default)]
    pub rig: Option<PathBuf>,
    /// The drives, by pattern.
    #[serde(rename = "drive", default)]
    pub drives: Vec<DriveEntry>,
    /// The scenarios the drives are repetitions of.
    #[serde(rename = "scenario", default)]
    pub scenarios: Vec<ScenarioEntry>,
    /// The models every drive is re-simulated with.
    #[serde(rename = "model", default)]
    pub models: Vec<ModelEntry>,
    /// Where the gap step's full re-simulations run (default: inside its task).
    #[serde(default)]
    pub gap: Option<GapEntry>,
}

/// Drives of one scenario, by a pattern.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveEntry {
    /// A glob of recordings or captures.
    pub recordings: String,
    /// Each drive's surveyed scene; `{dir}` stands for the drive's directory.
    pub scene: String,
    /// The scenario they repeat (default: one scenario called `default`).
    #[serde(default)]
    pub scenario: Option<String>,
}

/// What a scenario's repetitions are validated and studied with.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioEntry {
    /// Its name, as the drives give it.
    pub name: String,
    /// `validate --phases`: the scenario's phases.
    #[serde(default)]
    pub phases: Option<PathBuf>,
    /// The gap workflow's start model, by name (default: the first model).
    #[serde(default)]
    pub gap_model: Option<String>,
    /// A model known to have made the data (synthesized drives), for `gap --reference-model`.
    #[serde(default)]
    pub reference_model: Option<String>,
    /// How many of its drives (in name order) the gap workflow fits on; the others validate
    /// (default: the first half, rounded up).
    #[serde(default)]
    pub fit_runs: Option<usize>,
}

/// A lidar model.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelEntry {
    /// Its name in output paths and task ids.
    pub name: String,
    /// The model file.
    pub file: PathBuf,
}

/// A drive, found.
#[derive(Clone, Debug, PartialEq)]
pub struct Drive {
    /// Its name (unique in the campaign).
    pub name: String,
    /// The file matched.
    pub source: PathBuf,
    /// Whether it is a capture that `record` turns into a recording first.
    pub is_capture: bool,
    /// Its scene.
    pub scene: PathBuf,
    /// The files its scene names (meshes, actors' trajectories): inputs of every task that
    /// reads the scene, so that an edited mesh re-runs them and a worker fetches them.
    pub scene_files: Vec<PathBuf>,
    /// Its scenario's index in [`Campaign::scenarios`].
    pub scenario: usize,
}

/// A scenario, resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Its name.
    pub name: String,
    /// Its phases file.
    pub phases: Option<PathBuf>,
    /// The gap workflow's start model (index into [`Campaign::models`]).
    pub gap_model: usize,
    /// The reference model, if any.
    pub reference_model: Option<usize>,
    /// Drives the gap workflow fits on.
    pub fit_runs: usize,
    /// Its drives (indices into [`Campaign::drives`]), in name order.
    pub drives: Vec<usize>,
}

/// A model, resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// Its name.
    pub name: String,
    /// Its file.
    pub file: PathBuf,
}

/// A campaign with its patterns matched and its paths checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Campaign {
    /// The file it was read from.
    pub path: PathBuf,
    /// Its name.
    pub name: String,
    /// The steps, each once, in the method's order.
    pub steps: BTreeSet<Step>,
    /// The rig file for `record`.
    pub rig: Option<PathBuf>,
    /// The files the rig names (its DBC).
    pub rig_files: Vec<PathBuf>,
    /// The drives, in name order.
    pub drives: Vec<Drive>,
    /// The scenarios, in the file's order (an implicit `default` last).
    pub scenarios: Vec<Scenario>,
    /// The models, in the file's order.
    pub models: Vec<Model>,
    /// Where the gap step's full re-simulations run (`None`: inside the gap task).
    pub gap_trials: Option<GapTrials>,
}

/// Which extensions make a file a recording or a capture.
fn kind_of(path: &Path) -> Option<bool> {
    let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
    let name = name.strip_suffix(".zst").unwrap_or(&name);
    if name.ends_with(".mcap") {
        Some(false)
    } else if name.ends_with(".pcap") || name.ends_with(".pcapng") {
        Some(true)
    } else {
        None
    }
}

/// The file name without the extensions [`kind_of`] knows.
fn stem(path: &Path) -> String {
    let mut name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    for ext in [".zst", ".mcap", ".pcapng", ".pcap"] {
        if name.to_ascii_lowercase().ends_with(ext) {
            name.truncate(name.len() - ext.len());
        }
    }
    name
}

/// A name that is safe as one component of a path and a task id.
fn safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '-'
            }
        })
        .collect()
}

impl Campaign {
    /// Reads and resolves a campaign file.
    pub fn load(path: &Path) -> Result<Campaign, CampaignError> {
        let text = read_text("the campaign file", path)?;
        crate::config::check_finite(&text).map_err(|e| CampaignError::Invalid {
            path: path.to_owned(),
            what: e.to_string(),
        })?;
        let file: CampaignFile = toml::from_str(&text).map_err(|e| CampaignError::Invalid {
            path: path.to_owned(),
            what: e.to_string(),
        })?;
        let path = if mirror::is_url(path) {
            path.to_owned()
        } else {
            std::path::absolute(path).map_err(|source| CampaignError::Io {
                path: path.to_owned(),
                source,
            })?
        };
        Campaign::resolve(&path, file)
    }

    /// Resolves `file`, read from `path` (absolute).
    pub fn resolve(path: &Path, file: CampaignFile) -> Result<Campaign, CampaignError> {
        let base = parent_of(path);
        let r = Resolver { path, base: &base };
        if file.steps.is_empty() {
            return Err(r.invalid("`steps` is empty: name at least one step".into()));
        }
        // Checked before any drive is looked for (which may list a bucket).
        let gap_trials = file
            .gap
            .as_ref()
            .map(GapTrials::of)
            .transpose()
            .map_err(|e| r.invalid(e))?;
        if gap_trials.is_some() && !file.steps.contains(&Step::Gap) {
            return Err(r.invalid(
                "[gap] says where the gap step's trials run, but \"gap\" is not among the steps"
                    .into(),
            ));
        }
        if file.steps.contains(&Step::Efast) {
            return Err(r.invalid(
                "\"efast\" is not a step of a campaign: an eFAST design is a plan of its own (`hilrig efast plan`, `hilrig efast run`)".into(),
            ));
        }
        let models = file
            .models
            .iter()
            .map(|m| {
                Ok(Model {
                    name: safe(&m.name),
                    file: r.existing(format!("model '{}'", m.name), &m.file)?,
                })
            })
            .collect::<Result<Vec<_>, CampaignError>>()?;
        if let Some(dup) = first_repeat(models.iter().map(|m| m.name.as_str())) {
            return Err(r.invalid(format!("two models are called '{dup}'")));
        }
        let rig = match &file.rig {
            Some(p) => Some(r.existing("the rig".into(), p)?),
            None => None,
        };
        let rig_files = match &rig {
            Some(p) => named_files(p, Names::Rig)?,
            None => Vec::new(),
        };
        let found = r.drives(&file.drives)?;
        let names = drive_names(
            r.base,
            &found.iter().map(|f| f.source.clone()).collect::<Vec<_>>(),
        )
        .ok_or_else(|| r.invalid("two drives have the same path".into()))?;
        let mut scenarios = r.scenarios(&file.scenarios, &models)?;
        // Undeclared scenario names only where none is declared (a typo is not a new scenario).
        let declared = !scenarios.is_empty();
        let mut drives = Vec::new();
        for (f, name) in found.into_iter().zip(names) {
            let key = safe(&f.scenario);
            let index = match scenarios.iter().position(|s| s.name == key) {
                Some(i) => i,
                None if declared => {
                    return Err(r.invalid(format!(
                        "{} is of scenario '{}', which is not a [[scenario]]",
                        f.source.display(),
                        f.scenario
                    )))
                }
                None => {
                    scenarios.push(Scenario {
                        name: key,
                        phases: None,
                        gap_model: 0,
                        reference_model: None,
                        fit_runs: 0,
                        drives: Vec::new(),
                    });
                    scenarios.len() - 1
                }
            };
            let scene_files = named_files(&f.scene, Names::Scene)?;
            drives.push(Drive {
                name,
                source: f.source,
                is_capture: f.is_capture,
                scene: f.scene,
                scene_files,
                scenario: index,
            });
        }
        drives.sort_by(|a, b| a.name.cmp(&b.name));
        for (i, d) in drives.iter().enumerate() {
            scenarios[d.scenario].drives.push(i);
        }
        let mut campaign = Campaign {
            path: path.to_owned(),
            name: file.name,
            steps: file.steps.iter().copied().collect(),
            rig,
            rig_files,
            drives,
            scenarios,
            models,
            gap_trials,
        };
        campaign.check_steps()?;
        for s in &mut campaign.scenarios {
            if s.fit_runs == 0 {
                s.fit_runs = s.drives.len().div_ceil(2);
            }
        }
        Ok(campaign)
    }

    /// What the chosen steps need from each other and from the file.
    fn check_steps(&self) -> Result<(), CampaignError> {
        let invalid = |what: String| CampaignError::Invalid {
            path: self.path.clone(),
            what,
        };
        let has = |s: Step| self.steps.contains(&s);
        if let Some(d) = self.drives.iter().find(|d| d.is_capture) {
            if !has(Step::Record) && self.steps.iter().any(|&s| s != Step::Report) {
                return Err(invalid(format!(
                    "{} is a capture: add \"record\" to the steps (or name the recordings)",
                    d.source.display()
                )));
            }
            if has(Step::Record) && self.rig.is_none() {
                return Err(invalid(format!(
                    "{} is a capture: `record` needs the campaign's `rig`",
                    d.source.display()
                )));
            }
        }
        for (step, needs) in [(Step::Compare, Step::Resim), (Step::Validate, Step::Resim)] {
            if has(step) && !has(needs) {
                return Err(invalid(format!(
                    "\"{}\" needs \"{}\" among the steps",
                    step.name(),
                    needs.name()
                )));
            }
        }
        if (has(Step::Resim) || has(Step::Gap)) && self.models.is_empty() {
            return Err(invalid("resim and gap need at least one [[model]]".into()));
        }
        for step in [Step::Report, Step::Tables] {
            if has(step)
                && ![Step::Check, Step::Compare, Step::Validate, Step::Gap]
                    .iter()
                    .any(|&s| has(s))
            {
                return Err(invalid(format!(
                    "\"{}\" needs a step that writes JSON (check, compare, validate or gap)",
                    step.name()
                )));
            }
        }
        for s in &self.scenarios {
            if s.drives.is_empty() {
                return Err(invalid(format!("scenario '{}' has no drives", s.name)));
            }
            let n = s.drives.len();
            if (has(Step::Validate) || has(Step::Gap)) && n < 2 {
                return Err(invalid(format!(
                    "scenario '{}' has one drive: validate and gap need repetitions (two at least)",
                    s.name
                )));
            }
            if s.fit_runs > 0 && s.fit_runs >= n {
                return Err(invalid(format!(
                    "scenario '{}': fit_runs = {} leaves none of its {n} drives to validate",
                    s.name, s.fit_runs
                )));
            }
        }
        Ok(())
    }
}

/// A drive matched, before it is named.
struct Found {
    source: PathBuf,
    is_capture: bool,
    scene: PathBuf,
    scenario: String,
}

/// Resolves the campaign file's paths against its directory.
struct Resolver<'a> {
    path: &'a Path,
    base: &'a Path,
}

impl Resolver<'_> {
    fn invalid(&self, what: String) -> CampaignError {
        CampaignError::Invalid {
            path: self.path.to_owned(),
            what,
        }
    }

    /// An existing file by its canonical path: the plan's command lines read plainly, and one
    /// file reached two ways is one file.
    fn existing(&self, what: String, p: &Path) -> Result<PathBuf, CampaignError> {
        existing_in(self.base, what, p)
    }

    /// Every drive the patterns match, each with its scene.
    fn drives(&self, entries: &[DriveEntry]) -> Result<Vec<Found>, CampaignError> {
        if entries.is_empty() {
            return Err(self.invalid("no [[drive]]: name the drives' recordings".into()));
        }
        let mut found = Vec::new();
        for (k, d) in entries.iter().enumerate() {
            let pattern = joined(self.base, Path::new(&d.recordings))?;
            let files = matching(&pattern)?.map_err(|e| {
                self.invalid(format!("drive {}: pattern '{}': {e}", k + 1, d.recordings))
            })?;
            if files.is_empty() {
                return Err(CampaignError::NoDrive {
                    entry: k + 1,
                    pattern: pattern.display().to_string(),
                });
            }
            for source in files {
                let is_capture = kind_of(&source).ok_or_else(|| {
                    self.invalid(format!(
                        "drive {}: {} is neither a recording (.mcap) nor a capture (.pcap, .pcapng, either .zst)",
                        k + 1,
                        source.display()
                    ))
                })?;
                let dir = parent_of(&source).to_string_lossy().into_owned();
                let scene = d.scene.replace("{dir}", &dir);
                if scene.contains('{') {
                    return Err(self.invalid(format!(
                        "drive {}: scene '{}': the only placeholder is {{dir}}",
                        k + 1,
                        d.scene
                    )));
                }
                let scene = self.existing(
                    format!("the scene of {}", source.display()),
                    Path::new(&scene),
                )?;
                let scenario = d.scenario.clone().unwrap_or_else(|| "default".into());
                found.push(Found {
                    source,
                    is_capture,
                    scene,
                    scenario,
                });
            }
        }
        if let Some(dup) = first_repeat(found.iter().map(|f| f.source.clone())) {
            return Err(self.invalid(format!(
                "{} is matched by two [[drive]] patterns",
                dup.display()
            )));
        }
        Ok(found)
    }

    /// The declared scenarios, in the file's order, without drives yet.
    fn scenarios(
        &self,
        entries: &[ScenarioEntry],
        models: &[Model],
    ) -> Result<Vec<Scenario>, CampaignError> {
        let model = |name: &Option<String>, scenario: &str| match name {
            None => Ok(None),
            Some(name) => models
                .iter()
                .position(|m| &m.name == name)
                .map(Some)
                .ok_or_else(|| {
                    self.invalid(format!(
                        "scenario '{scenario}' names model '{name}', which is not a [[model]]"
                    ))
                }),
        };
        let mut out = Vec::new();
        for s in entries {
            let phases = match &s.phases {
                Some(p) => Some(self.existing(format!("the phases of scenario '{}'", s.name), p)?),
                None => None,
            };
            out.push(Scenario {
                name: safe(&s.name),
                phases,
                gap_model: model(&s.gap_model, &s.name)?.unwrap_or(0),
                reference_model: model(&s.reference_model, &s.name)?,
                fit_runs: s.fit_runs.unwrap_or(0),
                drives: Vec::new(),
            });
        }
        if let Some(dup) = first_repeat(out.iter().map(|s| s.name.clone())) {
            return Err(self.invalid(format!("two scenarios are called '{dup}'")));
        }
        Ok(out)
    }
}

/// The first value that occurs twice.
fn first_repeat<T: Ord + Clone>(items: impl Iterator<Item = T>) -> Option<T> {
    let mut seen = BTreeSet::new();
    items.into_iter().find(|i| !seen.insert(i.clone()))
}

/// The drives' names: stems where those are unique, else directory names, else relative paths.
fn drive_names(base: &Path, files: &[PathBuf]) -> Option<Vec<String>> {
    let unique = |names: &[String]| first_repeat(names.iter()).is_none();
    let stems: Vec<String> = files.iter().map(|f| safe(&stem(f))).collect();
    if unique(&stems) {
        return Some(stems);
    }
    let dirs: Vec<String> = files
        .iter()
        .map(|f| {
            f.parent()
                .and_then(Path::file_name)
                .map(|n| safe(&n.to_string_lossy()))
                .unwrap_or_default()
        })
        .collect();
    if unique(&dirs) && dirs.iter().all(|d| !d.is_empty()) {
        return Some(dirs);
    }
    let paths: Vec<String> = files
        .iter()
        .map(|f| {
            let rel = f.strip_prefix(base).unwrap_or(f);
            let rel = rel.with_file_name(stem(rel));
            safe(&rel.to_string_lossy().replace('/', "-"))
        })
        .collect();
    unique(&paths).then_some(paths)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_stems_then_directories_then_paths() {
        let base = Path::new("/c");
        let f = |s: &str| PathBuf::from(s);
        assert_eq!(
            drive_names(base, &[f("/c/a/one.mcap"), f("/c/b/two.pcapng.zst")]).unwrap(),
            ["one", "two"]
        );
        assert_eq!(
            drive_names(
                base,
                &[
                    f("/c/rep-01/drive.pcapng.zst"),
                    f("/c/rep-02/drive.pcapng.zst")
                ]
            )
            .unwrap(),
            ["rep-01", "rep-02"]
        );
        assert_eq!(
            drive_names(base, &[f("/c/x/rep/drive.mcap"), f("/c/y/rep/drive.mcap")]).unwrap(),
            ["x-rep-drive", "y-rep-drive"]
        );
    }

    #[test]
    fn kinds_by_extension() {
        assert_eq!(kind_of(Path::new("a/b.mcap")), Some(false));
        assert_eq!(kind_of(Path::new("a/b.pcapng.zst")), Some(true));
        assert_eq!(kind_of(Path::new("a/b.PCAP")), Some(true));
        assert_eq!(kind_of(Path::new("a/b.csv")), None);
    }
}

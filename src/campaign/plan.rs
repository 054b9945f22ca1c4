//! The task graph of a campaign: each task one invocation of an existing command on files,
//! with the files it reads and writes and the tasks it waits for.
//!
//! The graph is derived from the files, as `make` derives it: a task waits for the task that
//! writes a file it reads (plus the one gate the method has: a drive is re-simulated and
//! studied only after its reference data passed `check`). So a campaign whose drives lie among
//! its own outputs is a cycle, and two tasks writing one file is a conflict; both are refused
//! before anything runs. The plan is written as JSON (`hilrig campaign plan --json`) so that any
//! engine can run it: every path in it is absolute, every command line complete.

use super::file::{Campaign, GapTrials, Scenario, Step};
use super::tables::{Labels, TableKind};
pub use super::task::Task;
use super::CampaignError;
use crate::gap::study::{Role, RunEntry, StudyFile};
use crate::output::{Output, OutputKind};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A file the plan itself makes before any task runs (the gap workflow's study files).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedFile {
    /// Where.
    pub path: PathBuf,
    /// Its whole text.
    pub text: String,
}

/// A campaign's tasks in an order that runs each after the ones it waits for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The campaign's name.
    pub campaign: String,
    /// The campaign file.
    pub campaign_file: PathBuf,
    /// The output directory.
    pub out: PathBuf,
    /// Files written before the first task.
    pub files: Vec<PlannedFile>,
    /// The tasks.
    pub tasks: Vec<Task>,
}

impl Output for Plan {
    const KIND: OutputKind = OutputKind::CampaignPlan;
    const SCHEMA: u32 = 4;
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// Where a campaign's files go under its output directory.
struct Layout<'a> {
    out: &'a Path,
}

impl Layout<'_> {
    fn rec(&self, drive: &str) -> PathBuf {
        self.out.join("rec").join(format!("{drive}.mcap"))
    }
    fn check(&self, drive: &str) -> PathBuf {
        self.out.join("check").join(format!("{drive}.json"))
    }
    fn sim(&self, model: &str, drive: &str) -> PathBuf {
        self.out
            .join("sim")
            .join(model)
            .join(format!("{drive}.mcap"))
    }
    fn compare(&self, model: &str, drive: &str) -> PathBuf {
        self.out
            .join("compare")
            .join(model)
            .join(format!("{drive}.json"))
    }
    fn validate(&self, scenario: &str, model: &str) -> PathBuf {
        self.out
            .join("validate")
            .join(scenario)
            .join(format!("{model}.json"))
    }
    fn gap(&self, scenario: &str) -> PathBuf {
        self.out.join("gap").join(scenario)
    }
    fn log(&self, id: &str) -> PathBuf {
        self.out.join("logs").join(format!("{id}.log"))
    }
}

/// Adds a campaign's tasks step by step, with defaults for their exit codes and log.
struct Builder<'a> {
    campaign: &'a Campaign,
    layout: Layout<'a>,
    /// Each drive's recording: the capture recorded, or the file as given.
    recs: Vec<PathBuf>,
    tasks: Vec<Task>,
    /// Gate edges: task id -> the ids it waits for beyond its files.
    gates: BTreeMap<String, Vec<String>>,
    /// Files the plan writes itself.
    files: Vec<PlannedFile>,
    /// The JSON outputs with the name and labels of their tables.
    tables: Vec<(OutputKind, PathBuf, String, Labels)>,
}

impl Builder<'_> {
    fn has(&self, step: Step) -> bool {
        self.campaign.steps.contains(&step)
    }

    fn add(
        &mut self,
        id: String,
        step: Step,
        args: Vec<String>,
        inputs: Vec<PathBuf>,
        outputs: Vec<PathBuf>,
    ) -> &mut Task {
        let log = self.layout.log(&id);
        self.tasks
            .push(Task::new(id, step, args, (inputs, outputs), log));
        self.tasks.last_mut().expect("just pushed")
    }

    /// Notes a JSON output for the `tables` step: its tables' file name and labels.
    fn table(
        &mut self,
        kind: OutputKind,
        json: &Path,
        name: &str,
        [drive, scenario, model]: [Option<&str>; 3],
    ) {
        if self.has(Step::Tables) {
            let labels = Labels {
                drive: drive.map(str::to_owned),
                scenario: scenario.map(str::to_owned),
                model: model.map(str::to_owned),
            };
            self.tables
                .push((kind, json.to_owned(), name.to_owned(), labels));
        }
    }

    /// `table` of every JSON noted: Parquet files under `OUT/tables/TABLE/NAME.parquet`.
    fn tables(&mut self) {
        let dir = self.layout.out.join("tables");
        for (kind, json, name, labels) in std::mem::take(&mut self.tables) {
            let mut args = vec![
                "table".into(),
                s(&json),
                "--dir".into(),
                s(&dir),
                "--name".into(),
                name.clone(),
            ];
            for (flag, v) in [
                ("--drive", &labels.drive),
                ("--scenario", &labels.scenario),
                ("--model", &labels.model),
            ] {
                if let Some(v) = v {
                    args.extend([flag.into(), v.clone()]);
                }
            }
            let outputs = TableKind::of(kind)
                .iter()
                .map(|k| dir.join(k.name()).join(format!("{name}.parquet")))
                .collect();
            let id = format!("tables/{}/{name}", kind.name());
            self.add(id, Step::Tables, args, vec![json], outputs);
        }
    }

    /// The check of drive `d`, which its re-simulations and studies wait for.
    fn check_of(&self, d: &str) -> Option<String> {
        self.has(Step::Check).then(|| format!("check/{d}"))
    }

    /// `record` and `check` per drive.
    fn drives(&mut self) {
        let c = self.campaign;
        for (d, rec) in c.drives.iter().zip(self.recs.clone()) {
            if d.is_capture && self.has(Step::Record) {
                let rig = c
                    .rig
                    .clone()
                    .expect("checked: captures with record have a rig");
                let args = vec![
                    "record".into(),
                    "--rig".into(),
                    s(&rig),
                    "--from".into(),
                    s(&d.source),
                    "-o".into(),
                    s(&rec),
                ];
                self.add(
                    format!("record/{}", d.name),
                    Step::Record,
                    args,
                    [vec![rig, d.source.clone()], c.rig_files.clone()].concat(),
                    vec![rec.clone()],
                );
            }
            if self.has(Step::Check) {
                let json = self.layout.check(&d.name);
                let args = vec![
                    "check".into(),
                    s(&rec),
                    "--scene".into(),
                    s(&d.scene),
                    "--json".into(),
                    s(&json),
                ];
                let scenario = c.scenarios[d.scenario].name.as_str();
                self.table(
                    OutputKind::Check,
                    &json,
                    &d.name,
                    [Some(&d.name), Some(scenario), None],
                );
                let t = self.add(
                    format!("check/{}", d.name),
                    Step::Check,
                    args,
                    [vec![rec, d.scene.clone()], d.scene_files.clone()].concat(),
                    vec![json],
                );
                // A run that fails its check is a result; nothing waiting for it runs.
                t.results = vec![0, 1];
            }
        }
    }

    /// `resim` and `compare` per model and drive.
    fn models(&mut self) {
        let c = self.campaign;
        for m in &c.models {
            for (d, rec) in c.drives.iter().zip(self.recs.clone()) {
                let sim = self.layout.sim(&m.name, &d.name);
                if self.has(Step::Resim) {
                    let id = format!("resim/{}/{}", m.name, d.name);
                    let args = vec![
                        "resim".into(),
                        s(&rec),
                        "--scene".into(),
                        s(&d.scene),
                        "--model".into(),
                        s(&m.file),
                        "-o".into(),
                        s(&sim),
                    ];
                    let inputs = [
                        vec![rec.clone(), d.scene.clone(), m.file.clone()],
                        d.scene_files.clone(),
                    ]
                    .concat();
                    self.add(id.clone(), Step::Resim, args, inputs, vec![sim.clone()]);
                    if let Some(check) = self.check_of(&d.name) {
                        self.gates.entry(id).or_default().push(check);
                    }
                }
                if self.has(Step::Compare) {
                    let json = self.layout.compare(&m.name, &d.name);
                    let args = vec![
                        "compare".into(),
                        s(&rec),
                        s(&sim),
                        "--scene".into(),
                        s(&d.scene),
                        "--json".into(),
                        s(&json),
                    ];
                    let inputs = [vec![rec, sim, d.scene.clone()], d.scene_files.clone()].concat();
                    let name = format!("{}-{}", m.name, d.name);
                    let scenario = c.scenarios[d.scenario].name.as_str();
                    let labels = [Some(d.name.as_str()), Some(scenario), Some(m.name.as_str())];
                    self.table(OutputKind::Compare, &json, &name, labels);
                    self.add(
                        format!("compare/{}/{}", m.name, d.name),
                        Step::Compare,
                        args,
                        inputs,
                        vec![json],
                    );
                }
            }
        }
    }

    /// `validate` of scenario `sc` per model, over its repetitions.
    fn validate(&mut self, sc: &Scenario) {
        let c = self.campaign;
        for m in &c.models {
            let json = self.layout.validate(&sc.name, &m.name);
            let mut args = vec!["validate".to_string()];
            let mut inputs = Vec::new();
            for &i in &sc.drives {
                args.extend(["--real".into(), s(&self.recs[i])]);
                inputs.push(self.recs[i].clone());
            }
            for &i in &sc.drives {
                let sim = self.layout.sim(&m.name, &c.drives[i].name);
                args.extend(["--sim".into(), s(&sim)]);
                inputs.push(sim);
            }
            if let Some(p) = &sc.phases {
                args.extend(["--phases".into(), s(p)]);
                inputs.push(p.clone());
            }
            args.extend(["--json".into(), s(&json)]);
            let name = format!("{}-{}", sc.name, m.name);
            let labels = [None, Some(sc.name.as_str()), Some(m.name.as_str())];
            self.table(OutputKind::Validate, &json, &name, labels);
            let t = self.add(
                format!("validate/{}/{}", sc.name, m.name),
                Step::Validate,
                args,
                inputs,
                vec![json],
            );
            // A model that is not valid is the result, and the report shows it.
            t.results = vec![0, 1];
        }
    }

    /// `gap` of scenario `sc`, with the study file it reads.
    fn gap(&mut self, sc: &Scenario) -> Result<(), CampaignError> {
        let c = self.campaign;
        let dir = self.layout.gap(&sc.name);
        let study_path = dir.join("study.toml");
        let model = &c.models[sc.gap_model];
        // Objects named relative to the study in a bucket, so that its text (and so its hash in
        // the stamps) is the same on every worker's mirror.
        let dir_text = dir.to_string_lossy();
        let named = |p: &PathBuf| {
            super::mirror::relative(&dir_text, &p.to_string_lossy())
                .map_or_else(|| p.clone(), PathBuf::from)
        };
        let study = StudyFile {
            model: named(&model.file),
            scene: None,
            rig: None,
            runs: sc
                .drives
                .iter()
                .enumerate()
                .map(|(k, &i)| RunEntry {
                    recording: named(&self.recs[i]),
                    scene: Some(named(&c.drives[i].scene)),
                    role: if k < sc.fit_runs {
                        Role::Fit
                    } else {
                        Role::Validate
                    },
                })
                .collect(),
        };
        let text = study.to_toml().map_err(|e| CampaignError::Invalid {
            path: c.path.clone(),
            what: format!("scenario '{}': the gap study: {e}", sc.name),
        })?;
        self.files.push(PlannedFile {
            path: study_path.clone(),
            text: format!(
                "# The gap study of scenario '{}' of campaign '{}'.\n{text}",
                sc.name, c.name
            ),
        });
        let mut args = vec!["gap".into(), s(&study_path), "-o".into(), s(&dir)];
        if let Some(t) = &c.gap_trials {
            args.extend(t.args());
        }
        let mut inputs = vec![study_path, model.file.clone()];
        if let Some(r) = sc.reference_model {
            let r = &c.models[r].file;
            args.extend(["--reference-model".into(), s(r)]);
            inputs.push(r.clone());
        }
        for &i in &sc.drives {
            inputs.extend([self.recs[i].clone(), c.drives[i].scene.clone()]);
            inputs.extend(c.drives[i].scene_files.iter().cloned());
        }
        let id = format!("gap/{}", sc.name);
        let outputs = vec![dir.join("gap.json"), dir.join("model.fitted.toml")];
        // A task reads objects from a copy on its own node, and the gap task hands its trials
        // the paths it sees: an engine's workers on other nodes would not find them.
        if let Some(GapTrials::Engine(_)) = &c.gap_trials {
            if let Some(o) = inputs
                .iter()
                .chain(&outputs)
                .find(|p| super::mirror::is_url(p))
            {
                return Err(CampaignError::Invalid {
                    path: c.path.clone(),
                    what: format!(
                        "[gap] engine: the trials run on the engine's workers at the paths the \
                         gap task sees, but {} is an object, which each task reads from a copy \
                         on its own node; use `jobs` (trials on the gap task's node) or a disk \
                         the nodes share",
                        o.display()
                    ),
                });
            }
        }
        let labels = [None, Some(sc.name.as_str()), Some(model.name.as_str())];
        self.table(OutputKind::Gap, &outputs[0], &sc.name, labels);
        self.add(id.clone(), Step::Gap, args, inputs, outputs);
        // The workflow refuses runs that fail their check.
        let checks: Vec<String> = sc
            .drives
            .iter()
            .filter_map(|&i| self.check_of(&c.drives[i].name))
            .collect();
        self.gates.entry(id).or_default().extend(checks);
        Ok(())
    }

    /// `report` over every JSON the tasks before it write.
    fn report(&mut self) {
        let jsons: Vec<PathBuf> = self
            .tasks
            .iter()
            .filter(|t| {
                matches!(
                    t.step,
                    Step::Check | Step::Compare | Step::Validate | Step::Gap
                )
            })
            .flat_map(|t| {
                t.outputs
                    .iter()
                    .filter(|o| o.extension().is_some_and(|e| e == "json"))
                    .cloned()
            })
            .collect();
        let html = self.layout.out.join("report.html");
        // A drive that failed its check has no re-simulation to compare: the report is made
        // over what exists and lists the rest as absent (exit 1, a result).
        let mut args = vec!["report".to_string(), "--allow-absent".to_string()];
        args.extend(jsons.iter().map(|p| s(p)));
        args.extend(["-o".into(), s(&html)]);
        let json = self.layout.out.join("report.json");
        let task = self.add("report".into(), Step::Report, args, jsons, vec![html, json]);
        task.partial = true;
        task.results = vec![0, 1];
    }
}

impl Plan {
    /// The plan of `campaign` with its outputs under `out` (made absolute).
    pub fn build(campaign: &Campaign, out: &Path) -> Result<Plan, CampaignError> {
        let out = if super::mirror::is_url(out) {
            PathBuf::from(super::mirror::join(&out.to_string_lossy(), ".")?)
        } else {
            super::graph::canonical(out).map_err(|source| CampaignError::Io {
                path: out.to_owned(),
                source,
            })?
        };
        let layout = Layout { out: &out };
        let recs = campaign
            .drives
            .iter()
            .map(|d| {
                if d.is_capture {
                    layout.rec(&d.name)
                } else {
                    d.source.clone()
                }
            })
            .collect();
        let mut b = Builder {
            campaign,
            layout,
            recs,
            tasks: Vec::new(),
            gates: BTreeMap::new(),
            files: Vec::new(),
            tables: Vec::new(),
        };
        b.drives();
        b.models();
        for sc in &campaign.scenarios {
            if b.has(Step::Validate) {
                b.validate(sc);
            }
            if b.has(Step::Gap) {
                b.gap(sc)?;
            }
        }
        b.tables();
        if b.has(Step::Report) {
            b.report();
        }
        let Builder {
            tasks,
            gates,
            files,
            ..
        } = b;
        let tasks = super::graph::order(tasks, &gates)?;
        Ok(Plan {
            campaign: campaign.name.clone(),
            campaign_file: campaign.path.clone(),
            out,
            files,
            tasks,
        })
    }

    /// The task called `id`.
    pub fn task(&self, id: &str) -> Option<&Task> {
        self.tasks.iter().find(|t| t.id == id)
    }
}

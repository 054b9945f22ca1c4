//! An eFAST design as a plan (Rosenberger et al. 2019, §4): one task per few parameter sets,
//! each making their drives (`hilrig efast evaluate`), then the analysis over all of them
//! (`hilrig efast analyze`). A design of hundreds to thousands of drives is the largest work
//! the method asks for; as a plan it runs on any engine that runs campaigns: the local executor
//! (`hilrig efast run`, resumable like a campaign) or a Ray cluster (`hilrig efast plan --json`
//! to the `hilrig_ray` package), with the same outputs.
//!
//! The samples are the plan's own file (written before the first task), so every task reads
//! the same rows; each parameter set's drive is seeded by the design's seed and its row, so a
//! set's metric does not depend on which task, worker or chunk made it.

use super::file::Step;
use super::plan::{Plan, PlannedFile, Task};
use super::resolve::{named_files, Names};
use super::CampaignError;
use crate::stats::efast::{sample, samples_csv, Parameter};
use crate::stats::scenario::Scenario;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Parameter sets per `efast evaluate` task unless told otherwise: a few drives, so that a
/// lost worker loses little and a cluster's workers share the design evenly.
pub const DEFAULT_CHUNK: usize = 4;

/// An eFAST design: the parameters, the scenario that turns a parameter set into a metric,
/// and the sampling.
#[derive(Clone, Debug)]
pub struct Design<'a> {
    /// The parameter file.
    pub params: &'a Path,
    /// The scenario file.
    pub scenario: &'a Path,
    /// Samples per parameter.
    pub n: usize,
    /// Harmonics.
    pub m: usize,
    /// Seed of the search curves' phases, the drives and the bootstrap.
    pub seed: u64,
    /// Bootstrap windows for the confidence half-widths.
    pub resamples: usize,
    /// Parameter sets per evaluation task.
    pub chunk: usize,
}

/// Where a design's files go under its output directory.
pub struct Layout {
    out: PathBuf,
}

impl Layout {
    /// The layout under `out` (absolute).
    pub fn new(out: &Path) -> Layout {
        Layout {
            out: out.to_owned(),
        }
    }
    /// The parameter sets, one per row.
    pub fn samples(&self) -> PathBuf {
        self.out.join("samples.csv")
    }
    /// The metric of every set, in the samples' order.
    pub fn outputs(&self) -> PathBuf {
        self.out.join("outputs.csv")
    }
    /// The indices (JSON).
    pub fn indices(&self) -> PathBuf {
        self.out.join("indices.json")
    }
    /// The metrics of rows `from..=to` (1-based).
    fn part(&self, from: usize, to: usize) -> PathBuf {
        self.out
            .join("parts")
            .join(format!("rows-{from:05}-{to:05}.csv"))
    }
    fn log(&self, id: &str) -> PathBuf {
        self.out.join("logs").join(format!("{id}.log"))
    }
}

/// Why a design cannot be planned: the parameters, the sampling or the scenario (its knobs are
/// tried on the first parameter set), said before any drive is made.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    /// The parameter file or the sampling.
    #[error(transparent)]
    Efast(#[from] crate::stats::efast::EfastError),
    /// The scenario.
    #[error(transparent)]
    Scenario(#[from] crate::stats::scenario::ScenarioError),
    /// A file could not be read or a path made absolute.
    #[error(transparent)]
    Campaign(#[from] CampaignError),
}

/// The parameters of `path`.
pub fn read_params(path: &Path) -> Result<Vec<Parameter>, DesignError> {
    let text = std::fs::read_to_string(path).map_err(|source| CampaignError::Io {
        path: path.to_owned(),
        source,
    })?;
    Ok(crate::stats::efast::parse_params(
        &text,
        &path.display().to_string(),
    )?)
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

fn absolute(p: &Path) -> Result<PathBuf, CampaignError> {
    super::graph::canonical(p).map_err(|source| CampaignError::Io {
        path: p.to_owned(),
        source,
    })
}

impl Design<'_> {
    /// The plan of the design with its outputs under `out`: the samples as the plan's own
    /// file, an `efast evaluate` task per `chunk` rows, and `efast analyze` over their parts.
    /// Everything is checked first: the parameters, N against M, the scenario, and its knobs
    /// on the first parameter set.
    pub fn plan(&self, out: &Path) -> Result<Plan, DesignError> {
        // The outputs are files the tasks write where they run: a folder every worker sees
        // (this machine's, or a cluster's shared file system). A bucket URL would otherwise be
        // taken for a local folder called `s3:`.
        if super::mirror::is_url(out) {
            return Err(CampaignError::Invalid {
                path: out.to_owned(),
                what: "an eFAST design writes to a folder (local, or shared by the cluster's \
                       nodes), not to object storage"
                    .into(),
            }
            .into());
        }
        let ps = read_params(self.params)?;
        let rows = sample(&ps, self.n, self.m, self.seed)?;
        let params = absolute(self.params)?;
        // Loaded from where the tasks will load it: the documents it names are found from the
        // file's own folder, also when the path given is a link to it.
        let scenario_path = absolute(self.scenario)?;
        let scenario = Scenario::load(&scenario_path, &ps)?;
        scenario.check(&rows[0])?;
        // What a drive of the scenario reads: its four documents, the scene's meshes and
        // trajectories, the drive's rig with its DBC and calibration. All of them are the
        // evaluation tasks' inputs, so that a changed mesh or calibration makes them run again.
        let mut documents: Vec<PathBuf> = scenario
            .files()
            .iter()
            .map(|p| absolute(p))
            .collect::<Result<_, _>>()?;
        let scene_files = named_files(&documents[0], Names::Scene)?;
        documents.extend(scene_files);
        if let Some(rig) = scenario.rig() {
            let rig = absolute(&rig)?;
            documents.extend(named_files(&rig, Names::Rig)?);
            documents.push(rig);
        }
        let mut seen = std::collections::BTreeSet::new();
        documents.retain(|p| seen.insert(p.clone()));
        let out = absolute(out)?;
        let layout = Layout::new(&out);
        let samples = layout.samples();
        let mut tasks = Vec::new();
        let mut parts = Vec::new();
        let chunk = self.chunk.max(1);
        for from in (1..=rows.len()).step_by(chunk) {
            let to = (from + chunk - 1).min(rows.len());
            let part = layout.part(from, to);
            let id = format!("efast/evaluate/{from:05}-{to:05}");
            let mut inputs = vec![params.clone(), scenario_path.clone(), samples.clone()];
            inputs.extend(documents.iter().cloned());
            let log = layout.log(&id);
            tasks.push(Task::new(
                id,
                Step::Efast,
                vec![
                    "efast".into(),
                    "evaluate".into(),
                    "--params".into(),
                    s(&params),
                    "--scenario".into(),
                    s(&scenario_path),
                    "--samples".into(),
                    s(&samples),
                    "--rows".into(),
                    format!("{from}-{to}"),
                    "--seed".into(),
                    self.seed.to_string(),
                    "-o".into(),
                    s(&part),
                ],
                (inputs, vec![part.clone()]),
                log,
            ));
            parts.push(part);
        }
        let mut args = vec![
            "efast".into(),
            "analyze".into(),
            "--params".into(),
            s(&params),
            s(&samples),
        ];
        args.extend(parts.iter().map(|p| s(p)));
        args.extend([
            "-M".into(),
            self.m.to_string(),
            "--resamples".into(),
            self.resamples.to_string(),
            "--seed".into(),
            self.seed.to_string(),
            "--json".into(),
            s(&layout.indices()),
            "--joined".into(),
            s(&layout.outputs()),
        ]);
        let mut inputs = vec![params.clone(), samples.clone()];
        inputs.extend(parts);
        let id = "efast/analyze".to_owned();
        let log = layout.log(&id);
        tasks.push(Task::new(
            id,
            Step::Efast,
            args,
            (inputs, vec![layout.indices(), layout.outputs()]),
            log,
        ));
        let tasks = super::graph::order(tasks, &BTreeMap::new())?;
        Ok(Plan {
            campaign: format!(
                "efast: {}",
                self.scenario
                    .file_stem()
                    .map_or_else(|| s(self.scenario), |x| x.to_string_lossy().into_owned())
            ),
            campaign_file: scenario_path,
            out,
            files: vec![PlannedFile {
                path: samples,
                text: samples_csv(&ps, &rows),
            }],
            tasks,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fixture's design in chunks of 5: every row is evaluated by exactly one task, the
    /// analysis waits for all of them and reads their parts in the samples' order.
    #[test]
    fn every_row_is_evaluated_once_and_analyzed_in_order() {
        let fx = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/efast");
        let dir = tempfile::tempdir().unwrap();
        let design = Design {
            params: &fx.join("params.toml"),
            scenario: &fx.join("scenario.toml"),
            n: 17,
            m: 2,
            seed: 3,
            resamples: 10,
            chunk: 5,
        };
        let plan = design.plan(dir.path()).unwrap();
        let rows = plan.files[0].text.lines().count() - 1;
        let evaluate: Vec<&Task> = plan
            .tasks
            .iter()
            .filter(|t| t.args[1] == "evaluate")
            .collect();
        assert_eq!(evaluate.len(), rows.div_ceil(5));
        let mut covered = Vec::new();
        for t in &evaluate {
            let r = &t.args[t.args.iter().position(|a| a == "--rows").unwrap() + 1];
            let (a, b) = r.split_once('-').unwrap();
            covered.extend(a.parse::<usize>().unwrap()..=b.parse::<usize>().unwrap());
        }
        assert_eq!(covered, (1..=rows).collect::<Vec<_>>());
        let analyze = plan.tasks.last().unwrap();
        assert_eq!(analyze.id, "efast/analyze");
        let mut after = analyze.after.clone();
        after.sort();
        let mut ids: Vec<String> = evaluate.iter().map(|t| t.id.clone()).collect();
        ids.sort();
        assert_eq!(after, ids);
        let parts: Vec<&String> = analyze
            .args
            .iter()
            .filter(|a| a.contains("rows-"))
            .collect();
        let mut sorted = parts.clone();
        sorted.sort();
        assert_eq!(parts, sorted);
    }
}

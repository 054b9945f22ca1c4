//! One validation run re-simulated in full with a model and measured: the unit of the gap
//! workflow's full re-simulations ([`super::full_metrics`]), made in the workflow's own process
//! or, as `hilrig gap trial`, as a task that an engine runs ([`super::engine`]). Both ways give
//! the same [`TrialRun`], bit for bit: it is this one function of the run, the model and the
//! seed.

use super::keep::ScanSample;
use super::observe::{load_run, RunData};
use super::study::Role;
use super::GapError;
use crate::metrics::compare::{compare_simulated, Options as CompareOptions, ToSimulate};
use crate::metrics::features::{scan_features, ScanFeatures};
use crate::metrics::grid::Dims;
use crate::metrics::roi::Region;
use crate::sim::model::ModelFile;
use crate::sim::resim::Resimulator;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One validation run's trial as `hilrig gap trial` takes it: what a task needs to make the
/// run's [`TrialRun`] without the study.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TrialTask {
    /// The recording.
    pub recording: PathBuf,
    /// Its scene file.
    pub scene: PathBuf,
    /// A rig file overriding the recording's own.
    pub rig: Option<PathBuf>,
    /// The model.
    pub model: PathBuf,
    /// Its deterministic part, cast from the same casts.
    pub deterministic: Option<PathBuf>,
    /// The re-simulation's seed.
    pub seed: u64,
    /// Where the simulation goes.
    pub simulation: PathBuf,
    /// Remove the simulation once measured.
    pub scratch: bool,
    /// Also give the measured scans' features.
    pub measured: bool,
    /// Use a run that fails `check`.
    pub force: bool,
    /// Where the result goes (JSON).
    pub output: PathBuf,
}

impl TrialTask {
    /// Where an engine sends what the task prints: beside its result.
    pub fn log(&self) -> PathBuf {
        self.output.with_extension("log")
    }

    /// Its command line after `hilrig`.
    pub fn args(&self) -> Vec<String> {
        let s = |p: &Path| p.display().to_string();
        let mut args: Vec<String> = vec![
            "gap".into(),
            "trial".into(),
            "--recording".into(),
            s(&self.recording),
            "--scene".into(),
            s(&self.scene),
            "--model".into(),
            s(&self.model),
            "--seed".into(),
            self.seed.to_string(),
            "--simulation".into(),
            s(&self.simulation),
            "-o".into(),
            s(&self.output),
        ];
        if let Some(d) = &self.deterministic {
            args.extend(["--deterministic".into(), s(d)]);
        }
        if let Some(r) = &self.rig {
            args.extend(["--rig".into(), s(r)]);
        }
        for (flag, on) in [
            ("--scratch", self.scratch),
            ("--measured", self.measured),
            ("--force", self.force),
        ] {
            if on {
                args.push(flag.into());
            }
        }
        args
    }
}

/// Makes the trial `t` and writes its result: the run loaded and checked as the workflow loads
/// a validation run, re-simulated and measured as in the workflow's own process.
pub fn trial(t: &TrialTask) -> Result<TrialRun, GapError> {
    // The models first: a bad one is said before the run is read and checked. They are the
    // workflow's own, read as it holds them (its hash of each is checked against the
    // result's); the range checks of a user's model file are not repeated, so that a fitted
    // model simulates here exactly as in the workflow's process.
    let model = |p: &Path| {
        let bad = |message: String| GapError::Model {
            run: p.display().to_string(),
            source: crate::sim::model::ModelError::Toml {
                path: p.display().to_string(),
                message,
            },
        };
        let text = std::fs::read_to_string(p).map_err(|e| bad(e.to_string()))?;
        toml::from_str::<ModelFile>(&text).map_err(|e| bad(e.to_string()))
    };
    let m = model(&t.model)?;
    let det = t.deterministic.as_deref().map(model).transpose()?;
    let rig = t.rig.as_deref().map(crate::rig::Rig::load).transpose()?;
    let scene = crate::scene::Scene::load(&t.scene).map_err(|source| GapError::Scene {
        recording: t.recording.clone(),
        source,
    })?;
    // Its firings are not sampled: a trial casts the whole run.
    let run = load_run(
        &t.recording,
        scene,
        &t.scene,
        rig.as_ref(),
        Role::Validate,
        None,
        0,
        t.force,
    )?;
    let result = one_run(
        &run,
        t.seed,
        (&m, det.as_ref()),
        &t.simulation,
        !t.scratch,
        t.measured,
        // A trial re-simulates its run once.
        None,
    )?;
    crate::output::write(&t.output, &result)?;
    Ok(result)
}

/// One validation run re-simulated in full with a model and measured: what a round needs of
/// it. Made here for each run in turn, or by `hilrig gap trial` as a task of a plan that an
/// engine runs ([`super::engine::RoundEngine`]); either way the same numbers, bit for bit.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrialRun {
    /// The recording.
    pub recording: PathBuf,
    /// The simulation (its VelodyneScans; removed again when it was a scratch one).
    pub simulation: PathBuf,
    /// The comparison's mean OCR^K over the scans (`None` when no scan had a grid).
    pub ocr: Option<f64>,
    /// Its mean precision.
    pub precision: Option<f64>,
    /// Its mean IoU.
    pub iou: Option<f64>,
    /// Per scan stamp (ns), what the keep rule judges of the simulation.
    pub samples: BTreeMap<i64, ScanSample>,
    /// The same of the model's deterministic part, when it was cast too.
    pub deterministic: Option<BTreeMap<i64, ScanSample>>,
    /// The measured scans' features, when asked for (they are the same in every round).
    pub measured: Option<Vec<ScanFeatures>>,
    /// The simulated scans' features.
    pub simulated: Vec<ScanFeatures>,
    /// The re-simulation's seed.
    pub seed: u64,
    /// SHA-256 of the model's TOML text ([`ModelFile::to_toml`]) as the trial held it.
    pub model_sha256: String,
    /// The same of its deterministic part, when it was cast too.
    pub deterministic_sha256: Option<String>,
    /// The hilrig that made it ([`crate::output::BUILD`]): another build may simulate
    /// differently, and its result is then not this study's.
    pub build: String,
}

/// SHA-256 (hex) of a model's TOML text: what a trial's result says it was made with.
pub(super) fn model_sha256(m: &ModelFile) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(m.to_toml().as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

impl crate::output::Output for TrialRun {
    const KIND: crate::output::OutputKind = crate::output::OutputKind::GapTrial;
    const SCHEMA: u32 = 1;
}

/// Where validation run `index` (from 0) of a round tagged `tag` is simulated to.
pub(super) fn simulation_path(dir: &Path, tag: &str, index: usize) -> PathBuf {
    dir.join(format!("{tag}-validation-{:02}.mcap", index + 1))
}

/// The seed of validation run `index`'s re-simulations (from 0): the same in every round, so
/// that two models are compared on the same draws where they share their randomness.
pub(super) fn seed_of(index: usize) -> u64 {
    index as u64 + 1
}

/// Validation run `r` re-simulated with `model` (and its deterministic part `det`, from the
/// same casts) into `sim_path` with `seed`, and compared scan by scan as it is cast; the
/// simulation removed again unless `keep_file`; the measured scans' features only when
/// `want_measured`. With `hits`, the run's centre hits of the re-simulations before are
/// reused where the rays are the same, or kept for the later ones.
pub(super) fn one_run(
    r: &RunData,
    seed: u64,
    (model, det): (&ModelFile, Option<&ModelFile>),
    sim_path: &Path,
    keep_file: bool,
    want_measured: bool,
    hits: Option<&crate::sim::hit_log::HitLog>,
) -> Result<TrialRun, GapError> {
    let quiet = |_: u64, _: u64| {};
    let (_, sensor, calibration) = r.rig.lidar_sensor().map_err(|source| GapError::Lidar {
        run: r.name.clone(),
        source,
    })?;
    let decoder = hilrig_velodyne::Decoder::with_calibration(sensor, calibration);
    let resim_error = |source| GapError::Resim {
        run: r.name.clone(),
        source,
    };
    let mut resim = Resimulator::new(
        &r.path,
        &r.rig,
        &r.scene,
        &r.scene_path,
        model,
        seed,
        sim_path,
        r.trajectory.span().0,
    )
    .map_err(resim_error)?;
    if let Some(det) = det {
        resim = resim
            .with_deterministic_part(&r.rig, &r.scene, det)
            .map_err(resim_error)?;
    }
    if let Some(log) = hits {
        resim = resim.with_hit_log(log);
    }
    let (mut real_scans, mut sim_scans) = (Vec::new(), Vec::new());
    let compare_error = |source| GapError::Compare {
        run: r.name.clone(),
        source: std::sync::Arc::new(source),
    };
    let checked = r.checked.clone().map_err(|source| GapError::Compare {
        run: r.name.clone(),
        source,
    })?;
    let (c, det_c) = std::thread::scope(|scope| {
        // The deterministic part's twins, a batch at a time, to its own comparison: at
        // most one batch waits (memory stays a batch's, whatever the run's length).
        let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<crate::bag::scans::Scan>>(1);
        let det_thread = det.map(|_| {
            let checked = checked.clone();
            let decoder = decoder.clone();
            scope.spawn(move || {
                let mut features = Vec::new();
                let c = compare_simulated(
                    &r.path,
                    checked,
                    &mut |t: ToSimulate<'_>| {
                        let sims = rx
                            .recv()
                            .map_err(|_| "the model's own comparison stopped")?;
                        if sims.len() != t.scans.len() {
                            return Err("the twins of another batch".into());
                        }
                        features.extend(scan_features(&sims, &decoder));
                        Ok(sims)
                    },
                    Some(&r.scene),
                    options(),
                    &quiet,
                );
                (c, features)
            })
        });
        let c = compare_simulated(
            &r.path,
            checked,
            &mut |t: ToSimulate<'_>| {
                let sims = if det.is_some() {
                    let (sims, part) = resim.cast_pair(t.trajectory, t.pps_locked, t.scans)?;
                    tx.send(part)
                        .map_err(|_| "the deterministic part's comparison stopped")?;
                    sims
                } else {
                    resim.cast(t.trajectory, t.pps_locked, t.scans)?
                };
                if want_measured {
                    real_scans.extend(scan_features(t.scans, &decoder));
                }
                sim_scans.extend(scan_features(&sims, &decoder));
                Ok(sims)
            },
            Some(&r.scene),
            options(),
            &quiet,
        );
        // No more twins: the deterministic part's comparison ends with the run (or learns
        // that this one stopped).
        drop(tx);
        let det_c = det_thread.map(|t| t.join().expect("the comparison thread does not panic"));
        (c, det_c)
    });
    // The model's own error first: the other side's is then only that it stopped.
    let c = c.map_err(compare_error)?;
    let det_c = match det_c {
        Some((c, features)) => Some((c.map_err(compare_error)?, features)),
        None => None,
    };
    let stats = resim.finish().map_err(resim_error)?;
    if hits.is_some() {
        tracing::info!(
            "{}: {} centre rays' static hits reused, {} rays cast",
            r.name,
            stats.reused,
            stats.rays
        );
    }
    if !keep_file {
        // A scratch simulation: nothing a user opens. Failing to remove it loses nothing.
        let _ = std::fs::remove_file(sim_path);
    }
    Ok(TrialRun {
        recording: r.path.clone(),
        simulation: sim_path.to_owned(),
        ocr: c.summary.ocr_mean,
        precision: c.summary.precision_mean,
        iou: c.summary.iou_mean,
        samples: per_scan(&c, &sim_scans),
        deterministic: det_c.map(|(c, features)| per_scan(&c, &features)),
        measured: want_measured.then_some(real_scans),
        simulated: sim_scans,
        seed,
        model_sha256: model_sha256(model),
        deterministic_sha256: det.map(model_sha256),
        build: crate::output::BUILD.to_owned(),
    })
}

/// The comparison the rounds make: OCR, precision and IoU at the admissible cell.
fn options() -> CompareOptions {
    CompareOptions {
        cell_m: None,
        k: 1,
        dims: Dims::Voxel,
        region: Region::All,
        exclude_ground: true,
        allow_small_cell: false,
        trajectory: None,
        sensor_frame: false,
        grid_phases: crate::metrics::compare::DEFAULT_GRID_PHASES,
        // The rounds report OCR, precision and IoU: no curve, no point metrics.
        curve_every: 0,
        point_metrics: false,
    }
}

/// Per scan of a comparison, what the keep rule judges: its grid metrics and the simulated
/// scan's features.
fn per_scan(
    c: &crate::metrics::compare::Comparison,
    features: &[crate::metrics::features::ScanFeatures],
) -> BTreeMap<i64, ScanSample> {
    let mut per_scan: BTreeMap<i64, ScanSample> = BTreeMap::new();
    for row in &c.scans {
        per_scan.entry(row.stamp_ns).or_default().grid =
            row.grid.map(|g| [g.ocr, g.precision, g.iou]);
    }
    for f in features {
        per_scan.entry(f.stamp.0).or_default().features = Some(f.values());
    }
    per_scan
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A trial's command line holds every field the task needs, the optional ones only when
    /// set, and its log lies beside its result.
    #[test]
    fn a_trial_task_is_its_command_line() {
        let mut t = TrialTask {
            recording: "/d/run.mcap".into(),
            scene: "/d/scene.toml".into(),
            rig: None,
            model: "/o/sim/round-1-x.model.toml".into(),
            deterministic: None,
            seed: 2,
            simulation: "/o/sim/round-1-x-validation-02.mcap".into(),
            scratch: false,
            measured: false,
            force: false,
            output: "/o/sim/round-1-x-validation-02.json".into(),
        };
        let args = t.args();
        let value = |args: &[String], flag: &str| {
            args.iter()
                .position(|a| a == flag)
                .map(|i| args[i + 1].clone())
        };
        assert_eq!(&args[..2], ["gap", "trial"]);
        assert_eq!(value(&args, "--seed").as_deref(), Some("2"));
        assert_eq!(
            value(&args, "-o").as_deref(),
            Some("/o/sim/round-1-x-validation-02.json")
        );
        for absent in [
            "--rig",
            "--deterministic",
            "--scratch",
            "--measured",
            "--force",
        ] {
            assert!(!args.iter().any(|a| a == absent), "{absent} in {args:?}");
        }
        t.rig = Some("/d/rig.toml".into());
        t.deterministic = Some("/o/sim/round-1-x.deterministic.toml".into());
        (t.scratch, t.measured, t.force) = (true, true, true);
        let args = t.args();
        assert_eq!(value(&args, "--rig").as_deref(), Some("/d/rig.toml"));
        assert_eq!(
            value(&args, "--deterministic").as_deref(),
            Some("/o/sim/round-1-x.deterministic.toml")
        );
        for present in ["--scratch", "--measured", "--force"] {
            assert!(
                args.iter().any(|a| a == present),
                "{present} not in {args:?}"
            );
        }
        assert_eq!(t.log(), Path::new("/o/sim/round-1-x-validation-02.log"));
    }
}

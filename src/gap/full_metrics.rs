//! The validation runs re-simulated in full after each round, for the metrics a user reads
//! beside the per-firing likelihood the workflow decides by: OCR^K, precision, IoU and the
//! validation's traffic lights (Rosenberger et al. 2019, Fig. 7), so that the report shows the
//! gap shrink on data the fit did not see, and the keep rule's metric half ([`super::keep`])
//! judges every trial by them.

use super::keep::{self, GridBasis, Samples, ScanSample};
use super::observe::RunData;
use super::report::{FeatureAvm, FeatureLight, MetricCheck, ReferenceCheck, RunMetrics};
use super::GapError;
use crate::metrics::compare::{compare_simulated, Options as CompareOptions, ToSimulate};
use crate::metrics::features::scan_features;
use crate::metrics::grid::Dims;
use crate::metrics::roi::Region;
use crate::sim::model::ModelFile;
use crate::sim::resim::Resimulator;
use crate::stats::repetitions::RunFeatures;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Re-simulates the validation runs in full with `model` into `dir` and measures them: each run
/// is read once, its scans cast batch by batch and compared as they come (OCR^K, precision,
/// IoU at the admissible cell), and their features kept for the validation (Rosenberger et al.
/// 2019, Fig. 7) of the simulated runs against the measured ones. The simulations are written
/// to `dir` (their VelodyneScans) for the user to open.
///
/// `measured` holds the measured runs' features once a first call has found them (the same
/// scans are compared in every round; only the simulation changes). With `keep_files` false
/// the simulations are removed once measured. Returns the metrics and, per scan, what the
/// keep rule judges.
fn run_metrics(
    val: &[RunData],
    model: &ModelFile,
    (dir, tag, keep_files): (&Path, &str, bool),
    measured: &mut Vec<RunFeatures>,
) -> Result<(RunMetrics, Samples), GapError> {
    std::fs::create_dir_all(dir).map_err(|source| GapError::Output {
        path: dir.to_owned(),
        source,
    })?;
    let quiet = |_: u64, _: u64| {};
    let known = measured.len() == val.len();
    if !known {
        measured.clear();
    }
    let mut sim_features = Vec::new();
    let mut samples = Samples::default();
    let (mut ocr, mut precision, mut iou) = (Vec::new(), Vec::new(), Vec::new());
    for (i, r) in val.iter().enumerate() {
        let sim_path = dir.join(format!("{tag}-validation-{:02}.mcap", i + 1));
        let (_, sensor, calibration) = r.rig.lidar_sensor().map_err(|source| GapError::Lidar {
            run: r.name.clone(),
            source,
        })?;
        let decoder = hilrig_velodyne::Decoder::with_calibration(sensor, calibration);
        let mut resim = Resimulator::new(
            &r.path,
            &r.rig,
            &r.scene,
            &r.scene_path,
            model,
            i as u64 + 1,
            &sim_path,
            r.trajectory.span().0,
        )
        .map_err(|source| GapError::Resim {
            run: r.name.clone(),
            source,
        })?;
        let (mut real_scans, mut sim_scans) = (Vec::new(), Vec::new());
        let checked = r.checked.clone().map_err(|source| GapError::Compare {
            run: r.name.clone(),
            source,
        })?;
        let c = compare_simulated(
            &r.path,
            checked,
            &mut |t: ToSimulate<'_>| {
                let sims = resim.cast(t.trajectory, t.pps_locked, t.scans)?;
                if !known {
                    real_scans.extend(scan_features(t.scans, &decoder));
                }
                sim_scans.extend(scan_features(&sims, &decoder));
                Ok(sims)
            },
            Some(&r.scene),
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
            },
            &quiet,
        )
        .map_err(|source| GapError::Compare {
            run: r.name.clone(),
            source: std::sync::Arc::new(source),
        })?;
        resim.finish().map_err(|source| GapError::Resim {
            run: r.name.clone(),
            source,
        })?;
        if !keep_files {
            // A scratch simulation: nothing a user opens. Failing to remove it loses nothing.
            let _ = std::fs::remove_file(&sim_path);
        }
        let mut per_scan: BTreeMap<i64, ScanSample> = BTreeMap::new();
        for row in &c.scans {
            per_scan.entry(row.stamp_ns).or_default().grid =
                row.grid.map(|g| [g.ocr, g.precision, g.iou]);
        }
        for f in &sim_scans {
            per_scan.entry(f.stamp.0).or_default().features = Some(f.values());
        }
        samples.runs.push(per_scan);
        ocr.extend(c.summary.ocr_mean);
        precision.extend(c.summary.precision_mean);
        iou.extend(c.summary.iou_mean);
        if !known {
            measured.push(RunFeatures {
                name: r.path.display().to_string(),
                damage: None,
                scans: real_scans,
            });
        }
        sim_features.push(RunFeatures {
            name: sim_path.display().to_string(),
            damage: None,
            scans: sim_scans,
        });
    }
    let v = crate::stats::repetitions::validate_features(measured, &sim_features, &[])?;
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    let metrics = RunMetrics {
        ocr: mean(&ocr),
        precision: mean(&precision),
        iou: mean(&iou),
        avm: v
            .cells
            .iter()
            .map(|c| FeatureAvm {
                metric: c.metric.clone(),
                avm: c.avm,
            })
            .collect(),
        lights: v
            .cells
            .iter()
            .map(|c| FeatureLight {
                metric: c.metric.clone(),
                light: c.light,
            })
            .collect(),
        verdict: v.verdict,
    };
    Ok((metrics, samples))
}

/// A model's full re-simulation of the validation runs: its metrics and its scans.
struct Full {
    model: ModelFile,
    metrics: RunMetrics,
    samples: Samples,
}

/// A trial judged by [`Watch::judge`]: its check, and what [`Watch::accept`] keeps if it is
/// added.
pub(super) struct Judged {
    /// The metric half of the keep rule.
    pub check: MetricCheck,
    full: Full,
    deterministic: Option<Samples>,
}

/// The validation runs' full metrics as the workflow goes: the current model's, and every
/// trial's judged against them.
pub(super) struct Watch<'a> {
    val: &'a [RunData],
    dir: PathBuf,
    measured: Vec<RunFeatures>,
    now: Full,
    /// The current model's deterministic part, re-simulated, once a trial needed it (when
    /// the model has random effects).
    deterministic_now: Option<Samples>,
}

impl<'a> Watch<'a> {
    /// Re-simulates the validation runs with the start model (the round-0 simulations).
    pub fn start(val: &'a [RunData], model: &ModelFile, dir: PathBuf) -> Result<Self, GapError> {
        let mut measured = Vec::new();
        let (metrics, samples) = run_metrics(val, model, (&dir, "round-0", true), &mut measured)?;
        Ok(Watch {
            val,
            dir,
            measured,
            now: Full {
                model: model.clone(),
                metrics,
                samples,
            },
            deterministic_now: None,
        })
    }

    /// The current model's metrics.
    pub fn metrics_now(&self) -> &RunMetrics {
        &self.now.metrics
    }

    fn scratch(&mut self, model: &ModelFile, tag: &str) -> Result<Samples, GapError> {
        let dir = self.dir.clone();
        Ok(run_metrics(self.val, model, (&dir, tag, false), &mut self.measured)?.1)
    }

    /// Re-simulates the validation runs with `trial` (written as `tag`) and judges it against
    /// the current model ([`keep::judge`]); the grid metrics on the deterministic parts.
    pub fn judge(&mut self, trial: &ModelFile, tag: &str) -> Result<Judged, GapError> {
        let dir = self.dir.clone();
        let (metrics, samples) =
            run_metrics(self.val, trial, (&dir, tag, true), &mut self.measured)?;
        let full = Full {
            model: trial.clone(),
            metrics,
            samples,
        };
        let (det_now, det_trial) = (
            keep::deterministic_part(&self.now.model),
            keep::deterministic_part(trial),
        );
        let random_now = keep::has_random_effects(&self.now.model);
        let random_trial = keep::has_random_effects(trial);
        let basis = if keep::same_effects(&det_now, &det_trial) {
            GridBasis::Unchanged
        } else if random_now || random_trial {
            GridBasis::DeterministicParts
        } else {
            GridBasis::Models
        };
        if basis != GridBasis::Unchanged {
            self.simulate_deterministic_now(&format!("{tag}-current-deterministic"))?;
        }
        let deterministic = match basis {
            GridBasis::Unchanged => None,
            _ if random_trial => Some(self.scratch(&det_trial, &format!("{tag}-deterministic"))?),
            _ => None,
        };
        let grid = match basis {
            GridBasis::Unchanged => None,
            _ => Some((
                self.grid_now(),
                deterministic.as_ref().unwrap_or(&full.samples),
            )),
        };
        let measured = self.measured_by_stamp();
        let j = keep::judge(&measured, (&self.now.samples, &full.samples), grid, 2019);
        Ok(Judged {
            check: MetricCheck {
                after: full.metrics.clone(),
                grid: basis,
                judged: j.judged,
                level: keep::FAMILY_LEVEL / j.judged.max(1) as f64,
                decision: j.decision(),
                improved: j.improved,
                worse: j.worse,
            },
            full,
            deterministic,
        })
    }

    /// The current model against `reference` (a model known to have made the data): the
    /// validation runs re-simulated with it (written as `reference`), and the current model
    /// judged as a trial against it, the grid on the deterministic parts.
    pub fn against(
        &mut self,
        reference: &ModelFile,
        path: &Path,
    ) -> Result<ReferenceCheck, GapError> {
        let dir = self.dir.clone();
        let (metrics, samples) = run_metrics(
            self.val,
            reference,
            (&dir, "reference", true),
            &mut self.measured,
        )?;
        let random_ref = keep::has_random_effects(reference);
        let random_now = keep::has_random_effects(&self.now.model);
        let grid_ref = if random_ref {
            Some(self.scratch(
                &keep::deterministic_part(reference),
                "reference-deterministic",
            )?)
        } else {
            None
        };
        self.simulate_deterministic_now("fitted-deterministic")?;
        let measured = self.measured_by_stamp();
        let j = keep::judge(
            &measured,
            (&samples, &self.now.samples),
            Some((grid_ref.as_ref().unwrap_or(&samples), self.grid_now())),
            2019,
        );
        Ok(ReferenceCheck {
            path: path.display().to_string(),
            name: reference.name.clone(),
            metrics,
            fitted: self.now.metrics.clone(),
            grid: if random_ref || random_now {
                GridBasis::DeterministicParts
            } else {
                GridBasis::Models
            },
            judged: j.judged,
            level: keep::FAMILY_LEVEL / j.judged.max(1) as f64,
            worse: j.worse,
            improved: j.improved,
        })
    }

    /// Re-simulates the current model's deterministic part (as `tag`) when it has random
    /// effects and no trial has yet.
    fn simulate_deterministic_now(&mut self, tag: &str) -> Result<(), GapError> {
        if keep::has_random_effects(&self.now.model) && self.deterministic_now.is_none() {
            let det = keep::deterministic_part(&self.now.model);
            self.deterministic_now = Some(self.scratch(&det, tag)?);
        }
        Ok(())
    }

    /// What the current model's grid metrics are judged on: its deterministic part's
    /// simulation, or its own where it has no random effect.
    fn grid_now(&self) -> &Samples {
        self.deterministic_now.as_ref().unwrap_or(&self.now.samples)
    }

    fn measured_by_stamp(&self) -> keep::Measured {
        self.measured
            .iter()
            .map(|r| r.scans.iter().map(|s| (s.stamp.0, s.values())).collect())
            .collect()
    }

    /// `judged`'s model becomes the current one.
    pub fn accept(&mut self, judged: Judged) {
        let old = std::mem::replace(&mut self.now, judged.full);
        self.deterministic_now = match judged.check.grid {
            // The deterministic part stayed: so did its simulation (the old model's own, when
            // it had no random effect).
            GridBasis::Unchanged => self
                .deterministic_now
                .take()
                .or_else(|| (!keep::has_random_effects(&old.model)).then_some(old.samples)),
            _ => judged.deterministic,
        };
    }
}

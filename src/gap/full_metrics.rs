//! The validation runs re-simulated in full after each round, for the metrics a user reads
//! beside the per-firing likelihood the workflow decides by: OCR^K, precision, IoU and the
//! validation's traffic lights (Rosenberger et al. 2019, Fig. 7), so that the report shows the
//! gap shrink on data the fit did not see, and the keep rule's metric half ([`super::keep`])
//! judges every trial by them.

use super::engine::{Engine, Simulations, TrialRun};
use super::keep::{self, GridBasis, Samples};
use super::observe::RunData;
use super::report::{FeatureAvm, FeatureLight, MetricCheck, ReferenceCheck, RunMetrics};

use super::GapError;
use crate::sim::hit_log::HitLog;
use crate::sim::model::ModelFile;
use crate::stats::repetitions::RunFeatures;
use std::path::{Path, PathBuf};

/// Re-simulates the validation runs in full with `model` into `dir` and measures them: each run
/// is read once, its scans cast batch by batch and compared as they come (OCR^K, precision,
/// IoU at the admissible cell), and their features kept for the validation (Rosenberger et al.
/// 2019, Fig. 7) of the simulated runs against the measured ones. The simulations are written
/// to `dir` (their VelodyneScans) for the user to open. The runs are re-simulated here one
/// after the other, or as the tasks of a plan on `engine`.
///
/// With `det` (the model's deterministic part, [`keep::deterministic_part`]), the same casts
/// give its simulation too ([`crate::sim::resim::Resimulator::cast_pair`]), compared on a second thread as the
/// batches come, not written: what the keep rule judges a trial's grid metrics on, for the
/// price of one cast of the runs instead of two.
///
/// `measured` holds the measured runs' features once a first call has found them (the same
/// scans are compared in every round; only the simulation changes). With `keep_files` false
/// the simulations are removed once measured. Returns the metrics and, per scan, what the
/// keep rule judges, of the model and of its deterministic part.
fn run_metrics(
    val: &[RunData],
    model: &ModelFile,
    det: Option<&ModelFile>,
    sims: Simulations<'_>,
    measured: &mut Vec<RunFeatures>,
    engine: &Engine,
) -> Result<(RunMetrics, Samples, Option<Samples>), GapError> {
    std::fs::create_dir_all(sims.dir).map_err(|source| GapError::Output {
        path: sims.dir.to_owned(),
        source,
    })?;
    let known = measured.len() == val.len();
    let runs: Vec<TrialRun> = engine.run(val, (model, det), sims, !known)?;
    if !known {
        measured.clear();
    }
    let mut sim_features = Vec::new();
    let mut samples = Samples::default();
    let mut det_samples = det.map(|_| Samples::default());
    let (mut ocr, mut precision, mut iou) = (Vec::new(), Vec::new(), Vec::new());
    for (r, t) in val.iter().zip(runs) {
        samples.runs.push(t.samples);
        if let Some(d) = det_samples.as_mut() {
            d.runs.push(t.deterministic.unwrap_or_default());
        }
        ocr.extend(t.ocr);
        precision.extend(t.precision);
        iou.extend(t.iou);
        if !known {
            measured.push(RunFeatures {
                name: r.path.display().to_string(),
                damage: None,
                scans: t.measured.unwrap_or_default(),
            });
        }
        sim_features.push(RunFeatures {
            name: t.simulation.display().to_string(),
            damage: None,
            scans: t.simulated,
        });
    }
    let v = crate::stats::repetitions::validate_features(measured, &sim_features, &[])?;
    Ok((
        metrics_of(&v, [&ocr, &precision, &iou]),
        samples,
        det_samples,
    ))
}

/// The round's metrics: the runs' mean OCR, precision and IoU, and the validation's cells.
fn metrics_of(
    v: &crate::stats::repetitions::Validation,
    [ocr, precision, iou]: [&[f64]; 3],
) -> RunMetrics {
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    RunMetrics {
        ocr: mean(ocr),
        precision: mean(precision),
        iou: mean(iou),
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
    }
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
    /// Where the re-simulations run.
    engine: Engine,
    dir: PathBuf,
    measured: Vec<RunFeatures>,
    now: Full,
    /// The current model's deterministic part, re-simulated, once a trial needed it (when
    /// the model has random effects).
    deterministic_now: Option<Samples>,
    /// Per validation run, the centre hits its first re-simulation kept: most rounds' models
    /// cast the same rays, and traverse none of them again.
    hits: Vec<HitLog>,
}

impl<'a> Watch<'a> {
    /// Re-simulates the validation runs with the start model (the round-0 simulations).
    pub fn start(
        val: &'a [RunData],
        model: &ModelFile,
        dir: PathBuf,
        engine: Engine,
    ) -> Result<Self, GapError> {
        let mut measured = Vec::new();
        let hits: Vec<HitLog> = val.iter().map(|_| HitLog::in_dir(dir.clone())).collect();
        let (metrics, samples, _) = run_metrics(
            val,
            model,
            None,
            Simulations {
                dir: &dir,
                tag: "round-0",
                keep: true,
                hits: &hits,
            },
            &mut measured,
            &engine,
        )?;
        Ok(Watch {
            val,
            engine,
            dir,
            measured,
            now: Full {
                model: model.clone(),
                metrics,
                samples,
            },
            deterministic_now: None,
            hits,
        })
    }

    /// The current model's metrics.
    pub fn metrics_now(&self) -> &RunMetrics {
        &self.now.metrics
    }

    fn scratch(&mut self, model: &ModelFile, tag: &str) -> Result<Samples, GapError> {
        let dir = self.dir.clone();
        Ok(run_metrics(
            self.val,
            model,
            None,
            Simulations {
                dir: &dir,
                tag,
                keep: false,
                hits: &self.hits,
            },
            &mut self.measured,
            &self.engine,
        )?
        .1)
    }

    /// Re-simulates the validation runs with `trial` (written as `tag`) and judges it against
    /// the current model ([`keep::judge`]); the grid metrics on the deterministic parts.
    pub fn judge(&mut self, trial: &ModelFile, tag: &str) -> Result<Judged, GapError> {
        let dir = self.dir.clone();
        let (det_now, det_trial) = (
            keep::deterministic_part(&self.now.model),
            keep::deterministic_part(trial),
        );
        let random_now = keep::has_random_effects(&self.now.model);
        let random_trial = keep::has_random_effects(trial);
        let basis = if keep::same_returns(&det_now, &det_trial) {
            GridBasis::Unchanged
        } else if random_now || random_trial {
            GridBasis::DeterministicParts
        } else {
            GridBasis::Models
        };
        // The trial's deterministic part, where the grid is judged on it, from the trial's
        // own casts.
        let det = (basis != GridBasis::Unchanged && random_trial).then_some(&det_trial);
        let (metrics, samples, deterministic) = run_metrics(
            self.val,
            trial,
            det,
            Simulations {
                dir: &dir,
                tag,
                keep: true,
                hits: &self.hits,
            },
            &mut self.measured,
            &self.engine,
        )?;
        let full = Full {
            model: trial.clone(),
            metrics,
            samples,
        };
        if basis != GridBasis::Unchanged {
            self.simulate_deterministic_now(&format!("{tag}-current-deterministic"))?;
        }
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
        let random_ref = keep::has_random_effects(reference);
        let random_now = keep::has_random_effects(&self.now.model);
        let det_ref = keep::deterministic_part(reference);
        let (metrics, samples, grid_ref) = run_metrics(
            self.val,
            reference,
            random_ref.then_some(&det_ref),
            Simulations {
                dir: &dir,
                tag: "reference",
                keep: true,
                hits: &self.hits,
            },
            &mut self.measured,
            &self.engine,
        )?;
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

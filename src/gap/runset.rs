//! The runs of one role (parameterization or validation) as the workflow works on them: their
//! sampled firings and features, the bootstrap blocks and resamples a gain's interval comes
//! from, and the casts kept from round to round. Candidates are fitted and scored on one set,
//! trials judged on the other, by the same scoring and the same gain: one type, so that the
//! two cannot drift apart.

use super::bootstrap::{self, Blocks};
use super::casts::Casts;
use super::likelihood::{self, random_of, Random, Scales, Scored};
use super::observe::{Feature, Obs, RunData};
use super::GapError;
use crate::sim::model::ModelFile;
use std::sync::{Arc, PoisonError, RwLock};

/// Measured ranges per run and sampled slot (NaN: no return), standing in for the recorded ones.
pub type Measured = Vec<Vec<f32>>;

/// Runs of one role with everything a score and its interval need.
pub struct RunSet {
    /// The runs.
    pub runs: Vec<RunData>,
    /// Each run's features, one per sampled firing.
    pub feats: Vec<Vec<Feature>>,
    /// The bootstrap blocks over the runs' scans.
    pub blocks: Blocks,
    /// Resamples of the blocks (a fixed set per role, so that every interval of a study uses
    /// the same ones).
    pub resamples: Vec<Vec<u32>>,
    /// Casts kept from round to round.
    pub casts: Casts,
    /// Measured ranges that stand in for the recorded ones while a detection limit is searched
    /// ([`RunSet::with_measured`]); none otherwise.
    measured: RwLock<Option<Arc<Measured>>>,
}

/// A model's observations, scores and the residual scales used, per run.
pub struct Evaluation {
    /// Observations per run.
    pub obs: Vec<Vec<Obs>>,
    /// Scores per run.
    pub scored: Vec<Scored>,
    /// Residual scales per run.
    pub scales: Vec<Scales>,
}

/// How much better one model explains a set's firings than another: the log-likelihood gain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gain {
    /// Total over the set.
    pub total: f64,
    /// Its bootstrap 95 % interval (none with fewer than two blocks).
    pub interval: Option<(f64, f64)>,
    /// The total per 1000 firings scored.
    pub per_1000_firings: f64,
}

impl RunSet {
    /// The set of `runs` with their features; `seed` fixes the bootstrap resamples.
    pub fn new(runs: Vec<RunData>, feats: Vec<Vec<Feature>>, seed: u64) -> RunSet {
        let blocks = Blocks::new(&runs.iter().map(|r| r.scans).collect::<Vec<_>>());
        let resamples = blocks.resamples(seed);
        RunSet {
            runs,
            feats,
            blocks,
            resamples,
            casts: Casts::default(),
            measured: RwLock::new(None),
        }
    }

    /// `f` run on this set with `measured` in place of the recorded ranges: every cast, score,
    /// fit and gain made inside sees them. A detection limit injects an effect into the data
    /// this way: the runs, the sample and the casts (which depend on the model only) stay the
    /// set's own, so nothing is loaded or cast twice.
    pub fn with_measured<T>(&self, measured: Measured, f: impl FnOnce(&RunSet) -> T) -> T {
        let slot = || {
            self.measured
                .write()
                .unwrap_or_else(PoisonError::into_inner)
        };
        *slot() = Some(Arc::new(measured));
        // Restored whatever `f` does, even when it panics.
        struct Restore<'a>(&'a RwLock<Option<Arc<Measured>>>);
        impl Drop for Restore<'_> {
            fn drop(&mut self) {
                *self.0.write().unwrap_or_else(PoisonError::into_inner) = None;
            }
        }
        let _restore = Restore(&self.measured);
        f(self)
    }

    /// The largest finite value of `f` over the runs (0 when none is finite): a reference
    /// uncertainty that the repetitions need not average out.
    pub fn largest_over_runs(&self, f: impl Fn(&RunData) -> f64) -> f64 {
        self.runs
            .iter()
            .map(f)
            .filter(|x| x.is_finite())
            .fold(0.0, f64::max)
    }

    /// The standard error the median residual of `obs` (this set's casts) inherits from the
    /// surveys of the runs' scenes ([`likelihood::survey_sigma`]): runs measured against the
    /// same scene file share its errors.
    pub fn survey_sigma(&self, obs: &[Vec<Obs>]) -> f64 {
        let survey_of = |r: &RunData| {
            self.runs
                .iter()
                .position(|s| s.scene_path == r.scene_path)
                .unwrap_or(0)
        };
        let runs: Vec<(&[Obs], &[Feature], usize)> = obs
            .iter()
            .zip(&self.feats)
            .zip(&self.runs)
            .map(|((o, f), r)| (o.as_slice(), f.as_slice(), survey_of(r)))
            .collect();
        likelihood::survey_sigma(runs)
    }

    /// The set's casts with the recorded ranges, whatever [`RunSet::with_measured`] put in
    /// their place.
    pub fn cast_recorded(&self, model: &ModelFile) -> Result<Vec<Vec<Obs>>, GapError> {
        self.casts.of(&self.runs, model)
    }

    /// Every sampled firing cast with `model`'s deterministic part (kept casts reused).
    pub fn cast(&self, model: &ModelFile) -> Result<Vec<Vec<Obs>>, GapError> {
        let mut obs = self.casts.of(&self.runs, model)?;
        let measured = self
            .measured
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone();
        if let Some(m) = measured {
            for (o, m) in obs.iter_mut().zip(m.iter()) {
                for (o, &m) in o.iter_mut().zip(m) {
                    o.measured = m;
                }
            }
        }
        Ok(obs)
    }

    /// The residual scales of `obs`, per run.
    pub fn scales_of(&self, obs: &[Vec<Obs>]) -> Vec<Scales> {
        obs.iter()
            .zip(&self.feats)
            .map(|(o, f)| likelihood::scales(o, f))
            .collect()
    }

    /// Scores of `obs` under the random parts `random`, with the residual scales `scales`.
    pub fn score(&self, obs: &[Vec<Obs>], random: Random, scales: &[Scales]) -> Vec<Scored> {
        obs.iter()
            .zip(&self.runs)
            .zip(&self.feats)
            .zip(scales)
            .map(|(((o, r), f), s)| likelihood::score(o, f, random, s, r.range_quantum_m, r.scans))
            .collect()
    }

    /// Observations and scores of `model`, with the residual scales `scales` (per run), or
    /// the ones of these observations when `None`.
    pub fn evaluate(
        &self,
        model: &ModelFile,
        scales: Option<&[Scales]>,
    ) -> Result<Evaluation, GapError> {
        let obs = self.cast(model)?;
        let scales = match scales {
            Some(s) => s.to_vec(),
            None => self.scales_of(&obs),
        };
        let scored = self.score(&obs, random_of(model), &scales);
        Ok(Evaluation {
            obs,
            scored,
            scales,
        })
    }

    /// The gain of the scores `new` over `old` (both of this set), summed per bootstrap
    /// block for its interval.
    pub fn gain(&self, new: &[Scored], old: &[Scored]) -> Gain {
        let mut per_block = vec![0.0; self.blocks.len()];
        let mut firings = 0;
        for (r, (a, b)) in new.iter().zip(old).enumerate() {
            firings += b.firings;
            for (s, (x, y)) in a.per_scan.iter().zip(&b.per_scan).enumerate() {
                per_block[self.blocks.of(r, s as u32)] += x - y;
            }
        }
        let total: f64 = per_block.iter().sum();
        Gain {
            total,
            interval: bootstrap::sum_interval(&per_block, &self.resamples),
            per_1000_firings: total / firings.max(1) as f64 * 1000.0,
        }
    }
}

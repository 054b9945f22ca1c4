//! The effect catalogue as candidates: for each effect of `src/sim/model.rs` the current model
//! lacks, its signature on the per-firing data, a fit of its parameters with a bootstrap
//! interval, and its score: the log-likelihood it adds on the parameterization runs
//! ([`super::likelihood`]), with a block-bootstrap interval.
//!
//! The fits follow each effect's physical definition in the catalogue, nothing else:
//!
//! | effect | signature | fit |
//! |---|---|---|
//! | `range_bias` | residuals offset on every surface, at every range | median residual away from edges |
//! | `range_noise` | neighbouring firings on one surface disagree by more than the quantum | spread of neighbour differences (reference errors cancel) |
//! | `random_dropout` | predicted returns missing, independent of range, reflectivity, angle | share missing away from edges |
//! | `detection_threshold` | predicted returns missing where ρ cos θ / R² is small | the power threshold that best splits returned from missing (exact sweep) |
//! | `beam_divergence` | returns beyond object borders, mixed ranges at depth edges | grid over the divergence, scored on all firings |
//! | `motion_distortion` | residuals growing with the time since the rotation started, with ego speed | the switch: each firing at its own pose |
//! | `time_offset` | residuals along the ego's motion, proportional to speed and yaw rate | Gauss-Newton on the residuals away from edges |
//! | `mount_misalignment` | residuals that rotate with the sensor, also at standstill | Gauss-Newton on roll, pitch and yaw |
//! | `intensity` | measured reflectivity falls with the incidence angle | exponent k of cos θ by a robust fit, noise from the rest |
//! | `weather` | far returns missing in proportion to range beyond the threshold; near returns in front of the target | extinction on a grid with the threshold re-swept; clutter share over the firings whose receiver would report a droplet (`Clutter::support`) |
//!
//! Each effect also has a resolution floor: below it, the fitted value is not told apart from
//! the reference data's own errors and the candidate is not eligible (see [`FLOORS`]).

mod beam;
mod detection;
mod floors;
mod geometric;
pub(super) use geometric::least_clearing;
mod weather;
pub use floors::{floor, FLOORS};

use crate::sim::model::EffectKind;
use detection::{power_at, sort_rows, sweep, sweep_ll};
use geometric::{widened, Axis};

use super::bootstrap;
use super::likelihood::random_of;
use super::likelihood::{self, Random, Scored};
use super::observe::Obs;
use super::runset::{Gain, RunSet};
use super::GapError;
use crate::sim::model::{Effect, ModelFile};
use rayon::prelude::*;

/// A 95 % interval.
pub type Interval = (f64, f64);

/// The catalogue in the order its candidates are fitted.
pub const CATALOGUE: [EffectKind; 10] = [
    EffectKind::RangeBias,
    EffectKind::RangeNoise,
    EffectKind::RandomDropout,
    EffectKind::DetectionThreshold,
    EffectKind::MotionDistortion,
    EffectKind::TimeOffset,
    EffectKind::MountMisalignment,
    EffectKind::BeamDivergence,
    EffectKind::Intensity,
    EffectKind::Weather,
];

/// A predicted return away from edges: its bootstrap block, predicted power, and whether the
/// sensor returned it.
pub(super) type DetectionRow = (usize, f64, bool);

/// A fitted parameter.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Param {
    /// Name as in `model.toml` (borrowed where the fit names it, owned where read back).
    pub name: std::borrow::Cow<'static, str>,
    /// Fitted value.
    pub value: f64,
    /// 95 % bootstrap interval.
    pub interval: Option<(f64, f64)>,
}

/// One candidate of a round.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Candidate {
    /// The effect's name.
    pub effect: EffectKind,
    /// The effect as it would be added, every field of it as `model.fitted.toml` would hold
    /// it (the beam's footprint pattern and echo logic too, which `params` do not name);
    /// `None` when it could not be fitted.
    #[serde(default)]
    pub fitted: Option<Effect>,
    /// Effects of the current model re-fitted with it (a detection threshold re-fitted with
    /// beam divergence, which changes the received power).
    #[serde(skip)]
    pub refitted: Vec<Effect>,
    /// Its fitted parameters.
    pub params: Vec<Param>,
    /// Log-likelihood gain on the parameterization runs, nats.
    pub gain: f64,
    /// Its 95 % block-bootstrap interval.
    pub gain_interval: Option<(f64, f64)>,
    /// Gain per 1000 firings, nats.
    pub gain_per_1000_firings: f64,
    /// The fitted value clears the effect's resolution floor.
    pub above_floor: bool,
    /// Eligible: above the floor and a gain whose interval excludes zero.
    pub eligible: bool,
    /// What limited it, if anything.
    pub note: Option<String>,
}

impl Candidate {
    /// A candidate that could not be fitted, with why.
    fn unfitted(effect: EffectKind, note: String) -> Candidate {
        Candidate {
            effect,
            fitted: None,
            refitted: Vec::new(),
            params: vec![],
            gain: 0.0,
            gain_interval: None,
            gain_per_1000_firings: 0.0,
            above_floor: false,
            eligible: false,
            note: Some(note),
        }
    }
}

/// The range noise σ that explains neighbour differences `diffs` (block, m) of ranges
/// quantized to `quantum`, with its interval over the first 100 of `resamples`: the
/// differences dithered ([`likelihood::dither`]), each resample's spread by itself.
fn fitted_noise(
    mut diffs: Vec<(usize, f64)>,
    quantum: f64,
    resamples: &[Vec<u32>],
) -> (f64, Option<Interval>) {
    likelihood::dither(&mut diffs, quantum);
    let values: Vec<f64> = diffs.iter().map(|x| x.1).collect();
    let sigma = likelihood::noise_from_differences(&values, quantum).unwrap_or(0.0);
    let mut boots: Vec<f64> = resamples
        .iter()
        .take(100)
        .filter_map(|c| {
            likelihood::noise_from_differences(&bootstrap::resampled(&diffs, c), quantum)
        })
        .collect();
    (sigma, bootstrap::interval(&mut boots))
}

/// Whether a fitted value clears its floor with 95 % confidence: its whole bootstrap interval
/// (the value itself when there is none) lies at or beyond `floor` on one side of zero.
fn clears(value: f64, interval: Option<Interval>, floor: f64) -> bool {
    let (lo, hi) = interval.unwrap_or((value, value));
    let (lo, hi) = (lo.min(value), hi.max(value));
    lo >= floor || hi <= -floor
}

/// A detection threshold re-fitted along with another effect, as a parameter of that
/// candidate.
fn refitted_threshold(threshold: Option<&Effect>) -> Option<Param> {
    match threshold {
        Some(Effect::DetectionThreshold {
            reference_range_m, ..
        }) => Some(Param {
            name: "detection_threshold.reference_range_m (re-fitted)".into(),
            value: *reference_range_m,
            interval: None,
        }),
        _ => None,
    }
}

/// The reflectivity at which fitted detection thresholds are expressed (the specification
/// sheets' "range at 10 % reflectivity").
pub const REFERENCE_REFLECTIVITY: f64 = 0.10;

/// The parameterization runs and the current model's evaluation of them, which every
/// candidate is fitted on and scored against.
pub struct Fitting<'a> {
    /// The parameterization runs.
    pub set: &'a RunSet,
    /// The current model.
    pub current: &'a ModelFile,
    /// Its observations per run.
    pub obs: &'a [Vec<Obs>],
    /// Its scores per run.
    pub scored: &'a [Scored],
    /// The residual scales per run, held for the round.
    pub scales: &'a [likelihood::Scales],
}

/// `model` with `effect` added (replacing one of the same name).
pub fn with_effect(model: &ModelFile, effect: Effect) -> ModelFile {
    let mut m = model.clone();
    m.effects.retain(|e| e.name() != effect.name());
    m.effects.push(effect);
    m
}

impl<'a> Fitting<'a> {
    /// The fitting of `set` under `current`, from its evaluation `now` (observations, scores
    /// and residual scales of `current` on `set`).
    pub fn of(
        set: &'a RunSet,
        current: &'a ModelFile,
        now: &'a super::runset::Evaluation,
    ) -> Fitting<'a> {
        Fitting {
            set,
            current,
            obs: &now.obs,
            scored: &now.scored,
            scales: &now.scales,
        }
    }
}

impl Fitting<'_> {
    fn score_all(&self, obs: &[Vec<Obs>], random: Random) -> Vec<Scored> {
        self.set.score(obs, random, self.scales)
    }

    fn cast(&self, model: &ModelFile) -> Result<Vec<Vec<Obs>>, GapError> {
        self.set.cast(model)
    }

    fn candidate(
        &self,
        effect: EffectKind,
        fitted: Effect,
        params: Vec<Param>,
        above_floor: bool,
        scored: &[Scored],
    ) -> Candidate {
        let Gain {
            total: gain,
            interval: gain_interval,
            per_1000_firings: per,
        } = self.set.gain(scored, self.scored);
        let sum = |s: &[Scored]| {
            s.iter().fold([0.0; 4], |mut a, x| {
                for (t, v) in a.iter_mut().zip(x.terms) {
                    *t += v;
                }
                a
            })
        };
        let (new, old) = (sum(scored), sum(self.scored));
        tracing::debug!(
            "candidate {effect}: {params:?}: gain per term (detection, range, difference, intensity) {:?}",
            [new[0] - old[0], new[1] - old[1], new[2] - old[2], new[3] - old[3]]
        );
        let eligible = above_floor && gain_interval.is_some_and(|(lo, _)| lo > 0.0) && gain > 0.0;
        Candidate {
            effect,
            fitted: Some(fitted),
            refitted: Vec::new(),
            params,
            gain,
            gain_interval,
            gain_per_1000_firings: per,
            above_floor,
            eligible,
            note: (!above_floor).then(|| "fitted value below the resolution floor".to_owned()),
        }
    }

    /// Residuals away from edges, with their pooled block.
    fn residual_blocks(&self, obs: &[Vec<Obs>]) -> Vec<(usize, f64)> {
        let mut out = Vec::new();
        for (r, (o, f)) in obs.iter().zip(&self.set.feats).enumerate() {
            out.extend(
                likelihood::residuals(o, f)
                    .into_iter()
                    .map(|(s, e)| (self.set.blocks.of(r, s), e)),
            );
        }
        out
    }

    fn bias(&self) -> Result<Candidate, GapError> {
        let res = bootstrap::ByValue::new(self.residual_blocks(self.obs));
        let all: Vec<u32> = vec![1; self.set.blocks.len()];
        let b = res.weighted_median(&all).unwrap_or(0.0);
        // Each resample's median by itself (on every core; in order, so the same interval).
        let mut boots: Vec<f64> = self
            .set
            .resamples
            .par_iter()
            .filter_map(|c| res.weighted_median(c))
            .collect();
        let interval = bootstrap::interval(&mut boots);
        // The floor is tested on the lidar's own interval (it stands for the reference's
        // uncertainty already); the interval reported holds the survey's error too.
        let above = clears(b, interval, floor::RANGE_BIAS_M);
        let interval = interval.map(|i| widened(b, i, self.set.survey_sigma(self.obs)));
        let effect = Effect::RangeBias { bias_m: b };
        let model = with_effect(self.current, effect.clone());
        let scored = self.score_all(&self.cast(&model)?, random_of(&model));
        Ok(self.candidate(
            EffectKind::RangeBias,
            effect,
            vec![Param {
                name: "bias_m".into(),
                value: b,
                interval,
            }],
            above,
            &scored,
        ))
    }

    fn noise(&self) -> Candidate {
        let mut diffs = Vec::new();
        let mut quantum = 0.002f64;
        for (r, (o, f)) in self.obs.iter().zip(&self.set.feats).enumerate() {
            quantum = self.set.runs[r].range_quantum_m;
            diffs.extend(
                likelihood::differences(o, f)
                    .into_iter()
                    .map(|(s, d)| (self.set.blocks.of(r, s), d)),
            );
        }
        let (sigma, interval) = fitted_noise(diffs, quantum, &self.set.resamples);
        let effect = Effect::RangeNoise { sigma_m: sigma };
        let model = with_effect(self.current, effect.clone());
        let scored = self.score_all(self.obs, random_of(&model));
        self.candidate(
            EffectKind::RangeNoise,
            effect,
            vec![Param {
                name: "sigma_m".into(),
                value: sigma,
                interval,
            }],
            clears(sigma, interval, floor::RANGE_NOISE_M),
            &scored,
        )
    }

    /// Per block: predicted returns away from edges, and how many of them the sensor
    /// returned; and the rows (block, power, returned) for the threshold sweep.
    fn detections(&self) -> (Vec<DetectionRow>, Vec<(f64, f64)>) {
        self.detections_of(self.obs)
    }

    fn detections_of(&self, obs: &[Vec<Obs>]) -> (Vec<DetectionRow>, Vec<(f64, f64)>) {
        let mut rows = Vec::new();
        let mut per_block = vec![(0.0, 0.0); self.set.blocks.len()];
        for (r, (o, f)) in obs.iter().zip(&self.set.feats).enumerate() {
            for (o, f) in o.iter().zip(f) {
                if !o.cast || f.is_edge() || !o.predicted.is_finite() {
                    continue;
                }
                let b = self.set.blocks.of(r, f.scan);
                let hit = o.measured.is_finite();
                rows.push((b, f64::from(o.power), hit));
                per_block[b].0 += 1.0;
                if hit {
                    per_block[b].1 += 1.0;
                }
            }
        }
        (rows, per_block)
    }

    fn dropout(&self) -> Candidate {
        let (_, per_block) = self.detections();
        let share = |c: &[u32]| {
            let (n, h) = per_block.iter().zip(c).fold((0.0, 0.0), |a, (b, &k)| {
                (a.0 + f64::from(k) * b.0, a.1 + f64::from(k) * b.1)
            });
            (n > 0.0).then(|| (1.0 - h / (n * (1.0 - likelihood::EPS))).max(0.0))
        };
        let all = vec![1u32; self.set.blocks.len()];
        let p = share(&all).unwrap_or(0.0).min(0.999);
        let mut boots: Vec<f64> = self.set.resamples.iter().filter_map(|c| share(c)).collect();
        let interval = bootstrap::interval(&mut boots);
        let above = clears(p, interval, floor::DROPOUT);
        // The share assumes the sensor loses a further EPS of returns that no model explains
        // (the likelihood's floor); if it loses none, the dropout is larger by EPS (1 − p). The
        // reported interval holds both readings.
        let interval = interval.map(|(lo, hi)| (lo, hi + likelihood::EPS * (1.0 - hi)));
        let effect = Effect::RandomDropout { probability: p };
        let model = with_effect(self.current, effect.clone());
        let scored = self.score_all(self.obs, random_of(&model));
        self.candidate(
            EffectKind::RandomDropout,
            effect,
            vec![Param {
                name: "probability".into(),
                value: p,
                interval,
            }],
            above,
            &scored,
        )
    }

    /// The detection threshold (as a minimum power) that best explains which of `obs`'s
    /// predicted returns the sensor missed; `None` when no threshold beats none. Swept on the
    /// firings away from depth edges ([`DetectionRow`]s of `detections_of`): there a firing's
    /// echo is one, and a threshold that removes it leaves no return. (At an edge a
    /// dual-return packet's strongest block may hold the second strongest echo, whose removal
    /// leaves the last one there instead.)
    pub(super) fn threshold_of(&self, obs: &[Vec<Obs>]) -> Option<f64> {
        let (mut rows, _) = self.detections_of(obs);
        sort_rows(&mut rows);
        let keep = 1.0 - random_of(self.current).dropout;
        power_at(&rows, sweep(&rows, keep, &|_| 1.0))
    }

    /// The median predicted range of the firings (away from edges) whose predicted power lies
    /// within a quarter of `p_min`: where a threshold there decides; infinite when none does.
    fn ranges_near(&self, p_min: f64) -> f64 {
        let mut r: Vec<f64> = self
            .obs
            .iter()
            .zip(&self.set.feats)
            .flat_map(|(o, f)| o.iter().zip(f))
            .filter(|(o, f)| o.cast && !f.is_edge() && o.predicted.is_finite())
            .filter(|(o, _)| (f64::from(o.power) / p_min - 1.0).abs() < 0.25)
            .map(|(o, _)| f64::from(o.predicted))
            .collect();
        likelihood::median(&mut r).unwrap_or(f64::INFINITY)
    }

    fn threshold(&self) -> Result<Candidate, GapError> {
        let (mut rows, _) = self.detections();
        sort_rows(&mut rows);
        let keep = 1.0 - random_of(self.current).dropout;
        let k = sweep(&rows, keep, &|_| 1.0);
        let range_of = |p: f64| (REFERENCE_REFLECTIVITY / p).sqrt();
        let reference_reflectivity = REFERENCE_REFLECTIVITY;
        let Some(p_min) = power_at(&rows, k) else {
            return Ok(Candidate::unfitted(
                EffectKind::DetectionThreshold,
                "no threshold explains the missing returns better than none".into(),
            ));
        };
        let mut boots: Vec<f64> = self
            .set
            .resamples
            .iter()
            .take(100)
            .filter_map(|c| {
                let k = sweep(&rows, keep, &|i| f64::from(c[rows[i].0]));
                power_at(&rows, k).map(range_of)
            })
            .collect();
        let effect = Effect::DetectionThreshold {
            reference_range_m: range_of(p_min),
            reference_reflectivity,
        };
        // The powers are the model's, from the surveyed places: surfaces that all lie δ
        // farther than surveyed return 2δ / r less power than predicted at the threshold's
        // ranges r, and the reference range (power^-1/2) moves by δ / r, relative. The
        // interval holds that.
        let survey = self.set.survey_sigma(self.obs) / self.ranges_near(p_min);
        let interval = bootstrap::interval(&mut boots)
            .map(|i| widened(range_of(p_min), i, range_of(p_min) * survey));
        let model = with_effect(self.current, effect.clone());
        let scored = self.score_all(&self.cast(&model)?, random_of(&model));
        Ok(self.candidate(
            EffectKind::DetectionThreshold,
            effect,
            vec![
                Param {
                    name: "reference_range_m".into(),
                    value: range_of(p_min),
                    interval,
                },
                Param {
                    name: "reference_reflectivity".into(),
                    value: reference_reflectivity,
                    interval: None,
                },
            ],
            k as f64 >= floor::THRESHOLD_REMOVES * rows.len() as f64,
            &scored,
        ))
    }

    /// Fits one effect of the catalogue to the runs under the current model (which should not
    /// hold it): its candidate, or `None` where there is nothing to fit (motion distortion is a
    /// switch, and is `None` when the current model has it on already).
    pub fn fit(&self, kind: EffectKind) -> Result<Option<Candidate>, GapError> {
        Ok(Some(match kind {
            EffectKind::RangeBias => self.bias()?,
            EffectKind::RangeNoise => self.noise(),
            EffectKind::RandomDropout => self.dropout(),
            EffectKind::DetectionThreshold => self.threshold()?,
            EffectKind::MotionDistortion => return self.motion(),
            EffectKind::TimeOffset => self.time_offset()?,
            EffectKind::MountMisalignment => self.mount()?,
            EffectKind::BeamDivergence => self.divergence()?,
            EffectKind::Intensity => self.intensity()?,
            EffectKind::Weather => self.weather()?,
        }))
    }

    fn time_offset(&self) -> Result<Candidate, GapError> {
        // The trajectory's own timing is known only to the GNSS offset's uncertainty: the
        // reported interval holds it (see `geometric`).
        let time_sigma = self.set.largest_over_runs(|r| r.time_sigma_ms);
        self.geometric(
            EffectKind::TimeOffset,
            &[Axis {
                name: "offset_ms",
                step: 2.0,
                max_step: 60.0,
                reference_sigma: time_sigma,
            }],
            &|t| Effect::TimeOffset { offset_ms: t[0] },
            &|t, i| clears(t[0], i[0], floor::TIME_OFFSET_MS),
        )
    }

    fn mount(&self) -> Result<Candidate, GapError> {
        // The trajectory's heading error turns the whole scan like a mount yaw: the yaw's
        // reported interval holds it (see `geometric`).
        let heading_sigma = self.set.largest_over_runs(|r| r.heading_sigma_deg);
        let axis = |name, reference_sigma| Axis {
            name,
            step: 0.1,
            max_step: 3.0,
            reference_sigma,
        };
        self.geometric(
            EffectKind::MountMisalignment,
            &[
                axis("roll_deg", 0.0),
                axis("pitch_deg", 0.0),
                axis("yaw_deg", heading_sigma),
            ],
            &|t| Effect::MountMisalignment {
                roll_deg: t[0],
                pitch_deg: t[1],
                yaw_deg: t[2],
            },
            &|t, i| {
                clears(t[0], i[0], floor::MOUNT_DEG)
                    || clears(t[1], i[1], floor::MOUNT_DEG)
                    || clears(t[2], i[2], floor::MOUNT_DEG)
            },
        )
    }

    /// Every effect of the catalogue the current model lacks, fitted and scored, best first
    /// (weather only on top of a detection threshold, whose extinction it changes); `progress`
    /// is told the name of each as it starts.
    pub fn all(&self, progress: &dyn Fn(EffectKind)) -> Result<Vec<Candidate>, GapError> {
        let has = |kind: EffectKind| self.current.effects.iter().any(|e| e.kind() == kind);
        let mut out = Vec::new();
        for kind in CATALOGUE {
            let wanted = match kind {
                // A switch: `motion` says whether the current model has it off.
                EffectKind::MotionDistortion => true,
                EffectKind::Weather => !has(kind) && has(EffectKind::DetectionThreshold),
                _ => !has(kind),
            };
            if wanted {
                progress(kind);
                out.extend(self.fit(kind)?);
            }
        }
        out.sort_by(|a, b| b.gain.total_cmp(&a.gain));
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_threshold_sweep_finds_the_power_below_which_returns_go_missing() {
        // Powers 1..=1000 (×1e-6); returns below 300e-6 missing, one stray return below and one
        // stray miss above.
        let mut rows: Vec<DetectionRow> = (1..=1000)
            .map(|i| (0, f64::from(i) * 1e-6, i >= 300))
            .collect();
        rows[10].2 = true;
        rows[700].2 = false;
        // Out of order, with rows no power can be read for (no surface hit: NaN; behind the
        // sensor: 0), which the sweep must not count as missed returns below every threshold.
        rows.reverse();
        rows.push((0, f64::NAN, false));
        rows.push((0, 0.0, false));
        rows.swap(3, 500);
        sort_rows(&mut rows);
        assert_eq!(rows.len(), 1000);
        let k = sweep(&rows, 1.0, &|_| 1.0);
        let p = power_at(&rows, k).unwrap();
        assert!((p - 299.5e-6).abs() < 1e-6, "{p}");
        // No missing returns: no threshold.
        let all: Vec<DetectionRow> = (1..=100).map(|i| (0, f64::from(i), true)).collect();
        assert_eq!(power_at(&all, sweep(&all, 1.0, &|_| 1.0)), None);
    }

    /// The range noise's 95 % interval holds the truth in most samples of quantized ranges
    /// (2 mm, as a Velodyne reports them), for noise of a few quanta up to a few centimetres.
    /// Without the dither the intervals had zero width and held it in about half.
    #[test]
    fn the_noise_interval_of_quantized_ranges_holds_its_coverage() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let q = 0.002;
        let blocks = bootstrap::Blocks::new(&[600]);
        let resamples = blocks.resamples(5);
        let quantize = |r: f64| (r / q).round() * q;
        for sigma in [0.004, 0.0147, 0.031] {
            let (mut held, mut zero_width) = (0, 0);
            let samples = 30;
            for seed in 0..samples {
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000 + seed);
                let noise = Normal::new(0.0, sigma).unwrap();
                let diffs: Vec<(usize, f64)> = (0..6000)
                    .map(|_| {
                        let scan: u32 = rng.random_range(0..600);
                        // Neighbours 0.2° apart: on a surface facing the sensor their ranges
                        // differ by a fraction of a millimetre, at an oblique one by
                        // centimetres.
                        let p1 = 5.0 + 40.0 * rng.random::<f64>();
                        let step = if rng.random::<f64>() < 0.7 {
                            2e-4
                        } else {
                            0.04
                        };
                        let p2 = p1 + step * (rng.random::<f64>() - 0.5);
                        let e1 = quantize(p1 + noise.sample(&mut rng)) - p1;
                        let e2 = quantize(p2 + noise.sample(&mut rng)) - p2;
                        (blocks.of(0, scan), e1 - e2)
                    })
                    .collect();
                let (fit, interval) = fitted_noise(diffs, q, &resamples);
                let (lo, hi) = interval.unwrap();
                assert!(lo <= fit && fit <= hi, "{fit} outside [{lo}, {hi}]");
                zero_width += usize::from(hi - lo < 1e-9);
                held += usize::from(lo <= sigma && sigma <= hi);
            }
            assert_eq!(zero_width, 0, "sigma {sigma}");
            assert!(held >= 26, "sigma {sigma}: held in {held} of {samples}");
        }
    }

    #[test]
    fn a_floor_is_cleared_only_by_the_whole_interval() {
        assert!(clears(0.05, Some((0.04, 0.06)), 0.005));
        assert!(clears(-0.05, Some((-0.06, -0.04)), 0.005));
        assert!(!clears(0.05, Some((-0.01, 0.06)), 0.005));
        assert!(!clears(0.004, None, 0.005));
        assert!(clears(2.0, None, 1.0));
    }

    #[test]
    fn adding_an_effect_replaces_one_of_the_same_name() {
        let m = ModelFile::idealized();
        let m = with_effect(&m, Effect::RangeBias { bias_m: 0.1 });
        let m = with_effect(&m, Effect::RangeNoise { sigma_m: 0.01 });
        let m = with_effect(&m, Effect::RangeBias { bias_m: 0.2 });
        assert_eq!(m.effects.len(), 2);
        assert!(m.effects.contains(&Effect::RangeBias { bias_m: 0.2 }));
        let r = random_of(&m);
        assert_eq!((r.sigma_m, r.dropout, r.clutter), (0.01, 0.0, None));
    }
}

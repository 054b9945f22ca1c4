//! The weather candidate (rain or fog, `src/sim/model.rs`): two-way extinction `exp(−2αR)` of
//! the received power, which removes far returns through the detection threshold, and near
//! clutter: droplet echoes in front of the target that the receiver reports instead of it.
//! Offered when the model has a detection threshold (extinction acts only through it).
//!
//! Signature: returns missing more with range than the threshold alone explains, and returns
//! within a few metres where the model sees a farther target or none. Fit: for each α of a grid
//! the threshold is swept again on the attenuated power (the two trade off: a higher threshold
//! also removes far returns, but not in proportion to range); the clutter probability is the
//! share of clutter-like returns over the firings in which a clutter echo would be the
//! reported return (`Clutter::support`), its range the farthest such return.

use super::{
    power_at, random_of, refitted_threshold, sort_rows, sweep_ll, with_effect, Candidate,
    DetectionRow, Fitting, Param, REFERENCE_REFLECTIVITY,
};
use crate::gap::likelihood::{self, Clutter};
use crate::gap::observe::Obs;
use crate::gap::GapError;
use crate::sim::model::Effect;
use crate::sim::model::EffectKind;

/// Extinction coefficients tried, per metre (fog of 80 m visibility: 0.05; heavy rain of
/// 25 mm/h: about 0.007).
const ALPHAS: [f64; 16] = [
    0.0, 0.002, 0.003, 0.004, 0.005, 0.006, 0.0075, 0.009, 0.0105, 0.012, 0.014, 0.017, 0.02,
    0.025, 0.035, 0.05,
];

/// Steps between the grid's neighbours of its best extinction, searched again.
const REFINE_STEPS: u32 = 16;

/// Clutter-like returns lie within this range, m.
const CLUTTER_RANGE_M: f64 = 5.0;

/// A return this much nearer than the target, m, is clutter-like (nearer ones are the target's
/// own, with its noise); droplets within it of the target are neither counted nor exposed.
const TARGET_MARGIN_M: f64 = 0.5;

/// The apparent reflectivity of droplet echoes assumed in the fit (the catalogue's default).
const CLUTTER_REFLECTIVITY: f64 = 0.05;

impl Fitting<'_> {
    pub(super) fn weather(&self) -> Result<Candidate, GapError> {
        let mut base = self.current.clone();
        base.effects
            .retain(|e| !matches!(e, Effect::DetectionThreshold { .. }));
        let obs = self.cast(&base)?;
        let keep = 1.0 - random_of(self.current).dropout;
        // (block, power, returned, range) of predicted returns away from edges.
        let mut rows: Vec<(usize, f64, bool, f64)> = Vec::new();
        let mut clutter_ranges: Vec<f64> = Vec::new();
        for (r, (o, f)) in obs.iter().zip(&self.set.feats).enumerate() {
            for (o, f) in o.iter().zip(f) {
                if !o.cast || f.is_edge() {
                    continue;
                }
                let m = f64::from(o.measured);
                if o.measured.is_finite()
                    && m < CLUTTER_RANGE_M
                    && (!o.predicted.is_finite() || m < f64::from(o.predicted) - TARGET_MARGIN_M)
                {
                    clutter_ranges.push(m);
                }
                if o.predicted.is_finite() {
                    rows.push((
                        self.set.blocks.of(r, f.scan),
                        f64::from(o.power),
                        o.measured.is_finite(),
                        f64::from(o.predicted),
                    ));
                }
            }
        }
        // The detection log-likelihood at extinction α, and the threshold's power there.
        let at = |alpha: f64| {
            let mut attenuated: Vec<DetectionRow> = rows
                .iter()
                .map(|&(b, p, hit, range)| (b, p * (-2.0 * alpha * range).exp(), hit))
                .collect();
            sort_rows(&mut attenuated);
            let (k, ll) = sweep_ll(&attenuated, keep, &|_| 1.0);
            (ll, power_at(&attenuated, k))
        };
        // The best of `alphas`: (α, log-likelihood, threshold power).
        let best_of = |alphas: &mut dyn Iterator<Item = f64>| {
            alphas.fold((0.0, f64::NEG_INFINITY, None), |b, alpha| {
                let (ll, p) = at(alpha);
                if ll > b.1 {
                    (alpha, ll, p)
                } else {
                    b
                }
            })
        };
        let coarse = best_of(&mut ALPHAS.into_iter());
        // Then finer, at 15 points between the grid's neighbours of the best: the grid's
        // steps are 20-40 % apart (a true 0.027 /m was fitted as 0.035, now 0.0297; 0.0167 as
        // 0.014, now 0.0167).
        let i = ALPHAS.iter().position(|&a| a == coarse.0).unwrap_or(0);
        let (lo, hi) = (
            ALPHAS[i.saturating_sub(1)],
            ALPHAS[(i + 1).min(ALPHAS.len() - 1)],
        );
        let fine = best_of(
            &mut (1..REFINE_STEPS).map(|k| lo + (hi - lo) * f64::from(k) / f64::from(REFINE_STEPS)),
        );
        let (best, _, best_p) = if fine.1 > coarse.1 { fine } else { coarse };
        let clutter_like = clutter_ranges.len();
        let blind = self
            .current
            .limits
            .and_then(|l| l.min_range_m)
            .unwrap_or(0.5);
        // Droplet ranges are uniform from the blind zone out: the farthest from their 90th
        // percentile (robust to the odd return of another cause).
        clutter_ranges.sort_by(f64::total_cmp);
        let max_m = if clutter_like >= 20 {
            let q = clutter_ranges[clutter_like * 9 / 10];
            (blind + (q - blind) / 0.9).clamp(1.0, CLUTTER_RANGE_M)
        } else {
            3.0
        };
        let min_m = blind.min(max_m);
        let clutter = Clutter {
            probability: 1.0,
            min_m,
            max_m,
            reflectivity: CLUTTER_REFLECTIVITY,
            first_echo: likelihood::first_echo(self.current),
        };
        let exposure = self.exposure(&obs, &clutter, keep, (best, best_p));
        let probability = if exposure > 0.0 {
            (clutter_like as f64 / exposure).min(1.0)
        } else {
            0.0
        };
        let effect = Effect::Weather {
            extinction_per_m: best,
            clutter_probability: probability,
            clutter_max_range_m: max_m,
            clutter_reflectivity: CLUTTER_REFLECTIVITY,
        };
        let threshold = best_p.map(|p| Effect::DetectionThreshold {
            reference_range_m: (REFERENCE_REFLECTIVITY / p).sqrt(),
            reference_reflectivity: REFERENCE_REFLECTIVITY,
        });
        let mut model = with_effect(self.current, effect.clone());
        if let Some(t) = &threshold {
            model = with_effect(&model, t.clone());
        }
        let scored = self.score_all(&self.cast(&model)?, random_of(&model));
        let mut params = vec![
            Param {
                name: "extinction_per_m".into(),
                value: best,
                interval: None,
            },
            Param {
                name: "clutter_probability".into(),
                value: probability,
                interval: None,
            },
            Param {
                name: "clutter_max_range_m".into(),
                value: max_m,
                interval: None,
            },
        ];
        params.extend(refitted_threshold(threshold.as_ref()));
        let mut c = self.candidate(
            EffectKind::Weather,
            effect,
            params,
            best >= super::floor::EXTINCTION_PER_M || probability >= super::floor::CLUTTER,
            &scored,
        );
        c.refitted.extend(threshold);
        Ok(c)
    }

    /// The firings in which a droplet, when there is one, would be counted as clutter-like:
    /// the expected count per unit of clutter probability, for the runs cast without the
    /// weather and the threshold (`obs`), at the fitted extinction and threshold power
    /// (`fitted`).
    fn exposure(
        &self,
        obs: &[Vec<Obs>],
        clutter: &Clutter,
        keep: f64,
        (best, best_p): (f64, Option<f64>),
    ) -> f64 {
        // The firings in which a droplet, when there is one, is a clutter-like return: the
        // reported one, nearer than the target (`Clutter::support`) by the margin the count
        // asks, on a firing the dropout leaves (it takes the droplet's echo with the target's).
        keep * obs
            .iter()
            .flatten()
            .zip(self.set.feats.iter().flatten())
            .filter(|(o, f)| o.cast && !f.is_edge())
            .map(|(o, f)| {
                // Cast here without the weather: the target's power as the fitted
                // extinction leaves it, which the droplet must outshine (the score's
                // casts hold the extinction).
                let mut o = *o;
                if o.predicted.is_finite() {
                    o.power *= (-2.0 * best * f64::from(o.predicted)).exp() as f32;
                }
                // And without a threshold: in a block of last returns, a target the
                // fitted threshold does not detect lets the droplets in front of it
                // through, one it detects hides them all.
                let undetected = o.predicted.is_finite()
                    && f.reports == crate::sim::lidar::Reported::Last
                    && best_p.is_some_and(|p| f64::from(o.power) < p);
                // The farthest a reported droplet lies, and nearer than the target by the
                // count's margin.
                let reach = if undetected {
                    Some(f64::from(o.predicted))
                } else {
                    clutter.support(&o, f).map(|(_, hi)| hi)
                };
                let margin = if o.predicted.is_finite() {
                    f64::from(o.predicted) - TARGET_MARGIN_M
                } else {
                    f64::INFINITY
                };
                reach.map_or(0.0, |hi| clutter.share_up_to(hi.min(margin)))
            })
            .sum::<f64>()
    }
}

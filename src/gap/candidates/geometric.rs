//! The geometric candidates: a time offset and a mount misalignment fitted by Gauss-Newton
//! on the re-cast ranges, and motion distortion switched on.

use super::{random_of, with_effect, Candidate, Fitting, Interval, Param};
use crate::gap::bootstrap;
use crate::gap::likelihood;
use crate::gap::GapError;
use crate::sim::model::Effect;
use crate::sim::model::EffectKind;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Firings on smooth surfaces a geometric fit needs: its normal equations have up to four
/// unknowns, and the bootstrap resamples blocks of them.
const MIN_SMOOTH_FIRINGS: usize = 100;

/// The rows of a linearised fit, each a bootstrap block, a Jacobian row (intercept first) and
/// a residual, stored flat: the fit sums them for every bootstrap resample, six times, and a
/// row that was its own `Vec` took a cache miss each (`perf` of `gap` on three 10 s VLP-16
/// runs: the fit 15 % of its CPU time with a `Vec` per row, 6 % flat, with the same results).
struct Rows {
    /// Entries per Jacobian row: the intercept and one per axis.
    p: usize,
    /// The Jacobian rows, `p` entries each, one after the other.
    jacobian: Vec<f64>,
    /// The residuals.
    residual: Vec<f64>,
    /// Runs of consecutive rows of one block: (block, first row). Rows come scan by scan, so
    /// a resample that leaves a block out skips its rows at once.
    spans: Vec<(usize, usize)>,
}

impl Rows {
    fn new(p: usize) -> Rows {
        Rows {
            p,
            jacobian: Vec::new(),
            residual: Vec::new(),
            spans: Vec::new(),
        }
    }

    fn push(&mut self, block: usize, jacobian: &[f64], residual: f64) {
        debug_assert_eq!(jacobian.len(), self.p);
        if self.spans.last().is_none_or(|&(b, _)| b != block) {
            self.spans.push((block, self.residual.len()));
        }
        self.jacobian.extend_from_slice(jacobian);
        self.residual.push(residual);
    }

    fn len(&self) -> usize {
        self.residual.len()
    }

    /// Each span's block and its rows' range.
    fn blocks(&self) -> impl Iterator<Item = (usize, std::ops::Range<usize>)> + '_ {
        let ends = self.spans.iter().skip(1).map(|s| s.1).chain([self.len()]);
        self.spans
            .iter()
            .zip(ends)
            .map(|(&(b, from), to)| (b, from..to))
    }
}

/// One parameter of a geometric effect, as the fit steps it.
pub(super) struct Axis {
    /// Its name in the effect.
    pub name: &'static str,
    /// The one-sided difference step of the Jacobian.
    pub step: f64,
    /// The largest Gauss-Newton step.
    pub max_step: f64,
    /// The standard uncertainty it inherits from the reference data (0 for none; see
    /// [`Fitting::geometric`]).
    pub reference_sigma: f64,
}

/// Whether fitted values (with their intervals) clear the effect's floor.
pub(super) type FloorTest<'a> = &'a dyn Fn(&[f64], &[Option<Interval>]) -> bool;

impl Fitting<'_> {
    /// Gauss-Newton with robust (Huber) weights on the residuals away from edges for the
    /// parameters of a geometric effect, with an intercept as nuisance (a range offset must
    /// not pass for a rotation or a time shift). The Jacobian comes from one-sided differences
    /// of the re-cast ranges; rows where a step moves the beam to another surface are left
    /// out. Returns the parameters and their bootstrap intervals from the last linearisation.
    fn gauss_newton(
        &self,
        make: &dyn Fn(&[f64]) -> Effect,
        axes: &[Axis],
    ) -> Result<(Vec<f64>, Vec<Option<Interval>>), GapError> {
        let n = axes.len();
        let mut theta = vec![0.0; n];
        let mut last: Option<(Rows, Vec<f64>, f64)> = None;
        for _ in 0..5 {
            let base = self.cast(&with_effect(self.current, make(&theta)))?;
            let mut stepped = Vec::with_capacity(n);
            for k in 0..n {
                let mut t = theta.clone();
                t[k] += axes[k].step;
                stepped.push(self.cast(&with_effect(self.current, make(&t)))?);
            }
            let mut rows = Rows::new(n + 1);
            let mut row = Vec::with_capacity(n + 1);
            for r in 0..self.set.runs.len() {
                for (i, (o, f)) in base[r].iter().zip(&self.set.feats[r]).enumerate() {
                    if f.is_edge() || !o.measured.is_finite() || !o.predicted.is_finite() {
                        continue;
                    }
                    row.clear();
                    row.push(1.0);
                    let mut ok = true;
                    for (k, s) in stepped.iter().enumerate() {
                        let p = s[r][i].predicted;
                        let d = f64::from(p - o.predicted);
                        if !p.is_finite() || d.abs() > 0.3 {
                            ok = false;
                            break;
                        }
                        row.push(d / axes[k].step);
                    }
                    if ok {
                        rows.push(
                            self.set.blocks.of(r, f.scan),
                            &row,
                            f64::from(o.measured - o.predicted),
                        );
                    }
                }
            }
            if rows.len() < MIN_SMOOTH_FIRINGS {
                return Err(GapError::TooFewSmoothFirings {
                    firings: rows.len(),
                    needed: MIN_SMOOTH_FIRINGS,
                });
            }
            let s = likelihood::robust_sigma(&rows.residual)
                .unwrap_or(0.01)
                .max(1e-3);
            let all = vec![1u32; self.set.blocks.len()];
            let Some(delta) = irls(&rows, s, &all) else {
                break;
            };
            let mut done = true;
            for k in 0..n {
                let d = delta[k + 1].clamp(-axes[k].max_step, axes[k].max_step);
                if d.abs() > 0.02 * axes[k].step {
                    done = false;
                }
                theta[k] += d;
            }
            last = Some((rows, theta.clone(), s));
            if done {
                break;
            }
        }
        let Some((rows, at, s)) = last else {
            return Ok((theta, vec![None; n]));
        };
        // The linearisation point of the last rows is `at` minus the last step; the bootstrap
        // re-solves that step on resampled blocks.
        let all = vec![1u32; self.set.blocks.len()];
        let step = irls(&rows, s, &all).unwrap_or_else(|| vec![0.0; n + 1]);
        let mut intervals = Vec::with_capacity(n);
        // Each resample is solved by itself (on every core; in order, so the same intervals).
        let boots: Vec<Vec<f64>> = self.set.resamples[..self.set.resamples.len().min(100)]
            .par_iter()
            .filter_map(|c| irls(&rows, s, c))
            .collect();
        for k in 0..n {
            let mut v: Vec<f64> = boots
                .iter()
                .map(|b| at[k] - step[k + 1].clamp(-axes[k].max_step, axes[k].max_step) + b[k + 1])
                .collect();
            intervals.push(bootstrap::interval(&mut v));
        }
        Ok((theta, intervals))
    }

    /// A geometric effect fitted ([`Self::gauss_newton`]) and scored. Each axis's
    /// `reference_sigma` is the standard uncertainty it inherits from the reference data:
    /// a lidar time offset is measured against the trajectory's timing, known only to the GNSS
    /// offset's sigma, and a mount yaw against the smoothed heading, known only to its sigma.
    /// The bootstrap sees neither (it resamples the lidar's firings, not the reference), so
    /// each side of the reported 95 % interval is widened by 1.96 times it, in quadrature, and
    /// it is that interval which must clear the resolution floor. (Until 2026-11 the lidar's own
    /// interval had to clear the larger of the floor and one reference sigma: a true offset of
    /// zero seen through a reference 1.5 sigma off was added, its reported interval holding
    /// zero.)
    /// Repetitions of a drive pass the same places under the same sky, so their reference
    /// errors need not average out: the largest of the runs' sigmas is taken, not a mean.
    pub(super) fn geometric(
        &self,
        effect: EffectKind,
        axes: &[Axis],
        make: &dyn Fn(&[f64]) -> Effect,
        floor: FloorTest<'_>,
    ) -> Result<Candidate, GapError> {
        let (theta, intervals) = match self.gauss_newton(make, axes) {
            Ok(x) => x,
            Err(e) => return Ok(Candidate::unfitted(effect, e.to_string())),
        };
        let fitted = make(&theta);
        // The floor is tested on the interval reported, the reference's uncertainty in it: an
        // effect is never added while the interval it is reported with holds no effect at all.
        // Where the bootstrap gave none, on the reference's uncertainty alone (the value
        // itself would let an offset of the reference's own timing through).
        let tested = judged(&theta, &intervals, axes);
        let above = floor(&theta, &tested);
        // Reported: the same, where the bootstrap gave an interval.
        let intervals: Vec<Option<Interval>> = intervals
            .iter()
            .zip(tested)
            .map(|(own, t)| own.and(t))
            .collect();
        let model = with_effect(self.current, fitted.clone());
        let scored = self.score_all(&self.cast(&model)?, random_of(&model));
        let params = axes
            .iter()
            .zip(&theta)
            .zip(intervals)
            .map(|((a, v), i)| Param {
                name: a.name.into(),
                value: *v,
                interval: i,
            })
            .collect();
        Ok(self.candidate(effect, fitted, params, above, &scored))
    }

    pub(super) fn motion(&self) -> Result<Option<Candidate>, GapError> {
        let disabled = self
            .current
            .effects
            .iter()
            .any(|e| matches!(e, Effect::MotionDistortion { enabled: false }));
        if !disabled {
            return Ok(None);
        }
        let effect = Effect::MotionDistortion { enabled: true };
        let model = with_effect(self.current, effect.clone());
        let scored = self.score_all(&self.cast(&model)?, random_of(&model));
        Ok(Some(self.candidate(
            EffectKind::MotionDistortion,
            effect,
            vec![Param {
                name: "enabled".into(),
                value: 1.0,
                interval: None,
            }],
            true,
            &scored,
        )))
    }
}

/// Iteratively reweighted least squares (Huber, k = 1.345 s) of `rows`, each weighted by its
/// block's count; `None` where the normal equations are singular. The normal equations are
/// summed into fixed-size arrays, one triangle of the symmetric matrix only: this runs for every
/// bootstrap resample over every firing (summing into a `DMatrix` element by element was an
/// eighth of a `gap` round's CPU time; see [`Rows`] for their layout).
fn irls(rows: &Rows, s: f64, counts: &[u32]) -> Option<Vec<f64>> {
    // The catalogue's geometric effects have one to three axes and an intercept.
    match rows.p {
        1 => irls_of::<1>(rows, s, counts),
        2 => irls_of::<2>(rows, s, counts),
        3 => irls_of::<3>(rows, s, counts),
        4 => irls_of::<4>(rows, s, counts),
        p => unreachable!(
            "a geometric effect of {} axes: the catalogue's have at most three",
            p.saturating_sub(1)
        ),
    }
}

/// [`irls`] with `P` entries per Jacobian row.
fn irls_of<const P: usize>(rows: &Rows, s: f64, counts: &[u32]) -> Option<Vec<f64>> {
    if rows.len() == 0 || rows.p != P {
        return None;
    }
    let mut delta = [0.0; P];
    for _ in 0..6 {
        let mut a = [[0.0; P]; P];
        let mut b = [0.0; P];
        for (blk, range) in rows.blocks() {
            let c = f64::from(counts[blk]);
            if c == 0.0 {
                continue;
            }
            let jacobian = rows.jacobian[range.start * P..range.end * P].chunks_exact(P);
            for (j, &e) in jacobian.zip(&rows.residual[range]) {
                let r = e - j.iter().zip(&delta).map(|(x, d)| x * d).sum::<f64>();
                let w = c * (1.345 * s / r.abs().max(1e-12)).min(1.0);
                for k in 0..P {
                    let wj = w * j[k];
                    b[k] += wj * e;
                    for (acc, jl) in a[k][k..].iter_mut().zip(&j[k..]) {
                        *acc += wj * jl;
                    }
                }
            }
        }
        let m = DMatrix::from_fn(P, P, |k, l| a[k.min(l)][k.max(l)]);
        let x = m.lu().solve(&DVector::from_column_slice(&b))?;
        delta.copy_from_slice(x.as_slice());
    }
    Some(delta.to_vec())
}

/// The intervals a geometric effect's floor is tested on: the lidar's own `intervals` of the
/// fitted `theta`, each widened by its axis's reference sigma ([`widened`]); where the
/// bootstrap gave none, the reference's alone about the value.
pub(super) fn judged(
    theta: &[f64],
    intervals: &[Option<Interval>],
    axes: &[Axis],
) -> Vec<Option<Interval>> {
    intervals
        .iter()
        .zip(theta)
        .zip(axes)
        .map(|((i, &v), a)| {
            (i.is_some() || a.reference_sigma > 0.0)
                .then(|| widened(v, i.unwrap_or((v, v)), a.reference_sigma))
        })
        .collect()
}

/// The normal quantile of the reported intervals' 95 %.
const Z95: f64 = 1.96;

/// The least size of an effect whose interval, widened by `reference_sigma`, can clear `floor`:
/// the detection-limit search starts there.
pub(in crate::gap) fn least_clearing(floor: f64, reference_sigma: f64) -> f64 {
    floor + Z95 * reference_sigma.max(0.0)
}

/// `interval` about `value` with `sigma` more on each side: each half-width and 1.96 sigma in
/// quadrature.
pub(super) fn widened(value: f64, (lo, hi): Interval, sigma: f64) -> Interval {
    let extra = Z95 * sigma.max(0.0);
    let (below, above) = ((value - lo).max(0.0), (hi - value).max(0.0));
    (value - below.hypot(extra), value + above.hypot(extra))
}

#[cfg(test)]
mod tests {
    use super::super::{clears, floor};
    use super::{irls, judged, widened, Axis, Rows};

    /// The robust fit of a line e = 2 + 3 x through points with 1 cm scatter and one gross
    /// outlier: Huber's weights leave the outlier little say, and a block counted zero times
    /// (left out of this bootstrap resample) none.
    #[test]
    fn irls_fits_a_line_through_an_outlier_and_skips_uncounted_blocks() {
        let mut rows = Rows::new(2);
        for i in 0..40 {
            let x = f64::from(i) * 0.1;
            let scatter = if i % 2 == 0 { 0.01 } else { -0.01 };
            rows.push(0, &[1.0, x], 2.0 + 3.0 * x + scatter);
        }
        rows.push(0, &[1.0, 2.0], 50.0);
        // A block of wrong rows that the resample does not count.
        for i in 0..40 {
            rows.push(1, &[1.0, f64::from(i)], -100.0);
        }
        let fit = irls(&rows, 0.01, &[1, 0]).unwrap();
        assert!(
            (fit[0] - 2.0).abs() < 0.02 && (fit[1] - 3.0).abs() < 0.01,
            "{fit:?}"
        );
        assert_eq!(irls(&Rows::new(2), 0.01, &[1]), None);
    }

    /// Rows of one block that come back after another's are the same block: a resample that
    /// counts a block twice weighs all its stretches as two copies of them would be weighed,
    /// and one that leaves a block out fits the other's rows alone (four parameters, noisy
    /// rows with outliers, so that the weights move the fit).
    #[test]
    fn irls_weighs_every_stretch_of_a_block_by_its_count() {
        let truth = [0.5, -1.0, 2.0, 0.25];
        let row = |i: u32| {
            let x = f64::from(i);
            let j = [1.0, (x * 0.37).sin(), (x * 0.11).cos(), x * 0.01];
            let noise = 0.02 * (x * 1.7).sin() + if i.is_multiple_of(13) { 0.5 } else { 0.0 };
            let e: f64 = j.iter().zip(truth).map(|(a, b)| a * b).sum::<f64>() + noise;
            (j, e)
        };
        let mut rows = Rows::new(4);
        let (mut doubled, mut alone) = (Rows::new(4), Rows::new(4));
        for i in 0..60u32 {
            let (j, e) = row(i);
            // Stretches of three rows, each block's coming back after the other's.
            let block = (i / 3) as usize % 2;
            rows.push(block, &j, e);
            for _ in 0..2 - block {
                doubled.push(0, &j, e);
            }
            if block == 1 {
                alone.push(0, &j, e);
            }
        }
        assert_eq!(rows.spans.len(), 20);
        let close = |a: Vec<f64>, b: Vec<f64>| {
            assert!(
                a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-9),
                "{a:?} {b:?}"
            );
        };
        close(
            irls(&rows, 0.02, &[2, 1]).unwrap(),
            irls(&doubled, 0.02, &[1]).unwrap(),
        );
        close(
            irls(&rows, 0.02, &[0, 1]).unwrap(),
            irls(&alone, 0.02, &[1]).unwrap(),
        );
        // No block counted: nothing to solve.
        assert_eq!(irls(&rows, 0.02, &[0, 0]), None);
    }

    #[test]
    fn the_reference_widens_each_side_in_quadrature() {
        // 2.0 with [1.9, 2.2] and a reference sigma of 0.1: 1.96 x 0.1 = 0.196 more on each
        // side, in quadrature with 0.1 below and 0.2 above.
        let (lo, hi) = widened(2.0, (1.9, 2.2), 0.1);
        assert!((lo - (2.0 - (0.1f64.powi(2) + 0.196f64.powi(2)).sqrt())).abs() < 1e-12);
        assert!((hi - (2.0 + (0.2f64.powi(2) + 0.196f64.powi(2)).sqrt())).abs() < 1e-12);
        // No reference uncertainty: the interval stays.
        assert_eq!(widened(2.0, (1.9, 2.2), 0.0), (1.9, 2.2));
    }

    /// A time offset whose lidar interval is narrow but which the GNSS timing's own error could
    /// make: the seed-5 dual-return weather drive's 4.6 ms, its lidar interval about ±1 ms, the
    /// timing known to 3.1 ms. Its own interval clears the floor; the one it is reported and
    /// judged with holds zero. Four sigmas of the timing clear it.
    #[test]
    fn an_offset_the_reference_timing_explains_does_not_clear_its_floor() {
        let axis = |reference_sigma| Axis {
            name: "offset_ms",
            step: 2.0,
            max_step: 60.0,
            reference_sigma,
        };
        let lidar = (3.6, 5.6);
        assert!(clears(4.6, Some(lidar), floor::TIME_OFFSET_MS.max(3.1)));
        let tested = judged(&[4.6], &[Some(lidar)], &[axis(3.1)]);
        let reported = tested[0].unwrap();
        assert_eq!(reported, widened(4.6, lidar, 3.1));
        assert!(reported.0 < 0.0 && reported.1 > 10.0, "{reported:?}");
        assert!(!clears(4.6, tested[0], floor::TIME_OFFSET_MS));
        // Without a bootstrap interval, the reference's sigma alone still holds zero.
        let alone = judged(&[4.6], &[None], &[axis(3.1)]);
        assert!(!clears(4.6, alone[0], floor::TIME_OFFSET_MS), "{alone:?}");
        // Without a reference sigma either, the value is tested as it is (as `clears` does).
        assert_eq!(judged(&[4.6], &[None], &[axis(0.0)]), vec![None]);
        let far = judged(&[12.4], &[Some((11.4, 13.4))], &[axis(3.1)]);
        assert!(clears(12.4, far[0], floor::TIME_OFFSET_MS), "{far:?}");
    }
}

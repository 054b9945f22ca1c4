//! Block bootstrap over scans. Reference errors are correlated over seconds (RTK noise is a
//! Gauss-Markov process with a correlation time of about 2 s), so scans are resampled in blocks
//! of [`BLOCK_SCANS`] consecutive scans (2 s at 10 Hz), pooled over the runs.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Scans per bootstrap block.
pub const BLOCK_SCANS: usize = 20;

/// Scans that the parameterization runs, and the validation runs, must hold at least: two
/// blocks. With one, every resample is that block and a gain's interval is a single point, so
/// an effect would be added on the sign of one number.
pub const MIN_SCANS: usize = 2 * BLOCK_SCANS;

/// Resamples drawn for an interval.
pub const RESAMPLES: usize = 400;

/// The blocks of a set of runs: where each run's blocks start in the pooled numbering.
#[derive(Clone, Debug)]
pub struct Blocks {
    offsets: Vec<usize>,
    total: usize,
}

impl Blocks {
    /// Blocks of runs with these scan counts.
    pub fn new(scans: &[usize]) -> Blocks {
        let mut offsets = Vec::with_capacity(scans.len());
        let mut total = 0;
        for &n in scans {
            offsets.push(total);
            total += n.div_ceil(BLOCK_SCANS).max(1);
        }
        Blocks { offsets, total }
    }

    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.total
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.total == 0
    }

    /// The block of `scan` of run `run`.
    pub fn of(&self, run: usize, scan: u32) -> usize {
        self.offsets[run] + scan as usize / BLOCK_SCANS
    }

    /// `RESAMPLES` resamples, each as a count per block (how often it was drawn).
    pub fn resamples(&self, seed: u64) -> Vec<Vec<u32>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..RESAMPLES)
            .map(|_| {
                let mut c = vec![0u32; self.total];
                for _ in 0..self.total {
                    c[rng.random_range(0..self.total)] += 1;
                }
                c
            })
            .collect()
    }
}

/// The 2.5 % and 97.5 % quantiles of `values` (reordered).
pub fn interval(values: &mut [f64]) -> Option<(f64, f64)> {
    let v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    let mut v = v;
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    Some((at(0.025), at(0.975)))
}

/// The interval of a sum of per-block values.
pub fn sum_interval(per_block: &[f64], resamples: &[Vec<u32>]) -> Option<(f64, f64)> {
    let mut sums: Vec<f64> = resamples
        .iter()
        .map(|c| {
            c.iter()
                .zip(per_block)
                .map(|(&n, v)| f64::from(n) * v)
                .sum()
        })
        .collect();
    interval(&mut sums)
}

/// Values, each with its block, in ascending order: sorted once, so that the weighted median of
/// every resample is one pass over them (sorting again for each of the [`RESAMPLES`] was a
/// tenth of a `gap` round's CPU time).
pub struct ByValue(Vec<(usize, f64)>);

impl ByValue {
    /// `values` (block, value), sorted by value.
    pub fn new(mut values: Vec<(usize, f64)>) -> ByValue {
        values.sort_by(|a, b| a.1.total_cmp(&b.1));
        ByValue(values)
    }

    /// The weighted median with the resample's block counts: the smallest value at which the
    /// counts reach half of their total; `None` when the resample counts none of the values.
    pub fn weighted_median(&self, counts: &[u32]) -> Option<f64> {
        let total: u64 = self.0.iter().map(|&(b, _)| u64::from(counts[b])).sum();
        if total == 0 {
            return None;
        }
        let mut acc = 0u64;
        for &(b, x) in &self.0 {
            acc += u64::from(counts[b]);
            if 2 * acc >= total {
                return Some(x);
            }
        }
        self.0.last().map(|x| x.1)
    }
}

/// The values of a resample: each value repeated as often as its block was drawn.
pub fn resampled(values: &[(usize, f64)], counts: &[u32]) -> Vec<f64> {
    let mut out = Vec::with_capacity(values.len());
    for &(b, x) in values {
        for _ in 0..counts[b] {
            out.push(x);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_number_the_runs_scans_in_order() {
        let b = Blocks::new(&[45, 20, 1]);
        assert_eq!(b.len(), 3 + 1 + 1);
        assert_eq!(
            (b.of(0, 0), b.of(0, 19), b.of(0, 20), b.of(0, 44)),
            (0, 0, 1, 2)
        );
        assert_eq!((b.of(1, 0), b.of(1, 19), b.of(2, 0)), (3, 3, 4));
        let r = b.resamples(7);
        assert_eq!(r.len(), RESAMPLES);
        assert!(r.iter().all(|c| c.iter().sum::<u32>() as usize == b.len()));
        assert_eq!(r, b.resamples(7));
    }

    #[test]
    fn weighted_median_counts_each_block_as_often_as_drawn() {
        let v = [(0, 1.0), (0, 2.0), (1, 10.0), (2, 20.0)];
        // Given in any order.
        let sorted = ByValue::new(vec![(2, 20.0), (0, 2.0), (1, 10.0), (0, 1.0)]);
        assert_eq!(sorted.weighted_median(&[1, 1, 1]), Some(2.0));
        // Block 0 drawn three times: its values dominate.
        assert_eq!(sorted.weighted_median(&[3, 0, 1]), Some(2.0));
        assert_eq!(sorted.weighted_median(&[0, 1, 2]), Some(20.0));
        assert_eq!(sorted.weighted_median(&[0, 0, 0]), None);
        assert_eq!(resampled(&v, &[0, 2, 1]), vec![10.0, 10.0, 20.0]);
    }

    #[test]
    fn a_sum_interval_covers_the_sum_and_excludes_zero_for_a_clear_gain() {
        let per_block: Vec<f64> = (0..50).map(|i| 10.0 + f64::from(i % 5)).collect();
        let b = Blocks::new(&[50 * BLOCK_SCANS]);
        let (lo, hi) = sum_interval(&per_block, &b.resamples(1)).unwrap();
        let total: f64 = per_block.iter().sum();
        assert!(lo < total && total < hi && lo > 0.0, "{lo} {total} {hi}");
        assert_eq!(interval(&mut [f64::NAN]), None);
    }

    /// The rule that decides whether an effect is kept: a gain whose blocks scatter around zero
    /// must get an interval that holds zero (else noise is taken for an effect), and the same
    /// blocks shifted by a clear mean must not.
    #[test]
    fn a_zero_mean_gain_interval_holds_zero_and_a_shifted_one_does_not() {
        // Deterministic scatter of unit size around zero: ±1 alternating with ±0.5.
        let zero: Vec<f64> = (0..60)
            .map(|i| {
                let s = if i % 2 == 0 { 1.0 } else { -1.0 };
                s * if (i / 2) % 2 == 0 { 1.0 } else { 0.5 }
            })
            .collect();
        assert!(zero.iter().sum::<f64>().abs() < 1e-12);
        let b = Blocks::new(&[60 * BLOCK_SCANS]);
        let r = b.resamples(3);
        let (lo, hi) = sum_interval(&zero, &r).unwrap();
        assert!(lo < 0.0 && 0.0 < hi, "zero-mean gain: [{lo}, {hi}]");
        // The sum's bootstrap sd is sqrt(n) · sd(block) = sqrt(60 · 0.625) ≈ 6.1: the interval
        // spans about ±12; a mean of 1 a block (sum 60) lies far outside it.
        assert!(hi - lo > 6.0 && hi - lo < 40.0, "width {}", hi - lo);
        let shifted: Vec<f64> = zero.iter().map(|x| x + 1.0).collect();
        let (lo, _) = sum_interval(&shifted, &r).unwrap();
        assert!(lo > 0.0, "a clear gain: lower end {lo}");
    }
}

//! Spearman's rank correlation, with a percentile bootstrap interval: the trend of a metric
//! against a scenario quantity (Fig. 5 of Rosenberger et al. 2019: OCR against the mean
//! distance to the objects), without assuming the trend is linear.

use rand::{Rng, SeedableRng};

/// Ranks from 1, ties sharing their mean rank.
fn ranks(v: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i + 1;
        while j < idx.len() && v[idx[j]] == v[idx[i]] {
            j += 1;
        }
        let mean = (i + j + 1) as f64 / 2.0;
        for &k in &idx[i..j] {
            r[k] = mean;
        }
        i = j;
    }
    r
}

fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx).powi(2);
        syy += (b - my).powi(2);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

/// Spearman's ρ of the pairs (`x`, `y`): Pearson's correlation of their ranks. `None` with
/// fewer than three pairs, a constant side or a value that is not finite.
pub fn spearman(x: &[f64], y: &[f64]) -> Option<f64> {
    if x.len() != y.len() || x.len() < 3 || x.iter().chain(y).any(|v| !v.is_finite()) {
        return None;
    }
    pearson(&ranks(x), &ranks(y))
}

/// ρ with its percentile bootstrap 95 % interval (`rounds` resamples of the pairs with
/// replacement, seeded: the same data give the same interval).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Correlation {
    /// Spearman's ρ.
    pub rho: f64,
    /// 2.5th percentile of the bootstrap.
    pub low: f64,
    /// 97.5th percentile.
    pub high: f64,
    /// Pairs.
    pub n: usize,
}

/// [`spearman`] with its bootstrap interval.
pub fn spearman_with_interval(
    x: &[f64],
    y: &[f64],
    rounds: usize,
    seed: u64,
) -> Option<Correlation> {
    let rho = spearman(x, y)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let n = x.len();
    let mut boot: Vec<f64> = (0..rounds)
        .filter_map(|_| {
            let pick: Vec<usize> = (0..n).map(|_| rng.random_range(0..n)).collect();
            let bx: Vec<f64> = pick.iter().map(|&i| x[i]).collect();
            let by: Vec<f64> = pick.iter().map(|&i| y[i]).collect();
            spearman(&bx, &by)
        })
        .collect();
    if boot.is_empty() {
        return None;
    }
    boot.sort_by(f64::total_cmp);
    let at = |q: f64| boot[((q * (boot.len() - 1) as f64).round() as usize).min(boot.len() - 1)];
    Some(Correlation {
        rho,
        low: at(0.025),
        high: at(0.975),
        n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spearman_of_monotone_tied_and_worked_cases() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(spearman(&x, &[1.0, 4.0, 9.0, 16.0, 100.0]), Some(1.0));
        assert_eq!(spearman(&x, &[5.0, 3.0, 2.0, 1.0, 0.0]), Some(-1.0));
        // Worked: ranks of y = (2, 1, 4, 3, 5): 1 - 6 Σd² / (n (n² - 1)) = 1 - 6·4/120 = 0.8.
        let r = spearman(&x, &[20.0, 10.0, 40.0, 30.0, 50.0]).unwrap();
        assert!((r - 0.8).abs() < 1e-12, "{r}");
        // Ties share their mean rank.
        assert_eq!(ranks(&[3.0, 1.0, 3.0, 2.0]), vec![3.5, 1.0, 3.5, 2.0]);
        assert_eq!(spearman(&x, &[1.0; 5]), None);
        assert_eq!(spearman(&x[..2], &[1.0, 2.0]), None);
    }

    #[test]
    fn the_bootstrap_interval_holds_rho_and_narrows_with_more_pairs() {
        let noisy = |n: usize| -> (Vec<f64>, Vec<f64>) {
            let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
            let y: Vec<f64> = x
                .iter()
                .map(|v| -v + 7.0 * ((v * 12.9898).sin() * 43758.5453).fract())
                .collect();
            (x, y)
        };
        let (x, y) = noisy(30);
        let small = spearman_with_interval(&x, &y, 2000, 1).unwrap();
        assert!(
            small.low <= small.rho && small.rho <= small.high,
            "{small:?}"
        );
        let (x, y) = noisy(300);
        let big = spearman_with_interval(&x, &y, 2000, 1).unwrap();
        assert!(
            big.high - big.low < small.high - small.low,
            "{small:?} {big:?}"
        );
        assert!(big.high < 0.0);
    }
}

//! How well a model explains the measured firings: a log-likelihood per scan, summed over four
//! terms, so that candidates of every kind (a range offset, a detection rule, a geometry error,
//! a random effect) are scored on one scale, and the gain of a candidate can be bootstrapped
//! over the scans.
//!
//! - Detection: each firing returns or not. Where the model predicts a return, it comes with
//!   probability `(1 − dropout)(1 − ε)`; where it predicts none, with `ε` (ε = 10⁻³ is the rate
//!   of returns no model of the catalogue explains; 5 % at depth edges, where a few centimetres
//!   of reference error move a return from one surface to the other).
//! - Range: the residual measured − predicted of firings away from depth edges, a Gaussian whose
//!   scale is estimated from the current model's residuals (it holds the reference data's
//!   errors, which no lidar effect explains) and held for the round, with a 2 % outlier floor
//!   over ±5 m. A model that predicts the ranges better concentrates the residuals.
//! - Difference: the residual of a firing minus that of the same laser's previous firing (its
//!   neighbour 0.1-0.4° away on the same surface). Trajectory and survey errors are common to
//!   both and cancel; per-firing range noise does not: `Var = 2(σ² + q²/12) + τ²` with q the
//!   range quantum and τ = 1 mm for what the surface's shape leaves. This term is what tells
//!   range noise from reference noise.
//! - Intensity: measured − predicted calibrated reflectivity (diffuse targets), Gaussian with an
//!   estimated scale.
//!
//! Edge firings (see [`Feature::is_edge`]) enter the range term with their own scale and a 30 %
//! outlier share.

use super::observe::{Feature, Obs};

/// The random parts of a model, which the likelihood applies analytically.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Random {
    /// Range noise σ, m.
    pub sigma_m: f64,
    /// Dropout probability.
    pub dropout: f64,
    /// Weather clutter, if any.
    pub clutter: Option<Clutter>,
}

/// The weather effect's clutter: with `probability` a firing also sees a droplet echo at a
/// uniform range in `[min_m, max_m]` with the power of a `reflectivity` target; it is the
/// reported (strongest) echo when it outshines the target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clutter {
    /// Probability per firing.
    pub probability: f64,
    /// Nearest range (the sensor's blind zone), m.
    pub min_m: f64,
    /// Farthest range, m.
    pub max_m: f64,
    /// Apparent reflectivity.
    pub reflectivity: f64,
}

impl Clutter {
    /// The probability that a clutter echo, when there is one, is the strongest of a firing
    /// whose target echo has `power` (`None`: no target).
    pub fn wins(&self, power: Option<f64>) -> f64 {
        let span = (self.max_m - self.min_m).max(1e-9);
        match power {
            Some(p) if p > 0.0 => {
                let r = (self.reflectivity / p).sqrt().min(self.max_m);
                ((r - self.min_m) / span).clamp(0.0, 1.0)
            }
            _ => 1.0,
        }
    }
}

/// Returns no model explains, per firing (away from edges).
pub const EPS: f64 = 1e-3;
/// The same at depth edges.
pub const EPS_EDGE: f64 = 0.05;
const OUTLIER: f64 = 0.02;
const OUTLIER_EDGE: f64 = 0.3;
const WINDOW_M: f64 = 10.0;
const TAU_M: f64 = 1e-3;
const INTENSITY_WINDOW: f64 = 100.0;

/// Median of a slice (reordered); `None` when empty.
pub fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

/// 1.4826 × the median absolute deviation from the median: the standard deviation of a
/// Gaussian, robust to outliers.
pub fn robust_sigma(v: &[f64]) -> Option<f64> {
    let mut c = v.to_vec();
    let m = median(&mut c)?;
    let mut d: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    median(&mut d).map(|x| 1.4826 * x)
}

fn ln_gauss_mix(e: f64, sigma: f64, outlier: f64, window: f64) -> f64 {
    let g = (-0.5 * (e / sigma).powi(2)).exp() / (sigma * (2.0 * std::f64::consts::PI).sqrt());
    ((1.0 - outlier) * g + outlier / window).ln()
}

/// Both a measured and a predicted return.
fn both(o: &Obs) -> bool {
    o.measured.is_finite() && o.predicted.is_finite()
}

/// The log-likelihood terms of one evaluation.
#[derive(Clone, Debug, Default)]
pub struct Scored {
    /// Total per scan.
    pub per_scan: Vec<f64>,
    /// Sums of the terms: detection, range, difference, intensity.
    pub terms: [f64; 4],
    /// Firings counted.
    pub firings: usize,
}

/// The residual scales of a run: held fixed while the candidates of a round are scored, so that
/// a candidate gains by concentrating the residuals, not by the noise of a re-estimated scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scales {
    /// Away from edges, m.
    pub plain: f64,
    /// At edges, m.
    pub edge: f64,
    /// Intensity, counts.
    pub intensity: f64,
}

/// The robust residual scales of one run's observations under the current model.
pub fn scales(obs: &[Obs], feat: &[Feature]) -> Scales {
    let (mut plain, mut edge, mut intensity) = (Vec::new(), Vec::new(), Vec::new());
    for (o, f) in obs.iter().zip(feat) {
        if !both(o) {
            continue;
        }
        let e = f64::from(o.measured - o.predicted);
        if f.is_edge() {
            edge.push(e);
        } else {
            plain.push(e);
            if o.intensity <= 100 && o.reflectivity <= 1.0 {
                intensity.push(f64::from(o.intensity) - 100.0 * f64::from(o.reflectivity));
            }
        }
    }
    Scales {
        plain: robust_sigma(&plain).unwrap_or(0.01).max(1e-3),
        edge: robust_sigma(&edge).unwrap_or(0.05).max(5e-3),
        intensity: robust_sigma(&intensity).unwrap_or(1.0).max(0.5),
    }
}

/// Scores one run's observations under a model whose random parts are `random`, with the
/// residual scales `scales`; `quantum_m` is the sensor's range quantum, `scans` the run's scan
/// count.
pub fn score(
    obs: &[Obs],
    feat: &[Feature],
    random: Random,
    scales: &Scales,
    quantum_m: f64,
    scans: usize,
) -> Scored {
    let (s_plain, s_edge, s_int) = (scales.plain, scales.edge, scales.intensity);
    let q2 = quantum_m * quantum_m / 12.0;
    let s_diff = (2.0 * (random.sigma_m.powi(2) + q2) + TAU_M * TAU_M).sqrt();
    let s_plain = s_plain.max(random.sigma_m);
    let s_edge = (s_edge * s_edge + random.sigma_m.powi(2)).sqrt();
    let mut out = Scored {
        per_scan: vec![0.0; scans],
        ..Scored::default()
    };
    let keep = 1.0 - random.dropout;
    for (o, f) in obs.iter().zip(feat) {
        if !o.cast {
            continue;
        }
        out.firings += 1;
        let edge = f.is_edge();
        let eps = if edge { EPS_EDGE } else { EPS };
        let mut p_return = if o.predicted.is_finite() {
            keep * (1.0 - eps)
        } else {
            eps
        };
        // Clutter: a droplet echo that outshines the target replaces it.
        let clutter = random.clutter.map(|c| {
            let w = c.probability * c.wins(o.predicted.is_finite().then_some(f64::from(o.power)));
            (w, c)
        });
        if let Some((w, _)) = clutter {
            p_return = 1.0 - (1.0 - p_return) * (1.0 - w);
        }
        let det = if o.measured.is_finite() {
            p_return
        } else {
            1.0 - p_return
        }
        .max(1e-12)
        .ln();
        let mut terms = [det, 0.0, 0.0, 0.0];
        if both(o) {
            let e = f64::from(o.measured - o.predicted);
            terms[1] = if edge {
                ln_gauss_mix(e, s_edge, OUTLIER_EDGE, WINDOW_M)
            } else {
                ln_gauss_mix(e, s_plain, OUTLIER, WINDOW_M)
            };
            if let Some((w, c)) = clutter {
                let m = f64::from(o.measured);
                let uniform = if (c.min_m..=c.max_m).contains(&m) {
                    1.0 / (c.max_m - c.min_m).max(1e-9)
                } else {
                    0.0
                };
                terms[1] = ((1.0 - w) * terms[1].exp() + w * uniform).max(1e-300).ln();
            }
            if !edge {
                let n = f.neighbour as usize;
                if let (Some(no), Some(nf)) = (obs.get(n), feat.get(n)) {
                    if both(no) && !nf.is_edge() {
                        let d = e - f64::from(no.measured - no.predicted);
                        terms[2] = ln_gauss_mix(d, s_diff, OUTLIER, WINDOW_M);
                    }
                }
                if o.intensity <= 100 && o.reflectivity <= 1.0 {
                    let ei = f64::from(o.intensity) - 100.0 * f64::from(o.reflectivity);
                    terms[3] = ln_gauss_mix(ei, s_int, OUTLIER, INTENSITY_WINDOW);
                }
            }
        }
        for (t, v) in out.terms.iter_mut().zip(terms) {
            *t += v;
        }
        if let Some(s) = out.per_scan.get_mut(f.scan as usize) {
            *s += terms.iter().sum::<f64>();
        }
    }
    out
}

/// Residuals measured − predicted of non-edge firings with both returns, with their scans.
pub fn residuals(obs: &[Obs], feat: &[Feature]) -> Vec<(u32, f64)> {
    obs.iter()
        .zip(feat)
        .filter(|(o, f)| both(o) && !f.is_edge())
        .map(|(o, f)| (f.scan, f64::from(o.measured - o.predicted)))
        .collect()
}

/// Differences of neighbouring residuals (see the module doc), with their scans.
pub fn differences(obs: &[Obs], feat: &[Feature]) -> Vec<(u32, f64)> {
    obs.iter()
        .zip(feat)
        .filter(|(o, f)| both(o) && !f.is_edge())
        .filter_map(|(o, f)| {
            let n = f.neighbour as usize;
            let (no, nf) = (obs.get(n)?, feat.get(n)?);
            (both(no) && !nf.is_edge()).then(|| {
                (
                    f.scan,
                    f64::from(o.measured - o.predicted) - f64::from(no.measured - no.predicted),
                )
            })
        })
        .collect()
}

/// The range noise σ that explains the spread of `differences` (m), given the quantum.
pub fn noise_from_differences(differences: &[f64], quantum_m: f64) -> Option<f64> {
    let s = robust_sigma(differences)?;
    let var = s * s / 2.0 - quantum_m * quantum_m / 12.0 - TAU_M * TAU_M / 2.0;
    Some(var.max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn range_noise_is_recovered_from_neighbour_differences_whatever_the_common_offset() {
        // Residual = a slowly varying reference error common to neighbours + noise + quantum.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let quantum = 0.002;
        for sigma in [0.0f64, 0.01, 0.03] {
            let noise = Normal::new(0.0, sigma.max(1e-12)).unwrap();
            let drift = Normal::new(0.0, 0.05).unwrap();
            let diffs: Vec<f64> = (0..40_000)
                .map(|_| {
                    let common = drift.sample(&mut rng);
                    let q = |x: f64| (x / quantum).round() * quantum;
                    q(common + noise.sample(&mut rng)) - q(common + noise.sample(&mut rng))
                })
                .collect();
            let fitted = noise_from_differences(&diffs, quantum).unwrap();
            assert!(
                (fitted - sigma).abs() < 0.05 * sigma + 1.5e-3,
                "σ {sigma}: {fitted}"
            );
        }
    }

    #[test]
    fn clutter_wins_only_where_it_outshines_the_target() {
        let c = Clutter {
            probability: 0.1,
            min_m: 0.5,
            max_m: 3.0,
            reflectivity: 0.05,
        };
        assert_eq!(c.wins(None), 1.0);
        // A bright close target (power 1): no droplet between 0.5 and 3 m outshines it.
        assert_eq!(c.wins(Some(1.0)), 0.0);
        // A target of power 0.05 / 2² is outshone by droplets nearer than 2 m.
        assert!((c.wins(Some(0.05 / 4.0)) - 0.6).abs() < 1e-9);
        assert_eq!(c.wins(Some(1e-9)), 1.0);
    }

    #[test]
    fn robust_sigma_ignores_outliers() {
        let mut v: Vec<f64> = (0..999).map(|i| f64::from(i % 3) - 1.0).collect();
        v.extend([1e6, -1e6, 5e3]);
        let s = robust_sigma(&v).unwrap();
        assert!((s - 1.4826).abs() < 1e-9, "{s}");
        assert_eq!(median(&mut []), None);
    }
}

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
use crate::sim::lidar::Reported;
use crate::sim::model::{Effect, ModelFile};

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
/// uniform range in `[min_m, max_m]` with the power of a `reflectivity` target, hidden behind
/// the surface the beam meets. Which firings report it depends on the receiver
/// ([`Clutter::support`]).
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
    /// The receiver reports the nearest echo that holds its share of the footprint (a beam
    /// divergence's `first_echo_share`), not the strongest: a droplet fills the whole beam.
    pub first_echo: bool,
}

impl Clutter {
    /// The ranges at which a droplet echo is the return reported for firing `o` (`f` says
    /// which of its echoes the block reports), `None` where no droplet is: in front of the
    /// target, as near as the blind zone, and
    /// - for a block of strongest returns, only as near as it outshines the target;
    /// - for a block of last returns, nowhere when there is a target (it is the last echo);
    /// - for a first-echo receiver, and for a dual-return packet's strongest block, anywhere
    ///   in front of the target (a droplet there is the strongest echo, or the second
    ///   strongest where the target is both the strongest and the last).
    ///
    /// With no target predicted, the whole range. (Scored with the strongest echo's rule, the
    /// clutter share of two last-return drives was fitted 31 % low.)
    ///
    /// The target is the reported echo. Under a divergent beam the simulator also hides a
    /// droplet behind a nearer echo of part of the footprint that the receiver does not
    /// report (a sliver of an edge): there this support is wider than the simulator's. Such
    /// firings are edges, which the weather fit leaves out.
    pub fn support(&self, o: &Obs, f: &Feature) -> Option<(f64, f64)> {
        let hi = if !o.predicted.is_finite() {
            self.max_m
        } else if f.reports == Reported::Last {
            return None;
        } else {
            let front = f64::from(o.predicted).min(self.max_m);
            if self.first_echo || f.reports == Reported::DualStrongest {
                front
            } else {
                front.min(self.outshines_nearer_than(f64::from(o.power)))
            }
        };
        (hi > self.min_m).then_some((self.min_m, hi))
    }

    /// The range within which a droplet's echo is stronger than a target's of `power`, m.
    pub fn outshines_nearer_than(&self, power: f64) -> f64 {
        if power > 0.0 {
            (self.reflectivity / power).sqrt()
        } else {
            f64::INFINITY
        }
    }

    /// The probability that a droplet echo, when there is one, is the return reported for
    /// firing `o` ([`Clutter::support`]).
    pub fn wins_firing(&self, o: &Obs, f: &Feature) -> f64 {
        self.share_of(self.support(o, f))
    }

    /// The share of droplets that fall in `support` (`None`: none).
    pub fn share_of(&self, support: Option<(f64, f64)>) -> f64 {
        support.map_or(0.0, |(_, hi)| self.share_up_to(hi))
    }

    /// The share of droplets nearer than `range`, m.
    pub fn share_up_to(&self, range: f64) -> f64 {
        let span = (self.max_m - self.min_m).max(1e-9);
        ((range.min(self.max_m) - self.min_m) / span).clamp(0.0, 1.0)
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

pub use crate::estimate::robust::{core_sigma, median, robust_sigma};

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
    /// Per scan, a score of what shows a beam's width whatever its footprint model (not a
    /// part of the total): the detection term of every firing (returns beyond an object's
    /// silhouette, which grow with the beam) and the range of firings whose footprint mixes
    /// depths ([`Feature::is_mixed`]: the mixed ranges there), an edge's as in the total, a
    /// smaller step's scored within the depth its probes found off the hit's plane, with the
    /// edges' outlier share. A beam's width is fitted on this alone: on one plane, two
    /// footprint models of the same beam place the echo differently by tenths of
    /// millimetres (how they sample and weight the footprint), thousands of times over, and
    /// at a centimetre's step by millimetres to decimetres (how they group the depths),
    /// which is one implementation's echo logic and not the beam (a 4 mrad beam of another
    /// footprint model was fitted as 1.60 mrad through them).
    pub at_edges: Vec<f64>,
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
        at_edges: vec![0.0; scans],
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
        // Clutter: a droplet echo the receiver reports instead of the target replaces it;
        // `w` is the chance of one on a firing the dropout leaves (a dropped firing loses its
        // droplet with its target, as in the simulator and the weather fit's exposure).
        let clutter = random.clutter.map(|c| {
            let support = c.support(o, f);
            (c.probability * c.share_of(support), c, support)
        });
        let w = clutter.map_or(0.0, |(w, ..)| w);
        let p_return = if o.predicted.is_finite() {
            // Not dropped, and not both the target missed and no droplet.
            keep * (1.0 - eps * (1.0 - w))
        } else {
            // A return no model explains, or a droplet on a firing not dropped.
            1.0 - (1.0 - eps) * (1.0 - keep * w)
        };
        let det = if o.measured.is_finite() {
            p_return
        } else {
            1.0 - p_return
        }
        .max(1e-12)
        .ln();
        let mut terms = [det, 0.0, 0.0, 0.0];
        // The part at edges: the detection, and the range of a firing whose footprint mixes
        // depths (see `at_edges`).
        let mut at_edges = det;
        if both(o) {
            let e = f64::from(o.measured - o.predicted);
            // A range term with a droplet echo's density mixed in where clutter may have
            // replaced the target: uniform, probability / span, over the ranges where it is
            // the reported return, none elsewhere.
            let with_clutter = |ln: f64| match clutter {
                Some((_, c, support)) => {
                    let m = f64::from(o.measured);
                    let droplet = match support {
                        Some((lo, hi)) if (lo..=hi).contains(&m) => {
                            c.probability / (c.max_m - c.min_m).max(1e-9)
                        }
                        _ => 0.0,
                    };
                    ((1.0 - w) * ln.exp() + droplet).max(1e-300).ln()
                }
                None => ln,
            };
            terms[1] = with_clutter(if edge {
                ln_gauss_mix(e, s_edge, OUTLIER_EDGE, WINDOW_M)
            } else {
                ln_gauss_mix(e, s_plain, OUTLIER, WINDOW_M)
            });
            if edge {
                at_edges += terms[1];
            } else if f.is_mixed() {
                // Where the footprint mixes depths, the echo lies anywhere among them (how a
                // receiver groups and weighs the parts is its own): the range is scored within
                // the depth the probes found off the hit's plane, with the edges' outlier
                // share. (That depth stretched along the beam, divided by the incidence's
                // cosine, is the echo's possible spread at a plane's step; scored with it,
                // the test's 8 mrad beam of another footprint model was fitted as 4.5 mrad:
                // at grazing incidence it hid the mixed ranges the width shows in.)
                let depth = f64::from(f.off_plane);
                at_edges += with_clutter(ln_gauss_mix(
                    e,
                    s_plain.hypot(depth),
                    OUTLIER_EDGE,
                    WINDOW_M,
                ));
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
        if let Some(s) = out.at_edges.get_mut(f.scan as usize) {
            *s += at_edges;
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

/// The steepest incidence at which a surface's misplacement is turned into a range error:
/// beyond it (84°) the footprint's own spread and the sensor's noise take over.
const MIN_COS: f64 = 0.1;

/// The standard error that the median of the residuals of `runs` (each its firings and
/// features, and which survey of its scene it was measured against) inherits from the
/// surfaces' places. Each surface is misplaced along its normal by an error of its
/// [`Feature::accuracy`] that every firing on it shares (`accuracy / cos θ` in range), in every
/// run measured against the same survey; a bootstrap over scans cannot see it. A median moves
/// with the residuals about it: a surface's error moves it by the error times its firings'
/// share among the residuals within one robust σ of the median (each weighted by `1 / cos θ`),
/// and the surfaces' errors add in quadrature. (Weighting all residuals, as for a mean, gave the
/// ground's 2 cm at grazing incidence a 7 cm say in a median it hardly moves.)
pub fn survey_sigma<'a>(runs: impl IntoIterator<Item = (&'a [Obs], &'a [Feature], usize)>) -> f64 {
    // (survey, surface, accuracy, 1 / cos θ, residual)
    let mut rows: Vec<(usize, u32, f64, f64, f64)> = Vec::new();
    for (obs, feat, survey) in runs {
        for (o, f) in obs
            .iter()
            .zip(feat)
            .filter(|(o, f)| both(o) && !f.is_edge())
        {
            rows.push((
                survey,
                f.surface,
                f64::from(f.accuracy),
                1.0 / f64::from(f.cos).max(MIN_COS),
                f64::from(o.measured - o.predicted),
            ));
        }
    }
    let mut e: Vec<f64> = rows.iter().map(|r| r.4).collect();
    let (Some(s), Some(m)) = (robust_sigma(&e), median(&mut e)) else {
        return 0.0;
    };
    // (survey, surface) -> (accuracy, sum of 1 / cos θ about the median). Ordered: summed in
    // a hash map's order, the result changed in its last bits from one run of `gap` to the next
    // (its seed is the process's), and with it the intervals in `gap.json`.
    let mut surfaces: std::collections::BTreeMap<(usize, u32), (f64, f64)> = Default::default();
    let mut near = 0usize;
    for &(survey, surface, accuracy, w, r) in &rows {
        if (r - m).abs() <= s {
            near += 1;
            let e = surfaces.entry((survey, surface)).or_insert((accuracy, 0.0));
            e.1 += w;
        }
    }
    if near == 0 {
        return 0.0;
    }
    let n = near as f64;
    surfaces
        .values()
        .map(|(a, w)| (a * w / n).powi(2))
        .sum::<f64>()
        .sqrt()
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

/// Adds to each difference its own uniform draw over one range quantum (a fixed stream: the
/// same draws on every call), before [`noise_from_differences`].
///
/// Why: the differences of quantized ranges sit on a lattice of the quantum (offset only by
/// the predicted ranges' small differences), so their median absolute deviation jumps from one
/// lattice step to the next. A bootstrap resample then gives the very same spread as the
/// sample, and the range noise's 95 % interval had zero width; the estimate itself was off by
/// up to half a step (1 mm of a 14 mm deviation: 3-4 % of σ). Dithered, the spread is a smooth
/// function of the sample; the dither's own variance, q²/12, is taken out again.
pub fn dither(differences: &mut [(usize, f64)], quantum_m: f64) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(DITHER_STREAM);
    for (_, d) in differences {
        *d += quantum_m * (rng.random::<f64>() - 0.5);
    }
}

/// The dither's random stream.
const DITHER_STREAM: u64 = 0x6469_7468_6572;

/// The range noise σ that explains the spread of `dithered` differences (m, see [`dither`]),
/// given the quantum: `s² = 2(σ² + q²/12) + τ² + q²/12`, s the spread of the differences'
/// Gaussian core ([`core_sigma`]: pairs on a surface the model did not predict are left out).
pub fn noise_from_differences(dithered: &[f64], quantum_m: f64) -> Option<f64> {
    let s = core_sigma(dithered)?;
    let var = s * s / 2.0 - quantum_m * quantum_m / 8.0 - TAU_M * TAU_M / 2.0;
    Some(var.max(0.0).sqrt())
}

/// The random parts of a model.
pub fn random_of(model: &ModelFile) -> Random {
    let mut r = Random::default();
    for e in &model.effects {
        match *e {
            Effect::RangeNoise { sigma_m } => r.sigma_m = sigma_m,
            Effect::RandomDropout { probability } => r.dropout = probability,
            Effect::Weather {
                clutter_probability,
                clutter_max_range_m,
                clutter_reflectivity,
                ..
            } if clutter_probability > 0.0 => {
                r.clutter = Some(Clutter {
                    probability: clutter_probability,
                    min_m: model
                        .limits
                        .and_then(|l| l.min_range_m)
                        .unwrap_or(0.5)
                        .min(clutter_max_range_m),
                    max_m: clutter_max_range_m,
                    reflectivity: clutter_reflectivity,
                    first_echo: first_echo(model),
                });
            }
            _ => {}
        }
    }
    r
}

/// Whether `model`'s receiver reports the nearest echo holding its share of the footprint
/// (a beam divergence with `first_echo_share`), not the strongest.
pub fn first_echo(model: &ModelFile) -> bool {
    model.effects.iter().any(|e| {
        matches!(
            e,
            Effect::BeamDivergence {
                first_echo_share: Some(_),
                ..
            }
        )
    })
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

    /// Neighbour differences: each plain firing with both returns against its named
    /// neighbour, if that one has both returns and is not at an edge; with the firing's scan.
    #[test]
    fn differences_pair_each_firing_with_its_named_neighbour() {
        let at = |scan: u32, neighbour: u32| Feature {
            scan,
            neighbour,
            ..plain()
        };
        let obs = [
            firing(8.01, 8.0),     // 0: residual +1 cm
            firing(7.98, 8.0),     // 1: −2 cm, neighbour 0
            firing(f32::NAN, 8.0), // 2: no return
            firing(8.05, 8.0),     // 3: neighbour 2 has no return
            firing(9.0, 8.5),      // 4: an edge, neighbour 0
            firing(8.03, 8.0),     // 5: neighbour 4 is an edge
            firing(8.02, 8.0),     // 6: neighbour out of range
            firing(8.0, 8.0),      // 7: 0, neighbour 1
        ];
        let feat = [
            at(0, u32::MAX),
            at(1, 0),
            at(1, 0),
            at(1, 2),
            Feature {
                step: 5.0,
                ..at(1, 0)
            },
            at(2, 4),
            at(2, 99),
            at(3, 1),
        ];
        let d = differences(&obs, &feat);
        let r = |i: usize| f64::from(obs[i].measured - obs[i].predicted);
        assert_eq!(d, [(1, r(1) - r(0)), (3, r(7) - r(1))], "{d:?}");
    }

    /// The noise from the dithered differences' robust spread s: Var = 2 (σ² + q²/12) + τ²
    /// + q²/12, so σ² = s²/2 − q²/8 − τ²/2; below zero, no noise.
    #[test]
    fn the_noise_of_the_differences_in_closed_form() {
        // 100 differences of +3 cm, 100 of −3 cm and one of 0: s = 1.4826 × 3 cm.
        let mut d = vec![0.03; 100];
        d.extend([-0.03; 100]);
        d.push(0.0);
        let s = 1.4826 * 0.03;
        let q: f64 = 0.004;
        let want = (s * s / 2.0 - q * q / 8.0 - TAU_M * TAU_M / 2.0).sqrt();
        let got = noise_from_differences(&d, q).unwrap();
        assert!((got - want).abs() < 1e-12, "{got} vs {want}");
        // Differences no wider than the quantum and the surface explain: no noise.
        assert_eq!(
            noise_from_differences(&[0.0005, -0.0005, 0.0], 0.004),
            Some(0.0)
        );
        assert_eq!(noise_from_differences(&[], 0.004), None);
    }

    /// A wall (1000 firings head-on, surveyed to 5 cm) and the ground (1000 at 78°, to 1 cm):
    /// each holds half the residuals about the median, so each moves it by half its range
    /// error (2.5 cm; the ground's 1 cm is 5 cm in range), in quadrature. Residuals far from
    /// the median (another surface, 1 m off) do not move it; runs measured against one survey
    /// share its errors (they add), against two they do not (quadrature).
    #[test]
    fn the_survey_moves_the_median_by_the_surfaces_about_it() {
        let mut obs = Vec::new();
        let mut feat = Vec::new();
        for i in 0..3000 {
            // The same spread of residuals on the wall and the ground.
            let e = 1e-3 * f64::from((i / 3) % 11) - 5e-3;
            let (surface, cos, accuracy, e) = match i % 3 {
                0 => (1, 1.0, 0.05, e),
                1 => (crate::scene::SurfaceId::GROUND.0, 0.2, 0.01, e),
                _ => (2, 1.0, 0.5, 1.0),
            };
            obs.push(Obs {
                measured: 10.0 + e as f32,
                predicted: 10.0,
                ..Obs::default()
            });
            feat.push(Feature {
                range: 10.0,
                surface,
                cos,
                accuracy,
                ..Feature::default()
            });
        }
        let one = survey_sigma([(obs.as_slice(), feat.as_slice(), 0)]);
        let want = (0.025f64.powi(2) * 2.0).sqrt();
        assert!((one - want).abs() < 1e-3 * want, "{one} vs {want}");
        let same = survey_sigma([(obs.as_slice(), feat.as_slice(), 0); 2]);
        assert!((same - want).abs() < 1e-3 * want, "{same} vs {want}");
        let two = survey_sigma([(obs.as_slice(), feat.as_slice(), 0), (&obs, &feat, 1)]);
        assert!((two - want / 2f64.sqrt()).abs() < 1e-3 * want, "{two}");
        assert_eq!(survey_sigma([]), 0.0);
    }

    /// The same residuals give the same survey error to the last bit, however many surfaces
    /// they lie on: `gap` reports the same intervals run after run (a map summed in its hash
    /// order gave the last bits of each process's own order).
    #[test]
    fn the_survey_error_is_the_same_to_the_last_bit_every_time() {
        let (mut obs, mut feat) = (Vec::new(), Vec::new());
        for i in 0..4000u32 {
            obs.push(Obs {
                measured: 10.0 + 1e-3 * (i % 7) as f32,
                predicted: 10.0,
                ..Obs::default()
            });
            feat.push(Feature {
                range: 10.0,
                surface: i % 400,
                cos: 0.3 + 0.7 * (i % 13) as f32 / 13.0,
                accuracy: 0.001 * (1 + i % 37) as f32,
                ..Feature::default()
            });
        }
        let first = survey_sigma([(obs.as_slice(), feat.as_slice(), 0)]);
        assert!(first > 0.0);
        for _ in 0..50 {
            let again = survey_sigma([(obs.as_slice(), feat.as_slice(), 0)]);
            assert_eq!(again.to_bits(), first.to_bits());
        }
    }

    /// Droplet echoes in 10 % of the firings, from 0.5 to 3 m, of a 5 % target's brightness.
    const DRIZZLE: Clutter = Clutter {
        probability: 0.1,
        min_m: 0.5,
        max_m: 3.0,
        reflectivity: 0.05,
        first_echo: false,
    };

    #[test]
    fn clutter_wins_only_where_it_outshines_the_target() {
        let c = DRIZZLE;
        // A target beyond the clutter's reach, in a block of strongest returns, with `power`.
        let wins = |power: Option<f64>| match power {
            Some(p) => c.share_up_to(c.outshines_nearer_than(p)),
            None => c.wins_firing(&Obs::default(), &Feature::default()),
        };
        assert_eq!(wins(None), 1.0);
        // A bright close target (power 1): no droplet between 0.5 and 3 m outshines it.
        assert_eq!(wins(Some(1.0)), 0.0);
        // A target of power 0.05 / 2² is outshone by droplets nearer than 2 m.
        assert!((wins(Some(0.05 / 4.0)) - 0.6).abs() < 1e-9);
        assert_eq!(wins(Some(1e-9)), 1.0);
    }

    /// Which firings report a droplet. Strongest returns: in front of the target where it
    /// outshines it (a bright wall at 2 m: nowhere; a faint one at 10 m: the whole 0.5-3 m).
    /// Last returns: only where no target is predicted (a droplet is always in front of it).
    /// A first-echo receiver: anywhere in front of the target, however bright (2 m: 1.5 of
    /// the 2.5 m). With no target, every droplet shows.
    #[test]
    fn the_receiver_decides_which_droplets_show() {
        let c = DRIZZLE;
        let first = Clutter {
            first_echo: true,
            ..DRIZZLE
        };
        let obs = |range: f32, power: f32| Obs {
            measured: range,
            predicted: range,
            power,
            cast: true,
            ..Obs::default()
        };
        let last = Feature {
            reports: Reported::Last,
            ..Feature::default()
        };
        let dual = Feature {
            reports: Reported::DualStrongest,
            ..Feature::default()
        };
        let strongest = Feature::default();
        let (bright, faint, none) = (obs(2.0, 1.0), obs(10.0, 1e-9), Obs::default());
        assert_eq!(c.wins_firing(&bright, &strongest), 0.0);
        assert_eq!(c.support(&faint, &strongest), Some((0.5, 3.0)));
        assert_eq!(c.wins_firing(&faint, &strongest), 1.0);
        assert_eq!(c.wins_firing(&bright, &last), 0.0);
        assert_eq!(c.wins_firing(&faint, &last), 0.0);
        assert_eq!(c.wins_firing(&none, &last), 1.0);
        assert_eq!(first.support(&bright, &strongest), Some((0.5, 2.0)));
        assert!((first.wins_firing(&bright, &strongest) - 0.6).abs() < 1e-9);
        assert_eq!(first.wins_firing(&none, &strongest), 1.0);
        // A dual-return packet's strongest block reports a droplet anywhere in front of the
        // target, bright or faint (the droplet, or the second strongest where the target is
        // both strongest and last).
        assert_eq!(c.support(&bright, &dual), Some((0.5, 2.0)));
        assert_eq!(c.support(&faint, &dual), Some((0.5, 3.0)));
        assert_eq!(c.support(&bright, &strongest), None);
        assert_eq!(
            c.wins_firing(&bright, &dual),
            first.wins_firing(&bright, &strongest)
        );
    }

    /// The Gaussian density, written out: N(e; 0, s).
    fn gauss(e: f64, s: f64) -> f64 {
        (-e * e / (2.0 * s * s)).exp() / (s * (2.0 * std::f64::consts::PI).sqrt())
    }

    /// The log of the module doc's range model: a Gaussian of scale `s` with an outlier share
    /// `o` spread uniformly over a window `w`.
    fn ln_mixture(e: f64, s: f64, o: f64, w: f64) -> f64 {
        ((1.0 - o) * gauss(e, s) + o / w).ln()
    }

    /// A firing away from depth edges, at 8 m, without an azimuth neighbour, in scan 0.
    fn plain() -> Feature {
        Feature {
            range: 8.0,
            step: 0.0,
            neighbour: u32::MAX,
            ..Feature::default()
        }
    }

    /// A cast firing measuring `measured` where the model predicts `predicted` (NaN: none), the
    /// intensity byte out of the diffuse range (no intensity term).
    fn firing(measured: f32, predicted: f32) -> Obs {
        Obs {
            measured,
            predicted,
            intensity: 255,
            power: 1.0,
            reflectivity: f32::NAN,
            lambertian: f32::NAN,
            cast: true,
        }
    }

    const SCALES: Scales = Scales {
        plain: 1.0 / 64.0,
        edge: 0.05,
        intensity: 5.0,
    };

    fn score1(obs: &[Obs], feat: &[Feature], random: Random) -> Scored {
        score(obs, feat, random, &SCALES, 0.002, 1)
    }

    #[test]
    fn a_residual_scores_the_gaussian_density_of_the_held_scale() {
        // Exact in f32: a residual of 2/64 m, two of the held scale's 1/64 m.
        let s = score1(&[firing(8.031_25, 8.0)], &[plain()], Random::default());
        assert_eq!(s.firings, 1);
        // A predicted return comes with probability 1 − ε (ε = 10⁻³, no dropout).
        assert!(
            (s.terms[0] - (1.0f64 - 1e-3).ln()).abs() < 1e-12,
            "{:?}",
            s.terms
        );
        // The range term: the density of a 2-sigma residual, with the 2 % outlier floor over
        // the ±5 m window the module doc names.
        let want = ln_mixture(2.0 / 64.0, 1.0 / 64.0, 0.02, 10.0);
        assert!((s.terms[1] - want).abs() < 1e-9, "{} vs {want}", s.terms[1]);
        // 2 sigma below the peak: ln N(2σ) − ln N(0) = −2, diluted only by the floor.
        let peak = score1(&[firing(8.0, 8.0)], &[plain()], Random::default());
        let drop = s.terms[1] - peak.terms[1];
        assert!((drop + 2.0).abs() < 0.01, "{drop}");
        assert_eq!((s.terms[2], s.terms[3]), (0.0, 0.0));
    }

    #[test]
    fn dropout_changes_the_score_of_a_return_by_ln_one_minus_p_and_of_a_miss_by_its_probability() {
        let p = 0.1;
        let dropout = Random {
            dropout: p,
            ..Random::default()
        };
        let hit = [firing(8.0, 8.0)];
        let miss = [firing(f32::NAN, 8.0)];
        let f = [plain()];
        let gain_hit =
            score1(&hit, &f, dropout).terms[0] - score1(&hit, &f, Random::default()).terms[0];
        assert!(
            (gain_hit - (1.0f64 - p).ln()).abs() < 1e-12,
            "dropout {p} changes a return's score by {gain_hit}, not ln(1 - p) = {}",
            (1.0f64 - p).ln()
        );
        // A predicted return that is missing: lost to dropout (p) or to the unexplained rate.
        let miss_p = score1(&miss, &f, dropout);
        let want = (1.0 - (1.0 - p) * (1.0 - 1e-3)).ln();
        assert!((miss_p.terms[0] - want).abs() < 1e-12, "{:?}", miss_p.terms);
        let miss_0 = score1(&miss, &f, Random::default()).terms[0];
        assert!((miss_0 - 1e-3f64.ln()).abs() < 1e-12, "{miss_0}");
        // A miss has no range term.
        assert_eq!(miss_p.terms[1], 0.0);
    }

    /// A dropped firing loses its droplet with its target (as the simulator drops it): with a
    /// 0.5 dropout and a droplet on every firing, a firing with no target returns a droplet
    /// half the time, and a missing target is missed only when dropped (or both the target
    /// and the droplet are missed).
    #[test]
    fn a_dropped_firing_takes_its_droplet_with_it() {
        let rain = Random {
            dropout: 0.5,
            clutter: Some(Clutter {
                probability: 1.0,
                ..DRIZZLE
            }),
            ..Random::default()
        };
        let f = [plain()];
        // No target, a droplet at 2 m returned: the droplet's chance 0.5, or a stray return.
        let droplet = score1(&[firing(2.0, f32::NAN)], &f, rain);
        let want = (1.0f64 - (1.0 - 1e-3) * (1.0 - 0.5)).ln();
        assert!(
            (droplet.terms[0] - want).abs() < 1e-12,
            "{:?}",
            droplet.terms
        );
        // No target and nothing returned: the firing was dropped (or missed both).
        let nothing = score1(&[firing(f32::NAN, f32::NAN)], &f, rain);
        assert!(
            (nothing.terms[0] - ((1.0 - 1e-3) * 0.5f64).ln()).abs() < 1e-12,
            "{:?}",
            nothing.terms
        );
        // A faint target at 10 m that every droplet outshines: a return whenever not dropped.
        let target = Obs {
            power: 1e-9,
            ..firing(10.0, 10.0)
        };
        let kept = score1(&[target], &f, rain);
        assert!(
            (kept.terms[0] - 0.5f64.ln()).abs() < 1e-12,
            "{:?}",
            kept.terms
        );
    }

    /// The likelihood's clutter is the model's weather: its probability and reach, the blind
    /// zone of its limits, and a first-echo receiver where its divergence names a share.
    #[test]
    fn the_clutter_is_the_models_weather_and_its_receiver() {
        let model = |share: &str, probability: f64| -> ModelFile {
            toml::from_str(&format!(
                r#"
                name = "m"
                [limits]
                min_range_m = 0.8
                [[effect]]
                name = "detection_threshold"
                reference_range_m = 80.0
                reference_reflectivity = 0.1
                [[effect]]
                name = "weather"
                extinction_per_m = 0.004
                clutter_probability = {probability}
                clutter_max_range_m = 2.5
                [[effect]]
                name = "beam_divergence"
                horizontal_mrad = 3.0
                vertical_mrad = 1.5
                {share}
                "#
            ))
            .unwrap()
        };
        let c = random_of(&model("first_echo_share = 0.3", 0.02))
            .clutter
            .unwrap();
        assert_eq!((c.probability, c.min_m, c.max_m), (0.02, 0.8, 2.5));
        assert!(c.first_echo);
        assert!(!random_of(&model("", 0.02)).clutter.unwrap().first_echo);
        assert_eq!(random_of(&model("", 0.0)).clutter, None);
    }

    #[test]
    fn a_return_no_model_predicts_scores_the_unexplained_rate_and_more_at_depth_edges() {
        let stray = [firing(5.0, f32::NAN)];
        let s = score1(&stray, &[plain()], Random::default());
        assert!((s.terms[0] - 1e-3f64.ln()).abs() < 1e-12, "{:?}", s.terms);
        assert_eq!(s.terms[1], 0.0);
        let edge = Feature {
            step: 5.0,
            ..plain()
        };
        assert!(edge.is_edge());
        let e = score1(&stray, &[edge], Random::default());
        assert!((e.terms[0] - 0.05f64.ln()).abs() < 1e-12, "{:?}", e.terms);
        // Nothing predicted, nothing measured: the likely case.
        let quiet = score1(&[firing(f32::NAN, f32::NAN)], &[plain()], Random::default());
        assert!((quiet.terms[0] - (1.0f64 - 1e-3).ln()).abs() < 1e-12);
    }

    #[test]
    fn neighbour_differences_are_gaussian_with_twice_the_noise_and_the_quantum() {
        // Two firings of one laser on one surface: residuals 1 cm and −1 cm; the second names
        // the first as its neighbour.
        let obs = [firing(8.01, 8.0), firing(7.99, 8.0)];
        let feat = [
            plain(),
            Feature {
                neighbour: 0,
                ..plain()
            },
        ];
        let sigma = 0.006;
        let random = Random {
            sigma_m: sigma,
            ..Random::default()
        };
        let s = score1(&obs, &feat, random);
        // Var(e₂ − e₁) = 2 (σ² + q²/12) + τ²: two independent noisy, quantized residuals (q =
        // 2 mm) and what a surface's shape leaves (τ = 1 mm).
        let q: f64 = 0.002;
        let sd = (2.0 * (sigma * sigma + q * q / 12.0) + 1e-6).sqrt();
        let d = f64::from(7.99f32 - 8.0f32) - f64::from(8.01f32 - 8.0f32);
        let want = ln_mixture(d, sd, 0.02, 10.0);
        assert!((s.terms[2] - want).abs() < 1e-9, "{} vs {want}", s.terms[2]);
    }

    #[test]
    fn intensity_is_scored_against_the_predicted_reflectivity() {
        let o = Obs {
            intensity: 60,
            reflectivity: 0.5,
            ..firing(8.0, 8.0)
        };
        let s = score1(&[o], &[plain()], Random::default());
        // 60 counts measured where a reflectivity of 0.5 reads 50: two scales of 5 counts off,
        // outlier floor over the 100 counts of the diffuse range.
        let want = ln_mixture(10.0, 5.0, 0.02, 100.0);
        assert!((s.terms[3] - want).abs() < 1e-9, "{} vs {want}", s.terms[3]);
    }

    /// At a depth edge the range residual is scored with the held edge scale and the model's
    /// range noise added in quadrature (both spread it), and the edge's larger outlier share.
    #[test]
    fn an_edge_residual_scores_the_edge_scale_with_the_noise_added_in_quadrature() {
        let edge = Feature {
            step: 5.0,
            ..plain()
        };
        let noisy = Random {
            sigma_m: 0.03,
            ..Random::default()
        };
        let s = score1(&[firing(8.1, 8.0)], &[edge], noisy);
        // Held edge scale 0.05 m, noise 0.03 m: 0.058 m.
        let sd = (0.05f64 * 0.05 + 0.03 * 0.03).sqrt();
        let e = f64::from(8.1f32 - 8.0f32);
        let want = ln_mixture(e, sd, 0.3, 10.0);
        assert!((s.terms[1] - want).abs() < 1e-9, "{} vs {want}", s.terms[1]);
    }

    /// A return where the model predicts one, with rain: the range term mixes the target's
    /// density (weight 1 − w) with the droplets' uniform density over their span (weight w,
    /// w = the clutter probability where droplets outshine the target: all of it here).
    #[test]
    fn clutter_mixes_a_uniform_range_density_into_a_predicted_return() {
        let c = DRIZZLE;
        let rain = Random {
            clutter: Some(c),
            ..Random::default()
        };
        // A faint target at 2 m read at 1.5 m: 32 scales off, a droplet echo far likelier.
        // The target hides the droplets behind it: one reported in 0.1 × 1.5 / 2.5 firings,
        // at the density 0.1 / 2.5 per metre in front of it.
        let o = Obs {
            power: 1e-9,
            ..firing(1.5, 2.0)
        };
        let s = score1(&[o], &[plain()], rain);
        let target = ln_mixture(-0.5, 1.0 / 64.0, 0.02, 10.0).exp();
        let want = (0.94 * target + 0.1 / 2.5).ln();
        assert!((s.terms[1] - want).abs() < 1e-9, "{} vs {want}", s.terms[1]);
        // Read at 2.5 m, behind the target, it is no droplet's.
        let behind = score1(
            &[Obs {
                power: 1e-9,
                ..firing(2.5, 2.0)
            }],
            &[plain()],
            rain,
        );
        let want = (0.94 * ln_mixture(0.5, 1.0 / 64.0, 0.02, 10.0).exp()).ln();
        assert!(
            (behind.terms[1] - want).abs() < 1e-9,
            "{} vs {want}",
            behind.terms[1]
        );
    }

    /// The residual scales of a run: range residuals split at depth edges; intensity from the
    /// diffuse returns only (a retro-reflector's byte says nothing of the diffuse scale).
    #[test]
    fn scales_come_from_the_plain_and_edge_residuals_and_the_diffuse_intensities() {
        let (mut obs, mut feat) = (Vec::new(), Vec::new());
        for k in 0..200 {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            // Plain: ±2 cm, intensity 50 ± 4 where 0.5 reads 50.
            obs.push(Obs {
                intensity: (50.0 + 4.0 * sign) as u8,
                reflectivity: 0.5,
                ..firing(10.0 + 0.02 * sign, 10.0)
            });
            feat.push(plain());
            // Edge: ±20 cm.
            obs.push(firing(10.0 + 0.2 * sign, 10.0));
            feat.push(Feature {
                step: 5.0,
                ..plain()
            });
            // A retro-reflector: byte 100 where "reflectivity" 3 would read 300.
            obs.push(Obs {
                intensity: 100,
                reflectivity: 3.0,
                ..firing(10.0 + 0.02 * sign, 10.0)
            });
            feat.push(plain());
        }
        // One firing at the centre of each (an odd count: one median).
        obs.push(Obs {
            intensity: 50,
            reflectivity: 0.5,
            ..firing(10.0, 10.0)
        });
        feat.push(plain());
        obs.push(firing(10.0, 10.0));
        feat.push(Feature {
            step: 5.0,
            ..plain()
        });
        let s = scales(&obs, &feat);
        // Median absolute deviation × 1.4826: the plain residuals are ±2 cm, the edge ones
        // ±20 cm, the diffuse intensities ±4 counts (the retro-reflector's -200 counts left out).
        assert!((s.plain - 0.02 * 1.4826).abs() < 1e-6, "{s:?}");
        assert!((s.edge - 0.2 * 1.4826).abs() < 1e-5, "{s:?}");
        assert!((s.intensity - 4.0 * 1.4826).abs() < 1e-9, "{s:?}");
    }

    #[test]
    fn clutter_adds_returns_where_nothing_is_predicted() {
        let c = DRIZZLE;
        let rain = Random {
            clutter: Some(c),
            ..Random::default()
        };
        // Nothing predicted: a droplet echo (10 %) or an unexplained return (ε).
        let s = score1(&[firing(2.0, f32::NAN)], &[plain()], rain);
        let want = (1.0 - (1.0 - 1e-3) * (1.0 - 0.1f64)).ln();
        assert!((s.terms[0] - want).abs() < 1e-12, "{:?}", s.terms);
    }

    /// The part at edges: the detection of every firing, and the range of a firing whose
    /// footprint mixes depths, scored within the depth its probes found off the hit's plane
    /// (with the edges' outlier share); a plain firing's range, differences and intensity are not
    /// in it, nor the range of a mixed firing without a return; clutter enters both alike.
    #[test]
    fn the_part_at_edges_is_detection_and_the_ranges_of_mixed_footprints() {
        use crate::gap::observe::PLANAR_M;
        let on_plane = Feature {
            cos: 0.5,
            ..plain()
        };
        // 4 cm off the plane (met at 60°).
        let step = Feature {
            off_plane: 0.04,
            ..on_plane
        };
        let just_planar = Feature {
            off_plane: PLANAR_M,
            ..on_plane
        };
        let just_not = Feature {
            off_plane: PLANAR_M * 1.01,
            ..on_plane
        };
        assert!(!on_plane.is_mixed() && step.is_mixed() && !step.is_edge());
        assert!(!just_planar.is_mixed() && just_not.is_mixed());
        let edge = Feature {
            step: 9.0,
            ..plain()
        };
        assert!(edge.is_mixed());
        // One firing in scan 0, scored with its neighbours' in scan 1: (total, part at edges)
        // of scan 0.
        let one = |o: Obs, f: Feature, random: Random| {
            let mut feat = [on_plane, step, edge, f];
            for x in &mut feat[..3] {
                x.scan = 1;
            }
            feat[3].scan = 0;
            let obs = [firing(8.03, 8.0), firing(8.03, 8.0), firing(8.03, 8.0), o];
            let t = score(&obs, &feat, random, &SCALES, 0.002, 2);
            (t.per_scan[0], t.at_edges[0])
        };
        let none = Random::default();
        // A residual of 3 cm: almost two of the plain scale's 1/64 m.
        let e = f64::from(8.03f32 - 8.0);
        let det = (1.0 - 1e-3f64).ln();
        let det_edge = (1.0 - 0.05f64).ln();
        let plain_range = ln_mixture(e, SCALES.plain, 0.02, 10.0);
        // Plain: all of it in the total, only its detection at edges.
        let (total, at) = one(firing(8.03, 8.0), on_plane, none);
        assert!((at - det).abs() < 1e-12, "{at}");
        assert!((total - det - plain_range).abs() < 1e-9);
        // A 4 cm step: within its 4 cm at edges, as plain in the total.
        let (total, at) = one(firing(8.03, 8.0), step, none);
        let depth = f64::from(step.off_plane);
        let within = ln_mixture(e, SCALES.plain.hypot(depth), 0.3, 10.0);
        assert!((at - det - within).abs() < 1e-9, "{at}");
        assert!((total - det - plain_range).abs() < 1e-9);
        // A mixed firing that measured nothing: only its detection, in both.
        let (total, at) = one(firing(f32::NAN, 8.0), step, none);
        let missed = (1e-3f64).ln();
        assert!((at - missed).abs() < 1e-12 && (total - missed).abs() < 1e-12);
        // An edge: the same range term in both, with clutter or without.
        let (total, at) = one(firing(8.03, 8.0), edge, none);
        assert!((at - total).abs() < 1e-12, "{at} {total}");
        assert!((at - det_edge - ln_mixture(e, SCALES.edge, 0.3, 10.0)).abs() < 1e-9);
        let rain = Random {
            clutter: Some(Clutter {
                probability: 0.2,
                min_m: 1.0,
                max_m: 30.0,
                reflectivity: 0.05,
                first_echo: false,
            }),
            ..none
        };
        // A faint target at 8 m: a clutter echo in front of it outshines it.
        let faint = Obs {
            power: 1e-4,
            ..firing(8.03, 8.0)
        };
        let (total, at) = one(faint, edge, rain);
        assert!((at - total).abs() < 1e-12, "{at} {total}");
        assert!((at - one(faint, edge, none).1).abs() > 1e-3);
    }

    #[test]
    fn per_scan_scores_add_up_to_the_terms_and_uncast_firings_do_not_count() {
        let mut obs = Vec::new();
        let mut feat = Vec::new();
        for k in 0..30u32 {
            let r = 5.0 + k as f32 * 0.37;
            let measured = match k % 5 {
                0 => f32::NAN,
                1 => r + 0.02,
                _ => r - 0.003 * (k % 3) as f32,
            };
            obs.push(Obs {
                intensity: 40 + k as u8,
                reflectivity: 0.4,
                ..firing(measured, if k % 7 == 3 { f32::NAN } else { r })
            });
            feat.push(Feature {
                scan: k % 3,
                step: if k % 11 == 4 { 9.0 } else { 0.0 },
                neighbour: if k > 0 && k % 4 != 0 { k - 1 } else { u32::MAX },
                ..plain()
            });
        }
        let random = Random {
            sigma_m: 0.004,
            dropout: 0.05,
            clutter: None,
        };
        let s = score(&obs, &feat, random, &SCALES, 0.002, 3);
        assert_eq!(s.firings, 30);
        let total: f64 = s.terms.iter().sum();
        let per_scan: f64 = s.per_scan.iter().sum();
        assert!(
            (total - per_scan).abs() < 1e-9,
            "the terms add up to {total}, the scans to {per_scan}"
        );
        assert!(s.per_scan.iter().all(|x| *x < 0.0 && x.is_finite()));
        // Firings the model did not cast, with any values at all, change nothing.
        let mut more_obs = obs.clone();
        let mut more_feat = feat.clone();
        for k in 0..10u32 {
            more_obs.push(Obs {
                cast: false,
                ..firing(1.0 + k as f32, 50.0)
            });
            more_feat.push(Feature {
                scan: k % 3,
                ..plain()
            });
        }
        let t = score(&more_obs, &more_feat, random, &SCALES, 0.002, 3);
        assert_eq!(t.firings, 30, "uncast firings counted");
        assert_eq!(t.terms, s.terms, "uncast firings changed the terms");
        assert_eq!(
            t.per_scan, s.per_scan,
            "uncast firings changed the scans' scores"
        );
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

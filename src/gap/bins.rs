//! The disagreement, binned: per feature of the firings (range, reflectivity of the surface
//! hit, incidence angle, depth step in the beam's surroundings, ego speed and yaw rate, time
//! within the rotation, azimuth, laser, elevation), how often the sensor and the model return,
//! and the range residuals' median, spread and tails. What an engineer looks at to see *where*
//! simulation and measurement disagree; the candidates' signatures are read on the same data.

use super::likelihood::{median, robust_sigma};
use super::observe::{Feature, Obs};

/// One bin of one feature.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Bin {
    /// Lower edge (inclusive), in the feature's unit.
    pub from: f64,
    /// Upper edge (exclusive).
    pub to: f64,
    /// Firings cast.
    pub firings: usize,
    /// Share of them the sensor returned.
    pub measured_share: f64,
    /// Share the model returned.
    pub predicted_share: f64,
    /// Residuals (measured − predicted) of firings both returned: count.
    pub both: usize,
    /// Their median, m.
    pub median_m: Option<f64>,
    /// Their robust σ (1.4826 MAD), m.
    pub sigma_m: Option<f64>,
    /// 5 % quantile, m.
    pub p05_m: Option<f64>,
    /// 95 % quantile, m.
    pub p95_m: Option<f64>,
    /// This bin disagrees: the return shares differ by more than 1 point and three standard
    /// errors, or the median residual is beyond 1 cm and three standard errors.
    pub disagrees: bool,
}

/// The bins of one feature.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Table {
    /// Feature name and unit (borrowed where binned, owned where read back).
    pub feature: std::borrow::Cow<'static, str>,
    /// Its bins (empty ones left out).
    pub bins: Vec<Bin>,
}

type Getter = fn(&Feature, &Obs) -> Option<f64>;

/// The features and their bin edges.
fn features() -> Vec<(&'static str, Getter, Vec<f64>)> {
    vec![
        (
            "range_m",
            |f, o| {
                if o.predicted.is_finite() {
                    Some(f64::from(o.predicted))
                } else {
                    (f.range > 0.0).then_some(f64::from(f.range))
                }
            },
            vec![0.0, 2.0, 5.0, 10.0, 20.0, 40.0, 80.0, 400.0],
        ),
        (
            "reflectivity",
            |f, _| (f.range > 0.0).then_some(f64::from(f.rho)),
            vec![0.0, 0.1, 0.2, 0.4, 0.7, 1.0, 10.0],
        ),
        (
            "incidence_deg",
            |f, _| (f.range > 0.0).then(|| f64::from(f.cos).clamp(-1.0, 1.0).acos().to_degrees()),
            vec![0.0, 20.0, 40.0, 60.0, 75.0, 90.1],
        ),
        (
            "depth_step_m",
            |f, _| Some(f64::from(f.step).min(1e3)),
            vec![0.0, 0.05, 0.2, 1.0, 5.0, 1e3 + 1.0],
        ),
        (
            "ego_speed_mps",
            |f, _| Some(f64::from(f.speed)),
            vec![0.0, 0.3, 2.0, 5.0, 10.0, 100.0],
        ),
        (
            "yaw_rate_dps",
            |f, _| Some(f64::from(f.yaw_rate.abs())),
            vec![0.0, 2.0, 5.0, 10.0, 20.0, 1e3],
        ),
        (
            "time_in_rotation_s",
            |f, _| Some(f64::from(f.t_rotation)),
            vec![0.0, 0.02, 0.04, 0.06, 0.08, 0.1, 1.0],
        ),
        (
            "azimuth_deg",
            |f, _| Some(f64::from(f.azimuth)),
            (0..=12).map(|i| f64::from(i) * 30.0).collect(),
        ),
        (
            "laser",
            |f, _| Some(f64::from(f.laser)),
            (0..=128).map(f64::from).collect(),
        ),
        (
            "elevation_deg",
            |f, _| Some(f64::from(f.elevation)),
            (-5..=3).map(|i| f64::from(i) * 5.0).collect(),
        ),
    ]
}

/// The tables of one evaluation over several runs.
pub fn tables(runs: &[(&[Obs], &[Feature])]) -> Vec<Table> {
    features()
        .into_iter()
        .map(|(name, get, edges)| {
            let n = edges.len() - 1;
            let mut count = vec![0usize; n];
            let mut meas = vec![0usize; n];
            let mut pred = vec![0usize; n];
            let mut res: Vec<Vec<f64>> = vec![Vec::new(); n];
            for (obs, feat) in runs {
                for (o, f) in obs.iter().zip(feat.iter()) {
                    if !o.cast {
                        continue;
                    }
                    let Some(x) = get(f, o) else { continue };
                    let i = edges.partition_point(|e| *e <= x);
                    if i == 0 || i > n {
                        continue;
                    }
                    let b = i - 1;
                    count[b] += 1;
                    meas[b] += usize::from(o.measured.is_finite());
                    pred[b] += usize::from(o.predicted.is_finite());
                    if o.measured.is_finite() && o.predicted.is_finite() {
                        res[b].push(f64::from(o.measured - o.predicted));
                    }
                }
            }
            let bins = (0..n)
                .filter(|&b| count[b] > 0)
                .map(|b| {
                    let c = count[b] as f64;
                    let (ms, ps) = (meas[b] as f64 / c, pred[b] as f64 / c);
                    let r = &mut res[b];
                    let sigma = robust_sigma(r);
                    let med = median(r);
                    r.sort_by(f64::total_cmp);
                    let q =
                        |p: f64| (!r.is_empty()).then(|| r[((r.len() - 1) as f64 * p) as usize]);
                    let se_share = ((ms * (1.0 - ms) + ps * (1.0 - ps)) / c).sqrt();
                    let se_med =
                        sigma.map_or(f64::INFINITY, |s| 1.25 * s / (r.len() as f64).sqrt());
                    let disagrees = ((ms - ps).abs() > 0.01 && (ms - ps).abs() > 3.0 * se_share)
                        || med.is_some_and(|m| m.abs() > 0.01 && m.abs() > 3.0 * se_med);
                    Bin {
                        from: edges[b],
                        to: edges[b + 1],
                        firings: count[b],
                        measured_share: ms,
                        predicted_share: ps,
                        both: r.len(),
                        median_m: med,
                        sigma_m: sigma,
                        p05_m: q(0.05),
                        p95_m: q(0.95),
                        disagrees,
                    }
                })
                .collect();
            Table {
                feature: name.into(),
                bins,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(measured: f32, predicted: f32, cast: bool) -> Obs {
        Obs {
            measured,
            intensity: 50,
            predicted,
            power: 1.0,
            reflectivity: 50.0,
            lambertian: 50.0,
            cast,
        }
    }

    /// `n` firings on a mid-grey surface seen head-on.
    fn plain_features(n: usize) -> Vec<Feature> {
        vec![
            Feature {
                rho: 0.5,
                cos: 1.0,
                ..Feature::default()
            };
            n
        ]
    }

    /// Three range bins whose disagreement is known by construction: one where the sensor
    /// reads 5 cm farther than the model on every firing, one where it loses every tenth
    /// return, one that agrees to the millimetre; firings the model did not cast count nowhere.
    #[test]
    fn bins_find_a_known_bias_and_a_known_loss_and_pass_agreement() {
        let scatter = |i: usize| ((i % 5) as f32 - 2.0) * 0.0005;
        let mut o = Vec::new();
        for i in 0..2000 {
            o.push(obs(15.0 + 0.05 + scatter(i), 15.0, true));
            o.push(obs(
                if i % 10 == 0 {
                    f32::NAN
                } else {
                    25.0 + scatter(i)
                },
                25.0,
                true,
            ));
            o.push(obs(7.0 + scatter(i), 7.0, true));
        }
        for _ in 0..100 {
            o.push(obs(f32::NAN, 15.0, false));
        }
        let f = plain_features(o.len());
        let t = tables(&[(&o, &f)]);
        let range = t.iter().find(|t| t.feature == "range_m").unwrap();
        let bin = |from: f64| range.bins.iter().find(|b| b.from == from).unwrap();

        let biased = bin(10.0);
        assert_eq!(biased.firings, 2000, "uncast firings count nowhere");
        assert!((biased.median_m.unwrap() - 0.05).abs() < 1e-4, "{biased:?}");
        assert_eq!((biased.measured_share, biased.predicted_share), (1.0, 1.0));
        assert!(biased.disagrees);

        let lossy = bin(20.0);
        assert_eq!((lossy.firings, lossy.both), (2000, 1800));
        assert!((lossy.measured_share - 0.9).abs() < 1e-12, "{lossy:?}");
        assert_eq!(lossy.predicted_share, 1.0);
        assert!(lossy.median_m.unwrap().abs() < 1e-3);
        assert!(lossy.disagrees, "a tenth of the returns lost");

        let fine = bin(5.0);
        assert!(!fine.disagrees, "{fine:?}");
        assert!(
            fine.sigma_m.unwrap() < 2e-3 && fine.p05_m.unwrap() < 0.0 && fine.p95_m.unwrap() > 0.0
        );
    }

    /// The 5th and 95th percentiles of a bin's residuals are the order statistics at
    /// (n - 1) p, rounded down: of 40 residuals 0, 1, ..., 39 mm, 1 and 37 mm.
    #[test]
    fn a_bins_percentiles_are_its_order_statistics() {
        let o: Vec<Obs> = (0..40)
            .rev()
            .map(|k| obs(30.0 + k as f32 * 0.001, 30.0, true))
            .collect();
        let f = plain_features(o.len());
        let t = tables(&[(&o, &f)]);
        let bin = &t.iter().find(|t| t.feature == "range_m").unwrap().bins[0];
        assert_eq!(bin.both, 40);
        let (p05, p95) = (bin.p05_m.unwrap(), bin.p95_m.unwrap());
        assert!(
            (p05 - 0.001).abs() < 1e-5 && (p95 - 0.037).abs() < 1e-5,
            "p05 {p05}, p95 {p95}"
        );
    }
}

//! The area validation metric (Ferson, Oberkampf and Ginzburg 2008; Rosenberger et al. 2019,
//! §8): the area between the empirical cumulative distribution functions of a metric over the
//! real repetitions and over the simulated ones, ∫ |F_real(x) − F_sim(x)| dx, in the metric's
//! own unit. It is 0 only when the two samples have the same distribution and grows with both a
//! shift and a difference in spread. (It is the first Wasserstein distance of the two empirical
//! distributions, which is how scipy computes it: `tests/stats_interop.rs` holds the two
//! against each other.)
//!
//! And the traffic light of Fig. 7: the interval the metric spans over the real repetitions
//! against the one over the simulated repetitions.

/// The area between the empirical CDFs of `a` and `b`; `None` when either is empty or holds a
/// value that is not finite.
pub fn area_validation_metric(a: &[f64], b: &[f64]) -> Option<f64> {
    if a.is_empty() || b.is_empty() || a.iter().chain(b).any(|x| !x.is_finite()) {
        return None;
    }
    let (mut a, mut b) = (a.to_vec(), b.to_vec());
    a.sort_by(f64::total_cmp);
    b.sort_by(f64::total_cmp);
    let mut all: Vec<f64> = a.iter().chain(&b).copied().collect();
    all.sort_by(f64::total_cmp);
    let cdf = |s: &[f64], x: f64| s.partition_point(|&v| v <= x) as f64 / s.len() as f64;
    // Both CDFs are constant between consecutive values of the pooled sample.
    Some(
        all.windows(2)
            .map(|w| (cdf(&a, w[0]) - cdf(&b, w[0])).abs() * (w[1] - w[0]))
            .sum(),
    )
}

/// The traffic light of one scenario sample and metric (Fig. 7 of Rosenberger et al. 2019).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Light {
    /// 1: the simulated interval lies inside the real one.
    Green,
    /// 2: the intervals overlap, the simulated one reaches outside.
    Yellow,
    /// 3: the intervals are disjoint.
    Red,
    /// Not evaluable (no value on one side).
    Black,
}

/// The closed interval a sample spans; `None` when it is empty or not finite.
pub fn interval(v: &[f64]) -> Option<(f64, f64)> {
    if v.is_empty() || v.iter().any(|x| !x.is_finite()) {
        return None;
    }
    Some((
        v.iter().copied().fold(f64::INFINITY, f64::min),
        v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    ))
}

/// The light of the simulated values `sim` against the real values `real`.
pub fn light(real: &[f64], sim: &[f64]) -> Light {
    let (Some((ra, rb)), Some((sa, sb))) = (interval(real), interval(sim)) else {
        return Light::Black;
    };
    if sa >= ra && sb <= rb {
        Light::Green
    } else if sb < ra || sa > rb {
        Light::Red
    } else {
        Light::Yellow
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn worked_examples() {
        assert!(
            (area_validation_metric(&[1.0, 2.0, 3.0], &[2.0, 4.0]).unwrap() - 1.0).abs() < 1e-12
        );
        assert!(
            (area_validation_metric(&[0.0, 0.0, 1.0], &[0.0, 1.0, 1.0]).unwrap() - 1.0 / 3.0).abs()
                < 1e-12
        );
        assert_eq!(area_validation_metric(&[2.0, 1.0], &[1.0, 2.0]), Some(0.0));
        // A shift by d moves the whole CDF: the area is d.
        let a: Vec<f64> = (0..10).map(f64::from).collect();
        let b: Vec<f64> = a.iter().map(|x| x + 0.25).collect();
        assert!((area_validation_metric(&a, &b).unwrap() - 0.25).abs() < 1e-12);
        assert_eq!(area_validation_metric(&[], &[1.0]), None);
        assert_eq!(area_validation_metric(&[f64::NAN], &[1.0]), None);
    }

    #[test]
    fn traffic_lights_of_interval_cases() {
        let real = [0.5, 0.7, 0.6];
        assert_eq!(light(&real, &[0.55, 0.65]), Light::Green);
        assert_eq!(light(&real, &[0.5, 0.7]), Light::Green);
        assert_eq!(light(&real, &[0.6, 0.8]), Light::Yellow);
        assert_eq!(light(&real, &[0.4, 0.9]), Light::Yellow);
        assert_eq!(light(&real, &[0.71, 0.9]), Light::Red);
        assert_eq!(light(&real, &[0.1, 0.49]), Light::Red);
        // Intervals that touch in one value share it: overlapping, not disjoint.
        assert_eq!(light(&real, &[0.3, 0.5]), Light::Yellow);
        assert_eq!(light(&real, &[0.7, 0.9]), Light::Yellow);
        assert_eq!(light(&real, &[]), Light::Black);
        assert_eq!(light(&[], &[0.5]), Light::Black);
        assert_eq!(light(&real, &[f64::NAN]), Light::Black);
    }
}

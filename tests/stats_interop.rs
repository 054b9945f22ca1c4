//! The statistics against their reference implementations: the area validation metric against
//! scipy's `wasserstein_distance` (the same quantity: the area between two empirical CDFs).

use crate::common;

use common::interop_script;
use hilrig::stats::avm::area_validation_metric;
use rand::{Rng, SeedableRng};

#[test]
fn the_area_validation_metric_equals_scipy_s_wasserstein_distance() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2008);
    let mut pairs: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
    for (na, nb) in [(1, 1), (3, 2), (5, 17), (40, 9), (200, 333)] {
        let shift = rng.random_range(-1.0..1.0);
        let a: Vec<f64> = (0..na).map(|_| rng.random_range(0.0..1.0)).collect();
        let b: Vec<f64> = (0..nb)
            .map(|_| rng.random_range(0.0..2.0) * rng.random_range(0.0..1.0) + shift)
            .collect();
        pairs.push((a, b));
    }
    // Ties and repeated values.
    pairs.push((vec![0.0, 0.0, 1.0, 1.0, 1.0], vec![1.0, 0.0, 0.5]));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pairs.json");
    std::fs::write(&path, serde_json::to_string(&pairs).unwrap()).unwrap();
    let stdout = interop_script("wasserstein.py", &[path.as_os_str()]);
    let scipy: Vec<f64> = String::from_utf8(stdout)
        .unwrap()
        .lines()
        .map(|l| l.parse().unwrap())
        .collect();
    assert_eq!(scipy.len(), pairs.len());
    for ((a, b), want) in pairs.iter().zip(&scipy) {
        let got = area_validation_metric(a, b).unwrap();
        assert!(
            (got - want).abs() <= 1e-12 * want.max(1.0),
            "{} vs {}: {got} vs scipy {want}",
            a.len(),
            b.len()
        );
    }
}

//! What a drive says about its own sensors' noise: when the vehicle stands (the one time the
//! true yaw rate is known, zero), how noisy its yaw-rate sensor is then, and how many GNSS
//! epochs count as one independent measurement when the receiver's errors wander.

use hilrig_stamp::UtcNanos;
use nalgebra::Vector2;

/// Below this mean CAN speed (over [`STILL_WINDOW_NS`]) the vehicle stands still, m/s. A car
/// turns only by rolling (its yaw rate is speed times curvature, and the tightest curvature is
/// about 1/4 m), so at 1 cm/s it turns by less than 0.15° a second.
const STILL_SPEED: f64 = 0.01;
/// The window of that mean, ns: half a second either side.
const STILL_WINDOW_NS: i64 = 500_000_000;

/// Per CAN sample: whether the vehicle stands still (the mean speed over ±0.5 s is below 1 cm/s
/// either way: a mean of the signed speed, so that the sensor's noise averages out instead of
/// adding up).
pub fn standstill(motion: &[(UtcNanos, f64, f64)]) -> Vec<bool> {
    // Prefix sums of the speed for the windowed means.
    let mut sum = Vec::with_capacity(motion.len() + 1);
    sum.push(0.0);
    for m in motion {
        sum.push(sum[sum.len() - 1] + m.1);
    }
    motion
        .iter()
        .map(|&(t, _, _)| {
            let a = motion.partition_point(|m| m.0 .0 < t.0 - STILL_WINDOW_NS);
            let b = motion.partition_point(|m| m.0 .0 <= t.0 + STILL_WINDOW_NS);
            b > a && ((sum[b] - sum[a]) / (b - a) as f64).abs() < STILL_SPEED
        })
        .collect()
}

/// The CAN yaw-rate sensor's noise (standard deviation about its mean) while the vehicle stands
/// still, rad/s: the one time its true value is known. `None` with fewer than 50 such samples.
pub fn yaw_rate_noise(motion: &[(UtcNanos, f64, f64)]) -> Option<f64> {
    let w: Vec<f64> = motion
        .iter()
        .zip(standstill(motion))
        .filter(|(_, s)| *s)
        .map(|(m, _)| m.2)
        .collect();
    if w.len() < 50 {
        return None;
    }
    let mean = w.iter().sum::<f64>() / w.len() as f64;
    let var = w.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (w.len() - 1) as f64;
    Some(var.sqrt())
}

/// How many times more uncertain an estimate from GNSS residuals is than the smoother's white-
/// noise covariance says: the integrated autocorrelation time `1 + 2 Σ ρ_k` of the residuals
/// `errors` (normalised by their sigmas, both axes), summed until the autocorrelation first drops to
/// zero. RTK errors wander (multipath, atmosphere) over seconds, so ten epochs a second are far
/// fewer independent measurements; the variance of anything fitted to them grows by this
/// factor (Box, Jenkins and Reinsel, "Time Series Analysis", the variance of a mean of
/// autocorrelated data). `use_epoch` picks the epochs that count (RTK-fixed ones); a run of
/// them is only continued over consecutive epochs. At least 1.
pub fn correlation_factor(
    errors: &[Vector2<f64>],
    sigmas: &[Vector2<f64>],
    use_epoch: &[bool],
) -> f64 {
    let z: Vec<Option<Vector2<f64>>> = errors
        .iter()
        .zip(sigmas)
        .zip(use_epoch)
        .map(|((e, s), &u)| u.then(|| e.component_div(s)))
        .collect();
    integrated_autocorrelation(&z)
}

/// The integrated autocorrelation time `1 + 2 Σ ρ_k` of a series (gaps as `None`: a lag is
/// only taken between present samples), summed until ρ first drops to zero; at least 1, and 1
/// for fewer than ten samples.
pub fn integrated_autocorrelation(z: &[Option<Vector2<f64>>]) -> f64 {
    let n = z.iter().flatten().count();
    if n < 10 {
        return 1.0;
    }
    let mean = z.iter().flatten().fold(Vector2::zeros(), |a, v| a + v) / n as f64;
    let var = z
        .iter()
        .flatten()
        .map(|v| (v - mean).norm_squared())
        .sum::<f64>()
        / n as f64;
    if var <= 0.0 {
        return 1.0;
    }
    let mut tau = 1.0;
    for lag in 1..n / 4 {
        let (mut sum, mut pairs) = (0.0, 0usize);
        for k in lag..z.len() {
            if let (Some(a), Some(b)) = (z[k - lag], z[k]) {
                sum += (a - mean).dot(&(b - mean));
                pairs += 1;
            }
        }
        if pairs < 5 {
            break;
        }
        let rho = sum / pairs as f64 / var;
        if rho <= 0.0 {
            break;
        }
        tau += 2.0 * rho;
    }
    tau.max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// White residuals count once each; residuals that follow a first-order Gauss-Markov process
    /// with correlation ρ per epoch count (1 - ρ) / (1 + ρ) times (the closed form of
    /// 1 + 2 Σ ρ^k).
    #[test]
    fn correlation_factor_of_white_and_of_wandering_residuals() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let n = Normal::new(0.0, 1.0).unwrap();
        let res = |e: Vec<Vector2<f64>>| e;
        let count = 20_000;
        let white: Vec<Vector2<f64>> = (0..count)
            .map(|_| Vector2::new(n.sample(&mut rng), n.sample(&mut rng)))
            .collect();
        let sig = vec![Vector2::new(1.0, 1.0); count];
        let all = vec![true; count];
        let f = correlation_factor(&res(white), &sig, &all);
        assert!((f - 1.0).abs() < 0.1, "white: {f}");
        let rho: f64 = 0.9;
        let mut e = Vector2::zeros();
        let drive = (1.0 - rho * rho).sqrt();
        let wander: Vec<Vector2<f64>> = (0..count)
            .map(|_| {
                e = e * rho + Vector2::new(n.sample(&mut rng), n.sample(&mut rng)) * drive;
                e
            })
            .collect();
        let f = correlation_factor(&res(wander), &sig, &all);
        let expected = (1.0 + rho) / (1.0 - rho);
        assert!(
            (f - expected).abs() < 0.15 * expected,
            "Gauss-Markov: {f} vs {expected}"
        );
    }

    /// A drive that stands, rolls at 1 m/s and stands again: the standing samples are found
    /// (not the rolling ones, nor the noise of a sensor that reads up to 3 cm/s while standing), and
    /// the yaw-rate noise is the standing samples' spread.
    #[test]
    fn standing_still_and_the_yaw_rate_noise_are_read_from_the_data() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let n = Normal::new(0.0, 1.0).unwrap();
        let motion: Vec<(UtcNanos, f64, f64)> = (0..1500)
            .map(|k| {
                let t = k as f64 * 0.02;
                let v: f64 = if (10.0..20.0).contains(&t) { 1.0 } else { 0.0 };
                let noisy_speed = (v + 0.01 * n.sample(&mut rng)).max(0.0);
                (
                    UtcNanos(k * 20_000_000),
                    noisy_speed,
                    0.003 * n.sample(&mut rng),
                )
            })
            .collect();
        let still = standstill(&motion);
        for (k, s) in still.iter().enumerate() {
            let t = k as f64 * 0.02;
            if !(9.0..21.0).contains(&t) {
                assert!(*s, "standing at {t} s");
            }
            if (10.0..20.0).contains(&t) {
                assert!(!*s, "rolling at {t} s");
            }
        }
        let sigma = yaw_rate_noise(&motion).unwrap();
        assert!((sigma - 0.003).abs() < 0.0003, "yaw-rate noise {sigma}");
    }
}

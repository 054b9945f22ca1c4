//! The ego trajectory from RTK GNSS and CAN: an extended Kalman filter with a constant turn rate
//! and velocity (CTRV) motion model, followed by a Rauch-Tung-Striebel pass, so that every
//! instant uses the measurements before and after it.
//!
//! State (rear-axle centre, local ENU frame): `[x, y, ψ, v, ω, a]`, heading ψ from east
//! counter-clockwise, speed v along the heading (no side slip at parking speeds), yaw rate ω and
//! longitudinal acceleration a; and two constants that `check` wants to know: the GNSS time
//! offset δ (a fix stamped t describes the instant t - δ) and the antenna's forward lever arm,
//! both fixed at their configured values unless [`Settings::estimate_offset_and_lever`] is on.
//! The acceleration matters: with speed held constant between CAN
//! frames, the integrated position lags by half a frame interval (10 ms at 50 Hz) whenever the
//! vehicle accelerates, which would read as a GNSS time offset.
//! Measurements: the antenna's horizontal position (state position plus the rotated lever arm,
//! with the receiver's per-epoch sigmas), CAN speed and CAN yaw rate. Jacobians are taken
//! numerically: five states, and the model stays readable.

use crate::scene::pose::{PoseSample, Trajectory};
use hilrig_stamp::UtcNanos;
use nalgebra::{SMatrix, SVector, Vector2, Vector3};

type S = SVector<f64, 8>;
type P = SMatrix<f64, 8, 8>;

/// Index of the GNSS time offset δ (s) in the state: a fix stamped t describes t - δ.
const DELTA: usize = 6;
/// Index of the antenna's forward lever arm (m) in the state.
const LEVER_X: usize = 7;

/// One GNSS antenna position in the local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssObs {
    /// Epoch time.
    pub t: UtcNanos,
    /// East, north of the antenna, m.
    pub position: Vector2<f64>,
    /// 1-sigma east and north error, m.
    pub sigma: Vector2<f64>,
}

/// Noise settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Antenna position in the vehicle frame (x forward, y left), m.
    pub lever: Vector2<f64>,
    /// Longitudinal jerk noise, m/s³ per √s.
    pub accel_noise: f64,
    /// Yaw acceleration noise, rad/s² per √s.
    pub yaw_accel_noise: f64,
    /// CAN speed noise, m/s.
    pub speed_sigma: f64,
    /// CAN yaw-rate noise, rad/s.
    pub yaw_rate_sigma: f64,
    /// Estimate the GNSS time offset and the antenna's forward lever arm as constant states
    /// (starting from 0 s and `lever.x`) instead of taking them as given.
    pub estimate_offset_and_lever: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            lever: Vector2::zeros(),
            accel_noise: 3.0,
            yaw_accel_noise: 1.0,
            speed_sigma: 0.03,
            yaw_rate_sigma: 0.005,
            estimate_offset_and_lever: false,
        }
    }
}

/// A GNSS epoch against the smoothed trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Residual {
    /// Epoch time.
    pub t: UtcNanos,
    /// Measured minus smoothed antenna position (east, north), m.
    pub error: Vector2<f64>,
    /// Normalised by the receiver's sigmas: |e/σ|² (χ² with 2 degrees of freedom).
    pub nis: f64,
}

/// The smoothed trajectory.
#[derive(Clone, Debug)]
pub struct EgoTrajectory {
    times: Vec<UtcNanos>,
    states: Vec<S>,
    covs: Vec<P>,
    /// GNSS residuals against the smoothed trajectory.
    pub residuals: Vec<Residual>,
}

fn ctrv(x: &S, dt: f64) -> S {
    let (px, py, psi, v, w, a) = (x[0], x[1], x[2], x[3], x[4], x[5]);
    // The turn at constant rate with the mean speed of the interval.
    let vm = v + 0.5 * a * dt;
    let (nx, ny) = if w.abs() > 1e-6 {
        (
            px + vm / w * ((psi + w * dt).sin() - psi.sin()),
            py + vm / w * (psi.cos() - (psi + w * dt).cos()),
        )
    } else {
        (px + vm * dt * psi.cos(), py + vm * dt * psi.sin())
    };
    S::from_column_slice(&[nx, ny, psi + w * dt, v + a * dt, w, a, x[DELTA], x[LEVER_X]])
}

fn jacobian<const M: usize>(f: impl Fn(&S) -> SVector<f64, M>, x: &S) -> SMatrix<f64, M, 8> {
    let mut j = SMatrix::<f64, M, 8>::zeros();
    for i in 0..8 {
        let h = 1e-6 * (1.0 + x[i].abs());
        let (mut a, mut b) = (*x, *x);
        a[i] += h;
        b[i] -= h;
        let d = (f(&a) - f(&b)) / (2.0 * h);
        j.set_column(i, &d);
    }
    j
}

/// Where the antenna was at the instant a fix stamped now describes: the state's position plus
/// the rotated lever arm (forward part from the state), moved back by δ along the antenna's
/// velocity.
fn antenna(x: &S, lever: &Vector2<f64>) -> Vector2<f64> {
    let (s, c) = x[2].sin_cos();
    let (lx, ly) = (x[LEVER_X], lever.y);
    let at = Vector2::new(x[0] + c * lx - s * ly, x[1] + s * lx + c * ly);
    let (v, w) = (x[3], x[4]);
    let vel = Vector2::new(v * c - w * (s * lx + c * ly), v * s + w * (c * lx - s * ly));
    at - vel * x[DELTA]
}

/// The RTS gain `Pf Fᵀ Pp⁻¹` on the first `active` states (the rest have no variance and keep
/// their value).
fn rts_gain(pf: &P, f: &P, pp: &P, active: usize) -> Option<P> {
    if active == 8 {
        return Some(pf * f.transpose() * pp.try_inverse()?);
    }
    let inv = pp.fixed_view::<6, 6>(0, 0).into_owned().try_inverse()?;
    let g = (pf * f.transpose()).fixed_view::<6, 6>(0, 0) * inv;
    let mut c = P::zeros();
    c.fixed_view_mut::<6, 6>(0, 0).copy_from(&g);
    Some(c)
}

enum Meas {
    Gnss(GnssObs),
    Motion(f64, f64),
}

/// Why no trajectory can be made.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// Too little data.
    #[error("no trajectory: {0}")]
    Insufficient(String),
}

impl EgoTrajectory {
    /// Smooths GNSS positions and CAN motion (time, speed, yaw rate) into a trajectory.
    pub fn smooth(
        gnss: &[GnssObs],
        motion: &[(UtcNanos, f64, f64)],
        s: &Settings,
    ) -> Result<EgoTrajectory, TrajectoryError> {
        if gnss.len() < 2 {
            return Err(TrajectoryError::Insufficient(format!(
                "{} usable GNSS epochs (at least 2 needed)",
                gnss.len()
            )));
        }
        let mut events: Vec<(UtcNanos, Meas)> =
            gnss.iter().map(|g| (g.t, Meas::Gnss(*g))).collect();
        events.extend(motion.iter().map(|&(t, v, w)| (t, Meas::Motion(v, w))));
        events.sort_by_key(|e| e.0);
        // Initial heading: the course of the first metre the antenna travels.
        let psi0 = gnss
            .iter()
            .find(|g| (g.position - gnss[0].position).norm() > 1.0)
            .map_or(0.0, |g| {
                let d = g.position - gnss[0].position;
                d.y.atan2(d.x)
            });
        let p0 = gnss[0].position;
        let mut x = S::from_column_slice(&[p0.x, p0.y, psi0, 0.0, 0.0, 0.0, 0.0, s.lever.x]);
        let rear = p0 - (antenna(&x, &s.lever) - p0);
        x[0] = rear.x;
        x[1] = rear.y;
        // When estimated, δ and the lever arm start from diffuse priors (σ 0.1 s and 10 m), so
        // that what the drive says decides them and the rig file's value only seeds the
        // linearisation.
        let (var_delta, var_lever) = if s.estimate_offset_and_lever {
            (0.1f64.powi(2), 10f64.powi(2))
        } else {
            (0.0, 0.0)
        };
        let mut p = P::from_diagonal(&S::from_column_slice(&[
            1.0, 1.0, 0.5, 1.0, 0.1, 1.0, var_delta, var_lever,
        ]));
        let n = events.len();
        let (mut xp, mut pp, mut xf, mut pf, mut fs) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        let mut t_prev = events[0].0;
        for (t, m) in &events {
            let dt = ((t.0 - t_prev.0) as f64 * 1e-9).max(0.0);
            t_prev = *t;
            let f = jacobian(|y| ctrv(y, dt), &x);
            x = ctrv(&x, dt);
            let mut q = P::zeros();
            q[(0, 0)] = 1e-6 * dt;
            q[(1, 1)] = 1e-6 * dt;
            q[(2, 2)] = 1e-7 * dt;
            q[(3, 3)] = 1e-4 * dt;
            q[(4, 4)] = s.yaw_accel_noise.powi(2) * dt;
            q[(5, 5)] = s.accel_noise.powi(2) * dt;
            p = f * p * f.transpose() + q;
            xp.push(x);
            pp.push(p);
            fs.push(f);
            match m {
                Meas::Gnss(g) => {
                    let h = jacobian(|y| antenna(y, &s.lever), &x);
                    let r = SMatrix::<f64, 2, 2>::from_diagonal(&g.sigma.component_mul(&g.sigma));
                    let y = g.position - antenna(&x, &s.lever);
                    let sm = h * p * h.transpose() + r;
                    if let Some(si) = sm.try_inverse() {
                        let k = p * h.transpose() * si;
                        x += k * y;
                        p = (P::identity() - k * h) * p;
                    }
                }
                Meas::Motion(v, w) => {
                    let mut h = SMatrix::<f64, 2, 8>::zeros();
                    h[(0, 3)] = 1.0;
                    h[(1, 4)] = 1.0;
                    let r = SMatrix::<f64, 2, 2>::from_diagonal(&Vector2::new(
                        s.speed_sigma.powi(2),
                        s.yaw_rate_sigma.powi(2),
                    ));
                    let y = Vector2::new(v - x[3], w - x[4]);
                    let sm = h * p * h.transpose() + r;
                    if let Some(si) = sm.try_inverse() {
                        let k = p * h.transpose() * si;
                        x += k * y;
                        p = (P::identity() - k * h) * p;
                    }
                }
            }
            p = (p + p.transpose()) * 0.5;
            xf.push(x);
            pf.push(p);
        }
        // Rauch-Tung-Striebel. Constants that are not estimated have no variance at all, so the
        // predicted covariance is singular in their rows and columns: the gain is taken on the
        // states that vary (a failed inverse would silently leave the filter's estimate, which
        // lags at the start of a drive and wherever the vehicle stands still).
        let active = if s.estimate_offset_and_lever { 8 } else { 6 };
        let mut xs = xf.clone();
        let mut ps = pf.clone();
        for k in (0..n.saturating_sub(1)).rev() {
            let Some(c) = rts_gain(&pf[k], &fs[k + 1], &pp[k + 1], active) else {
                continue;
            };
            xs[k] = xf[k] + c * (xs[k + 1] - xp[k + 1]);
            ps[k] = pf[k] + c * (ps[k + 1] - pp[k + 1]) * c.transpose();
        }
        let mut residuals = Vec::new();
        for (k, (_, m)) in events.iter().enumerate() {
            if let Meas::Gnss(g) = m {
                let e = g.position - antenna(&xs[k], &s.lever);
                residuals.push(Residual {
                    t: g.t,
                    error: e,
                    nis: (e.x / g.sigma.x).powi(2) + (e.y / g.sigma.y).powi(2),
                });
            }
        }
        Ok(EgoTrajectory {
            times: events.iter().map(|e| e.0).collect(),
            states: xs,
            covs: ps,
            residuals,
        })
    }

    /// First and last instant.
    pub fn span(&self) -> (UtcNanos, UtcNanos) {
        (self.times[0], self.times[self.times.len() - 1])
    }

    /// The estimated GNSS time offset (s) and antenna forward lever arm (m), with their 1-sigma
    /// uncertainties: (δ, σ_δ, x, σ_x).
    pub fn offset_and_lever(&self) -> (f64, f64, f64, f64) {
        let (x, p) = (&self.states[0], &self.covs[0]);
        (
            x[DELTA],
            p[(DELTA, DELTA)].max(0.0).sqrt(),
            x[LEVER_X],
            p[(LEVER_X, LEVER_X)].max(0.0).sqrt(),
        )
    }

    /// State `[x, y, ψ, v, ω, a, δ, lever x]` and its covariance at `t` (propagated from the
    /// smoothed state before it).
    pub fn state_at(&self, t: UtcNanos) -> Option<(SVector<f64, 8>, SMatrix<f64, 8, 8>)> {
        let (a, b) = self.span();
        if t < a || t > b {
            return None;
        }
        let k = self.times.partition_point(|&x| x <= t).saturating_sub(1);
        let dt = (t.0 - self.times[k].0) as f64 * 1e-9;
        Some((ctrv(&self.states[k], dt), self.covs[k]))
    }

    /// The rear-axle pose at `t`, and its 1-sigma horizontal position error (m).
    pub fn pose_at(&self, t: UtcNanos) -> Option<(PoseSample, f64)> {
        let (x, p) = self.state_at(t)?;
        Some((
            PoseSample {
                t,
                position: Vector3::new(x[0], x[1], 0.0),
                yaw: x[2],
                pitch: 0.0,
                roll: 0.0,
            },
            ((p[(0, 0)] + p[(1, 1)]) / 2.0).max(0.0).sqrt(),
        ))
    }

    /// The trajectory sampled every `step_ns` (for re-simulation, which interpolates it).
    pub fn sampled(&self, step_ns: i64) -> Option<Trajectory> {
        let (a, b) = self.span();
        let mut v = Vec::new();
        let mut t = a;
        while t <= b {
            v.push(self.pose_at(t)?.0);
            t = UtcNanos(t.0 + step_ns);
        }
        Trajectory::new(v).ok()
    }
}

/// How many times more uncertain an estimate from GNSS residuals is than the smoother's white-
/// noise covariance says: the integrated autocorrelation time `1 + 2 Σ ρ_k` of the residuals
/// (normalised by their sigmas, both axes), summed until the autocorrelation first drops to
/// zero. RTK errors wander (multipath, atmosphere) over seconds, so ten epochs a second are far
/// fewer independent measurements; the variance of anything fitted to them grows by this
/// factor (Box, Jenkins and Reinsel, "Time Series Analysis", the variance of a mean of
/// autocorrelated data). `use_epoch` picks the epochs that count (RTK-fixed ones); a run of
/// them is only continued over consecutive epochs. At least 1.
pub fn correlation_factor(
    residuals: &[Residual],
    sigmas: &[Vector2<f64>],
    use_epoch: &[bool],
) -> f64 {
    let z: Vec<Option<Vector2<f64>>> = residuals
        .iter()
        .zip(sigmas)
        .zip(use_epoch)
        .map(|((r, s), &u)| u.then(|| r.error.component_div(s)))
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

    #[test]
    fn recovers_a_turning_drive_from_noisy_gnss_and_can() {
        let (v, w) = (3.0, 0.3);
        let lever = Vector2::new(0.6, 0.0);
        // The truth in closed form, independent of the module's motion and measurement models:
        // a circle of radius v/w driven at constant speed from (5, -2) heading 0.4 rad; the
        // antenna 0.6 m ahead of the rear axle along the heading.
        let (x0, y0, psi0) = (5.0, -2.0, 0.4);
        let truth = |t: f64| -> [f64; 3] {
            let psi = psi0 + w * t;
            let r = v / w;
            [
                x0 + r * (psi.sin() - psi0.sin()),
                y0 - r * (psi.cos() - psi0.cos()),
                psi,
            ]
        };
        let antenna = |x: [f64; 3], l: &Vector2<f64>| -> Vector2<f64> {
            let (s, c) = x[2].sin_cos();
            Vector2::new(x[0] + l.x * c - l.y * s, x[1] + l.x * s + l.y * c)
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let n = Normal::new(0.0, 0.01).unwrap();
        let gnss: Vec<GnssObs> = (0..200)
            .map(|k| {
                let t = k as f64 * 0.1;
                let a = antenna(truth(t), &lever);
                GnssObs {
                    t: UtcNanos((t * 1e9) as i64),
                    position: a + Vector2::new(n.sample(&mut rng), n.sample(&mut rng)),
                    sigma: Vector2::new(0.01, 0.01),
                }
            })
            .collect();
        let motion: Vec<(UtcNanos, f64, f64)> = (0..1000)
            .map(|k| (UtcNanos(k * 20_000_000 + 5_000_000), v, w))
            .collect();
        let tr = EgoTrajectory::smooth(
            &gnss,
            &motion,
            &Settings {
                lever,
                ..Settings::default()
            },
        )
        .unwrap();
        let mut worst = 0.0f64;
        for k in 10..190 {
            let t = k as f64 * 0.1 + 0.05;
            let (pose, sigma) = tr.pose_at(UtcNanos((t * 1e9) as i64)).unwrap();
            let x = truth(t);
            worst = worst.max((pose.position.xy() - Vector2::new(x[0], x[1])).norm());
            assert!(((pose.yaw - x[2] + 1.0).rem_euclid(std::f64::consts::TAU) - 1.0).abs() < 0.01);
            assert!(sigma < 0.02);
        }
        // Smoothing 1 cm GNSS with CAN motion: better than a single epoch.
        assert!(worst < 0.012, "worst {worst}");
        let rms = (tr
            .residuals
            .iter()
            .map(|r| r.error.norm_squared())
            .sum::<f64>()
            / tr.residuals.len() as f64
            / 2.0)
            .sqrt();
        assert!((rms - 0.01).abs() < 0.003, "residual rms {rms}");
    }

    /// White residuals count once each; residuals that follow a first-order Gauss-Markov process
    /// with correlation ρ per epoch count (1 - ρ) / (1 + ρ) times (the closed form of
    /// 1 + 2 Σ ρ^k).
    #[test]
    fn correlation_factor_of_white_and_of_wandering_residuals() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let n = Normal::new(0.0, 1.0).unwrap();
        let res = |e: Vec<Vector2<f64>>| -> Vec<Residual> {
            e.into_iter()
                .enumerate()
                .map(|(k, e)| Residual {
                    t: UtcNanos(k as i64 * 100_000_000),
                    error: e,
                    nis: e.norm_squared(),
                })
                .collect()
        };
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
}

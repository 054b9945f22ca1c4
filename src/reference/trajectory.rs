//! The ego trajectory from RTK GNSS and CAN: an extended Kalman filter with a constant turn rate
//! and velocity (CTRV) motion model, followed by a Rauch-Tung-Striebel pass, so that every
//! instant uses the measurements before and after it.
//!
//! State (rear-axle centre, local ENU frame): `[x, y, ψ, v, ω, a]` and the yaw acceleration α,
//! heading ψ from east counter-clockwise, speed v along the heading (no side slip at parking
//! speeds), yaw rate ω and longitudinal acceleration a; and two constants that `check` wants to
//! know: the GNSS time offset δ (a fix stamped t describes the instant t - δ) and the antenna's forward lever arm,
//! both fixed at their configured values unless [`Settings::estimate_offset_and_lever`] is on;
//! and the slowly wandering part of the GNSS error, east and north (see [`GnssNoise`]).
//! The acceleration matters: with speed held constant between CAN
//! frames, the integrated position lags by half a frame interval (10 ms at 50 Hz) whenever the
//! vehicle accelerates, which would read as a GNSS time offset.
//! Measurements: the antenna's horizontal position (state position plus the rotated lever arm,
//! with the receiver's per-epoch sigmas), CAN speed and CAN yaw rate, and where the rig has a
//! heading source (an INS, a dual-antenna receiver) its heading with its stated sigma, against
//! the state's heading plus a constant offset of the source (the baseline's misalignment,
//! estimated as a twelfth state from a 10° prior). With the time offset and lever arm, the CAN
//! speed's residual scale error is estimated too (a thirteenth state). Jacobians are taken
//! numerically: thirteen states, and the model stays readable.
//!
//! Long file: the filter, the smoother, the choice of the noise models (yaw jerk, GNSS) and the
//! sampling of the result share one private state layout (the index constants, the state and
//! covariance types); split, each part would have to expose it.

use super::noise::standstill;
use crate::scene::pose::{PoseSample, Trajectory};
use hilrig_stamp::UtcNanos;
use nalgebra::{SMatrix, SVector, Vector2, Vector3};

/// Number of states.
const N: usize = 13;
type S = SVector<f64, N>;
type P = SMatrix<f64, N, N>;

/// Index of the GNSS time offset δ (s) in the state: a fix stamped t describes t - δ.
const DELTA: usize = 6;
/// Index of the antenna's forward lever arm (m) in the state.
const LEVER_X: usize = 7;
/// Index of the GNSS error's slowly wandering east part (m); north follows it.
const BIAS_E: usize = 8;
/// Index of the yaw acceleration (rad/s²).
const YAW_ACC: usize = 10;
/// Index of the heading source's constant offset (rad, ENU sense: the source reads ψ + b).
const HEADING_BIAS: usize = 11;
/// Index of the CAN speed's residual scale error ε (CAN reads (1 + ε) v), estimated with the
/// time offset and lever arm: a scale taken as exact, although known only to a few 1e-4, misfits
/// along the track as the distance grows, and the time offset and lever arm, which misfit along
/// the track too, took that up with sigmas too small for it (at 20 Hz fixes, rms(error/sigma)
/// 1.6-1.8 over 30 drives).
const SPEED_SCALE: usize = 12;
/// The prior of ε, when estimated: 1 %, wide against what the regression on straight driving
/// leaves (a few 1e-4), so that the drive decides it.
const SPEED_SCALE_PRIOR: f64 = 0.01;
/// The prior of the heading source's offset, rad (10°: a baseline misaligned by more is a
/// mounting error, and the data decide within that).
pub const HEADING_BIAS_PRIOR: f64 = 0.1745;

/// One heading measurement of the rig's heading source, in the smoother's frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingObs {
    /// Time of the report.
    pub t: UtcNanos,
    /// The vehicle's heading the source reports, rad from east counter-clockwise (the rig's
    /// mounting offset already taken off).
    pub yaw: f64,
    /// Its 1-sigma error, rad.
    pub sigma: f64,
}

/// A heading report against the smoothed trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadingResidual {
    /// Time.
    pub t: UtcNanos,
    /// Reported minus smoothed heading (with the source's estimated offset), rad.
    pub error: f64,
    /// `error²` over the report's variance plus the trajectory's (χ² with 1 degree of freedom).
    pub nis: f64,
}

/// An angle wrapped to (-π, π].
pub(crate) fn wrap(a: f64) -> f64 {
    let t = (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    if t <= -std::f64::consts::PI {
        t + std::f64::consts::TAU
    } else {
        t
    }
}

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
    /// Yaw jerk noise, rad/s³ per √s (see [`fit_yaw_jerk_noise`]).
    pub yaw_jerk_noise: f64,
    /// CAN speed noise, m/s.
    pub speed_sigma: f64,
    /// CAN yaw-rate noise, rad/s.
    pub yaw_rate_sigma: f64,
    /// Estimate the GNSS time offset and the antenna's forward lever arm as constant states
    /// (starting from 0 s and `lever.x`) instead of taking them as given.
    pub estimate_offset_and_lever: bool,
    /// How the GNSS error wanders (white by default).
    pub gnss_noise: GnssNoise,
    /// 1-sigma prior of the heading source's offset, rad: [`HEADING_BIAS_PRIOR`] (10°) when the
    /// drive alone decides it, the calibration's sigma when the rig file states one.
    pub heading_offset_sigma: f64,
}

/// The GNSS error as the smoother models it: a share of each epoch's variance wanders as a
/// first-order Gauss-Markov process with correlation time `correlation_s` (multipath and the
/// atmosphere change over seconds, so consecutive RTK fixes err alike), the rest is white.
/// Modelled as two states, the wandering part is told apart from motion by CAN: over a few
/// seconds the wheels and the yaw rate say how the vehicle moved, so a common drift of the
/// fixes is the receiver's, not the vehicle's. That keeps the heading, which hangs on
/// differences between nearby fixes, from inheriting an error that those differences cancel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssNoise {
    /// Correlation time of the wandering part, s (0: all white).
    pub correlation_s: f64,
    /// Share of each epoch's variance that wanders, 0..1.
    pub correlated_share: f64,
}

impl GnssNoise {
    /// Independent errors from epoch to epoch.
    pub const WHITE: GnssNoise = GnssNoise {
        correlation_s: 0.0,
        correlated_share: 0.0,
    };

    /// Whether any of the error wanders.
    pub fn wanders(&self) -> bool {
        self.correlation_s > 0.0 && self.correlated_share > 0.0
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            lever: Vector2::zeros(),
            accel_noise: 3.0,
            yaw_jerk_noise: 3.0,
            speed_sigma: 0.03,
            yaw_rate_sigma: 0.005,
            estimate_offset_and_lever: false,
            gnss_noise: GnssNoise::WHITE,
            heading_offset_sigma: HEADING_BIAS_PRIOR,
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
    /// Normalised by the receiver's sigmas and the trajectory's own uncertainty at that epoch:
    /// eᵀ (Σ_fix + Σ_trajectory)⁻¹ e (χ² with 2 degrees of freedom).
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
    /// Heading-source residuals against it (empty without a heading source).
    pub heading_residuals: Vec<HeadingResidual>,
}

fn ctrv(x: &S, dt: f64) -> S {
    let (px, py, psi, v, a, alpha) = (x[0], x[1], x[2], x[3], x[5], x[YAW_ACC]);
    // The turn at the interval's mean rate and with its mean speed.
    let w = x[4] + 0.5 * alpha * dt;
    let vm = v + 0.5 * a * dt;
    let (nx, ny) = if w.abs() > 1e-6 {
        (
            px + vm / w * ((psi + w * dt).sin() - psi.sin()),
            py + vm / w * (psi.cos() - (psi + w * dt).cos()),
        )
    } else {
        (px + vm * dt * psi.cos(), py + vm * dt * psi.sin())
    };
    let mut out = *x;
    out[0] = nx;
    out[1] = ny;
    out[2] = psi + w * dt;
    out[3] = v + a * dt;
    out[4] = x[4] + alpha * dt;
    out
}

fn jacobian<const M: usize>(f: impl Fn(&S) -> SVector<f64, M>, x: &S) -> SMatrix<f64, M, N> {
    let mut j = SMatrix::<f64, M, N>::zeros();
    for i in 0..N {
        let h = 1e-6 * (1.0 + x[i].abs());
        let (mut a, mut b) = (*x, *x);
        a[i] += h;
        b[i] -= h;
        let d = (f(&a) - f(&b)) / (2.0 * h);
        j.set_column(i, &d);
    }
    j
}

/// Where the receiver puts the antenna in a fix stamped now: the state's position plus the
/// rotated lever arm (forward part from the state), moved back by δ along the antenna's
/// velocity, plus the wandering part of the GNSS error (zero when it is not modelled).
fn antenna(x: &S, lever: &Vector2<f64>) -> Vector2<f64> {
    let (s, c) = x[2].sin_cos();
    let (lx, ly) = (x[LEVER_X], lever.y);
    let at = Vector2::new(x[0] + c * lx - s * ly, x[1] + s * lx + c * ly);
    let (v, w) = (x[3], x[4]);
    let vel = Vector2::new(v * c - w * (s * lx + c * ly), v * s + w * (c * lx - s * ly));
    at - vel * x[DELTA] + Vector2::new(x[BIAS_E], x[BIAS_E + 1])
}

/// The RTS gain `Pf Fᵀ Pp⁻¹` on the `active` states (the rest have no variance and keep their
/// value).
fn rts_gain(pf: &P, f: &P, pp: &P, active: &[usize]) -> Option<P> {
    let m = active.len();
    let pfft = pf * f.transpose();
    let sub = nalgebra::DMatrix::from_fn(m, m, |i, j| pp[(active[i], active[j])]);
    let inv = sub.try_inverse()?;
    let mut c = P::zeros();
    for &ai in active {
        for (j, _) in active.iter().enumerate() {
            let mut acc = 0.0;
            for (k, &ak) in active.iter().enumerate() {
                acc += pfft[(ai, ak)] * inv[(k, j)];
            }
            c[(ai, active[j])] = acc;
        }
    }
    Some(c)
}

enum Meas {
    Gnss(GnssObs),
    Heading(HeadingObs),
    /// CAN speed and yaw rate, and whether the vehicle stands still then.
    Motion(f64, f64, bool),
}

/// At most this many passes of filter and smoother (see [`EgoTrajectory::smooth_with_heading`]).
const MAX_PASSES: usize = 6;

/// The yaw rate of a car standing still: zero, to within 1e-4 rad/s (0.3° in a minute).
const STILL_YAW_SIGMA: f64 = 1e-4;

/// Why no trajectory can be made.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// Too little data.
    #[error("no trajectory: {0}")]
    Insufficient(String),
}

/// The forward pass: what the smoother runs backwards over.
struct Filtered {
    times: Vec<UtcNanos>,
    /// Predicted and filtered states and covariances, and the transition Jacobians.
    xp: Vec<S>,
    pp: Vec<P>,
    xf: Vec<S>,
    pf: Vec<P>,
    fs: Vec<P>,
    /// Which events are GNSS fixes (with the fix).
    gnss: Vec<Option<GnssObs>>,
    /// Which events are heading reports (with the report).
    heading: Vec<Option<HeadingObs>>,
    /// Log-likelihood of the GNSS innovations (up to a constant).
    log_likelihood: f64,
    /// Log-likelihood of the CAN yaw-rate innovations while moving (up to a constant).
    yaw_log_likelihood: f64,
    /// States that carry variance.
    active: Vec<usize>,
}

/// The filter's first state, its covariance and the states that carry variance. `share` is the
/// wandering part of the GNSS variance (0 when the GNSS error is white).
fn initial_state(
    gnss: &[GnssObs],
    motion: &[(UtcNanos, f64, f64)],
    headings: &[HeadingObs],
    s: &Settings,
    share: f64,
    start: Option<&S>,
) -> (S, P, Vec<usize>) {
    // Initial heading: the course of the first metre the antenna travels.
    let psi0 = gnss
        .iter()
        .find(|g| (g.position - gnss[0].position).norm() > 1.0)
        .map_or(0.0, |g| {
            let d = g.position - gnss[0].position;
            d.y.atan2(d.x)
        });
    // A heading source says it from the first report, standing or not.
    let psi0 = headings.first().map_or(psi0, |h| h.yaw);
    let p0 = gnss[0].position;
    let mut x = S::zeros();
    x[0] = p0.x;
    x[1] = p0.y;
    x[2] = psi0;
    x[LEVER_X] = s.lever.x;
    let rear = p0 - (antenna(&x, &s.lever) - p0);
    x[0] = rear.x;
    x[1] = rear.y;
    // Speed and yaw rate from the first CAN sample (a drive may begin moving, even turning).
    if let Some(&(_, v, w)) = motion.first() {
        x[3] = v;
        x[4] = w;
    }
    // Or the whole first state from a previous pass: the linearisation then starts where the
    // drive's data put it (the course of the first metre is off by half the turn when the
    // recording begins in a curve). The prior stays as wide as before.
    if let Some(x0) = start {
        x.fixed_rows_mut::<6>(0).copy_from(&x0.fixed_rows::<6>(0));
    }
    // When estimated, δ and the lever arm start from diffuse priors (σ 0.1 s and 10 m), so
    // that what the drive says decides them and the rig file's value only seeds the
    // linearisation.
    let (var_delta, var_lever) = if s.estimate_offset_and_lever {
        (0.1f64.powi(2), 10f64.powi(2))
    } else {
        (0.0, 0.0)
    };
    let b0 = share * gnss[0].sigma.component_mul(&gnss[0].sigma);
    let var_heading_bias = if headings.is_empty() {
        0.0
    } else {
        s.heading_offset_sigma * s.heading_offset_sigma
    };
    let p = P::from_diagonal(&S::from_column_slice(&[
        1.0,
        1.0,
        0.5,
        1.0,
        0.1,
        1.0,
        var_delta,
        var_lever,
        b0.x,
        b0.y,
        0.1,
        var_heading_bias,
        if s.estimate_offset_and_lever {
            SPEED_SCALE_PRIOR * SPEED_SCALE_PRIOR
        } else {
            0.0
        },
    ]));
    let mut active: Vec<usize> = (0..6).collect();
    active.push(YAW_ACC);
    if s.estimate_offset_and_lever {
        active.extend([DELTA, LEVER_X, SPEED_SCALE]);
    }
    if share > 0.0 {
        active.extend([BIAS_E, BIAS_E + 1]);
    }
    if !headings.is_empty() {
        active.push(HEADING_BIAS);
    }
    (x, p, active)
}

/// The process noise of a step of `dt` seconds (the GNSS wander's is added by the caller).
/// White noise on the yaw jerk and on the longitudinal jerk, integrated over the step, so that
/// heading, yaw rate and yaw acceleration (speed and acceleration) take up what the jerk may
/// have done within it and no more (the dt⁵/20 … dt terms of an integrated white noise). A
/// vehicle's yaw rate is smooth on the scale of a CAN interval: modelled with white noise on
/// the yaw acceleration instead, the yaw rate would wander between two samples, and the
/// heading with it (at 0.2 rad/s² per √s and 50 Hz, 0.13° in a second), so that the heading
/// followed the GNSS noise rather than the integrated yaw rate. Standing (`still`), the car
/// cannot turn.
fn process_noise(dt: f64, still: bool, s: &Settings) -> P {
    let mut q = P::zeros();
    q[(0, 0)] = 1e-6 * dt;
    q[(1, 1)] = 1e-6 * dt;
    q[(3, 3)] = 1e-4 * dt;
    let (dt2, dt3) = (dt * dt / 2.0, dt * dt * dt / 3.0);
    if still {
        q[(4, 4)] = STILL_YAW_SIGMA.powi(2) * dt;
    } else {
        // [ψ, ω, α] of an integrated white jerk: qj · [[dt⁵/20, dt⁴/8, dt³/6],
        // [dt⁴/8, dt³/3, dt²/2], [dt³/6, dt²/2, dt]].
        let qj = s.yaw_jerk_noise.powi(2);
        let (t5, t4, t3) = (dt.powi(5) / 20.0, dt.powi(4) / 8.0, dt.powi(3) / 6.0);
        let m = [[t5, t4, t3], [t4, dt3, dt2], [t3, dt2, dt]];
        let idx = [2, 4, YAW_ACC];
        for (i, &a) in idx.iter().enumerate() {
            for (j, &b) in idx.iter().enumerate() {
                q[(a, b)] = qj * m[i][j];
            }
        }
    }
    let qa = s.accel_noise.powi(2);
    q[(3, 3)] += qa * dt3;
    q[(3, 5)] = qa * dt2;
    q[(5, 3)] = qa * dt2;
    q[(5, 5)] = qa * dt;
    q
}

/// The measurements in time order, each CAN sample with whether the vehicle stands then: built
/// once per drive, filtered as often as the noise model and the second pass need.
struct Events<'a> {
    gnss: &'a [GnssObs],
    motion: &'a [(UtcNanos, f64, f64)],
    headings: &'a [HeadingObs],
    ordered: Vec<(UtcNanos, Meas)>,
}

impl<'a> Events<'a> {
    fn new(
        gnss: &'a [GnssObs],
        motion: &'a [(UtcNanos, f64, f64)],
        headings: &'a [HeadingObs],
    ) -> Result<Events<'a>, TrajectoryError> {
        if gnss.len() < 2 {
            return Err(TrajectoryError::Insufficient(format!(
                "{} usable GNSS epochs (at least 2 needed)",
                gnss.len()
            )));
        }
        let mut ordered: Vec<(UtcNanos, Meas)> =
            gnss.iter().map(|g| (g.t, Meas::Gnss(*g))).collect();
        ordered.extend(
            motion
                .iter()
                .zip(standstill(motion))
                .map(|(&(t, v, w), still)| (t, Meas::Motion(v, w, still))),
        );
        ordered.extend(headings.iter().map(|h| (h.t, Meas::Heading(*h))));
        ordered.sort_by_key(|e| e.0);
        Ok(Events {
            gnss,
            motion,
            headings,
            ordered,
        })
    }
}

/// The extended Kalman filter over GNSS fixes and CAN motion in time order.
/// `about`: a previous pass's smoothed states, one per event, to linearise the motion and the
/// antenna about (an iterated extended Kalman smoother, Bell 1994): the filter's own estimate
/// is what an extended Kalman filter linearises about, and where that is far off (the start of
/// a recording in a turn) the linearisation error stays in the result. `None`: the filter's own.
fn filter(ev: &Events<'_>, s: &Settings, start: Option<&S>, about: Option<&[S]>) -> Filtered {
    let (gnss, motion, events) = (ev.gnss, ev.motion, &ev.ordered);
    let wander = s.gnss_noise.wanders();
    let share = if wander {
        s.gnss_noise.correlated_share.clamp(0.0, 0.99)
    } else {
        0.0
    };
    let (mut x, mut p, active) = initial_state(gnss, motion, ev.headings, s, share, start);
    let b0 = Vector2::new(p[(BIAS_E, BIAS_E)], p[(BIAS_E + 1, BIAS_E + 1)]);
    let var_bias = |g: &GnssObs| share * g.sigma.component_mul(&g.sigma);
    let n = events.len();
    let mut out = Filtered {
        times: events.iter().map(|e| e.0).collect(),
        xp: Vec::with_capacity(n),
        pp: Vec::with_capacity(n),
        xf: Vec::with_capacity(n),
        pf: Vec::with_capacity(n),
        fs: Vec::with_capacity(n),
        gnss: Vec::with_capacity(n),
        heading: Vec::with_capacity(n),
        log_likelihood: 0.0,
        yaw_log_likelihood: 0.0,
        active,
    };
    let mut t_prev = events[0].0;
    // Whether the vehicle stands still since the last CAN sample. Standing, it cannot turn:
    // the heading and yaw rate get no process noise (the yaw-jerk noise of a moving
    // car, leaking into the heading between CAN samples, would let the heading wander with
    // the GNSS noise seen through the lever arm while the vehicle waits).
    let mut still_now = false;
    // The wandering error's steady variance, from the latest fix's sigmas.
    let mut bias_var = b0;
    for (k, (t, m)) in events.iter().enumerate() {
        let dt = ((t.0 - t_prev.0) as f64 * 1e-9).max(0.0);
        t_prev = *t;
        // The step's linearisation point: the previous event's smoothed state of the last pass
        // (for the first event, the start itself), or the filter's own estimate.
        let prev = match about {
            Some(a) if k > 0 => a[k - 1],
            _ => x,
        };
        let mut f = jacobian(|y| ctrv(y, dt), &prev);
        x = ctrv(&prev, dt) + f * (x - prev);
        let mut q = process_noise(dt, still_now, s);
        if wander {
            let phi = (-dt / s.gnss_noise.correlation_s).exp();
            for (i, var) in [(BIAS_E, bias_var.x), (BIAS_E + 1, bias_var.y)] {
                x[i] *= phi;
                f[(i, i)] = phi;
                q[(i, i)] = var * (1.0 - phi * phi);
            }
        }
        p = f * p * f.transpose() + q;
        out.xp.push(x);
        out.pp.push(p);
        out.fs.push(f);
        match m {
            Meas::Gnss(g) => {
                let at = about.map_or(x, |a| a[k]);
                let h = jacobian(|y| antenna(y, &s.lever), &at);
                let white = (1.0 - share) * g.sigma.component_mul(&g.sigma);
                let r = SMatrix::<f64, 2, 2>::from_diagonal(&white);
                let y = g.position - antenna(&at, &s.lever) - h * (x - at);
                let sm = h * p * h.transpose() + r;
                if let Some(si) = sm.try_inverse() {
                    out.log_likelihood -=
                        0.5 * (sm.determinant().max(1e-300).ln() + (y.transpose() * si * y)[0]);
                    let k = p * h.transpose() * si;
                    x += k * y;
                    p = (P::identity() - k * h) * p;
                }
                bias_var = var_bias(g);
            }
            Meas::Heading(hd) => {
                let mut h = SMatrix::<f64, 1, N>::zeros();
                h[(0, 2)] = 1.0;
                h[(0, HEADING_BIAS)] = 1.0;
                let y = wrap(hd.yaw - x[2] - x[HEADING_BIAS]);
                let sm = (h * p * h.transpose())[(0, 0)] + hd.sigma * hd.sigma;
                if sm > 0.0 {
                    let k = p * h.transpose() / sm;
                    x += k * y;
                    p = (P::identity() - k * h) * p;
                }
            }
            Meas::Motion(v, w, still) => {
                still_now = *still;
                let mut h = SMatrix::<f64, 2, N>::zeros();
                h[(0, 3)] = 1.0 + x[SPEED_SCALE];
                h[(0, SPEED_SCALE)] = x[3];
                h[(1, 4)] = 1.0;
                // Standing still, the car does not turn, whatever the yaw-rate sensor's noise
                // says.
                let (w, sw) = if *still {
                    (0.0, STILL_YAW_SIGMA)
                } else {
                    (*w, s.yaw_rate_sigma)
                };
                let r = SMatrix::<f64, 2, 2>::from_diagonal(&Vector2::new(
                    s.speed_sigma.powi(2),
                    sw.powi(2),
                ));
                let y = Vector2::new(v - x[3] * (1.0 + x[SPEED_SCALE]), w - x[4]);
                let sm = h * p * h.transpose() + r;
                if !*still && sm[(1, 1)] > 0.0 {
                    out.yaw_log_likelihood -= 0.5 * (sm[(1, 1)].ln() + y.y * y.y / sm[(1, 1)]);
                }
                if let Some(si) = sm.try_inverse() {
                    let k = p * h.transpose() * si;
                    x += k * y;
                    p = (P::identity() - k * h) * p;
                }
            }
        }
        p = (p + p.transpose()) * 0.5;
        out.xf.push(x);
        out.pf.push(p);
        out.gnss.push(match m {
            Meas::Gnss(g) => Some(*g),
            _ => None,
        });
        out.heading.push(match m {
            Meas::Heading(h) => Some(*h),
            _ => None,
        });
    }
    out
}

/// The yaw-jerk noises the motion model is chosen from, rad/s³ per √s.
const YAW_JERK_NOISES: [f64; 7] = [0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0];

/// How freely the yaw rate may change, as the drive's own CAN yaw rate shows it: among yaw-jerk
/// noises from 0.1 to 100 rad/s³ per √s, the one under which the filter's yaw-rate innovations
/// while moving are most likely (maximum likelihood, as for the GNSS noise in
/// [`fit_gnss_noise`]). A car that swerves gets a larger noise, one that drives smooth arcs a
/// smaller one; the heading between two CAN samples is then held to the yaw rate as tightly as
/// the drive's yaw rate is smooth.
pub fn fit_yaw_jerk_noise(gnss: &[GnssObs], motion: &[(UtcNanos, f64, f64)], s: &Settings) -> f64 {
    Events::new(gnss, motion, &[])
        .ok()
        .and_then(|events| {
            most_likely(
                &events,
                YAW_JERK_NOISES,
                |q| Settings {
                    yaw_jerk_noise: q,
                    ..*s
                },
                |f| f.yaw_log_likelihood,
            )
        })
        .unwrap_or(s.yaw_jerk_noise)
}

/// The yaw-rate sensors' noises the CAN yaw rate's noise is chosen from, rad/s.
const YAW_RATE_SIGMAS: [f64; 8] = [0.0005, 0.001, 0.002, 0.003, 0.005, 0.01, 0.02, 0.05];

/// The CAN yaw rate's noise as the drive's own yaw rate shows it while moving, for drives that
/// never stand long enough to measure it directly ([`crate::reference::noise::yaw_rate_noise`]):
/// among 0.5 to 50 mrad/s, the one under which the filter's yaw-rate innovations while moving
/// are most likely, with the yaw-jerk noise of `s` (so fitted in turn with
/// [`fit_yaw_jerk_noise`]: the jerk makes the yaw rate vary between samples, the sensor's noise
/// makes it scatter about that, and the innovations tell the two apart by their correlation).
pub fn fit_yaw_rate_noise(gnss: &[GnssObs], motion: &[(UtcNanos, f64, f64)], s: &Settings) -> f64 {
    Events::new(gnss, motion, &[])
        .ok()
        .and_then(|events| {
            most_likely(
                &events,
                YAW_RATE_SIGMAS,
                |sigma| Settings {
                    yaw_rate_sigma: sigma,
                    ..*s
                },
                |f| f.yaw_log_likelihood,
            )
        })
        .unwrap_or(s.yaw_rate_sigma)
}

/// Of the `candidates`, the first one under which the filter over `events` (with the settings
/// `settings(candidate)`) scores highest by `score`, a log-likelihood; `None` when none scores
/// above -∞.
fn most_likely<T: Copy>(
    events: &Events<'_>,
    candidates: impl IntoIterator<Item = T>,
    settings: impl Fn(T) -> Settings,
    score: impl Fn(&Filtered) -> f64,
) -> Option<T> {
    let mut best: (f64, Option<T>) = (f64::NEG_INFINITY, None);
    for c in candidates {
        let l = score(&filter(events, &settings(c), None, None));
        if l > best.0 {
            best = (l, Some(c));
        }
    }
    best.1
}

/// The correlation times the GNSS error model is chosen from, s (0: white).
const CORRELATION_TIMES_S: [f64; 8] = [0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 60.0];
/// The shares of the variance that wander. An RTK fix's white part (the carrier phase's own
/// noise) is millimetric: a receiver whose error all wanders (1.5 cm over 10 s at 20 Hz) was
/// fitted at 95 % with a correlation time of 16-60 s instead, and its heading sigma was too
/// small (rms error/sigma 1.28 over 30 drives; with 99 % among the shares, 1.16). 99 % once
/// let twenty fixes a second pin what the motion model could not follow (a 6 m/s slalom's
/// heading erred by 0.175°, p95); since the smoothing is iterated about its own trajectory,
/// that slalom errs by 0.046-0.054° (`benches/check_other_drives.py`, slalom seed 3).
const CORRELATED_SHARES: [f64; 3] = [0.6, 0.95, 0.99];

/// The GNSS error model the drive itself supports best: among white noise and Gauss-Markov
/// wander with correlation times from 0.5 s to a minute (holding 60 % or 95 % of each epoch's
/// variance), the one under which the filter's GNSS innovations are most likely (maximum
/// likelihood noise identification, Mehra 1970). No correlation time is assumed: a receiver
/// whose errors are white gets the white model.
pub fn fit_gnss_noise(
    gnss: &[GnssObs],
    motion: &[(UtcNanos, f64, f64)],
    s: &Settings,
) -> GnssNoise {
    let models = CORRELATION_TIMES_S.iter().flat_map(|&tau| {
        let shares: &[f64] = if tau == 0.0 {
            &[0.0]
        } else {
            &CORRELATED_SHARES
        };
        shares.iter().map(move |&share| GnssNoise {
            correlation_s: tau,
            correlated_share: share,
        })
    });
    Events::new(gnss, motion, &[])
        .ok()
        .and_then(|events| {
            most_likely(
                &events,
                models,
                |model| Settings {
                    gnss_noise: model,
                    ..*s
                },
                |f| f.log_likelihood,
            )
        })
        .unwrap_or(GnssNoise::WHITE)
}

impl EgoTrajectory {
    /// Smooths GNSS positions and CAN motion (time, speed, yaw rate) into a trajectory.
    pub fn smooth(
        gnss: &[GnssObs],
        motion: &[(UtcNanos, f64, f64)],
        s: &Settings,
    ) -> Result<EgoTrajectory, TrajectoryError> {
        Self::smooth_with_heading(gnss, motion, &[], s)
    }

    /// [`EgoTrajectory::smooth`] with the reports of a heading source fused as well.
    pub fn smooth_with_heading(
        gnss: &[GnssObs],
        motion: &[(UtcNanos, f64, f64)],
        headings: &[HeadingObs],
        s: &Settings,
    ) -> Result<EgoTrajectory, TrajectoryError> {
        let events = Events::new(gnss, motion, headings)?;
        // An extended Kalman filter linearises about its own estimate, and its first state (the
        // course of the first metre, the first CAN sample) is off by much of a turn when the
        // recording begins in one: the linearisation error then stays in the smoothed result
        // (0.9° at the start of a 6.5 m/s slalom from standstill with 5 Hz fixes, with a sigma
        // of 0.03°). So the smoothing is iterated (Gauss-Newton): each pass starts from the
        // last one's smoothed start and linearises about its smoothed trajectory, until no
        // heading moves by more than 0.001° (far below any sigma the smoother gives).
        let mut pass = Self::smooth_from(&events, s, None, None);
        for _ in 1..MAX_PASSES {
            let next = Self::smooth_from(&events, s, Some(&pass.states[0]), Some(&pass.states));
            let moved = next
                .states
                .iter()
                .zip(&pass.states)
                .map(|(a, b)| wrap(a[2] - b[2]).abs())
                .fold(0.0, f64::max);
            pass = next;
            if moved < 1.7e-5 {
                break;
            }
        }
        Ok(pass)
    }

    fn smooth_from(
        events: &Events<'_>,
        s: &Settings,
        start: Option<&S>,
        about: Option<&[S]>,
    ) -> EgoTrajectory {
        let fl = filter(events, s, start, about);
        // Rauch-Tung-Striebel. Constants that are not estimated have no variance at all, so the
        // predicted covariance is singular in their rows and columns: the gain is taken on the
        // states that vary (a failed inverse would silently leave the filter's estimate, which
        // lags at the start of a drive and wherever the vehicle stands still).
        let n = fl.xf.len();
        let mut xs = fl.xf.clone();
        let mut ps = fl.pf.clone();
        for k in (0..n.saturating_sub(1)).rev() {
            let Some(c) = rts_gain(&fl.pf[k], &fl.fs[k + 1], &fl.pp[k + 1], &fl.active) else {
                continue;
            };
            xs[k] = fl.xf[k] + c * (xs[k + 1] - fl.xp[k + 1]);
            ps[k] = fl.pf[k] + c * (ps[k + 1] - fl.pp[k + 1]) * c.transpose();
        }
        let mut residuals = Vec::new();
        for (k, g) in fl.gnss.iter().enumerate() {
            if let Some(g) = g {
                // Measured minus the antenna without the wandering error: the whole GNSS error.
                let mut truth = xs[k];
                truth[BIAS_E] = 0.0;
                truth[BIAS_E + 1] = 0.0;
                let e = g.position - antenna(&truth, &s.lever);
                // Normalised by the fix's own variance plus the trajectory's at that epoch (as
                // a fix left out would be predicted): where the trajectory is itself uncertain,
                // at the start of a drive or after a gap, a fix may lie further off it.
                let mut h = jacobian(|y| antenna(y, &s.lever), &truth);
                h.fixed_view_mut::<2, 2>(0, BIAS_E).fill(0.0);
                let hp = h * ps[k] * h.transpose();
                let cov =
                    SMatrix::<f64, 2, 2>::from_diagonal(&g.sigma.component_mul(&g.sigma)) + hp;
                let nis = cov.try_inverse().map_or(
                    (e.x / g.sigma.x).powi(2) + (e.y / g.sigma.y).powi(2),
                    |ci| (e.transpose() * ci * e)[0],
                );
                residuals.push(Residual {
                    t: g.t,
                    error: e,
                    nis,
                });
            }
        }
        let mut heading_residuals = Vec::new();
        for (k, h) in fl.heading.iter().enumerate() {
            if let Some(h) = h {
                let error = wrap(h.yaw - xs[k][2] - xs[k][HEADING_BIAS]);
                let var = ps[k][(2, 2)]
                    + ps[k][(HEADING_BIAS, HEADING_BIAS)]
                    + 2.0 * ps[k][(2, HEADING_BIAS)];
                heading_residuals.push(HeadingResidual {
                    t: h.t,
                    error,
                    nis: error * error / (h.sigma * h.sigma + var.max(0.0)),
                });
            }
        }
        EgoTrajectory {
            times: fl.times,
            states: xs,
            covs: ps,
            residuals,
            heading_residuals,
        }
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

    /// The heading source's estimated offset and its 1-sigma, rad (ENU sense: the source
    /// reads ψ + b); `None` without a heading source.
    pub fn heading_offset(&self) -> Option<(f64, f64)> {
        let p = &self.covs[0];
        (p[(HEADING_BIAS, HEADING_BIAS)] > 0.0).then(|| {
            (
                self.states[0][HEADING_BIAS],
                p[(HEADING_BIAS, HEADING_BIAS)].sqrt(),
            )
        })
    }

    /// What the heading source should read at `t`: the heading plus the source's offset
    /// (rad, from east counter-clockwise), and the variance of that sum.
    pub fn source_heading_at(&self, t: UtcNanos) -> Option<(f64, f64)> {
        let (x, p) = self.state_at(t)?;
        let var = p[(2, 2)] + p[(HEADING_BIAS, HEADING_BIAS)] + 2.0 * p[(2, HEADING_BIAS)];
        Some((x[2] + x[HEADING_BIAS], var.max(0.0)))
    }

    /// State `[x, y, ψ, v, ω, a, δ, lever x, GNSS wander east, north, α, heading offset]` and its covariance at
    /// `t` (propagated from the smoothed state before it).
    pub fn state_at(&self, t: UtcNanos) -> Option<(S, P)> {
        let k = self.index_at(t)?;
        let dt = (t.0 - self.times[k].0) as f64 * 1e-9;
        Some((ctrv(&self.states[k], dt), self.covs[k]))
    }

    /// The smoothed sample at or before `t` (`None` outside the span).
    fn index_at(&self, t: UtcNanos) -> Option<usize> {
        let (a, b) = self.span();
        if t < a || t > b {
            return None;
        }
        Some(self.times.partition_point(|&x| x <= t).saturating_sub(1))
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

    /// The smoother's 1-sigma heading error at `t`, rad.
    pub fn heading_sigma_at(&self, t: UtcNanos) -> Option<f64> {
        let k = self.index_at(t)?;
        Some(self.covs[k][(2, 2)].max(0.0).sqrt())
    }

    /// The smoothed trajectory as CSV, one row every `step_ns`: time (s, nine decimals), rear-axle
    /// east and north (m), heading (deg, from east counter-clockwise) and the smoother's 1-sigma
    /// position and heading errors. What `check --trajectory` writes, so that an engineer can
    /// hold the reference against their own tools.
    pub fn to_csv(&self, step_ns: i64) -> String {
        let mut out = String::from("t,x,y,yaw_deg,sigma_xy_m,sigma_yaw_deg\n");
        let (a, b) = self.span();
        let mut t = a;
        while t <= b {
            if let (Some((pose, sxy)), Some(spsi)) = (self.pose_at(t), self.heading_sigma_at(t)) {
                let (secs, nanos) = t.secs_nanos();
                out.push_str(&format!(
                    "{secs}.{nanos:09},{:.4},{:.4},{:.4},{:.4},{:.4}\n",
                    pose.position.x,
                    pose.position.y,
                    pose.yaw.to_degrees(),
                    sxy,
                    spsi.to_degrees()
                ));
            }
            t = UtcNanos(t.0 + step_ns);
        }
        out
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

    /// A heading source of 0.05° (1σ) at 20 Hz, misaligned by 1.2°, on a drive that stands
    /// for 3 s, then drives a slalom: the offset is estimated within 2σ of the truth, and the
    /// smoothed heading's error stays within 0.05° at the 95th percentile from the first
    /// second on, standing too (the track alone cannot say the heading there). The truth is
    /// integrated here at 1 ms, apart from the module's motion model.
    #[test]
    fn a_heading_source_is_fused_with_its_offset_estimated() {
        let lever = Vector2::new(1.0, 0.0);
        let dt = 1e-3;
        let (mut x, mut y, mut psi) = (0.0f64, 0.0f64, 0.7f64);
        let mut truth = Vec::new();
        for k in 0..30_000 {
            let t = k as f64 * dt;
            let (v, w) = if t < 3.0 {
                (0.0, 0.0)
            } else {
                (
                    (t - 3.0).min(2.0) * 3.0,
                    0.25 * (std::f64::consts::TAU * (t - 3.0) / 6.0).sin(),
                )
            };
            truth.push((t, x, y, psi, v, w));
            x += v * dt * psi.cos();
            y += v * dt * psi.sin();
            psi += w * dt;
        }
        let at = |t: f64| truth[((t / dt).round() as usize).min(truth.len() - 1)];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(32);
        let gn = Normal::new(0.0, 0.02).unwrap();
        let gnss: Vec<GnssObs> = (0..300)
            .map(|k| {
                let (t, x, y, psi, ..) = at(k as f64 * 0.1);
                let a = Vector2::new(x + lever.x * psi.cos(), y + lever.x * psi.sin());
                GnssObs {
                    t: UtcNanos((t * 1e9).round() as i64),
                    position: a + Vector2::new(gn.sample(&mut rng), gn.sample(&mut rng)),
                    sigma: Vector2::new(0.02, 0.02),
                }
            })
            .collect();
        let cn = Normal::new(0.0, 0.003).unwrap();
        let motion: Vec<(UtcNanos, f64, f64)> = (0..1500)
            .map(|k| {
                let (t, .., v, w) = at(k as f64 * 0.02 + 0.005);
                let w = if v == 0.0 {
                    0.0
                } else {
                    w + cn.sample(&mut rng)
                };
                (UtcNanos((t * 1e9).round() as i64), v, w)
            })
            .collect();
        let (offset, sigma) = (1.2f64.to_radians(), 0.05f64.to_radians());
        let hn = Normal::new(0.0, sigma).unwrap();
        let headings: Vec<HeadingObs> = (0..600)
            .map(|k| {
                let (t, _, _, psi, ..) = at(k as f64 * 0.05 + 0.01);
                HeadingObs {
                    t: UtcNanos((t * 1e9).round() as i64),
                    yaw: psi + offset + hn.sample(&mut rng),
                    sigma,
                }
            })
            .collect();
        let s = Settings {
            lever,
            ..Settings::default()
        };
        let tr = EgoTrajectory::smooth_with_heading(&gnss, &motion, &headings, &s).unwrap();
        let (b, sb) = tr.heading_offset().unwrap();
        assert!(
            (b - offset).abs() <= 2.0 * sb,
            "offset {:.4}° ± {:.4}°, truth 1.2°",
            b.to_degrees(),
            sb.to_degrees()
        );
        let mut errors: Vec<f64> = (20..590)
            .map(|k| {
                let t = k as f64 * 0.05;
                let (pose, _) = tr.pose_at(UtcNanos((t * 1e9).round() as i64)).unwrap();
                wrap(pose.yaw - at(t).3).abs().to_degrees()
            })
            .collect();
        errors.sort_by(f64::total_cmp);
        let p95 = errors[errors.len() * 95 / 100];
        assert!(p95 <= 0.05, "heading error p95 {p95:.4}°");
        // The reports fit their stated accuracy.
        let mean_nis = tr.heading_residuals.iter().map(|r| r.nis).sum::<f64>()
            / tr.heading_residuals.len() as f64;
        assert!((0.5..1.5).contains(&mean_nis), "mean NIS {mean_nis}");
        // Without the source the heading is the track's: worse.
        let plain = EgoTrajectory::smooth(&gnss, &motion, &s).unwrap();
        assert!(plain.heading_offset().is_none());
        let mut plain_errors: Vec<f64> = (20..590)
            .map(|k| {
                let t = k as f64 * 0.05;
                let (pose, _) = plain.pose_at(UtcNanos((t * 1e9).round() as i64)).unwrap();
                wrap(pose.yaw - at(t).3).abs().to_degrees()
            })
            .collect();
        plain_errors.sort_by(f64::total_cmp);
        let plain_p95 = plain_errors[plain_errors.len() * 95 / 100];
        assert!(
            plain_p95 > p95,
            "track alone p95 {plain_p95:.4}° vs fused {p95:.4}°"
        );
        eprintln!("heading error p95: fused {p95:.4}°, track alone {plain_p95:.4}°; offset {:.4}° ± {:.4}°", b.to_degrees(), sb.to_degrees());
    }

    #[test]
    fn angles_wrap_into_one_turn() {
        assert!((wrap(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap(-0.1) + 0.1).abs() < 1e-15);
        assert!((wrap(std::f64::consts::TAU + 0.2) - 0.2).abs() < 1e-12);
    }
}

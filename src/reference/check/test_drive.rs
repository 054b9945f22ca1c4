//! A drive whose truth is known in closed form, for the check's unit tests: the rear axle
//! starts at the origin heading east and follows segments of constant acceleration or constant
//! yaw rate (never both at once, so that each millisecond step is exact: a straight stretch at
//! the step's mean speed, or an arc at constant speed). From it, the GNSS antenna's positions
//! at 10 Hz as a receiver would stamp them (an antenna ahead of the axle, stamps late by a
//! given delay) and CAN ego motion at 50 Hz (with a given speed scale and yaw-rate bias), free
//! of noise, so that what a check measures is what was put in.

use crate::reference::run::{Motion, Run};
use crate::reference::trajectory::{EgoTrajectory, GnssObs, Settings};
use hilrig_stamp::UtcNanos;
use nalgebra::Vector2;

/// The drive's start, ns.
pub(super) const T0: i64 = 1_800_000_000_000_000_000;

/// The integration step, ns.
const STEP_NS: i64 = 1_000_000;

/// One stretch: duration (s), longitudinal acceleration (m/s²), yaw rate (rad/s).
pub(super) type Segment = (f64, f64, f64);

/// The true rear-axle state every millisecond: x, y (m), heading (rad), speed (m/s), yaw rate
/// (rad/s).
pub(super) struct Drive(Vec<[f64; 5]>);

impl Drive {
    /// The drive from speed `v0` through `segments`.
    pub(super) fn new(v0: f64, segments: &[Segment]) -> Drive {
        let dt = STEP_NS as f64 * 1e-9;
        let (mut x, mut y, mut psi, mut v) = (0.0f64, 0.0f64, 0.0f64, v0);
        let mut out = vec![[x, y, psi, v, segments.first().map_or(0.0, |s| s.2)]];
        for &(duration, a, w) in segments {
            assert!(a == 0.0 || w == 0.0, "accelerate or turn, not both");
            for _ in 0..(duration / dt).round() as usize {
                let v_mid = v + 0.5 * a * dt;
                if w == 0.0 {
                    x += v_mid * dt * psi.cos();
                    y += v_mid * dt * psi.sin();
                } else {
                    // An arc of radius v / w.
                    let psi1 = psi + w * dt;
                    x += v / w * (psi1.sin() - psi.sin());
                    y -= v / w * (psi1.cos() - psi.cos());
                    psi = psi1;
                }
                v += a * dt;
                out.push([x, y, psi, v, w]);
            }
        }
        Drive(out)
    }

    /// The drive's end.
    pub(super) fn end(&self) -> UtcNanos {
        UtcNanos(T0 + (self.0.len() as i64 - 1) * STEP_NS)
    }

    /// The state at `t` (on the millisecond; clamped to the drive: standing before and after).
    pub(super) fn at(&self, t: UtcNanos) -> [f64; 5] {
        let k = ((t.0 - T0) / STEP_NS).clamp(0, self.0.len() as i64 - 1);
        self.0[k as usize]
    }

    /// The path length of the rear axle, m.
    pub(super) fn length(&self) -> f64 {
        self.0
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum()
    }

    /// Where an antenna `lever` (forward, left) of the rear axle is at `t`.
    pub(super) fn antenna(&self, t: UtcNanos, lever: Vector2<f64>) -> Vector2<f64> {
        let [x, y, psi, _, _] = self.at(t);
        let (s, c) = psi.sin_cos();
        Vector2::new(x + c * lever.x - s * lever.y, y + s * lever.x + c * lever.y)
    }

    /// GNSS epochs every 100 ms: the antenna `lever` ahead of the axle, each fix stamped
    /// `delay_ms` after the instant it describes (a fix stamped t describes t − delay), with a
    /// 1 cm sigma.
    pub(super) fn gnss(&self, lever: Vector2<f64>, delay_ms: f64) -> Vec<GnssObs> {
        let delay = (delay_ms * 1e6).round() as i64;
        (0..)
            .map(|k| UtcNanos(T0 + k * 100_000_000))
            .take_while(|t| *t <= self.end())
            .map(|t| GnssObs {
                t,
                position: self.antenna(UtcNanos(t.0 - delay), lever),
                sigma: Vector2::new(0.01, 0.01),
            })
            .collect()
    }

    /// CAN ego motion every 20 ms (from 10 ms): speed times `scale`, yaw rate plus `yaw_bias`.
    pub(super) fn motion(&self, scale: f64, yaw_bias: f64) -> Vec<Motion> {
        (0..)
            .map(|k| UtcNanos(T0 + 10_000_000 + k * 20_000_000))
            .take_while(|t| *t <= self.end())
            .map(|t| {
                let [_, _, _, v, w] = self.at(t);
                Motion {
                    t,
                    speed: v * scale,
                    yaw_rate: w + yaw_bias,
                }
            })
            .collect()
    }
}

/// A run holding only `motion`.
pub(super) fn run(motion: Vec<Motion>) -> Run {
    Run {
        motion,
        ..Run::default()
    }
}

/// CAN motion as the smoother takes it: (time, speed, yaw rate).
pub(super) fn tuples(motion: &[Motion]) -> Vec<(UtcNanos, f64, f64)> {
    motion.iter().map(|m| (m.t, m.speed, m.yaw_rate)).collect()
}

/// The trajectory smoothed from `gnss` and `motion` with the antenna at `lever`.
pub(super) fn smooth(gnss: &[GnssObs], motion: &[Motion], lever: Vector2<f64>) -> EgoTrajectory {
    EgoTrajectory::smooth(
        gnss,
        &tuples(motion),
        &Settings {
            lever,
            ..Settings::default()
        },
    )
    .expect("a drive with GNSS and CAN")
}

/// A GNSS epoch at `t` as the receiver reports it: GGA `quality` (4 fixed, 5 float, else no
/// RTK), horizontal sigmas (lat, lon), correction age; a position (unused by what reads it).
pub(super) fn fix(t: UtcNanos, quality: u8, sigma: (f64, f64), age_s: f64) -> hilrig_gnss::Fix {
    use hilrig_gnss::{FixSource, RtkState};
    hilrig_gnss::Fix {
        source: FixSource::Nmea,
        time: Some(t),
        time_of_day: None,
        lat: Some(48.0),
        lon: Some(11.0),
        alt_msl: None,
        alt_ellipsoid: None,
        quality,
        rtk: match quality {
            4 => RtkState::Fixed,
            5 => RtkState::Float,
            _ => RtkState::None,
        },
        sigma_lat_m: Some(sigma.0),
        sigma_lon_m: Some(sigma.1),
        sigma_alt_m: Some(2.0 * sigma.0),
        correction_age_s: Some(age_s),
        station_id: None,
        satellites: None,
        speed_mps: None,
        heading_deg: None,
    }
}

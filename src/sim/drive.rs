//! A planned drive (`drive.toml`) and how a human drives it: the path, the speed profile, a
//! stop for a crossing walker, and the variation between repetitions.
//!
//! ```toml
//! name = "parking, third slot on the left"
//! start_utc = "2026-11-21T10:00:00Z"
//! rig = "../../rigs/demo.toml"        # sensors, mounting, lever arm, DBC (relative to this file)
//!
//! [path]                              # rear-axle centre in the scene's local frame
//! waypoints = [[-16.0, 0.0], [0.0, 0.0], [6.0, 2.5], [7.0, 6.0]]
//! cruise_speed_mps = 2.2
//!
//! [[walker]]                          # an actor of the scene walking a straight line
//! actor = "pedestrian"
//! from = [3.0, -6.0]
//! to = [3.0, 6.0]
//! speed_mps = 1.0
//! start_s = 2.0                       # after the drive's start
//!
//! [yield_to]                          # the ego waits for this walker
//! walker = "pedestrian"
//! stop_at_m = 8.0                     # arc length of the stop line
//! ```
//!
//! The sensor, GNSS, CAN and survey error sections are documented on their structs.
//!
//! Long file: the drive file format (every table documented, as users read it) and the
//! driver that turns it into a trajectory share their types; split, the format would be documented
//! in one file and interpreted in another.

use crate::scene::pose::{PoseSample, Trajectory};
use hilrig_stamp::UtcNanos;
use nalgebra::{Vector2, Vector3};
use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::Deserialize;

/// The path to follow.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {
    /// Points the rear-axle centre passes, local frame, metres (smoothed by a Catmull-Rom spline).
    pub waypoints: Vec<[f64; 2]>,
    /// Speed between stops, m/s.
    pub cruise_speed_mps: f64,
    /// Acceleration, m/s².
    #[serde(default = "d_acc")]
    pub acceleration_mps2: f64,
    /// Deceleration, m/s².
    #[serde(default = "d_dec")]
    pub deceleration_mps2: f64,
    /// Standing before moving off, s (ignored when the drive starts moving).
    #[serde(default = "one")]
    pub lead_in_s: f64,
    /// Speed at the first waypoint, m/s: 0 starts from standstill; above 0 the recording
    /// begins with the vehicle already moving (and, where the path starts in a curve, already
    /// turning).
    #[serde(default)]
    pub start_speed_mps: f64,
    /// Standing after arriving, s.
    #[serde(default = "one")]
    pub lead_out_s: f64,
}

/// A walker crossing on a straight line.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WalkerSpec {
    /// The scene actor that walks (its shape comes from the scene).
    pub actor: String,
    /// Start point, metres.
    pub from: [f64; 2],
    /// End point, metres.
    pub to: [f64; 2],
    /// Walking speed, m/s.
    pub speed_mps: f64,
    /// When it starts walking, seconds after the drive's start.
    pub start_s: f64,
}

/// Which walker the ego yields to, and where it stops.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct YieldSpec {
    /// Walker's actor name.
    pub walker: String,
    /// Arc length of the stop line along the path, metres.
    pub stop_at_m: f64,
    /// The path is blocked while the walker is nearer than this to it, metres.
    #[serde(default = "d_clearance")]
    pub clearance_m: f64,
}

/// Human variation between repetitions (1 sigma).
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variation {
    /// Lateral deviation from the planned path, metres.
    #[serde(default = "d_lateral")]
    pub lateral_m: f64,
    /// Relative cruise speed variation.
    #[serde(default = "d_speed")]
    pub speed_factor: f64,
    /// Walker start time variation, s.
    #[serde(default = "d_walker_start")]
    pub walker_start_s: f64,
    /// Relative walking speed variation.
    #[serde(default = "d_speed")]
    pub walker_speed_factor: f64,
}

impl Default for Variation {
    fn default() -> Self {
        Variation {
            lateral_m: d_lateral(),
            speed_factor: d_speed(),
            walker_start_s: d_walker_start(),
            walker_speed_factor: d_speed(),
        }
    }
}

/// Lidar stream errors and settings.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarStream {
    /// Rotation rate.
    #[serde(default = "d_rpm")]
    pub rpm: f64,
    /// "strongest", "last" or "dual".
    #[serde(default = "d_mode")]
    pub return_mode: String,
    /// Delay from a packet's last firing to its host stamp, µs.
    #[serde(default = "d_lidar_latency")]
    pub latency_us: f64,
    /// Standard deviation of that delay (half-normal, added), µs.
    #[serde(default = "d_lidar_jitter")]
    pub jitter_us: f64,
    /// Share of data packets lost on the network.
    #[serde(default = "d_loss")]
    pub packet_loss: f64,
    /// One position packet per this many data packets.
    #[serde(default = "d_position_every")]
    pub position_every: u32,
}

/// GNSS stream errors and settings.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssStream {
    /// Epochs per second.
    #[serde(default = "d_gnss_rate")]
    pub rate_hz: f64,
    /// RTK fixed horizontal noise, 1 sigma per axis, metres (first-order Gauss-Markov).
    #[serde(default = "d_sigma_h")]
    pub sigma_horizontal_m: f64,
    /// Vertical noise, metres.
    #[serde(default = "d_sigma_v")]
    pub sigma_vertical_m: f64,
    /// Correlation time of the noise, s.
    #[serde(default = "d_tau")]
    pub correlation_s: f64,
    /// Serial delay from epoch to host stamp, ms.
    #[serde(default = "d_gnss_latency")]
    pub latency_ms: f64,
    /// Standard deviation of that delay (half-normal, added), ms.
    #[serde(default = "d_gnss_jitter")]
    pub jitter_ms: f64,
    /// Geoid separation written in GGA, metres.
    #[serde(default = "d_geoid")]
    pub geoid_separation_m: f64,
}

/// CAN stream errors and settings.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanStream {
    /// Ego motion frames per second.
    #[serde(default = "d_can_rate")]
    pub rate_hz: f64,
    /// Speed noise, m/s.
    #[serde(default = "d_speed_noise")]
    pub speed_sigma_mps: f64,
    /// Yaw rate noise, rad/s.
    #[serde(default = "d_yaw_noise")]
    pub yaw_rate_sigma_rps: f64,
    /// Delay to the host stamp, ms.
    #[serde(default = "one")]
    pub latency_ms: f64,
}

/// How well the static objects were surveyed.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Survey {
    /// Position error per axis, 1 sigma, metres ("about 10 cm").
    #[serde(default = "d_survey")]
    pub sigma_m: f64,
}

macro_rules! defaults {
    ($($name:ident: $t:ty = $v:expr;)*) => { $(fn $name() -> $t { $v })* };
}
defaults! {
    one: f64 = 1.0;
    d_acc: f64 = 0.8;
    d_dec: f64 = 1.0;
    d_clearance: f64 = 2.0;
    d_lateral: f64 = 0.10;
    d_speed: f64 = 0.08;
    d_walker_start: f64 = 0.5;
    d_rpm: f64 = 600.0;
    d_mode: String = "strongest".into();
    d_lidar_latency: f64 = 300.0;
    d_lidar_jitter: f64 = 60.0;
    d_loss: f64 = 0.0005;
    d_position_every: u32 = 10;
    d_gnss_rate: f64 = 10.0;
    d_sigma_h: f64 = 0.010;
    d_sigma_v: f64 = 0.020;
    d_tau: f64 = 2.0;
    d_gnss_latency: f64 = 35.0;
    d_gnss_jitter: f64 = 2.0;
    d_geoid: f64 = 47.0;
    d_can_rate: f64 = 50.0;
    d_speed_noise: f64 = 0.01;
    d_yaw_noise: f64 = 0.002;
    d_survey: f64 = 0.10;
}

impl Default for LidarStream {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}
impl Default for GnssStream {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}
impl Default for CanStream {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}
impl Default for Survey {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}

/// A time window of a drive, seconds after its start.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Window {
    /// Start, s.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
}

impl Window {
    /// Whether `t_s` (seconds after the start) lies inside.
    pub fn contains(&self, t_s: f64) -> bool {
        t_s >= self.from_s && t_s < self.to_s
    }
}

/// A degraded RTK solution in a window.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RtkFault {
    /// Start, s after the drive's start.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
    /// GGA quality written: 5 float, 2 DGNSS, 1 autonomous.
    pub quality: u8,
}

/// A sigma spike: the receiver reports (and has) a larger error in a window.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SigmaFault {
    /// Start, s after the drive's start.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
    /// 1-sigma horizontal error, m.
    pub sigma_m: f64,
}

/// The lidar's clock runs free instead of being PPS-locked.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FreeClock {
    /// Offset against UTC at the start, ms.
    pub offset_ms: f64,
    /// Drift, ppm.
    pub drift_ppm: f64,
}

/// One GNSS epoch off by a displacement the receiver does not report (a multipath or
/// wrong-ambiguity jump: still "fixed", with the usual sigmas).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct JumpFault {
    /// The epoch nearest this time, s after the drive's start.
    pub at_s: f64,
    /// Displacement east and north, m.
    pub offset_m: [f64; 2],
}

/// Corrections reaching the receiver late in a window (GGA field 13).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AgeFault {
    /// Start, s after the drive's start.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
    /// Age of the corrections, s.
    pub age_s: f64,
}

/// Faults injected into the reference data (for testing `hilrig check`); none by default.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Faults {
    /// RTK float or non-RTK segments.
    #[serde(default)]
    pub rtk: Vec<RtkFault>,
    /// Sigma spikes.
    #[serde(default)]
    pub sigma_spike: Vec<SigmaFault>,
    /// GNSS fixes labelled this much later than the instant they describe, ms.
    #[serde(default)]
    pub gnss_time_offset_ms: f64,
    /// A free-running lidar clock.
    #[serde(default)]
    pub lidar_free_running: Option<FreeClock>,
    /// A PPS-locked lidar whose stamps are late by this much, ms (a firing at t is stamped
    /// t + offset: a misconfigured time source).
    #[serde(default)]
    pub lidar_time_offset_ms: f64,
    /// Windows without lidar data packets.
    #[serde(default)]
    pub lidar_gap: Vec<Window>,
    /// CAN speed reads this factor times the truth.
    #[serde(default = "one")]
    pub can_speed_scale: f64,
    /// The true antenna sits this far from where the rig file says, metres (x, y, z).
    #[serde(default)]
    pub antenna_error_m: [f64; 3],
    /// Windows without GNSS output (the receiver or its serial line is silent).
    #[serde(default)]
    pub gnss_gap: Vec<Window>,
    /// Windows without CAN frames (the bus or the logger's interface is silent).
    #[serde(default)]
    pub can_gap: Vec<Window>,
    /// Single GNSS epochs displaced without the receiver knowing.
    #[serde(default)]
    pub position_jump: Vec<JumpFault>,
    /// Windows with old corrections.
    #[serde(default)]
    pub correction_age: Vec<AgeFault>,
}

impl Default for Faults {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}

/// The drive file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveFile {
    /// Name.
    pub name: String,
    /// Start, ISO 8601 UTC (`2026-11-21T10:00:00Z`).
    pub start_utc: String,
    /// Rig file (sensors, mounting, lever arm, DBC), relative to the drive file.
    pub rig: std::path::PathBuf,
    /// The path.
    pub path: PathSpec,
    /// Walkers.
    #[serde(default, rename = "walker")]
    pub walkers: Vec<WalkerSpec>,
    /// Yielding.
    #[serde(default)]
    pub yield_to: Option<YieldSpec>,
    /// Variation between repetitions.
    #[serde(default)]
    pub variation: Variation,
    /// Lidar stream.
    #[serde(default)]
    pub lidar: LidarStream,
    /// GNSS stream.
    #[serde(default)]
    pub gnss: GnssStream,
    /// CAN stream.
    #[serde(default)]
    pub can: CanStream,
    /// Survey of static objects.
    #[serde(default)]
    pub survey: Survey,
    /// Injected faults (none by default).
    #[serde(default)]
    pub faults: Option<Faults>,
}

/// Parses `YYYY-MM-DDTHH:MM:SS[.fff]Z`.
pub fn parse_utc(s: &str) -> Option<UtcNanos> {
    let s = s.strip_suffix('Z')?;
    let (date, time) = s.split_once('T')?;
    let mut d = date.split('-');
    let y: i64 = d.next()?.parse().ok()?;
    let m: u32 = d.next()?.parse().ok()?;
    let day: u32 = d.next()?.parse().ok()?;
    let mut t = time.split(':');
    let h: i64 = t.next()?.parse().ok()?;
    let mi: i64 = t.next()?.parse().ok()?;
    let sec: f64 = t.next()?.parse().ok()?;
    if !(1..=12).contains(&m) || !(1..=31).contains(&day) || h > 23 || mi > 59 || sec >= 61.0 {
        return None;
    }
    let nanos = (h * 3600 + mi * 60) * 1_000_000_000 + (sec * 1e9).round() as i64;
    hilrig_stamp::civil::utc_from_civil(y, m, day, nanos)
}

/// One repetition as driven.
#[derive(Clone, Debug)]
pub struct Driven {
    /// Rear-axle pose in the local frame.
    pub ego: Trajectory,
    /// Speed (m/s) and yaw rate (rad/s) per ego sample.
    pub motion: Vec<(f64, f64)>,
    /// Walkers' trajectories by actor name.
    pub walkers: Vec<(String, Trajectory)>,
    /// When the ego was stopped for the walker (start, end), if it was.
    pub yield_stop: Option<(UtcNanos, UtcNanos)>,
    /// Drive start and end.
    pub span: (UtcNanos, UtcNanos),
}

/// Why a drive cannot be driven.
#[derive(Debug, thiserror::Error)]
pub enum DriveError {
    /// A bad value.
    #[error("drive '{name}': {what}")]
    Invalid {
        /// Drive name.
        name: String,
        /// What.
        what: String,
    },
}

fn catmull_rom(points: &[Vector2<f64>], per_segment: usize) -> Vec<Vector2<f64>> {
    let n = points.len();
    let p = |i: isize| points[i.clamp(0, n as isize - 1) as usize];
    let mut out = Vec::new();
    for i in 0..n - 1 {
        let (p0, p1, p2, p3) = (
            p(i as isize - 1),
            p(i as isize),
            p(i as isize + 1),
            p(i as isize + 2),
        );
        for k in 0..per_segment {
            let t = k as f64 / per_segment as f64;
            let (t2, t3) = (t * t, t * t * t);
            out.push(
                (p1 * 2.0
                    + (p2 - p0) * t
                    + (p0 * 2.0 - p1 * 5.0 + p2 * 4.0 - p3) * t2
                    + (p1 * 3.0 - p0 - p2 * 3.0 + p3) * t3)
                    * 0.5,
            );
        }
    }
    out.push(points[n - 1]);
    out
}

/// Arc length over which a driver turns the steering wheel from one curvature to the next, m.
/// A car's curvature follows its steering wheel, which takes time to turn: about a second at
/// parking speed, a metre or so of path. A spline through waypoints is only smooth in its
/// direction, and its curvature jumps at every waypoint (the yaw rate would step from 10 to
/// 50 °/s in 20 ms, which no car does and which no 50 Hz yaw-rate sensor could follow).
const STEER_TRANSITION_M: f64 = 1.0;

/// The path a car can drive along `pts` (evenly spaced): its heading, as a function of arc
/// length, averaged twice over `transition` (so the curvature ramps instead of stepping), and
/// the points integrated again from the first one along that heading.
fn steered(pts: &[Vector2<f64>], transition: f64) -> Vec<Vector2<f64>> {
    if pts.len() < 3 {
        return pts.to_vec();
    }
    let steps: Vec<f64> = pts.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
    let mut heading: Vec<f64> = Vec::with_capacity(steps.len());
    for w in pts.windows(2) {
        let d = w[1] - w[0];
        let mut h = d.y.atan2(d.x);
        if let Some(&prev) = heading.last() {
            h = prev + (h - prev + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
        }
        heading.push(h);
    }
    let mean_step = steps.iter().sum::<f64>() / steps.len() as f64;
    let half = ((transition / mean_step / 2.0).round() as usize).max(1);
    for _ in 0..2 {
        let n = heading.len();
        let mut sum = vec![0.0; n + 1];
        for (k, h) in heading.iter().enumerate() {
            sum[k + 1] = sum[k] + h;
        }
        heading = (0..n)
            .map(|k| {
                let (a, b) = (k.saturating_sub(half), (k + half + 1).min(n));
                (sum[b] - sum[a]) / (b - a) as f64
            })
            .collect();
    }
    let mut out = Vec::with_capacity(pts.len());
    out.push(pts[0]);
    for (h, ds) in heading.iter().zip(&steps) {
        let last = out[out.len() - 1];
        out.push(last + Vector2::new(h.cos(), h.sin()) * *ds);
    }
    out
}

/// A polyline with its cumulative arc length.
struct Polyline {
    pts: Vec<Vector2<f64>>,
    s: Vec<f64>,
}

impl Polyline {
    fn new(pts: Vec<Vector2<f64>>) -> Polyline {
        let mut s = vec![0.0];
        for w in pts.windows(2) {
            s.push(s[s.len() - 1] + (w[1] - w[0]).norm());
        }
        Polyline { pts, s }
    }
    fn length(&self) -> f64 {
        self.s[self.s.len() - 1]
    }
    /// Position and unit tangent at arc length `s`. The tangent turns continuously: at each
    /// vertex it is the direction of the chord between its neighbours, and along a segment it
    /// is blended between the two vertices' tangents. A real vehicle's heading has no steps;
    /// the segments' own directions would make one step per vertex (0.4° per 2 cm in a 3 m
    /// turn), a staircase that no heading estimate should be asked to follow.
    fn at(&self, s: f64) -> (Vector2<f64>, Vector2<f64>) {
        let s = s.clamp(0.0, self.length());
        let i = self
            .s
            .partition_point(|&x| x <= s)
            .saturating_sub(1)
            .min(self.pts.len() - 2);
        let seg = self.pts[i + 1] - self.pts[i];
        let len = seg.norm().max(1e-12);
        let f = ((s - self.s[i]) / len).clamp(0.0, 1.0);
        let tangent = |k: usize| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(self.pts.len() - 1));
            let d = self.pts[b] - self.pts[a];
            if d.norm() > 1e-12 {
                d.normalize()
            } else {
                seg / len
            }
        };
        let blended = tangent(i) * (1.0 - f) + tangent(i + 1) * f;
        let tan = if blended.norm() > 1e-9 {
            blended.normalize()
        } else {
            seg / len
        };
        (self.pts[i] + seg * f, tan)
    }
}

impl DriveFile {
    /// Reads a drive file.
    pub fn load(path: &std::path::Path) -> Result<DriveFile, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let d: DriveFile = toml::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        if parse_utc(&d.start_utc).is_none() {
            return Err(format!(
                "{}: start_utc '{}' is not YYYY-MM-DDTHH:MM:SSZ",
                path.display(),
                d.start_utc
            ));
        }
        Ok(d)
    }

    /// Drives the path once, with human variation drawn from `rng` (none when `vary` is false).
    #[allow(
        clippy::too_many_lines,
        reason = "one time-stepping loop whose state (speed, position, yield phase, variation) every step shares"
    )]
    pub fn drive(&self, rng: &mut impl Rng, vary: bool) -> Result<Driven, DriveError> {
        let bad = |what: String| DriveError::Invalid {
            name: self.name.clone(),
            what,
        };
        let p = &self.path;
        if p.waypoints.len() < 2 {
            return Err(bad("the path needs at least two waypoints".into()));
        }
        if !(p.cruise_speed_mps > 0.0 && p.acceleration_mps2 > 0.0 && p.deceleration_mps2 > 0.0) {
            return Err(bad("speeds and accelerations must be positive".into()));
        }
        if !(p.start_speed_mps >= 0.0 && p.start_speed_mps.is_finite()) {
            return Err(bad(format!(
                "start_speed_mps = {} (must be 0 or more)",
                p.start_speed_mps
            )));
        }
        let start = parse_utc(&self.start_utc).ok_or_else(|| {
            bad(format!(
                "start_utc '{}' is not ISO 8601 UTC",
                self.start_utc
            ))
        })?;
        let mut gauss = |sigma: f64| -> f64 {
            if vary && sigma > 0.0 {
                Normal::new(0.0, sigma).map_or(0.0, |n| n.sample(rng))
            } else {
                0.0
            }
        };
        let v = &self.variation;
        let wps: Vec<Vector2<f64>> = p
            .waypoints
            .iter()
            .map(|w| Vector2::new(w[0], w[1]))
            .collect();
        let planned = Polyline::new(catmull_rom(&wps, 200));
        let length = planned.length();
        // The driver's deviation: two smooth half-waves along the path, zero at both ends, plus
        // a final offset that grows in smoothly (nobody parks on the same centimetre twice).
        let (a1, a2, a_end) = (
            gauss(v.lateral_m),
            gauss(v.lateral_m * 0.5),
            gauss(v.lateral_m * 0.5),
        );
        let driven_pts: Vec<Vector2<f64>> = (0..=(length / 0.02).ceil() as usize)
            .map(|k| {
                let s = (k as f64 * 0.02).min(length);
                let (pos, tan) = planned.at(s);
                let normal = Vector2::new(-tan.y, tan.x);
                let x = s / length;
                let off = a1 * (std::f64::consts::PI * x).sin()
                    + a2 * (2.0 * std::f64::consts::PI * x).sin()
                    + a_end * x * x * (3.0 - 2.0 * x);
                pos + normal * off
            })
            .collect();
        let path = Polyline::new(steered(&driven_pts, STEER_TRANSITION_M));
        let length = path.length();
        let cruise = p.cruise_speed_mps * (1.0 + gauss(v.speed_factor)).max(0.5);

        // Walkers.
        let mut walkers = Vec::new();
        let mut block: Option<(f64, f64)> = None;
        let end_guess = 3600.0;
        for w in &self.walkers {
            let t_start = w.start_s + gauss(v.walker_start_s);
            let speed = w.speed_mps * (1.0 + gauss(v.walker_speed_factor)).max(0.3);
            let (a, b) = (
                Vector2::new(w.from[0], w.from[1]),
                Vector2::new(w.to[0], w.to[1]),
            );
            let dist = (b - a).norm();
            if dist <= 0.0 || speed <= 0.0 {
                return Err(bad(format!("walker '{}' has no walk", w.actor)));
            }
            let dir = (b - a) / dist;
            let yaw = dir.y.atan2(dir.x);
            let at = |t: f64| a + dir * ((t - t_start) * speed).clamp(0.0, dist);
            let mut samples = Vec::new();
            let mut t = -1.0;
            while t <= end_guess {
                let q = at(t);
                samples.push(PoseSample {
                    t: UtcNanos(start.0 + (t * 1e9).round() as i64),
                    position: Vector3::new(q.x, q.y, 0.0),
                    yaw,
                    pitch: 0.0,
                    roll: 0.0,
                });
                t += 0.1;
            }
            if let Some(y) = &self.yield_to {
                if y.walker == w.actor {
                    // When the walker is within the clearance of the path.
                    let (mut first, mut last) = (f64::INFINITY, f64::NEG_INFINITY);
                    let mut t = t_start;
                    while t <= t_start + dist / speed + 0.01 {
                        let q = at(t);
                        let near = path
                            .pts
                            .iter()
                            .step_by(5)
                            .any(|pp| (pp - q).norm() < y.clearance_m);
                        if near {
                            first = first.min(t);
                            last = last.max(t);
                        }
                        t += 0.05;
                    }
                    if first.is_finite() {
                        block = Some((first, last));
                    }
                }
            }
            walkers.push((
                w.actor.clone(),
                Trajectory::new(samples).map_err(|e| bad(e.to_string()))?,
            ));
        }
        if let Some(y) = &self.yield_to {
            if !self.walkers.iter().any(|w| w.actor == y.walker) {
                return Err(bad(format!("yield_to names no walker '{}'", y.walker)));
            }
        }

        // Speed profile by time stepping (1 ms), sampled every 10 ms.
        let dt = 1e-3;
        let (mut s, mut vel, mut t) = (0.0f64, 0.0f64, 0.0f64);
        let mut samples: Vec<(f64, f64, f64)> = Vec::new(); // t, s, v
        let mut stop: Option<(f64, f64)> = None;
        let mut step = 0u64;
        if p.start_speed_mps > 0.0 {
            vel = p.start_speed_mps;
            samples.push((0.0, 0.0, vel));
        }
        while p.start_speed_mps <= 0.0 && t < p.lead_in_s {
            if step.is_multiple_of(10) {
                samples.push((t, 0.0, 0.0));
            }
            t += dt;
            step += 1;
        }
        loop {
            let mut limit = cruise;
            // Arrive at the end at rest.
            limit = limit.min((2.0 * p.deceleration_mps2 * (length - s).max(0.0)).sqrt());
            if let (Some(y), Some((_, clear))) = (&self.yield_to, block) {
                if t < clear && s < y.stop_at_m + 0.01 {
                    limit =
                        limit.min((2.0 * p.deceleration_mps2 * (y.stop_at_m - s).max(0.0)).sqrt());
                }
            }
            if vel < limit {
                vel = (vel + p.acceleration_mps2 * dt).min(limit);
            } else {
                vel = limit;
            }
            if vel < 1e-3 && s > 0.1 && s < length - 0.05 {
                let e = stop.get_or_insert((t, t));
                e.1 = t;
            }
            s += vel * dt;
            t += dt;
            step += 1;
            if step.is_multiple_of(10) {
                samples.push((t, s.min(length), vel));
            }
            if s >= length - 0.01 && vel < 0.05 {
                break;
            }
            if t > end_guess - 60.0 {
                return Err(bad("the drive does not finish within 59 minutes".into()));
            }
        }
        let t_arrive = t;
        while t < t_arrive + p.lead_out_s {
            t += 0.01;
            samples.push((t, length, 0.0));
        }
        let mut poses = Vec::with_capacity(samples.len());
        let mut motion = Vec::with_capacity(samples.len());
        let mut last_yaw: Option<f64> = None;
        for &(ts, sk, vk) in &samples {
            let (pos, tan) = path.at(sk);
            let mut yaw = tan.y.atan2(tan.x);
            if let Some(prev) = last_yaw {
                // Unwrap so that the yaw rate is continuous.
                yaw = prev + (yaw - prev + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
            }
            last_yaw = Some(yaw);
            poses.push(PoseSample {
                t: UtcNanos(start.0 + (ts * 1e9).round() as i64),
                position: Vector3::new(pos.x, pos.y, 0.0),
                yaw,
                pitch: 0.0,
                roll: 0.0,
            });
            motion.push((vk, 0.0));
        }
        for (k, m) in motion.iter_mut().enumerate() {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(poses.len() - 1));
            if b > a {
                let dt = (poses[b].t.0 - poses[a].t.0) as f64 * 1e-9;
                m.1 = (poses[b].yaw - poses[a].yaw) / dt;
            }
        }
        let ego = Trajectory::new(poses).map_err(|e| bad(e.to_string()))?;
        let span = ego.span();
        // Walkers are only needed while the ego drives (and a second either side).
        for (_, w) in &mut walkers {
            let keep: Vec<PoseSample> = w
                .samples()
                .iter()
                .filter(|p| {
                    p.t.0 >= span.0 .0 - 1_000_000_000 && p.t.0 <= span.1 .0 + 1_000_000_000
                })
                .copied()
                .collect();
            *w = Trajectory::new(keep).map_err(|e| bad(e.to_string()))?;
        }
        let ns = |x: f64| UtcNanos(start.0 + (x * 1e9).round() as i64);
        Ok(Driven {
            ego,
            motion,
            walkers,
            yield_stop: stop.map(|(a, b)| (ns(a), ns(b))),
            span,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    const DRIVE: &str = r#"
name = "t"
start_utc = "2026-11-21T10:00:00Z"
rig = "rig.toml"
[path]
waypoints = [[-10.0, 0.0], [0.0, 0.0], [5.0, 3.0], [6.0, 8.0]]
cruise_speed_mps = 2.0
[[walker]]
actor = "ped"
from = [-2.0, -6.0]
to = [-2.0, 6.0]
speed_mps = 1.0
start_s = 3.0
[yield_to]
walker = "ped"
stop_at_m = 4.0
"#;

    /// A drive that starts moving in a curve: the first sample already has the start speed and
    /// a yaw rate, and the curvature ramps (no yaw-rate step anywhere larger than a steering
    /// wheel allows).
    #[test]
    fn starts_moving_in_a_curve_with_a_steered_yaw_rate() {
        let text = DRIVE
            .replace(
                "waypoints = [[-10.0, 0.0], [0.0, 0.0], [5.0, 3.0], [6.0, 8.0]]",
                "waypoints = [[-14.0, -6.0], [-10.0, 0.0], [0.0, 0.0], [5.0, 3.0], [6.0, 8.0]]\nstart_speed_mps = 2.0",
            );
        let f: DriveFile = toml::from_str(&text).unwrap();
        let d = f
            .drive(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1), false)
            .unwrap();
        assert!((d.motion[0].0 - 2.0).abs() < 1e-9, "{:?}", d.motion[0]);
        assert!(d.motion[1].1.abs() > 0.05, "not turning: {:?}", d.motion[1]);
        // Yaw acceleration between 10 ms samples: a steering wheel turned over a second gives
        // a few rad/s², a curvature step would give tens.
        let worst = d
            .motion
            .windows(2)
            .map(|w| (w[1].1 - w[0].1).abs() / 0.01)
            .fold(0.0, f64::max);
        assert!(worst < 5.0, "yaw acceleration {worst} rad/s²");
    }

    #[test]
    fn stops_for_the_walker_and_arrives_at_rest() {
        let d: DriveFile = toml::from_str(DRIVE).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for vary in [false, true] {
            let run = d.drive(&mut rng, vary).unwrap();
            let (a, b) = run.yield_stop.expect("the ego must stop for the walker");
            assert!(b.0 - a.0 > 500_000_000, "stopped {} ns", b.0 - a.0);
            let last = run.ego.samples().last().unwrap();
            assert!((last.position.x - 6.0).abs() < 0.3 && (last.position.y - 8.0).abs() < 0.3);
            assert!(run.motion.iter().all(|m| m.0 <= 2.0 * 1.3));
            // Stopped before the stop line, where the walker crosses later.
            let mut h = 0;
            let at_stop = run
                .ego
                .sample_at(UtcNanos((a.0 + b.0) / 2), &mut h)
                .unwrap();
            assert!(at_stop.position.x < -5.0, "{}", at_stop.position.x);
        }
        assert_eq!(
            parse_utc("2026-11-21T10:00:00Z"),
            hilrig_stamp::civil::utc_from_civil(2026, 11, 21, 36_000 * 1_000_000_000)
        );
    }
}

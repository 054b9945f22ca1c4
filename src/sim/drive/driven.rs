//! The drive itself: how a human drives a drive file once (the speed profile by time stepping,
//! the stop for a crossing walker, the variation between repetitions), the trajectory that
//! results ([`Driven`]), and whether a car can drive the path as planned.
//!
//! A file of its own because it is the driver model, a time-stepping loop whose state the
//! format it reads ([`super::file`]) and the geometry it drives along ([`super::path`]) never
//! see.

use super::file::{parse_utc, DriveError, DriveFile};
use super::path::{catmull_rom, steer_transition_m, steered, Polyline, STEER_TRANSITION_M};
use crate::scene::pose::{PoseSample, Trajectory};
use crate::sim::drivable::{beyond, Exceedance, PathPoint, PASSENGER_CAR};
use hilrig_stamp::UtcNanos;
use nalgebra::{Vector2, Vector3};
use rand::Rng;
use rand_distr::{Distribution, Normal};

/// One repetition as driven.
#[derive(Clone, Debug)]
pub struct Driven {
    /// Rear-axle pose in the local frame.
    pub ego: Trajectory,
    /// Speed (m/s, negative while backing up) and yaw rate (rad/s) per ego sample.
    pub motion: Vec<(f64, f64)>,
    /// Walkers' trajectories by actor name.
    pub walkers: Vec<(String, Trajectory)>,
    /// When the ego was stopped for the walker (start, end), if it was.
    pub yield_stop: Option<(UtcNanos, UtcNanos)>,
    /// Drive start and end.
    pub span: (UtcNanos, UtcNanos),
    /// The limits of a car this repetition exceeds as driven (see [`DriveFile::drivable`]).
    pub beyond_car: Vec<Exceedance>,
    /// The same of the leg backed up, with that leg's waypoints (the path's end, two points
    /// straight behind it, then `path.reverse.waypoints`), which its exceedances count from.
    pub beyond_car_backing: Vec<Exceedance>,
    /// The leg backed up's waypoints, as [`Driven::beyond_car_backing`] counts them.
    pub backing_waypoints: Vec<[f64; 2]>,
}

/// Catmull-Rom points per stretch between two waypoints.
const SPLINE_POINTS_PER_SEGMENT: usize = 200;

/// Spacing of the driven path's points, m.
const PATH_STEP_M: f64 = 0.02;

/// Half the arc length over which the change of curvature is measured, m: a quarter of the
/// steering transition, short enough to see the steepest part of its ramp.
const CURVATURE_CHANGE_HALF_M: f64 = STEER_TRANSITION_M / 4.0;

/// The path as driven, point by point: curvature and its change from the steered path, the
/// speed it is passed at from the speed profile `samples` (time, arc length, speed), and the
/// stretch between two waypoints each point came from (`planned`: the spline, whose
/// [`SPLINE_POINTS_PER_SEGMENT`] points per stretch the driven points were laid along, one
/// every [`PATH_STEP_M`]).
fn as_driven(
    path: &Polyline,
    planned: &Polyline,
    stretches: usize,
    samples: &[(f64, f64, f64)],
) -> Vec<PathPoint> {
    let n = path.pts.len();
    // Headings of the path's pieces, unwrapped, and the curvature at each point between two.
    let mut heading: Vec<f64> = Vec::with_capacity(n.saturating_sub(1));
    for w in path.pts.windows(2) {
        let d = w[1] - w[0];
        let mut h = d.y.atan2(d.x);
        if let Some(&prev) = heading.last() {
            h = prev + (h - prev + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
        }
        heading.push(h);
    }
    let mut curvature = vec![0.0; n];
    for i in 1..n.saturating_sub(1) {
        let ds = (path.s[i + 1] - path.s[i - 1]) / 2.0;
        if ds > 1e-9 {
            curvature[i] = (heading[i] - heading[i - 1]) / ds;
        }
    }
    if n >= 3 {
        curvature[0] = curvature[1];
        curvature[n - 1] = curvature[n - 2];
    }
    // The speed at an arc length: the speed profile with arc length increasing (the fastest
    // sample where the vehicle stands), linear in between.
    let mut profile: Vec<(f64, f64)> = Vec::with_capacity(samples.len());
    for &(_, s, v) in samples {
        match profile.last_mut() {
            Some(last) if s <= last.0 => last.1 = last.1.max(v),
            _ => profile.push((s, v)),
        }
    }
    let speed_at = |s: f64| -> f64 {
        let k = profile.partition_point(|p| p.0 < s);
        match (k.checked_sub(1).map(|j| profile[j]), profile.get(k)) {
            (Some(a), Some(b)) if b.0 > a.0 => a.1 + (b.1 - a.1) * (s - a.0) / (b.0 - a.0),
            (_, Some(b)) => b.1,
            (Some(a), None) => a.1,
            (None, None) => 0.0,
        }
    };
    let half = ((CURVATURE_CHANGE_HALF_M / PATH_STEP_M).round() as usize).max(1);
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half).min(n - 1));
            let change = if path.s[b] - path.s[a] > 1e-9 {
                (curvature[b] - curvature[a]) / (path.s[b] - path.s[a])
            } else {
                0.0
            };
            let along_plan = (i as f64 * PATH_STEP_M).min(planned.length());
            let on_spline = planned
                .s
                .partition_point(|&x| x <= along_plan)
                .saturating_sub(1);
            PathPoint {
                s_m: path.s[i],
                position: [path.pts[i].x, path.pts[i].y],
                speed_mps: speed_at(path.s[i]),
                curvature_per_m: curvature[i],
                curvature_change_per_m2: change,
                segment: (on_spline / SPLINE_POINTS_PER_SEGMENT).min(stretches.saturating_sub(1)),
            }
        })
        .collect()
}

impl DriveFile {
    /// Every number of the path, the walkers, the yield and the variation is finite: TOML reads
    /// `nan` and `inf`, and one of them in a waypoint would make a path of NaN, which no check
    /// downstream can locate. The error names the field (and the waypoint, counted from 0).
    fn finite(&self) -> Result<(), DriveError> {
        let bad = |what: String| DriveError::Invalid {
            name: self.name.clone(),
            what,
        };
        let p = &self.path;
        for (i, w) in p.waypoints.iter().enumerate() {
            if !w.iter().all(|x| x.is_finite()) {
                return Err(bad(format!(
                    "waypoint {i} (counted from 0) is [{}, {}]: a waypoint is two finite numbers, metres in the scene's local frame",
                    w[0], w[1]
                )));
            }
        }
        let mut fields: Vec<(String, f64)> = vec![
            ("path.cruise_speed_mps".into(), p.cruise_speed_mps),
            ("path.acceleration_mps2".into(), p.acceleration_mps2),
            ("path.deceleration_mps2".into(), p.deceleration_mps2),
            ("path.lead_in_s".into(), p.lead_in_s),
            ("path.start_speed_mps".into(), p.start_speed_mps),
            ("path.lead_out_s".into(), p.lead_out_s),
            ("variation.lateral_m".into(), self.variation.lateral_m),
            ("variation.speed_factor".into(), self.variation.speed_factor),
            (
                "variation.walker_start_s".into(),
                self.variation.walker_start_s,
            ),
            (
                "variation.walker_speed_factor".into(),
                self.variation.walker_speed_factor,
            ),
        ];
        for w in &self.walkers {
            let f = |k: &str| format!("walker '{}' {k}", w.actor);
            fields.extend([
                (f("from[0]"), w.from[0]),
                (f("from[1]"), w.from[1]),
                (f("to[0]"), w.to[0]),
                (f("to[1]"), w.to[1]),
                (f("speed_mps"), w.speed_mps),
                (f("start_s"), w.start_s),
            ]);
        }
        if let Some(y) = &self.yield_to {
            fields.extend([
                ("yield_to.stop_at_m".into(), y.stop_at_m),
                ("yield_to.clearance_m".into(), y.clearance_m),
            ]);
        }
        if let Some(r) = &p.reverse {
            for (i, w) in r.waypoints.iter().enumerate() {
                fields.extend([
                    (format!("path.reverse.waypoints[{i}][0]"), w[0]),
                    (format!("path.reverse.waypoints[{i}][1]"), w[1]),
                ]);
            }
            fields.extend([
                ("path.reverse.speed_mps".into(), r.speed_mps),
                ("path.reverse.pause_s".into(), r.pause_s),
            ]);
        }
        match fields.iter().find(|(_, x)| !x.is_finite()) {
            Some((name, x)) => Err(bad(format!("{name} = {x}: must be a finite number"))),
            None => Ok(()),
        }
    }

    /// Whether a car can drive the path as planned: drives it without human variation and
    /// refuses it when it turns tighter than a car can turn, faster through a turn than a
    /// car's tyres hold or its yaw rate reaches, or changes its curvature faster than a car
    /// steers (see [`crate::sim::drivable`]): the driver model enters a single bend within that
    /// ([`steer_transition_m`]), so a drive beyond it reverses tight turns too quickly (a
    /// slalom of 3 m radii at 4 m/s). A repetition's human variation may take it beyond a
    /// limit by a little; that stays in [`Driven::beyond_car`] for `synth` to report.
    pub fn drivable(&self) -> Result<(), DriveError> {
        use rand::SeedableRng;
        let undrivable = |name: String, exceeded: Vec<Exceedance>, waypoints: &[[f64; 2]]| {
            if exceeded.is_empty() {
                Ok(())
            } else {
                Err(DriveError::Undrivable {
                    name,
                    exceeded,
                    waypoints: waypoints.to_vec(),
                })
            }
        };
        self.finite()?;
        // Without variation nothing is drawn: the generator only has to exist.
        let rng = &mut rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let forward = self.forward_leg();
        let planned = forward.drive_leg(rng, false)?;
        undrivable(self.name.clone(), planned.beyond_car, &self.path.waypoints)?;
        if let Some(leg) = self.reverse_leg(planned.ego.samples().last())? {
            let back = leg.drive_leg(rng, false)?;
            undrivable(
                format!("{}, {}", self.name, super::file::BACKING_UP),
                back.beyond_car,
                &leg.path.waypoints,
            )?;
        }
        Ok(())
    }

    /// Drives the path once, with human variation drawn from `rng` (none when `vary` is false),
    /// and backs up after it where the path says so.
    pub fn drive(&self, rng: &mut impl Rng, vary: bool) -> Result<Driven, DriveError> {
        // The whole file first: each leg checks only its own path, which for the reversing leg
        // holds its waypoints under the names of a path of its own.
        self.finite()?;
        let forward = self.forward_leg().drive_leg(rng, vary)?;
        let mut driven = match self.reverse_leg(forward.ego.samples().last())? {
            Some(leg) => {
                let back = leg.drive_leg(rng, vary)?;
                let mut d = forward
                    .then_backing(back)
                    .map_err(|e| DriveError::Invalid {
                        name: self.name.clone(),
                        what: e,
                    })?;
                d.backing_waypoints = leg.path.waypoints;
                d
            }
            None => forward,
        };
        // Walkers are only needed while the ego drives (and a second either side).
        let span = driven.span;
        for (_, w) in &mut driven.walkers {
            let keep: Vec<PoseSample> = w
                .samples()
                .iter()
                .filter(|p| {
                    p.t.0 >= span.0 .0 - 1_000_000_000 && p.t.0 <= span.1 .0 + 1_000_000_000
                })
                .copied()
                .collect();
            *w = Trajectory::new(keep).map_err(|e| DriveError::Invalid {
                name: self.name.clone(),
                what: e.to_string(),
            })?;
        }
        Ok(driven)
    }

    /// Drives one leg's path forwards, with human variation drawn from `rng` (none when `vary`
    /// is false); its walkers for the whole hour it allows.
    #[allow(
        clippy::too_many_lines,
        reason = "one time-stepping loop whose state (speed, position, yield phase, variation) every step shares"
    )]
    fn drive_leg(&self, rng: &mut impl Rng, vary: bool) -> Result<Driven, DriveError> {
        let bad = |what: String| DriveError::Invalid {
            name: self.name.clone(),
            what,
        };
        let p = &self.path;
        if p.waypoints.len() < 2 {
            return Err(bad("the path needs at least two waypoints".into()));
        }
        self.finite()?;
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
        let planned = Polyline::new(catmull_rom(&wps, SPLINE_POINTS_PER_SEGMENT));
        let length = planned.length();
        // The driver's deviation: two smooth half-waves along the path, zero at both ends, plus
        // a final offset that grows in smoothly (nobody parks on the same centimetre twice).
        let (a1, a2, a_end) = (
            gauss(v.lateral_m),
            gauss(v.lateral_m * 0.5),
            gauss(v.lateral_m * 0.5),
        );
        let driven_pts: Vec<Vector2<f64>> = (0..=(length / PATH_STEP_M).ceil() as usize)
            .map(|k| {
                let s = (k as f64 * PATH_STEP_M).min(length);
                let (pos, tan) = planned.at(s);
                let normal = Vector2::new(-tan.y, tan.x);
                let x = s / length;
                let off = a1 * (std::f64::consts::PI * x).sin()
                    + a2 * (2.0 * std::f64::consts::PI * x).sin()
                    + a_end * x * x * (3.0 - 2.0 * x);
                pos + normal * off
            })
            .collect();
        let path = Polyline::new(steered(&driven_pts, steer_transition_m(p.cruise_speed_mps)));
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
        let beyond_car = beyond(
            &as_driven(&path, &planned, wps.len() - 1, &samples),
            &PASSENGER_CAR,
        );
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
        let ns = |x: f64| UtcNanos(start.0 + (x * 1e9).round() as i64);
        Ok(Driven {
            ego,
            motion,
            walkers,
            yield_stop: stop.map(|(a, b)| (ns(a), ns(b))),
            span,
            beyond_car,
            beyond_car_backing: Vec::new(),
            backing_waypoints: Vec::new(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::drivable::{
        Quantity, MAX_CURVATURE_RATE_PER_M_S, MAX_LATERAL_ACCELERATION_MPS2,
    };
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

    /// `DRIVE` without its walker, along `waypoints` at `speed`.
    fn plain(waypoints: &str, speed: f64) -> DriveFile {
        let text = DRIVE
            .replace(
                "waypoints = [[-10.0, 0.0], [0.0, 0.0], [5.0, 3.0], [6.0, 8.0]]",
                &format!("waypoints = {waypoints}"),
            )
            .replace(
                "cruise_speed_mps = 2.0",
                &format!("cruise_speed_mps = {speed:?}\nacceleration_mps2 = 2.0"),
            );
        let text = text.split("[[walker]]").next().unwrap();
        toml::from_str(text).unwrap()
    }

    /// What a car does is driven without a word: a 20 m bend at 8 m/s (0.33 g), a parking
    /// manoeuvre at 2 m/s (the parking fixture's path: a 2.6 m radius into the slot), and every
    /// drive of fixtures/ as planned.
    #[test]
    fn drives_a_car_can_do_are_accepted() {
        // A straight east, a quarter circle of 20 m, a straight north: a waypoint every 15° of
        // the circle (5.2 m apart) and as far apart along the straights (a Catmull-Rom spline
        // through unevenly spaced waypoints overshoots).
        let step = 2.0 * 20.0 * 7.5f64.to_radians().sin();
        let mut w: Vec<String> = (0..6)
            .map(|k| format!("[{}, 0.0]", -step * f64::from(6 - k)))
            .collect();
        for k in 0..=6 {
            let a = (f64::from(k) * 15.0).to_radians();
            w.push(format!("[{}, {}]", 20.0 * a.sin(), 20.0 * (1.0 - a.cos())));
        }
        w.extend((1..=6).map(|k| format!("[20.0, {}]", 20.0 + step * f64::from(k))));
        let bend = plain(&format!("[{}]", w.join(", ")), 8.0);
        bend.drivable().unwrap();
        let d = bend
            .drive(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1), false)
            .unwrap();
        assert_eq!(d.beyond_car, vec![]);
        // It does turn as fast as 8 m/s on 20 m make it (0.4 rad/s; the spline waves about
        // the circle between its waypoints, up to a third tighter).
        let yaw = d.motion.iter().map(|m| m.1.abs()).fold(0.0, f64::max);
        assert!((0.38..0.6).contains(&yaw), "yaw rate {yaw}");
        let parking = plain(
            "[[-16.0, 0.0], [-6.0, 0.0], [-1.0, 0.4], [1.6, 1.8], [2.5, 3.6], [2.55, 4.8]]",
            2.0,
        );
        parking.drivable().unwrap();
        let d = parking
            .drive(&mut rand_chacha::ChaCha8Rng::seed_from_u64(1), false)
            .unwrap();
        assert_eq!(d.beyond_car, vec![]);
        for f in ["parking", "gap", "efast"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("fixtures")
                .join(f)
                .join("drive.toml");
            let d = DriveFile::load(&path).unwrap();
            d.drivable()
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
    }

    /// A slalom whose turns a car can each take (radius 4 m and more, 0.4 g, 55 °/s) but
    /// reverses every 3 m at 4 m/s: the steering would have to turn faster than any car's.
    /// Refused for that alone, naming the value; at walking pace the same slalom is kept.
    #[test]
    fn a_slalom_reversed_faster_than_a_car_steers_is_refused() {
        let wavelength = 6.0;
        let amplitude = 0.3 / (std::f64::consts::TAU / wavelength).powi(2);
        // A waypoint every 0.5 m, on the straights before and after too (a Catmull-Rom spline
        // through unevenly spaced waypoints overshoots).
        let w: Vec<String> = (-32..=(8.0 * wavelength) as i32 + 32)
            .map(|k| {
                let x = f64::from(k) * 0.5;
                let y = if (0.0..=4.0 * wavelength).contains(&x) {
                    amplitude * (std::f64::consts::TAU * x / wavelength).sin()
                } else {
                    0.0
                };
                format!("[{x}, {y}]")
            })
            .collect();
        let waypoints = format!("[{}]", w.join(", "));
        let Err(DriveError::Undrivable { exceeded, .. }) = plain(&waypoints, 4.0).drivable() else {
            panic!("a 3 m slalom at 4 m/s was accepted");
        };
        let q: Vec<Quantity> = exceeded.iter().map(|x| x.quantity).collect();
        assert_eq!(q, [Quantity::CurvatureRate], "{exceeded:?}");
        assert!(
            exceeded[0].value > MAX_CURVATURE_RATE_PER_M_S,
            "{exceeded:?}"
        );
        plain(&waypoints, 1.5).drivable().unwrap();
    }

    /// Waypoints that make the spline loop, driven at 8.8 m/s (the reported drive): refused,
    /// naming the stretch between the waypoints where it loops, and the values against the
    /// limits. The same path at walking pace is still too tight for any car.
    #[test]
    fn a_loop_is_refused_with_the_waypoints_and_the_values() {
        let looping = "[[-20.0, 0.0], [0.0, 0.0], [2.0, 1.0], [1.0, 2.0], [0.0, 0.5], [20.0, 1.0]]";
        let Err(e) = plain(looping, 8.8).drivable() else {
            panic!("a loop at 8.8 m/s was accepted");
        };
        let DriveError::Undrivable { exceeded, .. } = &e else {
            panic!("{e}");
        };
        let q: Vec<Quantity> = exceeded.iter().map(|x| x.quantity).collect();
        assert!(q.contains(&Quantity::LateralAcceleration), "{q:?}");
        assert!(q.contains(&Quantity::YawRate) && q.contains(&Quantity::Curvature));
        assert!(q.contains(&Quantity::CurvatureRate), "{q:?}");
        let lateral = exceeded
            .iter()
            .find(|x| x.quantity == Quantity::LateralAcceleration)
            .unwrap();
        // The loop lies between waypoints 1 and 4; it is driven near cruise speed.
        assert!((1..=3).contains(&lateral.at.segment), "{lateral:?}");
        assert!(lateral.at.speed_mps > 4.0, "{lateral:?}");
        assert!(
            lateral.value > 3.0 * MAX_LATERAL_ACCELERATION_MPS2,
            "{lateral}"
        );
        let text = e.to_string();
        let k = lateral.at.segment;
        let named = format!(
            "between waypoint {k} [{}, {}] and waypoint {} [{}, {}]",
            plain(looping, 1.0).path.waypoints[k][0],
            plain(looping, 1.0).path.waypoints[k][1],
            k + 1,
            plain(looping, 1.0).path.waypoints[k + 1][0],
            plain(looping, 1.0).path.waypoints[k + 1][1],
        );
        assert!(text.contains(&named), "{text}");
        assert!(
            text.contains("lateral acceleration") && text.contains("above the 8.8 m/s²"),
            "{text}"
        );
        // At 1 m/s the tyres would hold it; the turning radius still does not.
        let Err(DriveError::Undrivable { exceeded, .. }) = plain(looping, 1.0).drivable() else {
            panic!("a loop at 1 m/s was accepted");
        };
        assert_eq!(exceeded[0].quantity, Quantity::Curvature, "{exceeded:?}");
    }

    /// A waypoint or a speed that is not a finite number is named; no path of NaN is driven.
    #[test]
    fn a_waypoint_that_is_not_a_number_is_named() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let e = plain("[[-10.0, 0.0], [0.0, 0.0], [nan, 3.0], [6.0, 8.0]]", 2.0)
            .drive(&mut rng, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("waypoint 2") && e.contains("NaN"), "{e}");
        let e = plain("[[-10.0, 0.0], [0.0, -inf]]", 2.0)
            .drivable()
            .unwrap_err()
            .to_string();
        assert!(e.contains("waypoint 1") && e.contains("-inf"), "{e}");
        let e = plain("[[-10.0, 0.0], [0.0, 0.0]]", f64::INFINITY)
            .drivable()
            .unwrap_err()
            .to_string();
        assert!(e.contains("path.cruise_speed_mps = inf"), "{e}");
    }

    /// Backing into a slot after driving past it: the car stops at the path's end, stands, and
    /// backs up with a negative speed, its heading continuous through the turn-around (the
    /// body does not turn round: its heading is the path's direction turned by 180° while it
    /// backs) and its position too; it ends at the last point, at rest, standing the lead-out.
    /// A leg too tight for a car is refused, naming the leg.
    #[test]
    fn backs_up_after_the_path_with_a_negative_speed_and_a_continuous_heading() {
        let mut d = plain("[[-10.0, 0.0], [0.0, 0.0], [8.0, 0.0]]", 2.0);
        d.path.reverse = Some(crate::sim::drive::ReverseLeg {
            waypoints: vec![[4.0, 1.0], [2.0, 4.0], [1.8, 6.0]],
            speed_mps: 1.0,
            pause_s: 1.0,
        });
        d.drivable().unwrap();
        let r = d
            .drive(&mut rand_chacha::ChaCha8Rng::seed_from_u64(3), false)
            .unwrap();
        let poses = r.ego.samples();
        assert_eq!(poses.len(), r.motion.len());
        let mut backing = 0.0;
        for (w, m) in poses.windows(2).zip(&r.motion) {
            let dt = (w[1].t.0 - w[0].t.0) as f64 * 1e-9;
            assert!(dt > 0.0);
            let step = (w[1].position - w[0].position).xy();
            assert!(
                step.norm() <= 2.1 * dt + 1e-6,
                "a jump of {} m",
                step.norm()
            );
            assert!(
                (w[1].yaw - w[0].yaw).abs() < 0.02,
                "the heading jumps by {} rad at {:?}",
                w[1].yaw - w[0].yaw,
                w[0].t
            );
            // The motion is along the heading, signed by the speed.
            let along = step.dot(&Vector2::new(w[0].yaw.cos(), w[0].yaw.sin()));
            if m.0.abs() > 0.2 {
                assert_eq!(along.signum(), m.0.signum(), "at {:?}: {m:?}", w[0].t);
            }
            if m.0 < 0.0 {
                backing += dt;
            }
        }
        assert!(backing > 5.0, "backed up for {backing} s");
        let last = poses.last().unwrap();
        assert!(
            (last.position.xy() - Vector2::new(1.8, 6.0)).norm() < 0.05,
            "{:?}",
            last.position
        );
        assert_eq!(r.motion.last().unwrap().0, 0.0);
        // Backing into the slot turned the car's nose about 90° to the right of its aisle
        // heading (it points away from the slot): a heading near -90°, the path's direction
        // (north, into the slot) turned round.
        assert!(
            (last.yaw.to_degrees() + 90.0).abs() < 25.0,
            "{}",
            last.yaw.to_degrees()
        );

        d.path.reverse.as_mut().unwrap().waypoints = vec![[7.0, 0.0], [6.5, 2.0], [7.0, 2.5]];
        let e = d.drivable().unwrap_err().to_string();
        assert!(e.contains("backing up"), "{e}");
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

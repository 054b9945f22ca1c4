//! The path geometry of a drive: the Catmull-Rom spline through the waypoints, the steering
//! that ramps its curvature as a driver turns a wheel, and the polyline a drive is sampled
//! along.
//!
//! A file of its own because it is plain geometry on points: it knows nothing of the drive
//! file's format or of the speed profile, and the driver ([`super::driven`]) only calls it.

use nalgebra::Vector2;

pub(super) fn catmull_rom(points: &[Vector2<f64>], per_segment: usize) -> Vec<Vector2<f64>> {
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
pub(super) const STEER_TRANSITION_M: f64 = 1.0;

/// Time over which a driver turns the steering wheel into a bend, s: above 2.5 m/s the
/// transition grows with speed ([`steer_transition_m`]), so that a bend is entered no faster
/// than a car steers (the curvature then changes by at most Δκ / 0.8 s: a straight into the
/// tightest turn a car makes, 1/2.2 m, at 0.57 1/(m·s), below the
/// [`crate::sim::drivable::MAX_CURVATURE_RATE_PER_M_S`] of 0.8).
const STEER_TIME_S: f64 = 0.4;

/// The arc length over which the driver model steers into a bend at `speed_mps`: a metre at
/// parking speed, `speed × STEER_TIME_S` above it.
pub(super) fn steer_transition_m(speed_mps: f64) -> f64 {
    STEER_TRANSITION_M.max(speed_mps * STEER_TIME_S)
}

/// The path a car can drive along `pts` (evenly spaced): its heading, as a function of arc
/// length, averaged twice over `transition` (so the curvature ramps instead of stepping), and
/// the points integrated again from the first one along that heading.
pub(super) fn steered(pts: &[Vector2<f64>], transition: f64) -> Vec<Vector2<f64>> {
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
pub(super) struct Polyline {
    pub(super) pts: Vec<Vector2<f64>>,
    pub(super) s: Vec<f64>,
}

impl Polyline {
    pub(super) fn new(pts: Vec<Vector2<f64>>) -> Polyline {
        let mut s = vec![0.0];
        for w in pts.windows(2) {
            s.push(s[s.len() - 1] + (w[1] - w[0]).norm());
        }
        Polyline { pts, s }
    }
    pub(super) fn length(&self) -> f64 {
        self.s[self.s.len() - 1]
    }
    /// Position and unit tangent at arc length `s`. The tangent turns continuously: at each
    /// vertex it is the direction of the chord between its neighbours, and along a segment it
    /// is blended between the two vertices' tangents. A real vehicle's heading has no steps;
    /// the segments' own directions would make one step per vertex (0.4° per 2 cm in a 3 m
    /// turn), a staircase that no heading estimate should be asked to follow.
    pub(super) fn at(&self, s: f64) -> (Vector2<f64>, Vector2<f64>) {
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

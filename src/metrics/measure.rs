//! One scan pair measured: both scans decoded and placed, then what the pair says by itself
//! (the objects each sees, the per-firing range residuals, the point distances), keeping only
//! the points in the region for the grids that span several scans.

use super::cloud::{Cloud, Frame};
use super::pairing::Pair;
use super::points::{distances, PointScores};
use super::report::ObjectSeen;
use super::roi::Roi;
use hilrig_stamp::UtcNanos;
use nalgebra::Point3;

/// An object counts as seen with this many measured points in a scan.
pub const MIN_POINTS_SEEN: usize = 10;

fn extent(points: &[Point3<f64>]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let (mut lo, mut hi) = (points[0], points[0]);
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (hi - lo).norm()
}

/// What the sensor saw of the objects in one scan pair.
pub(super) fn objects_seen(roi: &Roi, real: &Cloud, sim: &Cloud) -> Vec<ObjectSeen> {
    let margin = 0.2;
    roi.boxes()
        .iter()
        .filter_map(|(name, b)| {
            let r: Vec<&(Point3<f64>, f32)> = real
                .all
                .iter()
                .filter(|(p, _)| b.contains(p, margin))
                .collect();
            if r.len() < MIN_POINTS_SEEN {
                return None;
            }
            let s: Vec<Point3<f64>> = sim
                .all
                .iter()
                .filter(|(p, _)| b.contains(p, margin))
                .map(|(p, _)| *p)
                .collect();
            let rp: Vec<Point3<f64>> = r.iter().map(|(p, _)| *p).collect();
            Some(ObjectSeen {
                name: name.clone(),
                real_points: r.len(),
                sim_points: s.len(),
                range_m: r.iter().map(|(_, d)| f64::from(*d)).sum::<f64>() / r.len() as f64,
                real_extent_m: extent(&rp),
                sim_extent_m: extent(&s),
            })
        })
        .collect()
}

/// The range residuals of one scan pair: their sum and sum of squares over the firings both
/// have, and the returns only one has.
#[derive(Clone, Copy, Default)]
pub(super) struct Residuals {
    pub(super) sum: f64,
    pub(super) sum2: f64,
    pub(super) both: usize,
    pub(super) only_real: usize,
    pub(super) only_sim: usize,
}

/// Simulated minus measured range of the firings both have, and the returns only one has.
pub(super) fn residuals(real: &Cloud, sim: &Cloud) -> Residuals {
    let mut r = Residuals::default();
    let (a, b) = (&real.firings, &sim.firings);
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].0.cmp(&b[j].0) {
            std::cmp::Ordering::Less => {
                r.only_real += 1;
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                r.only_sim += 1;
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                let diff = f64::from(b[j].1) - f64::from(a[i].1);
                r.sum += diff;
                r.sum2 += diff * diff;
                r.both += 1;
                i += 1;
                j += 1;
            }
        }
    }
    r.only_real += a.len() - i;
    r.only_sim += b.len() - j;
    r
}

/// What one scan pair contributes once it is measured: the clouds' points in the region (for
/// the grids of this and the next K - 1 windows, and the snapshot), and its own numbers.
pub(super) struct Measured {
    pub(super) real: Vec<Point3<f64>>,
    pub(super) sim: Vec<Point3<f64>>,
    pub(super) origin: Option<Point3<f64>>,
    pub(super) middle: UtcNanos,
    pub(super) stamp: UtcNanos,
    pub(super) objects: Vec<ObjectSeen>,
    pub(super) res: Residuals,
    pub(super) points: Option<PointScores>,
    /// Returns (firings with a return) measured and simulated.
    pub(super) returns: (usize, usize),
}

/// Decodes and measures one pair.
pub(super) fn measure(frame: &Frame<'_>, roi: &Roi, (r, s): &Pair) -> Measured {
    let (real, sim) = (frame.cloud(r), frame.cloud(s));
    let objects = objects_seen(roi, &real, &sim);
    Measured {
        points: distances(&real.points, &sim.points),
        res: residuals(&real, &sim),
        returns: (real.firings.len(), sim.firings.len()),
        origin: real.origin,
        middle: real.middle,
        stamp: r.stamp,
        objects,
        real: real.points,
        sim: sim.points,
    }
}

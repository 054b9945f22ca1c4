//! One scan pair measured: both scans decoded and placed, then what the pair says by itself
//! (the objects each sees, the per-firing range residuals, the point distances), keeping only
//! the points in the region for the grids that span several scans.

use super::cloud::{Cloud, Frame};
use super::pairing::Pair;
use super::points::{distances_with_twins, PointScores};
use super::report::ObjectSeen;
use super::roi::Roi;
use hilrig_stamp::UtcNanos;
use nalgebra::Point3;

/// An object counts as seen with this many measured points in a scan.
pub const MIN_POINTS_SEEN: usize = 10;

/// The points of one cloud in one object's box: how many, their range sum, their extent.
#[derive(Clone, Copy)]
struct InBox {
    points: usize,
    range_sum: f64,
    lo: Point3<f64>,
    hi: Point3<f64>,
}

impl InBox {
    const EMPTY: InBox = InBox {
        points: 0,
        range_sum: 0.0,
        lo: Point3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
        hi: Point3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
    };

    fn add(&mut self, p: &Point3<f64>, range: f32) {
        self.points += 1;
        self.range_sum += f64::from(range);
        self.lo = self.lo.inf(p);
        self.hi = self.hi.sup(p);
    }

    /// The diagonal of the points' bounding box, m (0 without points).
    fn extent(&self) -> f64 {
        if self.points == 0 {
            0.0
        } else {
            (self.hi - self.lo).norm()
        }
    }
}

/// What the sensor saw of the objects in one scan pair: every point tested against the boxes
/// of its own cell of the region's index, once.
pub(super) fn objects_seen(roi: &Roi, real: &Cloud, sim: &Cloud) -> Vec<ObjectSeen> {
    let tally = |cloud: &Cloud| {
        let mut boxes = vec![InBox::EMPTY; roi.boxes().len()];
        for (p, range) in &cloud.all {
            for i in roi.boxes_at(p) {
                boxes[i].add(p, *range);
            }
        }
        boxes
    };
    let (r, s) = (tally(real), tally(sim));
    roi.boxes()
        .iter()
        .zip(r.iter().zip(&s))
        .filter(|(_, (r, _))| r.points >= MIN_POINTS_SEEN)
        .map(|((name, _), (r, s))| ObjectSeen {
            name: name.clone(),
            real_points: r.points,
            sim_points: s.points,
            range_m: r.range_sum / r.points as f64,
            real_extent_m: r.extent(),
            sim_extent_m: s.extent(),
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

/// The points of two clouds that the same firing returned (index in each cloud's `points`).
fn twins(real: &Cloud, sim: &Cloud) -> Vec<(u32, u32)> {
    let sorted = |c: &Cloud| {
        let mut v: Vec<(u64, u32)> = c
            .point_keys
            .iter()
            .enumerate()
            .map(|(i, &k)| (k, i as u32))
            .collect();
        radsort::sort_by_key(&mut v, |e| e.0);
        v
    };
    let (a, b) = (sorted(real), sorted(sim));
    let mut out = Vec::with_capacity(a.len().min(b.len()));
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].0.cmp(&b[j].0) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                out.push((a[i].1, b[j].1));
                i += 1;
                j += 1;
            }
        }
    }
    out
}

/// Decodes and measures one pair.
pub(super) fn measure(
    frame: &Frame<'_>,
    roi: &Roi,
    (r, s): &Pair,
    point_metrics: bool,
) -> Measured {
    let (real, sim) = (frame.cloud(r), frame.cloud(s));
    let objects = objects_seen(roi, &real, &sim);
    Measured {
        points: if point_metrics {
            distances_with_twins(&real.points, &sim.points, &twins(&real, &sim))
        } else {
            None
        },
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

#[cfg(test)]
mod tests {
    use super::{residuals, Cloud, InBox};
    use hilrig_stamp::UtcNanos;
    use nalgebra::Point3;

    fn cloud(firings: &[(u64, f32)]) -> Cloud {
        Cloud {
            points: Vec::new(),
            point_keys: Vec::new(),
            firings: firings.to_vec(),
            all: Vec::new(),
            origin: None,
            middle: UtcNanos(0),
        }
    }

    /// Firings paired by key: the residual is simulated minus measured over the firings both
    /// have; the rest are counted on their side, the tails after the other list ends too.
    #[test]
    fn residuals_pair_firings_by_key_and_count_the_rest() {
        // Measured keys 1 2 3 5 7 10 11 12, simulated 2 3 4 7: both 2 3 7; only measured 1 5
        // and the tail 10 11 12; only simulated 4.
        let real = cloud(&[
            (1, 9.0),
            (2, 10.0),
            (3, 20.0),
            (5, 1.0),
            (7, 30.0),
            (10, 1.0),
            (11, 1.0),
            (12, 1.0),
        ]);
        let sim = cloud(&[(2, 10.5), (3, 19.0), (4, 2.0), (7, 30.25)]);
        let r = residuals(&real, &sim);
        assert_eq!(
            (r.both, r.only_real, r.only_sim),
            (3, 5, 1),
            "firings in both, only measured, only simulated"
        );
        assert!(
            (r.sum - (0.5 - 1.0 + 0.25)).abs() < 1e-12,
            "sum of simulated minus measured {}, want -0.25",
            r.sum
        );
        assert!(
            (r.sum2 - (0.25 + 1.0 + 0.0625)).abs() < 1e-12,
            "sum of squares {}, want 1.3125",
            r.sum2
        );
        // The other way round: the simulated list has the tail.
        let r = residuals(&sim, &real);
        assert_eq!((r.both, r.only_real, r.only_sim), (3, 1, 5));
        assert!((r.sum - 0.25).abs() < 1e-12, "{}", r.sum);
        // Nothing in common.
        let r = residuals(&cloud(&[(1, 1.0), (2, 1.0)]), &cloud(&[(3, 1.0)]));
        assert_eq!((r.both, r.only_real, r.only_sim, r.sum), (0, 2, 1, 0.0));
    }

    /// An object's extent is the diagonal of its points' bounding box; no points, no extent.
    #[test]
    fn an_objects_extent_is_its_points_bounding_box_diagonal() {
        let mut b = InBox::EMPTY;
        assert_eq!(b.extent(), 0.0);
        b.add(&Point3::new(1.0, 1.0, 1.0), 5.0);
        assert_eq!(b.extent(), 0.0, "one point spans nothing");
        b.add(&Point3::new(4.0, 5.0, 1.0), 7.0);
        b.add(&Point3::new(2.0, 3.0, 1.0), 6.0);
        assert!((b.extent() - 5.0).abs() < 1e-12, "{}", b.extent());
        assert_eq!((b.points, b.range_sum), (3, 18.0));
    }
}

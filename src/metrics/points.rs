//! Point metrics: how far each cloud's points are from the other cloud.
//!
//! - Chamfer distance: the mean nearest-neighbour distance from A to B and from B to A,
//!   averaged: ½ (1/|A| Σ_a min_b ‖a − b‖ + 1/|B| Σ_b min_a ‖b − a‖), in metres (distances, not
//!   their squares, so it reads as a length).
//! - Hausdorff distance: the largest of those nearest-neighbour distances either way,
//!   max(max_a min_b ‖a − b‖, max_b min_a ‖b − a‖): the worst point.
//!
//! Nearest neighbours are exact (in f64), found in hashed grids of the other cloud. A query
//! first looks within half a cell of the finest grid (10 cm); a point found that near is the
//! nearest, since anything nearer lies in the cells searched. Otherwise the next grid, with
//! cells four times larger, and so on. Any point of the other cloud bounds
//! the search, and a re-simulation nearly always gives one a few centimetres away: the twin,
//! the same firing's return; without a twin, the neighbour found for the query before. Points
//! tens of metres from every point of the other cloud go to `kiddo`'s immutable k-d tree (a
//! well-kept crate, exact queries), built only when one comes. A k-d tree query for every
//! point was nine tenths of `compare`'s time on a street: it costs as much as decoding ten
//! points, one or two grid cells about as much as one.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;

/// Chamfer and Hausdorff distances of two clouds, m.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PointScores {
    /// Chamfer distance, m.
    pub chamfer_m: f64,
    /// Hausdorff distance, m.
    pub hausdorff_m: f64,
}

/// Cell edge of the finest grid, m: a ball around a point with a twin 2 cm away touches one or
/// two cells, and a cell holds a few tens of points even on a wall 3 m from the sensor.
const FINEST_CELL_M: f64 = 0.1;

/// Each grid's cells are this many times the edge of the one before.
const LEVEL_RATIO: f64 = 4.0;

/// Grids (the coarsest has cells of 6.4 m).
const LEVELS: usize = 4;

/// One grid: a cloud's points sorted by (a 32-bit hash of) their cell, with an open-addressing
/// table from the hash to its run of points. Two cells with one hash share a run: their points
/// are then searched together, which costs time, never correctness.
struct Level {
    cell: f64,
    points: Vec<[f64; 3]>,
    /// Per slot: cell hash (`EMPTY` when free), first point, number of points.
    table: Vec<(u32, u32, u32)>,
    mask: usize,
}

const EMPTY: u32 = u32::MAX;

/// `x.floor() as i64` by truncation: `f64::floor` is a library call unless the target has
/// SSE4.1, and this is on every point's path. (NaN gives 0, as the cast does.)
#[inline]
fn floor(x: f64) -> i64 {
    let t = x as i64;
    t - i64::from(x < t as f64)
}

/// The hash of a cell's integer coordinates (never `EMPTY`).
fn hash(c: [i64; 3]) -> u32 {
    let h = (c[0] as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (c[1] as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (c[2] as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    ((h >> 32) as u32).min(EMPTY - 1)
}

fn slot(h: u32, mask: usize) -> usize {
    (h.wrapping_mul(0x9E37_79B1) >> 7) as usize & mask
}

impl Level {
    fn new(cloud: &[Point3<f64>], cell: f64) -> Level {
        // (hash, index) pairs sorted, then the points gathered in that order: the sort moves 8
        // bytes an element instead of 32.
        let mut keyed: Vec<(u32, u32)> = cloud
            .iter()
            .enumerate()
            .map(|(i, p)| (hash(Level::cell_of(cell, &[p.x, p.y, p.z])), i as u32))
            .collect();
        radsort::sort_by_key(&mut keyed, |e| e.0);
        let cells = 1 + keyed.windows(2).filter(|w| w[0].0 != w[1].0).count();
        let cap = (cells * 2).next_power_of_two().max(16);
        let mut table = vec![(EMPTY, 0u32, 0u32); cap];
        let mask = cap - 1;
        let mut i = 0;
        while i < keyed.len() {
            let h = keyed[i].0;
            let mut j = i + 1;
            while j < keyed.len() && keyed[j].0 == h {
                j += 1;
            }
            let mut s = slot(h, mask);
            while table[s].0 != EMPTY {
                s = (s + 1) & mask;
            }
            table[s] = (h, i as u32, (j - i) as u32);
            i = j;
        }
        Level {
            cell,
            points: keyed
                .iter()
                .map(|&(_, i)| {
                    let p = &cloud[i as usize];
                    [p.x, p.y, p.z]
                })
                .collect(),
            table,
            mask,
        }
    }

    fn cell_of(cell: f64, p: &[f64; 3]) -> [i64; 3] {
        [floor(p[0] / cell), floor(p[1] / cell), floor(p[2] / cell)]
    }

    fn run(&self, h: u32) -> &[[f64; 3]] {
        let mut s = slot(h, self.mask);
        loop {
            let (key, start, len) = self.table[s];
            if key == h {
                return &self.points[start as usize..(start + len) as usize];
            }
            if key == EMPTY {
                return &[];
            }
            s = (s + 1) & self.mask;
        }
    }

    /// Folds the points of cell `c` into `best` (squared distance to `p`, and the point).
    fn visit(&self, c: [i64; 3], p: &[f64; 3], best: &mut (f64, Option<[f64; 3]>)) {
        for q in self.run(hash(c)) {
            let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
            let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if d2 < best.0 {
                *best = (d2, Some(*q));
            }
        }
    }

    /// Every cell the cube of half edge `r` around `p` touches, folded into `best`.
    fn search(&self, p: &[f64; 3], r: f64, best: &mut (f64, Option<[f64; 3]>)) {
        let lo = Level::cell_of(self.cell, &[p[0] - r, p[1] - r, p[2] - r]);
        let hi = Level::cell_of(self.cell, &[p[0] + r, p[1] + r, p[2] + r]);
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    self.visit([x, y, z], p, best);
                }
            }
        }
    }
}

/// A cloud indexed for exact nearest-neighbour queries: grids of growing cells and, for the
/// rare point tens of metres from every other, a k-d tree; each built on first use.
struct Grid<'a> {
    cloud: &'a [Point3<f64>],
    levels: [Option<Level>; LEVELS],
    tree: Option<Option<ImmutableKdTree<f32, 3>>>,
}

/// A cube of this many coarsest cells' half edge at most is searched in the grid; beyond, the
/// k-d tree.
const MAX_COARSE_REACH: f64 = 4.0;

impl<'a> Grid<'a> {
    fn new(cloud: &'a [Point3<f64>]) -> Grid<'a> {
        Grid {
            cloud,
            levels: [None, None, None, None],
            tree: None,
        }
    }

    fn level(&mut self, k: usize) -> &Level {
        let cloud = self.cloud;
        self.levels[k]
            .get_or_insert_with(|| Level::new(cloud, FINEST_CELL_M * LEVEL_RATIO.powi(k as i32)))
    }

    /// The squared distance from `p` to its nearest point and that point, given a point of the
    /// cloud `bound2` away (infinite when none is known; the point is `None` when none is
    /// nearer than the bound).
    fn nearest2(&mut self, p: &[f64; 3], bound2: f64) -> (f64, Option<[f64; 3]>) {
        // A few ulps of the coordinates more, so that rounding leaves no cell out.
        let pad = 8.0 * f64::EPSILON * p[0].abs().max(p[1].abs()).max(p[2].abs());
        let mut best = (bound2, None);
        for k in 0..LEVELS {
            let reach = best.0.sqrt().min(0.5 * self.level(k).cell);
            self.level(k).search(p, reach + pad, &mut best);
            if best.0.sqrt() <= reach {
                return best;
            }
        }
        let coarsest = self.level(LEVELS - 1).cell;
        let r = best.0.sqrt();
        if r <= MAX_COARSE_REACH * coarsest {
            self.level(LEVELS - 1).search(p, r + pad, &mut best);
            return best;
        }
        self.tree_nearest2(p, best)
    }

    /// The nearest point by the k-d tree (f32): its candidate is the nearest to within f32
    /// rounding, so every point within that rounding of it is measured again in f64.
    fn tree_nearest2(
        &mut self,
        p: &[f64; 3],
        mut best: (f64, Option<[f64; 3]>),
    ) -> (f64, Option<[f64; 3]>) {
        let cloud = self.cloud;

        let tree = self.tree.get_or_insert_with(|| {
            let entries: Vec<[f32; 3]> = cloud
                .iter()
                .map(|q| [q.x as f32, q.y as f32, q.z as f32])
                .collect();
            ImmutableKdTree::new_from_slice(&entries).ok()
        });
        let Some(tree) = tree else {
            return best;
        };
        let pf = [p[0] as f32, p[1] as f32, p[2] as f32];
        let nn = tree
            .query(&pf)
            .nearest_one::<SquaredEuclidean<f32>>()
            .execute();
        // f32 coordinates are off by up to 2^-24 of the largest coordinate, on both sides.
        let scale = p[0].abs().max(p[1].abs()).max(p[2].abs()) + f64::from(nn.distance).sqrt();
        let r = f64::from(nn.distance).sqrt() + 8.0 * f64::from(f32::EPSILON) * scale;
        let near = tree
            .query(&pf)
            .within::<SquaredEuclidean<f32>>((r * r) as f32 * (1.0 + 1e-6))
            .unsorted()
            .execute();
        for n in near {
            let q = cloud[n.item as usize];
            let d2 = (q.x - p[0]).powi(2) + (q.y - p[1]).powi(2) + (q.z - p[2]).powi(2);
            if d2 < best.0 {
                best = (d2, Some([q.x, q.y, q.z]));
            }
        }
        best
    }
}

/// Nearest-neighbour distances from every point of `from` to `to` (not empty); `twin[i]` is
/// the index in `to` of a point known to be close to `from[i]` (its twin), or `u32::MAX`.
fn nearest(from: &[Point3<f64>], to: &[Point3<f64>], twin: &[u32]) -> Vec<f64> {
    let mut grid = Grid::new(to);
    let mut out = vec![0.0; from.len()];
    // The point found for the query before: a bound for this one too.
    let mut previous: Option<[f64; 3]> = None;
    // Queries in space-filling-curve order: consecutive ones then lie close together, so the
    // cells they search are in the cache (in firing order, the next query is the next laser,
    // metres away, and the search waited on memory most of its time).
    for i in spatial_order(from) {
        let p = &from[i as usize];
        let q = [p.x, p.y, p.z];
        let d2 =
            |o: &[f64; 3]| (o[0] - q[0]).powi(2) + (o[1] - q[1]).powi(2) + (o[2] - q[2]).powi(2);
        let mut bound = twin
            .get(i as usize)
            .and_then(|&t| to.get(t as usize))
            .map_or(f64::INFINITY, |t| d2(&[t.x, t.y, t.z]));
        if let Some(o) = &previous {
            bound = bound.min(d2(o));
        }
        let (best, at) = grid.nearest2(&q, bound);
        previous = at.or(previous);
        out[i as usize] = best.sqrt();
    }
    out
}

/// Cell edge of the space-filling curve that orders the queries, m.
const ORDER_CELL_M: f64 = 0.4;

/// The indices of `points` along a Morton (Z-order) curve over cells of [`ORDER_CELL_M`]
/// (21 bits an axis from the cloud's lowest corner: 800 km).
fn spatial_order(points: &[Point3<f64>]) -> Vec<u32> {
    let mut lo = [f64::INFINITY; 3];
    for p in points {
        lo = [lo[0].min(p.x), lo[1].min(p.y), lo[2].min(p.z)];
    }
    let spread = |v: u64| -> u64 {
        // Every bit of the low 21 moved to every third position.
        let mut x = v & 0x1f_ffff;
        x = (x | (x << 32)) & 0x1f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x1f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        (x | (x << 2)) & 0x1249_2492_4924_9249
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let c = |v: f64, o: f64| floor((v - o) / ORDER_CELL_M).max(0) as u64;
            let k =
                spread(c(p.x, lo[0])) | (spread(c(p.y, lo[1])) << 1) | (spread(c(p.z, lo[2])) << 2);
            (k, i as u32)
        })
        .collect();
    radsort::sort_by_key(&mut keyed, |e| e.0);
    keyed.into_iter().map(|e| e.1).collect()
}

/// The Chamfer and Hausdorff distances of `a` and `b`; `None` when either is empty. `twins`
/// pairs indices of points of `a` and `b` that are known to lie close together (the same
/// firing's returns); they only speed the search up.
pub fn distances_with_twins(
    a: &[Point3<f64>],
    b: &[Point3<f64>],
    twins: &[(u32, u32)],
) -> Option<PointScores> {
    if a.is_empty() || b.is_empty() {
        return None;
    }
    let (mut ta, mut tb) = (vec![u32::MAX; a.len()], vec![u32::MAX; b.len()]);
    for &(i, j) in twins {
        if let (Some(x), Some(y)) = (ta.get_mut(i as usize), tb.get_mut(j as usize)) {
            *x = j;
            *y = i;
        }
    }
    // The two directions are independent: each on its own core where one is free (in
    // `compare`, scans are already spread over the cores and this adds nothing).
    let (ab, ba) = rayon::join(|| nearest(a, b, &ta), || nearest(b, a, &tb));
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    Some(PointScores {
        chamfer_m: 0.5 * (mean(&ab) + mean(&ba)),
        hausdorff_m: max(&ab).max(max(&ba)),
    })
}

/// The Chamfer and Hausdorff distances of `a` and `b`; `None` when either is empty.
pub fn distances(a: &[Point3<f64>], b: &[Point3<f64>]) -> Option<PointScores> {
    distances_with_twins(a, b, &[])
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn brute(a: &[Point3<f64>], b: &[Point3<f64>]) -> PointScores {
        let nn = |p: &Point3<f64>, s: &[Point3<f64>]| {
            s.iter()
                .map(|q| (p - q).norm())
                .fold(f64::INFINITY, f64::min)
        };
        let ab: Vec<f64> = a.iter().map(|p| nn(p, b)).collect();
        let ba: Vec<f64> = b.iter().map(|p| nn(p, a)).collect();
        PointScores {
            chamfer_m: 0.5
                * (ab.iter().sum::<f64>() / ab.len() as f64
                    + ba.iter().sum::<f64>() / ba.len() as f64),
            hausdorff_m: ab.iter().chain(&ba).copied().fold(0.0, f64::max),
        }
    }

    fn close(got: PointScores, want: PointScores, what: &str) {
        assert!(
            (got.chamfer_m - want.chamfer_m).abs() < 1e-12,
            "{what}: {got:?} {want:?}"
        );
        assert!(
            (got.hausdorff_m - want.hausdorff_m).abs() < 1e-12,
            "{what}: {got:?} {want:?}"
        );
    }

    /// Against a brute-force search on random clouds of different sizes (duplicates included),
    /// spread over many cells and packed into few, near the origin and kilometres from it, and
    /// with points far beyond the coarsest grid's cells from the other cloud.
    #[test]
    fn chamfer_and_hausdorff_equal_a_brute_force_search() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for (na, nb, spread, far) in [
            (1, 1, 20.0, 0.0),
            (7, 300, 20.0, 0.0),
            (500, 211, 20.0, 0.0),
            (1000, 1000, 20.0, 0.0),
            (800, 900, 0.3, 0.0),
            (600, 700, 2.0, 3500.0),
            (50, 60, 400.0, 0.0),
        ] {
            let mut cloud = |n: usize| -> Vec<Point3<f64>> {
                (0..n)
                    .map(|_| {
                        Point3::new(
                            far + rng.random_range(-spread..spread),
                            -far + rng.random_range(-spread..spread),
                            rng.random_range(-2.0..3.0) * spread / 20.0,
                        )
                    })
                    .collect()
            };
            let (a, mut b) = (cloud(na), cloud(nb));
            b.extend(a.iter().take(3).copied());
            let want = brute(&a, &b);
            close(distances(&a, &b).unwrap(), want, &format!("{na}x{nb}"));
            // Twins, right and wrong ones alike, change nothing but the speed.
            let twins: Vec<(u32, u32)> = (0..na.min(nb) as u32)
                .map(|i| (i, (i * 7) % nb as u32))
                .collect();
            close(
                distances_with_twins(&a, &b, &twins).unwrap(),
                want,
                &format!("{na}x{nb} with twins"),
            );
        }
        assert_eq!(distances(&[], &[Point3::origin()]), None);
        // One point 40 km from a cloud: found by the k-d tree.
        let a = [Point3::new(40_000.0, -3.0, 1.0)];
        let b = [Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 2.0, 3.0)];
        close(distances(&a, &b).unwrap(), brute(&a, &b), "far");
    }

    /// A scan-like pair: a wall and the ground seen by a sensor, the second cloud the first
    /// with centimetre noise, a tenth of its points missing and a few stray ones; twins as a
    /// re-simulation gives them.
    #[test]
    fn a_re_simulated_scan_gives_the_brute_force_distances() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut a = Vec::new();
        for i in 0..60 {
            for j in 0..40 {
                let (u, v) = (f64::from(i) * 0.05, f64::from(j) * 0.07);
                a.push(Point3::new(10.0 + u * 0.01, u, v));
                a.push(Point3::new(u * 3.0, v - 5.0, 0.0));
            }
        }
        let (mut b, mut twins) = (Vec::new(), Vec::new());
        for (i, p) in a.iter().enumerate() {
            if rng.random::<f64>() < 0.1 {
                continue;
            }
            twins.push((i as u32, b.len() as u32));
            b.push(p + nalgebra::Vector3::new(rng.random_range(-0.02..0.02), 0.0, 0.0));
        }
        b.push(Point3::new(4.0, 4.0, 9.0));
        close(
            distances_with_twins(&a, &b, &twins).unwrap(),
            brute(&a, &b),
            "scan",
        );
    }
}

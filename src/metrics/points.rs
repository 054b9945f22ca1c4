//! Point metrics: how far each cloud's points are from the other cloud.
//!
//! - Chamfer distance: the mean nearest-neighbour distance from A to B and from B to A,
//!   averaged: ½ (1/|A| Σ_a min_b ‖a − b‖ + 1/|B| Σ_b min_a ‖b − a‖), in metres (distances, not
//!   their squares, so it reads as a length).
//! - Hausdorff distance: the largest of those nearest-neighbour distances either way,
//!   max(max_a min_b ‖a − b‖, max_b min_a ‖b − a‖): the worst point.
//!
//! Nearest neighbours are exact (in f64), found in hashed grids of the other cloud. A query
//! first looks within half a cell of the finest grid (30 cm), its own cell first and then only
//! the cells that could still hold a nearer point; a point found within that half cell is the
//! nearest, since anything nearer lies in the cells searched. Otherwise the next grid, with
//! cells three times larger, and so on. Any point of the other cloud bounds
//! the search, and a re-simulation nearly always gives one a few centimetres away: the twin,
//! the same firing's return; without a twin, the neighbour found for the query before. Points
//! more than 97 m from every point of the other cloud go to `kiddo`'s immutable k-d tree (a
//! well-kept crate, exact queries), built only when one comes. A k-d tree query for every
//! point was nine tenths of `compare`'s time on a street: it costs as much as decoding ten
//! points.

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

/// Cell edge of the finest grid, m. A cell lookup (a hash, a probe, a run elsewhere in memory)
/// costs as much as a few tens of distances, and against a scene surveyed to 10 cm the nearest
/// point of the other cloud is often 5-15 cm away: with 10 cm cells a third of the queries went
/// on to the next grid and the lookups were most of the time. With 30 cm cells (and the search
/// passing over cells already too far) `compare` of a VLS-128 street drive took 0.78 of the CPU
/// time, with the same distances; 0.2-0.4 m were alike, 0.6 m slower; the sparse VLP-16
/// parking drive, where the point metrics are a small part, took as long as before.
const FINEST_CELL_M: f64 = 0.3;

/// Each grid's cells are this many times the edge of the one before: three, not four, so that
/// a query whose nearest point is a few metres away searches cells of 8.1 m, not of 19.2 m
/// holding tens of thousands of a dense sensor's points (as fast on the VLS-128 drive).
const LEVEL_RATIO: f64 = 3.0;

/// Grids (the coarsest has cells of 24.3 m).
const LEVELS: usize = 5;

/// One grid: a cloud's points sorted by (a 32-bit hash of) their cell, with an open-addressing
/// table from the hash to its run of points. Two cells with one hash share a run: their points
/// are then searched together, which costs time, never correctness.
struct Level {
    cell: f64,
    /// The points' coordinates, one array an axis (so that a run's distances are computed four
    /// at a time).
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
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

/// The squared distance of `a` and `b`. Every distance of the search is this one expression
/// (`visit` finds a run's least distance and then the point at exactly that distance; the
/// tests compare with a brute force bit for bit).
#[inline(always)]
fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// The lesser of `a` and `b` as a compare and a select (`a` when neither is less): unlike
/// `f64::min` it makes vector code in `visit`.
#[inline(always)]
fn lesser(a: f64, b: f64) -> f64 {
    if b < a {
        b
    } else {
        a
    }
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
        let axis = |k: usize| -> Vec<f64> {
            keyed
                .iter()
                .map(|&(_, i)| cloud[i as usize].coords[k])
                .collect()
        };
        Level {
            cell,
            xs: axis(0),
            ys: axis(1),
            zs: axis(2),
            table,
            mask,
        }
    }

    fn cell_of(cell: f64, p: &[f64; 3]) -> [i64; 3] {
        [floor(p[0] / cell), floor(p[1] / cell), floor(p[2] / cell)]
    }

    /// The run of points of the cell with hash `h`: its first index and length.
    fn run(&self, h: u32) -> (usize, usize) {
        let mut s = slot(h, self.mask);
        loop {
            let (key, start, len) = self.table[s];
            if key == h {
                return (start as usize, len as usize);
            }
            if key == EMPTY {
                return (0, 0);
            }
            s = (s + 1) & self.mask;
        }
    }

    /// Folds the points of cell `c` into `best` (squared distance to `p`, and the point).
    ///
    /// The run's smallest squared distance is found first, four lanes at a time without a
    /// branch (the compiler makes it vector code); only when it beats `best` is the run walked
    /// again for the point. Both passes compute the same expression, so the point found is one
    /// at exactly that distance.
    fn visit(&self, c: [i64; 3], p: &[f64; 3], best: &mut (f64, Option<[f64; 3]>)) {
        let (start, len) = self.run(hash(c));
        let end = start + len;
        let (xs, ys, zs) = (
            &self.xs[start..end],
            &self.ys[start..end],
            &self.zs[start..end],
        );
        let d2 = |i: usize| dist2(&[xs[i], ys[i], zs[i]], p);
        let mut lanes = [f64::INFINITY; 4];
        let (cx, cy, cz) = (xs.chunks_exact(4), ys.chunks_exact(4), zs.chunks_exact(4));
        let tail = cx
            .remainder()
            .iter()
            .zip(cy.remainder())
            .zip(cz.remainder());
        for ((x, y), z) in cx.zip(cy).zip(cz) {
            for l in 0..4 {
                lanes[l] = lesser(lanes[l], dist2(&[x[l], y[l], z[l]], p));
            }
        }
        for ((x, y), z) in tail {
            lanes[0] = lesser(lanes[0], dist2(&[*x, *y, *z], p));
        }
        let least = lanes.into_iter().fold(f64::INFINITY, lesser);
        if least < best.0 {
            if let Some(i) = (0..len).find(|&i| d2(i) == least) {
                *best = (least, Some([xs[i], ys[i], zs[i]]));
            }
        }
    }

    /// Every cell the cube of half edge `r` around `p` touches, folded into `best`: `p`'s own
    /// cell first, then the others that can still hold a nearer point. A cell whose box lies
    /// `best` or farther from `p` cannot (its points are at least that far), so it is passed
    /// over: on a dense cloud the nearest point is nearly always in the own cell, far nearer
    /// than the bound the cube was drawn with, and most of the cube's cells are then skipped.
    /// `pad` (a few ulps of the coordinates) shrinks each box distance, so that a point that
    /// rounding put in a cell beyond its true border is never skipped.
    fn search(&self, p: &[f64; 3], r: f64, pad: f64, best: &mut (f64, Option<[f64; 3]>)) {
        let lo = Level::cell_of(self.cell, &[p[0] - r, p[1] - r, p[2] - r]);
        let hi = Level::cell_of(self.cell, &[p[0] + r, p[1] + r, p[2] + r]);
        let own = Level::cell_of(self.cell, p);
        self.visit(own, p, best);
        let gap2 = |i: i64, v: f64| slab_gap2(self.cell, i, v, pad);
        for x in lo[0]..=hi[0] {
            let gx = gap2(x, p[0]);
            if gx >= best.0 {
                continue;
            }
            for y in lo[1]..=hi[1] {
                let gxy = gx + gap2(y, p[1]);
                if gxy >= best.0 {
                    continue;
                }
                for z in lo[2]..=hi[2] {
                    if [x, y, z] == own || gxy + gap2(z, p[2]) >= best.0 {
                        continue;
                    }
                    self.visit([x, y, z], p, best);
                }
            }
        }
    }
}

/// The squared distance along one axis from `v` to the slab of cells `i` of edge `cell` (0
/// inside it), never more than the true distance from `v` to a point that `Level::cell_of`
/// puts in that cell. Rounding makes the two disagree by an ulp or so: the division in
/// `cell_of` can put a point just below the computed border `i * cell` into cell `i`, and the
/// border's own product rounds either way. So the gap is shrunk by `pad` (a few ulps of the
/// query's coordinates) and by two ulps of the border.
fn slab_gap2(cell: f64, i: i64, v: f64, pad: f64) -> f64 {
    let (a, b) = (i as f64 * cell, i.saturating_add(1) as f64 * cell);
    let slack = pad + 2.0 * f64::EPSILON * a.abs().max(b.abs());
    let g = ((a - v).max(v - b) - slack).max(0.0);
    g * g
}

/// A cloud indexed for exact nearest-neighbour queries: grids of growing cells and, for the
/// rare point more than `MAX_GRID_REACH_M` from every other, a k-d tree; each built on first
/// use.
struct Grid<'a> {
    cloud: &'a [Point3<f64>],
    levels: [Option<Level>; LEVELS],
    tree: Option<Option<ImmutableKdTree<f32, 3>>>,
}

/// A cube of at most this half edge (four of the coarsest grid's cells) is searched in the
/// coarsest grid; beyond, the k-d tree. A point whose nearest neighbour lies tens of metres
/// away is not rare on a street (a facade's upper floors where the other cloud has no
/// return): handing those to the tree built it anew for most scans, and `compare` of the
/// VLS-128 drive took a tenth longer than with the grid reaching this far.
const MAX_GRID_REACH_M: f64 = 97.2;

impl<'a> Grid<'a> {
    fn new(cloud: &'a [Point3<f64>]) -> Grid<'a> {
        Grid {
            cloud,
            levels: [const { None }; LEVELS],
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
            let level = self.level(k);
            let reach = best.0.sqrt().min(0.5 * level.cell);
            level.search(p, reach + pad, pad, &mut best);
            if best.0.sqrt() <= reach {
                return best;
            }
        }
        let r = best.0.sqrt();
        if r <= MAX_GRID_REACH_M {
            self.level(LEVELS - 1).search(p, r + pad, pad, &mut best);
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
            let d2 = dist2(&[q.x, q.y, q.z], p);
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
    //
    // The queries and their twins' bounds are gathered in that order first: in the loop below
    // each query's load from `from` (in firing order) missed the cache and waited behind the
    // search before it, while a loop of loads alone keeps many misses in flight.
    let queries: Vec<(u32, [f64; 3], f64)> = spatial_order(from)
        .into_iter()
        .map(|i| {
            let p = &from[i as usize];
            let q = [p.x, p.y, p.z];
            let bound = twin
                .get(i as usize)
                .and_then(|&t| to.get(t as usize))
                .map_or(f64::INFINITY, |t| dist2(&[t.x, t.y, t.z], &q));
            (i, q, bound)
        })
        .collect();
    for (i, q, mut bound) in queries {
        if let Some(o) = &previous {
            bound = bound.min(dist2(o, &q));
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

    /// A coordinate on a border of the finest grid's cells (`k` cells from `base`) or one to
    /// three ulps to either side of it, where the division in `cell_of` and the border's own
    /// product round either way.
    fn by_a_border(rng: &mut rand_chacha::ChaCha8Rng, base: i64) -> f64 {
        let mut v = (base + rng.random_range(-6i64..6)) as f64 * FINEST_CELL_M;
        let steps = rng.random_range(-3i32..=3);
        for _ in 0..steps.abs() {
            v = if steps > 0 {
                v.next_up()
            } else {
                v.next_down()
            };
        }
        v
    }

    /// No point lies nearer to a query than the gap the search computes to the slab of the
    /// point's own cell: near the origin, 2.5 km from it and on the negative side, on borders
    /// and ulps beside them.
    #[test]
    fn the_gap_to_a_cell_never_exceeds_the_distance_to_its_points() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for base in [0i64, 8333, -8333, 3] {
            for _ in 0..20_000 {
                let (q, v) = (by_a_border(&mut rng, base), by_a_border(&mut rng, base));
                let i = Level::cell_of(FINEST_CELL_M, &[q, 0.0, 0.0])[0];
                let pad = 8.0 * f64::EPSILON * v.abs();
                let d = q - v;
                assert!(
                    slab_gap2(FINEST_CELL_M, i, v, pad) <= d * d,
                    "point {q:e} in cell {i}, query {v:e}"
                );
            }
        }
    }

    /// Points on and ulps beside the finest grid's cell borders, near the origin and 2.5 km
    /// from it: the cells the search passes over as too far never hold the nearest point. The
    /// distances, each of them, are bit for bit the brute-force ones (the same expression: a
    /// skipped nearest point would show as a difference of an ulp or more).
    #[test]
    fn points_on_cell_borders_are_never_passed_over() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        for base in [0i64, 8333, -8333] {
            let mut cloud = |n: usize| -> Vec<Point3<f64>> {
                (0..n)
                    .map(|_| {
                        Point3::new(
                            by_a_border(&mut rng, base),
                            by_a_border(&mut rng, base),
                            by_a_border(&mut rng, 0),
                        )
                    })
                    .collect()
            };
            let (a, b) = (cloud(400), cloud(300));
            let got = nearest(&a, &b, &[]);
            for (p, d) in a.iter().zip(&got) {
                let want = b
                    .iter()
                    .map(|q| dist2(&[q.x, q.y, q.z], &[p.x, p.y, p.z]))
                    .fold(f64::INFINITY, lesser)
                    .sqrt();
                assert_eq!(d.to_bits(), want.to_bits(), "{p}: {d} against {want}");
            }
        }
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

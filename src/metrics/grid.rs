//! Grid metrics (Rosenberger et al. 2019, §5, after the collection of Rosenberger et al. 2018,
//! their ref. [24]): points binned into the cells of a Cartesian grid, a bird's-eye 2D grid or 3D
//! voxels, and the occupancy of the real and the simulated grid compared cell by cell.
//!
//! Occupancy over K consecutive scans (the paper's OCR^K): a cell is occupied, ζ = 1, when it
//! holds points in more than half of the K scans (P(p in c) > 0.5), so noise that lands in a
//! cell once is not counted. With K = 1 a cell is occupied when it holds any point.
//!
//! - OCR^K = Σ ζ(c̃ ∧ c) / Σ ζ(c): the share of the real grid's occupied cells that are occupied
//!   in the simulated grid too (the paper's formula, whose numerator counts the simulated cells
//!   that are "true classified", i.e. occupied in both). Optimum 1.
//! - precision = |both| / |simulated occupied|; recall = |both| / |real occupied| (= OCR);
//!   IoU = |both| / |either|.
//! - cosine similarity of the cells' point counts (summed over the K scans): Σ n_r n_s /
//!   (‖n_r‖ ‖n_s‖), which also weighs how many points each cell holds.

use nalgebra::Point3;

/// Why a grid cannot be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    /// The cell size is not a positive finite length.
    #[error("grid cell {0} m: a cell must be a positive finite length")]
    BadCell(f64),
    /// K is zero.
    #[error("K = 0: occupancy needs at least one scan")]
    NoScans,
}

/// Bird's-eye cells (east, north) or voxels (east, north, up).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Dims {
    /// 2D: cells of the ground plane, every height in one cell.
    Bev,
    /// 3D voxels.
    Voxel,
}

/// Cell size, dimensionality and where the cells' corners lie.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    cell_m: f64,
    dims: Dims,
    /// A corner of a cell, m (the scene origin unless [`GridSpec::shifted`]).
    origin: [f64; 3],
}

/// A cell's integer coordinates (the third is 0 in 2D).
pub type Cell = [i64; 3];

impl GridSpec {
    /// A grid of `cell_m` metre cells.
    pub fn new(cell_m: f64, dims: Dims) -> Result<GridSpec, GridError> {
        if !(cell_m.is_finite() && cell_m > 0.0) {
            return Err(GridError::BadCell(cell_m));
        }
        Ok(GridSpec {
            cell_m,
            dims,
            origin: [0.0; 3],
        })
    }

    /// The same grid moved by `fraction` of a cell along every axis (diagonally).
    ///
    /// Where the cell boundaries fall decides what a grid metric measures as much as the
    /// cell size: a wall that lies on a boundary puts its points on either side at random
    /// (a centimetre of reference error decides), and OCR drops as if the model were wrong,
    /// while half a cell over the same wall fills one row of cells in both clouds. On a
    /// synthesized drive re-simulated with the very model that made it, OCR^1 was 0.55 at a
    /// 1.073 m cell and 0.96 at 1.075 m (a wall 12 cells from the origin). `compare` averages
    /// over several shifted grids for that reason ([`GridScores::mean`]).
    pub fn shifted(self, fraction: f64) -> GridSpec {
        let d = fraction * self.cell_m;
        GridSpec {
            origin: [d; 3],
            ..self
        }
    }

    /// The cell size, m.
    pub fn cell_m(&self) -> f64 {
        self.cell_m
    }

    /// The same grid's cells in the ground plane (bird's-eye), corners where they were.
    pub fn in_plane(self) -> GridSpec {
        GridSpec {
            dims: Dims::Bev,
            ..self
        }
    }

    /// A cell's corner with the smallest coordinates (east, north), m.
    pub fn corner(&self, c: &Cell) -> [f64; 2] {
        [
            self.origin[0] + c[0] as f64 * self.cell_m,
            self.origin[1] + c[1] as f64 * self.cell_m,
        ]
    }

    /// The cell a point falls in (cells are half-open: [o + k c, o + (k + 1) c) with o the
    /// origin).
    pub fn cell(&self, p: &Point3<f64>) -> Cell {
        let inv = 1.0 / self.cell_m;
        let o = &self.origin;
        let k = |v: f64, o: f64| floor_i64((v - o) * inv);
        match self.dims {
            Dims::Bev => [k(p.x, o[0]), k(p.y, o[1]), 0],
            Dims::Voxel => [k(p.x, o[0]), k(p.y, o[1]), k(p.z, o[2])],
        }
    }
}

/// ⌊v⌋ as an integer, without the libm call `f64::floor` compiles to on a baseline x86-64
/// target (a tenth of the binning time). Saturates like `as`; NaN gives 0.
fn floor_i64(v: f64) -> i64 {
    let t = v as i64;
    if (t as f64) > v {
        t - 1
    } else {
        t
    }
}

/// Bits per axis of a packed cell key: cells within ±2²⁰ of the origin (±105 km at 10 cm).
const AXIS_BITS: u32 = 21;
const AXIS_OFFSET: i64 = 1 << (AXIS_BITS - 1);
const AXIS_MASK: u64 = (1 << AXIS_BITS) - 1;

/// A cell as one sortable integer (the grid is binned by sorting keys, not hashing them: a
/// 100 k-point scan sorts in about a millisecond).
fn pack(c: Cell) -> u64 {
    // Saturating: a point at infinity has a cell at i64::MAX (found by the binning test in a
    // debug build); it lands in the edge cell like any point beyond ±105 km.
    let f = |v: i64| (v.saturating_add(AXIS_OFFSET).clamp(0, AXIS_MASK as i64) as u64) & AXIS_MASK;
    (f(c[0]) << (2 * AXIS_BITS)) | (f(c[1]) << AXIS_BITS) | f(c[2])
}

/// The smallest cell whose grid holds every point within `reach_m` of the scene origin (along
/// each axis) without clamping a cell index to the edge of the key's range (±2²⁰ cells, a
/// cell to spare for the shifted grids): below it, distinct cells far out would merge and the
/// metrics would be wrong without a sign.
pub fn smallest_cell_m(reach_m: f64) -> f64 {
    reach_m / (AXIS_OFFSET - 2) as f64
}

/// Whether `pack` keeps the cell as it is (no axis clamped to the edge).
fn in_pack_range(c: &Cell) -> bool {
    c.iter().all(|&v| (-AXIS_OFFSET..AXIS_OFFSET).contains(&v))
}

fn unpack(k: u64) -> Cell {
    let f = |v: u64| (v & AXIS_MASK) as i64 - AXIS_OFFSET;
    [f(k >> (2 * AXIS_BITS)), f(k >> AXIS_BITS), f(k)]
}

/// A scan's (or K scans') hit cells: their packed keys, sorted, and the points in each, as two
/// parallel lists (the merges that compare two grids walk the keys alone; a list of
/// (key, count) pairs would drag the counts and the padding along, 16 bytes a cell instead of 8).
#[derive(Clone, Debug, Default, PartialEq)]
struct Hits {
    keys: Vec<u64>,
    counts: Vec<u32>,
}

/// Reused buffers for binning scans.
#[derive(Default)]
struct Scratch {
    wide: Vec<u64>,
    narrow: Vec<u32>,
}

thread_local! {
    /// Each thread's binning buffers, kept between scans: a scan's keys are larger than the
    /// allocator's mmap threshold, so fresh buffers would be mapped, faulted in page by page
    /// and unmapped again for every scan.
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// The distinct keys of a sorted list and how often each occurs, written in place over the
/// list's front (`sorted` keeps the distinct keys, truncated) with the counts returned.
/// Branch-free: whether the next key starts a new cell is as good as random on a scan's keys,
/// and a branch on it is mispredicted about every other point.
fn count_runs<K: Copy + PartialEq>(sorted: &mut Vec<K>) -> Vec<u32> {
    let Some(&first) = sorted.first() else {
        return Vec::new();
    };
    let n = sorted.len();
    let mut counts = vec![0u32; n];
    let (mut j, mut prev) = (0usize, first);
    for i in 0..n {
        let k = sorted[i];
        j += usize::from(k != prev);
        prev = k;
        sorted[j] = k;
        counts[j] += 1;
    }
    sorted.truncate(j + 1);
    counts.truncate(j + 1);
    counts
}

impl Scratch {
    /// One scan's hit cells, sorted by packed key, with their point counts.
    ///
    /// Sorting is the cost. A scan spans a few hundred cells per axis, so its cells are
    /// first numbered relative to its own bounding box in one 32-bit key when they fit (half
    /// the radix passes of the 64-bit key), counted, and only the distinct cells are packed
    /// into the grid-wide key afterwards. Both numberings order cells the same way (x, then y,
    /// then z), so the cells come out sorted by the grid-wide key either way.
    fn hits(&mut self, spec: &GridSpec, scan: &[Point3<f64>]) -> Hits {
        let Some(first) = scan.first() else {
            return Hits::default();
        };
        let (mut lo, mut hi) = (*first, *first);
        let mut finite = true;
        for p in scan {
            lo = lo.inf(p);
            hi = hi.sup(p);
            finite &= p.x.is_finite() && p.y.is_finite() && p.z.is_finite();
        }
        let (c0, c1) = (spec.cell(&lo), spec.cell(&hi));
        let bits: [u32; 3] =
            std::array::from_fn(|i| 64 - (c1[i].wrapping_sub(c0[i]) as u64).leading_zeros());
        if finite && bits.iter().sum::<u32>() <= 32 {
            let (shift_x, shift_y) = (bits[1] + bits[2], bits[2]);
            self.narrow.clear();
            self.narrow.extend(scan.iter().map(|p| {
                let c = spec.cell(p);
                let r = |i: usize| (c[i] - c0[i]) as u64;
                ((r(0) << shift_x) | (r(1) << shift_y) | r(2)) as u32
            }));
            // Radix sort (`radsort`: stable, allocation-light, several times faster than a
            // comparison sort on 100 k integer keys; a hand-written three-pass sort of 9-bit
            // digits for these narrow keys measured no faster).
            radsort::sort(&mut self.narrow);
            let counts = count_runs(&mut self.narrow);
            let field = |k: u64, shift: u32, b: u32| (k >> shift) & ((1u64 << b) - 1);
            let keys = if in_pack_range(&c0) && in_pack_range(&c1) {
                // Every cell of the box packs without clamping, so a cell's key is the box
                // corner's key plus its offsets in their fields (no carry crosses a field).
                let base = pack(c0);
                self.narrow
                    .iter()
                    .map(|&k| {
                        let k = u64::from(k);
                        base + (field(k, shift_x, bits[0]) << (2 * AXIS_BITS))
                            + (field(k, shift_y, bits[1]) << AXIS_BITS)
                            + field(k, 0, bits[2])
                    })
                    .collect()
            } else {
                self.narrow
                    .iter()
                    .map(|&k| {
                        let k = u64::from(k);
                        let f = |shift, b| field(k, shift, b) as i64;
                        pack([
                            c0[0] + f(shift_x, bits[0]),
                            c0[1] + f(shift_y, bits[1]),
                            c0[2] + f(0, bits[2]),
                        ])
                    })
                    .collect()
            };
            Hits { keys, counts }
        } else {
            self.wide.clear();
            self.wide.extend(scan.iter().map(|p| pack(spec.cell(p))));
            // Radix sort (`radsort`: stable, allocation-light, several times faster than a
            // comparison sort on 100 k integer keys).
            radsort::sort(&mut self.wide);
            let counts = count_runs(&mut self.wide);
            Hits {
                keys: self.wide.clone(),
                counts,
            }
        }
    }
}

/// The occupancy of K scans: which cells are occupied, and every hit cell's point count.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Occupancy {
    /// Occupied cells (more than half of the K scans hit them), as sorted keys; `None` when
    /// every hit cell is occupied (K = 1), which then are the keys of `hits` (not copied:
    /// a scan's cells are most of the work of an OCR).
    occupied: Option<Vec<u64>>,
    /// Every hit cell with its points over all K scans.
    hits: Hits,
}

impl Occupancy {
    /// Bins `scans` (K of them) into `spec`'s cells.
    pub fn of(spec: &GridSpec, scans: &[&[Point3<f64>]]) -> Result<Occupancy, GridError> {
        let k = scans.len();
        if k == 0 {
            return Err(GridError::NoScans);
        }
        // Per scan: its cells' keys, sorted, with their point counts.
        let mut per_scan: Vec<Hits> = Vec::with_capacity(k);
        SCRATCH.with_borrow_mut(|scratch| {
            for scan in scans {
                per_scan.push(scratch.hits(spec, scan));
            }
        });
        if k == 1 {
            return Ok(Occupancy {
                occupied: None,
                hits: per_scan.pop().unwrap_or_default(),
            });
        }
        // Merged over the scans: points, and in how many scans each cell was hit.
        let mut all: Vec<(u64, u32, u32)> = per_scan
            .iter()
            .flat_map(|h| h.keys.iter().zip(&h.counts).map(|(&key, &n)| (key, n, 1)))
            .collect();
        radsort::sort_by_key(&mut all, |e| e.0);
        let mut merged: Vec<(u64, u32, u32)> = Vec::with_capacity(all.len());
        for e in all {
            match merged.last_mut() {
                Some(m) if m.0 == e.0 => {
                    m.1 += e.1;
                    m.2 += 1;
                }
                _ => merged.push(e),
            }
        }
        Ok(Occupancy {
            occupied: Some(
                merged
                    .iter()
                    .filter(|e| 2 * e.2 as usize > k)
                    .map(|e| e.0)
                    .collect(),
            ),
            hits: Hits {
                keys: merged.iter().map(|e| e.0).collect(),
                counts: merged.iter().map(|e| e.1).collect(),
            },
        })
    }

    /// The occupied cells, sorted.
    pub fn occupied(&self) -> Vec<Cell> {
        self.occupied_keys().iter().map(|&k| unpack(k)).collect()
    }

    /// The occupied cells' keys, sorted.
    fn occupied_keys(&self) -> &[u64] {
        self.occupied.as_deref().unwrap_or(&self.hits.keys)
    }

    /// Points in `cell` over the K scans.
    pub fn count(&self, cell: Cell) -> u32 {
        self.hits
            .keys
            .binary_search(&pack(cell))
            .map_or(0, |i| self.hits.counts[i])
    }
}

/// The cell-wise comparison of a real and a simulated occupancy. Ratios are `None` when their
/// denominator is empty (no real cell: OCR is undefined, not 0 or 1).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GridScores {
    /// OCR^K = |both| / |real|.
    pub ocr: Option<f64>,
    /// |both| / |simulated|.
    pub precision: Option<f64>,
    /// |both| / |either|.
    pub iou: Option<f64>,
    /// Cosine similarity of the point counts per cell.
    pub cosine: Option<f64>,
    /// Occupied cells: real, simulated, both.
    pub real_cells: usize,
    /// Simulated occupied cells.
    pub sim_cells: usize,
    /// Cells occupied in both.
    pub both_cells: usize,
}

impl GridScores {
    /// The mean of several grids' scores (the same clouds on shifted grids): each ratio the
    /// mean of the grids where it is defined, cell counts rounded means. `None` for no grids.
    pub fn mean(all: &[GridScores]) -> Option<GridScores> {
        if all.is_empty() {
            return None;
        }
        let avg = |f: fn(&GridScores) -> Option<f64>| {
            let v: Vec<f64> = all.iter().filter_map(f).collect();
            (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
        };
        let count = |f: fn(&GridScores) -> usize| {
            (all.iter().map(f).sum::<usize>() as f64 / all.len() as f64).round() as usize
        };
        Some(GridScores {
            ocr: avg(|g| g.ocr),
            precision: avg(|g| g.precision),
            iou: avg(|g| g.iou),
            cosine: avg(|g| g.cosine),
            real_cells: count(|g| g.real_cells),
            sim_cells: count(|g| g.sim_cells),
            both_cells: count(|g| g.both_cells),
        })
    }
}

/// How many keys two sorted lists of distinct keys share. Branch-free: on two scans' cells the
/// comparison goes either way at random, and a branch per step would be mispredicted about
/// every other time (a fifth of the OCR's time before this).
fn shared(a: &[u64], b: &[u64]) -> usize {
    let (mut i, mut j, mut n) = (0, 0, 0);
    while i < a.len() && j < b.len() {
        let (x, y) = (a[i], b[j]);
        n += usize::from(x == y);
        i += usize::from(x <= y);
        j += usize::from(y <= x);
    }
    n
}

/// The cells two grids' hits share, and Σ n_a n_b over them (branch-free like [`shared`]).
fn shared_counts(a: &Hits, b: &Hits) -> (usize, f64) {
    let (ak, bk) = (a.keys.as_slice(), b.keys.as_slice());
    let (mut i, mut j, mut n, mut dot) = (0, 0, 0, 0u64);
    while i < ak.len() && j < bk.len() {
        let (x, y) = (ak[i], bk[j]);
        let eq = x == y;
        n += usize::from(eq);
        dot += u64::from(eq) * u64::from(a.counts[i]) * u64::from(b.counts[j]);
        i += usize::from(x <= y);
        j += usize::from(y <= x);
    }
    (n, dot as f64)
}

/// Compares the occupancy of the real grid with the simulated one.
pub fn compare(real: &Occupancy, sim: &Occupancy) -> GridScores {
    let (hit_both, dot) = shared_counts(&real.hits, &sim.hits);
    let both = match (&real.occupied, &sim.occupied) {
        (None, None) => hit_both,
        _ => shared(real.occupied_keys(), sim.occupied_keys()),
    };
    let (r, s) = (real.occupied_keys().len(), sim.occupied_keys().len());
    let ratio = |n: usize, d: usize| (d > 0).then(|| n as f64 / d as f64);
    let norm = |o: &Occupancy| {
        o.hits
            .counts
            .iter()
            .map(|&n| f64::from(n).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let (nr, ns) = (norm(real), norm(sim));
    GridScores {
        ocr: ratio(both, r),
        precision: ratio(both, s),
        iou: ratio(both, r + s - both),
        cosine: (nr > 0.0 && ns > 0.0).then(|| dot / (nr * ns)),
        real_cells: r,
        sim_cells: s,
        both_cells: both,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new(x, y, z)
    }

    /// The hand-computed case: real points in cells (0,0), (1,0), (2,0), (2,1) of a 1 m grid,
    /// simulated ones in (0,0), (2,0) twice and (5,5); heights 0 to 9 m.
    fn hand_case(g: &GridSpec) -> (Occupancy, Occupancy) {
        let real = vec![
            p(0.5, 0.5, 0.0),
            p(1.5, 0.2, 3.0),
            p(2.1, 0.9, 0.0),
            p(2.9, 1.1, 0.0),
        ];
        let sim = vec![
            p(0.1, 0.1, 9.0),
            p(2.5, 0.5, 0.0),
            p(2.6, 0.4, 1.0),
            p(5.5, 5.5, 0.0),
        ];
        (occ(g, &[real]), occ(g, &[sim]))
    }

    fn occ(spec: &GridSpec, scans: &[Vec<Point3<f64>>]) -> Occupancy {
        let refs: Vec<&[Point3<f64>]> = scans.iter().map(|s| s.as_slice()).collect();
        Occupancy::of(spec, &refs).unwrap()
    }

    /// A wall on a cell boundary: measured a centimetre in front of it and simulated a
    /// centimetre behind it, the grid at the origin puts the two in different cells (OCR 0);
    /// the grids shifted by a quarter, a half and three quarters of a cell hold both in one
    /// (OCR 1), and the mean over the four is 3/4.
    #[test]
    fn a_wall_on_a_cell_boundary_and_the_shifted_grid() {
        // A wall at x = 2 m (a boundary of the 1 m grid), points 10 cm apart along y and z.
        let wall = |x: f64| -> Vec<Point3<f64>> {
            (0..400)
                .map(|i| p(x, f64::from(i % 20) * 0.1, f64::from(i / 20) * 0.1))
                .collect()
        };
        let (real, sim) = (wall(2.01), wall(1.99));
        let g = GridSpec::new(1.0, Dims::Voxel).unwrap();
        let at = |g: &GridSpec| {
            compare(
                &occ(g, std::slice::from_ref(&real)),
                &occ(g, std::slice::from_ref(&sim)),
            )
        };
        assert_eq!(at(&g).ocr, Some(0.0));
        let all: Vec<GridScores> = (0..4).map(|j| at(&g.shifted(f64::from(j) / 4.0))).collect();
        assert_eq!(
            all.iter().map(|s| s.ocr.unwrap()).collect::<Vec<_>>(),
            [0.0, 1.0, 1.0, 1.0]
        );
        let m = GridScores::mean(&all).unwrap();
        // Cells: 2 x 2 along y and z at the origin, 3 x 3 shifted; counts are rounded means.
        assert_eq!((m.ocr, m.real_cells, m.both_cells), (Some(0.75), 8, 7));
        // The corner moves with the shift: 0.2 m lies below a corner at 0.25 m.
        assert_eq!(g.shifted(0.25).cell(&p(0.2, 0.3, 0.26)), [-1, 0, 0]);
        assert_eq!(GridScores::mean(&[]), None);
    }

    /// A cell's corner is where its points begin, on a shifted grid too, and the cell size
    /// is the one asked for.
    #[test]
    fn a_cells_corner_is_where_its_points_begin() {
        let g = GridSpec::new(0.5, Dims::Bev).unwrap().shifted(0.25);
        assert_eq!(g.cell_m(), 0.5);
        for q in [p(1.7, -0.9, 4.0), p(-3.1, 12.4, 0.0), p(0.125, 0.125, 0.0)] {
            let c = g.cell(&q);
            let [x, y] = g.corner(&c);
            assert!(
                (x..x + 0.5).contains(&q.x) && (y..y + 0.5).contains(&q.y),
                "{q:?} is in cell {c:?}, whose corner is ({x}, {y})"
            );
        }
        assert_eq!(g.corner(&[3, -2, 0]), [1.625, -0.875]);
        // The same voxels seen from above: every height in one cell, corners where they were.
        let v = GridSpec::new(0.5, Dims::Voxel).unwrap().shifted(0.25);
        assert_eq!(v.cell(&p(1.7, -0.9, 4.0)), [3, -3, 7]);
        assert_eq!(v.in_plane().cell(&p(1.7, -0.9, 4.0)), [3, -3, 0]);
    }

    /// Shared keys of two sorted lists, whichever runs out first.
    #[test]
    fn shared_counts_common_keys_whichever_list_ends_first() {
        assert_eq!(shared(&[1, 2], &[2, 3, 4]), 1);
        assert_eq!(shared(&[2, 3, 4], &[1, 2]), 1);
        assert_eq!(shared(&[1, 3, 5, 7], &[0, 3, 4, 5, 9]), 2);
        assert_eq!(shared(&[], &[1]), 0);
        assert_eq!(shared(&[5, 6], &[5, 6]), 2);
    }

    /// Worked by hand with 1 m cells: real points in cells (0,0), (1,0), (2,0) and (2,1);
    /// simulated in (0,0), (2,0) (two points) and (5,5). Both: 2 of 4 real cells, OCR 1/2;
    /// precision 2/3; IoU 2/5. Counts: real (1,1,1,1), simulated (1,0,2,0) plus (5,5): 1, so
    /// cosine = (1 + 2) / (2 · √6).
    #[test]
    fn ocr_precision_iou_and_cosine_of_a_hand_computed_2d_case() {
        let g = GridSpec::new(1.0, Dims::Bev).unwrap();
        let (real, sim) = hand_case(&g);
        let s = compare(&real, &sim);
        assert_eq!((s.real_cells, s.sim_cells, s.both_cells), (4, 3, 2));
        assert_eq!(s.ocr, Some(0.5));
        assert_eq!(s.precision, Some(2.0 / 3.0));
        assert_eq!(s.iou, Some(0.4));
        assert!((s.cosine.unwrap() - 3.0 / (2.0 * 6f64.sqrt())).abs() < 1e-12);
    }

    /// The same points as voxels: heights now separate cells. Real (0,0,0), (1,0,3), (2,0,0),
    /// (2,1,0); simulated (0,0,9), (2,0,0), (2,0,1), (5,5,0): only (2,0,0) is in both.
    #[test]
    fn voxels_separate_heights() {
        let g = GridSpec::new(1.0, Dims::Voxel).unwrap();
        let (real, sim) = hand_case(&g);
        let s = compare(&real, &sim);
        assert_eq!((s.real_cells, s.sim_cells, s.both_cells), (4, 4, 1));
        assert_eq!(s.ocr, Some(0.25));
    }

    /// K = 3: a cell is occupied when hit in at least 2 of the 3 scans (more than half), however
    /// many points one scan puts into it.
    #[test]
    fn k_scans_need_more_than_half_of_them() {
        let g = GridSpec::new(1.0, Dims::Bev).unwrap();
        let a = p(0.5, 0.5, 0.0); // cell (0,0): scans 1, 2, 3
        let b = p(1.5, 0.5, 0.0); // cell (1,0): scans 1, 3
        let c = p(2.5, 0.5, 0.0); // cell (2,0): scan 2 only, ten points
        let scans = vec![
            vec![a, b],
            vec![a, c, c, c, c, c, c, c, c, c, c],
            vec![a, b],
        ];
        let o = occ(&g, &scans);
        assert_eq!(o.occupied(), vec![[0, 0, 0], [1, 0, 0]]);
        assert_eq!(o.count([2, 0, 0]), 10);
        assert_eq!(o.count([0, 0, 0]), 3);
        // K = 2 needs both scans (1 of 2 is not more than half).
        let o2 = occ(&g, &scans[..2]);
        assert_eq!(o2.occupied(), vec![[0, 0, 0]]);
    }

    /// OCR(x, x) = 1; shifted along a wall by 0, 1, 2, 3 cells, a cloud's OCR against itself
    /// falls monotonically (the wall's ends leave their cells); one cell across the wall, nothing
    /// overlaps.
    #[test]
    fn ocr_of_a_cloud_with_itself_is_one_and_falls_as_it_is_shifted() {
        let g = GridSpec::new(0.1, Dims::Voxel).unwrap();
        // A wall 2 m wide and 1 m high at x = 5, 5 cm spacing.
        let mut cloud = Vec::new();
        for i in 0..40 {
            for j in 0..20 {
                cloud.push(p(
                    5.0123,
                    -1.0 + 0.0123 + i as f64 * 0.05,
                    0.0123 + j as f64 * 0.05,
                ));
            }
        }
        let real = occ(&g, &[cloud.clone()]);
        assert_eq!(compare(&real, &real).ocr, Some(1.0));
        let shifted = |dx: f64, dy: f64| {
            let moved: Vec<Point3<f64>> =
                cloud.iter().map(|q| p(q.x + dx, q.y + dy, q.z)).collect();
            compare(&real, &occ(&g, &[moved])).ocr.unwrap()
        };
        let along: Vec<f64> = (0..=3).map(|k| shifted(0.0, 0.1 * k as f64)).collect();
        assert_eq!(along[0], 1.0);
        for w in along.windows(2) {
            assert!(w[1] < w[0], "{along:?}");
        }
        assert!((along[3] - 17.0 / 20.0).abs() < 1e-9, "{along:?}");
        assert_eq!(shifted(0.1, 0.0), 0.0);
    }

    #[test]
    fn empty_real_grids_have_no_ocr_and_bad_cells_are_refused() {
        let g = GridSpec::new(1.0, Dims::Bev).unwrap();
        let s = compare(&occ(&g, &[vec![]]), &occ(&g, &[vec![p(0.0, 0.0, 0.0)]]));
        assert_eq!((s.ocr, s.precision, s.iou), (None, Some(0.0), Some(0.0)));
        for bad in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            assert!(GridSpec::new(bad, Dims::Voxel).is_err(), "{bad}");
        }
        assert_eq!(Occupancy::of(&g, &[]), Err(GridError::NoScans));
    }

    /// Packing keeps a cell's identity and the order of cells, negative ones included.
    #[test]
    fn packed_keys_round_trip_and_sort_like_cells() {
        let cells: Vec<Cell> = vec![
            [-5, 3, -1],
            [-5, 3, 0],
            [0, 0, 0],
            [7, -2, 9],
            [1_000_000, -1_000_000, 3],
        ];
        for c in &cells {
            assert_eq!(unpack(pack(*c)), *c);
        }
        for w in cells.windows(2) {
            assert!(pack(w[0]) < pack(w[1]), "{w:?}");
        }
    }

    /// Binning through the scan-relative 32-bit key and through the grid-wide key give the
    /// same cells and counts as counting cells in a map ([`GridSpec::cell`] point by point),
    /// for small scans, scans too wide for 32 bits, negative coordinates, shifted grids,
    /// points exactly on cell boundaries, a scan far from the origin, one beyond the packed
    /// keys' range (clamped to the edge cells) and a point at infinity.
    #[test]
    fn binning_equals_a_map_of_cells_for_narrow_and_wide_scans() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for (extent, centre, cell, dims, shift) in [
            (30.0, 0.0, 0.1, Dims::Voxel, 0.0),
            (30.0, 0.0, 0.1, Dims::Voxel, 0.37),
            (30.0, 0.0, 0.05, Dims::Bev, 0.0),
            (30.0, -7.3, 1.047, Dims::Bev, 0.618),
            (3000.0, 0.0, 0.05, Dims::Voxel, 0.0),
            (0.01, 0.0, 1.0, Dims::Voxel, 0.0),
            (40.0, 80_000.0, 0.1, Dims::Voxel, 0.25),
            (40.0, 104_850.0, 0.1, Dims::Voxel, 0.0),
        ] {
            let g = GridSpec::new(cell, dims).unwrap().shifted(shift);
            let mut scan: Vec<Point3<f64>> = (0..5000)
                .map(|_| {
                    let mut c = || centre + rng.random_range(-extent..extent);
                    p(c(), c(), c() / 10.0)
                })
                .collect();
            // On the boundaries: corners of cells, as a grid would put them.
            for _ in 0..500 {
                let mut b = |axis: usize| {
                    let k: i64 = rng.random_range(-300..300);
                    g.origin[axis] + (k + (centre / cell) as i64) as f64 * cell
                };
                scan.push(p(b(0), b(1), b(2)));
            }
            for with_infinity in [false, true] {
                if with_infinity {
                    scan.push(p(f64::INFINITY, 0.0, 0.0));
                }
                let mut want = std::collections::BTreeMap::new();
                for q in &scan {
                    *want.entry(pack(g.cell(q))).or_insert(0u32) += 1;
                }
                let got = Scratch::default().hits(&g, &scan);
                assert_eq!(
                    got.keys.into_iter().zip(got.counts).collect::<Vec<_>>(),
                    want.into_iter().collect::<Vec<_>>(),
                    "{extent} {cell} {dims:?}"
                );
            }
        }
    }
}

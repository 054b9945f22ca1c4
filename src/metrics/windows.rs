//! The occupancy grids of windows of K consecutive scans as the drive streams by: where each
//! window's grids lie, their scores, and the calibration curve's running sums.

use super::grid::{compare as grid_compare, Dims, GridScores, GridSpec, Occupancy};
use super::report::{CurvePoint, ScanRow};
use crate::scene::pose::Trajectory;
use nalgebra::Point3;
use rayon::prelude::*;

/// Cell sizes of the calibration curve, m.
pub const CURVE_CELLS_M: [f64; 9] = [0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0];

/// Where the j-th of the `phases` grids of the window ending at scan `i` lies, as a fraction
/// of a cell from the scene origin along every axis: (j + u_i) / N, with u_i = frac(½ + i/φ)
/// (the golden-ratio sequence). A window's N grids are spread evenly over a cell, and from
/// window to window the spread moves on, so that a drive's mean is taken over N times its
/// scans' placements, as if the grid had been put down at random; no placement is favoured,
/// in particular not the origin, where man-made scenes put their walls on round coordinates
/// and round cell sizes would put the boundaries.
pub(super) fn grid_phase(i: usize, j: usize, phases: usize) -> f64 {
    const INV_GOLDEN: f64 = 0.618_033_988_749_894_9;
    let u = (0.5 + i as f64 * INV_GOLDEN).fract();
    (j as f64 + u) / phases.max(1) as f64
}

/// A scan's points in the region, measured and simulated.
pub(super) type PointPair = (Vec<Point3<f64>>, Vec<Point3<f64>>);

/// The measured and the simulated point lists of consecutive scans.
pub(super) type Clouds<'a> = (&'a [&'a [Point3<f64>]], &'a [&'a [Point3<f64>]]);

/// The occupancy grids' scores of the window of K scans ending at each scan of `ends` (indices
/// into `real` and `sim`, which hold at least the K - 1 scans before the first), averaged over
/// `phases` shifted grids ([`grid_phase`]); `first` is the drive-wide index of `real[0]`.
pub(super) fn windows(
    spec: &GridSpec,
    phases: usize,
    k: usize,
    (real, sim): Clouds<'_>,
    first: usize,
    ends: impl IntoIterator<Item = usize>,
) -> Vec<Option<GridScores>> {
    let ends: Vec<usize> = ends.into_iter().collect();
    ends.into_par_iter()
        .map(|i| {
            let drive_index = first + i;
            if drive_index + 1 < k || i + 1 < k {
                return None;
            }
            let (r, s) = (&real[i + 1 - k..=i], &sim[i + 1 - k..=i]);
            let scores = (0..phases.max(1))
                .map(|j| {
                    let g = spec.shifted(grid_phase(drive_index, j, phases));
                    Some(grid_compare(
                        &Occupancy::of(&g, r).ok()?,
                        &Occupancy::of(&g, s).ok()?,
                    ))
                })
                .collect::<Option<Vec<GridScores>>>()?;
            GridScores::mean(&scores)
        })
        .collect()
}

/// The calibration curve's cells other than the chosen one, with their running OCR sums (one
/// grid per window each, summed in scan order).
pub(super) struct CurveSums {
    cells: Vec<f64>,
    others: Vec<(f64, GridSpec, f64, usize)>,
}

impl CurveSums {
    pub(super) fn new(cell: f64, admissible: f64, dims: Dims) -> CurveSums {
        let mut cells: Vec<f64> = CURVE_CELLS_M.to_vec();
        cells.extend([cell, admissible]);
        cells.sort_by(f64::total_cmp);
        cells.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        let others = cells
            .iter()
            .filter(|c| (**c - cell).abs() >= 1e-9)
            .filter_map(|&c| Some((c, GridSpec::new(c, dims).ok()?, 0.0, 0)))
            .collect();
        CurveSums { cells, others }
    }

    /// Adds the windows ending at `ends` (see [`windows`]) whose drive-wide index is a
    /// multiple of `every` (none for 0).
    pub(super) fn add(
        &mut self,
        (k, every): (usize, usize),
        clouds: Clouds<'_>,
        first: usize,
        ends: &std::ops::Range<usize>,
    ) {
        if every == 0 {
            return;
        }
        let sampled: Vec<usize> = ends
            .clone()
            .filter(|i| (first + i).is_multiple_of(every))
            .collect();
        if sampled.is_empty() {
            return;
        }
        let curve: Vec<Vec<Option<GridScores>>> = self
            .others
            .par_iter()
            .map(|(_, g, _, _)| windows(g, 1, k, clouds, first, sampled.iter().copied()))
            .collect();
        for (o, w) in self.others.iter_mut().zip(&curve) {
            for v in w.iter().flatten().filter_map(|g| g.ocr) {
                o.2 += v;
                o.3 += 1;
            }
        }
    }

    /// Mean OCR^K over the scans at each cell size of [`CURVE_CELLS_M`], the admissible and the
    /// chosen cell. The curve holds drive means only, and those need one grid per window (the
    /// placements move on from window to window, [`grid_phase`]); the chosen cell's point is
    /// the mean of the rows' scores, so that it equals the summary's.
    pub(super) fn points(&self, rows: &[ScanRow], cell: f64, admissible: f64) -> Vec<CurvePoint> {
        self.cells
            .iter()
            .map(|&c| CurvePoint {
                cell_m: c,
                ocr_mean: if (c - cell).abs() < 1e-9 {
                    mean(rows.iter().filter_map(|r| r.grid.and_then(|g| g.ocr)))
                } else {
                    self.others
                        .iter()
                        .find(|o| o.0 == c)
                        .and_then(|o| (o.3 > 0).then(|| o.2 / o.3 as f64))
                },
                admissible: c >= admissible - 1e-9,
            })
            .collect()
    }
}

fn mean(v: impl Iterator<Item = f64>) -> Option<f64> {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| s / n as f64)
}

/// The farthest any supported sensor reports a return: 65535 counts of 4 mm (262 m), rounded up.
const SENSOR_REACH_M: f64 = 300.0;

/// Refuses a cell so small that the grid's cell indices would clamp somewhere the drive's points
/// can lie (the trajectory's farthest position from the scene origin, plus the sensor's reach;
/// in the sensor frame the reach alone), naming the smallest cell this drive allows.
pub(super) fn refuse_clamping_cell(
    cell: f64,
    trajectory: &Trajectory,
    sensor_frame: bool,
) -> Result<(), String> {
    let farthest = if sensor_frame {
        0.0
    } else {
        trajectory
            .samples()
            .iter()
            .map(|s| s.position.amax())
            .fold(0.0, f64::max)
    };
    let reach = farthest + SENSOR_REACH_M;
    let smallest = super::grid::smallest_cell_m(reach);
    if cell < smallest {
        return Err(format!(
            "--cell {cell:e}: the grid's cell indices would be clamped (at most 2^20 cells either side of the origin; points here reach {reach:.0} m from it): the smallest cell for this drive is {smallest:.2e} m"
        ));
    }
    Ok(())
}

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
) -> Result<(), super::error::CompareError> {
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
        return Err(super::error::CompareError::CellClamped {
            cell,
            reach,
            smallest,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::grid::{smallest_cell_m, GridScores};
    use crate::scene::pose::PoseSample;
    use hilrig_stamp::UtcNanos;
    use nalgebra::Vector3;

    /// A window's grids lie evenly over one cell, a cell apart divided by their number, and
    /// move on by the golden ratio from window to window.
    #[test]
    fn a_windows_grids_are_spread_evenly_over_a_cell() {
        for n in [1, 2, 4, 5] {
            for i in 0..50 {
                let mut v: Vec<f64> = (0..n).map(|j| grid_phase(i, j, n)).collect();
                v.sort_by(f64::total_cmp);
                let u = (0.5 + i as f64 * 0.618_033_988_749_894_9).fract();
                assert!(
                    (v[0] - u / n as f64).abs() < 1e-12,
                    "window {i}, {n}: {v:?}"
                );
                assert!(v.iter().all(|x| (0.0..1.0).contains(x)), "{v:?}");
                for w in v.windows(2) {
                    assert!((w[1] - w[0] - 1.0 / n as f64).abs() < 1e-12, "{v:?}");
                }
            }
        }
    }

    fn scans(n: usize) -> Vec<Vec<Point3<f64>>> {
        (0..n)
            .map(|s| {
                (0..200)
                    .map(|i| {
                        let f = f64::from(i);
                        Point3::new(5.0 + 0.03 * f, s as f64 + (0.37 * f).sin(), 0.01 * f)
                    })
                    .collect()
            })
            .collect()
    }

    /// A window needs K scans: the first K - 1 of the drive have none, and neither has a scan
    /// whose predecessors are not in the batch; a cloud against itself has an OCR of 1.
    #[test]
    fn a_window_needs_k_scans_of_the_drive_and_of_the_batch() {
        let clouds = scans(4);
        let refs: Vec<&[Point3<f64>]> = clouds.iter().map(Vec::as_slice).collect();
        let spec = GridSpec::new(0.2, Dims::Voxel).unwrap();
        let ocr = |k: usize, first: usize| -> Vec<Option<f64>> {
            windows(&spec, 2, k, (&refs, &refs), first, 0..4)
                .iter()
                .map(|g| g.and_then(|g| g.ocr))
                .collect()
        };
        assert_eq!(ocr(1, 0), [Some(1.0); 4]);
        assert_eq!(ocr(2, 0), [None, Some(1.0), Some(1.0), Some(1.0)]);
        assert_eq!(ocr(3, 0), [None, None, Some(1.0), Some(1.0)]);
        // Scans 10.. of a drive: the batch holds no scan before its first.
        assert_eq!(ocr(2, 10), [None, Some(1.0), Some(1.0), Some(1.0)]);
    }

    fn row(ocr: f64) -> ScanRow {
        ScanRow {
            grid: Some(GridScores {
                ocr: Some(ocr),
                precision: None,
                iou: None,
                cosine: None,
                real_cells: 1,
                sim_cells: 1,
                both_cells: 1,
            }),
            ..ScanRow::default()
        }
    }

    /// The calibration curve: every cell of the list, the chosen and the admissible one among
    /// them; the chosen cell's point is the rows' mean, the others from the sampled windows
    /// (a cloud against a copy of itself: 1 at every cell).
    #[test]
    fn the_curve_holds_every_cell_and_the_chosen_one_is_the_rows_mean() {
        let clouds = scans(6);
        let refs: Vec<&[Point3<f64>]> = clouds.iter().map(Vec::as_slice).collect();
        let mut curve = CurveSums::new(0.3, 0.25, Dims::Voxel);
        curve.add((1, 2), (&refs, &refs), 0, &(0..6));
        let points = curve.points(&[row(0.8), row(0.6)], 0.3, 0.25);
        let cells: Vec<f64> = points.iter().map(|p| p.cell_m).collect();
        assert_eq!(
            cells,
            [0.05, 0.1, 0.2, 0.25, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0],
            "the list, the admissible and the chosen cell, in order"
        );
        for p in &points {
            let want = if p.cell_m == 0.3 { 0.7 } else { 1.0 };
            let got = p.ocr_mean.expect("every cell has a point");
            assert!((got - want).abs() < 1e-12, "{p:?}, want {want}");
            assert_eq!(p.admissible, p.cell_m >= 0.25, "{p:?}");
        }
        // No sampled window (every 0): only the chosen cell has a point.
        let mut none = CurveSums::new(0.3, 0.25, Dims::Voxel);
        none.add((1, 0), (&refs, &refs), 0, &(0..6));
        let points = none.points(&[row(0.5)], 0.3, 0.25);
        assert_eq!(points.iter().filter(|p| p.ocr_mean.is_some()).count(), 1);
    }

    /// The smallest cell `compare` names is accepted, anything below it refused; in the sensor
    /// frame the reach alone counts.
    #[test]
    fn the_smallest_cell_named_is_the_smallest_accepted() {
        let at = |t: i64, x: f64, y: f64| PoseSample {
            t: UtcNanos(t),
            position: Vector3::new(x, y, 3.0),
            yaw: 0.0,
            pitch: 0.0,
            roll: 0.0,
        };
        let trajectory = Trajectory::new(vec![at(0, 100.0, 20.0), at(1, 40.0, -250.0)]).unwrap();
        let smallest = smallest_cell_m(250.0 + SENSOR_REACH_M);
        assert!(refuse_clamping_cell(smallest, &trajectory, false).is_ok());
        let below = refuse_clamping_cell(smallest * 0.999, &trajectory, false)
            .unwrap_err()
            .to_string();
        assert!(
            below.contains(&format!("{smallest:.2e}")) && below.contains("550 m"),
            "{below}"
        );
        assert!(refuse_clamping_cell(smallest * 0.999, &trajectory, true).is_ok());
    }
}

//! The bird's-eye view of one scan pair that the report draws: measured and simulated points
//! over the scene's objects, and the cells only one of them occupies.

use super::grid::GridSpec;
use super::report::{Footprint, ScanRow, Snapshot, SNAPSHOT_POINTS};
use super::roi::Roi;
use nalgebra::Point3;

/// The bird's-eye [`Snapshot`] of scan `index` (`row`), from its measured and simulated points
/// in the region and the sensor's position, on `grid` (the first of the scan's grids; cells are
/// taken in the ground plane even for voxels). `compare` picks the scan with the most objects
/// in view and, of those, the smallest mean distance to them (the earliest on a tie): near the
/// objects the sensor resolves them best, so disagreements show as shapes rather than single
/// points; the first scan with every object in view is often the drive's start, far from most
/// of them.
pub(super) fn snapshot(
    (index, row): (usize, &ScanRow),
    (real, sim): (&[Point3<f64>], &[Point3<f64>]),
    origin: Option<Point3<f64>>,
    roi: &Roi,
    grid: &GridSpec,
) -> Snapshot {
    let thin = |p: &[Point3<f64>]| -> Vec<[f32; 2]> {
        let step = p.len().div_ceil(SNAPSHOT_POINTS).max(1);
        p.iter()
            .step_by(step)
            .map(|q| [q.x as f32, q.y as f32])
            .collect()
    };
    let bev = grid.in_plane();
    let cells = |p: &[Point3<f64>]| -> std::collections::BTreeSet<[i64; 3]> {
        p.iter().map(|q| bev.cell(q)).collect()
    };
    let (cr, cs) = (cells(real), cells(sim));
    let corner = |c: &[i64; 3]| bev.corner(c);
    Snapshot {
        scan: index,
        t_s: row.t_s,
        sensor: origin.map(|o| [o.x, o.y]),
        real: thin(real),
        sim: thin(sim),
        objects: roi
            .boxes()
            .iter()
            .map(|(n, b)| Footprint {
                name: n.clone(),
                min: [b.min.x, b.min.y],
                max: [b.max.x, b.max.y],
            })
            .collect(),
        cell_m: bev.cell_m(),
        only_real_cells: cr.difference(&cs).map(corner).collect(),
        only_sim_cells: cs.difference(&cr).map(corner).collect(),
        both_cells: cr.intersection(&cs).count(),
    }
}

//! The bird's-eye view of one scan pair that the report draws: measured and simulated points
//! over the scene's objects, and the cells only one of them occupies.

use super::cloud::Cloud;
use super::grid::GridSpec;
use super::report::{ScanRow, Snapshot, SNAPSHOT_POINTS};
use super::roi::Roi;
use nalgebra::Point3;

/// The bird's-eye [`Snapshot`] of the scan with the most objects in view and, of those, the
/// smallest mean distance to them (the earliest on a tie), on `grid_of(scan)` (the first of the
/// scan's grids; cells are taken in the ground plane even for voxels). Near the objects the
/// sensor resolves them best, so disagreements show as shapes rather than single points; the
/// first scan with every object in view is often the drive's start, far from most of them.
pub(super) fn snapshot(
    rows: &[ScanRow],
    real: &[Cloud],
    sim: &[Cloud],
    roi: &Roi,
    grid_of: &dyn Fn(usize) -> GridSpec,
) -> Option<Snapshot> {
    let i = (0..rows.len()).min_by(|&a, &b| {
        let key = |i: usize| {
            (
                std::cmp::Reverse(rows[i].objects_in_view),
                rows[i].mean_distance_m.unwrap_or(f64::INFINITY),
            )
        };
        let ((na, da), (nb, db)) = (key(a), key(b));
        na.cmp(&nb).then(da.total_cmp(&db)).then(a.cmp(&b))
    })?;
    let (r, s) = (&real[i], &sim[i]);
    let thin = |p: &[Point3<f64>]| -> Vec<[f32; 2]> {
        let step = p.len().div_ceil(SNAPSHOT_POINTS).max(1);
        p.iter()
            .step_by(step)
            .map(|q| [q.x as f32, q.y as f32])
            .collect()
    };
    let bev = grid_of(i).in_plane();
    let cells = |p: &[Point3<f64>]| -> std::collections::BTreeSet<[i64; 3]> {
        p.iter().map(|q| bev.cell(q)).collect()
    };
    let (cr, cs) = (cells(&r.points), cells(&s.points));
    let corner = |c: &[i64; 3]| bev.corner(c);
    Some(Snapshot {
        scan: i,
        t_s: rows[i].t_s,
        sensor: r.origin.map(|o| [o.x, o.y]),
        real: thin(&r.points),
        sim: thin(&s.points),
        objects: roi
            .boxes()
            .iter()
            .map(|(n, b)| (n.clone(), [b.min.x, b.min.y], [b.max.x, b.max.y]))
            .collect(),
        cell_m: bev.cell_m(),
        only_real_cells: cr.difference(&cs).map(corner).collect(),
        only_sim_cells: cs.difference(&cr).map(corner).collect(),
        both_cells: cr.intersection(&cs).count(),
    })
}

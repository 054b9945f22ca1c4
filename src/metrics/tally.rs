//! The running results of `compare`'s streamed pass: a row per scan pair, the residuals, the
//! return counts and the scan the report's snapshot will show, kept as the drive streams by.

use super::grid::GridScores;
use super::measure::{Measured, Residuals};
use super::report::ScanRow;
use super::windows::PointPair;
use crate::scene::pose::Trajectory;
use hilrig_stamp::UtcNanos;
use nalgebra::Point3;

/// The mean of the values, or `None` for none.
pub(super) fn mean(v: impl Iterator<Item = f64>) -> Option<f64> {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| s / n as f64)
}

/// The scan the snapshot shows: the most objects in view and, of those, the smallest mean
/// distance to them (the earliest on a tie), kept with its points as the drive streams by.
pub(super) struct SnapshotPick {
    pub(super) index: usize,
    key: (usize, f64),
    pub(super) real: Vec<Point3<f64>>,
    pub(super) sim: Vec<Point3<f64>>,
    pub(super) origin: Option<Point3<f64>>,
}

impl SnapshotPick {
    /// A row's key: objects in view, mean distance to them.
    fn key(row: &ScanRow) -> (usize, f64) {
        (
            row.objects_in_view,
            row.mean_distance_m.unwrap_or(f64::INFINITY),
        )
    }

    /// Whether a row beats the pick so far (more objects, then nearer; ties keep the earlier).
    fn beaten_by(this: Option<&SnapshotPick>, row: &ScanRow) -> bool {
        let key = SnapshotPick::key(row);
        this.is_none_or(|p| key.0 > p.key.0 || (key.0 == p.key.0 && key.1 < p.key.1))
    }
}

/// The running results of the streamed pass.
#[derive(Default)]
pub(super) struct Tally {
    pub(super) rows: Vec<ScanRow>,
    pub(super) res: Vec<Residuals>,
    pub(super) returns: (usize, usize),
    pub(super) any_real_point: bool,
    pub(super) pick: Option<SnapshotPick>,
    t0: Option<UtcNanos>,
}

impl Tally {
    /// The rows of a measured batch, with its windows' grid scores.
    pub(super) fn add(
        &mut self,
        measured: Vec<Measured>,
        grids: Vec<Option<GridScores>>,
        trajectory: &Trajectory,
    ) -> Vec<PointPair> {
        let mut clouds = Vec::with_capacity(measured.len());
        for (m, grid) in measured.into_iter().zip(grids) {
            let t0 = *self.t0.get_or_insert(m.middle);
            let per = |x: f64| (m.res.both > 0).then(|| x / m.res.both as f64);
            let mut hint = 0;
            let speed = trajectory
                .velocity_at(m.middle, &mut hint)
                .map_or(0.0, |v| v.xy().norm());
            let row = ScanRow {
                t_s: (m.middle.0 - t0.0) as f64 * 1e-9,
                stamp_ns: m.stamp.0,
                ego_speed_mps: speed,
                objects_in_view: m.objects.len(),
                mean_distance_m: mean(m.objects.iter().map(|o| o.range_m)),
                real_points: m.real.len(),
                sim_points: m.sim.len(),
                grid,
                points: m.points,
                range_diff_mean_m: per(m.res.sum),
                range_diff_rms_m: per(m.res.sum2).map(f64::sqrt),
                only_real: m.res.only_real,
                only_sim: m.res.only_sim,
                objects: m.objects,
            };
            self.any_real_point |= !m.real.is_empty();
            self.returns.0 += m.returns.0;
            self.returns.1 += m.returns.1;
            self.res.push(m.res);
            if SnapshotPick::beaten_by(self.pick.as_ref(), &row) {
                self.pick = Some(SnapshotPick {
                    index: self.rows.len(),
                    key: SnapshotPick::key(&row),
                    real: m.real.clone(),
                    sim: m.sim.clone(),
                    origin: m.origin,
                });
            }
            self.rows.push(row);
            clouds.push((m.real, m.sim));
        }
        clouds
    }
}

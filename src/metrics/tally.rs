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

#[cfg(test)]
mod tests {
    use super::Tally;
    use crate::metrics::measure::{Measured, Residuals};
    use crate::metrics::report::ObjectSeen;
    use crate::scene::pose::{PoseSample, Trajectory};
    use hilrig_stamp::UtcNanos;
    use nalgebra::{Point3, Vector3};

    const T0: i64 = 1_700_000_000_000_000_000;

    fn seen(range_m: f64) -> ObjectSeen {
        ObjectSeen {
            name: format!("at {range_m}"),
            real_points: 20,
            sim_points: 20,
            range_m,
            real_extent_m: 1.0,
            sim_extent_m: 1.0,
        }
    }

    /// A scan pair measured at `t_s` after T0 with objects at `ranges`, `n` measured points.
    fn measured(t_s: f64, ranges: &[f64], n: usize) -> Measured {
        let t = UtcNanos(T0 + (t_s * 1e9) as i64);
        Measured {
            real: vec![Point3::new(t_s, 0.0, 0.0); n],
            sim: vec![Point3::origin(); 2],
            origin: None,
            middle: t,
            stamp: UtcNanos(t.0 - 50_000_000),
            objects: ranges.iter().map(|&r| seen(r)).collect(),
            res: Residuals {
                sum: 0.3,
                sum2: 0.09,
                both: 3,
                only_real: 4,
                only_sim: 5,
            },
            points: None,
            returns: (7, 8),
        }
    }

    /// Rows from scan pairs whose numbers are known: time from the first scan's middle, the
    /// ego's speed, the mean distance to the objects in view, residuals per firing; the
    /// snapshot goes to the scan with the most objects in view and, of those, the nearest
    /// (the earliest on a tie).
    #[test]
    fn rows_and_the_snapshot_of_known_scans() {
        // 5 m/s east, then 12 m/s north-east.
        let at = |t_s: f64, x: f64, y: f64| PoseSample {
            t: UtcNanos(T0 + (t_s * 1e9) as i64),
            position: Vector3::new(x, y, 0.0),
            yaw: 0.0,
            pitch: 0.0,
            roll: 0.0,
        };
        let trajectory = Trajectory::new(vec![
            at(0.0, 0.0, 0.0),
            at(1.0, 5.0, 0.0),
            at(2.0, 5.0 + 12.0 * 0.6, 12.0 * 0.8),
        ])
        .unwrap();
        let mut tally = Tally::default();
        let scans = vec![
            measured(0.25, &[10.0, 14.0], 1),      // 2 objects, mean 12
            measured(0.5, &[9.0, 11.0, 16.0], 2),  // 3 objects, mean 12
            measured(0.75, &[8.0, 12.0, 13.0], 3), // 3 objects, mean 11: the pick
            measured(1.5, &[4.0], 4),              // 1 object, nearer
            measured(1.75, &[5.0, 17.0, 11.0], 5), // 3 objects, mean 11 too: a tie
        ];
        let clouds = tally.add(scans, vec![None; 5], &trajectory);
        assert_eq!(clouds.len(), 5);
        let t: Vec<f64> = tally.rows.iter().map(|r| r.t_s).collect();
        for (got, want) in t.iter().zip([0.0, 0.25, 0.5, 1.25, 1.5]) {
            assert!((got - want).abs() < 1e-9, "row times {t:?}");
        }
        let speed: Vec<f64> = tally.rows.iter().map(|r| r.ego_speed_mps).collect();
        assert!(
            (speed[0] - 5.0).abs() < 1e-9 && (speed[3] - 12.0).abs() < 1e-9,
            "speeds {speed:?}"
        );
        let dist: Vec<f64> = tally
            .rows
            .iter()
            .filter_map(|r| r.mean_distance_m)
            .collect();
        for (got, want) in dist.iter().zip([12.0, 12.0, 11.0, 4.0, 11.0]) {
            assert!((got - want).abs() < 1e-9, "mean distances {dist:?}");
        }
        let row = &tally.rows[0];
        assert!(
            (row.range_diff_mean_m.unwrap() - 0.1).abs() < 1e-12
                && (row.range_diff_rms_m.unwrap() - (0.03f64).sqrt()).abs() < 1e-12,
            "residual mean {:?} and rms {:?} of 3 firings summing to 0.3 m and 0.09 m²",
            row.range_diff_mean_m,
            row.range_diff_rms_m
        );
        assert_eq!((row.only_real, row.only_sim, row.real_points), (4, 5, 1));
        assert_eq!(tally.returns, (35, 40));
        let pick = tally.pick.as_ref().unwrap();
        assert_eq!(
            (pick.index, pick.real.len()),
            (2, 3),
            "the snapshot is the 3rd scan: 3 objects at 11 m, before the tie"
        );
    }
}

//! The accuracy budget (Rosenberger et al. 2019, §6): the ego reference's errors (RTK position,
//! timing times speed, interpolation between reference samples, a wrong lever arm) and the
//! scene's survey accuracy, combined as a root sum of squares into one reference accuracy, and
//! the smallest admissible grid cell: max(min cell, factor × reference accuracy).

use super::faults::FaultLog;
use super::names::FaultName;
use super::report::{Accuracy, Spatial, Stats, Temporal};
use crate::reference::run::Run;
use crate::reference::trajectory::EgoTrajectory;
use crate::rig::Thresholds;
use crate::scene::Scene;

/// What the budget combines besides the measurements.
pub(super) struct Errors<'a> {
    /// The GNSS time offset found, s.
    pub gnss_time_offset_s: f64,
    /// The lidar's time error, s.
    pub lidar_time_error_s: f64,
    /// Per GNSS epoch: RTK-fixed.
    pub fixed: &'a [bool],
    /// The heading's 1-sigma error over the usable stretches (see [`heading`]), deg.
    pub heading_sigma_deg: f64,
    /// The range it counts at (see [`heading_range`]), m.
    pub heading_range_m: f64,
}

/// Marks the stretches where the smoothed heading's 1-sigma error exceeds the limit (sampled
/// every 100 ms), and returns the 95th percentile of that sigma over the rest, deg. The sigma
/// is the smoother's own (its covariance, with the GNSS sigmas scaled for their correlation):
/// large where the heading is not yet or no longer shown by the motion (standing at the start,
/// slow turns), small while the vehicle drives.
pub(super) fn heading(
    traj: &EgoTrajectory,
    th: &Thresholds,
    range_m: f64,
    log: &mut FaultLog,
) -> f64 {
    const STEP: i64 = 100_000_000;
    let (a, b) = traj.span();
    let mut flagged = Vec::new();
    let mut kept = Vec::new();
    let mut t = a;
    while t <= b {
        if let Some(s) = traj.heading_sigma_at(t) {
            let deg = s.to_degrees();
            if deg > th.max_heading_sigma_deg {
                flagged.push((t, deg));
            } else {
                kept.push(deg);
            }
        }
        t = hilrig_stamp::UtcNanos(t.0 + STEP);
    }
    log.mark_runs(FaultName::HeadingUncertain, &flagged, STEP, |_, worst| {
        format!(
            "heading sigma up to {worst:.2}° (limit {:.2}°): {:.3} m at {:.0} m range; the heading shows once the vehicle drives a few metres",
            th.max_heading_sigma_deg,
            worst.to_radians() * range_m,
            range_m
        )
    });
    if kept.is_empty() {
        // Nothing usable: the budget says how bad the heading is everywhere.
        kept = flagged.iter().map(|f| f.1).collect();
    }
    if kept.is_empty() {
        return 0.0;
    }
    Stats::of(kept).p95
}

/// The range at which the heading error counts: the 95th percentile of the distances from the
/// ego (every second) to the scene's objects, at most `heading_range_m`; without a scene,
/// `heading_range_m`.
pub(super) fn heading_range(traj: &EgoTrajectory, th: &Thresholds, scene: Option<&Scene>) -> f64 {
    let Some(scene) = scene.filter(|s| !s.file.objects.is_empty()) else {
        return th.heading_range_m;
    };
    let (a, b) = traj.span();
    let mut d = Vec::new();
    let mut t = a;
    while t <= b {
        if let Some((pose, _)) = traj.pose_at(t) {
            for o in &scene.file.objects {
                d.push((nalgebra::Vector2::new(o.pose.x, o.pose.y) - pose.position.xy()).norm());
            }
        }
        t = hilrig_stamp::UtcNanos(t.0 + 1_000_000_000);
    }
    if d.is_empty() {
        return th.heading_range_m;
    }
    Stats::of(d).p95.min(th.heading_range_m)
}

/// The budget of a checked run. `traj` is the smoothed trajectory with the rig's lever arm;
/// `log` holds the faults found (a time
/// offset or lever arm counts in full only when it is a fault).
pub(super) fn accuracy(
    run: &Run,
    th: &Thresholds,
    sp: &Spatial,
    tm: &Temporal,
    traj: &EgoTrajectory,
    errors: &Errors<'_>,
    log: &FaultLog,
) -> Accuracy {
    let nis_fixed: Vec<f64> = traj
        .residuals
        .iter()
        .zip(errors.fixed)
        .filter(|(_, &f)| f)
        .map(|(r, _)| r.nis)
        .collect();
    let mean_nis = nis_fixed.iter().sum::<f64>() / nis_fixed.len().max(1) as f64;
    let v_p95 = Stats::of(run.motion.iter().map(|m| m.speed.abs()).collect()).p95;
    let offset_s = errors.gnss_time_offset_s;
    let mut acc = Accuracy {
        trajectory_m: sp.sigma_horizontal_m.median.max(sp.residual_m.rms)
            * (mean_nis / 2.0).max(1.0).sqrt(),
        // A time offset within its limit is not distinguishable from the estimate's own noise
        // (a few ms); one beyond it counts in full.
        temporal_m: v_p95
            * (if log.has(FaultName::GnssTimeOffset) {
                offset_s.powi(2)
            } else {
                0.0
            } + errors.lidar_time_error_s.powi(2))
            .sqrt(),
        interpolation_m: tm.interpolation_error_m.p95,
        lever_arm_m: 0.0,
        heading_sigma_deg: errors.heading_sigma_deg,
        heading_m: errors.heading_sigma_deg.to_radians() * errors.heading_range_m,
        heading_range_m: errors.heading_range_m,
        ..Accuracy::default()
    };
    if sp.sigma_horizontal_m.n == 0 {
        acc.trajectory_m = sp.residual_m.rms * (mean_nis / 2.0).max(1.0).sqrt();
    }
    if log.has(FaultName::LeverArm) {
        acc.lever_arm_m = (sp.lever_arm_x_measured_m.unwrap_or(0.0) - sp.lever_arm_x_rig_m).abs();
    }
    acc.ego_m = (acc.trajectory_m.powi(2)
        + acc.temporal_m.powi(2)
        + acc.interpolation_m.powi(2)
        + acc.lever_arm_m.powi(2)
        + acc.heading_m.powi(2))
    .sqrt();
    acc.scene_m = sp.scene_accuracy_m;
    acc.reference_m = (acc.ego_m.powi(2) + acc.scene_m.unwrap_or(0.0).powi(2)).sqrt();
    acc.grid_cell_m = th
        .min_grid_cell_m
        .max(th.grid_cell_accuracy_factor * acc.reference_m);
    acc
}

#[cfg(test)]
mod tests {
    use super::super::report::Stats;
    use super::super::test_drive::{self, Drive, T0};
    use super::*;
    use crate::reference::run::Motion;
    use crate::scene::file::SceneFile;
    use hilrig_stamp::UtcNanos;
    use nalgebra::Vector2;

    /// A smoothed drive standing at the origin for `seconds` (its GNSS residuals, whose
    /// normalised innovations the budget reads, are set by the tests).
    fn standing(seconds: f64) -> EgoTrajectory {
        let drive = Drive::new(0.0, &[(seconds, 0.0, 0.0)]);
        let lever = Vector2::new(0.6, 0.0);
        test_drive::smooth(&drive.gnss(lever, 0.0), &drive.motion(1.0, 0.0), lever)
    }

    fn stats(median: f64, p95: f64, rms: f64) -> Stats {
        Stats {
            n: 10,
            median,
            p95,
            max: p95,
            rms,
        }
    }

    /// The budget of a run whose parts are known numbers: CAN speed 2 m/s (95th percentile;
    /// a tenth of the run at 1 m/s), receiver sigma 1.2 cm, residuals 0.8 cm rms, a GNSS time
    /// offset of 30 ms, a lidar time error of 4 ms, interpolation 2 mm, the antenna measured
    /// at 1.1 m where the rig says 0.6 m, the heading to 0.1° at 20 m, the survey to 5 cm;
    /// `nis` the mean normalised innovation of the GNSS epochs, `faults` those raised; every
    /// error (not the speed or the range) times `scale`.
    fn budget(nis: f64, faults: &[FaultName], receiver_sigma: bool, scale: f64) -> Accuracy {
        let motion: Vec<Motion> = (0..100)
            .map(|k| Motion {
                t: UtcNanos(T0 + k * 20_000_000),
                speed: if k % 10 == 0 { 1.0 } else { -2.0 },
                yaw_rate: 0.0,
            })
            .collect();
        let run = test_drive::run(motion);
        let sp = Spatial {
            sigma_horizontal_m: if receiver_sigma {
                stats(0.012 * scale, 0.015 * scale, 0.012 * scale)
            } else {
                Stats::default()
            },
            residual_m: stats(0.007 * scale, 0.012 * scale, 0.008 * scale),
            lever_arm_x_measured_m: Some(0.6 + 0.5 * scale),
            lever_arm_x_rig_m: 0.6,
            scene_accuracy_m: Some(0.05 * scale),
            ..Spatial::default()
        };
        let tm = Temporal {
            interpolation_error_m: stats(0.001 * scale, 0.002 * scale, 0.001 * scale),
            ..Temporal::default()
        };
        let mut traj = standing(2.0);
        for r in &mut traj.residuals {
            r.nis = nis;
        }
        let fixed = vec![true; traj.residuals.len()];
        let errors = Errors {
            gnss_time_offset_s: 0.030 * scale,
            lidar_time_error_s: 0.004 * scale,
            fixed: &fixed,
            heading_sigma_deg: 0.1 * scale,
            heading_range_m: 20.0,
        };
        let mut log = FaultLog::new(UtcNanos(T0));
        for &f in faults {
            log.fault(f, UtcNanos(T0), UtcNanos(T0), String::new());
        }
        accuracy(&run, &Thresholds::default(), &sp, &tm, &traj, &errors, &log)
    }

    fn close(what: &str, got: f64, want: f64) {
        assert!(
            (got - want).abs() < 1e-12,
            "{what}: {got} m, the parts give {want} m"
        );
    }

    #[test]
    fn the_budget_is_the_root_sum_of_squares_of_the_physical_errors() {
        let acc = budget(
            1.0,
            &[FaultName::GnssTimeOffset, FaultName::LeverArm],
            true,
            1.0,
        );
        // Each part as what it physically is.
        let rtk = 0.012; // the receiver's sigma: its residuals (NIS 1 < 2) say it is honest
        let timing = 2.0 * (0.030f64.powi(2) + 0.004f64.powi(2)).sqrt(); // two time errors at speed
        let interp = 0.002;
        let lever = 1.1 - 0.6;
        let heading = 0.1 * std::f64::consts::PI / 180.0 * 20.0; // arc at range
        close("trajectory", acc.trajectory_m, rtk);
        close("temporal", acc.temporal_m, timing);
        close("interpolation", acc.interpolation_m, interp);
        close("lever arm", acc.lever_arm_m, lever);
        close("heading", acc.heading_m, heading);
        let ego =
            (rtk * rtk + timing * timing + interp * interp + lever * lever + heading * heading)
                .sqrt();
        close("ego", acc.ego_m, ego);
        close("scene", acc.scene_m.unwrap(), 0.05);
        let reference = (ego * ego + 0.05 * 0.05).sqrt();
        close("reference", acc.reference_m, reference);
        // The grid cell: ten times the reference accuracy, at least 10 cm (Rosenberger et al.
        // 2019, §6).
        close("grid cell", acc.grid_cell_m, 10.0 * reference);
    }

    #[test]
    fn offsets_and_lever_arms_within_their_limits_do_not_count_and_small_errors_keep_the_minimum_cell(
    ) {
        let acc = budget(1.0, &[], true, 1.0);
        close("temporal", acc.temporal_m, 2.0 * 0.004);
        close("lever arm", acc.lever_arm_m, 0.0);
        let heading = 0.1f64.to_radians() * 20.0;
        let ego =
            (0.012f64.powi(2) + 0.008f64.powi(2) + 0.002f64.powi(2) + heading * heading).sqrt();
        close("ego", acc.ego_m, ego);
        // Ten times 6.3 cm.
        close(
            "grid cell",
            acc.grid_cell_m,
            10.0 * (ego * ego + 0.0025).sqrt(),
        );
        // Every error a hundredth: a reference accuracy of 0.6 mm; the cell stays at 10 cm.
        let acc = budget(1.0, &[], true, 0.01);
        assert!(acc.reference_m < 0.001, "{}", acc.reference_m);
        close("grid cell", acc.grid_cell_m, 0.1);
    }

    #[test]
    fn optimistic_receiver_sigmas_are_inflated_by_the_normalised_innovations() {
        // A mean NIS of 8 where χ² with 2 degrees of freedom has 2: the errors are twice what
        // the receiver claims.
        let acc = budget(8.0, &[], true, 1.0);
        close("trajectory", acc.trajectory_m, 2.0 * 0.012);
        // Without receiver sigmas, the residuals' rms, inflated alike.
        let acc = budget(8.0, &[], false, 1.0);
        close("trajectory", acc.trajectory_m, 2.0 * 0.008);
        // Residuals smaller than the sigmas promise do not shrink the sigma.
        let acc = budget(0.5, &[], true, 1.0);
        close("trajectory", acc.trajectory_m, 0.012);
    }

    /// A scene with objects at `at` (x, y).
    fn scene(at: &[(f64, f64)]) -> Scene {
        let mut text = String::from(
            "name = \"ring\"\norigin = { latitude_deg = 48.0, longitude_deg = 11.0, height_m = 400.0 }\n",
        );
        for (k, (x, y)) in at.iter().enumerate() {
            text.push_str(&format!(
                "[[object]]\nname = \"o{k}\"\npose = {{ x = {x}, y = {y} }}\nreflectivity = 0.5\n\
                 parts = [{{ shape = \"box\", size = [0.5, 0.5, 1.0] }}]\n"
            ));
        }
        let file: SceneFile = toml::from_str(&text).unwrap();
        Scene::from_file(
            file,
            std::path::Path::new("."),
            std::path::Path::new("t.toml"),
        )
        .unwrap()
    }

    #[test]
    fn the_heading_counts_at_the_95th_percentile_of_the_objects_distances_at_most_the_rigs_range() {
        // The ego stands at the origin (the antenna 0.6 m ahead of it).
        let traj = standing(5.0);
        let th = Thresholds::default();
        let ring = [(12.0, 0.0), (0.0, 12.0), (-12.0, 0.0), (0.0, -12.0)];
        let r = heading_range(&traj, &th, Some(&scene(&ring)));
        assert!((r - 12.0).abs() < 0.005, "range {r} m, objects at 12 m");
        // Nineteen objects at 8 m and one at 15 m: the 95th percentile is the ring's 8 m...
        let mut near: Vec<(f64, f64)> = (0..19)
            .map(|k| {
                let a = f64::from(k) * 0.3;
                (8.0 * a.cos(), 8.0 * a.sin())
            })
            .collect();
        near.push((15.0, 0.0));
        let r = heading_range(&traj, &th, Some(&scene(&near)));
        assert!((r - 8.0).abs() < 0.005, "range {r} m");
        // ... two of twenty at 15 m make it 15 m; objects beyond the rig's 30 m count at 30 m.
        near[0] = (0.0, 15.0);
        let r = heading_range(&traj, &th, Some(&scene(&near)));
        assert!((r - 15.0).abs() < 0.005, "range {r} m");
        let far = [(50.0, 0.0), (0.0, 50.0)];
        assert_eq!(heading_range(&traj, &th, Some(&scene(&far))), 30.0);
        assert_eq!(heading_range(&traj, &th, None), 30.0);
        assert_eq!(heading_range(&traj, &th, Some(&scene(&[]))), 30.0);
    }

    #[test]
    fn the_heading_is_marked_where_no_motion_shows_it() {
        let lever = Vector2::new(0.6, 0.0);
        let th = Thresholds::default();
        // A car that never moves: GNSS cannot show its heading anywhere. The whole drive is
        // marked, and the budget states the heading's sigma over all of it.
        let standing = standing(10.0);
        let mut log = FaultLog::new(UtcNanos(T0));
        let still = heading(&standing, &th, 20.0, &mut log);
        assert!(log.faults.is_empty(), "marks are not faults");
        assert_eq!(log.marks.len(), 1, "{:?}", log.marks);
        let m = &log.marks[0];
        assert_eq!((m.name, m.from_s), (FaultName::HeadingUncertain, 0.0));
        assert!(m.to_s >= 10.0, "marked until {} s of 10 s", m.to_s);
        assert!(still > th.max_heading_sigma_deg, "{still}");
        // Driving at 3 m/s throughout: the track shows the heading everywhere.
        let drive = Drive::new(3.0, &[(10.0, 0.0, 0.0)]);
        let moving = test_drive::smooth(&drive.gnss(lever, 0.0), &drive.motion(1.0, 0.0), lever);
        let mut log = FaultLog::new(UtcNanos(T0));
        let shown = heading(&moving, &th, 20.0, &mut log);
        assert!(log.marks.is_empty(), "{:?}", log.marks);
        assert!(shown > 0.0 && shown <= th.max_heading_sigma_deg, "{shown}");
        // No limit: nothing marked, the same sigma; a limit nothing meets: all marked, the
        // sigma over all of it.
        let with_limit = |limit: f64, log: &mut FaultLog| {
            let th = Thresholds {
                max_heading_sigma_deg: limit,
                ..Thresholds::default()
            };
            heading(&moving, &th, 20.0, log)
        };
        let mut none = FaultLog::new(UtcNanos(T0));
        assert_eq!(with_limit(f64::INFINITY, &mut none), shown);
        assert!(none.marks.is_empty());
        let mut every = FaultLog::new(UtcNanos(T0));
        assert_eq!(with_limit(0.0, &mut every), shown);
        assert_eq!(every.marks.len(), 1);
    }
}

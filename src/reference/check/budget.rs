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

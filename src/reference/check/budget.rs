//! The accuracy budget (Rosenberger et al. 2019, §6): the ego reference's errors (RTK position,
//! timing times speed, interpolation between reference samples, a wrong lever arm) and the
//! scene's survey accuracy, combined as a root sum of squares into one reference accuracy, and
//! the smallest admissible grid cell: max(min cell, factor × reference accuracy).

use super::faults::FaultLog;
use super::report::{Accuracy, Spatial, Stats, Temporal};
use crate::reference::run::Run;
use crate::reference::trajectory::EgoTrajectory;
use crate::rig::Thresholds;

/// What the budget combines besides the measurements.
pub(super) struct Errors<'a> {
    /// The GNSS time offset found, s.
    pub gnss_time_offset_s: f64,
    /// The lidar's time error, s.
    pub lidar_time_error_s: f64,
    /// Per GNSS epoch: RTK-fixed.
    pub fixed: &'a [bool],
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
            * (if log.has("gnss_time_offset") {
                offset_s.powi(2)
            } else {
                0.0
            } + errors.lidar_time_error_s.powi(2))
            .sqrt(),
        interpolation_m: tm.interpolation_error_m.p95,
        lever_arm_m: 0.0,
        ..Accuracy::default()
    };
    if sp.sigma_horizontal_m.n == 0 {
        acc.trajectory_m = sp.residual_m.rms * (mean_nis / 2.0).max(1.0).sqrt();
    }
    if log.has("lever_arm") {
        acc.lever_arm_m = (sp.lever_arm_x_measured_m.unwrap_or(0.0) - sp.lever_arm_x_rig_m).abs();
    }
    acc.ego_m = (acc.trajectory_m.powi(2)
        + acc.temporal_m.powi(2)
        + acc.interpolation_m.powi(2)
        + acc.lever_arm_m.powi(2))
    .sqrt();
    acc.scene_m = sp.scene_accuracy_m;
    acc.reference_m = (acc.ego_m.powi(2) + acc.scene_m.unwrap_or(0.0).powi(2)).sqrt();
    acc.grid_cell_m = th
        .min_grid_cell_m
        .max(th.grid_cell_accuracy_factor * acc.reference_m);
    acc
}

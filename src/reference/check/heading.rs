//! The rig's heading source (an INS, a dual-antenna receiver): its reports as measurements of
//! the smoother, and the verdict on them. The smoother estimates the source's constant offset
//! against the track (the baseline's misalignment beyond what the rig file says); a report
//! is measured against the smoothed heading with that offset, and a stretch of reports that
//! does not fit the stated accuracy, a source that reports in a mode other than measured (dead
//! reckoning held over an outage, manual input, a simulator) or an offset beyond the limit is a
//! fault, named and located.

use super::faults::FaultLog;
use super::names::FaultName;
use super::report::HeadingReport;
use crate::reference::run::Run;
use crate::reference::trajectory::{
    wrap, EgoTrajectory, GnssObs, HeadingObs, HeadingResidual, Settings, TrajectoryError,
};
use crate::rig::{HeadingConfig, Thresholds};
use hilrig_gnss::{AttitudeMode, AttitudeOf};
use hilrig_stamp::UtcNanos;

/// Consecutive reports beyond 3 sigma that make a fault. One report in 370 lies beyond 3 sigma
/// by chance; five in a row, about one in 10^12.
const RUN_BEYOND_3_SIGMA: usize = 5;

/// The source's reports sorted for the smoother.
pub(super) struct Reports {
    /// The measured ones, as the smoother takes them.
    pub obs: Vec<HeadingObs>,
    /// Times of reports in a mode other than measured (not used).
    pub not_measured: Vec<(UtcNanos, AttitudeMode)>,
    /// Reports of the source without a time (before the stream showed its date; not used).
    pub untimed: usize,
    /// Messages of the source flagged invalid by their own flags (not used).
    pub invalid: u64,
    /// GNSS messages of the run that did not frame or decode (not used).
    pub malformed: u64,
}

/// The rig's heading source's reports in `run`: the heading turned into the smoother's
/// frame (from east, counter-clockwise) with the rig's mounting offset taken off, and the
/// larger of the stated and the rig's sigma.
pub(super) fn reports(run: &Run, cfg: &HeadingConfig) -> Reports {
    let source = cfg.source.attitude_source();
    let mut out = Reports {
        obs: Vec::new(),
        not_measured: Vec::new(),
        untimed: 0,
        invalid: run
            .gnss_rejected
            .invalid_attitudes
            .get(source.name())
            .copied()
            .unwrap_or(0),
        malformed: run.gnss_rejected.not_framed + run.gnss_rejected.not_decoded,
    };
    for (_, a) in &run.attitudes {
        if a.source != source || a.of != AttitudeOf::Vehicle {
            continue;
        }
        let Some(heading) = a.heading_deg else {
            continue;
        };
        let Some(t) = a.time else {
            out.untimed += 1;
            continue;
        };
        if a.mode != AttitudeMode::Measured {
            out.not_measured.push((t, a.mode));
            continue;
        }
        let sigma = a.sigma_heading_deg.unwrap_or(0.0).max(cfg.sigma_deg);
        out.obs.push(HeadingObs {
            t,
            yaw: std::f64::consts::FRAC_PI_2 - (heading - cfg.yaw_offset_deg).to_radians(),
            sigma: sigma.to_radians(),
        });
    }
    out.obs.sort_by_key(|o| o.t);
    out
}

/// Runs of at least [`RUN_BEYOND_3_SIGMA`] consecutive residuals beyond 3 sigma, as index
/// ranges.
pub(super) fn disagreeing(res: &[HeadingResidual]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < res.len() {
        if res[i].nis <= 9.0 {
            i += 1;
            continue;
        }
        let mut j = i;
        while j < res.len() && res[j].nis > 9.0 {
            j += 1;
        }
        if j - i >= RUN_BEYOND_3_SIGMA {
            out.push((i, j));
        }
        i = j;
    }
    out
}

/// The reports without those in stretches that disagree with `traj`: what the trajectory is
/// smoothed again with, so that a frozen or disturbed stretch does not pull the reference
/// heading along (it is located against the trajectory made without it).
pub(super) fn without_disagreeing(
    obs: &[HeadingObs],
    traj: &EgoTrajectory,
) -> Option<Vec<HeadingObs>> {
    let res = &traj.heading_residuals;
    let runs = disagreeing(res);
    if runs.is_empty() {
        return None;
    }
    let windows: Vec<(UtcNanos, UtcNanos)> = runs
        .iter()
        .map(|&(i, j)| (res[i].t, res[j - 1].t))
        .collect();
    Some(
        obs.iter()
            .filter(|o| !windows.iter().any(|(a, b)| *a <= o.t && o.t <= *b))
            .copied()
            .collect(),
    )
}

/// The trajectory with the heading reports fused, and the source's offset. Stretches of
/// reports that disagree with the track are left out and the trajectory made again without
/// them; the offset is the one fused from what is left (or, when nothing is left, from all).
pub(super) fn smooth(
    gnss: &[GnssObs],
    motion: &[(UtcNanos, f64, f64)],
    obs: &[HeadingObs],
    settings: &Settings,
) -> Result<(EgoTrajectory, Option<(f64, f64)>), TrajectoryError> {
    let traj = EgoTrajectory::smooth_with_heading(gnss, motion, obs, settings)?;
    let offset = traj.heading_offset();
    match without_disagreeing(obs, &traj) {
        None => Ok((traj, offset)),
        Some(kept) => {
            let again = EgoTrajectory::smooth_with_heading(gnss, motion, &kept, settings)?;
            let offset = again.heading_offset().or(offset);
            Ok((again, offset))
        }
    }
}

/// Every report against `traj` (the reports left out of the smoothing too): the error, and
/// its square over the report's variance plus the trajectory's. A trajectory without the
/// source's offset (every report was left out) takes `offset` with its variance.
fn residuals(
    obs: &[HeadingObs],
    traj: &EgoTrajectory,
    offset: (f64, f64),
) -> Vec<(HeadingResidual, f64)> {
    let fused = traj.heading_offset().is_some();
    obs.iter()
        .filter_map(|o| {
            let (expected, var) = if fused {
                traj.source_heading_at(o.t)?
            } else {
                let (x, p) = traj.state_at(o.t)?;
                (x[2] + offset.0, p[(2, 2)].max(0.0) + offset.1 * offset.1)
            };
            let error = wrap(o.yaw - expected);
            Some((
                HeadingResidual {
                    t: o.t,
                    error,
                    nis: error * error / (o.sigma * o.sigma + var),
                },
                o.sigma,
            ))
        })
        .collect()
}

/// Judges the reports against the smoothed trajectory and the source's offset (`None`: no
/// report was fused), logging faults.
pub(super) fn judge(
    reports: &Reports,
    traj: &EgoTrajectory,
    offset: Option<(f64, f64)>,
    cfg: &HeadingConfig,
    th: &Thresholds,
    gnss_period: i64,
    log: &mut FaultLog,
) -> HeadingReport {
    let period =
        super::temporal::median_interval(&reports.obs.iter().map(|o| o.t).collect::<Vec<_>>())
            .unwrap_or(gnss_period);
    let name = cfg.source.attitude_source().name();
    let mut report = HeadingReport {
        source: cfg.source,
        used: reports.obs.len(),
        not_measured: reports.not_measured.len(),
        untimed: reports.untimed,
        invalid: reports.invalid,
        malformed_gnss: reports.malformed,
        sigma_deg: cfg.sigma_deg,
        yaw_offset_rig_deg: cfg.yaw_offset_deg,
        yaw_offset_sigma_rig_deg: cfg.yaw_offset_sigma_deg,
        offset_deg: None,
        offset_sigma_deg: None,
        rms_normalized: None,
        beyond_3_sigma: 0,
    };
    let (a, z) = traj.span();
    let Some((b, sb)) = offset else {
        log.fault(
            FaultName::HeadingSourceMissing,
            a,
            z,
            format!(
                "the rig's heading source {name} reported no measured heading with a time ({} in another mode, {} without a time): the recording is not what the rig file describes",
                reports.not_measured.len(),
                reports.untimed
            ),
        );
        return report;
    };
    let (res, sigmas): (Vec<HeadingResidual>, Vec<f64>) =
        residuals(&reports.obs, traj, (b, sb)).into_iter().unzip();
    // Whether the reports fit their stated accuracy: their errors against the smoothed
    // heading in units of that accuracy (the trajectory's own error is small beside it where
    // the reports were fused; where they were left out it does not matter).
    let mean_nis = res
        .iter()
        .zip(&sigmas)
        .map(|(r, s)| (r.error / s).powi(2))
        .sum::<f64>()
        / res.len().max(1) as f64;
    let beyond = res.iter().filter(|r| r.nis > 9.0).count();
    for (i, j) in disagreeing(&res) {
        let worst = res[i..j]
            .iter()
            .map(|r| r.error.abs())
            .fold(0.0, f64::max)
            .to_degrees();
        log.fault(
            FaultName::HeadingSourceDisagrees,
            res[i].t,
            UtcNanos(res[j - 1].t.0 + period),
            format!(
                "{} {} reports in a row more than 3 sigma ({:.3}°) off the smoothed heading, up to {worst:.3}°: a frozen or disturbed source, or a wrong mounting (left out of the trajectory)",
                j - i,
                cfg.source.attitude_source().name(),
                cfg.sigma_deg
            ),
        );
    }
    // Reports in another mode, located as runs of each mode.
    for mode in [
        AttitudeMode::Estimated,
        AttitudeMode::Manual,
        AttitudeMode::Simulator,
    ] {
        let flagged: Vec<(UtcNanos, f64)> = reports
            .not_measured
            .iter()
            .filter(|(_, m)| *m == mode)
            .map(|&(t, _)| (t, 0.0))
            .collect();
        log.runs(
            FaultName::HeadingSourceNotMeasured,
            &flagged,
            period,
            |n, _| {
                format!(
                    "{n} {name} reports in mode {}: not measured, not used",
                    mode.name()
                )
            },
        );
    }
    // The smoother's offset is in its own (counter-clockwise) sense.
    let offset_deg = -b.to_degrees();
    if offset_deg.abs() > th.max_heading_offset_deg && offset_deg.abs() > 3.0 * sb.to_degrees() {
        log.fault(
            FaultName::HeadingSourceOffset,
            a,
            z,
            format!(
                "the source reads {offset_deg:+.2}° ± {:.2}° off the track beyond the rig's yaw_offset_deg = {}; limit {}°: check the mounting in the rig file",
                sb.to_degrees(),
                cfg.yaw_offset_deg,
                th.max_heading_offset_deg
            ),
        );
    }
    report.offset_deg = Some(offset_deg);
    report.offset_sigma_deg = Some(sb.to_degrees());
    report.rms_normalized = Some(mean_nis.sqrt());
    report.beyond_3_sigma = beyond;
    report
}

//! Temporal accuracy: per-source rate, gaps and jitter; the PPS state and the clock models the
//! recorder wrote into the MCAP; the lidar-to-GNSS offset; how far the ego moves between GNSS
//! epochs and what linear interpolation between them would cost.

use super::faults::{secs, FaultLog};
use super::names::FaultName;
use super::report::{SourceTiming, Stats, Temporal};
use crate::reference::run::Run;
use crate::reference::trajectory::EgoTrajectory;
use crate::rig::Thresholds;
use hilrig_gnss::Fix;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::PpsStatus;

/// The median interval between consecutive (distinct) times, ns.
pub(super) fn median_interval(times: &[UtcNanos]) -> Option<i64> {
    let mut d: Vec<i64> = times
        .windows(2)
        .map(|w| w[1].0 - w[0].0)
        .filter(|&d| d > 0)
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_unstable();
    Some(d[d.len() / 2])
}

/// The timing of every source, PPS and clock models, and the motion between GNSS epochs along
/// `traj`. Returns the measurements and the lidar's time error in seconds (the clock-model
/// residual p95 when the lidar runs without PPS, else 0), which the accuracy budget needs.
pub(super) fn measure(
    run: &Run,
    epochs: &[(UtcNanos, &Fix)],
    traj: &EgoTrajectory,
    th: &Thresholds,
    log: &mut FaultLog,
) -> (Temporal, f64) {
    let mut tm = Temporal::default();
    let gnss_times: Vec<UtcNanos> = epochs.iter().map(|e| e.0).collect();
    tm.sources.push(timing(
        log,
        "gnss",
        FaultName::GnssGap,
        &gnss_times,
        th.gap_periods,
    ));
    // CAN per message: two messages at 50 Hz (speed in one, yaw rate in the other) are two
    // sources, not one at 100 Hz with a jitter of half its period.
    for (id, times) in ego_messages(run) {
        tm.sources.push(timing(
            log,
            &format!("can 0x{id:x}"),
            FaultName::CanGap,
            &times,
            th.gap_periods,
        ));
    }
    if !run.packets.is_empty() {
        let lidar_times: Vec<UtcNanos> = run.packets.iter().map(|p| p.host).collect();
        tm.sources.push(timing(
            log,
            "lidar",
            FaultName::LidarGap,
            &lidar_times,
            th.gap_periods,
        ));
    }
    tm.clock_sync = run
        .metadata
        .iter()
        .filter(|(k, _)| k.starts_with("clock_sync/"))
        .map(|(k, v)| (k.trim_start_matches("clock_sync/").to_owned(), v.clone()))
        .collect();
    let meta =
        |src: &str, key: &str| -> Option<f64> { tm.clock_sync.get(src)?.get(key)?.parse().ok() };
    if let (Some(l), Some(g)) = (meta("lidar", "offset_ns"), meta("gnss", "offset_ns")) {
        tm.lidar_to_gnss_offset_ms = Some((l - g) * 1e-6);
    }
    let lidar_time_error_s = pps(run, th, &meta, &mut tm.pps_locked_share, log);
    let mut between = Vec::new();
    let mut interp = Vec::new();
    for w in epochs.windows(2) {
        let (a, b) = (w[0].0, w[1].0);
        let (Some((pa, _)), Some((pb, _))) = (traj.pose_at(a), traj.pose_at(b)) else {
            continue;
        };
        between.push((pb.position - pa.position).norm());
        if let Some((pm, _)) = traj.pose_at(UtcNanos((a.0 + b.0) / 2)) {
            interp.push((pm.position - (pa.position + pb.position) / 2.0).norm());
        }
    }
    tm.motion_between_epochs_m = Stats::of(between);
    tm.interpolation_error_m = Stats::of(interp);
    (tm, lidar_time_error_s)
}

/// The CAN messages that carry ego motion, with their times: those whose frames arrive at the
/// instants the recorder wrote ego motion. A recording without raw frames counts its ego
/// motion as one source (id 0).
fn ego_messages(run: &Run) -> Vec<(u32, Vec<UtcNanos>)> {
    let motion: std::collections::HashSet<UtcNanos> = run.motion.iter().map(|m| m.t).collect();
    let mut by_id: std::collections::BTreeMap<u32, Vec<UtcNanos>> = Default::default();
    for &(t, id) in &run.can_frames {
        by_id.entry(id).or_default().push(t);
    }
    let ego: Vec<(u32, Vec<UtcNanos>)> = by_id
        .into_iter()
        .filter(|(_, times)| times.iter().any(|t| motion.contains(t)))
        .collect();
    if ego.is_empty() {
        return vec![(0, run.motion.iter().map(|m| m.t).collect())];
    }
    ego
}

/// The PPS state of the position packets: the locked share, and when the rig requires PPS, the
/// faults of a free-running lidar clock. Returns the lidar's time error, s.
fn pps(
    run: &Run,
    th: &Thresholds,
    meta: &dyn Fn(&str, &str) -> Option<f64>,
    locked_share: &mut Option<f64>,
    log: &mut FaultLog,
) -> f64 {
    let mut lidar_time_error_s = 0.0;
    if run.pps.is_empty() {
        return lidar_time_error_s;
    }
    let locked = run.pps.iter().filter(|p| p.1 == PpsStatus::Locked).count();
    *locked_share = Some(locked as f64 / run.pps.len() as f64);
    let unlocked: Vec<UtcNanos> = run
        .pps
        .iter()
        .filter(|p| p.1 != PpsStatus::Locked)
        .map(|p| p.0)
        .collect();
    if th.require_pps && !unlocked.is_empty() {
        let drift = meta("lidar", "drift_ppm");
        let dur = secs(unlocked[0], unlocked[unlocked.len() - 1]);
        log.fault(
            FaultName::LidarNotPpsLocked,
            unlocked[0],
            unlocked[unlocked.len() - 1],
            format!(
                "{} of {} position packets report no PPS lock; the lidar clock runs free{}",
                unlocked.len(),
                run.pps.len(),
                // The clock model's drift is the change of host - sensor time per second of
                // sensor time: negative when the lidar's clock runs ahead of the host's.
                match drift {
                    Some(d) => format!(
                        ", running {:.1} ppm {} than host time ({:.2} ms over {dur:.1} s)",
                        d.abs(),
                        if d < 0.0 { "faster" } else { "slower" },
                        d.abs() * 1e-6 * dur * 1e3
                    ),
                    None => String::new(),
                }
            ),
        );
        // Without PPS the lidar's time is the host clock model's: its residual spread.
        lidar_time_error_s = meta("lidar", "residual_p95_ns").unwrap_or(0.0) * 1e-9;
        if lidar_time_error_s * 1e6 > th.max_clock_residual_p95_us {
            log.fault(
                FaultName::LidarClockResidual,
                unlocked[0],
                unlocked[unlocked.len() - 1],
                format!(
                    "lidar clock-model residual p95 {:.0} µs above {:.0} µs",
                    lidar_time_error_s * 1e6,
                    th.max_clock_residual_p95_us
                ),
            );
        }
    }
    lidar_time_error_s
}

/// Rate, period, jitter and gaps of one source; a gap over `gap_periods` periods is a fault.
fn timing(
    log: &mut FaultLog,
    source: &str,
    gap_name: FaultName,
    times: &[UtcNanos],
    gap_periods: f64,
) -> SourceTiming {
    let Some(period) = median_interval(times) else {
        return SourceTiming {
            source: source.to_owned(),
            count: times.len(),
            ..SourceTiming::default()
        };
    };
    let iv: Vec<f64> = times.windows(2).map(|w| (w[1].0 - w[0].0) as f64).collect();
    let mean = iv.iter().sum::<f64>() / iv.len() as f64;
    let jitter = (iv.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / iv.len() as f64).sqrt();
    let limit = gap_periods * period as f64;
    let mut gaps = 0;
    for w in times.windows(2) {
        let d = (w[1].0 - w[0].0) as f64;
        if d > limit {
            gaps += 1;
            log.fault(
                gap_name,
                w[0],
                w[1],
                format!(
                    "{source}: no data for {:.1} ms (about {:.0} samples missing; limit {:.0} periods of {:.3} ms)",
                    d * 1e-6,
                    d / period as f64 - 1.0,
                    gap_periods,
                    period as f64 * 1e-6
                ),
            );
        }
    }
    SourceTiming {
        source: source.to_owned(),
        count: times.len(),
        rate_hz: (times.len() - 1) as f64 / secs(times[0], times[times.len() - 1]).max(1e-9),
        period_ms: period as f64 * 1e-6,
        jitter_ms: jitter * 1e-6,
        gaps,
        max_interval_ms: iv.iter().copied().fold(0.0, f64::max) * 1e-6,
    }
}

//! Temporal accuracy: per-source rate, gaps and jitter; the PPS state and the clock models the
//! recorder wrote into the MCAP; the lidar-to-GNSS offset; how far the ego moves between GNSS
//! epochs and what linear interpolation between them would cost.

use super::faults::{secs, FaultLog};
use super::names::FaultName;
use super::report::{SourceTiming, Stats, Temporal};
use crate::bag::clock_sync::ClockSync;
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
    let mut tm = Temporal {
        logger_ahead_of_gnss_ms: run.logger_ahead_of_gnss_ns.map(|n| n as f64 * 1e-6),
        can_on_gnss_time: run.logger_clock.on_gnss(),
        logger_clock: run.logger_clock.state,
        ..Temporal::default()
    };
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
    let (clocks, unreadable) = ClockSync::of_recording(&run.metadata);
    for e in unreadable {
        tracing::warn!("{e}: its clock model is left out");
    }
    tm.clock_sync = clocks;
    if let (Some(l), Some(g)) = (tm.clock_sync.get("lidar"), tm.clock_sync.get("gnss")) {
        tm.lidar_to_gnss_offset_ms = Some((l.offset_ns - g.offset_ns) as f64 * 1e-6);
    }
    let lidar_clock = tm.clock_sync.get("lidar").cloned();
    let lidar_time_error_s = pps(run, th, lidar_clock.as_ref(), &mut tm.pps_locked_share, log);
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
    lidar_clock: Option<&ClockSync>,
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
        let drift = lidar_clock.map(|c| c.drift_ppm);
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
        lidar_time_error_s = lidar_clock.map_or(0.0, |c| c.residual_p95_ns as f64 * 1e-9);
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

/// Rate, period, jitter and gaps of one source; `gap_periods` samples missing in a row are a
/// gap, a fault.
fn timing(
    log: &mut FaultLog,
    source: &str,
    gap_name: FaultName,
    times: &[UtcNanos],
    gap_periods: u32,
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
    // `gap_periods` samples missing in a row: an interval of that many periods beyond the
    // one every sample has, less half a period of jitter. (An interval over `gap_periods`
    // periods made two lost lidar packets a gap whenever jitter stretched them by a
    // microsecond: 2 of 30 clean drives with the fixture's 0.05 % packet loss failed so.)
    let limit = (f64::from(gap_periods) + 0.5) * period as f64;
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
                    "{source}: no data for {:.1} ms (about {:.0} samples missing; a gap is {} missing in a row, periods of {:.3} ms)",
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

#[cfg(test)]
mod tests {
    use super::super::test_drive::{self, fix, Drive, T0};
    use super::*;
    use nalgebra::Vector2;

    fn at_ms(ms: &[i64]) -> Vec<UtcNanos> {
        ms.iter().map(|m| UtcNanos(T0 + m * 1_000_000)).collect()
    }

    #[test]
    fn the_period_is_the_median_interval_between_distinct_times() {
        // Intervals 100, 0 (a repeated stamp), 100, 100, 700 ms.
        let t = at_ms(&[0, 100, 100, 200, 300, 1000]);
        assert_eq!(median_interval(&t), Some(100_000_000));
        assert_eq!(median_interval(&at_ms(&[5])), None);
        assert_eq!(median_interval(&at_ms(&[5, 5])), None);
    }

    #[test]
    fn rate_period_jitter_and_gaps_of_a_source_are_those_of_its_intervals() {
        // 50 Hz with intervals alternating 19 and 21 ms: mean 20 ms, standard deviation 1 ms.
        let mut ms = vec![0i64];
        for k in 0..100 {
            ms.push(ms[k] + if k % 2 == 0 { 19 } else { 21 });
        }
        let mut log = FaultLog::new(UtcNanos(T0));
        let s = timing(&mut log, "can", FaultName::CanGap, &at_ms(&ms), 3);
        assert_eq!(s.count, 101);
        assert!((s.rate_hz - 50.0).abs() < 1e-9, "{}", s.rate_hz);
        assert!((s.period_ms - 21.0).abs() < 1e-9 || (s.period_ms - 19.0).abs() < 1e-9);
        assert!(
            (s.jitter_ms - 1.0).abs() < 1e-9,
            "jitter {} ms",
            s.jitter_ms
        );
        assert_eq!(s.gaps, 0);
        assert!(log.faults.is_empty());
        // Every 20 ms, but nothing from 1.0 to 1.1 s: one gap of 100 ms (four samples missing)
        // over the 3-period limit, located from the last sample before it to the first after.
        // The sample at 0.5 s is missing too: 40 ms, within the limit.
        let ms: Vec<i64> = (0..100)
            .map(|k| k * 20)
            .filter(|m| !(1001..1100).contains(m) && *m != 500)
            .collect();
        let s = timing(&mut log, "gnss", FaultName::GnssGap, &at_ms(&ms), 3);
        assert_eq!(s.gaps, 1, "gaps of 3 or more missing samples of 20 ms");
        assert!((s.period_ms - 20.0).abs() < 1e-9);
        assert!((s.max_interval_ms - 100.0).abs() < 1e-9);
        assert_eq!(log.faults.len(), 1);
        let f = &log.faults[0];
        assert_eq!((f.name, f.from_s, f.to_s), (FaultName::GnssGap, 1.0, 1.1));
        assert!(
            f.detail
                .contains("no data for 100.0 ms (about 4 samples missing"),
            "{}",
            f.detail
        );
    }

    /// Two samples lost in a row are no gap however the jitter falls (the interval is three
    /// periods, a microsecond either side); three in a row are.
    #[test]
    fn a_gap_is_as_many_samples_missing_in_a_row_as_the_rig_says() {
        let period_us = 1327i64;
        let at_us =
            |us: &[i64]| -> Vec<UtcNanos> { us.iter().map(|u| UtcNanos(T0 + u * 1000)).collect() };
        for (lost, jitter_us, gap) in [(2, 1, false), (2, -1, false), (3, -1, true)] {
            let mut us: Vec<i64> = (0..200).map(|k| k * period_us).collect();
            us.drain(100..100 + lost);
            for u in &mut us[100..] {
                *u += jitter_us;
            }
            let mut log = FaultLog::new(UtcNanos(T0));
            let s = timing(&mut log, "lidar", FaultName::LidarGap, &at_us(&us), 3);
            assert_eq!(s.gaps == 1, gap, "{lost} lost, jitter {jitter_us} µs");
        }
    }

    #[test]
    fn motion_and_interpolation_between_epochs_are_the_chord_and_the_sagitta_of_the_turn() {
        // A 20 m circle at 5 m/s (0.25 rad/s): GNSS every 100 ms is a chord of 2R sin(ωT/2),
        // and its midpoint lies R (1 − cos(ωT/2)) inside the arc.
        let (r, w, period) = (20.0f64, 0.25f64, 0.1f64);
        let drive = Drive::new(5.0, &[(10.0, 0.0, w)]);
        let lever = Vector2::new(0.6, 0.0);
        let gnss = drive.gnss(lever, 0.0);
        let motion = drive.motion(1.0, 0.0);
        let traj = test_drive::smooth(&gnss, &motion, lever);
        let fixes: Vec<hilrig_gnss::Fix> = gnss
            .iter()
            .map(|g| fix(g.t, 4, (0.01, 0.01), 1.0))
            .collect();
        let epochs: Vec<(UtcNanos, &Fix)> = fixes.iter().map(|f| (f.time.unwrap(), f)).collect();
        let mut run = test_drive::run(motion);
        let clock = |offset_ns: f64| ClockSync::of_model(0, offset_ns, 0.0, [0.0; 3], 100);
        run.metadata
            .insert("clock_sync/lidar".into(), clock(5e6).to_metadata());
        run.metadata
            .insert("clock_sync/gnss".into(), clock(2e6).to_metadata());
        let mut log = FaultLog::new(UtcNanos(T0));
        let (tm, lidar_error) = measure(&run, &epochs, &traj, &Thresholds::default(), &mut log);
        let chord = 2.0 * r * (w * period / 2.0).sin();
        let sagitta = r * (1.0 - (w * period / 2.0).cos());
        let between = tm.motion_between_epochs_m;
        assert_eq!(between.n, 100);
        assert!(
            (between.median - chord).abs() < 1e-4,
            "{} vs {chord}",
            between.median
        );
        let interp = tm.interpolation_error_m;
        assert!(
            (interp.median - sagitta).abs() < 0.02 * sagitta
                && (interp.p95 - sagitta).abs() < 0.02 * sagitta,
            "interpolation error median {} p95 {} m, sagitta {sagitta} m",
            interp.median,
            interp.p95
        );
        // The lidar's clock is 3 ms ahead of the GNSS's (from the clock models); without
        // position packets there is no PPS state and no lidar time error.
        let lidar_to_gnss = tm.lidar_to_gnss_offset_ms.unwrap();
        assert!(
            (lidar_to_gnss - 3.0).abs() < 1e-9,
            "lidar to GNSS {lidar_to_gnss} ms; the lidar's clock offset 5 ms, the GNSS's 2 ms"
        );
        assert_eq!((tm.pps_locked_share, lidar_error), (None, 0.0));
        // Sources: GNSS at 10 Hz, the ego motion (no raw frames: one source) at 50 Hz.
        let names: Vec<&str> = tm.sources.iter().map(|s| s.source.as_str()).collect();
        assert_eq!(names, ["gnss", "can 0x0"]);
        assert!((tm.sources[0].rate_hz - 10.0).abs() < 1e-9);
        assert!((tm.sources[1].rate_hz - 50.0).abs() < 1e-9);
        assert!(log.faults.is_empty(), "{:?}", log.faults);
    }

    #[test]
    fn can_sources_are_the_messages_that_carry_the_ego_motion() {
        let motion = Drive::new(0.0, &[(1.0, 0.0, 0.0)]).motion(1.0, 0.0);
        let mut run = test_drive::run(motion.clone());
        // 0x123 carries the motion (its frames arrive when the motion was written), 0x456 is
        // another message on the bus at other instants.
        for m in &motion {
            run.can_frames.push((m.t, 0x123));
            run.can_frames.push((UtcNanos(m.t.0 + 3_000_000), 0x456));
        }
        let ego = ego_messages(&run);
        assert_eq!(ego.len(), 1);
        assert_eq!(ego[0].0, 0x123);
        assert_eq!(ego[0].1.len(), motion.len());
    }

    #[test]
    fn a_free_running_lidar_clock_fails_and_counts_its_clock_residual() {
        let mut run = test_drive::run(vec![]);
        // Three position packets of four report a PPS lock.
        for (k, s) in [
            PpsStatus::Locked,
            PpsStatus::Absent,
            PpsStatus::Locked,
            PpsStatus::Locked,
        ]
        .into_iter()
        .enumerate()
        {
            run.pps.push((UtcNanos(T0 + k as i64 * 1_000_000_000), s));
        }
        let clock = ClockSync::of_model(0, 0.0, -60e-6, [0.0, 1_500_000.0, 2e6], 100);
        let meta = Some(&clock);
        let mut share = None;
        let mut log = FaultLog::new(UtcNanos(T0));
        let error = pps(&run, &Thresholds::default(), meta, &mut share, &mut log);
        assert_eq!(share, Some(0.75));
        // The clock model's residual p95 is the lidar's time error: 1.5 ms, over the 1 ms limit.
        assert!((error - 1.5e-3).abs() < 1e-12, "{error}");
        let names: Vec<FaultName> = log.faults.iter().map(|f| f.name).collect();
        assert_eq!(
            names,
            [FaultName::LidarNotPpsLocked, FaultName::LidarClockResidual]
        );
        // Host minus sensor time falling by 60 µs a second: the lidar's clock runs fast.
        assert!(
            log.faults[0].detail.contains("running 60.0 ppm faster"),
            "{}",
            log.faults[0].detail
        );
        // A rig that does not require PPS: the share is reported, nothing else.
        let th = Thresholds {
            require_pps: false,
            ..Thresholds::default()
        };
        let mut log = FaultLog::new(UtcNanos(T0));
        assert_eq!(pps(&run, &th, meta, &mut share, &mut log), 0.0);
        assert!(log.faults.is_empty());
    }
}

//! `hilrig check`: the post-drive gate (seed §6). Reference data that are not accurate enough
//! make every later metric meaningless, so before anything is re-simulated the run's spatial and
//! temporal accuracy are measured, combined into one reference accuracy, and turned into the
//! smallest admissible grid cell: max(10 cm, 10 × accuracy).
//!
//! Every problem found is a [`Fault`] with a name, a time window and the numbers behind it;
//! one-second segments take the verdict of the faults that overlap them, so the engineer sees
//! which parts of the drive are usable and why the others are not.
//!
//! What is measured and how:
//! - spatial: RTK state per epoch, the receiver's sigmas (GST/UBX), correction age, jumps (GNSS
//!   epochs that the smoothed GNSS+CAN trajectory cannot explain once the systematic errors below
//!   are taken out), GNSS against CAN: speed scale by regressing GNSS speed on CAN speed (and
//!   acceleration) on straight driving; GNSS time offset and antenna lever arm as constant states
//!   of the smoother (a time offset misfits along track whenever the speed changes, a lever-arm
//!   error sideways in turns); yaw rate against the GNSS course rate over a second; travelled
//!   distance; the scene's survey accuracy;
//! - temporal: per-source rate, gaps and jitter; PPS state and the clock models recorded in the
//!   MCAP; the lidar-to-GNSS offset; how far the ego moves between GNSS epochs and what linear
//!   interpolation between them would cost.

use super::run::Run;
use super::trajectory::{EgoTrajectory, GnssObs, Settings};
use crate::scene::geodesy::Enu;
use crate::rig::{Rig, Thresholds};
use crate::scene::file::Wgs84;
use crate::scene::Scene;
use hilrig_gnss::RtkState;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::PpsStatus;
use nalgebra::Vector2;
use serde::Serialize;

/// The overall verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// Accurate enough: re-simulate.
    Pass,
    /// Not accurate enough (see the faults).
    Fail,
    /// The input cannot be judged (no GNSS, no ego motion, unreadable).
    Unusable,
}

impl Verdict {
    /// The process exit code: 0 pass, 1 fail, 2 unusable.
    pub fn exit_code(self) -> u8 {
        match self {
            Verdict::Pass => 0,
            Verdict::Fail => 1,
            Verdict::Unusable => 2,
        }
    }
}

/// One problem, located in time.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Fault {
    /// What it is (`rtk_float`, `rtk_none`, `sigma_spike`, `correction_age`, `jump`,
    /// `can_speed_scale`, `gnss_time_offset`, `lever_arm`, `lidar_not_pps_locked`,
    /// `lidar_clock_residual`, `lidar_gap`, `gnss_gap`, `can_gap`).
    pub name: &'static str,
    /// Start (UTC).
    pub from: String,
    /// End (UTC).
    pub to: String,
    /// Start, seconds after the run's start.
    pub from_s: f64,
    /// End, seconds after the run's start.
    pub to_s: f64,
    /// What was measured, against which limit.
    pub detail: String,
    #[serde(skip)]
    window: (UtcNanos, UtcNanos),
}

/// Statistics of a series.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Stats {
    /// Samples.
    pub n: usize,
    /// Median.
    pub median: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Largest.
    pub max: f64,
    /// Root mean square.
    pub rms: f64,
}

impl Stats {
    fn of(mut v: Vec<f64>) -> Stats {
        v.retain(|x| x.is_finite());
        if v.is_empty() {
            return Stats::default();
        }
        let rms = (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
        Stats {
            n: v.len(),
            median: q(0.5),
            p95: q(0.95),
            max: v[v.len() - 1],
            rms,
        }
    }
}

/// The RTK state of one GNSS epoch.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RtkEpoch {
    /// Epoch time (UTC, ISO 8601 with milliseconds, as gpsd writes it).
    pub time: String,
    /// `fixed`, `float` or `none`.
    pub state: &'static str,
}

/// Spatial measurements.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Spatial {
    /// GNSS epochs.
    pub epochs: usize,
    /// RTK state per epoch.
    pub rtk_epochs: Vec<RtkEpoch>,
    /// Epochs per RTK state.
    pub rtk_fixed: usize,
    /// Float epochs.
    pub rtk_float: usize,
    /// Epochs without carrier-phase solution.
    pub rtk_none: usize,
    /// Share of RTK-fixed epochs.
    pub rtk_fixed_share: f64,
    /// Receiver 1-sigma horizontal error per axis (larger of lat/lon), m.
    pub sigma_horizontal_m: Stats,
    /// The three one-second windows with the largest horizontal sigma: (from s, to s, sigma m).
    pub worst_sigma_windows: Vec<(f64, f64, f64)>,
    /// Receiver 1-sigma vertical error, m.
    pub sigma_vertical_m: Stats,
    /// Correction age, s.
    pub correction_age_s: Stats,
    /// GNSS residuals against the smoothed trajectory, m (per axis).
    pub residual_m: Stats,
    /// Epochs that the trajectory cannot explain.
    pub jumps: usize,
    /// CAN speed / GNSS speed.
    pub can_speed_scale: Option<f64>,
    /// GNSS speed minus corrected CAN speed, m/s.
    pub speed_residual_mps: Stats,
    /// GNSS course rate minus CAN yaw rate, rad/s.
    pub yaw_rate_residual_rps: Stats,
    /// Distance by CAN speed, m.
    pub distance_can_m: f64,
    /// Distance along the GNSS antenna track, m.
    pub distance_gnss_m: f64,
    /// GNSS time stamps minus the instants they describe, measured against CAN, ms.
    pub gnss_time_offset_ms: Option<f64>,
    /// Antenna x (forward) from the data, m.
    pub lever_arm_x_measured_m: Option<f64>,
    /// Antenna x from the rig file, m.
    pub lever_arm_x_rig_m: f64,
    /// Worst survey accuracy of the scene's static objects, m (1 sigma).
    pub scene_accuracy_m: Option<f64>,
}

/// One source's timing.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SourceTiming {
    /// Source.
    pub source: &'static str,
    /// Samples.
    pub count: usize,
    /// Mean rate, Hz.
    pub rate_hz: f64,
    /// Nominal period (median interval), ms.
    pub period_ms: f64,
    /// Interval jitter (standard deviation), ms.
    pub jitter_ms: f64,
    /// Gaps (intervals over the gap limit).
    pub gaps: usize,
    /// Longest interval, ms.
    pub max_interval_ms: f64,
}

/// Temporal measurements.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Temporal {
    /// Per source.
    pub sources: Vec<SourceTiming>,
    /// Position packets reporting PPS lock.
    pub pps_locked_share: Option<f64>,
    /// Clock-sync metadata of the recording, per source.
    pub clock_sync: std::collections::BTreeMap<String, std::collections::BTreeMap<String, String>>,
    /// Lidar minus GNSS clock offset (host latencies included), ms.
    pub lidar_to_gnss_offset_ms: Option<f64>,
    /// How far the ego moves between GNSS epochs (speed × interval), m.
    pub motion_between_epochs_m: Stats,
    /// Error of interpolating linearly between GNSS epochs, m.
    pub interpolation_error_m: Stats,
}

/// The accuracy budget (1 sigma, metres).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Accuracy {
    /// Ego position from RTK (receiver sigmas, inflated if the residuals say they are optimistic).
    pub trajectory_m: f64,
    /// Time errors times speed.
    pub temporal_m: f64,
    /// Interpolation between reference samples.
    pub interpolation_m: f64,
    /// Lever arm error, when one is found.
    pub lever_arm_m: f64,
    /// The ego reference (root sum of squares of the above).
    pub ego_m: f64,
    /// Static objects (scene survey).
    pub scene_m: Option<f64>,
    /// Everything combined.
    pub reference_m: f64,
    /// Smallest admissible grid cell: max(min cell, factor × reference), m.
    pub grid_cell_m: f64,
}

/// A stretch of the run with one verdict.
#[derive(Clone, Debug, Serialize)]
pub struct Segment {
    /// Start, s after the run's start.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
    /// Pass or fail.
    pub verdict: Verdict,
    /// Names of the faults that make it fail.
    pub reasons: Vec<&'static str>,
}

/// The whole report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Overall verdict.
    pub verdict: Verdict,
    /// Why unusable, if so.
    pub unusable: Option<String>,
    /// Run start (UTC).
    pub start: String,
    /// Duration, s.
    pub duration_s: f64,
    /// Spatial measurements.
    pub spatial: Spatial,
    /// Temporal measurements.
    pub temporal: Temporal,
    /// Accuracy budget.
    pub accuracy: Accuracy,
    /// Faults found.
    pub faults: Vec<Fault>,
    /// Usable and unusable stretches.
    pub segments: Vec<Segment>,
    /// Problems reading the recording.
    pub damage: Option<String>,
}

fn iso(t: UtcNanos) -> String {
    hilrig_stamp::civil::iso8601_millis(t)
}

fn secs(a: UtcNanos, b: UtcNanos) -> f64 {
    (b.0 - a.0) as f64 * 1e-9
}

struct Ctx {
    start: UtcNanos,
    faults: Vec<Fault>,
}

impl Ctx {
    fn fault(&mut self, name: &'static str, from: UtcNanos, to: UtcNanos, detail: String) {
        self.faults.push(Fault {
            name,
            from: iso(from),
            to: iso(to),
            from_s: secs(self.start, from),
            to_s: secs(self.start, to),
            detail,
            window: (from, to),
        });
    }

    /// Faults for runs of consecutive flagged samples (a run ends after `gap` without a flag).
    fn runs(
        &mut self,
        name: &'static str,
        flagged: &[(UtcNanos, f64)],
        period: i64,
        describe: impl Fn(usize, f64) -> String,
    ) {
        let mut i = 0;
        while i < flagged.len() {
            let mut j = i + 1;
            while j < flagged.len() && flagged[j].0 .0 - flagged[j - 1].0 .0 <= period * 3 / 2 {
                j += 1;
            }
            let worst = flagged[i..j].iter().map(|f| f.1).fold(f64::NAN, f64::max);
            let (a, b) = (flagged[i].0, UtcNanos(flagged[j - 1].0 .0 + period));
            self.fault(name, a, b, describe(j - i, worst));
            i = j;
        }
    }
}

fn median_interval(times: &[UtcNanos]) -> Option<i64> {
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

fn timing(
    ctx: &mut Ctx,
    source: &'static str,
    gap_name: &'static str,
    times: &[UtcNanos],
    gap_periods: f64,
) -> SourceTiming {
    let Some(period) = median_interval(times) else {
        return SourceTiming {
            source,
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
            ctx.fault(
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
        source,
        count: times.len(),
        rate_hz: (times.len() - 1) as f64 / secs(times[0], times[times.len() - 1]).max(1e-9),
        period_ms: period as f64 * 1e-6,
        jitter_ms: jitter * 1e-6,
        gaps,
        max_interval_ms: iv.iter().copied().fold(0.0, f64::max) * 1e-6,
    }
}

/// Linear interpolation of CAN motion at `t`: (speed, yaw rate).
fn motion_at(m: &[super::run::Motion], t: UtcNanos) -> Option<(f64, f64)> {
    let k = m.partition_point(|x| x.t <= t);
    if k == 0 || k >= m.len() {
        return None;
    }
    let (a, b) = (&m[k - 1], &m[k]);
    let f = secs(a.t, t) / secs(a.t, b.t).max(1e-9);
    Some((
        a.speed + (b.speed - a.speed) * f,
        a.yaw_rate + (b.yaw_rate - a.yaw_rate) * f,
    ))
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// Checks a run. `scene` gives the origin of the local frame and the objects' survey accuracy;
/// without it the first GNSS epoch is the origin.
pub fn check(run: &Run, rig: &Rig, scene: Option<&Scene>) -> Report {
    check_with_trajectory(run, rig, scene).0
}

/// [`check`], and the ego trajectory it smoothed (RTK GNSS and CAN with the rig's lever arm, in
/// the scene's local frame) when the run has one: what re-simulation casts from, without
/// smoothing the run a second time.
pub fn check_with_trajectory(
    run: &Run,
    rig: &Rig,
    scene: Option<&Scene>,
) -> (Report, Option<EgoTrajectory>) {
    let mut trajectory = None;
    let report = check_into(run, rig, scene, &mut trajectory);
    (report, trajectory)
}

fn check_into(
    run: &Run,
    rig: &Rig,
    scene: Option<&Scene>,
    trajectory_out: &mut Option<EgoTrajectory>,
) -> Report {
    let th: &Thresholds = &rig.thresholds;
    let unusable = |why: String, spatial: Spatial| Report {
        verdict: Verdict::Unusable,
        unusable: Some(why),
        start: String::new(),
        duration_s: 0.0,
        spatial,
        temporal: Temporal::default(),
        accuracy: Accuracy::default(),
        faults: Vec::new(),
        segments: Vec::new(),
        damage: run.damage.clone(),
    };
    // Epochs with a position and a time.
    let epochs = gnss_epochs(run);
    if epochs.len() < 2 {
        return unusable(
            format!(
                "{} GNSS epochs with a position (is there a /gnss/nmea or /gnss/ubx stream?)",
                epochs.len()
            ),
            Spatial::default(),
        );
    }
    let mut all_times: Vec<UtcNanos> = vec![epochs[0].0, epochs[epochs.len() - 1].0];
    if let (Some(a), Some(b)) = (run.motion.first(), run.motion.last()) {
        all_times.extend([a.t, b.t]);
    }
    if let (Some(a), Some(b)) = (run.packets.first(), run.packets.last()) {
        all_times.extend([a.host, b.host]);
    }
    let start = *all_times.iter().min().unwrap_or(&epochs[0].0);
    let end = *all_times.iter().max().unwrap_or(&epochs[0].0);
    let mut ctx = Ctx {
        start,
        faults: Vec::new(),
    };
    let origin = local_origin(&epochs, scene);
    let enu = Enu::new(&origin);
    let gnss_period =
        median_interval(&epochs.iter().map(|e| e.0).collect::<Vec<_>>()).unwrap_or(100_000_000);

    // --- Spatial: RTK state, sigmas, correction age.
    let mut sp = Spatial {
        epochs: epochs.len(),
        lever_arm_x_rig_m: rig.gnss.as_ref().map_or(0.0, |g| g.antenna.x),
        ..Spatial::default()
    };
    let (mut float_epochs, mut none_epochs, mut spikes, mut old) = (vec![], vec![], vec![], vec![]);
    let (mut sig_h, mut sig_v, mut ages) = (vec![], vec![], vec![]);
    for &(t, f) in &epochs {
        match f.rtk {
            RtkState::Fixed => sp.rtk_fixed += 1,
            RtkState::Float => {
                sp.rtk_float += 1;
                float_epochs.push((t, f64::from(f.quality)));
            }
            RtkState::None => {
                sp.rtk_none += 1;
                none_epochs.push((t, f64::from(f.quality)));
            }
        }
        let h = f.sigma_lat_m.zip(f.sigma_lon_m).map(|(a, b)| a.max(b));
        if let Some(h) = h {
            sig_h.push(h);
        }
        if let Some(v) = f.sigma_alt_m {
            sig_v.push(v);
        }
        if f.rtk == RtkState::Fixed
            && (h.is_some_and(|h| h > th.max_sigma_horizontal_m)
                || f.sigma_alt_m.is_some_and(|v| v > th.max_sigma_vertical_m))
        {
            spikes.push((t, h.unwrap_or(0.0)));
        }
        if let Some(a) = f.correction_age_s {
            ages.push(a);
            if a > th.max_correction_age_s {
                old.push((t, a));
            }
        }
    }
    sp.rtk_fixed_share = sp.rtk_fixed as f64 / epochs.len() as f64;
    sp.sigma_horizontal_m = Stats::of(sig_h);
    let mut windows: std::collections::BTreeMap<i64, f64> = std::collections::BTreeMap::new();
    for &(t, f) in &epochs {
        if let Some(h) = f.sigma_lat_m.zip(f.sigma_lon_m).map(|(a, b)| a.max(b)) {
            let w = windows
                .entry((t.0 - start.0).div_euclid(1_000_000_000))
                .or_insert(0.0);
            *w = w.max(h);
        }
    }
    let mut worst: Vec<(i64, f64)> = windows.into_iter().collect();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    sp.worst_sigma_windows = worst
        .iter()
        .take(3)
        .map(|&(k, h)| (k as f64, k as f64 + 1.0, h))
        .collect();
    sp.sigma_vertical_m = Stats::of(sig_v);
    sp.correction_age_s = Stats::of(ages);
    ctx.runs("rtk_float", &float_epochs, gnss_period, |n, _| {
        format!("{n} epochs with an RTK float solution (GGA quality 5)")
    });
    ctx.runs("rtk_none", &none_epochs, gnss_period, |n, q| {
        format!("{n} epochs without an RTK solution (GGA quality {q:.0})")
    });
    ctx.runs("sigma_spike", &spikes, gnss_period, |n, worst| {
        format!(
            "{n} fixed epochs with sigma above {:.3} m (horizontal) or {:.3} m (vertical); worst horizontal {worst:.3} m",
            th.max_sigma_horizontal_m, th.max_sigma_vertical_m
        )
    });
    ctx.runs("correction_age", &old, gnss_period, |n, worst| {
        format!(
            "{n} epochs with corrections older than {:.1} s (worst {worst:.1} s)",
            th.max_correction_age_s
        )
    });
    if sp.rtk_fixed_share < th.min_rtk_fixed_share {
        // Located by the float/none faults above; this one states the share.
        let (a, b) = (epochs[0].0, epochs[epochs.len() - 1].0);
        ctx.fault(
            "rtk_fixed_share",
            a,
            b,
            format!(
                "{:.1} % of epochs RTK-fixed, below {:.1} %",
                sp.rtk_fixed_share * 100.0,
                th.min_rtk_fixed_share * 100.0
            ),
        );
    }

    sp.rtk_epochs = epochs
        .iter()
        .map(|(t, f)| RtkEpoch {
            time: iso(*t),
            state: f.rtk.name(),
        })
        .collect();
    if run.motion.len() < 2 {
        return unusable(
            "no ego motion (/ego/twist): the rig needs a CAN speed and yaw-rate mapping".into(),
            sp,
        );
    }

    // --- The smoothed trajectory.
    let lever = rig
        .gnss
        .as_ref()
        .map_or(Vector2::zeros(), |g| Vector2::new(g.antenna.x, g.antenna.y));
    let obs = observations(&epochs, &enu);
    let motion: Vec<(UtcNanos, f64, f64)> = run
        .motion
        .iter()
        .map(|m| (m.t, m.speed, m.yaw_rate))
        .collect();
    let traj = match EgoTrajectory::smooth(
        &obs,
        &motion,
        &Settings {
            lever,
            ..Settings::default()
        },
    ) {
        Ok(t) => t,
        Err(e) => return unusable(e.to_string(), sp),
    };
    let fixed: Vec<bool> = epochs
        .iter()
        .map(|(_, f)| f.rtk == RtkState::Fixed)
        .collect();
    // Epochs good enough to differentiate: fixed and within the sigma limits.
    let good: Vec<bool> = epochs
        .iter()
        .map(|(_, f)| {
            f.rtk == RtkState::Fixed
                && f.sigma_lat_m
                    .zip(f.sigma_lon_m)
                    .is_none_or(|(a, b)| a.max(b) <= th.max_sigma_horizontal_m)
        })
        .collect();
    // --- GNSS against CAN: antenna velocities on fixed epochs, central differences.
    struct Vel {
        t: UtcNanos,
        speed: f64,
        course: f64,
    }
    let mut vels = Vec::new();
    for k in 1..obs.len().saturating_sub(1) {
        if !(good[k - 1] && good[k] && good[k + 1]) {
            continue;
        }
        let dt = secs(obs[k - 1].t, obs[k + 1].t);
        if dt <= 0.0 || dt > 3.0 * gnss_period as f64 * 1e-9 {
            continue;
        }
        let d = (obs[k + 1].position - obs[k - 1].position) / dt;
        vels.push(Vel {
            t: obs[k].t,
            speed: d.norm(),
            course: d.y.atan2(d.x),
        });
    }
    let accel_at = |t: UtcNanos| -> Option<f64> {
        let h = 100_000_000;
        let (a, _) = motion_at(&run.motion, UtcNanos(t.0 - h))?;
        let (b, _) = motion_at(&run.motion, UtcNanos(t.0 + h))?;
        Some((b - a) / 0.2)
    };
    // Straight driving: v_gnss = b1 v_can + b2 a_can (scale 1/b1, time offset -b2/b1).
    let (mut s11, mut s12, mut s22, mut r1, mut r2, mut n_straight) = (0.0, 0.0, 0.0, 0.0, 0.0, 0);
    let mut moving_span: Option<(UtcNanos, UtcNanos)> = None;
    for v in &vels {
        let (Some((vc, w)), Some(a)) = (motion_at(&run.motion, v.t), accel_at(v.t)) else {
            continue;
        };
        if vc > 0.3 {
            moving_span = Some(moving_span.map_or((v.t, v.t), |(s, _)| (s, v.t)));
        }
        if vc > 0.3 && w.abs() < 0.05 {
            s11 += vc * vc;
            s12 += vc * a;
            s22 += a * a;
            r1 += vc * v.speed;
            r2 += a * v.speed;
            n_straight += 1;
        }
    }
    let det = s11 * s22 - s12 * s12;
    if n_straight >= 20 && s11 > 0.0 {
        let (b1, b2) = if s22 > 5.0 && det.abs() > 1e-9 {
            ((r1 * s22 - r2 * s12) / det, (s11 * r2 - s12 * r1) / det)
        } else {
            (r1 / s11, 0.0)
        };
        if b1 > 0.0 {
            let scale = 1.0 / b1;
            sp.can_speed_scale = Some(scale);
            // b2 (= -δ/scale) is not used: the smoother below fits the time offset far better
            // than a regression on the few accelerating epochs; it is in the model so that a time
            // offset does not bend the scale.
            let _ = b2;
            let span = moving_span.unwrap_or((start, end));
            if (scale - 1.0).abs() > th.max_speed_scale_error {
                ctx.fault(
                    "can_speed_scale",
                    span.0,
                    span.1,
                    format!(
                        "CAN speed is {:.2} % {} than GNSS speed ({n_straight} straight-driving epochs; limit {:.1} %)",
                        (scale - 1.0).abs() * 100.0,
                        if scale > 1.0 { "higher" } else { "lower" },
                        th.max_speed_scale_error * 100.0
                    ),
                );
            }
        }
    }
    // Time offset and lever arm, estimated as constant states of the smoother (CAN speed
    // corrected by the scale just measured, so that a scale error is not taken for a time
    // offset). A time offset shows as an along-track misfit whenever the speed changes (v·δ:
    // 11 cm for 50 ms at 8 km/h), a lever-arm error as a sideways misfit in turns, which CAN
    // (no side slip) cannot explain. Jumps are what is left once these are taken out.
    let speed_scale = sp.can_speed_scale.unwrap_or(1.0);
    let motion_fit: Vec<(UtcNanos, f64, f64)> = motion
        .iter()
        .map(|&(t, v, w)| (t, v / speed_scale, w))
        .collect();
    let fitted = EgoTrajectory::smooth(
        &obs,
        &motion_fit,
        &Settings {
            lever,
            estimate_offset_and_lever: true,
            ..Settings::default()
        },
    )
    .ok();
    let moving = run.motion.iter().filter(|m| m.speed > 0.5).count() >= 50;
    let turning = run
        .motion
        .iter()
        .filter(|m| m.yaw_rate.abs() > 0.1 && m.speed > 0.5)
        .count()
        >= 50;
    let (delta_fit, lever_fit) = match &fitted {
        Some(f) => {
            let (d, sd, x, sx) = f.offset_and_lever();
            (
                (moving && sd < 0.02).then_some(d),
                (turning && sx < 0.1).then_some(x),
            )
        }
        None => (None, None),
    };
    let traj_fit = fitted.as_ref().unwrap_or(&traj);
    sp.residual_m = Stats::of(
        traj_fit
            .residuals
            .iter()
            .zip(&fixed)
            .filter(|(_, &f)| f)
            .flat_map(|(r, _)| [r.error.x, r.error.y])
            .map(f64::abs)
            .collect(),
    );
    let jump_limit = th.max_jump_sigma.powi(2);
    let jumps: Vec<(UtcNanos, f64)> = traj_fit
        .residuals
        .iter()
        .zip(&fixed)
        .filter(|(r, &f)| f && r.nis > jump_limit)
        .map(|(r, _)| (r.t, r.error.norm()))
        .collect();
    sp.jumps = jumps.len();
    ctx.runs("jump", &jumps, gnss_period, |n, worst| {
        format!(
            "{n} fixed epochs more than {:.0} sigma off the trajectory that CAN speed and yaw rate allow (worst {worst:.3} m)",
            th.max_jump_sigma
        )
    });

    let offset_s = delta_fit.unwrap_or(0.0);
    sp.gnss_time_offset_ms = delta_fit.map(|d| d * 1e3);
    if (offset_s * 1e3).abs() > th.max_time_offset_ms {
        ctx.fault(
                "gnss_time_offset",
                moving_span.unwrap_or((start, end)).0,
                moving_span.unwrap_or((start, end)).1,
                format!(
                "GNSS time stamps are {:.1} ms {} the instants they describe, fitted against CAN motion (limit {:.0} ms)",
                offset_s.abs() * 1e3,
                if offset_s > 0.0 { "later than" } else { "earlier than" },
                th.max_time_offset_ms
                ),
            );
    }
    let scale = sp.can_speed_scale.unwrap_or(1.0);
    let delay = (offset_s * 1e9) as i64;
    // Residuals, distances, yaw rate and lever arm with the measured scale and offset applied.
    let mut speed_res = Vec::new();
    let mut yaw_res = Vec::new();
    // Yaw rate: the GNSS course change over about a second against integrated CAN yaw rate
    // (over one epoch the course noise of a few cm/s at walking pace would swamp it).
    let span_epochs = (1_000_000_000 / gnss_period.max(1)).max(1) as usize;
    for k in 0..vels.len().saturating_sub(span_epochs) {
        let (a, b) = (&vels[k], &vels[k + span_epochs]);
        let dt = secs(a.t, b.t);
        if dt <= 0.0
            || dt > 1.5 * span_epochs as f64 * gnss_period as f64 * 1e-9
            || a.speed < 1.0
            || b.speed < 1.0
        {
            continue;
        }
        let (ta, tb) = (UtcNanos(a.t.0 - delay), UtcNanos(b.t.0 - delay));
        let k0 = run.motion.partition_point(|m| m.t < ta);
        let k1 = run.motion.partition_point(|m| m.t <= tb);
        if k1 <= k0 + 1 {
            continue;
        }
        let turned: f64 = run.motion[k0..k1]
            .windows(2)
            .map(|w| 0.5 * (w[0].yaw_rate + w[1].yaw_rate) * secs(w[0].t, w[1].t))
            .sum();
        let covered = secs(run.motion[k0].t, run.motion[k1 - 1].t).max(1e-9);
        yaw_res.push(wrap(b.course - a.course) / dt - turned / covered);
    }
    // Speed residuals, and where the drive turns (where a lever-arm error shows).
    let mut n_turn = 0;
    let mut turn_span: Option<(UtcNanos, UtcNanos)> = None;
    for v in &vels {
        let tc = UtcNanos(v.t.0 - delay);
        if let Some((vc, w)) = motion_at(&run.motion, tc) {
            if vc > 0.5 {
                speed_res.push(v.speed - vc / scale);
            }
            if vc > 0.5 && w.abs() > 0.1 {
                n_turn += 1;
                turn_span = Some(turn_span.map_or((v.t, v.t), |(s, _)| (s, v.t)));
            }
        }
    }
    if let (Some(x), true) = (lever_fit, n_turn >= 10) {
        sp.lever_arm_x_measured_m = Some(x);
        if (x - sp.lever_arm_x_rig_m).abs() > th.max_lever_arm_error_m {
            let span = turn_span.unwrap_or((start, end));
            ctx.fault(
                "lever_arm",
                span.0,
                span.1,
                format!(
                    "GNSS against CAN in turns puts the antenna {x:.2} m ahead of the rear axle; the rig file says {:.2} m ({n_turn} turning epochs; limit {:.2} m)",
                    sp.lever_arm_x_rig_m, th.max_lever_arm_error_m
                ),
            );
        }
    }
    sp.speed_residual_mps = Stats::of(speed_res);
    sp.yaw_rate_residual_rps = Stats::of(yaw_res);
    sp.distance_can_m = run
        .motion
        .windows(2)
        .map(|w| 0.5 * (w[0].speed + w[1].speed) * secs(w[0].t, w[1].t))
        .sum();
    sp.distance_gnss_m = obs
        .windows(2)
        .zip(good.windows(2))
        .filter(|(_, f)| f[0] && f[1])
        .map(|(o, _)| (o[1].position - o[0].position).norm())
        .sum();
    sp.scene_accuracy_m = scene.map(|s| {
        s.file
            .objects
            .iter()
            .map(|o| o.accuracy_m)
            .chain(s.file.ground.map(|g| g.accuracy_m))
            .fold(0.0, f64::max)
    });

    // --- Temporal.
    let mut tm = Temporal::default();
    let gnss_times: Vec<UtcNanos> = epochs.iter().map(|e| e.0).collect();
    tm.sources.push(timing(
        &mut ctx,
        "gnss",
        "gnss_gap",
        &gnss_times,
        th.gap_periods,
    ));
    let can_times: Vec<UtcNanos> = run.motion.iter().map(|m| m.t).collect();
    tm.sources.push(timing(
        &mut ctx,
        "can",
        "can_gap",
        &can_times,
        th.gap_periods,
    ));
    if !run.packets.is_empty() {
        let lidar_times: Vec<UtcNanos> = run.packets.iter().map(|p| p.host).collect();
        tm.sources.push(timing(
            &mut ctx,
            "lidar",
            "lidar_gap",
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
    let mut lidar_time_error_s = 0.0;
    if !run.pps.is_empty() {
        let locked = run.pps.iter().filter(|p| p.1 == PpsStatus::Locked).count();
        tm.pps_locked_share = Some(locked as f64 / run.pps.len() as f64);
        let unlocked: Vec<UtcNanos> = run
            .pps
            .iter()
            .filter(|p| p.1 != PpsStatus::Locked)
            .map(|p| p.0)
            .collect();
        if th.require_pps && !unlocked.is_empty() {
            let drift = meta("lidar", "drift_ppm");
            let dur = secs(unlocked[0], unlocked[unlocked.len() - 1]);
            ctx.fault(
                "lidar_not_pps_locked",
                unlocked[0],
                unlocked[unlocked.len() - 1],
                format!(
                    "{} of {} position packets report no PPS lock; the lidar clock runs free{}",
                    unlocked.len(),
                    run.pps.len(),
                    match drift {
                        Some(d) => format!(
                            ", drifting {d:.1} ppm against host time ({:.2} ms over {dur:.1} s)",
                            d.abs() * 1e-6 * dur * 1e3
                        ),
                        None => String::new(),
                    }
                ),
            );
            // Without PPS the lidar's time is the host clock model's: its residual spread.
            lidar_time_error_s = meta("lidar", "residual_p95_ns").unwrap_or(0.0) * 1e-9;
            if lidar_time_error_s * 1e6 > th.max_clock_residual_p95_us {
                ctx.fault(
                    "lidar_clock_residual",
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
    }
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

    // --- Accuracy budget.
    let nis_fixed: Vec<f64> = traj
        .residuals
        .iter()
        .zip(&fixed)
        .filter(|(_, &f)| f)
        .map(|(r, _)| r.nis)
        .collect();
    let mean_nis = nis_fixed.iter().sum::<f64>() / nis_fixed.len().max(1) as f64;
    let v_p95 = Stats::of(run.motion.iter().map(|m| m.speed.abs()).collect()).p95;
    let mut acc = Accuracy {
        trajectory_m: sp.sigma_horizontal_m.median.max(sp.residual_m.rms)
            * (mean_nis / 2.0).max(1.0).sqrt(),
        // A time offset within its limit is not distinguishable from the estimate's own noise
        // (a few ms); one beyond it counts in full.
        temporal_m: v_p95
            * (if ctx.faults.iter().any(|f| f.name == "gnss_time_offset") {
                offset_s.powi(2)
            } else {
                0.0
            } + lidar_time_error_s.powi(2))
            .sqrt(),
        interpolation_m: tm.interpolation_error_m.p95,
        lever_arm_m: 0.0,
        ..Accuracy::default()
    };
    if sp.sigma_horizontal_m.n == 0 {
        acc.trajectory_m = sp.residual_m.rms * (mean_nis / 2.0).max(1.0).sqrt();
    }
    if ctx.faults.iter().any(|f| f.name == "lever_arm") {
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

    // --- Segments of one second.
    let mut segments: Vec<Segment> = Vec::new();
    let mut t = start;
    while t < end {
        let e = UtcNanos((t.0 + 1_000_000_000).min(end.0));
        let mut reasons: Vec<&'static str> = ctx
            .faults
            .iter()
            .filter(|f| f.window.0 < e && f.window.1 >= t)
            .map(|f| f.name)
            .collect();
        reasons.sort_unstable();
        reasons.dedup();
        let verdict = if reasons.is_empty() {
            Verdict::Pass
        } else {
            Verdict::Fail
        };
        match segments.last_mut() {
            Some(s) if s.verdict == verdict && s.reasons == reasons => s.to_s = secs(start, e),
            _ => segments.push(Segment {
                from_s: secs(start, t),
                to_s: secs(start, e),
                verdict,
                reasons,
            }),
        }
        t = e;
    }
    *trajectory_out = Some(traj);
    let verdict = if ctx.faults.is_empty() {
        Verdict::Pass
    } else {
        Verdict::Fail
    };
    Report {
        verdict,
        unusable: None,
        start: iso(start),
        duration_s: secs(start, end),
        spatial: sp,
        temporal: tm,
        accuracy: acc,
        faults: ctx.faults,
        segments,
        damage: run.damage.clone(),
    }
}

impl Report {
    /// The readable report.
    pub fn text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let v = match self.verdict {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::Unusable => "UNUSABLE",
        };
        let _ = writeln!(s, "verdict: {v}");
        if let Some(u) = &self.unusable {
            let _ = writeln!(s, "  {u}");
            if self.spatial.epochs > 0 {
                let sp = &self.spatial;
                let _ = writeln!(
                    s,
                    "GNSS only: {} epochs, {:.1} % RTK fixed ({} float, {} none)",
                    sp.epochs,
                    sp.rtk_fixed_share * 100.0,
                    sp.rtk_float,
                    sp.rtk_none
                );
            }
            return s;
        }
        let _ = writeln!(s, "run: {} + {:.1} s", self.start, self.duration_s);
        if let Some(d) = &self.damage {
            let _ = writeln!(s, "recording damaged: {d}");
        }
        let a = &self.accuracy;
        let _ = writeln!(
            s,
            "reference accuracy (1 sigma): {:.3} m = ego {:.3} m (RTK {:.3}, timing {:.3}, interpolation {:.4}, lever arm {:.3}){}",
            a.reference_m,
            a.ego_m,
            a.trajectory_m,
            a.temporal_m,
            a.interpolation_m,
            a.lever_arm_m,
            a.scene_m
                .map_or(String::new(), |m| format!(" and scene survey {m:.3} m"))
        );
        let _ = writeln!(
            s,
            "smallest admissible grid cell: {:.2} m (seed §6)",
            a.grid_cell_m
        );
        let sp = &self.spatial;
        let _ = writeln!(
            s,
            "spatial: {} epochs, {:.1} % RTK fixed ({} float, {} none); sigma h median {:.3} m, p95 {:.3} m, max {:.3} m; residual rms {:.3} m; {} jumps",
            sp.epochs,
            sp.rtk_fixed_share * 100.0,
            sp.rtk_float,
            sp.rtk_none,
            sp.sigma_horizontal_m.median,
            sp.sigma_horizontal_m.p95,
            sp.sigma_horizontal_m.max,
            sp.residual_m.rms,
            sp.jumps
        );
        if !sp.worst_sigma_windows.is_empty() {
            let w: Vec<String> = sp
                .worst_sigma_windows
                .iter()
                .map(|(a, b, h)| format!("{a:.0}-{b:.0} s: {h:.3} m"))
                .collect();
            let _ = writeln!(s, "largest sigmas: {}", w.join(", "));
        }
        let _ = writeln!(
            s,
            "GNSS vs CAN: speed scale {}, time offset {}, lever arm x {} (rig {:.2} m), distance {:.1} m (CAN) vs {:.1} m (GNSS), speed residual rms {:.3} m/s, yaw-rate residual rms {:.4} rad/s",
            sp.can_speed_scale.map_or("n/a".into(), |x| format!("{x:.4}")),
            sp.gnss_time_offset_ms.map_or("n/a".into(), |x| format!("{x:+.1} ms")),
            sp.lever_arm_x_measured_m.map_or("n/a".into(), |x| format!("{x:.2} m")),
            sp.lever_arm_x_rig_m,
            sp.distance_can_m,
            sp.distance_gnss_m,
            sp.speed_residual_mps.rms,
            sp.yaw_rate_residual_rps.rms
        );
        let tm = &self.temporal;
        for src in &tm.sources {
            let _ = writeln!(
                s,
                "timing {}: {} samples, {:.1} Hz, period {:.3} ms, jitter {:.3} ms, {} gaps, longest interval {:.1} ms",
                src.source, src.count, src.rate_hz, src.period_ms, src.jitter_ms, src.gaps, src.max_interval_ms
            );
        }
        for (src, m) in &tm.clock_sync {
            let get = |k: &str| m.get(k).and_then(|v| v.parse::<f64>().ok());
            let _ = writeln!(
                s,
                "clock {src}: offset {} ms, drift {} ppm, residual p95 {} µs (transport jitter){}",
                get("offset_ns").map_or("n/a".into(), |v| format!("{:.3}", v * 1e-6)),
                get("drift_ppm").map_or("n/a".into(), |v| format!("{v:.2}")),
                get("residual_p95_ns").map_or("n/a".into(), |v| format!("{:.0}", v * 1e-3)),
                m.get("pps").map_or(String::new(), |p| format!(", PPS {p}"))
            );
        }
        if let Some(p) = tm.pps_locked_share {
            let _ = writeln!(
                s,
                "lidar PPS locked in {:.1} % of position packets",
                p * 100.0
            );
        }
        if let Some(o) = tm.lidar_to_gnss_offset_ms {
            let _ = writeln!(
                s,
                "lidar-to-GNSS clock offset {o:.3} ms (host latencies included)"
            );
        }
        let _ = writeln!(
            s,
            "ego moves {:.3} m between GNSS epochs (p95); linear interpolation error p95 {:.4} m",
            tm.motion_between_epochs_m.p95, tm.interpolation_error_m.p95
        );
        if self.faults.is_empty() {
            let _ = writeln!(s, "faults: none");
        } else {
            let _ = writeln!(s, "faults:");
            for f in &self.faults {
                let _ = writeln!(
                    s,
                    "  {:<22} {:>7.1} s .. {:>7.1} s  {}",
                    f.name, f.from_s, f.to_s, f.detail
                );
            }
        }
        let _ = writeln!(s, "segments:");
        for g in &self.segments {
            let _ = writeln!(
                s,
                "  {:>7.1} s .. {:>7.1} s  {}{}",
                g.from_s,
                g.to_s,
                if g.verdict == Verdict::Pass {
                    "usable"
                } else {
                    "NOT usable"
                },
                if g.reasons.is_empty() {
                    String::new()
                } else {
                    format!(": {}", g.reasons.join(", "))
                }
            );
        }
        s
    }
}

/// The verdict on a recording, as `resim` asks for it: reads the run, checks it against the rig
/// (thresholds, lever arm) and the scene.
pub fn verdict(
    path: &std::path::Path,
    rig: &Rig,
    scene: Option<&Scene>,
) -> Result<Report, super::run::RunError> {
    let run = Run::read(path)?;
    Ok(check(&run, rig, scene))
}

/// GNSS epochs with a time and a position, one per epoch (a receiver that sends NMEA and UBX
/// reports each twice: the one with sigmas is kept).
fn gnss_epochs(run: &Run) -> Vec<(UtcNanos, &hilrig_gnss::Fix)> {
    let mut epochs: Vec<(UtcNanos, &hilrig_gnss::Fix)> = run
        .fixes
        .iter()
        .filter_map(|(_, f)| Some((f.time?, f)))
        .filter(|(_, f)| f.lat.is_some() && f.lon.is_some() && f.quality > 0)
        .collect();
    epochs.sort_by_key(|e| (e.0, e.1.sigma_lat_m.is_none()));
    epochs.dedup_by_key(|e| e.0);
    epochs
}

/// The origin of the local frame: the scene's, else the first epoch's position.
fn local_origin(epochs: &[(UtcNanos, &hilrig_gnss::Fix)], scene: Option<&Scene>) -> Wgs84 {
    scene.map(|s| s.file.origin).unwrap_or_else(|| {
        let f = epochs[0].1;
        Wgs84 {
            latitude_deg: f.lat.unwrap_or(0.0),
            longitude_deg: f.lon.unwrap_or(0.0),
            height_m: f.alt_ellipsoid.unwrap_or(0.0),
        }
    })
}

/// Antenna positions in the local frame with the receiver's sigmas (typical values by RTK state
/// where it reports none).
fn observations(epochs: &[(UtcNanos, &hilrig_gnss::Fix)], enu: &Enu) -> Vec<GnssObs> {
    let default_sigma = |f: &hilrig_gnss::Fix| match f.rtk {
        RtkState::Fixed => 0.02,
        RtkState::Float => 0.3,
        RtkState::None => 3.0,
    };
    epochs
        .iter()
        .map(|&(t, f)| {
            let p = enu.from_wgs84(&Wgs84 {
                latitude_deg: f.lat.unwrap_or(0.0),
                longitude_deg: f.lon.unwrap_or(0.0),
                height_m: f.alt_ellipsoid.unwrap_or(0.0),
            });
            let sl = f.sigma_lat_m.unwrap_or(default_sigma(f)).max(0.003);
            let so = f.sigma_lon_m.unwrap_or(default_sigma(f)).max(0.003);
            GnssObs {
                t,
                position: p.xy(),
                sigma: Vector2::new(so, sl),
            }
        })
        .collect()
}

//! `hilrig check`: the post-drive gate (Rosenberger et al. 2019, §6). Reference data that are not accurate enough
//! make every later metric meaningless, so before anything is re-simulated the run's spatial and
//! temporal accuracy are measured, combined into one reference accuracy, and turned into the
//! smallest admissible grid cell: max(10 cm, 10 × accuracy).
//!
//! Every problem found is a [`Fault`] with a name, a time window and the numbers behind it;
//! one-second segments take the verdict of the faults that overlap them, so the engineer sees
//! which parts of the drive are usable and why the others are not.
//!
//! What is measured and how:
//! - sources: a run without lidar data packets, GNSS fixes or CAN ego motion fails with a fault
//!   per missing source (without GNSS or CAN there is no trajectory, and only the receiver's
//!   own accuracy is measured);
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
//!
//! One file per kind of measurement, each a function over the run (and the smoothed trajectory)
//! that returns its part of the [`Report`]: [`sources`] (what the run lacks), [`spatial`] (the
//! receiver's own accuracy), [`consistency`] (GNSS against CAN), [`temporal`], [`budget`]
//! (accuracy and grid cell); [`names`] names the faults, [`faults`] keeps them and cuts the run
//! into segments; [`report`] is the report and its text. [`check`] composes them.

mod budget;
mod consistency;
mod direction;
mod faults;
mod heading;
mod names;
pub mod report;
mod sources;
mod spatial;
mod swing;
mod temporal;
#[cfg(test)]
mod test_drive;
mod travel;

pub use names::FaultName;
pub use report::{
    Accuracy, Fault, Report, RtkEpoch, Segment, SigmaWindow, SourceTiming, Spatial, Stats,
    Temporal, Verdict, Warning,
};
pub use travel::{DirectionFrom, LeverSwing, SwingOutcome, Travel, TravelStretch};

use super::noise::yaw_rate_noise;
use super::run::Run;
use super::trajectory::{
    fit_gnss_noise, fit_yaw_jerk_noise, fit_yaw_rate_noise, EgoTrajectory, GnssObs, Settings,
};
use crate::rig::Rig;
use crate::scene::file::Wgs84;
use crate::scene::geodesy::Enu;
use crate::scene::Scene;
use faults::{iso, secs, FaultLog};
use hilrig_gnss::RtkState;
use hilrig_stamp::UtcNanos;
use nalgebra::Vector2;

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

/// The report of a run that cannot be judged, with what was measured before that was found.
fn unusable(run: &Run, why: String, spatial: Spatial) -> Report {
    Report {
        verdict: Verdict::Unusable,
        unusable: Some(why),
        start: String::new(),
        duration_s: 0.0,
        spatial,
        temporal: Temporal::default(),
        accuracy: Accuracy::default(),
        faults: Vec::new(),
        marks: Vec::new(),
        warnings: Vec::new(),
        segments: Vec::new(),
        damage: run.damage.clone(),
        heading_source: None,
        travel: Travel::default(),
    }
}

/// The report of a run without GNSS fixes or without CAN ego motion: there is no trajectory,
/// so nothing but the receiver's own accuracy (when there are fixes) can be measured. It fails
/// with one fault per missing source, and the receiver's faults, over the stretch the run holds
/// data for; `unusable` says what could not be measured.
fn without_trajectory(
    run: &Run,
    rig: &Rig,
    epochs: &[(UtcNanos, &hilrig_gnss::Fix)],
    missing: Vec<(FaultName, String)>,
) -> Report {
    let span = data_span(run);
    let (start, end) = span.unwrap_or((UtcNanos(0), UtcNanos(0)));
    let mut log = FaultLog::new(start);
    let what: Vec<&str> = missing
        .iter()
        .filter(|(n, _)| *n != FaultName::NoLidarData)
        .map(|(n, _)| match n {
            FaultName::NoGnssFixes => "GNSS fixes",
            _ => "CAN ego motion",
        })
        .collect();
    for (name, detail) in missing {
        log.fault(name, start, end, detail);
    }
    let mut sp = Spatial::default();
    if !epochs.is_empty() {
        let times: Vec<UtcNanos> = epochs.iter().map(|e| e.0).collect();
        let period = temporal::median_interval(&times).unwrap_or(100_000_000);
        sp = spatial::receiver(epochs, &rig.thresholds, start, period, &mut log);
        sp.lever_arm_x_rig_m = rig.gnss.as_ref().map_or(0.0, |g| g.antenna.x);
    }
    if span.is_none() {
        // Nothing recorded at all: no instant to name.
        for f in &mut log.faults {
            f.from.clear();
            f.to.clear();
        }
    }
    Report {
        verdict: Verdict::Fail,
        unusable: Some(format!(
            "no reference trajectory without {}: {}",
            what.join(" and "),
            if epochs.is_empty() {
                "nothing else was measured"
            } else {
                "only the receiver's own accuracy was measured"
            }
        )),
        start: span.map_or(String::new(), |_| iso(start)),
        duration_s: secs(start, end),
        spatial: sp,
        temporal: Temporal::default(),
        accuracy: Accuracy::default(),
        segments: faults::segments(&log.faults, &[], start, end),
        faults: log.faults,
        marks: Vec::new(),
        warnings: Vec::new(),
        damage: run.damage.clone(),
        heading_source: None,
        travel: Travel::default(),
    }
}

/// The first and last instant of anything the run holds (GNSS, CAN, lidar), if it holds
/// anything.
fn data_span(run: &Run) -> Option<(UtcNanos, UtcNanos)> {
    let times = run
        .fixes
        .iter()
        .map(|(h, f)| f.time.unwrap_or(*h))
        .chain(run.motion.iter().map(|m| m.t))
        .chain(run.can_frames.iter().map(|c| c.0))
        .chain(run.packets.iter().map(|p| p.host))
        .chain(run.pps.iter().map(|p| p.0));
    times.fold(None, |span, t| match span {
        None => Some((t, t)),
        Some((a, b)) => Some((a.min(t), b.max(t))),
    })
}

/// The run's first and last instant over GNSS, CAN and lidar.
fn run_span(run: &Run, epochs: &[(UtcNanos, &hilrig_gnss::Fix)]) -> (UtcNanos, UtcNanos) {
    let mut all_times: Vec<UtcNanos> = vec![epochs[0].0, epochs[epochs.len() - 1].0];
    if let (Some(a), Some(b)) = (run.motion.first(), run.motion.last()) {
        all_times.extend([a.t, b.t]);
    }
    if let (Some(a), Some(b)) = (run.packets.first(), run.packets.last()) {
        all_times.extend([a.host, b.host]);
    }
    let start = *all_times.iter().min().unwrap_or(&epochs[0].0);
    let end = *all_times.iter().max().unwrap_or(&epochs[0].0);
    (start, end)
}

/// The smoother's settings for a drive: the antenna's lever arm from the rig, and the noise of
/// the CAN yaw rate, the yaw jerk and the GNSS error as the drive's own data show them.
fn noise_settings(
    obs: &[GnssObs],
    sent: &[(UtcNanos, f64, f64)],
    motion: &[(UtcNanos, f64, f64)],
    lever: Vector2<f64>,
) -> Settings {
    // The yaw-rate sensor's noise as the drive shows it while standing (the default where the
    // vehicle never stands), never below 0.5 mrad/s: a quiet sensor still has a bias. A stand is
    // found on the speed as sent; the fits below smooth the drive, on the motion signed for
    // the stretches backed up.
    let measured = yaw_rate_noise(sent);
    let settings = Settings {
        lever,
        yaw_rate_sigma: measured.map_or(Settings::default().yaw_rate_sigma, |s| s.max(5e-4)),
        ..Settings::default()
    };
    // How smoothly the yaw rate changes, as the drive's CAN yaw rate shows it: it decides how
    // closely the heading follows the integrated yaw rate between GNSS fixes.
    let settings = Settings {
        yaw_jerk_noise: fit_yaw_jerk_noise(obs, motion, &settings),
        ..settings
    };
    // A drive that never stands long enough shows its yaw-rate noise only against the motion:
    // fitted with the yaw jerk, in turn (the default of 5 mrad/s against a sensor of 2 mrad/s
    // made the heading's sigma a quarter too large on such drives).
    let settings = if measured.is_none() {
        let s = Settings {
            yaw_rate_sigma: fit_yaw_rate_noise(obs, motion, &settings).max(5e-4),
            ..settings
        };
        Settings {
            yaw_jerk_noise: fit_yaw_jerk_noise(obs, motion, &s),
            ..s
        }
    } else {
        settings
    };
    // RTK errors wander over seconds: weighted as if independent, ten epochs a second would pull
    // the trajectory (and its heading) along their wander. The smoothing models the wander as
    // states, with the correlation time and share that the drive's own GNSS innovations make
    // most likely (white, if that is what they are), so that CAN motion carries the short term
    // and GNSS the long term.
    let settings = Settings {
        gnss_noise: fit_gnss_noise(obs, motion, &settings),
        ..settings
    };
    tracing::debug!(
        "check: GNSS error wanders over {} s with {:.0} % of its variance; yaw jerk {} rad/s³/√s; yaw-rate noise {:.4} rad/s",
        settings.gnss_noise.correlation_s,
        settings.gnss_noise.correlated_share * 100.0,
        settings.yaw_jerk_noise,
        settings.yaw_rate_sigma
    );
    settings
}

fn check_into(
    run: &Run,
    rig: &Rig,
    scene: Option<&Scene>,
    trajectory_out: &mut Option<EgoTrajectory>,
) -> Report {
    let th = &rig.thresholds;
    // Epochs with a position and a time.
    let epochs = gnss_epochs(run);
    let missing = sources::missing(run, epochs.len(), rig);
    if epochs.len() < 2 || run.motion.len() < 2 {
        return without_trajectory(run, rig, &epochs, missing);
    }
    let (start, end) = run_span(run, &epochs);
    let mut log = FaultLog::new(start);
    // A run without lidar data is measured all the same (its reference may be fine), and fails.
    for (name, detail) in missing {
        log.fault(name, start, end, detail);
    }
    let enu = Enu::new(&local_origin(&epochs, scene));
    let gnss_period = temporal::median_interval(&epochs.iter().map(|e| e.0).collect::<Vec<_>>())
        .unwrap_or(100_000_000);

    let mut sp = spatial::receiver(&epochs, th, start, gnss_period, &mut log);
    sp.lever_arm_x_rig_m = rig.gnss.as_ref().map_or(0.0, |g| g.antenna.x);

    // The smoothed trajectory with the rig's lever arm.
    let lever = rig
        .gnss
        .as_ref()
        .map_or(Vector2::zeros(), |g| Vector2::new(g.antenna.x, g.antenna.y));
    let obs = observations(&epochs, &enu);
    // The rig's heading source, when it has one (see heading.rs).
    let heading_cfg = rig.gnss.as_ref().and_then(|g| g.heading.as_ref());
    let heading_reports = heading_cfg.map(|c| heading::reports(run, c));
    let heading_obs = heading_reports.as_ref().map_or(&[][..], |r| &r.obs[..]);
    let mut motion: Vec<(UtcNanos, f64, f64)> = run
        .motion
        .iter()
        .map(|m| (m.t, m.speed, m.yaw_rate))
        .collect();
    // The stretches backed up, where the speed is sent as a magnitude (told from the track),
    // before any smoother sees the motion.
    let sent = motion.clone();
    let travel = direction::signed(&obs, &mut motion, heading_obs, lever, start);
    let settings = noise_settings(&obs, &sent, &motion, lever);
    let fixed: Vec<bool> = epochs
        .iter()
        .map(|(_, f)| f.rtk == RtkState::Fixed)
        .collect();
    // A calibrated mounting (the rig states how well `yaw_offset_deg` is known) starts the
    // source's offset from that calibration; otherwise the drive alone decides it.
    let settings = Settings {
        heading_offset_sigma: heading_cfg
            .and_then(|c| c.yaw_offset_sigma_deg)
            .map_or(settings.heading_offset_sigma, f64::to_radians),
        ..settings
    };
    let (traj, heading_offset) = match heading::smooth(&obs, &motion, heading_obs, &settings) {
        Ok(t) => t,
        Err(e) => return unusable(run, e.to_string(), sp),
    };
    let heading_source = heading_cfg
        .zip(heading_reports.as_ref())
        .map(|(c, r)| heading::judge(r, &traj, heading_offset, c, th, gnss_period, &mut log));
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
    let inputs = consistency::Inputs {
        run,
        th,
        obs: &obs,
        fixed: &fixed,
        good: &good,
        motion: &motion,
        yaw_rate_sigma: settings.yaw_rate_sigma,
        yaw_jerk_noise: settings.yaw_jerk_noise,
        gnss_noise: settings.gnss_noise,
        lever,
        gnss_period,
        span: (start, end),
    };
    let mut warnings = Vec::new();
    warnings.extend(direction::swing_warning(&travel, lever.x));
    let offset_s = consistency::gnss_against_can(&inputs, &traj, &mut sp, &mut log, &mut warnings);
    sp.scene_accuracy_m = scene.map(|s| {
        s.file
            .objects
            .iter()
            .map(|o| o.accuracy_m)
            .chain(s.file.ground.map(|g| g.accuracy_m))
            .fold(0.0, f64::max)
    });

    let (tm, lidar_time_error_s) = temporal::measure(run, &epochs, &traj, th, &mut log);
    let heading_range_m = budget::heading_range(&traj, th, scene);
    let heading_sigma_deg = budget::heading(&traj, th, heading_range_m, &mut log);
    let errors = budget::Errors {
        heading_sigma_deg,
        heading_range_m,
        gnss_time_offset_s: offset_s,
        lidar_time_error_s,
        fixed: &fixed,
    };
    let acc = budget::accuracy(run, th, &sp, &tm, &traj, &errors, &log);
    let mut segments = faults::segments(&log.faults, &log.marks, start, end);
    // Marks take stretches out without failing the run; when they take out all of it, nothing
    // is left to measure a model against, and a run that passes would be re-simulated and
    // compared on nothing but reference error.
    if log.faults.is_empty()
        && !segments.is_empty()
        && segments.iter().all(|g| g.verdict != Verdict::Pass)
    {
        let mut why: Vec<FaultName> = log.marks.iter().map(|m| m.name).collect();
        why.sort_unstable();
        why.dedup();
        log.fault(
            FaultName::NothingUsable,
            start,
            end,
            format!(
                "every stretch of the run is marked not usable ({}): no stretch is left to measure a model against",
                why.join(", ")
            ),
        );
        segments = faults::segments(&log.faults, &log.marks, start, end);
    }
    *trajectory_out = Some(traj);
    let verdict = if log.faults.is_empty() {
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
        faults: log.faults,
        marks: log.marks,
        warnings,
        segments,
        damage: run.damage.clone(),
        heading_source,
        travel,
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

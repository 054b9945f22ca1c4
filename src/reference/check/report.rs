//! The check's report: what was measured (spatial, temporal), the accuracy budget, the faults
//! and the segments, as JSON (serde) and as the text `hilrig check` prints.

use super::names::FaultName;
use hilrig_stamp::UtcNanos;
use serde::{Deserialize, Serialize};

/// The overall verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
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
    /// Its name, as in the JSON ("pass", "fail", "unusable"): the one spelling wherever a
    /// verdict is written as text (the simulation's metadata too).
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Fail => "fail",
            Verdict::Unusable => "unusable",
        }
    }

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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fault {
    /// What it is, or for a mark, why its stretch is not usable.
    pub name: FaultName,
    /// For a source the run lacks, the topics it was looked for on.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub topics: Vec<String>,
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
    /// Start, ns since the Unix epoch (what `compare` and `gap` cut the run at).
    pub from_ns: UtcNanos,
    /// End, ns since the Unix epoch.
    pub to_ns: UtcNanos,
}

/// Something the check could not decide on this drive: a quantity whose uncertainty is too
/// large to say whether it is within its limit. Not a fault: the verdict does not change.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Warning {
    /// What (`gnss_time_offset`, `lever_arm`, `can_speed_scale`).
    pub name: FaultName,
    /// The estimate and its uncertainty, and the manoeuvre that would make it determinable.
    pub detail: String,
}

/// Statistics of a series.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
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
    /// The statistics of `v` (non-finite values left out; all zero when nothing is left).
    pub(super) fn of(mut v: Vec<f64>) -> Stats {
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RtkEpoch {
    /// Epoch time (UTC, ISO 8601 with milliseconds, as gpsd writes it).
    pub time: String,
    /// The state.
    pub state: hilrig_gnss::RtkState,
    /// Seconds after the run's start.
    pub t_s: f64,
    /// Receiver 1-sigma horizontal error (larger of lat/lon), m, when the receiver gives it.
    pub sigma_horizontal_m: Option<f64>,
}

/// A one-second window of the receiver's stated horizontal sigma.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SigmaWindow {
    /// Its start, s after the run's first epoch.
    pub from_s: f64,
    /// Its end, s.
    pub to_s: f64,
    /// The largest horizontal sigma in it (the larger of latitude and longitude), m.
    pub sigma_m: f64,
}

/// Spatial measurements.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
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
    /// The three one-second windows with the largest horizontal sigma, largest first.
    pub worst_sigma_windows: Vec<SigmaWindow>,
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
    /// Standard uncertainty (1 sigma) of the speed scale, correlation of the residuals included.
    pub can_speed_scale_sigma: Option<f64>,
    /// GNSS speed minus corrected CAN speed, m/s.
    pub speed_residual_mps: Stats,
    /// GNSS course rate minus CAN yaw rate, rad/s.
    pub yaw_rate_residual_rps: Stats,
    /// Path length by CAN speed (its magnitude, reversing included), m.
    pub distance_can_m: f64,
    /// Distance along the GNSS antenna track, m.
    pub distance_gnss_m: f64,
    /// GNSS time stamps minus the instants they describe, measured against CAN, ms: positive
    /// means the stamps are late (a fix stamped t describes t - offset).
    pub gnss_time_offset_ms: Option<f64>,
    /// Standard uncertainty (1 sigma) of the time offset, ms.
    pub gnss_time_offset_sigma_ms: Option<f64>,
    /// Antenna x (forward) from the data, m.
    pub lever_arm_x_measured_m: Option<f64>,
    /// Standard uncertainty (1 sigma) of the measured antenna x, m.
    pub lever_arm_x_sigma_m: Option<f64>,
    /// GNSS epochs in turns that the lever arm was measured in.
    pub lever_arm_turning_epochs: usize,
    /// How correlated in time the GNSS residuals are (integrated autocorrelation time, in
    /// epochs): the factor the time offset's and lever arm's variances are inflated by when the
    /// drive's GNSS noise model is white (a wandering model carries the correlation itself).
    pub gnss_noise_correlation: f64,
    /// Antenna x from the rig file, m.
    pub lever_arm_x_rig_m: f64,
    /// Worst survey accuracy of the scene's static objects, m (1 sigma).
    pub scene_accuracy_m: Option<f64>,
}

/// One source's timing.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct SourceTiming {
    /// Source (`gnss`, `lidar`, or one CAN message that carries ego motion, `can 0x123`).
    pub source: String,
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
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Temporal {
    /// Per source.
    pub sources: Vec<SourceTiming>,
    /// Position packets reporting PPS lock.
    pub pps_locked_share: Option<f64>,
    /// Clock-sync metadata of the recording, per source.
    /// (MCAP metadata holds strings; the JSON gives numbers as numbers.)
    pub clock_sync: std::collections::BTreeMap<String, crate::bag::clock_sync::ClockSync>,
    /// Lidar minus GNSS clock offset (host latencies included), ms.
    pub lidar_to_gnss_offset_ms: Option<f64>,
    /// How far the logger's clock ran ahead of GNSS time by the PPS-locked lidar's clock
    /// model, ms (its transport latency and timing error included;
    /// [`crate::reference::run::Run::logger_ahead_of_gnss_ns`]).
    pub logger_ahead_of_gnss_ms: Option<f64>,
    /// Whether CAN (and every other time on the logger's clock) was put on GNSS time with that
    /// model: the logger's clock was off beyond what the lidar's own timing could be
    /// ([`crate::reference::run::LOGGER_OFF_NS`]).
    #[serde(default)]
    pub can_on_gnss_time: bool,
    /// What the run could tell of the logger's clock, and so whether `can_on_gnss_time`.
    #[serde(default)]
    pub logger_clock: crate::reference::run::LoggerClockState,
    /// How far the ego moves between GNSS epochs (speed × interval), m.
    pub motion_between_epochs_m: Stats,
    /// Error of interpolating linearly between GNSS epochs, m.
    pub interpolation_error_m: Stats,
}

/// The accuracy budget (1 sigma, metres).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Accuracy {
    /// Ego position from RTK (receiver sigmas, inflated if the residuals say they are optimistic).
    pub trajectory_m: f64,
    /// Time errors times speed.
    pub temporal_m: f64,
    /// Interpolation between reference samples.
    pub interpolation_m: f64,
    /// Lever arm error, when one is found.
    pub lever_arm_m: f64,
    /// The smoothed heading's 1-sigma error (95th percentile over the usable stretches), deg.
    pub heading_sigma_deg: f64,
    /// That heading error as a position error at `heading_range_m`, m.
    pub heading_m: f64,
    /// The range the heading error is counted at: how far the scene's objects are from the ego
    /// (95th percentile), at most the rig's `heading_range_m`, m.
    pub heading_range_m: f64,
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
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Segment {
    /// Start, s after the run's start.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
    /// Pass or fail.
    pub verdict: Verdict,
    /// Names of the faults that make it fail, and of the marks that take it out (`verdict`
    /// `unusable` when there are only marks).
    pub reasons: Vec<FaultName>,
}

/// The whole report.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Report {
    /// Overall verdict.
    pub verdict: Verdict,
    /// What could not be measured and why, if something could not: the run is unreadable
    /// (verdict `unusable`), or lacks GNSS fixes or CAN ego motion (verdict `fail`, with a
    /// fault per missing source), so that there is no trajectory to measure.
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
    /// Stretches taken out although nothing is wrong with the data: the reference is too
    /// uncertain there (`heading_uncertain`: the smoother's heading sigma above the limit, as at
    /// the start of a drive before the vehicle has moved far enough to show its heading).
    /// `compare` and the gap workflow leave them out: a re-simulation there would show the
    /// reference's error as the model's.
    pub marks: Vec<Fault>,
    /// What could not be decided on this drive, and what would decide it.
    pub warnings: Vec<Warning>,
    /// Usable and unusable stretches.
    pub segments: Vec<Segment>,
    /// Problems reading the recording.
    pub damage: Option<String>,
    /// The rig's heading source, when it has one and it reported: what was used and how it
    /// fits the track.
    pub heading_source: Option<HeadingReport>,
    /// Which way the car travelled, and the stretches it backed up.
    #[serde(default)]
    pub travel: super::travel::Travel,
}

impl Fault {
    /// Its start and end, UTC.
    pub fn window(&self) -> (UtcNanos, UtcNanos) {
        (self.from_ns, self.to_ns)
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
            if let Some(d) = &self.damage {
                let _ = writeln!(s, "recording damaged: {d}");
            }
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
            if !self.faults.is_empty() {
                self.findings_text(&mut s);
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
            "reference accuracy (1 sigma): {:.3} m = ego {:.3} m (RTK {:.3}, timing {:.3}, interpolation {:.4}, lever arm {:.3}, heading {:.3}° = {:.3} m at {:.0} m){}",
            a.reference_m,
            a.ego_m,
            a.trajectory_m,
            a.temporal_m,
            a.interpolation_m,
            a.lever_arm_m,
            a.heading_sigma_deg,
            a.heading_m,
            a.heading_range_m,
            a.scene_m
                .map_or(String::new(), |m| format!(" and scene survey {m:.3} m"))
        );
        let _ = writeln!(
            s,
            "smallest admissible grid cell: {:.2} m (Rosenberger et al. 2019, §6)",
            a.grid_cell_m
        );
        let _ = writeln!(s, "{}", heading_text(self.heading_source.as_ref()));
        let _ = writeln!(s, "{}", self.travel.text());
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
                .map(|w| format!("{:.0}-{:.0} s: {:.3} m", w.from_s, w.to_s, w.sigma_m))
                .collect();
            let _ = writeln!(s, "largest sigmas: {}", w.join(", "));
        }
        let pm = |v: Option<f64>, sd: Option<f64>, digits: usize, unit: &str| match (v, sd) {
            (Some(v), Some(sd)) => format!("{v:.digits$} ± {sd:.digits$}{unit}"),
            (Some(v), None) => format!("{v:.digits$}{unit}"),
            _ => "n/a".into(),
        };
        let _ = writeln!(
            s,
            "GNSS vs CAN (± 1 sigma): speed scale {}, time offset {} (stamps late if positive), lever arm x {} (rig {:.2} m), distance {:.1} m (CAN) vs {:.1} m (GNSS, fixed epochs), speed residual rms {:.3} m/s, yaw-rate residual rms {:.4} rad/s",
            pm(sp.can_speed_scale, sp.can_speed_scale_sigma, 4, ""),
            pm(sp.gnss_time_offset_ms, sp.gnss_time_offset_sigma_ms, 1, " ms"),
            pm(sp.lever_arm_x_measured_m, sp.lever_arm_x_sigma_m, 2, " m"),
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
            let _ = writeln!(
                s,
                "clock {src}: offset {:.3} ms, drift {:.2} ppm, residual p95 {:.0} µs (transport jitter){}",
                m.offset_ns as f64 * 1e-6,
                m.drift_ppm,
                m.residual_p95_ns as f64 * 1e-3,
                m.pps.map_or(String::new(), |p| format!(", PPS {p:?}"))
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
        // Said where it changed the run or where the logger is off by more than a CAN frame
        // period or two (a model's offset within 5 ms is the lidar's transport latency).
        if tm.can_on_gnss_time || tm.logger_ahead_of_gnss_ms.is_some_and(|o| o.abs() >= 5.0) {
            let gnss_ahead_ms = tm.clock_sync.get("gnss").map(|g| g.offset_ns as f64 * 1e-6);
            let _ = writeln!(
                s,
                "logger clock: {}",
                tm.logger_clock
                    .describe(tm.logger_ahead_of_gnss_ms, gnss_ahead_ms)
            );
        }
        let _ = writeln!(
            s,
            "ego moves {:.3} m between GNSS epochs (p95); linear interpolation error p95 {:.4} m",
            tm.motion_between_epochs_m.p95, tm.interpolation_error_m.p95
        );
        self.findings_text(&mut s);
        s
    }

    /// Warnings, faults and segments, as `text` ends.
    fn findings_text(&self, s: &mut String) {
        use std::fmt::Write;
        for w in &self.warnings {
            let _ = writeln!(*s, "warning: {}: {}", w.name, w.detail);
        }
        if self.faults.is_empty() {
            let _ = writeln!(*s, "faults: none");
        } else {
            let _ = writeln!(*s, "faults:");
            for f in &self.faults {
                let _ = writeln!(
                    s,
                    "  {:<22} {:>7.1} s .. {:>7.1} s  {}",
                    f.name, f.from_s, f.to_s, f.detail
                );
            }
        }
        for m in &self.marks {
            let _ = writeln!(
                s,
                "not usable: {:<18} {:>7.1} s .. {:>7.1} s  {}",
                m.name, m.from_s, m.to_s, m.detail
            );
        }
        let _ = writeln!(*s, "segments:");
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
    }
}

/// What `check` says of the heading source (check.json `heading_source`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct HeadingReport {
    /// The message used.
    pub source: crate::rig::HeadingSource,
    /// Reports used.
    pub used: usize,
    /// Reports left out: in a mode other than measured.
    pub not_measured: usize,
    /// Reports left out: without a time.
    pub untimed: usize,
    /// Messages of the source that its own flags mark invalid (THS mode V, a NAV-ATT or
    /// RELPOSNED without its valid flag): counted, not used.
    pub invalid: u64,
    /// GNSS messages of the run, of any kind, that did not frame or decode (a checksum that
    /// fails, a heading out of its range, NaN): counted, not used.
    pub malformed_gnss: u64,
    /// The accuracy the rig file states, deg.
    pub sigma_deg: f64,
    /// The mounting offset the rig file states, deg (clockwise).
    pub yaw_offset_rig_deg: f64,
    /// How well the rig file says that mounting is known (a calibration's 1-sigma, deg); `None`:
    /// the drive alone decided the offset.
    pub yaw_offset_sigma_rig_deg: Option<f64>,
    /// The source's offset beyond that, as the drive shows it, deg (clockwise: the source
    /// reads this much more than the vehicle's heading); `None` without reports.
    pub offset_deg: Option<f64>,
    /// Its 1-sigma, deg.
    pub offset_sigma_deg: Option<f64>,
    /// sqrt(mean NIS) of the reports against the smoothed heading: about 1 when the source
    /// is as accurate as it says.
    pub rms_normalized: Option<f64>,
    /// Reports more than 3 sigma off the smoothed heading.
    pub beyond_3_sigma: usize,
}

/// The report's line on the heading source.
fn heading_text(h: Option<&HeadingReport>) -> String {
    let Some(h) = h else {
        return "heading source: none (the heading is the track's: RTK and CAN)".to_owned();
    };
    match (h.offset_deg, h.offset_sigma_deg, h.rms_normalized) {
        (Some(o), Some(so), Some(rms)) => format!(
            "heading source: {} ({} reports used, {} not measured, {} without a time, {} flagged invalid; {} GNSS messages malformed); offset against the track {o:+.3}° ± {so:.3}° beyond the rig's {}°{}; reports fit their {:.3}° at {rms:.2} of it (rms normalised), {} beyond 3 sigma",
            h.source.name(),
            h.used,
            h.not_measured,
            h.untimed,
            h.invalid,
            h.malformed_gnss,
            h.yaw_offset_rig_deg,
            h.yaw_offset_sigma_rig_deg
                .map_or(String::new(), |c| format!(" (calibrated to ± {c}°)")),
            h.sigma_deg,
            h.beyond_3_sigma
        ) + &format!(
            "\n  the mounting this drive measured, for the rig file's [gnss.heading] once the source is trusted: yaw_offset_deg = {:.4}, yaw_offset_sigma_deg = {:.4}",
            h.yaw_offset_rig_deg + o,
            so
        ),
        _ => format!(
            "heading source: {}: no measured report ({} not measured, {} without a time, {} flagged invalid; {} GNSS messages malformed)",
            h.source.name(), h.not_measured, h.untimed, h.invalid, h.malformed_gnss
        ),
    }
}

impl crate::output::Output for Report {
    const KIND: crate::output::OutputKind = crate::output::OutputKind::Check;
    const SCHEMA: u32 = 1;
}

#[cfg(test)]
mod tests {
    use super::Verdict;

    #[test]
    fn a_verdict_s_name_is_its_json_spelling() {
        for v in [Verdict::Pass, Verdict::Fail, Verdict::Unusable] {
            assert_eq!(
                serde_json::to_string(&v).unwrap(),
                format!("\"{}\"", v.name())
            );
        }
    }
}

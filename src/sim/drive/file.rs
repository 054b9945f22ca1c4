//! The drive file's format (`drive.toml`, see [`super`]): every table as the user writes it,
//! documented on its struct, with its defaults; loading a file, and the errors that name what
//! in it is wrong.
//!
//! A file of its own so that the format reads as a reference, apart from the driver that
//! interprets it ([`super::driven`]) and the path geometry ([`super::path`]).

use crate::sim::drivable::{Exceedance, PathPoint};
use hilrig_stamp::UtcNanos;
use serde::Deserialize;

/// The path to follow.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {
    /// Points the rear-axle centre passes, local frame, metres (smoothed by a Catmull-Rom spline).
    pub waypoints: Vec<[f64; 2]>,
    /// Speed between stops, m/s.
    pub cruise_speed_mps: f64,
    /// Acceleration, m/s².
    #[serde(default = "d_acc")]
    pub acceleration_mps2: f64,
    /// Deceleration, m/s².
    #[serde(default = "d_dec")]
    pub deceleration_mps2: f64,
    /// Standing before moving off, s (ignored when the drive starts moving).
    #[serde(default = "one")]
    pub lead_in_s: f64,
    /// Speed at the first waypoint, m/s: 0 starts from standstill; above 0 the recording
    /// begins with the vehicle already moving (and, where the path starts in a curve, already
    /// turning).
    #[serde(default)]
    pub start_speed_mps: f64,
    /// Standing after arriving, s.
    #[serde(default = "one")]
    pub lead_out_s: f64,
    /// A leg backed up after stopping at the last waypoint (a parking manoeuvre: past the slot,
    /// then back into it). Without it the drive ends at the last waypoint.
    #[serde(default)]
    pub reverse: Option<ReverseLeg>,
}

/// How a report names the reversing leg, and what its waypoints count from.
pub const BACKING_UP: &str = "backing up (waypoint 0 is where the path ends, 1 and 2 one and two metres straight behind it, then path.reverse.waypoints)";

/// A leg driven backwards. The car stops at the path's last waypoint, stands, backs straight
/// for the first metre (it stands in the direction it arrived) and then through `waypoints`, its rear
/// leading: its heading is the path's direction turned by 180°, its speed negative. The CAN
/// speed carries the sign only where the rig's DBC signal can (a signed signal, or a magnitude
/// with a `sign_signal`); a magnitude alone reads the same backing up as driving forward, as
/// on most cars.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReverseLeg {
    /// Points the rear-axle centre passes backing up, after two points one and two metres
    /// straight behind the path's end, local frame, metres.
    pub waypoints: Vec<[f64; 2]>,
    /// Speed backing up, m/s.
    #[serde(default = "one")]
    pub speed_mps: f64,
    /// Standing at the turn-around point before backing up, s.
    #[serde(default = "one")]
    pub pause_s: f64,
}

/// A walker crossing on a straight line.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WalkerSpec {
    /// The scene actor that walks (its shape comes from the scene).
    pub actor: String,
    /// Start point, metres.
    pub from: [f64; 2],
    /// End point, metres.
    pub to: [f64; 2],
    /// Walking speed, m/s.
    pub speed_mps: f64,
    /// When it starts walking, seconds after the drive's start.
    pub start_s: f64,
}

/// Which walker the ego yields to, and where it stops.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct YieldSpec {
    /// Walker's actor name.
    pub walker: String,
    /// Arc length of the stop line along the path, metres.
    pub stop_at_m: f64,
    /// The path is blocked while the walker is nearer than this to it, metres.
    #[serde(default = "d_clearance")]
    pub clearance_m: f64,
}

/// Human variation between repetitions (1 sigma).
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variation {
    /// Lateral deviation from the planned path, metres.
    #[serde(default = "d_lateral")]
    pub lateral_m: f64,
    /// Relative cruise speed variation.
    #[serde(default = "d_speed")]
    pub speed_factor: f64,
    /// Walker start time variation, s.
    #[serde(default = "d_walker_start")]
    pub walker_start_s: f64,
    /// Relative walking speed variation.
    #[serde(default = "d_speed")]
    pub walker_speed_factor: f64,
}

impl Default for Variation {
    fn default() -> Self {
        Variation {
            lateral_m: d_lateral(),
            speed_factor: d_speed(),
            walker_start_s: d_walker_start(),
            walker_speed_factor: d_speed(),
        }
    }
}

/// Lidar stream errors and settings.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarStream {
    /// Rotation rate.
    #[serde(default = "d_rpm")]
    pub rpm: f64,
    /// "strongest", "last" or "dual".
    #[serde(default = "d_mode")]
    pub return_mode: String,
    /// Delay from a packet's last firing to its host stamp, µs.
    #[serde(default = "d_lidar_latency")]
    pub latency_us: f64,
    /// Standard deviation of that delay (half-normal, added), µs.
    #[serde(default = "d_lidar_jitter")]
    pub jitter_us: f64,
    /// Share of data packets lost on the network.
    #[serde(default = "d_loss")]
    pub packet_loss: f64,
    /// One position packet per this many data packets.
    #[serde(default = "d_position_every")]
    pub position_every: u32,
    /// Whether the data packets carry returns, cast through the scene (the default). Without
    /// them, each packet has its stamp, its blocks' azimuths and its header, and every channel
    /// is empty: what a study of the reference data alone needs (`check` reads the packets'
    /// times, not their returns), synthesized without casting a ray.
    #[serde(default = "yes")]
    pub returns: bool,
}

/// GNSS stream errors and settings.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssStream {
    /// Epochs per second.
    #[serde(default = "d_gnss_rate")]
    pub rate_hz: f64,
    /// RTK fixed horizontal noise, 1 sigma per axis, metres (first-order Gauss-Markov).
    #[serde(default = "d_sigma_h")]
    pub sigma_horizontal_m: f64,
    /// Vertical noise, metres.
    #[serde(default = "d_sigma_v")]
    pub sigma_vertical_m: f64,
    /// Correlation time of the noise, s.
    #[serde(default = "d_tau")]
    pub correlation_s: f64,
    /// Serial delay from epoch to host stamp, ms.
    #[serde(default = "d_gnss_latency")]
    pub latency_ms: f64,
    /// Standard deviation of that delay (half-normal, added), ms.
    #[serde(default = "d_gnss_jitter")]
    pub jitter_ms: f64,
    /// Geoid separation written in GGA, metres.
    #[serde(default = "d_geoid")]
    pub geoid_separation_m: f64,
}

/// The heading source's stream (an INS, a dual-antenna receiver), as the rig's
/// `[gnss.heading]` message on the GNSS port: its truth, noise and faults.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeadingStream {
    /// Reports per second (THS and HDT, which have no time of their own, come with each GNSS
    /// epoch instead).
    #[serde(default = "d_heading_rate")]
    pub rate_hz: f64,
    /// Noise, 1 sigma, degrees (white: a dual antenna's carrier-phase heading, an INS's
    /// filtered one).
    #[serde(default = "d_heading_sigma")]
    pub sigma_deg: f64,
    /// How far the source's axis really is turned beyond the rig file's `yaw_offset_deg`,
    /// degrees clockwise (the baseline's misalignment that `check` estimates).
    #[serde(default)]
    pub misalignment_deg: f64,
    /// Delay from the report's instant to the host stamp, ms.
    #[serde(default = "d_heading_latency")]
    pub latency_ms: f64,
    /// Stretches in which the source dead-reckons and says so (THS mode E; other messages
    /// have no such mode and report as measured).
    #[serde(default)]
    pub estimated: Vec<Window>,
    /// Stretches in which the source repeats its last heading (a frozen output).
    #[serde(default)]
    pub frozen: Vec<Window>,
}

impl Default for HeadingStream {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}

/// CAN stream errors and settings.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanStream {
    /// Ego motion frames per second.
    #[serde(default = "d_can_rate")]
    pub rate_hz: f64,
    /// Speed noise, m/s.
    #[serde(default = "d_speed_noise")]
    pub speed_sigma_mps: f64,
    /// Yaw rate noise, rad/s.
    #[serde(default = "d_yaw_noise")]
    pub yaw_rate_sigma_rps: f64,
    /// Delay to the host stamp, ms.
    #[serde(default = "one")]
    pub latency_ms: f64,
}

/// How well the static objects were surveyed.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Survey {
    /// Position error per axis, 1 sigma, metres ("about 10 cm").
    #[serde(default = "d_survey")]
    pub sigma_m: f64,
}

macro_rules! defaults {
    ($($name:ident: $t:ty = $v:expr;)*) => { $(fn $name() -> $t { $v })* };
}
defaults! {
    yes: bool = true;
    one: f64 = 1.0;
    d_acc: f64 = 0.8;
    d_dec: f64 = 1.0;
    d_clearance: f64 = 2.0;
    d_lateral: f64 = 0.10;
    d_speed: f64 = 0.08;
    d_walker_start: f64 = 0.5;
    d_rpm: f64 = 600.0;
    d_mode: String = "strongest".into();
    d_lidar_latency: f64 = 300.0;
    d_lidar_jitter: f64 = 60.0;
    d_loss: f64 = 0.0005;
    d_position_every: u32 = 10;
    d_gnss_rate: f64 = 10.0;
    d_sigma_h: f64 = 0.010;
    d_sigma_v: f64 = 0.020;
    d_tau: f64 = 2.0;
    d_gnss_latency: f64 = 35.0;
    d_gnss_jitter: f64 = 2.0;
    d_geoid: f64 = 47.0;
    d_can_rate: f64 = 50.0;
    d_speed_noise: f64 = 0.01;
    d_yaw_noise: f64 = 0.002;
    d_survey: f64 = 0.10;
    d_heading_rate: f64 = 20.0;
    d_heading_sigma: f64 = 0.05;
    d_heading_latency: f64 = 10.0;
}

impl Default for LidarStream {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}
impl Default for GnssStream {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}
impl Default for CanStream {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}
impl Default for Survey {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}

/// A time window of a drive, seconds after its start.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Window {
    /// Start, s.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
}

impl Window {
    /// Whether `t_s` (seconds after the start) lies inside.
    pub fn contains(&self, t_s: f64) -> bool {
        t_s >= self.from_s && t_s < self.to_s
    }
}

/// A degraded RTK solution in a window.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RtkFault {
    /// Start, s after the drive's start.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
    /// GGA quality written: 5 float, 2 DGNSS, 1 autonomous.
    pub quality: u8,
}

/// A sigma spike: the receiver reports (and has) a larger error in a window.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SigmaFault {
    /// Start, s after the drive's start.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
    /// 1-sigma horizontal error, m.
    pub sigma_m: f64,
}

/// The lidar's clock runs free instead of being PPS-locked.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FreeClock {
    /// Offset against UTC at the start, ms.
    pub offset_ms: f64,
    /// Drift, ppm.
    pub drift_ppm: f64,
}

/// One GNSS epoch off by a displacement the receiver does not report (a multipath or
/// wrong-ambiguity jump: still "fixed", with the usual sigmas).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct JumpFault {
    /// The epoch nearest this time, s after the drive's start.
    pub at_s: f64,
    /// Displacement east and north, m.
    pub offset_m: [f64; 2],
}

/// Corrections reaching the receiver late in a window (GGA field 13).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AgeFault {
    /// Start, s after the drive's start.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
    /// Age of the corrections, s.
    pub age_s: f64,
}

/// Faults injected into the reference data (for testing `hilrig check`); none by default.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Faults {
    /// RTK float or non-RTK segments.
    #[serde(default)]
    pub rtk: Vec<RtkFault>,
    /// Sigma spikes.
    #[serde(default)]
    pub sigma_spike: Vec<SigmaFault>,
    /// GNSS fixes labelled this much later than the instant they describe, ms.
    #[serde(default)]
    pub gnss_time_offset_ms: f64,
    /// A free-running lidar clock.
    #[serde(default)]
    pub lidar_free_running: Option<FreeClock>,
    /// A PPS-locked lidar whose stamps are late by this much, ms (a firing at t is stamped
    /// t + offset: a misconfigured time source).
    #[serde(default)]
    pub lidar_time_offset_ms: f64,
    /// Windows without lidar data packets.
    #[serde(default)]
    pub lidar_gap: Vec<Window>,
    /// CAN speed reads this factor times the truth.
    #[serde(default = "one")]
    pub can_speed_scale: f64,
    /// The true antenna sits this far from where the rig file says, metres (x, y, z).
    #[serde(default)]
    pub antenna_error_m: [f64; 3],
    /// Windows without GNSS output (the receiver or its serial line is silent).
    #[serde(default)]
    pub gnss_gap: Vec<Window>,
    /// Windows without CAN frames (the bus or the logger's interface is silent).
    #[serde(default)]
    pub can_gap: Vec<Window>,
    /// Single GNSS epochs displaced without the receiver knowing.
    #[serde(default)]
    pub position_jump: Vec<JumpFault>,
    /// Windows with old corrections.
    #[serde(default)]
    pub correction_age: Vec<AgeFault>,
}

impl Default for Faults {
    fn default() -> Self {
        toml::from_str("").expect("defaults")
    }
}

/// The drive file.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveFile {
    /// Name.
    pub name: String,
    /// Start, ISO 8601 UTC (`2026-11-21T10:00:00Z`).
    pub start_utc: String,
    /// Rig file (sensors, mounting, lever arm, DBC), relative to the drive file.
    pub rig: std::path::PathBuf,
    /// The path.
    pub path: PathSpec,
    /// Walkers.
    #[serde(default, rename = "walker")]
    pub walkers: Vec<WalkerSpec>,
    /// Yielding.
    #[serde(default)]
    pub yield_to: Option<YieldSpec>,
    /// Variation between repetitions.
    #[serde(default)]
    pub variation: Variation,
    /// Lidar stream.
    #[serde(default)]
    pub lidar: LidarStream,
    /// GNSS stream.
    #[serde(default)]
    pub gnss: GnssStream,
    /// CAN stream.
    #[serde(default)]
    pub can: CanStream,
    /// The heading source's stream, written when the rig has `[gnss.heading]`.
    #[serde(default)]
    pub heading: HeadingStream,
    /// Survey of static objects.
    #[serde(default)]
    pub survey: Survey,
    /// Injected faults (none by default).
    #[serde(default)]
    pub faults: Option<Faults>,
}

/// Parses `YYYY-MM-DDTHH:MM:SS[.fff]Z`.
pub fn parse_utc(s: &str) -> Option<UtcNanos> {
    let s = s.strip_suffix('Z')?;
    let (date, time) = s.split_once('T')?;
    let mut d = date.split('-');
    let y: i64 = d.next()?.parse().ok()?;
    let m: u32 = d.next()?.parse().ok()?;
    let day: u32 = d.next()?.parse().ok()?;
    let mut t = time.split(':');
    let h: i64 = t.next()?.parse().ok()?;
    let mi: i64 = t.next()?.parse().ok()?;
    let sec: f64 = t.next()?.parse().ok()?;
    if !(1..=12).contains(&m) || !(1..=31).contains(&day) || h > 23 || mi > 59 || sec >= 61.0 {
        return None;
    }
    let nanos = (h * 3600 + mi * 60) * 1_000_000_000 + (sec * 1e9).round() as i64;
    hilrig_stamp::civil::utc_from_civil(y, m, day, nanos)
}

/// Why a drive cannot be driven.
#[derive(Debug, thiserror::Error)]
pub enum DriveError {
    /// A bad value.
    #[error("drive '{name}': {what}")]
    Invalid {
        /// Drive name.
        name: String,
        /// What.
        what: String,
    },
    /// The path as planned, at the speeds the drive passes it, is beyond what a car can do: a
    /// trajectory no vehicle makes, which `check` would then find fault with.
    #[error("drive '{name}': no car can drive this path: {}. Move or add waypoints so that the path turns more gently there (a spline through close or doubling-back waypoints loops), or lower cruise_speed_mps", beyond_text(.exceeded, .waypoints))]
    Undrivable {
        /// Drive name.
        name: String,
        /// Each limit exceeded, where it is exceeded most, the largest excess first.
        exceeded: Vec<Exceedance>,
        /// The drive's waypoints (to name the stretch each excess lies in).
        waypoints: Vec<[f64; 2]>,
    },
    /// The drive file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The drive file is not a drive (TOML, its keys).
    #[error("{path}: {source}")]
    Toml {
        /// The file.
        path: String,
        /// The parser's complaint, with the line.
        #[source]
        source: toml::de::Error,
    },
    /// A number of the drive file that is not finite.
    #[error("{path}: {source}")]
    NonFinite {
        /// The file.
        path: String,
        /// The key.
        #[source]
        source: crate::config::NonFinite,
    },
    /// A start time that does not read.
    #[error("{path}: start_utc '{text}' is not YYYY-MM-DDTHH:MM:SSZ")]
    StartUtc {
        /// The file.
        path: String,
        /// What it says.
        text: String,
    },
}

/// The limits exceeded and where: the stretch of the path (the two waypoints around it,
/// counted from 0 as in the file) and the point, once for the limits exceeded at the same point.
pub fn beyond_text(exceeded: &[Exceedance], waypoints: &[[f64; 2]]) -> String {
    let wp = |i: usize| {
        waypoints
            .get(i)
            .map_or_else(String::new, |w| format!(" [{}, {}]", w[0], w[1]))
    };
    let mut places: Vec<(PathPoint, Vec<String>)> = Vec::new();
    for e in exceeded {
        match places.iter_mut().find(|(p, _)| *p == e.at) {
            Some((_, what)) => what.push(e.to_string()),
            None => places.push((e.at, vec![e.to_string()])),
        }
    }
    places
        .iter()
        .map(|(p, what)| {
            format!(
                "between waypoint {}{} and waypoint {}{} (counted from 0; {:.1} m along the path, at [{:.2}, {:.2}], passed at {:.1} m/s on a radius of {:.2} m): {}",
                p.segment,
                wp(p.segment),
                p.segment + 1,
                wp(p.segment + 1),
                p.s_m,
                p.position[0],
                p.position[1],
                p.speed_mps,
                1.0 / p.curvature_per_m.abs(),
                what.join(", ")
            )
        })
        .collect::<Vec<_>>()
        .join("; ")
}

impl DriveFile {
    /// Reads a drive file.
    pub fn load(path: &std::path::Path) -> Result<DriveFile, DriveError> {
        let p = || path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|source| DriveError::Io { path: p(), source })?;
        crate::config::check_finite(&text)
            .map_err(|source| DriveError::NonFinite { path: p(), source })?;
        let d: DriveFile =
            toml::from_str(&text).map_err(|source| DriveError::Toml { path: p(), source })?;
        if parse_utc(&d.start_utc).is_none() {
            return Err(DriveError::StartUtc {
                path: p(),
                text: d.start_utc,
            });
        }
        Ok(d)
    }
}

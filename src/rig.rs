//! Rig files (`rigs/*.toml`): what is mounted where, how to reach it, and how to record.
//!
//! Every table rejects unknown keys, so a typo in a field name is an error at start, not a
//! silently ignored setting on the test vehicle. Paths (DBC, calibration, output directory) are
//! relative to the rig file's folder.

use hilrig_can::ego::EgoMapping;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A rig.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rig {
    /// Rig name, written into every recording's metadata.
    pub name: String,
    /// The lidar, if mounted.
    pub lidar: Option<LidarConfig>,
    /// The RTK GNSS receiver, if mounted.
    pub gnss: Option<GnssConfig>,
    /// The vehicle CAN bus, if connected.
    pub can: Option<CanConfig>,
    /// Recording settings.
    #[serde(default)]
    pub recording: RecordingConfig,
    /// Limits `hilrig check` judges the reference data by.
    #[serde(default)]
    pub thresholds: Thresholds,
    /// Folder of the rig file (set when loaded; paths resolve against it).
    #[serde(skip)]
    pub base: PathBuf,
}

/// A rigid mounting: position of the sensor origin in the vehicle frame (ISO 8855: x forward,
/// y left, z up, origin at the rear axle centre on the ground) and its orientation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mounting {
    /// Forward, metres.
    pub x: f64,
    /// Left, metres.
    pub y: f64,
    /// Up, metres.
    pub z: f64,
    /// Roll, degrees (about x).
    #[serde(default)]
    pub roll_deg: f64,
    /// Pitch, degrees (about y).
    #[serde(default)]
    pub pitch_deg: f64,
    /// Yaw, degrees (about z).
    #[serde(default)]
    pub yaw_deg: f64,
}

/// The lidar.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LidarConfig {
    /// Model (vlp16, puck-hires, vlp32c, hdl32e); checked against the packets' product byte.
    pub model: String,
    /// Address to bind for live recording.
    #[serde(default = "default_bind")]
    pub bind: String,
    /// UDP port of data packets.
    #[serde(default = "default_data_port")]
    pub data_port: u16,
    /// UDP port of position packets.
    #[serde(default = "default_position_port")]
    pub position_port: u16,
    /// Calibration file (ros-drivers YAML or VeloView XML), optional.
    pub calibration: Option<PathBuf>,
    /// Azimuth where one rotation (one VelodyneScan message) ends, degrees.
    #[serde(default)]
    pub cut_azimuth_deg: f64,
    /// TF frame of the sensor.
    #[serde(default = "default_lidar_frame")]
    pub frame_id: String,
    /// Where the sensor is mounted.
    #[serde(default)]
    pub mounting: Mounting,
}

/// The GNSS receiver.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GnssConfig {
    /// Serial port (prefer a stable /dev/serial/by-id/ name).
    pub port: String,
    /// Baud rate.
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// TF frame of the antenna.
    #[serde(default = "default_gnss_frame")]
    pub frame_id: String,
    /// Antenna phase centre in the vehicle frame (the lever arm).
    #[serde(default)]
    pub antenna: Mounting,
    /// The reference system's own heading, when it measures one (an INS, a dual-antenna
    /// receiver): which of its messages `check` fuses, and how it is mounted.
    #[serde(default)]
    pub heading: Option<HeadingConfig>,
}

/// The heading reference of the rig (`[gnss.heading]`).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeadingConfig {
    /// The message that carries it.
    pub source: HeadingSource,
    /// The source's heading axis against the vehicle's x axis, degrees clockwise seen from
    /// above: a dual-antenna baseline across the car reads 90 (or -90) off the vehicle's
    /// heading; an INS aligned with the car, 0. `check` estimates what remains.
    #[serde(default)]
    pub yaw_offset_deg: f64,
    /// How well `yaw_offset_deg` is known, 1 sigma, degrees: set it when a calibration measured
    /// the mounting (a long drive's `check` reports the offset it estimated, `offset_deg ±
    /// offset_sigma_deg` in `heading_source`). `check` then takes it as the offset's prior.
    /// Without it the drive alone decides the offset, and a drive can tell it only as well as
    /// its track tells the heading: on a 20 m parking manoeuvre with 1 cm RTK noise that is
    /// about 0.035°, which the smoothed heading then inherits.
    #[serde(default)]
    pub yaw_offset_sigma_deg: Option<f64>,
    /// Expected accuracy (1 sigma), degrees, for messages that state none (HDT, THS,
    /// PSTI,036) and as a floor under those that do.
    pub sigma_deg: f64,
}

impl HeadingConfig {
    /// Refuses accuracies that are not positive: a zero sigma would make the smoother take
    /// every report, or the mounting, as exact.
    /// (`name` says where the rig came from in the error.)
    fn check(&self, name: &str) -> Result<(), RigError> {
        let bad = |message: String| {
            Err(RigError::Parse {
                path: name.to_owned(),
                message,
            })
        };
        if self.sigma_deg <= 0.0 {
            return bad(format!(
                "gnss.heading.sigma_deg = {}: the source's accuracy must be positive",
                self.sigma_deg
            ));
        }
        match self.yaw_offset_sigma_deg {
            Some(s) if s <= 0.0 => bad(format!(
                "gnss.heading.yaw_offset_sigma_deg = {s}: how well the mounting is known must be positive (leave it out to estimate the offset from the drive)"
            )),
            _ => Ok(()),
        }
    }
}

/// A message that can carry the heading reference.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
pub enum HeadingSource {
    /// NMEA HDT.
    #[serde(rename = "HDT")]
    Hdt,
    /// NMEA THS.
    #[serde(rename = "THS")]
    Ths,
    /// PASHR.
    #[serde(rename = "PASHR")]
    Pashr,
    /// SkyTraq PSTI,036.
    #[serde(rename = "PSTI,036")]
    Psti036,
    /// UBX NAV-ATT.
    #[serde(rename = "NAV-ATT")]
    NavAtt,
    /// UBX NAV-PVAT.
    #[serde(rename = "NAV-PVAT")]
    NavPvat,
    /// UBX NAV-RELPOSNED (moving base).
    #[serde(rename = "NAV-RELPOSNED")]
    NavRelposned,
    /// UBX HNR-ATT.
    #[serde(rename = "HNR-ATT")]
    HnrAtt,
}

impl HeadingSource {
    /// Its name, as in the rig file and the receiver's messages (`HDT`, `NAV-ATT`).
    pub fn name(self) -> &'static str {
        self.attitude_source().name()
    }

    /// The driver's attitude source for the message.
    pub fn attitude_source(self) -> hilrig_gnss::AttitudeSource {
        use hilrig_gnss::AttitudeSource as A;
        match self {
            HeadingSource::Hdt => A::Hdt,
            HeadingSource::Ths => A::Ths,
            HeadingSource::Pashr => A::Pashr,
            HeadingSource::Psti036 => A::Psti036,
            HeadingSource::NavAtt => A::NavAtt,
            HeadingSource::NavPvat => A::NavPvat,
            HeadingSource::NavRelposned => A::NavRelposned,
            HeadingSource::HnrAtt => A::HnrAtt,
        }
    }
}

/// The CAN bus.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CanConfig {
    /// SocketCAN interface.
    pub interface: String,
    /// DBC file.
    pub dbc: PathBuf,
    /// Which DBC signals give ego motion.
    #[serde(default)]
    pub ego: EgoMapping,
}

/// Recording settings.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordingConfig {
    /// Output folder for live recordings.
    #[serde(default = "default_output_dir")]
    pub output_dir: PathBuf,
    /// Chunk compression: zstd, lz4 or none.
    #[serde(default = "default_compression")]
    pub compression: crate::bag::Compression,
    /// zstd level.
    #[serde(default = "default_level")]
    pub compression_level: u32,
    /// Chunk size in MiB (a chunk is also closed after one second).
    #[serde(default = "default_chunk_mib")]
    pub chunk_size_mib: u64,
    /// Start a new file after this many MiB (default: never). Static data (rig, metadata,
    /// /tf_static) is repeated in every file.
    #[serde(default)]
    pub split_size_mib: Option<u64>,
    /// Start a new file after this many seconds of data (default: never).
    #[serde(default)]
    pub split_duration_s: Option<f64>,
    /// Also write the decoded points of each rotation to /points (PointCloud2) for viewing.
    /// Off by default: it roughly doubles the file and costs CPU on the vehicle, and the
    /// packets already hold everything (`record --from` can add it in the office).
    #[serde(default)]
    pub points: bool,
    /// Messages that may wait between the sources and the writer thread (at least 1). The
    /// default, 8192, holds about two seconds of a VLP-32C plus everything else: a disk that
    /// stalls for longer makes the sources drop messages (counted, reported, exit status 1)
    /// rather than stall the sockets.
    #[serde(default = "default_queue")]
    pub queue_messages: usize,
}

impl RecordingConfig {
    /// The writer options these settings mean.
    pub fn bag_options(&self) -> crate::bag::BagOptions {
        crate::bag::BagOptions {
            compression: self.compression,
            level: self.compression_level,
            chunk_size: self.chunk_size_mib * 1024 * 1024,
            split_size: self.split_size_mib.map(|m| m * 1024 * 1024),
            split_duration_ns: self.split_duration_s.map(|s| (s * 1e9) as i64),
            durable: false,
        }
    }
}

impl Default for RecordingConfig {
    fn default() -> Self {
        RecordingConfig {
            output_dir: default_output_dir(),
            compression: default_compression(),
            compression_level: default_level(),
            chunk_size_mib: default_chunk_mib(),
            split_size_mib: None,
            split_duration_s: None,
            points: false,
            queue_messages: default_queue(),
        }
    }
}

fn default_bind() -> String {
    "0.0.0.0".into()
}
fn default_data_port() -> u16 {
    hilrig_velodyne::DATA_PORT
}
fn default_position_port() -> u16 {
    hilrig_velodyne::POSITION_PORT
}
fn default_lidar_frame() -> String {
    "velodyne".into()
}
fn default_gnss_frame() -> String {
    "gnss".into()
}
fn default_baud() -> u32 {
    115_200
}
fn default_output_dir() -> PathBuf {
    PathBuf::from("recordings")
}
fn default_compression() -> crate::bag::Compression {
    crate::bag::Compression::Zstd
}
fn default_level() -> u32 {
    1
}
fn default_chunk_mib() -> u64 {
    4
}
fn default_queue() -> usize {
    8192
}

/// Limits for the reference-data check (Rosenberger et al. 2019, §6: reference data must be an order of magnitude
/// more accurate than the smallest structure the metrics resolve). Each default says where it
/// comes from; override them per rig.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Thresholds {
    /// Share of epochs that must be RTK-fixed. Default 0.95: float epochs carry decimetre
    /// errors, so more than one epoch in twenty makes the trajectory unfit for a 10 cm grid.
    pub min_rtk_fixed_share: f64,
    /// Largest 1-sigma horizontal error of an epoch, m. Default 0.02: twice the 1 cm + 1 ppm
    /// horizontal RTK accuracy that receiver data sheets (u-blox F9P, Trimble) state.
    pub max_sigma_horizontal_m: f64,
    /// Largest 1-sigma vertical error, m. Default 0.04: twice the data-sheet vertical RTK
    /// accuracy (about 2 cm).
    pub max_sigma_vertical_m: f64,
    /// Largest age of RTK corrections, s. Default 5: beyond that RTK engines degrade to float
    /// (the default correction timeout of common receivers).
    pub max_correction_age_s: f64,
    /// A gap is this many samples missing in a row: an interval of more than this many and a
    /// half nominal periods (k lost samples leave k + 1), so that jitter cannot make one lost
    /// sample fewer a gap. A whole number, at least 1 (`3` or `3.0`). Default 3: one lost
    /// sample is noise, three in a row is a gap.
    #[serde(deserialize_with = "whole_count")]
    pub gap_periods: u32,
    /// Largest 95th percentile of the lidar's clock-model residuals (transport jitter) when it
    /// runs without PPS, µs: its packets are then placed in time by that model. Default 1000:
    /// at 10 km/h the ego moves 2.8 mm in 1 ms, well inside a 10 cm cell. The GNSS clock
    /// model's residuals are not judged: each fix carries its own time tag, and a serial
    /// line's jitter of a millisecond or two moves nothing.
    pub max_clock_residual_p95_us: f64,
    /// Smallest grid cell the metrics may use, m (Rosenberger et al. 2019, §6: 10 cm).
    pub min_grid_cell_m: f64,
    /// The grid cell must be at least this many times the reference accuracy (Rosenberger et al. 2019, §6: 10).
    pub grid_cell_accuracy_factor: f64,
    /// Largest relative error of the CAN speed against GNSS. Default 0.01: the tolerance of a
    /// wheel-speed calibration (tyre wear and pressure change the rolling radius by about 1 %).
    pub max_speed_scale_error: f64,
    /// Largest time offset between GNSS and CAN, ms. Default 10: at 10 km/h, 10 ms move the ego
    /// 2.8 cm, a quarter of the smallest grid cell.
    pub max_time_offset_ms: f64,
    /// Largest error of the antenna lever arm the data reveal, m. Default 0.10: in turns a
    /// lever-arm error becomes a position error of up to its own size, and 10 cm is the grid.
    pub max_lever_arm_error_m: f64,
    /// Whether the lidar must be PPS-locked. Default true: without PPS its time comes from host
    /// stamps and a free-running oscillator (tens of ppm), not from GNSS time.
    pub require_pps: bool,
    /// A GNSS epoch further than this many sigmas from the smoothed trajectory is a jump that
    /// CAN speed and yaw rate cannot explain. Default 5 (a false alarm once in 270 000 epochs).
    pub max_jump_sigma: f64,
    /// Largest 1-sigma heading error of the smoothed trajectory, degrees; stretches above it
    /// are marked not usable. A heading error turns the whole scene about the ego: at 30 m,
    /// 0.2° moves a point by 10 cm, the smallest grid cell (Rosenberger et al. 2019, §6).
    /// Default 0.2: RTK with CAN gives about 0.1° while the vehicle drives
    /// (`benches/check_campaign.py`), and more before it has moved far enough to show its
    /// heading, or in slow turns.
    pub max_heading_sigma_deg: f64,
    /// The largest offset of the heading source against the track beyond the rig file's
    /// `[gnss.heading] yaw_offset_deg`, degrees. Default 3: a dual-antenna baseline is laid out
    /// to a degree or two; more is a mounting the rig file does not describe.
    pub max_heading_offset_deg: f64,
    /// The range at which a heading error is counted in the accuracy budget, m. Default 30:
    /// beyond it a VLP-16's rings are more than half a metre apart and carry little of what the
    /// metrics compare.
    pub heading_range_m: f64,
}

/// A count of at least 1 given as a whole number, written as an integer or a float (`3.0`, as
/// rig files of earlier versions hold it); anything else is refused with the value.
fn whole_count<'de, D: serde::Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    let v = f64::deserialize(d)?;
    if v.fract() == 0.0 && (1.0..=f64::from(u32::MAX)).contains(&v) {
        Ok(v as u32)
    } else {
        Err(serde::de::Error::custom(format!(
            "{v} is not a whole number of at least 1 (samples missing in a row)"
        )))
    }
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            min_rtk_fixed_share: 0.95,
            max_sigma_horizontal_m: 0.02,
            max_sigma_vertical_m: 0.04,
            max_correction_age_s: 5.0,
            gap_periods: 3,
            max_clock_residual_p95_us: 1000.0,
            min_grid_cell_m: 0.10,
            grid_cell_accuracy_factor: 10.0,
            max_speed_scale_error: 0.01,
            max_time_offset_ms: 10.0,
            max_lever_arm_error_m: 0.10,
            require_pps: true,
            max_jump_sigma: 5.0,
            max_heading_sigma_deg: 0.2,
            max_heading_offset_deg: 3.0,
            heading_range_m: 30.0,
        }
    }
}

/// A rig file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum RigError {
    /// Reading failed.
    #[error("cannot read rig file {path}: {source}")]
    Io {
        /// Path.
        path: String,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// Not valid TOML or not the rig schema (unknown keys included).
    #[error("rig file {path}: {message}")]
    Parse {
        /// Path.
        path: String,
        /// What is wrong, with line and column.
        message: String,
    },
}

/// Why a rig's lidar cannot be decoded or simulated.
#[derive(Debug, thiserror::Error)]
pub enum LidarSensorError {
    /// No `[lidar]` table.
    #[error("the rig has no [lidar]")]
    NoLidar,
    /// A model the decoder does not know (the decoder's message names the known ones).
    #[error("{0}")]
    UnknownModel(String),
    /// The calibration file does not read.
    #[error(transparent)]
    Calibration(#[from] hilrig_velodyne::CalibrationError),
    /// A model whose geometry differs per unit, without its file.
    #[error("the {model} needs its unit's own calibration ({reason}): set [lidar] calibration = \"FILE\" (a ros-drivers YAML or VeloView XML file) in the rig")]
    NeedsCalibration {
        /// The model.
        model: hilrig_velodyne::Model,
        /// Why it needs one.
        reason: &'static str,
    },
}

impl Rig {
    /// The lidar's model and calibration (the rig's calibration file, else the model's built-in
    /// geometry), with its settings: what every step that decodes or simulates its packets
    /// needs. An error says what is missing or wrong.
    pub fn lidar_sensor(
        &self,
    ) -> Result<
        (
            &LidarConfig,
            hilrig_velodyne::Model,
            hilrig_velodyne::Calibration,
        ),
        LidarSensorError,
    > {
        let lidar = self.lidar.as_ref().ok_or(LidarSensorError::NoLidar)?;
        let model: hilrig_velodyne::Model = lidar
            .model
            .parse()
            .map_err(LidarSensorError::UnknownModel)?;
        let calibration = match &lidar.calibration {
            Some(p) => hilrig_velodyne::Calibration::from_file(&self.resolve(p), model)?,
            None if model.needs_calibration_file() => {
                return Err(LidarSensorError::NeedsCalibration {
                    model,
                    reason: model.calibration_file_reason().unwrap_or_default(),
                })
            }
            None => hilrig_velodyne::Calibration::builtin(model),
        };
        Ok((lidar, model, calibration))
    }

    /// Parses a rig file's text (`name` says where it came from in errors).
    pub fn from_toml(text: &str, name: &str) -> Result<Rig, RigError> {
        crate::config::check_finite(text).map_err(|e| RigError::Parse {
            path: name.to_owned(),
            message: e.to_string(),
        })?;
        let rig: Rig = toml::from_str(text).map_err(|e| RigError::Parse {
            path: name.to_owned(),
            message: e.to_string(),
        })?;
        rig.check_heading(name)?;
        Ok(rig)
    }

    /// The heading source's accuracies, checked (see [`HeadingConfig::check`]); `name` says
    /// where the rig came from in the error.
    fn check_heading(&self, name: &str) -> Result<(), RigError> {
        match self.gnss.as_ref().and_then(|g| g.heading.as_ref()) {
            Some(h) => h.check(name),
            None => Ok(()),
        }
    }

    /// Loads and checks a rig file.
    pub fn load(path: &Path) -> Result<Rig, RigError> {
        let text = std::fs::read_to_string(path).map_err(|e| RigError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        let mut rig = Rig::from_toml(&text, &path.display().to_string())?;
        rig.base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        if let Some(l) = &rig.lidar {
            l.model
                .parse::<hilrig_velodyne::Model>()
                .map_err(|e| RigError::Parse {
                    path: path.display().to_string(),
                    message: format!("lidar.model: {e}"),
                })?;
        }
        Ok(rig)
    }

    /// A path from the rig file, resolved against its folder.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.base.join(p)
        }
    }
}

impl Rig {
    /// The rig's extrinsics as static transforms from `base_link` (the vehicle frame).
    pub fn transforms(&self) -> Vec<crate::bag::msgs::Transform> {
        let t = |child: &str, m: &Mounting| crate::bag::msgs::Transform {
            parent: "base_link".into(),
            child: child.into(),
            translation: [m.x, m.y, m.z],
            rpy: [
                m.roll_deg.to_radians(),
                m.pitch_deg.to_radians(),
                m.yaw_deg.to_radians(),
            ],
        };
        let mut out = Vec::new();
        if let Some(l) = &self.lidar {
            out.push(t(&l.frame_id, &l.mounting));
        }
        if let Some(g) = &self.gnss {
            out.push(t(&g.frame_id, &g.antenna));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_demo_rig_loads_and_typos_are_rejected() {
        let rig = Rig::load(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/rigs/demo.toml"
        )))
        .unwrap();
        assert_eq!(rig.lidar.as_ref().unwrap().model, "vlp16");
        assert!(rig.can.as_ref().unwrap().ego.yaw_rate.is_some());
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.toml");
        std::fs::write(
            &bad,
            "name = \"x\"\n[lidar]\nmodel = \"vlp16\"\ndata_prot = 2368\n",
        )
        .unwrap();
        let e = Rig::load(&bad).unwrap_err().to_string();
        assert!(e.contains("unknown field `data_prot`"), "{e}");
        assert_eq!(rig.thresholds.min_grid_cell_m, 0.10);
        std::fs::write(
            &bad,
            "name = \"x\"\n[thresholds]\nmin_rtk_fixed_share = 0.9\nmax_sigma_horizontl_m = 1\n",
        )
        .unwrap();
        assert!(Rig::load(&bad)
            .unwrap_err()
            .to_string()
            .contains("max_sigma_horizontl_m"));
        std::fs::write(&bad, "name = \"x\"\n[lidar]\nmodel = \"velarray\"\n").unwrap();
        assert!(Rig::load(&bad)
            .unwrap_err()
            .to_string()
            .contains("lidar.model"));
    }

    /// A gap is a whole number of samples missing in a row: `3` and `3.0` read alike, `2.5`
    /// and `0` are refused with the value.
    #[test]
    fn gap_periods_is_a_whole_count() {
        let th = |v: &str| {
            Rig::from_toml(
                &format!("name = \"x\"\n[thresholds]\ngap_periods = {v}\n"),
                "t",
            )
        };
        assert_eq!(th("3").unwrap().thresholds.gap_periods, 3);
        assert_eq!(th("4.0").unwrap().thresholds.gap_periods, 4);
        for bad in ["2.5", "0", "-1"] {
            let e = th(bad).unwrap_err().to_string();
            assert!(e.contains("not a whole number of at least 1"), "{bad}: {e}");
        }
    }
}

//! Synthesizes measured drives as they come off the vehicle: per repetition one pcapng (optionally
//! zstd-compressed) holding Velodyne data and position packets, the GNSS receiver's serial
//! stream (GGA, RMC, GST) and the ego CAN frames, with realistic reference errors; plus what the
//! engineer would have (the surveyed scene) and what only the synthesizer knows (the truth).
//!
//! Per repetition `rep-NN/`:
//! - `drive.pcapng[.zst]`: the capture (interfaces: eth0, the GNSS serial port as USER0, can0);
//! - `scene.toml` + actor CSVs: the scene as surveyed (static objects displaced by the survey
//!   error, the walker's trajectory as measured);
//! - `truth.csv`: the true rear-axle trajectory; `truth.toml`: seeds, variation drawn, errors
//!   injected and counts.
//!
//! Randomness comes from ChaCha8 streams seeded from `(seed, repetition, purpose)`, so a
//! repetition is reproducible on its own and independent of thread scheduling.

use super::drive::{beyond_text, DriveFile, Driven};
use super::lidar::{FootprintCast, LidarSim, SimStats};
use super::model::ModelFile;
use super::spin::Spin;
use super::streams::{hms, nmea_lat_lon, Streams};
use crate::rig::Rig;
use crate::scene::file::{ActorFile, SceneFile};
use crate::scene::geodesy::Enu;
use crate::scene::Scene;
use hilrig_can::dbc::Database;
use hilrig_capture::writer::udp_ethernet_frame;
use hilrig_capture::{LinkType, PcapngWriter};
use hilrig_gnss::framer::nmea_sentence;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::packet::ReturnMode;
use hilrig_velodyne::{Calibration, Model, PositionPacket, PpsStatus};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use std::net::{Ipv4Addr, SocketAddrV4};
use std::path::{Path, PathBuf};

/// Why synthesis failed.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// The drive's rig file cannot be read.
    #[error(transparent)]
    Rig(#[from] crate::rig::RigError),
    /// The rig lacks a sensor synth makes data for.
    #[error("{}: synth needs a {what}", .rig.display())]
    RigLacks {
        /// The rig file.
        rig: PathBuf,
        /// What is missing (`[gnss]`).
        what: &'static str,
    },
    /// The rig's lidar cannot be synthesized.
    #[error("{}: synth needs a lidar: {source}", .rig.display())]
    Lidar {
        /// The rig file.
        rig: PathBuf,
        /// Why.
        #[source]
        source: crate::rig::LidarSensorError,
    },
    /// The rig's DBC cannot be read.
    #[error(transparent)]
    Dbc(#[from] hilrig_can::DbcError),
    /// The drive file's lidar return mode is not one a Velodyne has.
    #[error("lidar return_mode '{0}': expected strongest, last or dual")]
    ReturnMode(String),
    /// The drive cannot be driven (or its file is wrong).
    #[error(transparent)]
    Drive(#[from] super::drive::DriveError),
    /// The driven trajectory does not read back from its CSV.
    #[error("the true trajectory: {0}")]
    Trajectory(#[from] crate::scene::pose::TrajectoryError),
    /// A drive's walker that the scene has no actor of.
    #[error("drive walker '{0}' is not an actor of the scene")]
    Walker(String),
    /// The true scene cannot be built.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// The surveyed scene cannot be written as TOML.
    #[error("the surveyed scene: {0}")]
    SceneToml(#[from] toml::ser::Error),
    /// The truth model cannot simulate the rig's lidar.
    #[error(transparent)]
    Model(#[from] super::model::ModelError),
    /// A noise's sigma is not a number.
    #[error("{what}: {source}")]
    Noise {
        /// Which noise (`lidar jitter_us`).
        what: &'static str,
        /// Why.
        #[source]
        source: rand_distr::NormalError,
    },
    /// A sensor's stream cannot be made.
    #[error(transparent)]
    Stream(#[from] super::streams::StreamError),
    /// Writing failed.
    #[error("writing {path}: {source}")]
    Io {
        /// Path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

/// What to synthesize.
pub struct SynthJob<'a> {
    /// The true scene (as it really is).
    pub scene_file: &'a SceneFile,
    /// Its directory (meshes).
    pub scene_base: &'a Path,
    /// The drive.
    pub drive: &'a DriveFile,
    /// Directory of the drive file (the rig path is relative to it).
    pub drive_base: &'a Path,
    /// The truth model.
    pub truth: &'a ModelFile,
    /// Base seed.
    pub seed: u64,
    /// Compress the captures with zstd (`.pcapng.zst`).
    pub compress: bool,
    /// Human variation and reference errors on (off: the planned drive, no noise, no loss).
    pub errors: bool,
}

/// Counts of one repetition.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RepSummary {
    /// Repetition number (1-based).
    pub rep: u32,
    /// Capture file name (in the repetition's directory).
    pub capture: PathBuf,
    /// Data packets written.
    pub lidar_packets: u64,
    /// Data packets dropped (injected loss).
    pub lidar_packets_lost: u64,
    /// Position packets written.
    pub position_packets: u64,
    /// NMEA sentences written.
    pub sentences: u64,
    /// CAN frames written.
    pub can_frames: u64,
    /// Duration, s.
    pub duration_s: f64,
    /// Seconds the ego waited for the walker.
    pub yield_stop_s: f64,
    /// Firings with a return / all firings; none when the drive casts no returns
    /// (`[lidar] returns = false`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub return_share: Option<f64>,
    /// The limits of a car this repetition goes beyond as driven, each where it does so most:
    /// the change of curvature where the driver model steers faster than a car can, and any
    /// limit the human variation drawn for it takes a drive that is within them as planned
    /// beyond (a faster or tighter line). Not refused (the plan is a car's), but named.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub beyond_car: Vec<String>,
}

fn stream_rng(seed: u64, rep: u32, purpose: u64) -> ChaCha8Rng {
    // SplitMix64-style mixing of the three so nearby seeds give unrelated streams.
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(u64::from(rep) << 32)
        .wrapping_add(purpose);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ChaCha8Rng::seed_from_u64(z ^ (z >> 31))
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), SynthError> {
    std::fs::write(path, bytes).map_err(|source| SynthError::Io {
        path: path.to_owned(),
        source,
    })
}

/// Synthesizes repetition `rep` (1-based) into `dir`.
#[allow(
    clippy::too_many_lines,
    reason = "the lidar stream (spin schedule, parallel casting, loss, position packets) in order; rig parts, scenes, GNSS/CAN streams and the capture are functions of their own"
)]
pub fn synth_rep(job: &SynthJob, rep: u32, dir: &Path) -> Result<RepSummary, SynthError> {
    let RigParts {
        lidar,
        gnss: gnss_cfg,
        can: can_cfg,
        model,
        calibration,
        dbc,
        mode,
    } = rig_parts(job)?;
    let (lidar, gnss_cfg, can_cfg) = (&lidar, &gnss_cfg, &can_cfg);
    // Nothing is written for a drive no car can drive.
    job.drive.drivable()?;
    let errors = job.errors;
    let mut driven: Driven = job.drive.drive(&mut stream_rng(job.seed, rep, 1), errors)?;
    std::fs::create_dir_all(dir).map_err(|source| SynthError::Io {
        path: dir.to_owned(),
        source,
    })?;
    // The truth is the file: everything below uses the trajectory as `truth.csv` holds it, so
    // that re-simulating from that file casts bit-identical rays.
    let truth_csv = driven.ego.to_csv();
    driven.ego = crate::scene::pose::Trajectory::from_csv(&truth_csv)?;

    let scene = write_scenes(job, rep, dir, &driven, &truth_csv)?;

    // The synthesized drive stands in for the real sensor, whose beam meets even what is
    // thinner than the firings' spacing: its footprints are cast in full, not adaptively (the
    // committed drives were made so).
    let sim = LidarSim::new(&scene, model, calibration, &lidar.mounting, job.truth)?
        .with_footprint_cast(FootprintCast::Full);
    let (start, end) = driven.span;
    let mut events: Vec<(i64, u32, Vec<u8>)> = Vec::new();
    const ETH: u32 = 0;
    const SER: u32 = 1;
    const CAN: u32 = 2;
    let addr = |port| SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 201), port);
    let host = |port| SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 77), port);

    // Lidar: PPS-locked (its clock is UTC), packets stamped by the host after their last firing.
    let ls = &job.drive.lidar;
    let mut lrng = stream_rng(job.seed, rep, 3);
    let spin = Spin {
        model,
        mode,
        rpm: ls.rpm,
        phase_deg: lrng.random::<f64>() * 360.0,
        t0: UtcNanos(start.0 + 1_000_000),
    };
    let n_packets = spin.packets_in((end.0 - spin.t0.0) as f64 * 1e-9 - 0.002);
    let period = spin.packet_period_ns();
    let seed = job.seed;
    let faults = job.drive.faults.clone().unwrap_or_default();
    let since_start = |t: UtcNanos| (t.0 - start.0) as f64 * 1e-9;
    // The lidar's clock: UTC when PPS-locked (late by `lidar_time_offset_ms` if so injected),
    // else free-running with an offset and a drift.
    let free = faults.lidar_free_running;
    let late_ns = (faults.lidar_time_offset_ms * 1e6).round() as i64;
    let sensor_clock = move |t: UtcNanos| match free {
        Some(c) => UtcNanos(
            t.0 + (c.offset_ms * 1e6) as i64 + ((t.0 - start.0) as f64 * c.drift_ppm * 1e-6) as i64,
        ),
        None => UtcNanos(t.0 + late_ns),
    };
    let pps = if free.is_some() {
        PpsStatus::Absent
    } else {
        PpsStatus::Locked
    };
    let results: Vec<(Vec<u8>, SimStats, u32)> = (0..n_packets)
        .into_par_iter()
        .map(|k| {
            let sk = spin.packet(k, sensor_clock);
            let mut stats = SimStats::default();
            if !ls.returns {
                return (sk.packet.encode().to_vec(), stats, sk.packet.timestamp_us);
            }
            let pkt = sim.simulate(
                &sk.packet,
                sk.time,
                &driven.ego,
                seed ^ (u64::from(rep) << 40) ^ k,
                &mut stats,
            );
            (pkt.encode().to_vec(), stats, sk.packet.timestamp_us)
        })
        .collect();
    let jitter =
        Normal::new(0.0, ls.jitter_us.max(0.0) * 1000.0).map_err(|source| SynthError::Noise {
            what: "lidar jitter_us",
            source,
        })?;
    let mut summary = RepSummary {
        rep,
        duration_s: (end.0 - start.0) as f64 * 1e-9,
        yield_stop_s: driven
            .yield_stop
            .map_or(0.0, |(a, b)| (b.0 - a.0) as f64 * 1e-9),
        beyond_car: driven
            .beyond_car
            .iter()
            .map(|e| beyond_text(std::slice::from_ref(e), &job.drive.path.waypoints))
            .chain(driven.beyond_car_backing.iter().map(|e| {
                format!(
                    "{}, {}",
                    crate::sim::drive::BACKING_UP,
                    beyond_text(std::slice::from_ref(e), &driven.backing_waypoints)
                )
            }))
            .collect(),
        ..RepSummary::default()
    };
    let (mut firings, mut returns) = (0u64, 0u64);
    let mut last_host = 0i64;
    let mut gga_for_position = String::new();
    for (k, (bytes, stats, ts_us)) in results.into_iter().enumerate() {
        firings += stats.firings;
        returns += stats.returns;
        let first = spin.t0.0 as f64 + k as f64 * period;
        let lat = if errors {
            ls.latency_us * 1000.0 + jitter.sample(&mut lrng).abs()
        } else {
            ls.latency_us * 1000.0
        };
        let h = ((first + period + lat) as i64).max(last_host + 1000);
        if errors && lrng.random::<f64>() < ls.packet_loss {
            summary.lidar_packets_lost += 1;
            continue;
        }
        let t_first = UtcNanos(first as i64);
        if faults
            .lidar_gap
            .iter()
            .any(|w| w.contains(since_start(t_first)))
        {
            summary.lidar_packets_lost += 1;
            continue;
        }
        last_host = h;
        events.push((h, ETH, udp_ethernet_frame(addr(2368), host(2368), &bytes)));
        summary.lidar_packets += 1;
        if ls.position_every > 0 && (k as u64).is_multiple_of(u64::from(ls.position_every)) {
            // The RMC of the last whole second, as the sensor forwards it from the receiver.
            let t = UtcNanos(first as i64);
            let sec = UtcNanos(t.0 - t.0.rem_euclid(1_000_000_000));
            let (hms_s, date) = hms(sec);
            let mut hint = 0;
            let (lat_lon, sog, cog) = match driven.ego.sample_at(sec, &mut hint) {
                Some(p) => {
                    let enu = Enu::new(&job.scene_file.origin);
                    let w = enu.to_wgs84(&p.position);
                    (
                        nmea_lat_lon(w.latitude_deg, w.longitude_deg),
                        0.0,
                        (90.0 - p.yaw.to_degrees()).rem_euclid(360.0),
                    )
                }
                None => (gga_for_position.clone(), 0.0, 0.0),
            };
            gga_for_position = lat_lon.clone();
            let rmc = nmea_sentence(&format!(
                "GPRMC,{hms_s},A,{lat_lon},{sog:.1},{cog:.1},{date},,,D"
            ));
            let pp = PositionPacket::new(ts_us, pps, rmc.trim_end());
            events.push((
                h + 200_000,
                ETH,
                udp_ethernet_frame(addr(8308), host(8308), &pp.encode()),
            ));
            summary.position_packets += 1;
        }
    }
    summary.return_share = ls.returns.then(|| returns as f64 / firings.max(1) as f64);

    let streams = Streams {
        driven: &driven,
        faults: &faults,
        errors,
        span: (start, end),
        origin: &job.scene_file.origin,
    };
    let (gnss, sentences) =
        streams.gnss(&job.drive.gnss, gnss_cfg, &mut stream_rng(job.seed, rep, 4))?;
    summary.sentences += sentences;
    events.extend(gnss.into_iter().map(|(t, b)| (t, SER, b)));
    if let Some(h) = gnss_cfg.heading.as_ref() {
        let (heading, n) = streams.heading(
            &job.drive.heading,
            &job.drive.gnss,
            h,
            &mut stream_rng(job.seed, rep, 6),
        )?;
        summary.sentences += n;
        events.extend(heading.into_iter().map(|(t, b)| (t, SER, b)));
    }
    let can = streams.can(
        &job.drive.can,
        can_cfg,
        &dbc,
        &mut stream_rng(job.seed, rep, 5),
    )?;
    summary.can_frames += can.len() as u64;
    events.extend(can.into_iter().map(|(t, b)| (t, CAN, b)));

    summary.capture = write_capture(job, rep, dir, events, gnss_cfg, can_cfg, &summary)?;
    Ok(summary)
}

/// The true scene of repetition `rep` with its walkers (what the lidar sees), and into `dir` the
/// scene as surveyed (static objects displaced by the survey error), the walkers' CSVs and the
/// truth trajectory.
fn write_scenes(
    job: &SynthJob,
    rep: u32,
    dir: &Path,
    driven: &Driven,
    truth_csv: &str,
) -> Result<Scene, SynthError> {
    let errors = job.errors;
    // The true scene with this repetition's walkers.
    let mut truth_file = job.scene_file.clone();
    let mut surveyed = job.scene_file.clone();
    for (name, traj) in &driven.walkers {
        let csv = dir.join(format!(
            "{}.csv",
            name.replace(|c: char| !c.is_alphanumeric(), "_")
        ));
        write_file(&csv, traj.to_csv().as_bytes())?;
        let csv = std::path::absolute(&csv).map_err(|source| SynthError::Io {
            path: csv.clone(),
            source,
        })?;
        let mut found = false;
        for (a, s) in truth_file.actors.iter_mut().zip(surveyed.actors.iter_mut()) {
            if &a.name == name {
                a.trajectory = csv.clone();
                s.trajectory = PathBuf::from(csv.file_name().unwrap_or_default());
                found = true;
            }
        }
        if !found {
            return Err(SynthError::Walker(name.clone()));
        }
    }
    // Actors of the scene without a walk keep their trajectory files (resolved absolutely:
    // `Scene::from_file` joins the base again, which a relative base would double).
    for a in truth_file.actors.iter_mut() {
        if a.trajectory.is_relative() {
            let joined = job.scene_base.join(&a.trajectory);
            a.trajectory = std::path::absolute(&joined).unwrap_or(joined);
        }
    }
    let scene = Scene::from_file(truth_file, job.scene_base, Path::new("scene"))?;

    // The surveyed scene: each static object displaced by the survey error.
    let mut survey_rng = stream_rng(job.seed, rep, 2);
    let sigma = if errors {
        job.drive.survey.sigma_m
    } else {
        0.0
    };
    let survey_noise = Normal::new(0.0, sigma.max(0.0)).map_err(|source| SynthError::Noise {
        what: "survey sigma_m",
        source,
    })?;
    for o in &mut surveyed.objects {
        o.pose.x += survey_noise.sample(&mut survey_rng);
        o.pose.y += survey_noise.sample(&mut survey_rng);
        o.accuracy_m = o.accuracy_m.max(sigma);
    }
    for o in surveyed.objects.iter_mut().flat_map(|o| o.parts.iter_mut()) {
        if let crate::scene::Shape::Mesh { file, .. } = o {
            *file = std::path::absolute(job.scene_base.join(&*file)).unwrap_or(file.clone());
        }
    }
    surveyed
        .actors
        .retain(|a: &ActorFile| driven.walkers.iter().any(|(n, _)| n == &a.name));
    let text = toml::to_string(&surveyed)?;
    write_file(
        &dir.join("scene.toml"),
        format!(
            "# Scene as surveyed for repetition {rep} (static objects with survey error, sigma {sigma} m).\n{text}"
        )
        .as_bytes(),
    )?;
    write_file(&dir.join("truth.csv"), truth_csv.as_bytes())?;
    Ok(scene)
}

/// Sorts the events by receive time and writes them as `drive.pcapng[.zst]` (interfaces:
/// Ethernet, the GNSS serial port, CAN), with the manifest `truth.toml`; returns the capture's
/// file name.
fn write_capture(
    job: &SynthJob,
    rep: u32,
    dir: &Path,
    mut events: Vec<(i64, u32, Vec<u8>)>,
    gnss_cfg: &crate::rig::GnssConfig,
    can_cfg: &crate::rig::CanConfig,
    summary: &RepSummary,
) -> Result<PathBuf, SynthError> {
    let errors = job.errors;
    events.sort_by_key(|e| e.0);
    let mut w = PcapngWriter::new(Vec::new(), "hilrig synth").map_err(|source| SynthError::Io {
        path: dir.to_owned(),
        source,
    })?;
    let io = |source| SynthError::Io {
        path: dir.to_owned(),
        source,
    };
    w.add_interface(LinkType::ETHERNET, "eth0").map_err(io)?;
    w.add_interface(LinkType::USER0, &gnss_cfg.port)
        .map_err(io)?;
    w.add_interface(LinkType::CAN_SOCKETCAN, &can_cfg.interface)
        .map_err(io)?;
    for (t, i, b) in &events {
        w.write_packet(*i, UtcNanos(*t), b).map_err(io)?;
    }
    let bytes = w.finish().map_err(io)?;
    let (name, bytes) = if job.compress {
        (
            "drive.pcapng.zst",
            zstd::encode_all(&bytes[..], 19).map_err(io)?,
        )
    } else {
        ("drive.pcapng", bytes)
    };
    write_file(&dir.join(name), &bytes)?;
    let manifest = format!(
        "# What only the synthesizer knows about repetition {rep}.\nseed = {}\nrepetition = {rep}\nmodel = {:?}\nerrors = {errors}\n\n[summary]\n{}",
        job.seed,
        job.truth.name,
        toml::to_string(&RepSummary { capture: PathBuf::from(name), ..summary.clone() }).unwrap_or_default()
    );
    write_file(&dir.join("truth.toml"), manifest.as_bytes())?;
    Ok(PathBuf::from(name))
}

/// What synthesis needs of the drive's rig, each part checked.
struct RigParts {
    lidar: crate::rig::LidarConfig,
    gnss: crate::rig::GnssConfig,
    can: crate::rig::CanConfig,
    model: Model,
    calibration: Calibration,
    dbc: Database,
    mode: ReturnMode,
}

/// The drive's rig with a lidar, a GNSS receiver and CAN, the lidar's calibration, the DBC and
/// the return mode, or the input problem that prevents synthesis.
fn rig_parts(job: &SynthJob) -> Result<RigParts, SynthError> {
    let rig_path = job.drive_base.join(&job.drive.rig);
    let rig = Rig::load(&rig_path)?;
    let (lidar, model, calibration) = rig.lidar_sensor().map_err(|source| SynthError::Lidar {
        rig: rig_path.clone(),
        source,
    })?;
    let lacks = |what| SynthError::RigLacks {
        rig: rig_path.clone(),
        what,
    };
    let gnss = rig.gnss.clone().ok_or_else(|| lacks("[gnss]"))?;
    let can = rig.can.clone().ok_or_else(|| lacks("[can]"))?;
    let dbc = Database::from_file(&rig.resolve(&can.dbc))?;
    let mode = match job.drive.lidar.return_mode.as_str() {
        "strongest" => ReturnMode::Strongest,
        "last" => ReturnMode::Last,
        "dual" => ReturnMode::Dual,
        other => return Err(SynthError::ReturnMode(other.to_owned())),
    };
    Ok(RigParts {
        lidar: lidar.clone(),
        gnss,
        can,
        model,
        calibration,
        dbc,
        mode,
    })
}

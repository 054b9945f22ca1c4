//! Re-simulation: a validated recording turned back into synthetic lidar data, the same sensor
//! on the same trajectory through the scene's digital twin.
//!
//! Every recorded data packet is re-simulated in place: its block azimuths, stamp and return
//! mode are kept (they are the sensor's firing schedule), its returns are replaced by the
//! model's. The firings happen at the packet's own stamp — the sensor's time, which is GNSS time
//! when the lidar is PPS-locked; otherwise the recorder's clock model (host time base) — plus the
//! manual's firing offsets. The ego pose comes from the run's smoothed RTK+CAN trajectory (or a
//! trajectory file), the mounting from the rig. The output is an MCAP with the simulated
//! VelodyneScans (same stamps, so the same decoder and replay apply), `/sim/points` clouds for
//! viewing, and the model, scene and trajectory source in its metadata.

use super::lidar::{LidarSim, PacketTime, SimStats};
use super::model::ModelFile;
use crate::bag::scans::sensor_time;
use crate::bag::topics;
use crate::bag::{msgs, BagOptions, BagWriter};
use crate::reference::check::{check_with_trajectory, Report, Verdict};
use crate::rig::Rig;
use crate::scene::pose::Trajectory;
use crate::scene::Scene;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::{DataPacket, Decoder, DATA_PACKET_SIZE};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// Topic of the simulated clouds.
pub const SIM_POINTS: &str = "/sim/points";

/// Why re-simulation did not run.
#[derive(Debug, thiserror::Error)]
pub enum ResimError {
    /// The run failed `check` (and `--force` was not given).
    #[error("the run's reference data fail the check ({}): re-simulating it would measure the reference errors, not the model; see `hilrig check`, or give --force to re-simulate it anyway", .0.faults.iter().map(|f| f.name).collect::<Vec<_>>().join(", "))]
    Refused(Box<Report>),
    /// The input cannot be used.
    #[error("{0}")]
    Input(String),
    /// Writing failed.
    #[error("writing the simulation: {0}")]
    Output(String),
}

/// Where the ego poses come from.
pub enum PoseSource {
    /// The run's own RTK+CAN trajectory (the validator's smoother).
    Run,
    /// A trajectory file (`t, x, y, z, yaw_deg` in the scene frame), e.g. a synthesizer's truth.
    File(Trajectory, String),
}

/// Counts of a re-simulation.
#[derive(Clone, Debug, Default)]
pub struct ResimSummary {
    /// Scans written.
    pub scans: u64,
    /// Packets simulated.
    pub packets: u64,
    /// Firing and return counts.
    pub stats: SimStats,
    /// The check's verdict on the run.
    pub verdict: Option<Verdict>,
}

/// Re-simulates the run at `run_path` into `out` with `rig` (default: the rig file attached to
/// the recording). `progress(done, total)` is called per scan.
#[allow(clippy::too_many_arguments)]
#[allow(
    clippy::too_many_lines,
    reason = "read, check, pose source, parallel casting and writing hand large borrowed state on in order; the casting itself is LidarSim"
)]
pub fn resim(
    run_path: &Path,
    rig: Option<&Rig>,
    scene: &Scene,
    scene_path: &Path,
    model: &ModelFile,
    poses: PoseSource,
    force: bool,
    seed: u64,
    out: &Path,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<ResimSummary, ResimError> {
    let input = |e: String| ResimError::Input(e);
    let (bytes, run, rig) = crate::reference::run::load_with_rig(run_path, rig).map_err(input)?;
    let rig = &rig;
    let (report, smoothed) = check_with_trajectory(&run, rig, Some(scene));
    let mut summary = ResimSummary {
        verdict: Some(report.verdict),
        ..ResimSummary::default()
    };
    if report.verdict != Verdict::Pass && !force {
        return Err(ResimError::Refused(Box::new(report)));
    }
    let (trajectory, source) = match poses {
        PoseSource::File(t, name) => (t, format!("file {name}")),
        PoseSource::Run => {
            let t = smoothed
                .ok_or_else(|| input("the run has no RTK+CAN trajectory".into()))?
                .sampled(10_000_000)
                .ok_or_else(|| input("the run's trajectory is too short".into()))?;
            (
                t,
                "the run's RTK+CAN trajectory (EKF/RTS, 10 ms samples)".into(),
            )
        }
    };
    let (lidar, sensor, calibration) = rig.lidar_sensor().map_err(input)?;
    let sim = LidarSim::new(scene, sensor, calibration.clone(), &lidar.mounting, model)
        .map_err(|e| input(e.to_string()))?;
    let pps_locked = run
        .metadata
        .get("clock_sync/lidar")
        .and_then(|m| m.get("pps"))
        .is_some_and(|p| p == "Locked");

    // The recorded scans.
    let (scans, damage) = crate::bag::scans::read_scans(&bytes);
    if scans.is_empty() {
        return Err(input(format!(
            "{}: no /velodyne_packets to re-simulate{}",
            run_path.display(),
            damage.map_or(String::new(), |d| format!(" ({d})"))
        )));
    }

    let mut bag = BagWriter::create(out, &BagOptions::default())
        .map_err(|e| ResimError::Output(e.to_string()))?;
    let mut meta = BTreeMap::new();
    meta.insert("model".to_owned(), model.name.clone());
    meta.insert("model_toml".to_owned(), model.to_toml());
    meta.insert("scene".to_owned(), scene_path.display().to_string());
    meta.insert("scene_name".to_owned(), scene.file.name.clone());
    meta.insert("run".to_owned(), run_path.display().to_string());
    meta.insert("trajectory".to_owned(), source);
    meta.insert(
        "time_base".to_owned(),
        if pps_locked {
            "lidar stamps (PPS-locked: GNSS time)".to_owned()
        } else {
            "the recorder's clock model (lidar not PPS-locked)".to_owned()
        },
    );
    meta.insert("seed".to_owned(), seed.to_string());
    meta.insert("check_verdict".to_owned(), format!("{:?}", report.verdict));
    bag.metadata("sim", meta)
        .map_err(|e| ResimError::Output(e.to_string()))?;
    let first_log = UtcNanos(scans[0].log_time as i64);
    bag.attach(
        "model.toml",
        "application/toml",
        model.to_toml().as_bytes(),
        first_log,
    )
    .map_err(|e| ResimError::Output(e.to_string()))?;
    let decoder = Decoder::with_calibration(sensor, calibration);
    let total = scans.len() as u64;
    // All packets of all scans at once (both cores busy whatever the scan size), then the scans'
    // messages in parallel, then written in order.
    let mut jobs = Vec::new();
    let mut previous: Option<DataPacket> = None;
    for (k, scan) in scans.iter().enumerate() {
        let mut rates = Vec::with_capacity(scan.packets.len());
        let firsts: Vec<Option<UtcNanos>> = scan
            .packets
            .iter()
            .map(|(t, b)| {
                let p = DataPacket::decode(&b[..]).ok();
                // The rate since the packet before (what a dual-return VLS-128 packet needs).
                rates.push(
                    p.as_ref()
                        .zip(previous.as_ref())
                        .and_then(|(p, q)| hilrig_velodyne::decode::rate_between(q, p)),
                );
                if p.is_some() {
                    previous.clone_from(&p);
                }
                p.map(|p| {
                    if pps_locked {
                        sensor_time(p.timestamp_us, *t)
                    } else {
                        *t
                    }
                })
            })
            .collect();
        let rotation_start = firsts
            .iter()
            .flatten()
            .next()
            .copied()
            .unwrap_or(scan.stamp);
        for (i, (first, rate)) in firsts.into_iter().zip(rates).enumerate() {
            jobs.push((k, i, first, rotation_start, rate));
        }
    }
    let simulated: Vec<([u8; DATA_PACKET_SIZE], SimStats)> = jobs
        .par_iter()
        .enumerate()
        .map(|(n, &(k, i, first, rotation_start, rotation_rate))| {
            let b = &scans[k].packets[i].1;
            let mut st = SimStats::default();
            let out = match (DataPacket::decode(&b[..]), first) {
                (Ok(p), Some(first)) => sim
                    .simulate(
                        &p,
                        PacketTime {
                            first_firing: first,
                            rotation_start,
                            rotation_rate,
                        },
                        &trajectory,
                        seed ^ n as u64,
                        &mut st,
                    )
                    .encode(),
                _ => *b,
            };
            (out, st)
        })
        .collect();
    for (_, st) in &simulated {
        summary.stats.firings += st.firings;
        summary.stats.returns += st.returns;
        summary.stats.outside_trajectory += st.outside_trajectory;
    }
    let mut offsets = Vec::with_capacity(scans.len());
    let mut at = 0;
    for scan in &scans {
        offsets.push(at);
        at += scan.packets.len();
    }
    let messages: Vec<(Vec<u8>, Vec<u8>)> = scans
        .par_iter()
        .zip(offsets.par_iter())
        .map(|(scan, &o)| {
            let list: Vec<(UtcNanos, &[u8; DATA_PACKET_SIZE])> = scan
                .packets
                .iter()
                .zip(&simulated[o..o + scan.packets.len()])
                .map(|((t, _), (b, _))| (*t, b))
                .collect();
            (
                msgs::velodyne_scan(scan.stamp, &lidar.frame_id, &list),
                crate::record::messages::cloud_cdr(&decoder, scan.stamp, &lidar.frame_id, &list),
            )
        })
        .collect();
    for (k, (scan, (packets_cdr, cloud_cdr))) in scans.iter().zip(&messages).enumerate() {
        let (log, publish) = (
            UtcNanos(scan.log_time as i64),
            UtcNanos(scan.publish_time as i64),
        );
        bag.write(
            topics::VELODYNE_PACKETS,
            &msgs::velodyne_scan_type(),
            log,
            publish,
            packets_cdr,
        )
        .map_err(|e| ResimError::Output(e.to_string()))?;
        bag.write(
            SIM_POINTS,
            &msgs::point_cloud2_type(),
            log,
            publish,
            cloud_cdr,
        )
        .map_err(|e| ResimError::Output(e.to_string()))?;
        summary.scans += 1;
        summary.packets += scan.packets.len() as u64;
        progress(k as u64 + 1, total);
    }
    bag.finish()
        .map_err(|e| ResimError::Output(e.to_string()))?;
    Ok(summary)
}

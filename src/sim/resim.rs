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
//!
//! Long file: one caster (packets of a batch cast on every core, their messages made) behind
//! both ways of re-simulating a run, whole to a file (`resim`) and batch by batch for a caller
//! that compares as it goes (`Resimulator`, with a model's deterministic part from the same
//! casts); split, the caster would be shared across files for no reader's gain.

use super::hit_log::{HitLog, HitRun};
use super::lidar::{HitSlot, LidarSim, SimStats};
use super::model::ModelFile;
use super::sim_file::{ScanMessages, Writer};
use crate::bag::msgs;
use crate::bag::packet_times::{PacketTime, PacketTimes, Timed};
use crate::bag::scans::{Scan, ScanStream};
use crate::reference::check::{check_with_trajectory, Report, Verdict};
use crate::rig::Rig;
use crate::scene::pose::Trajectory;
use crate::scene::Scene;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::{DataPacket, Decoder, DATA_PACKET_SIZE};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub use super::sim_file::SIM_POINTS;

/// Why re-simulation did not run.
#[derive(Debug, thiserror::Error)]
pub enum ResimError {
    /// The run failed `check` (and `--force` was not given).
    #[error("the run's reference data fail the check ({}): re-simulating it would measure the reference errors, not the model; see `hilrig check`, or give --force to re-simulate it anyway", .0.faults.iter().map(|f| f.name).collect::<Vec<_>>().join(", "))]
    Refused(Box<Report>),
    /// The run holds no lidar scan to re-simulate.
    #[error("{}: no /velodyne_packets to re-simulate{}", .run.display(), .damage.as_ref().map_or(String::new(), |d| format!(" ({d})")))]
    NoScans {
        /// The run.
        run: PathBuf,
        /// What stopped the reading early, if anything.
        damage: Option<String>,
    },
    /// The run's check gives no trajectory to cast along.
    #[error("{}: {why}", .run.display())]
    NoTrajectory {
        /// The run.
        run: PathBuf,
        /// Why not: no RTK+CAN trajectory, or one too short to sample.
        why: &'static str,
    },
    /// The model cannot simulate the rig's lidar.
    #[error(transparent)]
    Model(#[from] super::model::ModelError),
    /// The run's scans cannot be read.
    #[error(transparent)]
    Scans(#[from] crate::bag::scans::ScanStreamError),
    /// Writing failed.
    #[error("writing the simulation: {0}")]
    Output(#[from] super::sim_file::WriteError),
    /// The run cannot be read, or has no rig.
    #[error(transparent)]
    Run(#[from] crate::reference::run::RunError),
    /// The rig's lidar cannot be simulated.
    #[error(transparent)]
    Lidar(#[from] crate::rig::LidarSensorError),
}

/// Whether a re-simulation writes `/sim/points`, the simulated clouds for viewing. They are
/// most of the file (a minute of a VLS-128: 1.7 of its 1.9 GB) and a sixth of the time; the
/// steps after `resim` (`compare`, `validate`, `replay`) read only the simulated VelodyneScans.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewingClouds {
    /// Write them (what the MCAP contract lists, and the default).
    #[default]
    Write,
    /// Leave them out: the VelodyneScans alone, for a file that is only measured.
    LeaveOut,
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

/// A recording read for re-simulation: the run as `check` needs it (GNSS, CAN, packet timing;
/// its scans are indexed, not kept) and the rig it was recorded with. Reading it is a pass over
/// the whole file, so a caller that also loads a large scene can do both at once (`hilrig resim`
/// does).
pub struct Recording {
    path: std::path::PathBuf,
    run: crate::reference::run::Run,
    rig: Rig,
}

impl Recording {
    /// Reads the recording at `path` with `rig` (default: the rig file attached to it).
    pub fn read(path: &Path, rig: Option<&Rig>) -> Result<Recording, ResimError> {
        let (run, rig) = crate::reference::run::load_with_rig(path, rig)?;
        Ok(Recording {
            path: path.to_owned(),
            run,
            rig,
        })
    }
}

/// Re-simulates the run at `run_path` into `out` with `rig` (default: the rig file attached to
/// the recording). `progress(done, total)` is called per scan.
#[allow(clippy::too_many_arguments)]
pub fn resim(
    run_path: &Path,
    rig: Option<&Rig>,
    scene: &Scene,
    scene_path: &Path,
    model: &ModelFile,
    poses: PoseSource,
    force: bool,
    seed: u64,
    clouds: ViewingClouds,
    out: &Path,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<ResimSummary, ResimError> {
    resim_recording(
        Recording::read(run_path, rig)?,
        scene,
        scene_path,
        model,
        poses,
        force,
        seed,
        clouds,
        out,
        progress,
    )
}

/// [`resim`] of a recording read already.
#[allow(clippy::too_many_arguments)]
#[allow(
    clippy::too_many_lines,
    reason = "check, pose source, parallel casting and writing hand large borrowed state on in order; the casting itself is LidarSim"
)]
pub fn resim_recording(
    recording: Recording,
    scene: &Scene,
    scene_path: &Path,
    model: &ModelFile,
    poses: PoseSource,
    force: bool,
    seed: u64,
    clouds: ViewingClouds,
    out: &Path,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<ResimSummary, ResimError> {
    let Recording { path, run, rig } = recording;
    let run_path = path.as_path();
    let rig = &rig;
    let (report, smoothed) = check_with_trajectory(&run, rig, Some(scene));
    let mut summary = ResimSummary {
        verdict: Some(report.verdict),
        ..ResimSummary::default()
    };
    if report.verdict != Verdict::Pass && !force {
        return Err(ResimError::Refused(Box::new(report)));
    }
    if run.scans.is_empty() {
        return Err(ResimError::NoScans {
            run: run_path.to_owned(),
            damage: run.damage.clone(),
        });
    }
    let (trajectory, source) = match poses {
        PoseSource::File(t, name) => (t, format!("file {name}")),
        PoseSource::Run => {
            let t = smoothed
                .ok_or("no RTK+CAN trajectory")
                .and_then(|t| t.sampled(10_000_000).ok_or("a trajectory too short"))
                .map_err(|why| ResimError::NoTrajectory {
                    run: run_path.to_owned(),
                    why,
                })?;
            (
                t,
                "the run's RTK+CAN trajectory (EKF/RTS, 10 ms samples)".into(),
            )
        }
    };
    let (lidar, sensor, calibration) = rig.lidar_sensor()?;
    let sim = LidarSim::new(scene, sensor, calibration.clone(), &lidar.mounting, model)?;
    let pps_locked = run.lidar_pps_locked();
    let total = run.scans.len() as u64;
    let first_log = run.scans[0].stamp;
    let scans = ScanStream::open(run_path)?;

    let mut meta = sim_metadata(model, scene, scene_path, run_path, source, seed);
    meta.insert(
        "time_base".to_owned(),
        if pps_locked {
            "lidar stamps (PPS-locked: GNSS time)".to_owned()
        } else {
            "the recorder's clock model (lidar not PPS-locked)".to_owned()
        },
    );
    meta.insert("check_verdict".to_owned(), report.verdict.name().to_owned());
    meta.insert(
        "viewing_clouds".to_owned(),
        match clouds {
            ViewingClouds::Write => format!("written ({SIM_POINTS})"),
            ViewingClouds::LeaveOut => format!("left out (no {SIM_POINTS}; --no-clouds)"),
        },
    );
    let writer = Writer::start(out, meta, model.to_toml(), first_log)?;
    let decoder = Decoder::with_calibration(sensor, calibration);
    let cast = Caster {
        clouds: clouds == ViewingClouds::Write,
        sim: &sim,
        trajectory: &trajectory,
        decoder: &decoder,
        frame_id: &lidar.frame_id,
        seed,
    };
    // Scans in batches of about BATCH_PACKETS packets: both cores busy whatever the scan size,
    // while the reader decompresses the next scans and the writer compresses the last ones.
    let mut state = CastState::new(pps_locked);
    let mut batch: Vec<Scan> = Vec::new();
    let mut in_batch = 0usize;
    let mut done = 0u64;
    let mut flush = |batch: &mut Vec<Scan>, summary: &mut ResimSummary| -> Result<(), ResimError> {
        let messages = cast.batch(batch, &mut state, &mut summary.stats);
        for (scan, m) in batch.iter().zip(messages) {
            summary.scans += 1;
            summary.packets += scan.packets.len() as u64;
            writer.send(m)?;
        }
        done += batch.len() as u64;
        progress(done, total);
        batch.clear();
        Ok(())
    };
    for scan in scans {
        in_batch += scan.packets.len();
        batch.push(scan);
        if in_batch >= BATCH_PACKETS {
            flush(&mut batch, &mut summary)?;
            in_batch = 0;
        }
    }
    flush(&mut batch, &mut summary)?;
    writer.finish()?;
    Ok(summary)
}

/// A packet to cast: its scan, its index there, its firings' time (`None`: it does not
/// decode), and its number in the run.
type Job = (usize, usize, Option<PacketTime>, u64);

/// Packets cast per batch: a few VLP-16 rotations, half a VLS-128 rotation; tens of
/// megabytes of scans and messages at most.
const BATCH_PACKETS: usize = 256;

/// What is carried from batch to batch: the packet before (a dual-return VLS-128 packet takes
/// its rotation rate from it) and the packets cast so far (each packet's seed is the run's
/// seed and its index, so the result does not depend on the batching).
struct CastState {
    times: PacketTimes,
    packets: u64,
}

impl CastState {
    fn new(pps_locked: bool) -> CastState {
        CastState {
            times: PacketTimes::new(pps_locked),
            packets: 0,
        }
    }
}

/// Casts batches of recorded scans.
struct Caster<'a> {
    /// Write the viewing clouds.
    clouds: bool,
    sim: &'a LidarSim<'a>,
    trajectory: &'a Trajectory,
    decoder: &'a Decoder,
    frame_id: &'a str,
    seed: u64,
}

impl Caster<'_> {
    /// The simulated messages of `scans`, in order; the firing counts added to `stats`.
    fn batch(
        &self,
        scans: &[Scan],
        state: &mut CastState,
        stats: &mut SimStats,
    ) -> Vec<ScanMessages> {
        let simulated = self.simulate(scans, (state, None), stats);
        self.messages(scans, &simulated)
    }

    /// Every packet of `scans` simulated, in order (a packet that does not decode is kept as
    /// it was); the firing counts added to `stats`.
    fn simulate(
        &self,
        scans: &[Scan],
        (state, hits): (&mut CastState, Option<&mut HitRun<'_>>),
        stats: &mut SimStats,
    ) -> Vec<[u8; DATA_PACKET_SIZE]> {
        self.each_packet(
            scans,
            (state, stats, hits),
            |p, time, seed, st, slot| match slot {
                Some(slot) => self
                    .sim
                    .simulate_reusing(p, time, self.trajectory, seed, st, slot)
                    .encode(),
                None => self
                    .sim
                    .simulate(p, time, self.trajectory, seed, st)
                    .encode(),
            },
            |b| *b,
        )
    }

    /// `cast(packet, time, seed, stats, hits)` of every packet of `scans`, in order, all of
    /// the batch at once (both cores busy whatever the scan size), with each packet's slot of
    /// `hits` when a log is kept; `kept(bytes)` of a packet that does not decode (it is kept
    /// as it was); the firing counts added to `stats`.
    #[allow(
        clippy::type_complexity,
        reason = "the cast's arguments, named at its callers"
    )]
    fn each_packet<T: Send>(
        &self,
        scans: &[Scan],
        (state, stats, hits): (&mut CastState, &mut SimStats, Option<&mut HitRun<'_>>),
        cast: impl Fn(&DataPacket, PacketTime, u64, &mut SimStats, Option<&mut HitSlot>) -> T + Sync,
        kept: impl Fn(&[u8; DATA_PACKET_SIZE]) -> T + Sync,
    ) -> Vec<T> {
        let jobs = Caster::jobs(scans, state);
        let mut hits = hits;
        let mut slots: Option<Vec<HitSlot>> = hits.as_deref_mut().map(|h| h.slots(jobs.len()));
        let mut each: Vec<Option<&mut HitSlot>> = match slots.as_mut() {
            Some(v) => v.iter_mut().map(Some).collect(),
            None => jobs.iter().map(|_| None).collect(),
        };
        let simulated: Vec<(T, SimStats)> = jobs
            .par_iter()
            .zip(each.par_iter_mut())
            .map(|(&(k, i, time, n), slot)| {
                let b = &scans[k].packets[i].1;
                let mut st = SimStats::default();
                let out = match (DataPacket::decode(&b[..]), time) {
                    (Ok(p), Some(time)) => {
                        cast(&p, time, self.seed ^ n, &mut st, slot.as_deref_mut())
                    }
                    _ => kept(b),
                };
                (out, st)
            })
            .collect();
        drop(each);
        if let (Some(h), Some(s)) = (hits, slots) {
            h.done(s);
        }
        let mut out = Vec::with_capacity(simulated.len());
        for (b, st) in simulated {
            *stats += st;
            out.push(b);
        }
        out
    }

    /// Every packet of `scans` (scan, packet, its firings' time, the packet's number in the
    /// run: its seed), in order. A packet that does not decode has no time.
    fn jobs(scans: &[Scan], state: &mut CastState) -> Vec<Job> {
        let mut jobs = Vec::new();
        for (k, scan) in scans.iter().enumerate() {
            for timed in state.times.of(scan) {
                let (i, time) = match timed {
                    Timed::Packet { index, time, .. } => (index, Some(time)),
                    Timed::Undecodable { index } => (index, None),
                };
                jobs.push((k, i, time, state.packets));
                state.packets += 1;
            }
        }
        jobs
    }

    /// [`Caster::simulate`] of this caster's model and of `det`, its deterministic part, from
    /// one cast ([`LidarSim::simulate_pair`]; `det` was checked deterministic when it was set,
    /// [`Resimulator::with_deterministic_part`]).
    fn simulate_pair(
        &self,
        det: &LidarSim<'_>,
        scans: &[Scan],
        (state, hits): (&mut CastState, Option<&mut HitRun<'_>>),
        stats: &mut SimStats,
    ) -> Vec<[[u8; DATA_PACKET_SIZE]; 2]> {
        self.each_packet(
            scans,
            (state, stats, hits),
            |p, time, seed, st, slot| {
                let (a, d) = self
                    .sim
                    .simulate_pair_reusing(det, p, time, self.trajectory, seed, st, slot)
                    .expect("a deterministic part, checked when it was set");
                [a.encode(), d.encode()]
            },
            |b| [*b, *b],
        )
    }

    /// The messages of `scans` with their simulated packets (`simulated`, in order), the
    /// viewing clouds only when the caster writes them.
    fn messages(&self, scans: &[Scan], simulated: &[[u8; DATA_PACKET_SIZE]]) -> Vec<ScanMessages> {
        let mut offsets = Vec::with_capacity(scans.len());
        let mut at = 0;
        for scan in scans {
            offsets.push(at);
            at += scan.packets.len();
        }
        scans
            .par_iter()
            .zip(offsets.par_iter())
            .map(|(scan, &o)| {
                let list: Vec<(UtcNanos, &[u8; DATA_PACKET_SIZE])> = scan
                    .packets
                    .iter()
                    .zip(&simulated[o..o + scan.packets.len()])
                    .map(|((t, _), b)| (*t, b))
                    .collect();
                ScanMessages {
                    log: UtcNanos(scan.log_time as i64),
                    publish: UtcNanos(scan.publish_time as i64),
                    packets_cdr: msgs::velodyne_scan(scan.stamp, self.frame_id, &list),
                    cloud_cdr: self.clouds.then(|| {
                        crate::record::messages::cloud_cdr(
                            self.decoder,
                            scan.stamp,
                            self.frame_id,
                            &list,
                        )
                    }),
                }
            })
            .collect()
    }
}

/// A re-simulation made scan by scan for a caller that reads the run itself and measures the
/// simulated scans as they come ([`crate::metrics::compare::compare_simulated`]: the gap
/// workflow's metrics): each batch of measured scans is cast, handed back, and written to the
/// simulation's file (its VelodyneScans; no viewing clouds).
pub struct Resimulator<'a> {
    sim: LidarSim<'a>,
    /// The model's deterministic part, simulated from the same casts ([`Resimulator::cast_pair`]).
    det: Option<LidarSim<'a>>,
    decoder: Decoder,
    frame_id: String,
    seed: u64,
    /// Made at the first cast, which says whether the lidar is PPS-locked.
    state: Option<CastState>,
    writer: Writer,
    stats: SimStats,
    /// The run's centre hits, reused or kept ([`Resimulator::with_hit_log`]).
    hits: Option<HitRun<'a>>,
}

impl<'a> Resimulator<'a> {
    /// A re-simulation of the run at `run_path` (recorded with `rig`) in `scene` with `model`,
    /// written to `out`; `seed` makes the model's randomness reproducible (as `resim`'s).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        run_path: &Path,
        rig: &Rig,
        scene: &'a Scene,
        scene_path: &Path,
        model: &ModelFile,
        seed: u64,
        out: &Path,
        first_log: UtcNanos,
    ) -> Result<Resimulator<'a>, ResimError> {
        let (lidar, sensor, calibration) = rig.lidar_sensor()?;
        let sim = LidarSim::new(scene, sensor, calibration.clone(), &lidar.mounting, model)?;
        let meta = sim_metadata(
            model,
            scene,
            scene_path,
            run_path,
            "the run's RTK+CAN trajectory (EKF/RTS, 10 ms samples)".to_owned(),
            seed,
        );
        Ok(Resimulator {
            sim,
            det: None,
            decoder: Decoder::with_calibration(sensor, calibration),
            frame_id: lidar.frame_id.clone(),
            seed,
            state: None,
            writer: Writer::start(out, meta, model.to_toml(), first_log)?,
            stats: SimStats::default(),
            hits: None,
        })
    }

    /// The simulated twins of `scans` (the run's next scans, in order), cast along
    /// `trajectory` at the packets' own stamps (GNSS time when `pps_locked`: a property of the
    /// run, so the first call's value holds for the whole re-simulation).
    pub fn cast(
        &mut self,
        trajectory: &Trajectory,
        pps_locked: bool,
        scans: &[Scan],
    ) -> Result<Vec<Scan>, ResimError> {
        Ok(self.cast_with(trajectory, pps_locked, scans, false)?.0)
    }

    /// This re-simulation casting `det` as well, the model's deterministic part (its random
    /// effects left out), for [`Resimulator::cast_pair`]; an error when `det` has a random
    /// effect. (That it is the model's deterministic part is the caller's to know.)
    pub fn with_deterministic_part(
        mut self,
        rig: &Rig,
        scene: &'a Scene,
        det: &ModelFile,
    ) -> Result<Resimulator<'a>, ResimError> {
        let (lidar, sensor, calibration) = rig.lidar_sensor()?;
        let sim = LidarSim::new(scene, sensor, calibration.clone(), &lidar.mounting, det)?;
        if !sim.is_deterministic() {
            return Err(ResimError::Model(crate::sim::model::ModelError::Invalid {
                model: det.name.clone(),
                effect: "(all)".to_owned(),
                what: "a model's deterministic part has no random effect".to_owned(),
            }));
        }
        self.det = Some(sim);
        Ok(self)
    }

    /// [`Resimulator::cast`], and the twins the deterministic part
    /// ([`Resimulator::with_deterministic_part`]) makes from the same casts (not written to
    /// the file): one cast of every beam for both, each bit for bit what it makes alone.
    /// Without a deterministic part, the model's twins twice.
    pub fn cast_pair(
        &mut self,
        trajectory: &Trajectory,
        pps_locked: bool,
        scans: &[Scan],
    ) -> Result<(Vec<Scan>, Vec<Scan>), ResimError> {
        let (full, part) = self.cast_with(trajectory, pps_locked, scans, true)?;
        let part = part.unwrap_or_else(|| full.clone());
        Ok((full, part))
    }

    /// The model's twins of `scans` (written to the file), and with `pair` the deterministic
    /// part's, when there is one.
    fn cast_with(
        &mut self,
        trajectory: &Trajectory,
        pps_locked: bool,
        scans: &[Scan],
        pair: bool,
    ) -> Result<(Vec<Scan>, Option<Vec<Scan>>), ResimError> {
        let caster = Caster {
            clouds: false,
            sim: &self.sim,
            trajectory,
            decoder: &self.decoder,
            frame_id: &self.frame_id,
            seed: self.seed,
        };
        let state = self.state.get_or_insert_with(|| CastState::new(pps_locked));
        let hits = self.hits.as_mut();
        let (full, part) = match self.det.as_ref().filter(|_| pair) {
            Some(det) => {
                let pairs = caster.simulate_pair(det, scans, (state, hits), &mut self.stats);
                let (full, part): (Vec<_>, Vec<_>) = pairs.into_iter().map(|[a, b]| (a, b)).unzip();
                (full, Some(part))
            }
            None => (caster.simulate(scans, (state, hits), &mut self.stats), None),
        };
        for m in caster.messages(scans, &full) {
            self.writer.send(m)?;
        }
        Ok((twins_of(scans, full), part.map(|p| twins_of(scans, p))))
    }

    /// Closes the simulation's file; the firings cast. A log of centre hits this
    /// re-simulation wrote is kept for the next ones.
    pub fn finish(self) -> Result<SimStats, ResimError> {
        self.writer.finish()?;
        if let Some(h) = self.hits {
            h.finish();
        }
        Ok(self.stats)
    }

    /// This re-simulation reusing the centre hits `log` kept from a re-simulation of the
    /// same run before (where the rays are the same), or keeping them there for the next ones
    /// ([`crate::sim::hit_log`]): the same packets, bit for bit.
    pub fn with_hit_log(mut self, log: &'a HitLog) -> Resimulator<'a> {
        self.hits = log.open();
        self
    }
}

/// `scans` with their packets replaced by `simulated` (in order), stamps kept.
fn twins_of(scans: &[Scan], simulated: Vec<[u8; DATA_PACKET_SIZE]>) -> Vec<Scan> {
    let mut packets = simulated.into_iter();
    scans
        .iter()
        .map(|scan| Scan {
            log_time: scan.log_time,
            publish_time: scan.publish_time,
            stamp: scan.stamp,
            packets: scan
                .packets
                .iter()
                .zip(packets.by_ref())
                .map(|((t, _), b)| (*t, b))
                .collect(),
        })
        .collect()
}

/// What a simulation's file says of itself (its `sim` metadata): the model, the scene, the run,
/// the poses and the seed, as `resim` and the gap workflow's re-simulations write them.
fn sim_metadata(
    model: &ModelFile,
    scene: &Scene,
    scene_path: &Path,
    run_path: &Path,
    trajectory: String,
    seed: u64,
) -> BTreeMap<String, String> {
    BTreeMap::from([
        ("model".to_owned(), model.name.clone()),
        ("model_toml".to_owned(), model.to_toml()),
        ("scene".to_owned(), scene_path.display().to_string()),
        ("scene_name".to_owned(), scene.file.name.clone()),
        ("run".to_owned(), run_path.display().to_string()),
        ("trajectory".to_owned(), trajectory),
        ("seed".to_owned(), seed.to_string()),
    ])
}

//! A run as the gap workflow sees it: a sample of its recorded packets, each firing with its
//! measured return, what a model predicts for the same firing (same packet stamp, block and
//! channel: re-simulation keeps the sensor's firing schedule), and the firing's features for
//! the bins.
//!
//! The workflow re-casts only a sample of the packets (every m-th, so that the sample walks
//! through all azimuths and the whole drive): a candidate's parameters are searched with tens
//! of casts, and a few hundred thousand firings per run pin every parameter of the catalogue
//! far below its documented range while one cast stays a fraction of a second.

use super::study::Role;
use super::GapError;
use crate::bag::packet_times::{PacketTimes, Timed};
use crate::bag::scans::ScanStream;
use crate::metrics::compare::Checked;
use crate::reference::check::{check_with_trajectory, Fault, Verdict};
use crate::rig::Rig;
use crate::scene::pose::Trajectory;
use crate::scene::{Scene, SurfaceId};
use crate::sim::lidar::{beam_frame, Firing, LidarSim, PacketTime, SimStats};
use crate::sim::model::{Effect, ModelFile};
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::packet::{BLOCKS, CHANNELS};
use hilrig_velodyne::DataPacket;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Firing slots per packet: blocks × channels.
pub const SLOTS: usize = BLOCKS * CHANNELS;

/// The slot of a firing within its packet's [`SLOTS`]: observations and features are paired
/// by it, so both are written through this one function.
pub(super) fn slot(block: u8, channel: u8) -> usize {
    usize::from(block) * CHANNELS + usize::from(channel)
}

/// The index of a slot of the `sample`-th sampled packet among all the run's slots (a
/// feature's `neighbour`).
fn slot_index(sample: usize, slot: u32) -> u32 {
    (sample * SLOTS) as u32 + slot
}

/// "No return" in the f32 columns.
pub const NONE: f32 = f32::NAN;

/// A recorded packet of the sample, with when its firings happened.
pub struct Sampled {
    /// Index of its scan within the run (the unit of the bootstrap).
    pub scan: u32,
    /// The packet as recorded.
    pub packet: DataPacket,
    /// Its timing.
    pub time: PacketTime,
    /// The sample's packet before it is the run's packet just before it, sampled with it so
    /// that its firings have a neighbour: the same laser one firing sequence earlier (a packet
    /// that holds one firing sequence, a dual-return VLS-128's, has none within itself).
    pub after_previous: bool,
}

/// Whether a packet holds one firing per laser, so that each firing's neighbour (the same
/// laser's firing before it) lies in the packet before: the layout's firing sequences per
/// packet, from the model and the packet's return mode.
fn one_sequence_per_packet(model: hilrig_velodyne::Model, packet: &DataPacket) -> bool {
    let mode = packet
        .return_mode
        .mode()
        .unwrap_or(hilrig_velodyne::ReturnMode::Strongest);
    hilrig_velodyne::PacketEncoder::new(model, mode).sequences_per_packet() < 2
}

/// One run, loaded and sampled.
pub struct RunData {
    /// A short name (the file name, with the part when a run is split).
    pub name: String,
    /// The recording.
    pub path: PathBuf,
    /// Its role.
    pub role: Role,
    /// Its scene.
    pub scene: Scene,
    /// Where the scene came from.
    pub scene_path: PathBuf,
    /// The rig.
    pub rig: Rig,
    /// The ego trajectory `check` smoothed from the run's RTK and CAN data.
    pub trajectory: Trajectory,
    /// The check's verdict.
    pub verdict: Verdict,
    /// The smoothed heading's 1σ error the check found, degrees: a mount yaw below it cannot
    /// be told from the trajectory's heading error.
    pub heading_sigma_deg: f64,
    /// The uncertainty of the GNSS time offset the check estimated, ms: the trajectory's
    /// timing is known to about this, so a lidar time offset below it cannot be told apart.
    pub time_sigma_ms: f64,
    /// The sampled packets.
    pub packets: Vec<Sampled>,
    /// Stretches left out (`check`'s marks within the run or its part): the reference is not
    /// usable there, and its error would pass for a lidar effect.
    pub left_out: Vec<Fault>,
    /// Scans in the run (or its part).
    pub scans: usize,
    /// Those of them with a packet outside the stretches left out: what the workflow can use.
    pub usable_scans: usize,
    /// The range quantum of the sensor, m.
    pub range_quantum_m: f64,
    /// What could not be read: the file's damage (read up to it) and data packets that did not
    /// decode, each said once; the workflow goes on with the rest and reports them.
    pub damage: Vec<String>,
    /// The run as its full comparisons take it, from this one check (or why they cannot take
    /// it): a validation run is compared after every round, and checked only here.
    pub checked: Result<Checked, std::sync::Arc<crate::metrics::compare::CompareError>>,
    /// The sampled packets' centre hits, kept by the first cast of them for the casts of
    /// every model with the same rays ([`super::casts::evaluate`]).
    pub sample_hits: std::sync::OnceLock<Vec<crate::sim::lidar::CentreHits>>,
}

/// What one firing measured and what a model predicts for it (`NONE` where there is no return).
#[derive(Clone, Copy, Debug)]
pub struct Obs {
    /// Measured range, m.
    pub measured: f32,
    /// Measured calibrated reflectivity (intensity byte).
    pub intensity: u8,
    /// Predicted range, m.
    pub predicted: f32,
    /// Predicted received power (ρ cos θ / R², relative).
    pub power: f32,
    /// Predicted reflectivity the intensity byte reports (×100).
    pub reflectivity: f32,
    /// What a Lambertian intensity effect would predict from the same cast
    /// ([`crate::sim::Echo::lambertian`]): the reflectivity of the model with that effect,
    /// read from a cast of the model without it ([`super::casts`]).
    pub lambertian: f32,
    /// The model cast this firing (false: outside the trajectory, or not a firing slot).
    pub cast: bool,
}

impl Default for Obs {
    fn default() -> Obs {
        Obs {
            measured: NONE,
            intensity: 0,
            predicted: NONE,
            power: NONE,
            reflectivity: NONE,
            lambertian: NONE,
            cast: false,
        }
    }
}

/// The features of one firing, for the bins and the likelihood's terms.
#[derive(Clone, Copy, Debug, Default)]
pub struct Feature {
    /// The scan (bootstrap unit).
    pub scan: u32,
    /// Laser.
    pub laser: u16,
    /// Range of the ideal beam's hit, m (0: none).
    pub range: f32,
    /// Reflectivity of the surface hit.
    pub rho: f32,
    /// Cosine of the incidence angle.
    pub cos: f32,
    /// Largest range step to the beam's surroundings (±5 mrad across, ±2.5 mrad along elevation),
    /// m: a depth edge inside the beam's possible footprint. Infinite when one side is sky.
    pub step: f32,
    /// Farthest a probe's hit lies off the plane the ideal beam's hit is on (the plane through
    /// it with its normal), m: a surface of another depth, another orientation or a curve
    /// inside the beam's possible footprint. Infinite when only one of the centre and a probe
    /// hits something; 0 when neither does.
    pub off_plane: f32,
    /// Ego speed, m/s.
    pub speed: f32,
    /// Ego yaw rate, degrees per second.
    pub yaw_rate: f32,
    /// Time since the rotation's first firing, s.
    pub t_rotation: f32,
    /// Azimuth in the sensor frame, degrees [0, 360).
    pub azimuth: f32,
    /// Elevation in the sensor frame, degrees.
    pub elevation: f32,
    /// The slot of the same laser's previous firing in the same packet (its azimuth
    /// neighbour), or `u32::MAX`.
    pub neighbour: u32,
    /// The ideal beam hits the scene's ground plane. A flat ground matches any trajectory
    /// over it, so only the other returns can tell whether a run and a scene belong together.
    pub ground: bool,
    /// The surface the ideal beam hits ([`SurfaceId`]'s number; none: `u32::MAX - 1`).
    pub surface: u32,
    /// How well that surface's place is known, 1 sigma, m ([`crate::scene::Scene::accuracy_of`]):
    /// an error every scan of the run shares.
    pub accuracy: f32,
    /// Which of the firing's echoes its block reports: which of them a droplet's replaces.
    pub reports: crate::sim::lidar::Reported,
}

/// [`Feature::surface`] of a beam that hits nothing.
pub const NO_SURFACE: u32 = u32::MAX - 1;

impl Feature {
    /// A firing whose beam footprint holds a depth edge: geometry errors there move returns
    /// between surfaces, so edge firings get their own, wider terms.
    pub fn is_edge(&self) -> bool {
        self.step > 0.05 * self.range + 0.1
    }

    /// A firing whose footprint may hold surfaces at more than one depth: an edge, or a probe
    /// beside the beam off the plane of its hit by more than [`PLANAR_M`] (a step too small to
    /// be an edge, a corner, a curve, a stripe standing a centimetre proud of a car's side).
    /// Where a footprint mixes depths, its echo's range depends on how the receiver weighs
    /// and groups the parts (merged into one echo, or the nearest part of a sizeable share
    /// alone): two footprint models of the same beam differ there by millimetres to
    /// decimetres, firing by firing, and a beam's width is fitted on these firings with their
    /// range scored within the depth the probes found ([`super::likelihood::Scored::at_edges`]).
    pub fn is_mixed(&self) -> bool {
        self.is_edge() || self.off_plane > PLANAR_M
    }
}

/// How far a probe's hit may lie off the plane of the beam's hit for the footprint to count as
/// one surface, m: a few times the millimetre scale of the neighbour-difference term, so that
/// flat ground and facades (within rounding) and millimetre roughness count as one surface,
/// and a box's step, a corner, a column's curve (5 cm beside the axis at 10 m: 10 mm of
/// sagitta on a 12 cm radius) do not.
pub const PLANAR_M: f32 = 0.005;

/// Angle of the probe rays beside the beam (across), rad: wider than the half-angle of any
/// beam the gap workflow should fit (the catalogue's VLP-16: 3.0 mrad full angle; footprints of
/// up to 10 mrad). A firing whose footprint reaches over an object's side is then an edge and
/// scored as one; at 2.5 mrad, an 8 mrad beam's firings beside an edge counted as plain, and
/// the millimetre scale of the difference term made the fit take the beam for half as wide.
const PROBE_ACROSS_RAD: f64 = 5e-3;

/// Angle of the probe rays above and below the beam, rad: as wide as the catalogue's beams
/// (VLP-16: 1.5 mrad full angle) and no wider, since the range of the road at grazing incidence
/// changes by `R δ tan θ` over an angle δ (1.2 m at 30 m for 2.5 mrad): wider probes would take
/// the road for an edge where the vertical divergence shows most.
const PROBE_ALONG_RAD: f64 = 2.5e-3;

/// Whether a mark's window touches a part of a run (both closed intervals): a mark that
/// begins before the part and reaches into it leaves the part's first scans out.
fn overlaps(window: (UtcNanos, UtcNanos), part: (UtcNanos, UtcNanos)) -> bool {
    window.0 <= part.1 && part.0 <= window.1
}

/// Loads a run: checks its reference data (refusing a run that fails unless `force`), smooths
/// its trajectory and samples about `firings` firings from the scans in `part` (all when
/// `None`).
#[allow(clippy::too_many_arguments)]
pub fn load_run(
    path: &Path,
    scene: Scene,
    scene_path: &Path,
    rig: Option<&Rig>,
    role: Role,
    part: Option<(usize, usize)>,
    firings: usize,
    force: bool,
) -> Result<RunData, GapError> {
    let (run, rig) = crate::reference::run::load_with_rig(path, rig)?;
    let (report, smoothed) = check_with_trajectory(&run, &rig, Some(&scene));
    if report.verdict != Verdict::Pass && !force {
        return Err(GapError::Refused {
            run: path.display().to_string(),
            faults: if report.faults.is_empty() {
                report.unusable.clone().unwrap_or_else(|| "unusable".into())
            } else {
                report
                    .faults
                    .iter()
                    .map(|f| f.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            },
        });
    }
    let smoothed_copy = smoothed.clone();
    let trajectory = smoothed
        .and_then(|t| t.sampled(10_000_000))
        .ok_or_else(|| GapError::NoTrajectory {
            run: path.to_owned(),
        })?;
    let (_, model, _) = rig.lidar_sensor().map_err(|source| GapError::Lidar {
        run: path.display().to_string(),
        source,
    })?;
    let pps_locked = run.lidar_pps_locked();
    let (from, to) = part.unwrap_or((0, run.scans.len()));
    let (from, to) = (from.min(run.scans.len()), to.min(run.scans.len()));
    let index = &run.scans[from..to];
    if index.is_empty() {
        return Err(GapError::NoScans {
            run: path.to_owned(),
        });
    }
    // The marks within this part of the run (on the run's times, as its index: GNSS time where
    // the run put its logger times on it; a mark is at least 100 ms long, and the sensor's
    // clock is within a millisecond of them).
    let (part_from, part_to) = (index[0].span.0, index[index.len() - 1].span.1);
    let marked: Vec<Fault> = report
        .marks
        .iter()
        .filter(|m| overlaps(m.window(), (part_from, part_to)))
        .cloned()
        .collect();
    let total: usize = index.iter().map(|s| s.packets as usize).sum();
    let every = (total * SLOTS).div_ceil(firings.max(SLOTS)).max(1);
    // Whether sampled packets come in pairs (see `Sampled::after_previous`), decided at the
    // first packet; pairs are taken half as often, so that the sample keeps its size.
    let mut paired: Option<bool> = None;
    // The packet just before the next one sampled, when pairs are taken and it is usable.
    let mut previous: Option<Sampled> = None;
    let mut packets = Vec::new();
    let mut times = PacketTimes::new(pps_locked);
    let mut n = 0usize;
    let mut undecodable = 0usize;
    let mut usable_scans = 0usize;
    // The scans are streamed: only the sample is kept.
    let mut stream = ScanStream::open(path)?;
    for (k, scan) in stream.by_ref().skip(from).take(to - from).enumerate() {
        let mut scan_usable = false;
        for timed in times.of(&scan) {
            let Timed::Packet { packet, time, .. } = timed else {
                undecodable += 1;
                previous = None;
                continue;
            };
            let usable = !marked.iter().any(|m| {
                let (a, b) = m.window();
                (a..=b).contains(&time.first_firing)
            });
            scan_usable |= usable;
            let pairs = *paired.get_or_insert_with(|| one_sequence_per_packet(model, &packet));
            let stride = if pairs { 2 * every } else { every };
            let sampled = |after_previous| Sampled {
                scan: k as u32,
                packet: *packet,
                time,
                after_previous,
            };
            if usable && n.is_multiple_of(stride) {
                if let Some(before) = previous.take() {
                    packets.push(before);
                    packets.push(sampled(true));
                } else {
                    packets.push(sampled(false));
                }
            } else {
                previous =
                    (pairs && usable && (n + 1).is_multiple_of(stride)).then(|| sampled(false));
            }
            n += 1;
        }
        usable_scans += usize::from(scan_usable);
    }
    let mut damage: Vec<String> = run
        .damage
        .iter()
        .chain(stream.finish().iter())
        .map(|d| format!("read up to damage ({d}); the workflow uses what could be read"))
        .collect();
    damage.dedup();
    if undecodable > 0 {
        damage.push(format!(
            "{undecodable} data packets did not decode and were left out"
        ));
    }
    for d in &damage {
        tracing::warn!("{}: {d}", path.display());
    }
    let checked = Checked::from_check(path, run, rig.clone(), report.clone(), smoothed_copy, None)
        .map_err(std::sync::Arc::new);
    let file = path.file_name().map_or_else(
        || path.display().to_string(),
        |f| f.to_string_lossy().into(),
    );
    Ok(RunData {
        name: match part {
            Some((a, b)) => format!("{file} [scans {a}..{b}]"),
            None => file,
        },
        path: path.to_owned(),
        role,
        scene,
        scene_path: scene_path.to_owned(),
        rig,
        trajectory,
        verdict: report.verdict,
        heading_sigma_deg: report.accuracy.heading_sigma_deg,
        time_sigma_ms: report.spatial.gnss_time_offset_sigma_ms.unwrap_or(0.0),
        packets,
        left_out: marked,
        scans: to - from,
        usable_scans,
        range_quantum_m: model.distance_resolution_m(),
        damage,
        checked,
        sample_hits: std::sync::OnceLock::new(),
    })
}

/// The scans of a recording (for splitting a single run in time).
pub fn count_scans(path: &Path) -> Result<usize, GapError> {
    let stream = ScanStream::open(path)?;
    Ok(stream.count())
}

/// The model without its random parts (noise, dropout, intensity noise, clutter): what it
/// predicts for each firing. The likelihood adds the random parts analytically.
pub fn deterministic(model: &ModelFile) -> ModelFile {
    let mut m = model.clone();
    m.effects
        .retain(|e| !matches!(e, Effect::RangeNoise { .. } | Effect::RandomDropout { .. }));
    for e in &mut m.effects {
        match e {
            Effect::Intensity { noise_sigma, .. } => *noise_sigma = 0.0,
            Effect::Weather {
                clutter_probability,
                ..
            } => *clutter_probability = 0.0,
            _ => {}
        }
    }
    m
}

pub(super) fn simulator<'a>(run: &'a RunData, model: &ModelFile) -> Result<LidarSim<'a>, GapError> {
    let (lidar, sensor, calibration) =
        run.rig.lidar_sensor().map_err(|source| GapError::Lidar {
            run: run.name.clone(),
            source,
        })?;
    LidarSim::new(&run.scene, sensor, calibration, &lidar.mounting, model).map_err(|source| {
        GapError::Model {
            run: run.name.clone(),
            source,
        }
    })
}

/// The features of every sampled firing, from the ideal beams of `model`'s geometry (its
/// mounting, time base and motion handling) with four probe rays each for depth edges.
pub fn features(run: &RunData, model: &ModelFile) -> Result<Vec<Feature>, GapError> {
    let model = deterministic(model);
    let sim = simulator(run, &model)?;
    let scene = &run.scene;
    let mut out = vec![Feature::default(); run.packets.len() * SLOTS];
    // Per sampled packet, the slot of each laser's last firing in it.
    let last_of_lasers: Vec<std::collections::HashMap<u16, u32>> = out
        .par_chunks_mut(SLOTS)
        .zip(run.packets.par_iter())
        .enumerate()
        .map(|(i, (slots, s))| {
            let mut stats = SimStats::default();
            let mut actors = scene.new_actor_poses();
            scene.actor_poses(s.time.first_firing, &mut actors);
            let mut last_of_laser = std::collections::HashMap::new();
            // What the gap observes of a firing is what the simulator reports for it
            // ([`Firing::reported`]).
            let reports = crate::sim::lidar::Reported::of(s.packet.return_mode.mode());
            let mut hint = 0usize;
            let max = 400.0;
            sim.simulate_observed(
                &s.packet,
                s.time,
                &run.trajectory,
                i as u64,
                &mut stats,
                &mut |f: &Firing| {
                    let slot = slot(f.block, f.channel);
                    let d = f.direction;
                    let centre = scene.cast(&f.origin, &d, 0.0, max, &actors);
                    // Probe rays across (u) and along elevation (w).
                    let (u, w) = beam_frame(&d);
                    let mut step = 0.0f64;
                    let mut off_plane = 0.0f64;
                    for (a, b) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
                        let pd = (d + u * (a * PROBE_ACROSS_RAD) + w * (b * PROBE_ALONG_RAD))
                            .normalize();
                        let probe = scene.cast(&f.origin, &pd, 0.0, max, &actors);
                        let (along, off) = match (&centre, probe) {
                            (Some(c), Some(p)) => (
                                (c.range - p.range).abs(),
                                c.normal.dot(&(pd * p.range - d * c.range)).abs(),
                            ),
                            (None, None) => (0.0, 0.0),
                            _ => (f64::INFINITY, f64::INFINITY),
                        };
                        step = step.max(along);
                        off_plane = off_plane.max(off);
                    }
                    let pose = sim.sensor_pose(&run.trajectory, f.time, &mut hint);
                    let local = pose.map_or(d, |p| p.rotation.inverse() * d);
                    let velocity = run.trajectory.velocity_at(f.time, &mut hint);
                    let mut yaw = |dt: i64| {
                        run.trajectory
                            .sample_at(UtcNanos(f.time.0 + dt), &mut hint)
                            .map(|p| p.yaw)
                    };
                    let yaw_rate = match (yaw(-50_000_000), yaw(50_000_000)) {
                        (Some(a), Some(b)) => {
                            let mut dy = b - a;
                            dy = (dy + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                                - std::f64::consts::PI;
                            (dy / 0.1).to_degrees()
                        }
                        _ => 0.0,
                    };
                    let neighbour = last_of_laser
                        .insert(f.laser, slot as u32)
                        .map_or(u32::MAX, |p| slot_index(i, p));
                    slots[slot] = Feature {
                        scan: s.scan,
                        laser: f.laser,
                        range: centre.as_ref().map_or(0.0, |h| h.range as f32),
                        rho: centre
                            .as_ref()
                            .map_or(0.0, |h| h.material.reflectivity as f32),
                        cos: centre.as_ref().map_or(0.0, |h| (-h.normal.dot(&d)) as f32),
                        step: step as f32,
                        off_plane: off_plane as f32,
                        speed: velocity.map_or(0.0, |v| v.xy().norm() as f32),
                        yaw_rate: yaw_rate as f32,
                        t_rotation: ((f.time.0 - s.time.rotation_start.0) as f64 * 1e-9) as f32,
                        azimuth: (local.y.atan2(local.x).to_degrees().rem_euclid(360.0)) as f32,
                        elevation: local.z.clamp(-1.0, 1.0).asin().to_degrees() as f32,
                        neighbour,
                        ground: centre
                            .as_ref()
                            .is_some_and(|h| h.material.surface == SurfaceId::GROUND),
                        surface: centre.as_ref().map_or(NO_SURFACE, |h| h.material.surface.0),
                        accuracy: centre
                            .as_ref()
                            .map_or(0.0, |h| scene.accuracy_of(h.material.surface) as f32),
                        reports,
                    };
                },
            );
            // Slots never cast keep their scan for the bootstrap.
            for f in slots.iter_mut() {
                f.scan = s.scan;
            }
            last_of_laser
        })
        .collect();
    // A packet sampled with the one before it: each laser's first firing in it (a cast slot
    // still without a neighbour; a slot never cast has the default, 0) takes that packet's
    // last firing of the laser.
    for (i, s) in run.packets.iter().enumerate().skip(1) {
        if !s.after_previous {
            continue;
        }
        for f in &mut out[i * SLOTS..(i + 1) * SLOTS] {
            if f.neighbour == u32::MAX {
                if let Some(&before) = last_of_lasers[i - 1].get(&f.laser) {
                    f.neighbour = slot_index(i - 1, before);
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::{deterministic, overlaps, slot, slot_index, SLOTS};
    use crate::sim::model::{Effect, ModelFile};
    use hilrig_stamp::UtcNanos;
    use hilrig_velodyne::packet::{BLOCKS, CHANNELS};

    #[test]
    fn every_firing_of_a_run_has_a_slot_of_its_own() {
        let mut seen = vec![0u32; 3 * SLOTS];
        for sample in 0..3 {
            for block in 0..BLOCKS as u8 {
                for channel in 0..CHANNELS as u8 {
                    let s = slot(block, channel);
                    assert!(s < SLOTS, "block {block} channel {channel}: slot {s}");
                    seen[slot_index(sample, s as u32) as usize] += 1;
                }
            }
        }
        assert!(seen.iter().all(|&n| n == 1), "{seen:?}");
    }

    #[test]
    fn a_mark_belongs_to_every_part_it_touches() {
        let w = |a: i64, b: i64| (UtcNanos(a), UtcNanos(b));
        let part = w(10, 20);
        // Inside, across either end, around it, and touching an end.
        for m in [
            w(12, 15),
            w(5, 12),
            w(18, 25),
            w(0, 30),
            w(20, 22),
            w(3, 10),
        ] {
            assert!(overlaps(m, part), "{m:?}");
        }
        // Wholly before or after.
        for m in [w(0, 9), w(21, 30)] {
            assert!(!overlaps(m, part), "{m:?}");
        }
    }

    /// What the model predicts for a firing: every effect but its random parts, which the
    /// likelihood adds analytically (noise and dropout gone, intensity noise and clutter 0).
    #[test]
    fn the_deterministic_model_keeps_every_effect_but_the_random_parts() {
        let model: ModelFile = toml::from_str(
            r#"
            name = "all"
            [[effect]]
            name = "range_noise"
            sigma_m = 0.02
            [[effect]]
            name = "range_bias"
            bias_m = 0.03
            [[effect]]
            name = "random_dropout"
            probability = 0.05
            [[effect]]
            name = "detection_threshold"
            reference_range_m = 80.0
            reference_reflectivity = 0.3
            [[effect]]
            name = "intensity"
            incidence_exponent = 1.5
            noise_sigma = 4.0
            [[effect]]
            name = "weather"
            extinction_per_m = 0.004
            clutter_probability = 0.02
            "#,
        )
        .unwrap();
        model.validate().unwrap();
        let d = deterministic(&model);
        let names: Vec<&str> = d.effects.iter().map(Effect::name).collect();
        assert_eq!(
            names,
            ["range_bias", "detection_threshold", "intensity", "weather"]
        );
        for e in &d.effects {
            match e {
                Effect::Intensity {
                    incidence_exponent,
                    noise_sigma,
                } => assert_eq!((*incidence_exponent, *noise_sigma), (1.5, 0.0)),
                Effect::Weather {
                    extinction_per_m,
                    clutter_probability,
                    ..
                } => assert_eq!((*extinction_per_m, *clutter_probability), (0.004, 0.0)),
                _ => {}
            }
        }
        assert_eq!(d.name, model.name);
    }
}

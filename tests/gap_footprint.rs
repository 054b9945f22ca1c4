//! Beam divergence from a footprint model that is not the simulator's (issue 33, must-hold 6):
//! the other hidden-effect tests synthesize with `LidarSim`, whose receiver reports the
//! strongest echo; this one reports the first echo of a sizeable share, and the gap workflow
//! must fit the beam's width through that difference (it fits the echo logic beside it).
//!
//! The model here is written from its physical description alone: a beam whose footprint is a
//! cone of full angle `W` with an even (top-hat) profile; the first echo the receiver detects is
//! the nearest surface that holds a sizeable share of the footprint (a quarter of it); a surface
//! with a smaller share is not seen. An echo carries the energy of its part of the footprint:
//! its range is the energy's centroid (each part weighted by ρ cos θ / R²), its intensity the
//! surface's reflectivity times the part's share.
//! The footprint is sampled by 37 rays spread evenly over the disc: the axis and 18 pairs
//! opposite each other about it (a sunflower pattern), so that the beam is centred on its axis
//! as a real beam's profile is (a plain sunflower of 37 has its centroid 1.3 % of the
//! half-angle off the axis, which on the road at grazing incidence moves the echo by as much
//! as the divergence's own spread does: the vertical divergence was fitted 25-34 % too wide
//! through it). Three
//! drives are synthesized with the idealized model and the drive's reference errors (RTK noise,
//! timing jitter, CAN noise, survey error); each capture's lidar packets are then measured again
//! with this model along the drive's true path, through the true scene, before `record`.

use crate::common;

use common::gap::{drive_at, found, hidden_captured, param, seed_of, IDEALIZED};
use common::{demo_rig, fixture};
use hilrig::bag::scans::sensor_time;
use hilrig::capture::{CaptureReader, PcapngWriter};
use hilrig::rig::Rig;
use hilrig::scene::pose::Trajectory;
use hilrig::scene::Scene;
use hilrig::sim::{LidarSim, ModelFile, PacketTime, SimStats};
use hilrig::velodyne::{Channel, DataPacket, DATA_PACKET_SIZE};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// Sub-rays sampling the footprint.
const SUB_RAYS: usize = 37;
/// The share of the footprint a surface must hold to be seen.
const SIZEABLE: f64 = 0.25;

/// The footprint's sub-ray offsets (across, along elevation), radians, for full angle `w`:
/// evenly spread over the disc, each standing for an equal part of its area (the axis a
/// disc of 1/37 of it, each pair the middle of a ring of 2/37), point-symmetric.
fn sunflower(w_rad: f64) -> Vec<(f64, f64)> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let n = SUB_RAYS as f64;
    let mut v = vec![(0.0, 0.0)];
    for k in 0..(SUB_RAYS - 1) / 2 {
        let r = 0.5 * w_rad * ((2.0 * k as f64 + 2.0) / n).sqrt();
        let t = k as f64 * golden;
        v.push((r * t.cos(), r * t.sin()));
        v.push((-r * t.cos(), -r * t.sin()));
    }
    v
}

/// One sub-ray's hit: the surface, its range, the power it returns (ρ cos θ / R²) and the
/// surface's reflectivity.
#[derive(Clone, Copy)]
struct SubHit {
    surface: u32,
    range: f64,
    power: f64,
    reflectivity: f64,
}

/// What the beam measures: the echo of the nearest surface that holds a sizeable share of the
/// footprint. An echo carries the energy of its part of the footprint: its range is the
/// energy's centroid, its intensity the reflectivity times the part's share. A surface with a
/// smaller share is not seen. `None` when no surface holds that much.
fn nearest_sizeable(hits: &[SubHit], share: f64) -> Option<(f64, f64)> {
    // (surface, nearest range, Σ power × range, Σ power, count, Σ reflectivity)
    let mut surfaces: Vec<(u32, f64, f64, f64, usize, f64)> = Vec::new();
    for h in hits {
        match surfaces.iter_mut().find(|x| x.0 == h.surface) {
            Some(x) => {
                x.1 = x.1.min(h.range);
                x.2 += h.power * h.range;
                x.3 += h.power;
                x.4 += 1;
                x.5 += h.reflectivity;
            }
            None => surfaces.push((
                h.surface,
                h.range,
                h.power * h.range,
                h.power,
                1,
                h.reflectivity,
            )),
        }
    }
    surfaces.sort_by(|a, b| a.1.total_cmp(&b.1));
    surfaces
        .iter()
        .find(|x| x.4 as f64 >= share * SUB_RAYS as f64 && x.3 > 0.0)
        .map(|x| (x.2 / x.3, x.5 / SUB_RAYS as f64))
}

/// `src` with every lidar data packet measured again by the footprint model of full angle
/// `w_mrad`, through `scene` along the true path `truth`, written to `dst`. The packets are
/// measured on every core (37 rays a firing: one core took half a minute a run).
fn remeasure(src: &Path, dst: &Path, w_mrad: f64, scene: &Scene, truth: &Trajectory) {
    use rayon::prelude::*;
    let rig = Rig::load(&demo_rig()).unwrap();
    let (lidar, model, calibration) = rig.lidar_sensor().unwrap();
    let ideal = ModelFile::idealized();
    let sim = LidarSim::new(scene, model, calibration.clone(), &lidar.mounting, &ideal).unwrap();
    let offsets = sunflower(w_mrad * 1e-3);
    let mut reader =
        CaptureReader::new(std::io::BufReader::new(std::fs::File::open(src).unwrap())).unwrap();
    let mut records = Vec::new();
    while let Some(rec) = reader.next_record() {
        let rec = rec.unwrap();
        records.push((rec.interface, rec.time, rec.data.to_vec()));
    }
    // Each record as it goes out, and whether it was a data packet with how many returns.
    let measured: Vec<(Vec<u8>, Option<usize>)> = records
        .par_iter()
        .map_init(
            || scene.new_actor_poses(),
            |actors, (_, time, data)| {
                let mut data = data.clone();
                let at = data.len().saturating_sub(DATA_PACKET_SIZE);
                let Ok(mut packet) = DataPacket::decode(&data[at..]) else {
                    return (data, None);
                };
                let first = sensor_time(packet.timestamp_us, *time);
                let t = PacketTime {
                    first_firing: first,
                    rotation_start: first,
                    rotation_rate: None,
                };
                let mut channels: Vec<(u8, u8, Channel)> = Vec::new();
                let mut stats = SimStats::default();
                sim.simulate_observed(&packet, t, truth, 0, &mut stats, &mut |f| {
                    scene.actor_poses(f.time, actors);
                    let d = f.direction;
                    let u = d.cross(&Vector3::z()).normalize();
                    let v = u.cross(&d);
                    let dirs: Vec<Vector3<f64>> = offsets
                        .iter()
                        .map(|&(a, b)| (d + u * a + v * b).normalize())
                        .collect();
                    // The sub-rays in one traversal: bit for bit what `Scene::cast` finds for
                    // each (its doc), in a third less time.
                    let mut cast = vec![None; dirs.len()];
                    scene.cast_bundle(&f.origin, &dirs, 0.0, 200.0, actors, &mut cast);
                    let hits: Vec<SubHit> = dirs
                        .iter()
                        .zip(cast)
                        .filter_map(|(sd, h)| {
                            h.map(|h| SubHit {
                                surface: h.material.surface.0,
                                range: h.range,
                                power: h.material.reflectivity * (-h.normal.dot(sd)).max(0.0)
                                    / (h.range * h.range),
                                reflectivity: h.material.reflectivity,
                            })
                        })
                        .collect();
                    let channel = nearest_sizeable(&hits, SIZEABLE)
                        .filter(|(r, _)| (0.5..=100.0).contains(r))
                        .and_then(|(r, refl)| {
                            Some(Channel {
                                distance: calibration.raw_distance(usize::from(f.laser), r)?,
                                reflectivity: (refl * 100.0).round().clamp(0.0, 100.0) as u8,
                            })
                        })
                        .unwrap_or_default();
                    channels.push((f.block, f.channel, channel));
                });
                let mut returns = 0;
                for (b, c, ch) in channels {
                    returns += usize::from(ch.distance > 0);
                    packet.blocks[usize::from(b)].channels[usize::from(c)] = ch;
                }
                data[at..].copy_from_slice(&packet.encode());
                (data, Some(returns))
            },
        )
        .collect();
    let mut w = PcapngWriter::new(Vec::new(), "tests/gap_footprint.rs").unwrap();
    for i in reader.interfaces() {
        w.add_interface(i.link, i.name.as_deref().unwrap_or(""))
            .unwrap();
    }
    let (mut packets, mut returns) = (0usize, 0usize);
    for ((interface, time, _), (data, r)) in records.iter().zip(&measured) {
        if let Some(r) = r {
            packets += 1;
            returns += r;
        }
        w.write_packet(*interface, *time, data).unwrap();
    }
    assert!(
        packets > 500 && returns > 100 * packets,
        "{packets} packets, {returns} returns"
    );
    std::fs::write(dst, w.finish().unwrap()).unwrap();
}

/// Synthesizes the study with divergence `w_mrad` of this footprint model, runs `hilrig gap`
/// from the idealized model and returns the fitted divergence (horizontal, vertical) of the
/// first round, which must have added beam divergence.
fn fitted(w_mrad: f64, speed: f64, survey: bool, case: &str) -> (f64, f64) {
    let dir = tempfile::tempdir().unwrap();
    let scene = Scene::load(&fixture("parking/scene.toml")).unwrap();
    let capture = |rep: &Path| -> PathBuf {
        let truth =
            Trajectory::from_csv(&std::fs::read_to_string(rep.join("truth.csv")).unwrap()).unwrap();
        let dst = rep.join("footprint.pcapng");
        remeasure(&rep.join("drive.pcapng"), &dst, w_mrad, &scene, &truth);
        dst
    };
    let study = hidden_captured(
        dir.path(),
        IDEALIZED,
        IDEALIZED,
        seed_of(case),
        &|t| {
            let t = drive_at(speed, false)(t);
            if survey {
                t
            } else {
                assert!(t.contains("[survey]\nsigma_m = 0.03 "), "{t}");
                t.replace("[survey]\nsigma_m = 0.03 ", "[survey]\nsigma_m = 0.0 #")
            }
        },
        &capture,
    );
    let out = common::gap::gap(
        &[
            study.as_os_str(),
            "--max-rounds".as_ref(),
            "1".as_ref(),
            "--no-full-metrics".as_ref(),
        ],
        &dir.path().join("out"),
    );
    eprintln!("{}", out.stdout);
    assert_eq!(out.code, Some(0), "{}\n{}", out.stdout, out.stderr);
    let f = found(out.report.as_ref().unwrap());
    assert_eq!(
        f.first().map(|x| x.0.as_str()),
        Some("beam_divergence"),
        "{}",
        out.stdout
    );
    (
        param(&f[0].1, "horizontal_mrad"),
        param(&f[0].1, "vertical_mrad"),
    )
}

/// Asserts both fitted axes lie within 30 % of the footprint's full angle `w`.
fn within_30_percent((h, v): (f64, f64), w: f64) {
    assert!((h - w).abs() <= 0.3 * w, "horizontal {h} mrad for {w}");
    assert!((v - w).abs() <= 0.3 * w, "vertical {v} mrad for {w}");
}

/// The vertical divergence shows on the road at grazing incidence, one surface under the whole
/// footprint, where every model that reports the echo energy's centroid agrees; the
/// horizontal one at the sides of objects, where the echo logic decides how far beyond the
/// silhouette a return stands out. The fit tries a first-echo receiver's shares beside the
/// strongest echo, and finds this model's quarter. The objects carry the drive's 3 cm survey
/// error, which moves a side by 3 mrad at 10 m: an 8 mrad beam still stands out of it.
#[test]
fn an_8_mrad_footprint_of_another_model_is_found_and_fitted_within_30_percent() {
    within_30_percent(fitted(8.0, 5.0, true, "footprint 8 mrad"), 8.0);
}

/// The narrow end of the range the issue asks for: a 3 mrad beam at 5 m/s, with the objects
/// where the scene says.
#[test]
fn a_3_mrad_footprint_of_another_model_is_fitted_within_30_percent_where_the_scene_is_exact() {
    within_30_percent(fitted(3.0, 5.0, false, "footprint 3 mrad"), 3.0);
}

//! The lidar model's speed on the parking scene (issue 5, must-hold 6):
//! - rays per second of the idealized model (per-firing pose, decoder beams, instanced
//!   pedestrian, quantisation into packets) against bare obvhs traversal of the very same rays
//!   in the same run (ratio, should be at least 0.8);
//! - simulation of a VLP-32C along the recorded drive on both cores, as a multiple of real time
//!   (re-simulation's core; should be at least 5x);
//! - BVH build time of the scene;
//! - the truth model (fixtures/parking/truth-model.toml: noise, threshold, a 3 × 1.5 mrad beam
//!   with 3 sub-rays per axis, dropout, intensity) against the idealized model on VLS-128 and
//!   VLP-16 packets, with the beam's footprint cast adaptively (the default) and in full:
//!   firings and rays per second on one thread, and the ratios (full / adaptive, truth /
//!   idealized) from interleaved rounds; on the parking scene (mostly sky for a VLS-128) and
//!   on a generated street (a meshed road with a crown and a gentle grade, kerbs, building
//!   fronts with balconies, parked cars, trees and lamp posts: surfaces in every direction).
//! - at real size (a street of 800 000 triangles 500 m from the origin, a VLS-128's rotation
//!   of 230 400 rays): single casts, a diverging beam's five sub-rays cast one by one
//!   against `Geometry::cast_bundle` (same hits bit for bit; the ratio is printed), and
//!   neighbouring firings cast together with `Geometry::cast_rays` in bundles of a few
//!   adjacent sequences and lasers (the ratio to single casts is printed).
//!
//! `cargo bench --bench raycast` runs criterion on each and then prints the ratios from
//! interleaved rounds, so that both sides of a ratio see the same machine load.

use criterion::{criterion_group, Criterion, Throughput};
use hilrig::rig::Mounting;
use hilrig::scene::file::{Ground, ObjectFile, Placement, SceneFile, Wgs84};
use hilrig::scene::pose::{PoseSample, Trajectory};
use hilrig::scene::{Geometry, Material, Primitive, Scene, Shape, SurfaceId};
use hilrig::sim::lidar::FootprintCast;
use hilrig::sim::spin::{Skeleton, Spin};
use hilrig::sim::{LidarSim, ModelFile, SimStats};
use hilrig::stamp::UtcNanos;
use hilrig::velodyne::packet::ReturnMode;
use hilrig::velodyne::{Calibration, Model};
use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

fn fixture(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(p)
}

struct Setup {
    scene: Scene,
    ego: Trajectory,
    mounting: Mounting,
}

fn setup() -> Setup {
    let scene = Scene::load(&fixture("parking/rep-01/scene.toml")).unwrap();
    let ego = Trajectory::from_csv(
        &std::fs::read_to_string(fixture("parking/rep-01/truth.csv")).unwrap(),
    )
    .unwrap();
    let rig = hilrig::rig::Rig::load(&PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/rigs/demo.toml"
    )))
    .unwrap();
    Setup {
        scene,
        ego,
        mounting: rig.lidar.unwrap().mounting,
    }
}

impl Setup {
    /// The lidar model for `model` with the demo rig's mounting in the parking scene.
    fn sim(&self, model: Model, file: &ModelFile) -> LidarSim<'_> {
        LidarSim::new(
            &self.scene,
            model,
            Calibration::builtin(model),
            &self.mounting,
            file,
        )
        .unwrap()
    }
}

fn skeletons(model: Model, mode: ReturnMode, ego: &Trajectory, seconds: f64) -> Vec<Skeleton> {
    let start = ego.span().0;
    spin_from(model, mode, UtcNanos(start.0 + 4_000_000_000), seconds)
}

/// The packets of `seconds` of spinning from `t0` at 600 rpm.
fn spin_from(model: Model, mode: ReturnMode, t0: UtcNanos, seconds: f64) -> Vec<Skeleton> {
    let spin = Spin {
        model,
        mode,
        rpm: 600.0,
        phase_deg: 0.0,
        t0,
    };
    (0..spin.packets_in(seconds))
        .map(|k| spin.packet(k, |t| t))
        .collect()
}

/// The rays the model casts for these packets (same arithmetic as `LidarSim::simulate`): in the
/// local frame for the static BVH, and in each actor's frame (at that firing's time) for the
/// actors' BVHs.
type Ray = (Point3<f64>, Vector3<f64>);

fn rays(sim: &LidarSim, scene: &Scene, ego: &Trajectory, sk: &[Skeleton]) -> Vec<(Ray, Vec<Ray>)> {
    let dec = sim.decoder();
    let n = dec.model().lasers();
    let mut out = Vec::new();
    let mut hint = 0;
    let mut actor_hints = vec![0; scene.actors.len()];
    for s in sk {
        let rate = dec.rotation_rate(&s.packet, 12);
        for col in 0..12 {
            for ch in 0..32 {
                let (az, t_us) = dec.firing(&s.packet, col, col, ch, rate);
                let t = UtcNanos(s.time.first_firing.0 + (t_us * 1000.0).round() as i64);
                let pose = sim.sensor_pose(ego, t, &mut hint).unwrap();
                let beam = dec.calibration().beam(ch % n, az);
                let o = pose.transform_point(&Point3::from(beam.origin));
                let d = pose.transform_vector(&Vector3::from(beam.direction));
                let local = scene
                    .actors
                    .iter()
                    .zip(actor_hints.iter_mut())
                    .filter_map(|(a, h)| a.trajectory.pose_at(t, h))
                    .map(|p| {
                        (
                            p.inverse_transform_point(&o),
                            p.inverse_transform_vector(&d),
                        )
                    })
                    .collect();
                out.push(((o, d), local));
            }
        }
    }
    out
}

/// Every BVH traversal the model does for these rays, and nothing else.
fn bare(scene: &Scene, rays: &[(Ray, Vec<Ray>)]) -> usize {
    let mut hits = 0;
    for ((o, d), local) in rays {
        let mut limit = 150.0;
        if let Some(h) = scene.statics.cast(o, d, 0.0, limit) {
            limit = h.range;
            hits += 1;
        }
        for (a, (lo, ld)) in scene.actors.iter().zip(local) {
            if let Some(h) = a.geometry.cast(lo, ld, 0.0, limit) {
                limit = h.range;
                hits += 1;
            }
        }
        black_box(limit);
    }
    hits
}

fn model_run(sim: &LidarSim, ego: &Trajectory, sk: &[Skeleton]) -> u64 {
    simulated(sim, ego, sk).returns
}

/// Simulates the packets on this thread; the counters.
fn simulated(sim: &LidarSim, ego: &Trajectory, sk: &[Skeleton]) -> SimStats {
    let mut stats = SimStats::default();
    for (k, s) in sk.iter().enumerate() {
        black_box(sim.simulate(&s.packet, s.time, ego, k as u64, &mut stats));
    }
    stats
}

fn truth_model() -> ModelFile {
    ModelFile::load(&fixture("parking/truth-model.toml")).unwrap()
}

/// The three models the truth-model comparison runs: idealized, truth with the footprint cast
/// in full, truth cast adaptively.
fn three_models(s: &Setup, model: Model) -> [(&'static str, LidarSim<'_>); 3] {
    let truth = truth_model();
    [
        ("idealized", s.sim(model, &ModelFile::idealized())),
        (
            "truth, full footprint",
            s.sim(model, &truth)
                .with_footprint_cast(FootprintCast::Full),
        ),
        (
            "truth, adaptive footprint",
            s.sim(model, &truth)
                .with_footprint_cast(FootprintCast::Adaptive),
        ),
    ]
}

/// A street 200 m long (x) and 34 m between the building fronts, written into `dir`: a road
/// mesh 14 m wide in 0.5 m cells with a 2 % crown and a 30 cm grade wave over 80 m, kerbs and
/// pavements, building fronts (set back differently, with balconies), cars parked on both
/// sides, trees and lamp posts; and the ego driving along it at 8 m/s for 6 s. Seen from the
/// road, nearly every beam meets something.
fn street(dir: &std::path::Path) -> (Scene, Trajectory) {
    use std::fmt::Write;
    let height =
        |x: f64, y: f64| 0.02 * (7.0 - y.abs()) + 0.3 * (x * std::f64::consts::TAU / 80.0).sin();
    let mut obj = String::new();
    let (nx, ny) = (400, 28);
    for i in 0..=nx {
        for j in 0..=ny {
            let (x, y) = (-100.0 + 0.5 * f64::from(i), -7.0 + 0.5 * f64::from(j));
            let _ = writeln!(obj, "v {x} {y} {}", height(x, y));
        }
    }
    let v = |i: u32, j: u32| i * (ny + 1) + j + 1;
    for i in 0..nx {
        for j in 0..ny {
            let _ = writeln!(
                obj,
                "f {} {} {} {}",
                v(i, j),
                v(i + 1, j),
                v(i + 1, j + 1),
                v(i, j + 1)
            );
        }
    }
    std::fs::write(dir.join("road.obj"), obj).unwrap();
    let boxed = |size: [f64; 3], x: f64, y: f64, z: f64| Shape::Box {
        size,
        at: Placement {
            x,
            y,
            z,
            ..Placement::default()
        },
        reflectivity: None,
    };
    let object =
        |name: String, x: f64, y: f64, z: f64, reflectivity: f64, parts: Vec<Shape>| ObjectFile {
            name,
            pose: Placement {
                x,
                y,
                z,
                ..Placement::default()
            },
            reflectivity,
            accuracy_m: 0.05,
            parts,
        };
    let mut objects = vec![object(
        "road".into(),
        0.0,
        0.0,
        0.0,
        0.1,
        vec![Shape::Mesh {
            file: "road.obj".into(),
            scale: 1.0,
            at: Placement::default(),
            reflectivity: None,
        }],
    )];
    for side in [-1.0f64, 1.0] {
        // Pavement with its kerb, 15 cm up (the wave lifts the road by up to 30 cm; the
        // pavement follows it in 10 m slabs).
        for k in 0..20 {
            let x = -95.0 + 10.0 * f64::from(k);
            objects.push(object(
                format!("pavement {side} {k}"),
                x,
                side * 12.0,
                height(x, 7.0) - 0.05,
                0.2,
                vec![boxed([10.0, 10.0, 0.2], 0.0, 0.0, 0.0)],
            ));
        }
        // Building fronts 12 to 20 m wide, set back 0 to 1.5 m, with a balcony per floor.
        let mut x = -100.0;
        let mut k = 0;
        while x < 100.0 {
            let w = 12.0 + f64::from(k % 5) * 2.0;
            let back = f64::from(k % 4) * 0.5;
            let y = side * (17.0 + back + 5.0);
            let mut parts = vec![boxed(
                [w, 10.0, 15.0 + f64::from(k % 3) * 3.0],
                0.0,
                0.0,
                0.0,
            )];
            for floor in 1..5 {
                parts.push(boxed(
                    [w * 0.4, 1.2, 0.15],
                    0.0,
                    -side * 5.6,
                    3.0 * f64::from(floor),
                ));
            }
            objects.push(object(
                format!("building {side} {k}"),
                x + w / 2.0,
                y,
                0.0,
                0.3,
                parts,
            ));
            x += w;
            k += 1;
        }
        // Cars parked along the kerb, trees and lamp posts on the pavement.
        for k in 0..28 {
            let x = -95.0 + 7.0 * f64::from(k);
            if k % 5 != 2 {
                objects.push(object(
                    format!("car {side} {k}"),
                    x,
                    side * 6.0,
                    height(x, 6.0),
                    [0.7, 0.06, 0.35, 0.5][k as usize % 4],
                    vec![
                        boxed([4.4, 1.8, 0.8], 0.0, 0.0, 0.3),
                        boxed([2.4, 1.6, 0.6], -0.2, 0.0, 1.1),
                    ],
                ));
            }
            let z = height(x, 7.0) + 0.15;
            let tree = k % 2 == 0;
            objects.push(object(
                format!("{} {side} {k}", if tree { "tree" } else { "lamp" }),
                x + 3.5,
                side * 8.0,
                z,
                0.4,
                vec![Shape::Cylinder {
                    radius: if tree { 0.18 } else { 0.07 },
                    height: if tree { 3.0 } else { 6.0 },
                    at: Placement::default(),
                    reflectivity: None,
                }],
            ));
            if tree {
                objects.push(object(
                    format!("crown {side} {k}"),
                    x + 3.5,
                    side * 8.0,
                    z + 3.0,
                    0.25,
                    vec![Shape::Cylinder {
                        radius: 1.8,
                        height: 3.0,
                        at: Placement::default(),
                        reflectivity: None,
                    }],
                ));
            }
        }
    }
    let file = SceneFile {
        name: "street".into(),
        origin: Wgs84 {
            latitude_deg: 48.78,
            longitude_deg: 11.47,
            height_m: 400.0,
        },
        ground: Some(Ground {
            z: -0.5,
            half_size_m: 300.0,
            reflectivity: 0.1,
            accuracy_m: 0.05,
        }),
        objects,
        actors: vec![],
    };
    let scene = Scene::from_file(file, dir, &dir.join("street.toml")).unwrap();
    let t0 = 1_763_700_000_000_000_000i64;
    let ego = Trajectory::new(
        (0..=600)
            .map(|i| {
                let t = f64::from(i) * 0.01;
                let x = -40.0 + 8.0 * t;
                PoseSample {
                    t: UtcNanos(t0 + i64::from(i) * 10_000_000),
                    position: nalgebra::Vector3::new(x, -3.5, height(x, -3.5)),
                    yaw: 0.0,
                    pitch: 0.0,
                    roll: 0.0,
                }
            })
            .collect(),
    )
    .unwrap();
    (scene, ego)
}

/// Truth model against idealized, full footprint against adaptive, on one thread: the median of
/// interleaved rounds, so that every ratio compares the same machine load.
fn truth_report(s: &Setup) {
    let dir = std::env::temp_dir().join(format!("hilrig-bench-street-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (street_scene, street_ego) = street(&dir);
    let street = Setup {
        scene: street_scene,
        ego: street_ego,
        mounting: s.mounting,
    };
    println!(
        "street scene: {} static primitives",
        street.scene.statics.len()
    );
    for (place, setup) in [("parking scene", s), ("street", &street)] {
        for (model, mode) in [
            (Model::Vls128, ReturnMode::Strongest),
            (Model::Vls128, ReturnMode::Dual),
            (Model::Vlp16, ReturnMode::Strongest),
        ] {
            truth_rounds(setup, place, model, mode);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn truth_rounds(s: &Setup, place: &str, model: Model, mode: ReturnMode) {
    let sims = three_models(s, model);
    let sk = spin_from(
        model,
        mode,
        UtcNanos(s.ego.span().0 .0 + 2_000_000_000),
        0.1,
    );
    let rounds = 9;
    let mut times = vec![Vec::new(); sims.len()];
    let mut stats = vec![SimStats::default(); sims.len()];
    for _ in 0..rounds {
        for (i, (_, sim)) in sims.iter().enumerate() {
            let t = Instant::now();
            stats[i] = simulated(sim, &s.ego, &sk);
            times[i].push(t.elapsed().as_secs_f64());
        }
    }
    for t in &mut times {
        t.sort_by(f64::total_cmp);
    }
    let median: Vec<f64> = times.iter().map(|t| t[rounds / 2]).collect();
    println!(
        "{model} {mode:?}, {place}, 0.1 s of packets ({} packets, {} firings, {} returns), 1 thread, median of {rounds} interleaved rounds:",
        sk.len(),
        stats[0].firings,
        stats[0].returns
    );
    for (i, (name, _)) in sims.iter().enumerate() {
        let st = &stats[i];
        println!(
            "  {name:<26} {:7.3} s  {:5.2} M firings/s  {:5.2} M rays/s  {:.2} rays/firing  footprints cast in full {:5.1} %",
            median[i],
            st.firings as f64 / median[i] / 1e6,
            st.rays as f64 / median[i] / 1e6,
            st.rays as f64 / st.firings as f64,
            100.0 * st.footprints_cast as f64 / st.firings as f64
        );
    }
    println!(
        "  time ratios: full / adaptive {:.2}; truth / idealized {:.2} (adaptive), {:.2} (full)",
        median[1] / median[2],
        median[2] / median[0],
        median[1] / median[0]
    );
}

/// A street at real size, 500 m from the frame origin: a ground of two triangles and facades
/// either side (y = ±9 m, 480 m long, 12 m high) tessellated into 17 cm squares, every third
/// one a window recessed 10 cm: 800 000 triangles, as benches/real_size.py's site.
fn street_800k() -> Geometry {
    let (x0, y0) = (500.0, -300.0);
    let p = |x: f64, y: f64, z: f64| Point3::new(x0 + x, y0 + y, z);
    let mut prims = Vec::new();
    let ground = Material {
        reflectivity: 0.12,
        surface: SurfaceId::GROUND,
    };
    let h = 400.0;
    prims.extend(Primitive::triangle(
        p(-h, -h, 0.0),
        p(h, -h, 0.0),
        p(h, h, 0.0),
        ground,
    ));
    prims.extend(Primitive::triangle(
        p(-h, -h, 0.0),
        p(h, h, 0.0),
        p(-h, h, 0.0),
        ground,
    ));
    let cell = 0.17;
    let (columns, rows) = ((480.0 / cell) as u32, (12.0 / cell) as u32);
    for (k, side) in [(0u32, 9.0f64), (1, -9.0)] {
        let m = Material {
            reflectivity: 0.4,
            surface: SurfaceId(k),
        };
        for i in 0..columns {
            for j in 0..rows {
                let (x, z) = (-240.0 + f64::from(i) * cell, f64::from(j) * cell);
                let y = if (i / 3 + j / 3) % 3 == 0 {
                    side + side.signum() * 0.1
                } else {
                    side
                };
                let (a, b) = (p(x, y, z), p(x + cell, y, z));
                let (c, d) = (p(x + cell, y, z + cell), p(x, y, z + cell));
                prims.extend(Primitive::triangle(a, b, c, m));
                prims.extend(Primitive::triangle(a, c, d, m));
            }
        }
    }
    Geometry::build(prims)
}

/// One rotation of a 128-beam sensor 2 m up driving along the street at 8 m/s: 1800 columns
/// (0.2° apart, 10 Hz), 128 beams from -25° to +15° each, in firing order.
fn street_rays() -> Vec<Ray> {
    let mut rays = Vec::with_capacity(1800 * 128);
    for col in 0..1800 {
        let az = f64::from(col) * 0.2f64.to_radians();
        let o = Point3::new(500.0 - 20.0 + 0.8 * f64::from(col) / 1800.0, -302.0, 2.0);
        for laser in 0..128 {
            let el = (-25.0 + 40.0 * f64::from(laser) / 127.0f64).to_radians();
            rays.push((
                o,
                Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin()),
            ));
        }
    }
    rays
}

/// The truth model's diverging beam (3 x 1.5 mrad, 3 sub-rays per axis inside the ellipse):
/// five sub-ray directions around `d`.
fn sub_rays(d: &Vector3<f64>) -> [Vector3<f64>; 5] {
    let u = d.cross(&Vector3::z()).normalize();
    let w = u.cross(d);
    [
        (0.0, -0.75e-3),
        (-1.5e-3, 0.0),
        (0.0, 0.0),
        (1.5e-3, 0.0),
        (0.0, 0.75e-3),
    ]
    .map(|(a, b)| (d + u * a + w * b).normalize())
}

fn street_single(g: &Geometry, rays: &[Ray]) -> usize {
    rays.iter()
        .filter(|(o, d)| g.cast(o, d, 0.0, 367.5).is_some())
        .count()
}

fn street_divergence(g: &Geometry, rays: &[Ray], bundled: bool) -> usize {
    let mut out = [None; 5];
    let mut hits = 0;
    for (o, d) in rays {
        let dirs = sub_rays(d);
        if bundled {
            g.cast_bundle(o, &dirs, 0.0, 367.5, &mut out);
        } else {
            for (h, d) in out.iter_mut().zip(&dirs) {
                *h = g.cast(o, d, 0.0, 367.5);
            }
        }
        hits += out.iter().filter(|h| h.is_some()).count();
    }
    hits
}

/// The rotation's rays cast in bundles of `sequences` adjacent columns times `lasers` adjacent
/// beams (`Geometry::cast_rays`), as the lidar model casts a packet's neighbouring firings.
fn street_neighbours(g: &Geometry, rays: &[Ray], sequences: usize, lasers: usize) -> usize {
    let mut ordered: Vec<Ray> = Vec::with_capacity(rays.len());
    for c0 in (0..1800).step_by(sequences) {
        for l0 in (0..128).step_by(lasers) {
            for c in c0..(c0 + sequences).min(1800) {
                for l in l0..(l0 + lasers).min(128) {
                    ordered.push(rays[c * 128 + l]);
                }
            }
        }
    }
    let n = sequences * lasers;
    let mut out = vec![None; n];
    let mut hits = 0;
    for r in ordered.chunks(n) {
        g.cast_rays(r, 0.0, 367.5, &mut out[..r.len()]);
        hits += out[..r.len()].iter().filter(|h| h.is_some()).count();
    }
    hits
}

fn bench(c: &mut Criterion) {
    let s = setup();
    let model = Model::Vlp16;
    let sim = s.sim(model, &ModelFile::idealized());
    let sk = skeletons(model, ReturnMode::Strongest, &s.ego, 0.1);
    let r = rays(&sim, &s.scene, &s.ego, &sk);
    let mut g = c.benchmark_group("parking_vlp16_rotation");
    g.throughput(Throughput::Elements(r.len() as u64));
    g.bench_function("bare_obvhs_traversal", |b| b.iter(|| bare(&s.scene, &r)));
    g.bench_function("idealized_model", |b| {
        b.iter(|| model_run(&sim, &s.ego, &sk))
    });
    g.finish();

    // The truth model's three ways on 10 ms of VLS-128 packets along the generated street.
    let dir = std::env::temp_dir().join(format!("hilrig-bench-street-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (scene, ego) = street(&dir);
    let st = Setup {
        scene,
        ego,
        mounting: s.mounting,
    };
    let mut g = c.benchmark_group("truth_model_vls128_street_10ms");
    let sims = three_models(&st, Model::Vls128);
    let sk = spin_from(
        Model::Vls128,
        ReturnMode::Strongest,
        UtcNanos(st.ego.span().0 .0 + 2_000_000_000),
        0.01,
    );
    g.throughput(Throughput::Elements(
        (sk.len() * hilrig::velodyne::packet::BLOCKS * hilrig::velodyne::packet::CHANNELS) as u64,
    ));
    for (name, sim) in &sims {
        g.bench_function(name.replace([',', ' '], "_"), |b| {
            b.iter(|| model_run(sim, &st.ego, &sk))
        });
    }
    g.finish();
    let _ = std::fs::remove_dir_all(&dir);
    let street = street_800k();
    let rays = street_rays();
    let mut g = c.benchmark_group("street_800k_vls128_rotation");
    g.sample_size(10);
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.bench_function("cast", |b| b.iter(|| street_single(&street, &rays)));
    g.throughput(Throughput::Elements(5 * rays.len() as u64));
    g.bench_function("divergence_5_sub_rays_one_by_one", |b| {
        b.iter(|| street_divergence(&street, &rays, false))
    });
    g.bench_function("divergence_5_sub_rays_bundled", |b| {
        b.iter(|| street_divergence(&street, &rays, true))
    });
    g.finish();

    let mut g = c.benchmark_group("bvh_build");
    g.bench_function("parking_scene", |b| {
        b.iter(|| Scene::load(&fixture("parking/rep-01/scene.toml")).unwrap())
    });
    g.finish();
}

fn report() {
    let s = setup();
    let model = Model::Vlp16;
    let sim = s.sim(model, &ModelFile::idealized());
    let sk = skeletons(model, ReturnMode::Strongest, &s.ego, 1.0);
    let r = rays(&sim, &s.scene, &s.ego, &sk);
    let (mut t_bare, mut t_model) = (Vec::new(), Vec::new());
    for _ in 0..15 {
        let t = Instant::now();
        black_box(bare(&s.scene, &r));
        t_bare.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        black_box(model_run(&sim, &s.ego, &sk));
        t_model.push(t.elapsed().as_secs_f64());
    }
    t_bare.sort_by(f64::total_cmp);
    t_model.sort_by(f64::total_cmp);
    let n = r.len() as f64;
    let (bare_rate, model_rate) = (n / t_bare[7], n / t_model[7]);
    println!(
        "rays/s on the parking scene (VLP-16, 1 s of firings, 1 thread, 15 interleaved rounds): \
         median: idealized model {:.2} M, bare obvhs traversal {:.2} M, ratio {:.2}; \
         best: {:.2} M vs {:.2} M, ratio {:.2}",
        model_rate / 1e6,
        bare_rate / 1e6,
        model_rate / bare_rate,
        n / t_model[0] / 1e6,
        n / t_bare[0] / 1e6,
        t_bare[0] / t_model[0]
    );

    let model = Model::Vlp32c;
    let sim32 = s.sim(model, &ModelFile::idealized());
    let truth = ModelFile::load(&fixture("parking/truth.toml")).unwrap();
    let sim32t = s.sim(model, &truth);
    let seconds = 3.0;
    for (name, sim, mode) in [
        ("idealized, strongest", &sim32, ReturnMode::Strongest),
        ("truth model, dual", &sim32t, ReturnMode::Dual),
    ] {
        let sk = skeletons(model, mode, &s.ego, seconds);
        let t = Instant::now();
        let returns: u64 = sk
            .par_iter()
            .enumerate()
            .map(|(k, x)| {
                let mut st = SimStats::default();
                black_box(sim.simulate(&x.packet, x.time, &s.ego, k as u64, &mut st));
                st.returns
            })
            .sum();
        let el = t.elapsed().as_secs_f64();
        println!(
            "VLP-32C {name}: {seconds} s of packets ({} packets, {returns} returns) simulated in {el:.2} s on {} threads: {:.1}x real time",
            sk.len(),
            rayon::current_num_threads(),
            seconds / el
        );
    }
    truth_report(&s);
    let t = Instant::now();
    let street = street_800k();
    let build = t.elapsed().as_secs_f64();
    let rays = street_rays();
    let (mut t_single, mut t_one, mut t_bundle) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..5 {
        let t = Instant::now();
        black_box(street_single(&street, &rays));
        t_single.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let one = street_divergence(&street, &rays, false);
        t_one.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        let bundled = street_divergence(&street, &rays, true);
        t_bundle.push(t.elapsed().as_secs_f64());
        assert_eq!(one, bundled);
    }
    // Neighbouring firings together, in the shapes the lidar model uses (a laser's firings in
    // three or four adjacent sequences) and larger ones (adjacent lasers too).
    let shapes = [(3usize, 1usize), (4, 1), (3, 2), (4, 4)];
    let mut t_shapes: Vec<Vec<f64>> = vec![Vec::new(); shapes.len()];
    for _ in 0..5 {
        let single = street_single(&street, &rays);
        for (&(s, l), t) in shapes.iter().zip(t_shapes.iter_mut()) {
            let start = Instant::now();
            assert_eq!(street_neighbours(&street, &rays, s, l), single);
            t.push(start.elapsed().as_secs_f64());
        }
    }
    for v in [&mut t_single, &mut t_one, &mut t_bundle]
        .into_iter()
        .chain(t_shapes.iter_mut())
    {
        v.sort_by(f64::total_cmp);
    }
    let n = rays.len() as f64;
    println!(
        "street of {} primitives (BVH build {build:.2} s), a VLS-128 rotation ({} rays, 1 thread, \
         median of 5 interleaved rounds): {:.2} M casts/s; five-sub-ray divergence: one by one \
         {:.2} M casts/s, bundled {:.2} M casts/s, x{:.2}",
        street.len(),
        rays.len(),
        n / t_single[2] / 1e6,
        5.0 * n / t_one[2] / 1e6,
        5.0 * n / t_bundle[2] / 1e6,
        t_one[2] / t_bundle[2]
    );
    for (&(s, l), t) in shapes.iter().zip(&t_shapes) {
        println!(
            "  neighbouring firings cast together, {s} sequences x {l} lasers: {:.2} M casts/s, x{:.2} the single casts",
            n / t[2] / 1e6,
            t_single[2] / t[2]
        );
    }
    let t = Instant::now();
    let sc = Scene::load(&fixture("parking/rep-01/scene.toml")).unwrap();
    println!(
        "parking scene: {} static primitives, BVH build {:.1} µs (load with parsing {:.1} µs)",
        sc.statics.len(),
        sc.statics.build_time.as_secs_f64() * 1e6,
        t.elapsed().as_secs_f64() * 1e6
    );
}

criterion_group!(benches, bench);

fn main() {
    benches();
    if std::env::var_os("HILRIG_BENCH_NO_REPORT").is_none() {
        report();
    }
    criterion::Criterion::default()
        .configure_from_args()
        .final_summary();
}

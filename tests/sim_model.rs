//! The lidar model against closed-form geometry, analytic motion and the statistics of each effect
//! (issue 5, must-holds 1, 3 and 4).

use hilrig::rig::Mounting;
use hilrig::scene::file::{Ground, ObjectFile, Placement, SceneFile, Wgs84};
use hilrig::scene::pose::{PoseSample, Trajectory};
use hilrig::scene::{Scene, Shape};
use hilrig::sim::lidar::Returns;
use hilrig::sim::spin::Spin;
use hilrig::sim::{Effect, FootprintPattern, LidarSim, ModelFile, SimStats};
use hilrig::stamp::UtcNanos;
use hilrig::velodyne::packet::ReturnMode;
use hilrig::velodyne::{Calibration, Decoder, Model, Point};
use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;

const T0: UtcNanos = UtcNanos(1_763_700_000_000_000_000);

fn scene(objects: Vec<ObjectFile>, ground: Option<Ground>) -> Scene {
    let file = SceneFile {
        name: "test".into(),
        origin: Wgs84 {
            latitude_deg: 48.0,
            longitude_deg: 11.0,
            height_m: 0.0,
        },
        ground,
        objects,
        actors: vec![],
    };
    Scene::from_file(file, Path::new("."), Path::new("test.toml")).unwrap()
}

fn object(name: &str, x: f64, y: f64, z: f64, shape: Shape, reflectivity: f64) -> ObjectFile {
    ObjectFile {
        name: name.into(),
        pose: Placement {
            x,
            y,
            z,
            ..Placement::default()
        },
        reflectivity,
        accuracy_m: 0.0,
        parts: vec![shape],
    }
}

/// An object of `shape` on the ground at (x, y), turned by `yaw` degrees.
fn yawed(name: &str, (x, y, yaw): (f64, f64, f64), shape: Shape, reflectivity: f64) -> ObjectFile {
    ObjectFile {
        pose: Placement {
            x,
            y,
            z: 0.0,
            yaw_deg: yaw,
            ..Placement::default()
        },
        ..object(name, 0.0, 0.0, 0.0, shape, reflectivity)
    }
}

fn wall(x: f64, reflectivity: f64) -> ObjectFile {
    // Near face at `x`, 1 km wide, 40 m tall.
    object(
        "wall",
        x + 0.25,
        0.0,
        -20.0,
        Shape::Box {
            size: [0.5, 1000.0, 40.0],
            at: Placement::default(),
            reflectivity: None,
        },
        reflectivity,
    )
}

/// Constant speed `v` (m/s) and yaw rate `w` (rad/s) from the origin heading east, sampled
/// every millisecond over `seconds`.
fn ctrv(v: f64, w: f64, seconds: f64) -> Trajectory {
    // From one second before T0, so that rotations begun before T0 have poses too.
    let n = (seconds * 1000.0) as i64;
    Trajectory::new(
        (-1000..=n)
            .map(|i| {
                let t = i as f64 * 1e-3;
                let (x, y) = analytic_xy(v, w, t);
                PoseSample {
                    t: UtcNanos(T0.0 + i * 1_000_000),
                    position: Vector3::new(x, y, 0.0),
                    yaw: w * t,
                    pitch: 0.0,
                    roll: 0.0,
                }
            })
            .collect(),
    )
    .unwrap()
}

fn analytic_xy(v: f64, w: f64, t: f64) -> (f64, f64) {
    if w.abs() < 1e-12 {
        (v * t, 0.0)
    } else {
        (v / w * (w * t).sin(), v / w * (1.0 - (w * t).cos()))
    }
}

const SENSOR_Z: f64 = 1.5;

fn mounting() -> Mounting {
    Mounting {
        x: 0.0,
        y: 0.0,
        z: SENSOR_Z,
        ..Mounting::default()
    }
}

fn model(effects: Vec<Effect>) -> ModelFile {
    ModelFile {
        name: "test".into(),
        effects,
        ..ModelFile::idealized()
    }
}

/// One rotation (plus a little) of simulated packets, decoded.
fn simulate_and_decode(
    sim: &LidarSim,
    ego: &Trajectory,
    spin: Spin,
    packets: u64,
) -> Vec<(Point, UtcNanos)> {
    let dec = Decoder::new(spin.model);
    let mut out = Vec::new();
    let mut stats = SimStats::default();
    for k in 0..packets {
        let sk = spin.packet(k, |t| t);
        let pkt = sim.simulate(&sk.packet, sk.time, ego, k, &mut stats);
        for p in dec.decode(&pkt).unwrap() {
            out.push((
                p,
                UtcNanos(sk.time.first_firing.0 + i64::from(p.time_offset_ns)),
            ));
        }
    }
    assert_eq!(stats.outside_trajectory, 0);
    out
}

fn spin(model: Model) -> Spin {
    Spin {
        model,
        mode: ReturnMode::Strongest,
        rpm: 600.0,
        phase_deg: 300.0,
        t0: UtcNanos(T0.0 + 10_000_000),
    }
}

fn laser_elevation(model: Model, laser: usize) -> f64 {
    model.laser_specs()[laser].vertical_deg.to_radians()
}

/// Half a range count plus f32 storage of the decoded metres.
fn quantum(model: Model) -> f64 {
    // f32 in the decoder (angle, sin/cos and the stored metres) adds up to ~0.02 mm here.
    model.distance_resolution_m() / 2.0 + 3e-5
}

#[test]
fn static_sensor_facing_a_wall_reproduces_each_lasers_range() {
    for model in [Model::Vlp16, Model::Vlp32c, Model::Hdl32e] {
        let d_wall = 12.0;
        let s = scene(vec![wall(d_wall, 0.5)], None);
        let sim = LidarSim::new(
            &s,
            model,
            Calibration::builtin(model),
            &mounting(),
            &ModelFile::idealized(),
        )
        .unwrap();
        let ego = ctrv(0.0, 0.0, 1.0);
        let sp = spin(model);
        let pts = simulate_and_decode(&sim, &ego, sp, sp.packets_in(0.1) + 1);
        let mut lasers_seen = vec![0usize; model.lasers()];
        for (p, _) in &pts {
            let a = f64::from(p.azimuth_deg).to_radians();
            let w = laser_elevation(model, usize::from(p.laser.0));
            let rot = -model.laser_specs()[usize::from(p.laser.0)]
                .azimuth_offset_deg
                .to_radians();
            // The beam's horizontal angle (azimuth minus the laser's rotation correction).
            let beam_az = (a - rot + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            assert!(
                beam_az.abs() < 90f64.to_radians(),
                "{model}: a return behind the sensor"
            );
            if beam_az.abs() > 60f64.to_radians() {
                // At grazing incidence the decoder's f32 azimuth (±4e-7 rad) moves the range by
                // more than the quantum: d r / d a = r tan a.
                continue;
            }
            // Closed form: a plane at x = d_wall from the beam's origin.
            let expect = d_wall / (w.cos() * beam_az.cos());
            assert!(
                (f64::from(p.distance_m) - expect).abs() <= quantum(model),
                "{model} laser {}: {} vs {expect}",
                p.laser.0,
                p.distance_m
            );
            lasers_seen[usize::from(p.laser.0)] += 1;
            if beam_az.abs() < 0.3f64.to_radians() {
                // Straight ahead each laser's range is d / cos(elevation).
                assert!((f64::from(p.distance_m) - d_wall / w.cos()).abs() < 0.01);
            }
        }
        assert!(
            lasers_seen.iter().all(|&n| n > 100),
            "{model}: {lasers_seen:?}"
        );
    }
}

#[test]
fn ranges_to_ground_boxes_and_cylinders_match_closed_form() {
    let model = Model::Vlp16;
    let q = quantum(model);
    let cyl = object(
        "column",
        8.0,
        0.0,
        0.0,
        Shape::Cylinder {
            radius: 1.0,
            height: 5.0,
            at: Placement::default(),
            reflectivity: None,
        },
        0.5,
    );
    let boxed = object(
        "box",
        -6.0,
        0.0,
        0.0,
        Shape::Box {
            size: [2.0, 4.0, 1.0],
            at: Placement {
                yaw_deg: 30.0,
                ..Placement::default()
            },
            reflectivity: None,
        },
        0.5,
    );
    let ground = Ground {
        z: 0.0,
        half_size_m: 100.0,
        reflectivity: 0.2,
        accuracy_m: 0.0,
    };
    let s = scene(vec![cyl, boxed], Some(ground));
    let sim = LidarSim::new(
        &s,
        model,
        Calibration::builtin(model),
        &mounting(),
        &ModelFile::idealized(),
    )
    .unwrap();
    let ego = ctrv(0.0, 0.0, 1.0);
    let sp = spin(model);
    let pts = simulate_and_decode(&sim, &ego, sp, sp.packets_in(0.1) + 1);
    let (mut n_cyl, mut n_ground, mut n_box) = (0, 0, 0);
    let yaw = 30f64.to_radians();
    for (p, _) in &pts {
        let laser = usize::from(p.laser.0);
        let w = laser_elevation(model, laser);
        let a = f64::from(p.azimuth_deg).to_radians();
        let zoff = model.laser_specs()[laser].vertical_offset_m;
        let origin = Vector3::new(0.0, 0.0, SENSOR_Z + zoff);
        let dir = Vector3::new(w.cos() * a.cos(), -w.cos() * a.sin(), w.sin());
        let mut candidates = Vec::new();
        // Ground: z = 0.
        if dir.z < 0.0 {
            candidates.push(-origin.z / dir.z);
        }
        // Cylinder at (8, 0), r = 1, z in [0, 5]: horizontal quadratic.
        let h = (dir.x * dir.x + dir.y * dir.y).sqrt();
        let hx = dir.x / h;
        let along = 8.0 * hx;
        let perp2 = 64.0 - along * along;
        if perp2 <= 1.0 && along > 0.0 {
            let th = along - (1.0 - perp2).sqrt();
            let t = th / h;
            let z = origin.z + t * dir.z;
            if (0.0..=5.0).contains(&z) {
                candidates.push(t);
            }
        }
        // Box at (-6, 0) yawed 30°: slab intersection in its frame.
        {
            let (c, s_) = (yaw.cos(), yaw.sin());
            let rel = origin - Vector3::new(-6.0, 0.0, 0.0);
            let lo = Vector3::new(c * rel.x + s_ * rel.y, -s_ * rel.x + c * rel.y, rel.z);
            let ld = Vector3::new(c * dir.x + s_ * dir.y, -s_ * dir.x + c * dir.y, dir.z);
            let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
            for (o, d, lo_b, hi_b) in [
                (lo.x, ld.x, -1.0, 1.0),
                (lo.y, ld.y, -2.0, 2.0),
                (lo.z, ld.z, 0.0, 1.0),
            ] {
                if d.abs() < 1e-15 {
                    if o < lo_b || o > hi_b {
                        t0 = f64::INFINITY;
                    }
                    continue;
                }
                let (a1, b1) = ((lo_b - o) / d, (hi_b - o) / d);
                t0 = t0.max(a1.min(b1));
                t1 = t1.min(a1.max(b1));
            }
            if t0 <= t1 && t0 > 0.0 {
                candidates.push(t0);
            }
        }
        let expect = candidates.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(
            expect.is_finite(),
            "laser {laser} az {}: a return where nothing is",
            p.azimuth_deg
        );
        assert!(
            (f64::from(p.distance_m) - expect).abs() <= q,
            "laser {laser} az {}: {} vs {expect}",
            p.azimuth_deg,
            p.distance_m
        );
        let hit = origin + dir * expect;
        if hit.z.abs() < 1e-6 {
            n_ground += 1;
        } else if (hit.x - 8.0).hypot(hit.y) < 1.0 + 1e-6 {
            n_cyl += 1;
        } else {
            n_box += 1;
        }
    }
    assert!(
        n_cyl > 50 && n_ground > 1000 && n_box > 50,
        "{n_cyl} {n_ground} {n_box}"
    );
}

#[test]
fn per_firing_poses_follow_constant_speed_and_yaw_rate() {
    let model = Model::Vlp16;
    let s = scene(vec![], None);
    let mount = Mounting {
        x: 1.2,
        y: 0.3,
        z: 1.9,
        ..Mounting::default()
    };
    let sim = LidarSim::new(
        &s,
        model,
        Calibration::builtin(model),
        &mount,
        &ModelFile::idealized(),
    )
    .unwrap();
    let (v, w) = (2.5, 0.4);
    let ego = ctrv(v, w, 2.0);
    let sp = spin(model);
    let dec = Decoder::new(model);
    let mut hint = 0;
    let mut worst = 0.0f64;
    for k in 0..sp.packets_in(1.0) {
        let sk = sp.packet(k, |t| t);
        let rate = dec.rotation_rate(&sk.packet, 12);
        for col in 0..12 {
            for ch in 0..32 {
                let (_, t_us) = dec.firing(&sk.packet, col, col, ch, rate);
                let t = UtcNanos(sk.time.first_firing.0 + (t_us * 1000.0).round() as i64);
                let pose = sim.sensor_pose(&ego, t, &mut hint).unwrap();
                let ts = (t.0 - T0.0) as f64 * 1e-9;
                let (x, y) = analytic_xy(v, w, ts);
                let yaw = w * ts;
                let expect = Vector3::new(
                    x + 1.2 * yaw.cos() - 0.3 * yaw.sin(),
                    y + 1.2 * yaw.sin() + 0.3 * yaw.cos(),
                    1.9,
                );
                worst = worst.max((pose.translation.vector - expect).norm());
                let (_, _, got_yaw) = pose.rotation.euler_angles();
                assert!((got_yaw - yaw).abs() < 1e-9);
            }
        }
    }
    // 1 ms samples of a 1 m/s² turn: chord error ≤ a dt² / 8 ≈ 1.3e-7 m.
    assert!(worst < 1e-6, "worst pose error {worst} m");
}

/// Ranges of the lasers at elevation ±1° straight ahead, per decoded point, keyed by firing.
fn forward_ranges(effects: Vec<Effect>, v: f64) -> Vec<(f64, f64, f64, UtcNanos, UtcNanos)> {
    let model = Model::Vlp16;
    let s = scene(vec![wall(30.0, 0.5)], None);
    let sim = LidarSim::new(
        &s,
        model,
        Calibration::builtin(model),
        &mounting(),
        &model_of(effects),
    )
    .unwrap();
    let ego = ctrv(v, 0.0, 2.0);
    let sp = spin(model);
    simulate_and_decode(&sim, &ego, sp, sp.packets_in(0.3))
        .into_iter()
        .filter(|(p, _)| {
            let a = f64::from(p.azimuth_deg);
            !(20.0..=340.0).contains(&a)
        })
        .map(|(p, t)| {
            let w = laser_elevation(model, usize::from(p.laser.0));
            let a = f64::from(p.azimuth_deg).to_radians();
            let packet_start = UtcNanos(t.0 - i64::from(p.time_offset_ns));
            (f64::from(p.distance_m), w, a, t, packet_start)
        })
        .collect()
}

fn model_of(effects: Vec<Effect>) -> ModelFile {
    model(effects)
}

#[test]
fn time_offset_and_motion_distortion_shift_points_as_expected() {
    let v = 3.0;
    // Idealized, moving toward the wall: range = (30 - v t) / (cos w cos a).
    let base = forward_ranges(vec![], v);
    assert!(base.len() > 1000);
    for &(r, w, a, t, _) in &base {
        let ts = (t.0 - T0.0) as f64 * 1e-9;
        let expect = (30.0 - v * ts) / (w.cos() * a.cos());
        assert!((r - expect).abs() <= 0.001 + 1e-5, "{r} vs {expect}");
    }
    // time_offset 20 ms: the stamps are 20 ms late, so each firing happened 20 ms earlier than
    // stamped, 6 cm farther from the wall.
    let offset = forward_ranges(vec![Effect::TimeOffset { offset_ms: 20.0 }], v);
    assert_eq!(offset.len(), base.len());
    for (&(r0, w, a, ..), &(r1, ..)) in base.iter().zip(&offset) {
        let expect = v * 0.020 / (w.cos() * a.cos());
        assert!(
            ((r1 - r0) - expect).abs() <= 0.002 + 1e-5,
            "{} vs {expect}",
            r1 - r0
        );
    }
    // Without motion distortion every firing of a rotation is cast from the rotation's start.
    let frozen = forward_ranges(vec![Effect::MotionDistortion { enabled: false }], v);
    let sp = spin(Model::Vlp16);
    let period = 60.0 / sp.rpm;
    let mut max_shift = 0.0f64;
    for (&(r0, w, a, t, packet), &(r1, ..)) in base.iter().zip(&frozen) {
        let ts = (t.0 - sp.t0.0) as f64 * 1e-9;
        let tp = (packet.0 - sp.t0.0) as f64 * 1e-9;
        // A packet belongs to the rotation in which its first firing happened; that rotation
        // began when the azimuth last passed 0 before it.
        let first_zero = (360.0 - sp.phase_deg) / 360.0 * period;
        let rotation_start = first_zero + ((tp - first_zero) / period).floor() * period;
        let since_start = ts - rotation_start;
        let expect = v * since_start / (w.cos() * a.cos());
        assert!(
            ((r1 - r0) - expect).abs() <= 0.002 + 1e-5,
            "{} vs {expect}",
            r1 - r0
        );
        max_shift = max_shift.max(r1 - r0);
    }
    assert!(max_shift > 0.25, "{max_shift}");
}

fn beam_sim(s: &Scene, effects: Vec<Effect>) -> LidarSim<'_> {
    LidarSim::new(
        s,
        Model::Vlp16,
        Calibration::builtin(Model::Vlp16),
        &mounting(),
        &model(effects),
    )
    .unwrap()
}

fn fire_at(sim: &LidarSim, s: &Scene, dir: Vector3<f64>, rng: &mut ChaCha8Rng) -> Returns {
    sim.fire(
        &Point3::new(0.0, 0.0, SENSOR_Z),
        &dir.normalize(),
        &s.new_actor_poses(),
        rng,
    )
}

#[test]
fn range_noise_sigma_and_bias_are_recovered() {
    let s = scene(vec![wall(20.0, 0.5)], None);
    let sim = beam_sim(
        &s,
        vec![
            Effect::RangeNoise { sigma_m: 0.02 },
            Effect::RangeBias { bias_m: 0.05 },
        ],
    );
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let n = 100_000;
    let r: Vec<f64> = (0..n)
        .map(|_| {
            fire_at(&sim, &s, Vector3::x(), &mut rng)
                .strongest
                .unwrap()
                .range
        })
        .collect();
    let mean = r.iter().sum::<f64>() / n as f64;
    let sd = (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
    // Sampling error of n = 1e5 Gaussian draws: the standard deviation's is σ/√(2n) = 0.22 % of
    // σ, the mean's σ/√n = 0.063 mm; both bounds are four of those (a wrong σ or bias of more
    // than about 1 % or 0.25 mm fails).
    let se_sd = 0.02 / (2.0 * n as f64).sqrt();
    let se_mean = 0.02 / (n as f64).sqrt();
    assert!((sd - 0.02).abs() < 4.0 * se_sd, "sigma {sd}");
    assert!((mean - 20.05).abs() < 4.0 * se_mean, "mean {mean}");
}

#[test]
fn random_dropout_rate_matches() {
    let s = scene(vec![wall(20.0, 0.5)], None);
    let sim = beam_sim(&s, vec![Effect::RandomDropout { probability: 0.1 }]);
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let n = 100_000;
    let lost = (0..n)
        .filter(|_| {
            fire_at(&sim, &s, Vector3::x(), &mut rng)
                .strongest
                .is_none()
        })
        .count();
    let p = lost as f64 / n as f64;
    // Binomial sd at p = 0.1, n = 1e5: 0.00095; allow 4 sd.
    assert!((p - 0.1).abs() < 0.0038, "dropout {p}");
}

#[test]
fn maximum_range_follows_reflectivity_and_incidence() {
    let threshold = Effect::DetectionThreshold {
        reference_range_m: 100.0,
        reference_reflectivity: 0.1,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for (rho, incidence_deg) in [(0.05, 0.0), (0.1, 0.0), (0.3, 0.0), (0.3, 60.0)] {
        // Bisect the range at which the return vanishes; the wall is placed so that the beam
        // meets it at that range and incidence.
        let a = f64::to_radians(incidence_deg);
        let (mut lo, mut hi) = (1.0, 400.0);
        for _ in 0..30 {
            let mid = (lo + hi) / 2.0;
            let s = scene(vec![wall(mid * a.cos(), rho)], None);
            let sim = LidarSim::new(
                &s,
                Model::Vlp16,
                Calibration::builtin(Model::Vlp16),
                &mounting(),
                &ModelFile {
                    limits: Some(hilrig::sim::model::Limits {
                        min_range_m: None,
                        max_range_m: Some(1000.0),
                    }),
                    ..model(vec![threshold.clone()])
                },
            )
            .unwrap();
            let dir = Vector3::new(a.cos(), a.sin(), 0.0);
            if fire_at(&sim, &s, dir, &mut rng).strongest.is_some() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let a = f64::to_radians(incidence_deg);
        let range_at_max = lo;
        let expect = 100.0 * (rho * a.cos() / 0.1).sqrt();
        assert!(
            ((range_at_max - expect) / expect).abs() < 0.01,
            "rho {rho} at {incidence_deg}°: {range_at_max} vs {expect}"
        );
    }
}

#[test]
fn beam_divergence_gives_edge_and_mixed_returns() {
    // A thin post 10 m ahead whose right edge is at y = 0, a wall 0.3 m behind it (mixed returns),
    // in a second scene, 10 m behind it (separate echoes: strongest and last differ).
    let post = |x: f64| {
        object(
            "post",
            x + 0.1,
            1.0,
            -5.0,
            Shape::Box {
                size: [0.2, 2.0, 10.0],
                at: Placement::default(),
                reflectivity: None,
            },
            0.5,
        )
    };
    let divergence = Effect::BeamDivergence {
        horizontal_mrad: 3.0,
        vertical_mrad: 1.5,
        sub_rays_per_axis: 7,
        range_separation_m: 0.5,
        first_echo_share: None,
        pattern: FootprintPattern::Grid,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    // Sweep the beam across the edge (y at 10 m from -3 cm to +3 cm).
    let sweep = |s: &Scene, effects: Vec<Effect>, rng: &mut ChaCha8Rng| -> Vec<(f64, Returns)> {
        let sim = beam_sim(s, effects);
        (0..=120)
            .map(|i| {
                let y = -0.03 + 0.0005 * f64::from(i);
                let dir = Vector3::new(10.0, y, 0.0);
                (y, fire_at(&sim, s, dir, rng))
            })
            .collect()
    };
    let near = scene(vec![post(10.0), wall(10.3, 0.5)], None);
    // Idealized: every range is either the post (10 m) or the wall (11.3 m), and the switch is
    // exactly at the edge.
    for (y, r) in sweep(&near, vec![], &mut rng) {
        if y.abs() < 1e-9 {
            continue;
        }
        let range = r.strongest.unwrap().range;
        let expect_post = y > 0.0;
        assert!(
            if expect_post {
                (range - 10.0 * (1.0 + (y / 10.0).powi(2)).sqrt()).abs() < 1e-6
            } else {
                range > 10.29
            },
            "idealized y {y}: {range}"
        );
    }
    let mixed: Vec<f64> = sweep(&near, vec![divergence.clone()], &mut rng)
        .into_iter()
        .map(|(_, r)| r.strongest.unwrap().range)
        .filter(|&r| r > 10.01 && r < 10.29)
        .collect();
    // The footprint at 10 m is 3 cm across: about 3 cm of the 6 cm sweep is mixed.
    assert!(
        mixed.len() >= 40 && mixed.len() <= 80,
        "{} mixed",
        mixed.len()
    );
    let far = scene(vec![post(10.0), wall(20.0, 0.5)], None);
    let two_echoes: Vec<(f64, Returns)> = sweep(&far, vec![divergence], &mut rng)
        .into_iter()
        .filter(|(_, r)| {
            let (s, l) = (r.strongest.unwrap(), r.last.unwrap());
            (s.range - l.range).abs() > 5.0
        })
        .collect();
    assert!(
        two_echoes.len() >= 40,
        "{} two-echo firings",
        two_echoes.len()
    );
    // Edge returns beyond the geometric edge (y < 0) carry less than the full reflectivity.
    let beyond: Vec<f64> = two_echoes
        .iter()
        .filter(|(y, _)| *y < -0.002)
        .map(|(_, r)| {
            r.last
                .unwrap()
                .reflectivity
                .min(r.strongest.unwrap().reflectivity)
        })
        .collect();
    assert!(
        !beyond.is_empty() && beyond.iter().all(|&x| x < 0.5),
        "{beyond:?}"
    );
}

/// A dark post 10 m ahead (its right edge at y = 0) in front of a bright wall 20 m ahead.
fn post_before_a_bright_wall() -> Scene {
    let post = object(
        "post",
        10.1,
        1.0,
        -5.0,
        Shape::Box {
            size: [0.2, 2.0, 10.0],
            at: Placement::default(),
            reflectivity: None,
        },
        0.05,
    );
    scene(vec![post, wall(20.0, 0.9)], None)
}

fn wide_beam() -> Effect {
    Effect::BeamDivergence {
        horizontal_mrad: 3.0,
        vertical_mrad: 1.5,
        sub_rays_per_axis: 7,
        range_separation_m: 0.5,
        first_echo_share: None,
        pattern: FootprintPattern::Grid,
    }
}

/// The Velodyne manuals' dual return mode (VLP-16 and VLP-32C user manuals, ch. 9): "If the
/// strongest return is also the last return, then the second-strongest return is provided."
/// A footprint split between a dark post and the bright wall behind it has the wall as both
/// its strongest and its last echo: the strongest block must then carry the post.
#[test]
fn where_the_strongest_echo_is_the_last_a_dual_return_reports_the_second_strongest() {
    let s = post_before_a_bright_wall();
    let sim = beam_sim(&s, vec![wide_beam()]);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut second, mut first_strongest, mut single) = (0, 0, 0);
    for i in 0..=120 {
        let y = -0.03 + 0.0005 * f64::from(i);
        let r = fire_at(&sim, &s, Vector3::new(10.0, y, 0.0), &mut rng);
        let (st, last) = (r.strongest.unwrap(), r.last.unwrap());
        let dual = r.dual_strongest().unwrap();
        if (last.range - st.range).abs() > 5.0 {
            // The post is the strongest: reported as such, nothing else needed.
            assert!(r.second.is_none(), "y {y}: {r:?}");
            assert_eq!(dual, st);
            first_strongest += 1;
        } else if let Some(sec) = r.second {
            // The wall is both: the post is the other echo, and weaker.
            assert!(
                sec.range < last.range - 5.0 && sec.power < st.power,
                "y {y}: {r:?}"
            );
            assert_eq!(dual, sec);
            second += 1;
        } else {
            // One echo only: the pair is identical.
            assert_eq!(dual, last);
            single += 1;
        }
    }
    assert!(
        second >= 5 && first_strongest >= 5 && single >= 50,
        "{second} second strongest, {first_strongest} post strongest, {single} single"
    );

    // In packets: where a strongest-return VLP-16 reports the wall at a firing, a dual-return
    // one reports the post in that block and the wall in the last. Without divergence (one
    // echo a firing) every dual firing is one point, reported as both.
    use hilrig::velodyne::ReturnType;
    let ego = ctrv(0.0, 0.0, 1.0);
    let by_firing = |effects: Vec<Effect>, mode: ReturnMode| {
        let sim = beam_sim(&s, effects);
        let sp = Spin {
            mode,
            ..spin(Model::Vlp16)
        };
        let mut out: std::collections::BTreeMap<(i64, u8), Vec<(ReturnType, f32)>> =
            Default::default();
        for (p, t) in simulate_and_decode(&sim, &ego, sp, sp.packets_in(0.3)) {
            out.entry((t.0, p.laser.0))
                .or_default()
                .push((p.return_type, p.distance_m));
        }
        out
    };
    let dual = by_firing(vec![wide_beam()], ReturnMode::Dual);
    let strongest = by_firing(vec![wide_beam()], ReturnMode::Strongest);
    // The two modes place a firing's beam a few microradians apart (the azimuth interpolated
    // over a dual packet's block pairs): the same echo within a few range quanta.
    let same = |a: f32, b: f32| (a - b).abs() < 0.01;
    let mut split = 0;
    for (key, pts) in &dual {
        let Some(single) = strongest.get(key) else {
            continue;
        };
        let s_range = single[0].1;
        match pts.as_slice() {
            [(ReturnType::Both, r)] => assert!(same(*r, s_range), "{key:?}: {r} {s_range}"),
            [(ReturnType::Last, last), (ReturnType::Strongest, st)] => {
                assert!(st < last, "{key:?}: {pts:?}");
                if same(s_range, *last) {
                    // The strongest is the last: the dual packet's other block is the post.
                    assert!(*st < last - 5.0, "{key:?}: {pts:?}");
                    split += 1;
                } else {
                    assert!(same(*st, s_range), "{key:?}: {pts:?} {s_range}");
                }
            }
            other => panic!("{key:?}: {other:?}"),
        }
    }
    assert!(split >= 10, "{split} firings with the second strongest");
    // "If only one return was detected, the data will be identical in the even|odd block
    // pairs": with intensity noise too (drawn once for the pair).
    let noisy = beam_sim(
        &s,
        vec![
            wide_beam(),
            Effect::Intensity {
                incidence_exponent: 1.0,
                noise_sigma: 3.0,
            },
        ],
    );
    let sp = Spin {
        mode: ReturnMode::Dual,
        ..spin(Model::Vlp16)
    };
    let (mut identical, mut two) = (0, 0);
    for k in 0..sp.packets_in(0.3) {
        let sk = sp.packet(k, |t| t);
        let pkt = noisy.simulate(&sk.packet, sk.time, &ego, k, &mut SimStats::default());
        for pair in pkt.blocks.chunks_exact(2) {
            for (last, st) in pair[0].channels.iter().zip(&pair[1].channels) {
                if last.distance == st.distance {
                    assert_eq!(last, st, "packet {k}");
                    identical += usize::from(last.distance > 0);
                } else {
                    two += 1;
                }
            }
        }
    }
    assert!(
        identical > 1000 && two >= 10,
        "{identical} identical pairs, {two} two echoes"
    );
    let ideal = by_firing(vec![], ReturnMode::Dual);
    assert!(ideal
        .values()
        .all(|p| matches!(p.as_slice(), [(ReturnType::Both, _)])));
}

/// A surface at grazing incidence returns one echo however far its footprint stretches in
/// range: the road 40 m ahead under an 8 mrad beam spans metres, which 5 sub-rays per axis
/// sample a metre or more apart, yet the surface is continuous and so is its pulse. Split, the
/// echo would be reported at one row's range with a fifth of the reflectivity.
#[test]
fn a_footprint_on_the_road_at_grazing_incidence_is_one_echo() {
    let ground = Ground {
        z: 0.0,
        half_size_m: 500.0,
        reflectivity: 0.2,
        accuracy_m: 0.0,
    };
    let s = scene(vec![], Some(ground));
    let divergence = Effect::BeamDivergence {
        horizontal_mrad: 8.0,
        vertical_mrad: 8.0,
        sub_rays_per_axis: 5,
        range_separation_m: 0.5,
        first_echo_share: None,
        pattern: FootprintPattern::Grid,
    };
    let sim = beam_sim(&s, vec![divergence]);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for ahead in [20.0, 40.0, 60.0] {
        // The footprint's range span: the rays 4 mrad below and above the centre.
        let e = (SENSOR_Z / ahead).atan();
        let near = SENSOR_Z / (e + 4e-3).sin();
        let far = SENSOR_Z / (e - 4e-3).sin();
        let r = fire_at(&sim, &s, Vector3::new(ahead, 0.0, -SENSOR_Z), &mut rng);
        let (st, last) = (r.strongest.unwrap(), r.last.unwrap());
        assert_eq!(st, last, "{ahead} m: two echoes {st:?} {last:?}");
        assert!(
            st.range > near && st.range < far,
            "{ahead} m: {} outside [{near}, {far}]",
            st.range
        );
        // The whole footprint's reflectivity: the plane's ρ, within its incidence's spread.
        assert!(
            (st.reflectivity - 0.2).abs() < 0.01,
            "{ahead} m: reflectivity {} of 0.2 (span {} m)",
            st.reflectivity,
            far - near
        );
    }
}

#[test]
fn weather_adds_near_clutter_and_shortens_range() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let threshold = Effect::DetectionThreshold {
        reference_range_m: 100.0,
        reference_reflectivity: 0.1,
    };
    let weather = Effect::Weather {
        extinction_per_m: 0.01,
        clutter_probability: 0.2,
        clutter_max_range_m: 3.0,
        clutter_reflectivity: 0.5,
    };
    // Far wall at 60 m, ρ = 0.1: clear weather sees it; α = 0.01/m loses e^-1.2 of the power.
    let s = scene(vec![wall(60.0, 0.1)], None);
    let clear = beam_sim(&s, vec![threshold.clone()]);
    assert!(fire_at(&clear, &s, Vector3::x(), &mut rng)
        .strongest
        .is_some());
    let rainy = beam_sim(&s, vec![threshold, weather]);
    let n = 20_000;
    let mut clutter = 0;
    for _ in 0..n {
        let r = fire_at(&rainy, &s, Vector3::x(), &mut rng);
        // ρ 0.1 at 60 m with e^-1.2: 0.1/3600 · 0.30 < 0.1/10000 · ... → below threshold.
        if let Some(e) = r.strongest {
            assert!(
                e.range <= 3.0,
                "the wall should vanish in rain, got {}",
                e.range
            );
            clutter += 1;
        }
    }
    let p = f64::from(clutter) / f64::from(n);
    assert!((p - 0.2).abs() < 0.012, "clutter rate {p}");
}

/// Rain's droplets lie in front of the surface the beam meets: a wall 2 m ahead under a
/// droplet range of 0.5-3 m hides the droplets behind it, so the last echo is always the wall
/// (a droplet behind it was once reported as the last echo) and no echo lies beyond it, while
/// a droplet in front of it, brighter than the faint wall, is the strongest echo in the share
/// of firings the uniform droplet range puts there: 0.5 × (2 − 0.5) / (3 − 0.5) = 0.3.
#[test]
fn rain_droplets_behind_the_wall_are_hidden() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let weather = Effect::Weather {
        extinction_per_m: 0.0,
        clutter_probability: 0.5,
        clutter_max_range_m: 3.0,
        clutter_reflectivity: 0.5,
    };
    // The weather acts through a threshold; this one (ρ 0.1 seen to 100 m) passes all echoes.
    let threshold = Effect::DetectionThreshold {
        reference_range_m: 100.0,
        reference_reflectivity: 0.1,
    };
    let s = scene(vec![wall(2.0, 0.1)], None);
    let rainy = beam_sim(&s, vec![threshold, weather]);
    let n = 20_000;
    let mut droplets = 0;
    for _ in 0..n {
        let r = fire_at(&rainy, &s, Vector3::x(), &mut rng);
        let (strongest, last) = (r.strongest.unwrap(), r.last.unwrap());
        assert!(
            (last.range - 2.0).abs() < 0.01,
            "the last echo is not the wall: {last:?}"
        );
        assert!(
            strongest.range < 2.01,
            "an echo beyond the wall: {strongest:?}"
        );
        if strongest.range < 1.99 {
            droplets += 1;
        }
    }
    let p = f64::from(droplets) / f64::from(n);
    assert!((p - 0.3).abs() < 0.015, "droplet share {p}");
}

/// Weather's extinction against Beer-Lambert (the two-way transmission `exp(-2 α R)` on the
/// received power), bounded from both sides: the range at which a wall vanishes, bisected with
/// the simulator, against the root of `ρ e^(-2αR) / R² = ρ_ref / R_ref²` found here without it.
/// A one-way path (`exp(-αR)`) would move the boundary from 56.7 m to 74 m at α = 0.01/m, a
/// tenfold α to 23 m; the tolerance (1 %) is the bisection's and the wall's placement's.
#[test]
fn weather_extinction_is_beer_lambert_on_the_two_way_path() {
    let (r_ref, rho_ref) = (100.0, 0.1);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for (rho, alpha) in [(0.1, 0.01), (0.3, 0.004), (0.1, 0.03)] {
        let effects = vec![
            Effect::DetectionThreshold {
                reference_range_m: r_ref,
                reference_reflectivity: rho_ref,
            },
            Effect::Weather {
                extinction_per_m: alpha,
                clutter_probability: 0.0,
                clutter_max_range_m: 3.0,
                clutter_reflectivity: 0.05,
            },
        ];
        // Closed form: the power margin falls monotonically with R; bisect its root.
        let margin = |r: f64| rho * (-2.0 * alpha * r).exp() / (r * r) - rho_ref / (r_ref * r_ref);
        let (mut lo, mut hi) = (1.0f64, 400.0f64);
        for _ in 0..60 {
            let mid = (lo + hi) / 2.0;
            if margin(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let expect = lo;
        // The simulator's boundary: walls nearer or farther, the beam along x.
        let (mut lo, mut hi) = (1.0f64, 400.0f64);
        for _ in 0..30 {
            let mid = (lo + hi) / 2.0;
            let s = scene(vec![wall(mid, rho)], None);
            let sim = LidarSim::new(
                &s,
                Model::Vlp16,
                Calibration::builtin(Model::Vlp16),
                &mounting(),
                &ModelFile {
                    limits: Some(hilrig::sim::model::Limits {
                        min_range_m: None,
                        max_range_m: Some(1000.0),
                    }),
                    ..model(effects.clone())
                },
            )
            .unwrap();
            if fire_at(&sim, &s, Vector3::x(), &mut rng)
                .strongest
                .is_some()
            {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        assert!(
            ((lo - expect) / expect).abs() < 0.01,
            "ρ {rho}, α {alpha}/m: the wall vanishes at {lo:.2} m, Beer-Lambert says {expect:.2} m"
        );
    }
}

#[test]
fn intensity_follows_incidence_and_mount_misalignment_rotates_the_beam() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let s = scene(vec![wall(10.0, 0.6)], None);
    let ideal = beam_sim(&s, vec![]);
    let lambert = beam_sim(
        &s,
        vec![Effect::Intensity {
            incidence_exponent: 1.0,
            noise_sigma: 0.0,
        }],
    );
    let a = 60f64.to_radians();
    let dir = Vector3::new(a.cos(), a.sin(), 0.0);
    let i0 = fire_at(&ideal, &s, dir, &mut rng).strongest.unwrap();
    let i1 = fire_at(&lambert, &s, dir, &mut rng).strongest.unwrap();
    assert!((i0.reflectivity - 0.6).abs() < 1e-9);
    assert!((i1.reflectivity - 0.3).abs() < 1e-9, "{}", i1.reflectivity);
}

/// The yaw of the beams against a wall 12 m ahead, measured from the decoded points: a point
/// the decoder puts at angle θ (counter-clockwise from the sensor's x axis, from its x and y)
/// was really measured along θ + δ, so its horizontal range is d / cos(θ + δ) and
/// δ = sign(θ) acos(d / r_h) - θ. The median over the points between 10° and 50° either side
/// (where one range count, 2 mm, moves δ by at most 0.002 / (12 tan 10°) = 1e-3 rad).
fn yaw_seen_at_a_wall(effects: Vec<Effect>) -> f64 {
    let model = Model::Vlp16;
    let d_wall = 12.0;
    let s = scene(vec![wall(d_wall, 0.5)], None);
    let sim = LidarSim::new(
        &s,
        model,
        Calibration::builtin(model),
        &mounting(),
        &model_of(effects),
    )
    .unwrap();
    let ego = ctrv(0.0, 0.0, 1.0);
    let sp = spin(model);
    let mut yaw: Vec<f64> = simulate_and_decode(&sim, &ego, sp, sp.packets_in(0.1) + 1)
        .iter()
        .filter_map(|(p, _)| {
            let (x, y) = (f64::from(p.x), f64::from(p.y));
            let theta = y.atan2(x);
            if !(10.0..50.0).contains(&theta.abs().to_degrees()) {
                return None;
            }
            let c = (d_wall / x.hypot(y)).min(1.0);
            Some(theta.signum() * c.acos() - theta)
        })
        .collect();
    assert!(yaw.len() > 500, "{} points", yaw.len());
    yaw.sort_by(f64::total_cmp);
    yaw[yaw.len() / 2].to_degrees()
}

/// `yaw_deg = 2` turns the sensor 2° counter-clockwise (towards the vehicle's left), as the
/// effect's documentation says.
#[test]
fn a_2_degree_mount_yaw_turns_the_beams_by_2_degrees_at_a_wall() {
    let straight = yaw_seen_at_a_wall(vec![]);
    assert!(straight.abs() < 0.01, "no misalignment: {straight}°");
    let skewed = yaw_seen_at_a_wall(vec![Effect::MountMisalignment {
        roll_deg: 0.0,
        pitch_deg: 0.0,
        yaw_deg: 2.0,
    }]);
    assert!(
        (skewed - 2.0).abs() < 0.01,
        "2° misalignment seen as {skewed}°"
    );
}

/// The ground's normal as the sensor sees it: a least-squares plane through the decoded points
/// (the sensor's own frame, decoded as if it were mounted as the rig says) within 25 m, its
/// normal pointing up.
fn ground_normal_seen(effects: Vec<Effect>) -> Vector3<f64> {
    let model = Model::Vlp16;
    let ground = Ground {
        z: 0.0,
        half_size_m: 200.0,
        reflectivity: 0.3,
        accuracy_m: 0.0,
    };
    let s = scene(vec![], Some(ground));
    let sim = LidarSim::new(
        &s,
        model,
        Calibration::builtin(model),
        &mounting(),
        &model_of(effects),
    )
    .unwrap();
    let ego = ctrv(0.0, 0.0, 1.0);
    let sp = spin(model);
    let pts: Vec<Vector3<f64>> = simulate_and_decode(&sim, &ego, sp, sp.packets_in(0.1) + 1)
        .iter()
        .map(|(p, _)| Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)))
        .filter(|p| p.xy().norm() < 25.0)
        .collect();
    assert!(pts.len() > 2000, "{} ground points", pts.len());
    let mean = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
    let cov = pts
        .iter()
        .map(|p| (p - mean) * (p - mean).transpose())
        .sum::<nalgebra::Matrix3<f64>>();
    let eig = nalgebra::SymmetricEigen::new(cov);
    let k = eig.eigenvalues.imin();
    let n: Vector3<f64> = eig.eigenvectors.column(k).into();
    if n.z < 0.0 {
        -n
    } else {
        n
    }
}

/// Mount roll and pitch against a plane's fitted normal. The sensor turned by R = Rx(roll)
/// (about its x axis, right-handed: z up, y left) sees the level ground's normal at R^T z =
/// (0, sin roll, cos roll); turned by Ry(pitch), at (-sin pitch, 0, cos pitch) (positive pitch:
/// nose down, ISO 8855). Computed here from the angles alone; a swapped axis, a sign or a
/// degree/radian slip fails by far more than the tolerance (0.01°, the fit's scatter over
/// thousands of points quantized to 2 mm).
#[test]
fn mount_roll_and_pitch_tilt_the_ground_plane_as_their_rotations_say() {
    let level = ground_normal_seen(vec![]);
    assert!(
        (level - Vector3::z()).norm() < 0.01f64.to_radians(),
        "level: {level}"
    );
    for (roll, pitch) in [(1.5f64, 0.0f64), (0.0, -2.0), (1.0, 1.0)] {
        let seen = ground_normal_seen(vec![Effect::MountMisalignment {
            roll_deg: roll,
            pitch_deg: pitch,
            yaw_deg: 0.0,
        }]);
        let r = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), pitch.to_radians())
            * nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), roll.to_radians());
        let expect = r.inverse() * Vector3::z();
        let angle = seen.angle(&expect).to_degrees();
        assert!(
            angle < 0.01,
            "roll {roll}°, pitch {pitch}°: normal seen {seen}, expected {expect} ({angle:.4}° apart)"
        );
    }
}

/// A UV sphere of radius `r` as an OBJ mesh (`rings` × `segments` quads, triangulated): a
/// curved surface of facets whose normals differ from one to the next.
fn sphere_obj(r: f64, rings: usize, segments: usize) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    for i in 0..=rings {
        let th = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let ph = std::f64::consts::TAU * j as f64 / segments as f64;
            let _ = writeln!(
                s,
                "v {} {} {}",
                r * th.sin() * ph.cos(),
                r * th.sin() * ph.sin(),
                r * th.cos()
            );
        }
    }
    let v = |i: usize, j: usize| i * segments + j % segments + 1;
    for i in 0..rings {
        for j in 0..segments {
            let _ = writeln!(
                s,
                "f {} {} {} {}",
                v(i, j),
                v(i + 1, j),
                v(i + 1, j + 1),
                v(i, j + 1)
            );
        }
    }
    s
}

/// A scene of depth edges around the sensor: ground, boxes (walls, a car, a yawed crate, a
/// building), cylinders (a column, a wide tank, poles 2 to 10 cm thick) and a tessellated
/// sphere; with `thin`, also objects narrower than the firings' spacing (3.5 mrad across at
/// 600 rpm): poles 1 cm thick at 12 m (0.8 mrad) and 2 cm at 20 m (1 mrad), a wire 12 mm thick
/// 4 m up, and a bar 2 cm high lying on the ground.
fn edge_scene(dir: &Path, thin: bool) -> Scene {
    std::fs::write(dir.join("sphere.obj"), sphere_obj(1.5, 24, 48)).unwrap();
    let bx = |name: &str, x: f64, y: f64, size: [f64; 3], yaw: f64, refl: f64| {
        yawed(
            name,
            (x, y, yaw),
            Shape::Box {
                size,
                at: Placement::default(),
                reflectivity: None,
            },
            refl,
        )
    };
    let cyl = |name: &str, x: f64, y: f64, radius: f64, height: f64| {
        object(
            name,
            x,
            y,
            0.0,
            Shape::Cylinder {
                radius,
                height,
                at: Placement::default(),
                reflectivity: None,
            },
            0.45,
        )
    };
    let mut objects = vec![
        bx("wall north", 0.0, 25.0, [30.0, 0.3, 6.0], 0.0, 0.5),
        bx("wall north 2", 22.0, 25.0, [10.0, 0.3, 3.0], 0.0, 0.5),
        // 1.45 m high, not 1.5: a horizontal laser at the sensor's 1.5 m would run along its top
        // face, where a ray's hit or miss of the edge is rounding's choice.
        bx("car", 8.0, 4.0, [4.5, 1.8, 1.45], 10.0, 0.35),
        bx("crate", -6.0, -5.0, [2.0, 2.0, 1.0], 30.0, 0.6),
        bx("building", -30.0, 0.0, [10.0, 40.0, 12.0], 0.0, 0.3),
        cyl("column", 12.0, -3.0, 0.12, 2.0),
        cyl("tank", 20.0, -12.0, 3.0, 4.0),
        cyl("pole 2 cm at 5 m", 5.0, 2.0, 0.01, 3.0),
        cyl("pole 4 cm at 9 m", 9.0, -1.0, 0.02, 3.0),
        cyl("pole 10 cm at 10 m", -8.0, 6.0, 0.05, 3.0),
        object(
            "sphere",
            -4.0,
            12.0,
            1.5,
            Shape::Mesh {
                file: "sphere.obj".into(),
                scale: 1.0,
                at: Placement::default(),
                reflectivity: None,
            },
            0.4,
        ),
    ];
    if thin {
        objects.extend([
            cyl("pole 1 cm at 12 m", -3.0, -11.6, 0.005, 4.0),
            cyl("pole 2 cm at 20 m", 15.0, 13.2, 0.01, 4.0),
            ObjectFile {
                pose: Placement {
                    x: -10.0,
                    y: -20.0,
                    z: 4.0,
                    pitch_deg: 90.0,
                    ..Placement::default()
                },
                ..cyl("wire", 0.0, 0.0, 0.006, 30.0)
            },
            bx("bar", 6.0, -8.0, [3.0, 0.02, 0.02], 90.0, 0.5),
        ]);
    }
    let ground = Ground {
        z: 0.0,
        half_size_m: 300.0,
        reflectivity: 0.15,
        accuracy_m: 0.0,
    };
    let file = SceneFile {
        name: "edges".into(),
        origin: Wgs84 {
            latitude_deg: 48.0,
            longitude_deg: 11.0,
            height_m: 0.0,
        },
        ground: Some(ground),
        objects,
        actors: vec![],
    };
    Scene::from_file(file, dir, &dir.join("edges.toml")).unwrap()
}

/// The truth model's effects (fixtures/parking/truth-model.toml): noise, threshold, a 3 × 1.5
/// mrad beam with 3 sub-rays per axis, dropout, intensity with noise.
fn truth_effects() -> Vec<Effect> {
    ModelFile::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/parking/truth-model.toml"),
    )
    .unwrap()
    .effects
}

/// The truth model without its random draws (range noise, dropout, intensity noise): what the
/// cast alone decides. (With them, one firing whose echo count differs shifts every later
/// draw of its packet.)
fn truth_deterministic() -> Vec<Effect> {
    truth_effects()
        .into_iter()
        .filter(|e| !matches!(e, Effect::RangeNoise { .. } | Effect::RandomDropout { .. }))
        .map(|e| match e {
            Effect::Intensity {
                incidence_exponent, ..
            } => Effect::Intensity {
                incidence_exponent,
                noise_sigma: 0.0,
            },
            e => e,
        })
        .collect()
}

/// What one simulation of a rotation gave: the packets, every firing's reported echo, and
/// the counters.
struct Rotation {
    packets: Vec<hilrig::velodyne::DataPacket>,
    reported: Vec<Option<hilrig::sim::Echo>>,
    stats: SimStats,
}

fn rotation(sim: &LidarSim, ego: &Trajectory, spin: Spin, seconds: f64) -> Rotation {
    let mut out = Rotation {
        packets: Vec::new(),
        reported: Vec::new(),
        stats: SimStats::default(),
    };
    for k in 0..spin.packets_in(seconds) {
        let sk = spin.packet(k, |t| t);
        let pkt = sim.simulate_observed(&sk.packet, sk.time, ego, k, &mut out.stats, &mut |f| {
            out.reported.push(f.reported);
        });
        out.packets.push(pkt);
    }
    out
}

/// How far the adaptive cast's output is from the full cast's.
#[derive(Debug, Default)]
struct Difference {
    /// Channels (returns) written by either.
    channels: usize,
    /// Channels whose raw distance differs by more than one count, or that only one wrote.
    beyond_quantum: usize,
    /// Channels whose intensity differs by more than one count.
    intensity: usize,
    /// Mean and largest |Δ range| of the reported echoes both have, metres.
    mean_m: f64,
    max_m: f64,
    /// Rays the adaptive cast cast, as a share of the full cast's.
    rays: f64,
}

fn difference(full: &Rotation, adaptive: &Rotation) -> Difference {
    let mut d = Difference::default();
    for (a, b) in full.packets.iter().zip(&adaptive.packets) {
        for (ba, bb) in a.blocks.iter().zip(&b.blocks) {
            for (ca, cb) in ba.channels.iter().zip(&bb.channels) {
                if ca.distance == 0 && cb.distance == 0 {
                    continue;
                }
                d.channels += 1;
                if ca.distance == 0 || cb.distance == 0 || ca.distance.abs_diff(cb.distance) > 1 {
                    d.beyond_quantum += 1;
                }
                if ca.reflectivity.abs_diff(cb.reflectivity) > 1 {
                    d.intensity += 1;
                }
            }
        }
    }
    let mut n = 0usize;
    for (a, b) in full.reported.iter().zip(&adaptive.reported) {
        if let (Some(a), Some(b)) = (a, b) {
            let x = (a.range - b.range).abs();
            d.mean_m += x;
            d.max_m = d.max_m.max(x);
            n += 1;
        }
    }
    d.mean_m /= n.max(1) as f64;
    d.rays = adaptive.stats.rays as f64 / full.stats.rays as f64;
    d
}

/// The simulator of `model` with `effects` in `s`, on the test mounting.
fn layout_sim<'a>(s: &'a Scene, model: Model, effects: &[Effect]) -> LidarSim<'a> {
    LidarSim::new(
        s,
        model,
        Calibration::builtin(model),
        &mounting(),
        &model_of(effects.to_vec()),
    )
    .unwrap()
}

/// The sensors and return modes the adaptive footprint is checked on: the standard layout
/// (VLP-16, 24 firing sequences a packet) and the banked ones (VLS-128, three, or one in dual;
/// HDL-64E, six or three).
const LAYOUTS: [(Model, ReturnMode); 6] = [
    (Model::Vlp16, ReturnMode::Strongest),
    (Model::Vlp16, ReturnMode::Dual),
    (Model::Vls128, ReturnMode::Strongest),
    (Model::Vls128, ReturnMode::Dual),
    (Model::Hdl64eS3, ReturnMode::Strongest),
    (Model::Hdl64eS3, ReturnMode::Dual),
];

/// One rotation with `effects`, cast with the full footprint and adaptively.
fn full_and_adaptive(
    s: &Scene,
    model: Model,
    mode: ReturnMode,
    effects: &[Effect],
) -> (Rotation, Rotation) {
    use hilrig::sim::lidar::FootprintCast;
    // Moving and turning, so that each firing has its own pose.
    let ego = ctrv(3.0, 0.2, 1.0);
    let sim = |how| layout_sim(s, model, effects).with_footprint_cast(how);
    let sp = Spin {
        mode,
        ..spin(model)
    };
    (
        rotation(&sim(FootprintCast::Full), &ego, sp, 0.1),
        rotation(&sim(FootprintCast::Adaptive), &ego, sp, 0.1),
    )
}

/// The adaptive footprint (BeamDivergence's documented tolerance): where no object narrower
/// than the firings' spacing stands, it gives the full cast's packets byte for byte, with the
/// truth model's random draws too; objects narrower than that change a few returns (their
/// partial echoes), at most 0.5 % of them on a scene where three of fifteen objects are.
#[test]
fn adaptive_footprint_equals_the_full_cast_within_its_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let plain = edge_scene(dir.path(), false);
    let thin = edge_scene(dir.path(), true);
    for (model, mode) in LAYOUTS {
        // Every edge of boxes, cylinders and a mesh: identical packets, noise, dropout and
        // intensity noise included (the same draws in the same order). The echoes agree to
        // 1e-9 m: where a sub-ray meets the edge two coplanar triangles share, the cast takes
        // whichever its traversal meets first, the adaptive cast the centre's.
        let (full, adaptive) = full_and_adaptive(&plain, model, mode, &truth_effects());
        let d = difference(&full, &adaptive);
        eprintln!("{model} {mode:?}, no thin objects, truth model: {d:?}");
        assert!(full.packets == adaptive.packets, "{model} {mode:?}: {d:?}");
        assert!(d.max_m < 1e-9, "{model} {mode:?}: {d:?}");
        assert!(
            full.reported
                .iter()
                .zip(&adaptive.reported)
                .all(|(a, b)| a.is_some() == b.is_some()),
            "{model} {mode:?}"
        );
        assert!(d.channels > 10_000, "{d:?}");
        // ... for a fraction of the rays.
        // ... for a fraction of the rays (a dual-return VLS-128 packet, one firing sequence
        // with no neighbour, is cast in full).
        let share = match (model, mode) {
            (Model::Vlp16, _) => 0.45,
            (_, ReturnMode::Dual) => 1.0,
            _ => 0.55,
        };
        assert!(d.rays <= share, "{model} {mode:?}: {d:?}");

        // Thin objects: the cast alone (no random draws, which one changed echo would shift
        // for the rest of its packet).
        let (full, adaptive) = full_and_adaptive(&thin, model, mode, &truth_deterministic());
        let d = difference(&full, &adaptive);
        eprintln!("{model} {mode:?}, thin objects, deterministic truth model: {d:?}");
        let beyond = d.beyond_quantum as f64 / d.channels as f64;
        assert!(beyond < 0.005, "{model} {mode:?}: {d:?}");
        // (The scene does show the risk where footprints are cast adaptively.)
        assert!(beyond > 0.0 || d.rays == 1.0, "{model} {mode:?}: {d:?}");
        assert!(d.mean_m < 1e-3, "{model} {mode:?}: {d:?}");
    }
}

/// A facade `width` × `height` m in its x-z plane, meshed in squares of `step` m (two
/// triangles each): a surveyed wall's fine mesh.
fn facade_obj(width: f64, height: f64, step: f64) -> String {
    use std::fmt::Write;
    let (nx, nz) = (
        (width / step).round() as usize,
        (height / step).round() as usize,
    );
    let mut s = String::new();
    for i in 0..=nz {
        for j in 0..=nx {
            let _ = writeln!(s, "v {} 0 {}", j as f64 * step, i as f64 * step);
        }
    }
    let v = |i: usize, j: usize| i * (nx + 1) + j + 1;
    for i in 0..nz {
        for j in 0..nx {
            let _ = writeln!(
                s,
                "f {} {} {} {}",
                v(i, j),
                v(i, j + 1),
                v(i + 1, j + 1),
                v(i + 1, j)
            );
        }
    }
    s
}

/// A street of finely meshed facades (squares of 4 cm, as a survey gives them) at 6, 12 and
/// 25 m around the sensor, one of them set back behind another's end, and the ground.
fn facade_scene(dir: &Path) -> Scene {
    std::fs::write(dir.join("facade.obj"), facade_obj(16.0, 5.0, 0.04)).unwrap();
    let facade = |name: &str, x: f64, y: f64, yaw: f64, refl: f64| {
        yawed(
            name,
            (x, y, yaw),
            Shape::Mesh {
                file: "facade.obj".into(),
                scale: 1.0,
                at: Placement::default(),
                reflectivity: None,
            },
            refl,
        )
    };
    let file = SceneFile {
        name: "street".into(),
        origin: Wgs84 {
            latitude_deg: 48.0,
            longitude_deg: 11.0,
            height_m: 0.0,
        },
        ground: Some(Ground {
            z: 0.0,
            half_size_m: 300.0,
            reflectivity: 0.15,
            accuracy_m: 0.0,
        }),
        objects: vec![
            facade("north", -8.0, 6.0, 0.0, 0.5),
            facade("north set back", 7.0, 9.0, 0.0, 0.5),
            facade("south", -8.0, -12.0, 0.0, 0.3),
            facade("west", -25.0, -8.0, 90.0, 0.4),
        ],
        actors: vec![],
    };
    Scene::from_file(file, dir, &dir.join("street.toml")).unwrap()
}

/// On finely meshed facades, most sub-rays that leave the centre ray's triangle meet one of
/// its neighbours that the witnesses met: the adaptive footprint intersects those instead of
/// casting, and still gives the full cast's packets byte for byte (the truth model's draws
/// included).
#[test]
fn on_finely_meshed_facades_the_adaptive_footprint_takes_the_neighbouring_facets() {
    let dir = tempfile::tempdir().unwrap();
    let s = facade_scene(dir.path());
    // The share of the full cast's rays: 0.41 and 0.57 (0.46 and 0.62 when every sub-ray
    // that leaves the centre's triangle was cast).
    for (model, most) in [(Model::Vlp16, 0.435), (Model::Vls128, 0.59)] {
        let (full, adaptive) =
            full_and_adaptive(&s, model, ReturnMode::Strongest, &truth_effects());
        let d = difference(&full, &adaptive);
        eprintln!("{model}, facades of 4 cm squares, truth model: {d:?}");
        assert!(d.channels > 10_000, "{d:?}");
        assert!(full.packets == adaptive.packets, "{model}: {d:?}");
        assert!(d.max_m < 1e-9, "{model}: {d:?}");
        assert!(d.rays <= most, "{model}: {d:?}");
    }
}

/// A Lambertian intensity effect (incidence exponent 1) changes nothing in a cast but the
/// reflectivity it predicts, and every cast gives that reflectivity too (`Echo::lambertian`),
/// bit for bit: what lets the gap workflow cast a model with that effect as the model without
/// it. On the standard and banked layouts, with a divergent beam cast adaptively (merged and
/// partial echoes, the threshold) and with the idealized beam (its single-echo path), with the
/// weather's extinction too; a model with another exponent returns the same echoes and still
/// reports the Lambertian value beside its own.
#[test]
fn a_lambertian_intensity_effect_changes_only_the_reflectivity_every_cast_also_gives() {
    let dir = tempfile::tempdir().unwrap();
    let s = edge_scene(dir.path(), false);
    let lambert = |k: f64| Effect::Intensity {
        incidence_exponent: k,
        noise_sigma: 0.0,
    };
    let extinction = Effect::Weather {
        extinction_per_m: 0.002,
        clutter_probability: 0.0,
        clutter_max_range_m: 20.0,
        clutter_reflectivity: 0.2,
    };
    let beam: Vec<Effect> = truth_deterministic()
        .into_iter()
        .filter(|e| !matches!(e, Effect::Intensity { .. }))
        .collect();
    let ego = ctrv(3.0, 0.2, 1.0);
    for (model, mode) in [
        (Model::Vlp16, ReturnMode::Strongest),
        (Model::Vls128, ReturnMode::Strongest),
        (Model::Vls128, ReturnMode::Dual),
    ] {
        let threshold = Effect::DetectionThreshold {
            reference_range_m: 60.0,
            reference_reflectivity: 0.1,
        };
        for without in [
            beam.clone(),
            Vec::new(),
            vec![threshold.clone(), extinction.clone()],
        ] {
            let sim = |effects: Vec<Effect>| {
                LidarSim::new(
                    &s,
                    model,
                    Calibration::builtin(model),
                    &mounting(),
                    &model_of(effects),
                )
                .unwrap()
            };
            let sp = Spin {
                mode,
                ..spin(model)
            };
            let with_k = |k: f64| {
                let mut e = without.clone();
                e.push(lambert(k));
                rotation(&sim(e), &ego, sp, 0.1)
            };
            let (bare, lambertian, steep) = (
                rotation(&sim(without.clone()), &ego, sp, 0.1),
                with_k(1.0),
                with_k(2.0),
            );
            assert_eq!(bare.reported.len(), lambertian.reported.len());
            let mut echoes = 0;
            let mut differ = 0;
            for ((a, b), c) in bare
                .reported
                .iter()
                .zip(&lambertian.reported)
                .zip(&steep.reported)
            {
                assert_eq!(a.is_some(), b.is_some(), "{model} {mode:?} {without:?}");
                assert_eq!(a.is_some(), c.is_some(), "{model} {mode:?} {without:?}");
                let (Some(a), Some(b), Some(c)) = (a, b, c) else {
                    continue;
                };
                echoes += 1;
                assert_eq!(a.range.to_bits(), b.range.to_bits());
                assert_eq!(a.power.to_bits(), b.power.to_bits());
                assert_eq!(a.lambertian.to_bits(), b.reflectivity.to_bits());
                assert_eq!(b.lambertian.to_bits(), b.reflectivity.to_bits());
                assert_eq!(c.lambertian.to_bits(), b.reflectivity.to_bits());
                assert_eq!(a.range.to_bits(), c.range.to_bits());
                assert_eq!(a.power.to_bits(), c.power.to_bits());
                differ += usize::from(a.reflectivity != b.reflectivity);
            }
            // The scene shows the effect: most echoes are not at normal incidence.
            assert!(echoes > 1000, "{model} {mode:?}: {echoes}");
            assert!(
                2 * differ > echoes,
                "{model} {mode:?}: {differ} of {echoes}"
            );
        }
    }
}

/// A model and its deterministic part simulated together from one cast of each beam
/// ([`LidarSim::simulate_pair`], what the gap workflow's full re-simulations use) give bit for
/// bit the packets each gives alone: on every layout, with the truth model plus weather
/// clutter (a divergent beam cast adaptively, every kind of random draw), and with range noise
/// on the idealized beam; and no pair with a model that is not deterministic.
#[test]
fn a_model_and_its_deterministic_part_cast_together_equal_each_alone() {
    let dir = tempfile::tempdir().unwrap();
    let s = edge_scene(dir.path(), false);
    let weather = |p: f64| Effect::Weather {
        extinction_per_m: 0.002,
        clutter_probability: p,
        clutter_max_range_m: 20.0,
        clutter_reflectivity: 0.2,
    };
    let truth: Vec<Effect> = truth_effects().into_iter().chain([weather(0.02)]).collect();
    let truth_det: Vec<Effect> = truth_deterministic()
        .into_iter()
        .chain([weather(0.0)])
        .collect();
    let noisy = vec![Effect::RangeNoise { sigma_m: 0.02 }];
    // Dropout alone leaves the idealized beam's single echo: the pair casts it the general way.
    let dropping = vec![Effect::RandomDropout { probability: 0.05 }];
    let ego = ctrv(3.0, 0.2, 1.0);
    for (model, mode) in LAYOUTS {
        for (trial, det) in [
            (&truth, &truth_det),
            (&noisy, &Vec::new()),
            (&dropping, &Vec::new()),
        ] {
            let sim = |effects: &Vec<Effect>| layout_sim(&s, model, effects);
            let (full, part) = (sim(trial), sim(det));
            assert!(part.is_deterministic() && !full.is_deterministic());
            assert!(full
                .simulate_pair(
                    &full,
                    &spin(model).packet(0, |t| t).packet,
                    spin(model).packet(0, |t| t).time,
                    &ego,
                    0,
                    &mut SimStats::default()
                )
                .is_none());
            let sp = Spin {
                mode,
                ..spin(model)
            };
            let (mut returns, mut differ) = (0usize, 0usize);
            for k in 0..sp.packets_in(0.1) {
                let sk = sp.packet(k, |t| t);
                let mut st = SimStats::default();
                let alone = (
                    full.simulate(&sk.packet, sk.time, &ego, k, &mut st),
                    part.simulate(&sk.packet, sk.time, &ego, k, &mut st),
                );
                let pair = full
                    .simulate_pair(&part, &sk.packet, sk.time, &ego, k, &mut st)
                    .expect("a deterministic part");
                assert!(pair == alone, "{model} {mode:?}, packet {k}");
                for (a, b) in alone.0.blocks.iter().zip(&alone.1.blocks) {
                    for (ca, cb) in a.channels.iter().zip(&b.channels) {
                        returns += usize::from(ca.distance > 0);
                        differ += usize::from(ca != cb);
                    }
                }
            }
            // The two models' packets do differ (the test would not see a pair that wrote
            // one model's packets twice).
            assert!(
                returns > 1000 && differ > returns / 100,
                "{model} {mode:?}: {differ} of {returns}"
            );
        }
    }
}

/// The edge scene with a walker crossing the sensor's path (an actor: cast at every firing,
/// never kept with the static hits).
fn edge_scene_with_walker(dir: &Path) -> Scene {
    let statics = edge_scene(dir, false);
    let csv = dir.join("walker.csv");
    let t0 = T0.0 as f64 * 1e-9;
    std::fs::write(
        &csv,
        format!(
            "t,x,y,z,yaw_deg\n{},6.0,-3.0,0.0,90.0\n{},6.0,3.0,0.0,90.0\n",
            t0 - 1.0,
            t0 + 2.0
        ),
    )
    .unwrap();
    let mut file = statics.file.clone();
    file.actors = vec![hilrig::scene::file::ActorFile {
        name: "walker".into(),
        trajectory: csv,
        accuracy_m: 0.0,
        reflectivity: 0.3,
        parts: vec![Shape::Cylinder {
            radius: 0.3,
            height: 1.8,
            at: Placement::default(),
            reflectivity: None,
        }],
    }];
    Scene::from_file(file, dir, &dir.join("scene.toml")).unwrap()
}

/// The gap workflow's rounds reuse the static hits of the centre rays a re-simulation before
/// kept (lidar/reuse.rs): the packets are those a fresh cast makes, bit for bit, for every
/// layout and for models with and without random effects and footprints; a model whose rays
/// are the same traverses none of its centre rays again, and one whose rays differ (a mount
/// yaw) casts them all anew.
#[test]
fn static_hits_kept_by_one_simulation_give_the_next_the_same_packets_without_casting() {
    use hilrig::sim::lidar::HitSlot;
    let dir = tempfile::tempdir().unwrap();
    let s = edge_scene_with_walker(dir.path());
    let ego = ctrv(3.0, 0.2, 1.0);
    let yawed = vec![Effect::MountMisalignment {
        yaw_deg: 0.1,
        pitch_deg: 0.0,
        roll_deg: 0.0,
    }];
    let noisy = vec![Effect::RangeNoise { sigma_m: 0.02 }];
    let (mut adaptive, mut reused) = (0, 0);
    for (model, mode) in LAYOUTS {
        let sim = |effects: &Vec<Effect>| layout_sim(&s, model, effects);
        let sp = Spin {
            mode,
            ..spin(model)
        };
        let packets: Vec<_> = (0..sp.packets_in(0.2))
            .map(|k| sp.packet(k, |t| t))
            .collect();
        // Every packet of `sim`, with the hits `given` (kept when `None`): the packets, the
        // hits kept, the rays cast.
        let run = |sim: &LidarSim, given: Option<&Vec<Option<hilrig::sim::lidar::CentreHits>>>| {
            let mut st = SimStats::default();
            let mut kept = Vec::new();
            let mut out = Vec::new();
            for (k, sk) in packets.iter().enumerate() {
                let mut slot = HitSlot {
                    given: given.and_then(|g| g[k].clone()).into_iter().collect(),
                    keep: given.is_none(),
                    ..HitSlot::default()
                };
                out.push(
                    sim.simulate_reusing(&sk.packet, sk.time, &ego, k as u64, &mut st, &mut slot),
                );
                kept.push(slot.kept);
            }
            (out, kept, st.rays)
        };
        let fresh = |sim: &LidarSim| -> Vec<_> {
            let mut st = SimStats::default();
            packets
                .iter()
                .enumerate()
                .map(|(k, sk)| sim.simulate(&sk.packet, sk.time, &ego, k as u64, &mut st))
                .collect()
        };
        let ideal = sim(&Vec::new());
        let (first, kept, cast) = run(&ideal, None);
        let ideal_kept = kept.clone();
        assert_eq!(
            first,
            fresh(&ideal),
            "{model} {mode:?}: keeping changed the packets"
        );
        assert!(kept.iter().all(Option::is_some) && cast > 1000);
        let returns: usize = first
            .iter()
            .flat_map(|p| p.blocks.iter().flat_map(|b| b.channels.iter()))
            .filter(|c| c.distance > 0)
            .count();
        assert!(returns > 1000, "{model} {mode:?}: {returns} returns");
        // The same rays: nothing traversed, the same packets (the walker included).
        for effects in [Vec::new(), noisy.clone()] {
            let m = sim(&effects);
            let (again, _, cast) = run(&m, Some(&kept));
            assert_eq!(cast, 0, "{model} {mode:?} {effects:?}");
            assert!(again == fresh(&m), "{model} {mode:?} {effects:?}");
        }
        // Other rays: every ray cast anew, the packets those of a fresh cast. A footprint
        // cast adaptively casts the same centre rays (its centre sub-ray is the beam's ray)
        // and only its other sub-rays, where its packet casts no witnesses outside itself
        // (the VLP-16's; a banked packet's witness sequences change its rays' hash).
        for effects in [yawed.clone(), truth_effects()] {
            let m = sim(&effects);
            let (_, _, alone) = run(&m, Some(&vec![None; packets.len()]));
            let (again, _, cast) = run(&m, Some(&kept));
            assert!(again == fresh(&m), "{model} {mode:?} {effects:?}");
            if model == Model::Vlp16 && effects != yawed {
                assert!(
                    cast < alone,
                    "{model} {mode:?} {effects:?}: {cast} of {alone}"
                );
                reused += 1;
            } else {
                assert_eq!(cast, alone, "{model} {mode:?} {effects:?}");
            }
        }
        // Hits kept with a footprint cast adaptively serve that model again (a layout whose
        // footprints are cast in full, a dual-return VLS-128's, keeps none).
        let truth = sim(&truth_effects());
        let (_, kept, full) = run(&truth, None);
        let (again, _, cast) = run(&truth, Some(&kept));
        assert!(again == fresh(&truth), "{model} {mode:?}");
        if kept.iter().any(Option::is_some) {
            assert!(cast < full, "{model} {mode:?}: {cast} of {full} rays");
            adaptive += 1;
        } else {
            assert_eq!(cast, full, "{model} {mode:?}");
        }
        // The hits of both models offered together (the gap workflow keeps a file for each
        // set of rays its models cast, src/sim/hit_log.rs): each model takes the first that
        // fits, the same packets, nothing cast that its own hits would have spared.
        if kept.iter().all(Option::is_some) {
            let both = |m: &LidarSim| {
                let mut st = SimStats::default();
                let mut used = Vec::new();
                let out: Vec<_> = packets
                    .iter()
                    .enumerate()
                    .map(|(k, sk)| {
                        let mut slot = HitSlot {
                            given: [&ideal_kept[k], &kept[k]]
                                .into_iter()
                                .flatten()
                                .cloned()
                                .collect(),
                            ..HitSlot::default()
                        };
                        let p = m.simulate_reusing(
                            &sk.packet, sk.time, &ego, k as u64, &mut st, &mut slot,
                        );
                        used.push(slot.used);
                        p
                    })
                    .collect();
                (out, used, st.rays)
            };
            let (again, used, c) = both(&ideal);
            assert!(again == fresh(&ideal), "{model} {mode:?}");
            assert_eq!(
                (c, used),
                (0, vec![Some(0); packets.len()]),
                "{model} {mode:?}"
            );
            let (again, used, c) = both(&truth);
            assert!(again == fresh(&truth), "{model} {mode:?}");
            assert_eq!(c, cast, "{model} {mode:?}: the truth model's rays");
            // The VLP-16's footprints cast the idealized model's centre rays; a banked
            // packet's add its witness sequences: the truth model's own hits.
            let own = if model == Model::Vlp16 { 0 } else { 1 };
            assert_eq!(used, vec![Some(own); packets.len()], "{model} {mode:?}");
        }
    }
    assert!(
        adaptive >= 4,
        "{adaptive} layouts cast footprints adaptively"
    );
    assert_eq!(
        reused, 2,
        "the VLP-16's footprints reuse the idealized centre hits"
    );
}

/// The stratified footprint the gap workflow fits with (its sub-rays off the grid's rows and
/// columns), and a first-echo receiver: cast adaptively, the same packets as cast in full.
#[test]
fn a_stratified_footprint_cast_adaptively_equals_the_full_cast() {
    let dir = tempfile::tempdir().unwrap();
    let plain = edge_scene(dir.path(), false);
    let effects: Vec<Effect> = truth_effects()
        .into_iter()
        .map(|e| match e {
            Effect::BeamDivergence {
                horizontal_mrad,
                vertical_mrad,
                range_separation_m,
                ..
            } => Effect::BeamDivergence {
                horizontal_mrad,
                vertical_mrad,
                sub_rays_per_axis: 5,
                range_separation_m,
                first_echo_share: Some(0.25),
                pattern: FootprintPattern::Stratified,
            },
            e => e,
        })
        .collect();
    assert!(effects
        .iter()
        .any(|e| matches!(e, Effect::BeamDivergence { .. })));
    for (model, mode) in [
        (Model::Vlp16, ReturnMode::Strongest),
        (Model::Vls128, ReturnMode::Strongest),
    ] {
        let (full, adaptive) = full_and_adaptive(&plain, model, mode, &effects);
        let d = difference(&full, &adaptive);
        eprintln!("{model} {mode:?}, stratified: {d:?}");
        assert!(full.packets == adaptive.packets, "{model} {mode:?}: {d:?}");
        assert!(d.channels > 10_000 && d.rays < 1.0, "{d:?}");
    }
}

/// Footprints entirely on one plane (a wall facing the sensor, with nothing behind it) get
/// the full cast's hits without their sub-rays being cast: only the centre rays (and, on the
/// VLS-128, the neighbouring sequences' outside the packet, and at a packet's edges a sub-ray
/// no neighbour vouches for) are. And the same seed gives the same packets.
#[test]
fn footprints_on_one_plane_cost_one_ray_and_equal_the_full_cast() {
    let s = scene(vec![wall(12.0, 0.5)], None);
    for (model, mode) in LAYOUTS {
        let (full, adaptive) = full_and_adaptive(&s, model, mode, &truth_effects());
        let d = difference(&full, &adaptive);
        eprintln!("{model} {mode:?}, one plane: {d:?} {:?}", adaptive.stats);
        assert!(full.packets == adaptive.packets, "{model} {mode:?}: {d:?}");
        assert!(d.channels > 5_000, "{d:?}");
        // The full cast casts five rays a firing. Adaptive: the centre; a sub-ray where a
        // packet's edge leaves it without a neighbour (VLP-16: 2 of 24 sequences, and the top
        // and bottom lasers); on the VLS-128, the neighbouring sequences' centres outside the
        // packet (two for its three sequences); its dual-return packets are cast in full.
        let most = match (model, mode) {
            (Model::Vlp16, _) => 0.35,
            (_, ReturnMode::Dual) => 1.0,
            _ => 0.45,
        };
        assert!(d.rays <= most, "{model} {mode:?}: {d:?}");
        let (_, again) = full_and_adaptive(&s, model, mode, &truth_effects());
        assert!(again.packets == adaptive.packets);
    }
}

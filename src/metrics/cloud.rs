//! A scan as `compare` uses it: decoded with the rig's calibration and placed in the scene frame
//! at each firing's pose, with each firing's range kept for the per-firing residuals.

use super::roi::Roi;
use crate::bag::packet_times::{PacketTimes, Timed};
use crate::bag::scans::Scan;
use crate::scene::pose::Trajectory;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::{Decoder, Point as LidarPoint};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};

/// A decoded scan in the scene frame, with the firings for the residuals.
pub(super) struct Cloud {
    /// Points in the region (scene frame) and their range, m.
    pub(super) points: Vec<Point3<f64>>,
    /// The firing key ([`firing_key`]) of each point of `points`.
    pub(super) point_keys: Vec<u64>,
    /// Per firing, keyed by [`firing_key`] and sorted by it: the range, m. (A sorted list
    /// joined by merging, not a hash map: hashing was a tenth of `compare`'s time.)
    pub(super) firings: Vec<(u64, f32)>,
    /// All points (scene frame) and range, for the objects.
    pub(super) all: Vec<(Point3<f64>, f32)>,
    /// Sensor position at the scan's middle.
    pub(super) origin: Option<Point3<f64>>,
    /// The scan's middle.
    pub(super) middle: UtcNanos,
}

/// A packet's sensor placement, blended linearly between its first and last firing: the
/// rotation matrices and translations of the sensor at the two ends (body pose and mount
/// composed), not the poses. A packet spans about a millisecond, in which the body turns by
/// well under a milliradian: the blended matrix departs from a rotation by under 1e-7 (a
/// micrometre at 10 m), and one matrix blend and product per point replaces computing a
/// rotation from Euler angles (a fifth of `compare`'s decoding time) and, after that, a
/// quaternion blend, its normalisation and two compositions (a sixth of its time on a parking
/// repetition). Translation is blended linearly, as the trajectory does between its samples.
struct Placement {
    a: UtcNanos,
    per_ns: f64,
    r: Matrix3<f64>,
    dr: Matrix3<f64>,
    t: Vector3<f64>,
    dt: Vector3<f64>,
}

impl Placement {
    /// The placement over the packet of `points`, whose stamp is `first`, or `None` when an
    /// end of it lies outside the trajectory (its points are then placed one by one).
    fn of_packet(
        trajectory: &Trajectory,
        first: UtcNanos,
        points: &[LidarPoint],
        mount: &Isometry3<f64>,
        hint: &mut usize,
    ) -> Option<Placement> {
        let (lo, hi) = points.iter().fold((i64::MAX, i64::MIN), |(lo, hi), q| {
            let t = i64::from(q.time_offset_ns);
            (lo.min(t), hi.max(t))
        });
        if lo > hi {
            return None;
        }
        let (a, b) = (UtcNanos(first.0 + lo), UtcNanos(first.0 + hi));
        let sa = trajectory.pose_at(a, hint)? * mount;
        let sb = trajectory.pose_at(b, hint)? * mount;
        let (ra, rb) = (
            sa.rotation.to_rotation_matrix().into_inner(),
            sb.rotation.to_rotation_matrix().into_inner(),
        );
        let (ta, tb) = (sa.translation.vector, sb.translation.vector);
        Some(Placement {
            a,
            per_ns: if b.0 == a.0 {
                0.0
            } else {
                1.0 / (b.0 - a.0) as f64
            },
            r: ra,
            dr: rb - ra,
            t: ta,
            dt: tb - ta,
        })
    }

    /// The sensor-frame point `p`, fired at `t`, in the scene frame.
    #[inline]
    fn place(&self, t: UtcNanos, p: &Vector3<f64>) -> Point3<f64> {
        let f = (t.0 - self.a.0) as f64 * self.per_ns;
        Point3::from((self.r + self.dr * f) * p + self.t + self.dt * f)
    }
}

pub(super) struct Frame<'a> {
    pub(super) decoder: &'a Decoder,
    pub(super) mount: Isometry3<f64>,
    pub(super) trajectory: &'a Trajectory,
    pub(super) pps_locked: bool,
    pub(super) roi: &'a Roi,
    pub(super) sensor_frame: bool,
}

impl Frame<'_> {
    /// Decodes `scan` and places it.
    pub(super) fn cloud(&self, scan: &Scan) -> Cloud {
        let mut out = Cloud {
            points: Vec::new(),
            point_keys: Vec::new(),
            firings: Vec::new(),
            all: Vec::new(),
            origin: None,
            middle: scan.stamp,
        };
        let mut hint = 0;
        let mut decoded: Vec<LidarPoint> = Vec::new();
        let mut times = Vec::new();
        // Scans are decoded on several cores: the packet before the scan's first is not known
        // here, so a dual-return VLS-128 scan's first packet is decoded at its block azimuths.
        for timed in PacketTimes::new(self.pps_locked).of(scan) {
            let Timed::Packet {
                index: k,
                packet: p,
                time,
            } = timed
            else {
                continue;
            };
            let first = time.first_firing;
            times.push(first);
            decoded.clear();
            if self
                .decoder
                .decode_into_at_rate(&p, time.rotation_rate, &mut decoded)
                .is_err()
            {
                continue;
            }
            let span =
                Placement::of_packet(self.trajectory, first, &decoded, &self.mount, &mut hint);
            for q in &decoded {
                let at = UtcNanos(first.0 + i64::from(q.time_offset_ns));
                let p = Vector3::new(f64::from(q.x), f64::from(q.y), f64::from(q.z));
                let world = match &span {
                    Some(s) => s.place(at, &p),
                    None => match self.trajectory.pose_at(at, &mut hint) {
                        Some(body) => body * self.mount * Point3::from(p),
                        None => continue,
                    },
                };
                let key = firing_key(k, q.time_offset_ns, q.laser.0, q.return_type as u8);
                out.firings.push((key, q.distance_m));
                out.all.push((world, q.distance_m));
                if self.sensor_frame {
                    out.points
                        .push(Point3::new(f64::from(q.x), f64::from(q.y), f64::from(q.z)));
                    out.point_keys.push(key);
                } else if self.roi.keeps(&world) {
                    out.points.push(world);
                    out.point_keys.push(key);
                }
            }
        }
        // Decoded in packet, block, laser order already for most models: nearly sorted.
        out.firings.sort_by_key(|f| f.0);
        out.firings.dedup_by_key(|f| f.0);
        if let (Some(a), Some(b)) = (times.first(), times.last()) {
            out.middle = UtcNanos((a.0 + b.0) / 2);
            let mut h = 0;
            out.origin = self
                .trajectory
                .pose_at(out.middle, &mut h)
                .map(|body| Point3::from((body * self.mount).translation.vector));
        }
        out
    }
}

/// A firing's identity within a scan: its packet's index in the scan, its time after the
/// packet's first firing (ns), the laser and the return type, in that order of significance.
/// The time, not the block: a 16-laser block holds two firing sequences, so block and laser
/// name two firings (the key once kept only one of them); a laser fires once at a time, and
/// measured and re-simulated packets share their firing times.
pub(super) fn firing_key(packet: usize, time_offset_ns: u32, laser: u8, return_type: u8) -> u64 {
    ((packet as u64) << 40)
        | (u64::from(time_offset_ns & 0xff_ffff) << 16)
        | (u64::from(laser) << 8)
        | u64::from(return_type)
}

#[cfg(test)]
mod tests {
    use super::{firing_key, Placement};
    use crate::scene::pose::{PoseSample, Trajectory};
    use hilrig_stamp::UtcNanos;
    use hilrig_velodyne::{LaserId, Point as LidarPoint, ReturnType};
    use nalgebra::{Isometry3, Point3, Vector3};

    /// A firing `offset_ns` after its packet's stamp (only the time matters here).
    fn firing(offset_ns: u32) -> LidarPoint {
        LidarPoint {
            laser: LaserId(0),
            ring: 0,
            block: 0,
            azimuth_deg: 0.0,
            distance_raw: 0,
            distance_m: 0.0,
            intensity: 0,
            return_type: ReturnType::Strongest,
            time_offset_ns: offset_ns,
            x: 0.0,
            y: 0.0,
            z: 0.0,
        }
    }

    /// The blend of a packet's end placements puts a point where the trajectory's own pose at
    /// its firing does: a car at 20 m/s turning at 1 rad/s, a 1.3 ms packet 4.1 s into the
    /// drive, a sensor mounted 1.2 m ahead and turned, points 1 m and 100 m out.
    #[test]
    fn a_packets_blended_placements_are_the_trajectorys() {
        let t0 = 1_700_000_000_000_000_000i64;
        let samples = (0..=100)
            .map(|i| {
                let s = f64::from(i) * 0.1;
                PoseSample {
                    t: UtcNanos(t0 + i64::from(i) * 100_000_000),
                    position: Vector3::new(20.0 * s, 3.0 * s * s, 0.1 * s),
                    yaw: s,
                    pitch: 0.01 * s,
                    roll: -0.02 * s,
                }
            })
            .collect();
        let trajectory = Trajectory::new(samples).unwrap();
        let first = UtcNanos(t0 + 4_100_000_000 + 37_000);
        let points: Vec<LidarPoint> = [2_304, 655_000, 1_327_104, 90_000].map(firing).into();
        let mount = Isometry3::new(Vector3::new(1.2, 0.1, 1.9), Vector3::new(0.01, -0.02, 0.3));
        let placement = Placement::of_packet(&trajectory, first, &points, &mount, &mut 0)
            .expect("a packet inside the trajectory is placed");
        for offset in [2_304, 300_000, 655_000, 1_000_000, 1_327_104] {
            let t = UtcNanos(first.0 + offset);
            let body = trajectory.pose_at(t, &mut 0).unwrap();
            for p in [
                Vector3::new(1.0, 0.0, 0.0),
                Vector3::new(-30.0, 90.0, -12.0),
            ] {
                let got = placement.place(t, &p);
                let want = body * mount * Point3::from(p);
                let off = (got - want).norm();
                assert!(
                    off < 1e-6 * (1.0 + p.norm()),
                    "{offset} ns into the packet, {p:?}: the blend is {off:e} m off the trajectory"
                );
            }
        }
        // A packet that ends beyond the trajectory has no blend (its firings are looked up one
        // by one).
        let late = UtcNanos(t0 + 10_000_000_000 - 500_000);
        assert!(Placement::of_packet(&trajectory, late, &points, &mount, &mut 0).is_none());
    }

    #[test]
    fn the_two_firing_sequences_of_a_16_laser_block_are_two_firings() {
        // VLP-16: laser 3 fires at 6.912 µs and, in the block's second sequence, at 62.208 µs.
        let (a, b) = (firing_key(0, 6_912, 3, 1), firing_key(0, 62_208, 3, 1));
        assert_ne!(a, b);
        // Ordered by packet first, then time, laser, return.
        assert!(firing_key(1, 0, 0, 0) > firing_key(0, 1_400_000, 31, 3));
        assert!(a < b && firing_key(0, 6_912, 3, 2) > a && firing_key(0, 6_912, 4, 0) > a);
    }
}

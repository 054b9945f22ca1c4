//! A packet's centre rays' static hits, kept from one re-simulation of a run for the next.
//!
//! The gap workflow re-simulates its validation runs in full in every round, and most rounds'
//! models cast the very rays of the round before: range noise, dropout or the intensity change
//! what a hit reports, not where a beam goes. Then the static geometry's hit of every centre
//! ray is known, as the primitive it met; that primitive's own intersection test with the same
//! ray gives the hit the traversal found, bit for bit ([`crate::scene::Geometry::hit_on`]), for
//! the price of one test instead of a traversal of the scene's BVH. The actors are cast as
//! always (they move).
//!
//! Whether the rays are the same is not judged from the model: each packet's rays (every
//! origin and direction, and the casting range, to the bit) are hashed, and kept hits are used
//! only for rays of the same hash. A model that moves the beams (a mount yaw, a time offset)
//! casts anew. Every model casts the same centre rays otherwise: a divergent beam's centre
//! sub-ray is the beam's own ray (`footprint::sub_ray`), so that the round that adds beam
//! divergence reuses the centre hits of the rounds before, and only its other sub-rays are
//! cast (a dual-return VLS-128's packets, whose footprints are cast whole, and the witness
//! sequences a banked packet casts around itself change its rays' hash: those re-simulations
//! keep hits of their own beside, `sim/hit_log.rs`, and reuse them from the next round on).

use super::{DataPacket, LidarSim, PacketTime, SimStats, Trajectory, Twin, CHANNELS};
use hilrig_velodyne::packet::Channel;
use nalgebra::{Point3, Vector3};

/// "No static primitive met" in [`CentreHits::prims`].
pub const NO_HIT: u32 = u32::MAX;

/// The static hits of one packet's centre rays, in the order the packet plans its firings.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CentreHits {
    /// The hash of the rays they were cast along ([`fingerprint`]).
    pub rays: u64,
    /// Per ray, the static primitive it met first, or [`NO_HIT`].
    pub prims: Vec<u32>,
}

/// What one packet's simulation reuses and keeps: the hits a re-simulation before kept for
/// it, and whether to keep this one's.
#[derive(Debug, Default)]
pub struct HitSlot {
    /// Hits kept for this packet before, by one re-simulation or several (whose models cast
    /// different rays): the first whose rays hash alike is used.
    pub given: Vec<CentreHits>,
    /// Which of `given` was used, when one was.
    pub used: Option<usize>,
    /// The hash of this packet's centre rays, when they were cast or taken ([`fingerprint`]).
    pub rays: Option<u64>,
    /// Keep this packet's hits in `kept` (when none of `given` fits).
    pub keep: bool,
    /// This packet's hits, when `keep` asked for them and they were cast.
    pub kept: Option<CentreHits>,
}

impl LidarSim<'_> {
    /// [`LidarSim::simulate`] reusing the static hits of a re-simulation before where this
    /// packet's centre rays are the same ([`HitSlot::given`]), and keeping this one's when
    /// asked ([`HitSlot::keep`]): bit for bit the same packet, its centre rays not traversed
    /// again (reuse.rs).
    pub fn simulate_reusing(
        &self,
        skeleton: &DataPacket,
        time: PacketTime,
        ego: &Trajectory,
        seed: u64,
        stats: &mut SimStats,
        hits: &mut HitSlot,
    ) -> DataPacket {
        self.simulate_observed_reusing(skeleton, time, ego, seed, stats, &mut |_| {}, hits)
    }

    /// [`LidarSim::simulate_observed`], reusing and keeping static hits as
    /// [`LidarSim::simulate_reusing`] does.
    #[allow(
        clippy::too_many_arguments,
        reason = "simulate_observed's and the hits"
    )]
    pub fn simulate_observed_reusing(
        &self,
        skeleton: &DataPacket,
        time: PacketTime,
        ego: &Trajectory,
        seed: u64,
        stats: &mut SimStats,
        observe: &mut dyn FnMut(&super::Firing),
        hits: &mut HitSlot,
    ) -> DataPacket {
        self.simulate_with(skeleton, time, ego, seed, stats, observe, None, Some(hits))
    }

    /// [`LidarSim::simulate_pair`], reusing and keeping static hits as
    /// [`LidarSim::simulate_reusing`] does.
    #[allow(clippy::too_many_arguments, reason = "simulate_pair's and the hits")]
    pub fn simulate_pair_reusing(
        &self,
        det: &LidarSim<'_>,
        skeleton: &DataPacket,
        time: PacketTime,
        ego: &Trajectory,
        seed: u64,
        stats: &mut SimStats,
        hits: Option<&mut HitSlot>,
    ) -> Option<(DataPacket, DataPacket)> {
        if !det.is_deterministic() {
            return None;
        }
        let mut twin = Twin {
            sim: det,
            pkt: skeleton.clone(),
        };
        for b in twin.pkt.blocks.iter_mut() {
            b.channels = [Channel::default(); CHANNELS];
        }
        let full = self.simulate_with(
            skeleton,
            time,
            ego,
            seed,
            stats,
            &mut |_| {},
            Some(&mut twin),
            hits,
        );
        Some((full, twin.pkt))
    }
}

/// A hash of rays and the range they are cast to, from the bits of every number: equal for
/// the same rays; different for rays that differ in one number, always (each step of the mix
/// is a bijection of the state for a given input, and of the input for a given state), and
/// for unrelated rays but for a chance of about 2^-64 (not a cryptographic hash: nothing
/// here is chosen by an adversary).
pub(super) fn fingerprint(
    rays: impl Iterator<Item = (Point3<f64>, Vector3<f64>)>,
    tmax: f64,
) -> u64 {
    let mut h: u64 = 0x243F_6A88_85A3_08D3;
    let mut mix = |x: u64| {
        h = (h.rotate_left(23) ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    };
    mix(tmax.to_bits());
    let mut n = 0u64;
    for (o, d) in rays {
        for v in [o.x, o.y, o.z, d.x, d.y, d.z] {
            mix(v.to_bits());
        }
        n += 1;
    }
    mix(n);
    h ^ (h >> 29)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Any change of a ray by one ulp, of the range, or of the rays' order or number changes
    /// the hash; the same rays give the same one.
    #[test]
    fn the_fingerprint_changes_with_every_bit_of_the_rays() {
        let rays: Vec<(Point3<f64>, Vector3<f64>)> = (0..40)
            .map(|i| {
                let a = f64::from(i) * 0.01;
                (
                    Point3::new(1.0, 2.0, 1.5),
                    Vector3::new(a.cos(), a.sin(), 0.0),
                )
            })
            .collect();
        let base = fingerprint(rays.iter().copied(), 200.0);
        assert_eq!(base, fingerprint(rays.iter().copied(), 200.0));
        assert_ne!(base, fingerprint(rays.iter().copied(), 200.5));
        assert_ne!(base, fingerprint(rays[..39].iter().copied(), 200.0));
        let mut swapped = rays.clone();
        swapped.swap(3, 4);
        assert_ne!(base, fingerprint(swapped.into_iter(), 200.0));
        for k in 0..6 {
            let mut moved = rays.clone();
            let (o, d) = &mut moved[17];
            let v = if k < 3 { &mut o[k] } else { &mut d[k - 3] };
            *v = f64::from_bits(v.to_bits() + 1);
            assert_ne!(
                base,
                fingerprint(moved.into_iter(), 200.0),
                "coordinate {k}"
            );
        }
    }
}

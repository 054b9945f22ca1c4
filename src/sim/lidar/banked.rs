//! The banked packet layouts for the simulator: the VLS-128's four blocks per firing sequence
//! and the HDL-64E's block pairs, one block per bank of 32 lasers, each laser firing at its own
//! slot of the model's firing table.

use super::footprint::CentreRay;
use super::{Firing, LidarSim, PacketPlan, PacketTime, Planned, SimStats, Twin};
use crate::scene::pose::Trajectory;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::packet::CHANNELS;
use hilrig_velodyne::{Channel, DataPacket, ReturnMode};
use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

impl LidarSim<'_> {
    /// [`LidarSim::simulate`] for the banked layouts: each block is one bank of 32 lasers (its
    /// flag says which), four blocks (VLS-128) or two (HDL-64E) a firing sequence; every firing
    /// is cast at its own azimuth and time from the firing table
    /// (`hilrig_velodyne::decode::{vls128_firing, hdl64e_firing}`), at the pose interpolated
    /// within its sequence.
    #[allow(clippy::too_many_arguments, reason = "simulate_with's, handed on")]
    pub(super) fn simulate_banked(
        &self,
        skeleton: &DataPacket,
        time: PacketTime,
        ego: &Trajectory,
        seed: u64,
        stats: &mut SimStats,
        observe: &mut dyn FnMut(&Firing),
        twin: Option<&mut Twin<'_, '_>>,
        hits: Option<&mut super::HitSlot>,
    ) -> DataPacket {
        use hilrig_velodyne::decode::{
            hdl64e_dual, hdl64e_firing, hdl64e_offset_us, hdl64e_rate, vls128_firing,
            vls128_offset_us, vls128_rate,
        };
        use hilrig_velodyne::packet::FLAGS_BANK;
        let model = self.decoder.model();
        let hdl64 = model.is_hdl64e();
        let mut pkt = skeleton.clone();
        for b in pkt.blocks.iter_mut() {
            b.channels = [Channel::default(); CHANNELS];
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mode = skeleton.return_mode.mode().unwrap_or(ReturnMode::Strongest);
        let dual = if hdl64 {
            hdl64e_dual(skeleton)
        } else {
            mode == ReturnMode::Dual
        };
        let rate = match (hdl64, dual) {
            (true, _) => hdl64e_rate(model, skeleton),
            (false, true) => time.rotation_rate.unwrap_or(0.0),
            (false, false) => vls128_rate(skeleton),
        };
        // Per block: the firing sequence's start (µs after the packet's first firing), and
        // where and when each laser fires.
        let column_start = |block: usize| -> f64 {
            match (hdl64, dual) {
                (true, true) => hdl64e_offset_us(model, block / 4 * 2, 0),
                (true, false) => hdl64e_offset_us(model, block / 2 * 2, 0),
                (false, true) => 0.0,
                (false, false) => vls128_offset_us(block / 4, 0),
            }
        };
        let firing = |block: usize, laser: usize| {
            if hdl64 {
                hdl64e_firing(model, skeleton, block, laser, rate, dual)
            } else {
                vls128_firing(skeleton, block, laser, rate, dual)
            }
        };
        let mut hint = 0usize;
        let fixed_pose = if self.fx.per_firing_pose {
            None
        } else {
            Some(self.sensor_pose(ego, self.cast_time(time.rotation_start), &mut hint))
        };
        let cal = self.decoder.calibration();
        let sequence_us = model.timing().sequence_us;
        // Blocks that carry a sequence's strongest (or only) returns, and where its last
        // returns go in dual mode: VLS-128 bank pairs (last, strongest) in the first eight
        // blocks; HDL-64E block pairs (strongest upper, lower, then last upper, lower).
        let blocks: Vec<usize> = match (hdl64, dual) {
            (_, false) => (0..12).collect(),
            (false, true) => (0..4).map(|p| 2 * p + 1).collect(),
            (true, true) => (0..12).filter(|i| i % 4 < 2).collect(),
        };
        let last_block = |block: usize| if hdl64 { block + 2 } else { block - 1 };
        // The firing sequence of a block: VLS-128 four banks, HDL-64E two (dual: block pairs
        // every four blocks), one sequence per dual VLS-128 packet.
        let sequence = |block: usize| match (hdl64, dual) {
            (true, false) => block / 2,
            (true, true) | (false, false) => block / 4,
            (false, true) => 0,
        };
        let sequences = blocks.last().map_or(0, |&b| sequence(b) + 1);
        // With an adaptive footprint, the centre rays of the firing sequences just before and
        // after the packet are cast too, as witnesses only: a VLS-128 packet holds three
        // sequences, so that without them two thirds of its footprints would lack a neighbour
        // across (and one above or below that brackets them), and two of their sub-rays
        // would be cast instead of one ray (2.9 rays a firing on the parking scene against
        // 2.5). A dual-return VLS-128 packet holds one sequence: two neighbours for each
        // firing cost more than they save (0.9 times the full cast's speed on the benchmark's
        // street), so that its footprints are cast in full.
        let adaptive = self.adaptive_footprint() && sequences > 1;
        let step_us = match blocks.iter().find(|&&b| sequence(b) == 1) {
            Some(&b) => column_start(b) - column_start(blocks[0]),
            None => sequence_us,
        };
        let mut jobs: Vec<(usize, i32)> = blocks.iter().map(|&b| (b, 0)).collect();
        if adaptive {
            for &b in &blocks {
                if sequence(b) == 0 {
                    jobs.push((b, -1));
                }
                if sequence(b) + 1 == sequences {
                    jobs.push((b, 1));
                }
            }
        }
        let mut plan = PacketPlan {
            firings: Vec::with_capacity(jobs.len() * CHANNELS),
            // Sequence 0 and the last are the neighbours outside the packet.
            sequences: sequences + 2,
            adaptive,
            mode,
            dual,
        };
        for (block, shift) in jobs {
            let Some(bank) = FLAGS_BANK
                .iter()
                .position(|f| *f == skeleton.blocks[block].flag)
            else {
                continue;
            };
            let shift_us = f64::from(shift) * step_us;
            let t0 = column_start(block) + shift_us;
            let t_a = self.cast_time(UtcNanos(time.first_firing.0 + (t0 * 1000.0).round() as i64));
            let t_b = UtcNanos(t_a.0 + (sequence_us * 1000.0).round() as i64);
            let bracket = match fixed_pose {
                Some(p) => p.map(|p| (p, p)),
                None => self
                    .sensor_pose(ego, t_a, &mut hint)
                    .zip(self.sensor_pose(ego, t_b, &mut hint)),
            };
            let Some((pa, pb)) = bracket else {
                if shift == 0 {
                    stats.firings += CHANNELS as u64;
                    stats.outside_trajectory += CHANNELS as u64;
                }
                continue;
            };
            let actors_at = UtcNanos((t_a.0 + t_b.0) / 2);
            let (ra, rb) = (
                pa.rotation.to_rotation_matrix().into_inner(),
                pb.rotation.to_rotation_matrix().into_inner(),
            );
            let (ta, tb) = (pa.translation.vector, pb.translation.vector);
            for ch in 0..CHANNELS {
                let laser = bank * CHANNELS + ch;
                let (az, t) = firing(block, laser);
                let (az, t) = (az + rate * shift_us, t + shift_us);
                let f = if fixed_pose.is_some() {
                    0.0
                } else {
                    ((t - t0) / sequence_us).clamp(0.0, 1.0)
                };
                let angle = (az * 0.01).to_radians() - cal.lasers[laser].rot_correction_rad;
                let (sa, ca) = angle.sin_cos();
                let beam = cal.beam_at(laser, sa, ca);
                let (os, ds) = (Vector3::from(beam.origin), Vector3::from(beam.direction));
                let r = ra + (rb - ra) * f;
                let o = Point3::from(r * os + ta + (tb - ta) * f);
                let d = r * ds;
                let d = d / d.norm();
                plan.firings.push(Planned {
                    block: block as u8,
                    last_block: if dual { last_block(block) } else { block } as u8,
                    channel: ch as u8,
                    laser: laser as u16,
                    sequence: (sequence(block) as i32 + 1 + shift) as u8,
                    witness_only: shift != 0,
                    time: UtcNanos(t_a.0 + (f * sequence_us * 1000.0).round() as i64),
                    actors_at,
                    centre: CentreRay {
                        origin: o,
                        direction: d,
                        hit: None,
                    },
                });
            }
        }
        self.cast_planned(&mut plan, stats, observe, &mut pkt, &mut rng, twin, hits);
        pkt
    }
}

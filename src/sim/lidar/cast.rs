//! Casting a packet's planned firings: with an adaptive divergent beam every centre ray first,
//! so that each footprint knows its neighbours' hits, then each firing's effects in the
//! packet's firing order into its channels.
//!
//! The random draws (dropout, clutter, range noise, intensity noise) happen in the second pass
//! only, firing by firing in the packet's order, exactly as when each firing was cast and
//! finished in turn: the same seed gives the same packet, and casting the centre rays ahead
//! changes no draw.

use super::footprint::Witnesses;
use super::{Firing, LidarSim, PacketPlan, Scratch, SimStats};
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::{DataPacket, ReturnMode};
use rand_chacha::ChaCha8Rng;

/// Marks a (sequence, laser) the packet does not fire.
const NONE: u16 = u16::MAX;

impl LidarSim<'_> {
    /// Casts `plan`'s firings, hands each to `observe` and writes its returns into `pkt`.
    pub(super) fn cast_planned(
        &self,
        plan: &mut PacketPlan,
        stats: &mut SimStats,
        observe: &mut dyn FnMut(&Firing),
        pkt: &mut DataPacket,
        rng: &mut ChaCha8Rng,
    ) {
        let adaptive = plan.adaptive;
        let has_actors = !self.scene.actors.is_empty();
        let mut actors = self.scene.new_actor_poses();
        let mut posed: Option<UtcNanos> = None;
        let mut pose_actors = |at: UtcNanos, actors: &mut _| {
            if has_actors && posed != Some(at) {
                self.scene.actor_poses(at, actors);
                posed = Some(at);
            }
        };
        let lasers = self.decoder.model().lasers();
        // Which firing of the plan each (sequence, laser) is.
        let mut index = Vec::new();
        if adaptive {
            index = vec![NONE; plan.sequences * lasers];
            let tmax = self.max_range * 1.5;
            for (i, p) in plan.firings.iter_mut().enumerate() {
                pose_actors(p.actors_at, &mut actors);
                let c = &mut p.centre;
                // Cast along the centre sub-ray's own direction (the unit `d` normalised
                // again, as the full cast computes it), so that both agree to the bit.
                c.hit = self
                    .scene
                    .cast(&c.origin, &c.direction.normalize(), 0.0, tmax, &actors);
                stats.rays += 1;
                if let Some(slot) =
                    index.get_mut(usize::from(p.sequence) * lasers + usize::from(p.laser))
                {
                    *slot = i as u16;
                }
            }
        }
        let plan = &*plan;
        let firing_at = |sequence: Option<usize>, laser: Option<usize>| {
            let (s, l) = (sequence?, laser?);
            if s >= plan.sequences || l >= lasers {
                return None;
            }
            let i = index.get(s * lasers + l).copied().filter(|&i| i != NONE)?;
            Some(&plan.firings[usize::from(i)].centre)
        };
        let mut scratch = Scratch::default();
        for p in plan.firings.iter().filter(|p| !p.witness_only) {
            pose_actors(p.actors_at, &mut actors);
            stats.firings += 1;
            let (seq, laser) = (usize::from(p.sequence), usize::from(p.laser));
            let (before, after) = (seq.checked_sub(1), Some(seq + 1));
            let (above, below) = (self.elevation.above(laser), self.elevation.below(laser));
            let witnesses: Witnesses = [
                firing_at(before, Some(laser)),
                firing_at(after, Some(laser)),
                firing_at(Some(seq), above),
                firing_at(Some(seq), below),
                firing_at(before, above),
                firing_at(before, below),
                firing_at(after, above),
                firing_at(after, below),
            ];
            let c = &p.centre;
            let r = self.fire_with(
                &c.origin,
                &c.direction,
                &actors,
                rng,
                adaptive.then_some((c, &witnesses)),
                &mut scratch,
                stats,
            );
            if r.strongest.is_some() {
                stats.returns += 1;
            }
            let mode = plan.mode;
            observe(&Firing {
                block: p.block,
                channel: p.channel,
                laser: p.laser,
                time: p.time,
                origin: c.origin,
                direction: c.direction,
                reported: if mode == ReturnMode::Last {
                    r.last
                } else {
                    r.strongest
                },
            });
            let (block, ch) = (usize::from(p.block), usize::from(p.channel));
            let strongest = self.channel(laser, r.strongest, rng);
            if plan.dual {
                pkt.blocks[block].channels[ch] = strongest;
                pkt.blocks[usize::from(p.last_block)].channels[ch] =
                    self.channel(laser, r.last, rng);
            } else if mode == ReturnMode::Last {
                pkt.blocks[block].channels[ch] = self.channel(laser, r.last, rng);
            } else {
                pkt.blocks[block].channels[ch] = strongest;
            }
        }
    }
}

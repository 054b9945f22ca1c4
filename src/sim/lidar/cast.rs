//! Casting a packet's planned firings: every centre ray first (with an adaptive divergent beam,
//! so that each footprint knows its neighbours' hits; without divergence, because the beam is
//! its centre ray), neighbouring firings traversing the scene together, then each firing's
//! effects in the packet's firing order into its channels. (A beam whose every sub-ray is cast
//! casts them in the second pass.)
//!
//! The random draws (dropout, clutter, range noise, intensity noise) happen in the second pass
//! only, firing by firing in the packet's order, exactly as when each firing was cast and
//! finished in turn: the same seed gives the same packet, and casting the centre rays ahead
//! changes no draw.

use super::footprint::Witnesses;
use super::reuse::{self, CentreHits, HitSlot, NO_HIT};
use super::{Firing, LidarSim, PacketPlan, Planned, Scratch, SimStats, Twin};
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::{DataPacket, ReturnMode};
use nalgebra::{Point3, Vector3};
use rand_chacha::ChaCha8Rng;

/// Firing sequences of one laser cast together, at most: a VLS-128 packet's three (with the
/// adaptive footprint's witnesses around them, five: three and two), a VLP-32C's twelve in
/// threes of four. Adjacent lasers added to a bundle made it slower on a VLS-128 minute through
/// an 800k-triangle street (`hilrig resim`, idealized model: 54.4-55.6 user CPU-s for three
/// sequences of two lasers adjacent in elevation against 51.7-51.9 for three sequences of one),
/// and larger bundles lose more to the nodes only some of their rays enter than they save
/// (`cargo bench --bench raycast`, one VLS-128 rotation of synthetic, evenly spaced beams:
/// three and four sequences of one laser 1.15-1.20 times as fast as ray by ray, three of two
/// lasers 1.18-1.20 times, four of four lasers 1.00-1.02 times).
const TOGETHER: usize = 4;

/// Marks a (sequence, laser) the packet does not fire.
const NONE: u16 = u16::MAX;

impl LidarSim<'_> {
    /// Casts `plan`'s firings, hands each to `observe` and writes its returns into `pkt`; the
    /// centre rays' static hits reused from `hits` or kept there (reuse.rs).
    #[allow(clippy::too_many_arguments, reason = "simulate_with's, handed on")]
    pub(super) fn cast_planned(
        &self,
        plan: &mut PacketPlan,
        stats: &mut SimStats,
        observe: &mut dyn FnMut(&Firing),
        pkt: &mut DataPacket,
        rng: &mut ChaCha8Rng,
        mut twin: Option<&mut Twin<'_, '_>>,
        hits: Option<&mut HitSlot>,
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
        // Every centre ray first, when the beam is its centre ray or its footprint is cast
        // adaptively; otherwise each footprint casts its own sub-rays below.
        let precast = adaptive || self.fx.divergence.is_none();
        // Which firing of the plan each (sequence, laser) is.
        let mut index = Vec::new();
        if adaptive {
            index = vec![NONE; plan.sequences * lasers];
        }
        if precast {
            self.cast_centres(plan, stats, hits);
            let tmax = self.casting_range();
            for (i, p) in plan.firings.iter_mut().enumerate() {
                pose_actors(p.actors_at, &mut actors);
                let c = &mut p.centre;
                if has_actors {
                    self.scene
                        .actors_into(&c.origin, &c.direction, 0.0, tmax, &actors, &mut c.hit);
                }
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
            let neighbourhood = precast.then_some((c, &witnesses));
            let (r, r_twin) = self.fire_with(
                twin.as_deref().map(|t| t.sim),
                &c.origin,
                &c.direction,
                &actors,
                rng,
                neighbourhood,
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
                reported: r.reported(super::Reported::of(Some(mode))),
            });
            let (block, last_block) = (usize::from(p.block), usize::from(p.last_block));
            let ch = usize::from(p.channel);
            self.write_returns(&r, (block, last_block, ch, laser), plan, pkt, rng);
            if let (Some(t), Some(r)) = (twin.as_deref_mut(), r_twin) {
                // The deterministic twin draws nothing from `rng`.
                t.sim
                    .write_returns(&r, (block, last_block, ch, laser), plan, &mut t.pkt, rng);
            }
        }
    }

    /// Writes a firing's returns into its channel of `pkt`: the strongest (or last) echo, and
    /// in dual mode the last one into the block that carries the last returns.
    fn write_returns(
        &self,
        r: &super::Returns,
        (block, last_block, ch, laser): (usize, usize, usize, usize),
        plan: &PacketPlan,
        pkt: &mut DataPacket,
        rng: &mut ChaCha8Rng,
    ) {
        // The same draws in every mode: the strongest block's first, then the last's.
        let first = if plan.dual {
            r.dual_strongest()
        } else {
            r.strongest
        };
        let strongest = self.channel(laser, first, rng);
        if plan.dual {
            pkt.blocks[block].channels[ch] = strongest;
            let last = self.channel(laser, r.last, rng);
            // One echo: the same data in both blocks, as the manuals say (the last block's
            // intensity noise is drawn all the same, so that every firing draws alike).
            pkt.blocks[last_block].channels[ch] = if r.single() { strongest } else { last };
        } else if plan.mode == ReturnMode::Last {
            pkt.blocks[block].channels[ch] = self.channel(laser, r.last, rng);
        } else {
            pkt.blocks[block].channels[ch] = strongest;
        }
    }

    /// The static geometry's hit of every planned centre ray (the full cast's centre sub-ray
    /// too, `footprint::sub_ray`), into its `hit`; the actors are the caller's. Neighbouring firings are cast together
    /// ([`crate::scene::Scene::cast_statics`]): a laser's firings in a few adjacent firing
    /// sequences, a fraction of a degree apart, share most of their traversal. Where `hits`
    /// gives the static hits of these very rays (a re-simulation before kept them: reuse.rs),
    /// each is its primitive's intersection instead, and none is traversed; where it asks,
    /// the hits are kept there.
    fn cast_centres(
        &self,
        plan: &mut PacketPlan,
        stats: &mut SimStats,
        hits: Option<&mut HitSlot>,
    ) {
        let n = plan.firings.len();
        let tmax = self.casting_range();
        // A slot that neither gives hits nor keeps them needs no hash.
        let mut reusing = hits.filter(|s| s.keep || !s.given.is_empty()).map(|slot| {
            let fp = reuse::fingerprint(
                plan.firings
                    .iter()
                    .map(|p| (p.centre.origin, p.centre.direction)),
                tmax,
            );
            (slot, fp)
        });
        if let Some((slot, fp)) = &mut reusing {
            slot.rays = Some(*fp);
            if let Some(used) = slot
                .given
                .iter()
                .position(|g| g.rays == *fp && g.prims.len() == n)
            {
                slot.used = Some(used);
                let given = &slot.given[used];
                stats.reused += n as u64;
                let statics = &self.scene.statics;
                for (p, &prim) in plan.firings.iter_mut().zip(&given.prims) {
                    let c = &mut p.centre;
                    c.hit = (prim != NO_HIT)
                        .then(|| statics.hit_on(prim, &c.origin, &c.direction, 0.0, tmax))
                        .flatten();
                }
                return;
            }
        }
        // The sequences the plan really casts (a banked packet's three, five with the
        // witnesses around them; a VLP-32C's twelve), split into groups of at most TOGETHER
        // of nearly equal size; a group's firings of one laser are cast together.
        let first = plan.firings.iter().map(|p| p.sequence).min().unwrap_or(0);
        let last = plan.firings.iter().map(|p| p.sequence).max().unwrap_or(0);
        let sequences = usize::from(last - first) + 1;
        let sequence_groups = sequences.div_ceil(TOGETHER);
        let per_group = sequences.div_ceil(sequence_groups);
        let lasers = self.decoder.model().lasers();
        let groups = lasers * sequence_groups;
        let group = |p: &Planned| {
            usize::from(p.laser) * sequence_groups
                + (usize::from(p.sequence - first) / per_group).min(sequence_groups - 1)
        };
        let keys: Vec<usize> = plan
            .firings
            .iter()
            .map(|p| group(p).min(groups - 1))
            .collect();
        // A counting sort of the firings by group (in plan order within one).
        let mut starts = vec![0usize; groups + 1];
        for &g in &keys {
            starts[g + 1] += 1;
        }
        for g in 0..groups {
            starts[g + 1] += starts[g];
        }
        let mut next = starts.clone();
        let mut order = vec![0usize; n];
        let mut rays = vec![(Point3::origin(), Vector3::zeros()); n];
        for (i, (p, &g)) in plan.firings.iter().zip(&keys).enumerate() {
            order[next[g]] = i;
            rays[next[g]] = (p.centre.origin, p.centre.direction);
            next[g] += 1;
        }
        let mut hits = vec![None; n];
        for g in 0..groups {
            let r = starts[g]..starts[g + 1];
            self.scene
                .cast_statics(&rays[r.clone()], 0.0, tmax, &mut hits[r]);
        }
        for (&i, h) in order.iter().zip(hits) {
            plan.firings[i].centre.hit = h;
        }
        stats.rays += n as u64;
        if let Some((slot, fp)) = reusing.filter(|(slot, _)| slot.keep) {
            slot.kept = Some(CentreHits {
                rays: fp,
                prims: plan
                    .firings
                    .iter()
                    .map(|p| p.centre.hit.and_then(|h| h.primitive).unwrap_or(NO_HIT))
                    .collect(),
            });
        }
    }
}

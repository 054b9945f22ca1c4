//! What one beam measures: its ray or its footprint's sub-rays cast, each one's received
//! power (the lidar equation, extinction, incidence), the merge of sub-ray hits into echoes,
//! and the threshold, bias and noise applied to each echo.

use super::footprint::{self, CentreRay, Footprint, Resolved, Witnesses};
use super::{beam_frame, effects, Echo, LidarSim, Returns, Scratch, SimStats};
use crate::scene::ActorPoses;
use hilrig_velodyne::packet::ReturnMode;
use nalgebra::{Point3, Vector3};
use rand::Rng;
use rand_distr::Distribution;

/// Whether echo `e` is reported before `s`: the stronger one, or for a first-echo receiver
/// (`first`, its share) the nearer.
fn better_of(first: Option<f64>, e: &Echo, s: &Echo) -> bool {
    match first {
        Some(_) => e.range < s.range,
        None => e.power > s.power,
    }
}

/// Merges sub-ray contributions `subs` (sorted by range; each with the range its part of the
/// footprint spans on its surface) into echoes at their power-weighted range; keeps the
/// strongest four, each one's share of the `total` sub-rays in `shares`. Returns how many
/// `echoes` holds.
///
/// Neighbours in range belong to one echo when the gap between them is within `separation`
/// (the pulse's range resolution) plus the larger span of their parts: a surface at
/// grazing incidence (the road 30 m ahead: 4 m of range under an 8 mrad footprint) returns one
/// long, continuous pulse, not the separate echoes its sparse sub-rays would make of it. Only a
/// gap in depth (an edge, an occluder in front of a background) separates echoes.
fn merge(
    subs: &[(Echo, f64)],
    separation: f64,
    total: usize,
    echoes: &mut [Echo; 4],
    shares: &mut [f64; 4],
) -> usize {
    let mut n = 0;
    let mut i = 0;
    while i < subs.len() {
        let mut j = i + 1;
        while j < subs.len()
            && subs[j].0.range - subs[j - 1].0.range <= separation + subs[j].1.max(subs[j - 1].1)
        {
            j += 1;
        }
        let group = || subs[i..j].iter().map(|s| &s.0);
        let p: f64 = group().map(|e| e.power).sum();
        let e = Echo {
            range: if p > 0.0 {
                group().map(|e| e.range * e.power).sum::<f64>() / p
            } else {
                subs[i].0.range
            },
            power: p,
            reflectivity: group().map(|e| e.reflectivity).sum(),
            lambertian: group().map(|e| e.lambertian).sum(),
        };
        let share = (j - i) as f64 / total.max(1) as f64;
        if n < echoes.len() {
            echoes[n] = e;
            shares[n] = share;
            n += 1;
        } else if let Some(weakest) = (0..echoes.len())
            .min_by(|&a, &b| echoes[a].power.total_cmp(&echoes[b].power))
            .filter(|&w| echoes[w].power < e.power)
        {
            echoes[weakest] = e;
            shares[weakest] = share;
        }
        i = j;
    }
    n
}

/// What a beam's cast found before the model's randomness: its echoes (at most four, at their
/// power-weighted ranges) and each one's share of the footprint.
#[derive(Clone, Copy)]
pub(super) struct Cast {
    echoes: [Echo; 4],
    shares: [f64; 4],
    n: usize,
}

impl LidarSim<'_> {
    /// [`LidarSim::fire`]; with `neighbourhood` (the beam's centre ray as cast already, and its
    /// witnesses), a divergent beam's sub-rays are cast only where the witnesses do not show
    /// the footprint to lie on the centre hit's plane (footprint.rs), and a beam without
    /// divergence is not cast again.
    ///
    /// With `det`, this model's deterministic part (the same model without its random
    /// effects, [`LidarSim::is_deterministic`]), what it reports of the beam too, from the
    /// same cast. This model's draws from `rng` are the ones it makes alone (the dropout's
    /// first, then the clutter's and the noise's), and `det` draws none, so that each reports
    /// bit for bit what it reports alone; the gap workflow judges a trial model's grid
    /// metrics on its deterministic part ([`crate::gap`]), and two casts were twice the work.
    #[allow(clippy::too_many_arguments, reason = "the ray loop's state, handed on")]
    pub(super) fn fire_with(
        &self,
        det: Option<&LidarSim<'_>>,
        o: &Point3<f64>,
        d: &Vector3<f64>,
        actors: &ActorPoses,
        rng: &mut impl Rng,
        neighbourhood: Option<(&CentreRay, &Witnesses)>,
        scratch: &mut Scratch,
        stats: &mut SimStats,
    ) -> (Returns, Option<Returns>) {
        let fx = &self.fx;
        let dropped = fx.dropout > 0.0 && rng.random::<f64>() < fx.dropout;
        if det.is_none() {
            if dropped {
                return (Returns::default(), None);
            }
            if self.ideal_echo {
                return (self.ideal_returns(o, d, actors, neighbourhood, stats), None);
            }
        }
        let cast = self.cast_beam(o, d, actors, neighbourhood, scratch, stats);
        let full = if dropped {
            Returns::default()
        } else {
            self.returns(cast, rng)
        };
        (full, det.map(|det| det.returns(cast, rng)))
    }

    /// The idealized beam: one ray, one echo, no power model.
    fn ideal_returns(
        &self,
        o: &Point3<f64>,
        d: &Vector3<f64>,
        actors: &ActorPoses,
        neighbourhood: Option<(&CentreRay, &Witnesses)>,
        stats: &mut SimStats,
    ) -> Returns {
        let Some(h) = self.centre_hit(o, d, actors, neighbourhood, stats) else {
            return Returns::default();
        };
        if h.range < self.min_range || h.range > self.max_range {
            return Returns::default();
        }
        let cos = -h.normal.dot(d);
        let e = Echo {
            range: h.range,
            power: h.material.reflectivity * cos / (h.range * h.range),
            reflectivity: h.material.reflectivity,
            // What `contribution` gives a whole footprint (its `1.0 * ρ` is ρ).
            lambertian: h.material.reflectivity * cos.max(0.0),
        };
        Returns {
            strongest: Some(e),
            last: Some(e),
            second: None,
        }
    }

    /// A beam's centre ray's hit: cast already when the caller has it.
    fn centre_hit(
        &self,
        o: &Point3<f64>,
        d: &Vector3<f64>,
        actors: &ActorPoses,
        neighbourhood: Option<(&CentreRay, &Witnesses)>,
        stats: &mut SimStats,
    ) -> Option<crate::scene::Hit> {
        match neighbourhood {
            Some((c, _)) => c.hit,
            None => {
                stats.rays += 1;
                self.scene.cast(o, d, 0.0, self.casting_range(), actors)
            }
        }
    }

    /// An echo of `share` of the footprint from a surface of reflectivity `refl` at `range`,
    /// met at incidence `cos`: its power by the lidar equation (with the weather's
    /// extinction), its apparent reflectivity (with the incidence exponent).
    fn contribution(&self, range: f64, refl: f64, cos: f64, share: f64) -> Echo {
        let alpha = self.fx.weather.map_or(0.0, |w| w.0);
        let k = self.fx.intensity.map(|i| i.0);
        let reflected = share * refl;
        let lambertian = reflected * cos.max(0.0);
        Echo {
            range,
            power: share * refl * cos / (range * range)
                * if alpha > 0.0 {
                    (-2.0 * alpha * range).exp()
                } else {
                    1.0
                },
            reflectivity: match k {
                None => reflected,
                // Lambertian (k = 1) is the common case; powf costs a tenth of a ray cast.
                Some(1.0) => lambertian,
                Some(k) => reflected * cos.max(0.0).powf(k),
            },
            lambertian,
        }
    }

    /// The beam cast: its centre ray, or its footprint's sub-rays merged into echoes.
    fn cast_beam(
        &self,
        o: &Point3<f64>,
        d: &Vector3<f64>,
        actors: &ActorPoses,
        neighbourhood: Option<(&CentreRay, &Witnesses)>,
        scratch: &mut Scratch,
        stats: &mut SimStats,
    ) -> Cast {
        let fx = &self.fx;
        let mut echoes: [Echo; 4] = [Echo {
            range: 0.0,
            power: 0.0,
            reflectivity: 0.0,
            lambertian: 0.0,
        }; 4];
        // Each echo's share of the footprint (the whole of it without divergence).
        let mut shares = [1.0f64; 4];
        let mut n = 0usize;
        match &fx.divergence {
            None => {
                if let Some(h) = self.centre_hit(o, d, actors, neighbourhood, stats) {
                    let cos = -h.normal.dot(d);
                    echoes[0] = self.contribution(h.range, h.material.reflectivity, cos, 1.0);
                    n = 1;
                }
            }
            Some(div) => {
                self.sub_ray_hits(o, d, actors, div, neighbourhood, scratch, stats);
                let share = 1.0 / div.pattern.offsets.len() as f64;
                let subs = &mut scratch.echoes;
                subs.clear();
                for (sd, h, _) in &scratch.hits {
                    if let Some(h) = h {
                        let cos = -h.normal.dot(sd);
                        // The range a sub-ray's share spans on a plane: r δ tan θ.
                        let c = cos.abs().max(0.01);
                        let span = h.range * div.spacing * (1.0 - c * c).sqrt() / c;
                        subs.push((
                            self.contribution(h.range, h.material.reflectivity, cos, share),
                            span,
                        ));
                    }
                }
                subs.sort_by(|a, b| a.0.range.total_cmp(&b.0.range));
                n = merge(
                    subs,
                    div.separation,
                    div.pattern.offsets.len(),
                    &mut echoes,
                    &mut shares,
                );
            }
        }
        Cast { echoes, shares, n }
    }

    /// What the receiver reports of `cast`: the weather's clutter added, the echoes below the
    /// threshold or outside the range limits dropped, bias and noise applied, the strongest
    /// (or, for a first-echo receiver, the nearest), the last, and where those two are one
    /// echo, the strongest of the others (what a dual-return packet reports beside the last).
    fn returns(&self, cast: Cast, rng: &mut impl Rng) -> Returns {
        let fx = &self.fx;
        let Cast {
            mut echoes,
            mut shares,
            mut n,
        } = cast;
        if let Some((_, p, rmax, refl)) = fx.weather {
            if p > 0.0 && rng.random::<f64>() < p && n < echoes.len() {
                let lo = self.min_range.min(rmax);
                let r = lo + rng.random::<f64>() * (rmax - lo);
                // The beam ends at the first surface it meets: a droplet behind it is hidden
                // (it would have made a last-return sensor report rain behind a wall).
                if echoes[..n].iter().all(|e| r < e.range) {
                    echoes[n] = self.contribution(r, refl, 1.0, 1.0);
                    shares[n] = 1.0;
                    n += 1;
                }
            }
        }
        let first = fx.divergence.as_ref().and_then(|d| d.first_share);
        // The echoes detected, each with its index: the strongest (or the nearest, for a
        // first-echo receiver, which reports that one where a Velodyne reports the
        // strongest) and the last.
        let mut detected: [Option<Echo>; 4] = [None; 4];
        let mut strongest: Option<(usize, Echo)> = None;
        let mut last: Option<(usize, Echo)> = None;
        for (i, (e, &share)) in echoes[..n].iter_mut().zip(&shares).enumerate() {
            if first.is_some_and(|s| share < s - 1e-9) {
                continue;
            }
            if let Some(min) = fx.min_power {
                if e.power < min {
                    continue;
                }
            }
            e.range += fx.bias_m;
            if let Some(noise) = &fx.noise {
                e.range += noise.sample(rng);
            }
            if e.range < self.min_range || e.range > self.max_range {
                continue;
            }
            detected[i] = Some(*e);
            if strongest.is_none_or(|(_, s)| better_of(first, e, &s)) {
                strongest = Some((i, *e));
            }
            if last.is_none_or(|(_, l)| e.range > l.range) {
                last = Some((i, *e));
            }
        }
        // Where the strongest is the last, the strongest of the others.
        let mut second: Option<Echo> = None;
        if let (Some((s, _)), Some((l, _))) = (strongest, last) {
            if s == l {
                for (i, e) in detected.iter().enumerate() {
                    match e {
                        Some(e) if i != l && second.is_none_or(|b| better_of(first, e, &b)) => {
                            second = Some(*e);
                        }
                        _ => {}
                    }
                }
            }
        }
        Returns {
            strongest: strongest.map(|(_, e)| e),
            last: last.map(|(_, e)| e),
            second,
        }
    }

    /// Every sub-ray's direction and hit into `scratch.hits`: all cast, or with
    /// `neighbourhood` only those its witnesses do not vouch for (footprint.rs).
    #[allow(clippy::too_many_arguments, reason = "the ray loop's state, handed on")]
    fn sub_ray_hits(
        &self,
        o: &Point3<f64>,
        d: &Vector3<f64>,
        actors: &ActorPoses,
        div: &effects::Divergence,
        neighbourhood: Option<(&CentreRay, &Witnesses)>,
        scratch: &mut Scratch,
        stats: &mut SimStats,
    ) {
        let (u, w) = beam_frame(d);
        let tmax = self.casting_range();
        let Some((centre, witnesses)) = neighbourhood else {
            // Every sub-ray, in one traversal (each exactly as cast alone).
            stats.footprints_cast += 1;
            stats.rays += div.pattern.offsets.len() as u64;
            scratch.hits.clear();
            scratch.dirs.clear();
            scratch.dirs.extend(
                div.pattern
                    .offsets
                    .iter()
                    .map(|&(a, b)| footprint::sub_ray(d, &u, &w, a, b)),
            );
            scratch.cast.clear();
            scratch.cast.resize(scratch.dirs.len(), None);
            self.scene
                .cast_bundle(o, &scratch.dirs, 0.0, tmax, actors, &mut scratch.cast);
            scratch.hits.extend(
                scratch
                    .dirs
                    .iter()
                    .zip(&scratch.cast)
                    .map(|(sd, h)| (*sd, *h, true)),
            );
            return;
        };
        let footprint = Footprint {
            centre,
            frame: (&u, &w),
            witnesses,
        };
        let mut cast = |sd: &Vector3<f64>| self.scene.cast(o, sd, 0.0, tmax, actors);
        let Resolved { cast: rays, full } = footprint::resolve(
            &footprint,
            &div.pattern,
            self.scene.statics.primitives(),
            self.witness_tolerance_m,
            tmax,
            &mut cast,
            &mut scratch.hits,
        );
        stats.rays += u64::from(rays);
        stats.footprints_cast += u64::from(full);
    }
}

impl Returns {
    /// What a dual-return packet carries beside the last echo: the strongest, or where the
    /// strongest is the last, the second strongest; the last again when it was the only echo
    /// (the pair of blocks then identical, [`Returns::single`]). So the Velodyne manuals
    /// describe the dual return mode (VLP-16 and VLP-32C user manuals, ch. 9; the simulator
    /// writes the VLS-128's and HDL-64E's dual packets by the same rule): a beam that meets a
    /// dark pole's edge in front of a bright wall reports both, not the wall twice.
    pub fn dual_strongest(&self) -> Option<Echo> {
        self.second.or(self.strongest)
    }

    /// One echo was detected (or none): a dual-return packet's two blocks carry the same.
    pub fn single(&self) -> bool {
        self.second.is_none() && self.strongest == self.last
    }

    /// The echo a block that reports `which` carries.
    pub fn reported(&self, which: Reported) -> Option<Echo> {
        match which {
            Reported::Strongest => self.strongest,
            Reported::Last => self.last,
            Reported::DualStrongest => self.dual_strongest(),
        }
    }
}

/// Which of a firing's echoes a packet's block reports (the gap workflow scores each firing
/// by it, and a droplet's echo replaces it or not by it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Reported {
    /// The strongest (a strongest-return packet).
    #[default]
    Strongest,
    /// The last (a last-return packet, and a dual-return packet's other block).
    Last,
    /// A dual-return packet's strongest block ([`Returns::dual_strongest`]): every detected
    /// echo in front of the last one can be it.
    DualStrongest,
}

impl Reported {
    /// What the block a firing's return goes to reports, in a packet of `mode` (its strongest
    /// block in a dual-return packet).
    pub fn of(mode: Option<ReturnMode>) -> Reported {
        match mode {
            Some(ReturnMode::Last) => Reported::Last,
            Some(ReturnMode::Dual) => Reported::DualStrongest,
            _ => Reported::Strongest,
        }
    }
}

//! Which sub-rays of a divergent beam's footprint must be cast, and which meet what the centre
//! ray met, so that intersecting that primitive (or a neighbouring facet of its surface) gives
//! their hit.
//!
//! A firing's footprint (3 × 1.5 mrad for the catalogue's VLP-16) is narrower than the spacing
//! of the firings around it: the same laser one firing sequence earlier and later (0.2° =
//! 3.5 mrad at 600 rpm) and the lasers next above and below in elevation. Their centre rays are
//! cast anyway (all of a packet's first); they are the footprint's *witnesses*. A witness
//! *agrees* when it met the centre's primitive, or the same material within one range quantum
//! of the centre hit's plane, or, when the centre met nothing, nothing. A sub-ray is found
//! without casting it when agreeing points *vouch* for it (they lie beyond it, on both sides of
//! its line: [`Surface::vouches`]) and no point that disagrees lies within [`BLOCKING`]
//! half-axes of it: an edge, an occluder's silhouette or the end of the surface that crossed
//! the footprint, being straight at this scale, would have to pass between the sub-ray and the
//! centre and so between the centre and one of the vouching points, which would then not
//! agree. Its hit is then the centre's primitive's own intersection test with the sub-ray: the
//! very arithmetic the cast does when that primitive is the first hit, so the result is
//! identical to the bit (but where the sub-ray meets the edge two coplanar triangles share:
//! the cast then takes whichever its traversal meets first, less than 1e-9 m apart), at the
//! cost of one primitive test instead of a BVH traversal. Where the sub-ray passes that
//! primitive's edge (a finely meshed surface), the neighbouring facets that the agreeing points
//! met are tried, and one it meets on the centre hit's plane (within a range quantum) is its
//! hit, by the same argument. The other sub-rays are cast: near an edge (the neighbour across
//! disagrees, or the lasers above or below do and leave no voucher on that side), at a
//! packet's boundary, the top or bottom laser, lasers that fire too far apart to bracket them,
//! and where the sub-ray meets none of those primitives there. Once cast, an agreeing sub-ray
//! vouches for the inner ones, a disagreeing one blocks those near it.
//!
//! Why not simply the centre's echo with the whole footprint's power: on a plane the merged
//! echo differs from the centre ray's by `r · O(δ² tan² θ)` (δ the sub-ray offset, θ the
//! incidence angle): below 0.1 mm up to 60° at 100 m, but 0.6 mm at 80° and 2.3 mm at 85°
//! (10 m, across the beam), 15 mm at 88°; and beyond about 80° at 50 m (75° at 100 m) the
//! footprint's range spread exceeds the 0.5 m range separation, and the echo is the spread
//! sub-rays' power-weighted mean (echo.rs). Intersecting per sub-ray keeps all of that.
//!
//! **What can still differ from the full cast** (the tolerance; measured in
//! `tests/sim_model.rs`, stated in [`crate::sim::Effect::BeamDivergence`]): an object in front
//! of the centre's primitive, inside the footprint, that no witness sees:
//! - an object narrower than the witnesses' spacing (across: one firing sequence, 3.5 mrad at
//!   600 rpm, 3.5 cm at 10 m; along elevation: the laser spacing, 35 mrad on the VLP-16, about
//!   15 on the VLS-128 within a group of lasers at one azimuth) lying between the centre rays
//!   of its row, where the full cast's sub-rays meet it: a pole, a wire, a bar. A vertical one
//!   of angular width `s < Δ` (the spacing) is missed by every centre ray of a row with
//!   probability `1 - s/Δ`, and then met by a sub-ray of a footprint beside it with
//!   probability about `2 s/Δ` (3 sub-rays per axis): the full cast reports its partial echo
//!   (strongest when it is near and bright, a mixed range within the range separation), the
//!   adaptive cast what lies behind. Where a centre ray meets it, its neighbours' witnesses
//!   disagree and their sub-rays near it are cast;
//! - the corner of an object, or the tip of a curved outline, reaching between a sub-ray and
//!   its vouchers while no witness on that side sees it (within about a half-axis of the
//!   sub-ray, at most [`LATERAL`] beside it): the scale at which the 3 × 3 grid itself
//!   samples the footprint;
//! - a surface of the same material less than one range quantum in front of the plane at every
//!   witness: the sub-ray's range is then off by less than that quantum.

use crate::scene::{Hit, Primitive};
use hilrig_velodyne::Calibration;
use nalgebra::{Point3, Vector3};

/// Lasers whose azimuth corrections differ by less than this (radians) fire at about the same
/// azimuth in one firing sequence, so that one can witness the other along elevation (0.1°;
/// the VLS-128's and VLP-32C's laser groups differ by 1.4° or more).
const SAME_AZIMUTH_RAD: f64 = 1.75e-3;

/// How far off a sub-ray's line (in footprint half-axes) the points beyond it that vouch for it
/// may lie: the VLS-128's and VLP-16's lasers next above and below fire up to 1.3 half-axes
/// further on than the laser between them at 600 rpm, and one firing sequence (a column) is
/// 2.4 half-axes, so that the same sequence and the one before or after bracket each sub-ray.
/// As wide as the spacing across, so that no object narrower than that can hide between the
/// two.
const LATERAL: f64 = 2.5;

/// A point beyond a sub-ray this close to its line (half-axes) vouches for it alone: the same
/// laser one sequence on lies a few thousandths off the line (the vehicle's motion).
const ON_LINE: f64 = 0.1;

/// A witness or cast sub-ray that disagrees blocks the sub-rays within this distance of it
/// (footprint half-axes): the neighbour across (2.4 half-axes at 600 rpm) blocks the three
/// sub-rays nearer to it than the centre, the one on its side and those above and below (a
/// sphere's outline, curved, once reached the one above between its vouchers when only the
/// one on the side was blocked); the lasers above and below (about 20 half-axes away on the
/// VLS-128, 47 on the VLP-16) block none, they only leave the sub-ray on their side without
/// a voucher there.
const BLOCKING: f64 = 3.0;

/// The most points a footprint keeps (witnesses and cast sub-rays); more could only vouch for
/// more.
const POINTS: usize = 16;

/// A centre ray as cast: where from, which way, and what it met.
#[derive(Clone, Copy, Debug)]
pub(super) struct CentreRay {
    /// Beam origin, scene frame.
    pub(super) origin: Point3<f64>,
    /// Unit direction, scene frame.
    pub(super) direction: Vector3<f64>,
    /// The first hit (within the simulator's casting range).
    pub(super) hit: Option<Hit>,
}

/// The sub-rays of a divergent beam, as the beam_divergence effect lays them out.
#[derive(Clone, Debug)]
pub(super) struct Pattern {
    /// Angular offsets (across, along elevation) in radians, in the order the full cast casts
    /// and merges them.
    pub(super) offsets: Vec<(f64, f64)>,
    /// Indices into `offsets`, the footprint's rim first: the adaptive cast judges them in this
    /// order, so that rim sub-rays it had to cast can vouch for the inner ones.
    outer_first: Vec<usize>,
    /// The footprint's half-axes (across, along elevation), radians: the unit in which
    /// vouching distances are measured.
    half_axes: (f64, f64),
}

impl Pattern {
    /// The pattern of these offsets over a footprint of these half-axes (radians). The
    /// half-axes are the footprint's own, not the outermost sub-rays': the vouching distances
    /// are calibrated against the spacing of the firings in footprint half-axes, and a pattern
    /// whose outermost sub-rays lie inside the rim (a stratified one, an even grid) must not
    /// shrink them.
    pub(super) fn new(offsets: Vec<(f64, f64)>, half_axes: (f64, f64)) -> Pattern {
        let half_axes = (half_axes.0.max(1e-12), half_axes.1.max(1e-12));
        let radius = |&(a, b): &(f64, f64)| (a / half_axes.0).hypot(b / half_axes.1);
        let mut outer_first: Vec<usize> = (0..offsets.len()).collect();
        outer_first.sort_by(|&i, &j| radius(&offsets[j]).total_cmp(&radius(&offsets[i])));
        Pattern {
            offsets,
            outer_first,
            half_axes,
        }
    }
}

/// Per laser, the lasers next above and below it in elevation among those that fire at about
/// the same azimuth: its witnesses along elevation.
#[derive(Clone, Debug)]
pub(super) struct Elevation {
    above: Vec<Option<u16>>,
    below: Vec<Option<u16>>,
}

impl Elevation {
    /// The neighbours of every laser of `cal`.
    pub(super) fn new(cal: &Calibration) -> Elevation {
        let lasers = &cal.lasers;
        let next = |l: usize, up: bool| -> Option<u16> {
            let me = &lasers[l];
            lasers
                .iter()
                .enumerate()
                .filter(|(m, o)| {
                    *m != l
                        && (o.rot_correction_rad - me.rot_correction_rad).abs() < SAME_AZIMUTH_RAD
                        && if up {
                            o.vertical_rad > me.vertical_rad
                        } else {
                            o.vertical_rad < me.vertical_rad
                        }
                })
                .min_by(|a, b| {
                    let da = (a.1.vertical_rad - me.vertical_rad).abs();
                    let db = (b.1.vertical_rad - me.vertical_rad).abs();
                    da.total_cmp(&db)
                })
                .and_then(|(m, _)| u16::try_from(m).ok())
        };
        Elevation {
            above: (0..lasers.len()).map(|l| next(l, true)).collect(),
            below: (0..lasers.len()).map(|l| next(l, false)).collect(),
        }
    }

    /// The laser above `laser` (same azimuth group), if any.
    pub(super) fn above(&self, laser: usize) -> Option<usize> {
        self.above.get(laser).copied().flatten().map(usize::from)
    }

    /// The laser below `laser` (same azimuth group), if any.
    pub(super) fn below(&self, laser: usize) -> Option<usize> {
        self.below.get(laser).copied().flatten().map(usize::from)
    }
}

/// The sub-ray through `(a, b)` radians off the unit direction `d` in its beam frame `(u, w)`.
/// The one formula for the full and the adaptive cast, so that both cast the same rays.
#[inline]
pub(super) fn sub_ray(
    d: &Vector3<f64>,
    u: &Vector3<f64>,
    w: &Vector3<f64>,
    a: f64,
    b: f64,
) -> Vector3<f64> {
    if a == 0.0 && b == 0.0 {
        // The centre sub-ray is the beam's own ray, to the bit (normalising the unit
        // direction again could move it by an ulp): the one ray a beam without divergence
        // casts, and the one an adaptive footprint casts first. So every model casts the same
        // centre rays, and a re-simulation reuses another's hits (reuse.rs).
        return *d;
    }
    (d + u * a + w * b).normalize()
}

/// What the centre ray met, seen from the beam origin: a primitive of the scene, or nothing
/// (sky, or beyond the casting range); and the points known to meet the same.
struct Surface<'a> {
    /// The static geometry's primitives (the centre's hit is one of them, or an actor's).
    prims: &'a [Primitive],
    o: &'a Point3<f64>,
    d: &'a Vector3<f64>,
    u: &'a Vector3<f64>,
    w: &'a Vector3<f64>,
    /// The centre's hit and its point; `None`: the centre ray met nothing.
    hit: Option<(Hit, Point3<f64>)>,
    /// Largest difference between an agreeing witness's range and where the centre hit's
    /// plane puts it, metres.
    tolerance_m: f64,
    half_axes: (f64, f64),
    /// Coordinates of the points that agree, the centre (0, 0) implied.
    points: [(f64, f64); POINTS],
    len: usize,
    /// Directions of the witnesses and cast sub-rays that do not agree: something else is
    /// there, and no sub-ray on that side of the centre (within 90° of one of them) is vouched
    /// for.
    blocked: [(f64, f64); POINTS],
    blocked_len: usize,
    /// The static primitives other than the centre's that agreeing points met (the surface's
    /// neighbouring facets): where a vouched sub-ray passes the centre primitive's edge, the
    /// one of them it meets is its hit.
    facets: [u32; POINTS],
    facets_len: usize,
}

impl<'a> Surface<'a> {
    /// The surface the centre ray from `o` along `d` (beam frame `u`, `w`) met with `hit`,
    /// before any point is known.
    fn new(
        prims: &'a [Primitive],
        (o, d, u, w): (
            &'a Point3<f64>,
            &'a Vector3<f64>,
            &'a Vector3<f64>,
            &'a Vector3<f64>,
        ),
        hit: Option<Hit>,
        tolerance_m: f64,
        half_axes: (f64, f64),
    ) -> Surface<'a> {
        Surface {
            prims,
            o,
            d,
            u,
            w,
            hit: hit.map(|h| (h, o + d * h.range)),
            tolerance_m,
            half_axes,
            points: [(0.0, 0.0); POINTS],
            len: 0,
            blocked: [(0.0, 0.0); POINTS],
            blocked_len: 0,
            facets: [0; POINTS],
            facets_len: 0,
        }
    }

    /// Whether a ray from `origin` along `dir` that met `hit` agrees with the centre (see the
    /// module's documentation): `Ok` with the coordinates of its point (of its direction when
    /// it met nothing), `Err` with those of its direction when it does not; gnomonic, in
    /// footprint half-axes.
    fn agrees(
        &self,
        origin: &Point3<f64>,
        dir: &Vector3<f64>,
        hit: Option<&Hit>,
    ) -> Result<(f64, f64), (f64, f64)> {
        let disagree = || Err(self.coordinates(dir).unwrap_or((0.0, 0.0)));
        let q = match (&self.hit, hit) {
            (None, None) => *dir,
            (Some((h0, p0)), Some(h)) => {
                if h0.primitive.is_none() || h.primitive != h0.primitive {
                    if h.material != h0.material {
                        return disagree();
                    }
                    let n0 = &h0.normal;
                    let den = n0.dot(dir);
                    if den > -1e-9 {
                        return disagree();
                    }
                    let predicted = n0.dot(&(p0 - origin)) / den;
                    if (h.range - predicted).abs() > self.tolerance_m {
                        return disagree();
                    }
                }
                origin + dir * h.range - self.o
            }
            _ => return disagree(),
        };
        self.coordinates(&q).ok_or((0.0, 0.0))
    }

    /// Gnomonic coordinates of the vector `q` from the beam origin, in footprint half-axes
    /// (`None` behind the origin).
    fn coordinates(&self, q: &Vector3<f64>) -> Option<(f64, f64)> {
        let z = q.dot(self.d);
        (z > 0.0).then(|| {
            (
                q.dot(self.u) / z / self.half_axes.0,
                q.dot(self.w) / z / self.half_axes.1,
            )
        })
    }

    fn add(&mut self, p: (f64, f64)) {
        if self.len < POINTS {
            self.points[self.len] = p;
            self.len += 1;
        }
    }

    /// Notes the primitive an agreeing point met, when it is a static one other than the
    /// centre's and not noted yet.
    fn facet(&mut self, hit: Option<&Hit>) {
        let Some(i) = hit.and_then(|h| h.primitive) else {
            return;
        };
        let centre = self.hit.as_ref().and_then(|(h, _)| h.primitive);
        if Some(i) != centre
            && self.facets_len < POINTS
            && !self.facets[..self.facets_len].contains(&i)
        {
            self.facets[self.facets_len] = i;
            self.facets_len += 1;
        }
    }

    fn block(&mut self, p: (f64, f64)) {
        if self.blocked_len < POINTS {
            self.blocked[self.blocked_len] = p;
            self.blocked_len += 1;
        }
    }

    /// Whether the points vouch for `p` (footprint half-axes): points beyond it along its
    /// direction lie on both sides of its line, at most [`LATERAL`] off it (or one lies on it,
    /// within [`ON_LINE`]). Then `p` lies in the triangle of the centre and those two, and an
    /// edge that separated `p` from the centre would separate one of them too. (A hull around
    /// `p` is not enough: the VLS-128's lasers above and below may both fire up to two
    /// half-axes further on, and their hull reached across the lower corner of a wall standing
    /// on the ground they both saw.)
    fn vouches(&self, p: (f64, f64)) -> bool {
        // Squared distances: `hypot`, careful about overflow that cannot happen at a few
        // half-axes, was a tenth of the footprint's time.
        if self.blocked[..self.blocked_len].iter().any(|q| {
            let (a, b) = (q.0 - p.0, q.1 - p.1);
            a * a + b * b <= BLOCKING * BLOCKING
        }) {
            return false;
        }
        let r = (p.0 * p.0 + p.1 * p.1).sqrt();
        let (px, py) = (p.0 / r, p.1 / r);
        let (mut left, mut right) = (false, false);
        for q in &self.points[..self.len] {
            if q.0 * px + q.1 * py < r * (1.0 - 1e-9) {
                continue;
            }
            let lateral = q.0 * py - q.1 * px;
            if lateral.abs() <= ON_LINE {
                return true;
            }
            left |= (-LATERAL..0.0).contains(&lateral);
            right |= (0.0..=LATERAL).contains(&lateral);
        }
        left && right
    }

    /// What the sub-ray `sd` meets: the centre's primitive intersected again (exactly what
    /// the cast's own test of that primitive gives), or, where the sub-ray passes that
    /// primitive's edge, the nearest of the surface's neighbouring facets
    /// ([`Surface::facets`]) that it meets within one range quantum of the centre hit's
    /// plane, or nothing; `None` when that cannot be said (an actor's hit, whose primitive is
    /// in the actor's frame, or the sub-ray meeting none of those primitives there): then it
    /// is cast. (On a VLS-128's 22 s drive through `benches/real_size.py`'s street, a third of
    /// the sub-rays the truth model cast were vouched for but left the centre's triangle.)
    ///
    /// The points that vouch for the sub-ray agree with the centre, so what it meets first
    /// lies on the centre's surface (the module's argument); a facet met there is that
    /// surface, found with the cast's own test of it. Off the plane, a facet is no evidence:
    /// the sub-ray is cast.
    fn predict(&self, sd: &Vector3<f64>, tmax: f64) -> Option<Option<Hit>> {
        let Some((h0, _)) = &self.hit else {
            return Some(None);
        };
        let prim = self.prims.get(h0.primitive? as usize)?;
        if let Some((range, normal)) = prim.intersect(self.o, sd, 0.0, tmax) {
            return Some(Some(Hit {
                range,
                normal,
                ..*h0
            }));
        }
        let mut best: Option<Hit> = None;
        for &i in &self.facets[..self.facets_len] {
            let Some(p) = self.prims.get(i as usize) else {
                continue;
            };
            let limit = best.map_or(tmax, |b| b.range);
            if let Some((range, normal)) = p.intersect(self.o, sd, 0.0, limit) {
                best = Some(Hit {
                    range,
                    normal,
                    material: p.material(),
                    primitive: Some(i),
                });
            }
        }
        // Only where the sub-ray meets it on the centre's plane: a facet that met a point
        // there may bend away from the surface further on (a crease of the mesh, a part that
        // runs on behind the wall), and a sub-ray would meet it behind the true first hit.
        best.filter(|h| self.agrees(self.o, sd, Some(h)).is_ok())
            .map(Some)
    }
}

/// What [`resolve`] did for one footprint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Resolved {
    /// Sub-rays cast (the centre, cast before, not counted).
    pub(super) cast: u32,
    /// Every sub-ray was cast: a witness or a cast sub-ray did not agree.
    pub(super) full: bool,
}

/// The witnesses of a footprint: first the same laser one firing sequence before and after and
/// the lasers above and below in the same sequence; then the lasers above and below in the
/// sequences before and after, which the same sequence's may need beside them to bracket a
/// sub-ray (a laser fires a few µs after another, further on). `None` where the packet has
/// none.
pub(super) type Witnesses<'a> = [Option<&'a CentreRay>; 8];

/// How many of the [`Witnesses`] are looked at for every footprint; the rest only when a
/// sub-ray lacks vouchers.
const FIRST_WITNESSES: usize = 4;

/// One sub-ray: its direction, its hit, and whether that hit was cast.
pub(super) type SubHit = (Vector3<f64>, Option<Hit>, bool);

/// A footprint to resolve: the centre ray (cast), its beam frame, its witnesses.
pub(super) struct Footprint<'a> {
    pub(super) centre: &'a CentreRay,
    pub(super) frame: (&'a Vector3<f64>, &'a Vector3<f64>),
    pub(super) witnesses: &'a Witnesses<'a>,
}

/// Finds the hit of every sub-ray of `pattern` around the footprint's centre: the centre's
/// primitive (or a neighbouring facet, [`Surface::predict`]) intersected again where agreeing
/// witnesses vouch for the sub-ray, cast with `cast` otherwise (within `tmax`, as the cast
/// does). `hits[k]` receives sub-ray `k`; the centre offset (0, 0) takes the centre ray's hit.
/// `prims` is the scene's static geometry, which the centre's hit indexes.
///
/// This is where the adaptive cast decides, and where it can differ from the full cast: a
/// vouched sub-ray misses whatever thin object or corner no witness saw (the module's
/// documentation); on tests/sim_model.rs's scene with four objects thinner than the spacing
/// that changes 0.19 % (VLP-16), 0.10 % (VLS-128) and 0.02 % (HDL-64E) of the returns by more
/// than one range quantum, and nothing at all without them.
#[allow(
    clippy::too_many_arguments,
    reason = "one footprint and the ray loop's state"
)]
pub(super) fn resolve(
    footprint: &Footprint,
    pattern: &Pattern,
    prims: &[Primitive],
    tolerance_m: f64,
    tmax: f64,
    cast: &mut dyn FnMut(&Vector3<f64>) -> Option<Hit>,
    hits: &mut Vec<SubHit>,
) -> Resolved {
    let centre = footprint.centre;
    let (o, d) = (&centre.origin, &centre.direction);
    let (u, w) = footprint.frame;
    hits.clear();
    hits.extend(pattern.offsets.iter().map(|&(a, b)| {
        let on_axis = (a, b) == (0.0, 0.0);
        (
            sub_ray(d, u, w, a, b),
            centre.hit.filter(|_| on_axis),
            on_axis,
        )
    }));
    let mut surface = Surface::new(
        prims,
        (o, d, u, w),
        centre.hit,
        tolerance_m,
        pattern.half_axes,
    );
    // Witnesses that agree become points; those that do not (an edge beside the footprint)
    // block the sub-rays near them.
    let witness = |surface: &mut Surface, ws: &[Option<&CentreRay>]| {
        for c in ws.iter().flatten() {
            match surface.agrees(&c.origin, &c.direction, c.hit.as_ref()) {
                Ok(p) => {
                    surface.add(p);
                    surface.facet(c.hit.as_ref());
                }
                Err(p) => surface.block(p),
            }
        }
    };
    let (first, more) = footprint.witnesses.split_at(FIRST_WITNESSES);
    witness(&mut surface, first);
    let mut more = Some(more);
    let (mut n, mut predicted) = (0, 0);
    for &k in &pattern.outer_first {
        let (sd, _, exact) = hits[k];
        if exact {
            continue;
        }
        let (a, b) = pattern.offsets[k];
        let p = (a / pattern.half_axes.0, b / pattern.half_axes.1);
        let mut vouched = surface.vouches(p);
        if !vouched {
            if let Some(ws) = more.take() {
                witness(&mut surface, ws);
                vouched = surface.vouches(p);
            }
        }
        if vouched {
            if let Some(h) = surface.predict(&sd, tmax) {
                hits[k].1 = h;
                predicted += 1;
                continue;
            }
        }
        let h = cast(&sd);
        n += 1;
        hits[k] = (sd, h, true);
        // Cast and agreeing, it vouches for the inner sub-rays; disagreeing, it blocks them.
        match surface.agrees(o, &sd, h.as_ref()) {
            Ok(_) => {
                surface.add(p);
                surface.facet(h.as_ref());
            }
            Err(_) => surface.block(p),
        }
    }
    Resolved {
        cast: n,
        full: predicted == 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, SurfaceId};

    const WALL: Material = Material {
        reflectivity: 0.5,
        surface: SurfaceId(0),
    };

    /// A centre ray along x onto a small triangle of a wall at x = 10 (primitive 0), and the
    /// surface it sees with the facets `facets` noted.
    fn surface<'a>(
        prims: &'a [Primitive],
        facets: &[u32],
        (origin, frame): (&'a Point3<f64>, &'a [Vector3<f64>; 3]),
    ) -> Surface<'a> {
        let hit = Hit {
            range: 10.0,
            normal: -Vector3::x(),
            material: WALL,
            primitive: Some(0),
        };
        let mut s = Surface::new(
            prims,
            (origin, &frame[0], &frame[1], &frame[2]),
            Some(hit),
            0.002,
            (1.5e-3, 0.75e-3),
        );
        for &f in facets {
            s.facet(Some(&Hit {
                primitive: Some(f),
                ..hit
            }));
        }
        s
    }

    /// A sub-ray that leaves the centre's triangle takes a neighbouring facet it meets on the
    /// centre's plane, with that facet's own test; a facet of the same wall that bends away
    /// behind the plane (a crease of the mesh) is no evidence there, and the sub-ray is cast.
    #[test]
    fn a_facet_counts_only_where_the_sub_ray_meets_it_on_the_centres_plane() {
        let p = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
        let prims: Vec<Primitive> = [
            // The centre's triangle: 2 cm across at x = 10.
            (
                p(10.0, -0.01, -0.01),
                p(10.0, 0.01, -0.01),
                p(10.0, 0.0, 0.01),
            ),
            // A crease: through the plane at y = 0.02, then 10 cm back for every cm aside.
            (p(10.0, 0.02, -1.0), p(10.0, 0.02, 1.0), p(11.0, 0.12, 0.0)),
            // A coplanar neighbour from y = 0.01 to 0.05.
            (p(10.0, 0.01, -0.5), p(10.0, 0.05, -0.5), p(10.0, 0.03, 0.5)),
        ]
        .into_iter()
        .map(|(a, b, c)| Primitive::triangle(a, b, c, WALL).unwrap())
        .collect();
        let frame = [Vector3::x(), Vector3::y(), Vector3::z()];
        let origin = p(0.0, 0.0, 0.0);
        // 4 mrad aside: at y = 0.04, past the centre's triangle.
        let sd = Vector3::new(1.0, 0.004, 0.0).normalize();
        assert!(prims[0]
            .intersect(&p(0.0, 0.0, 0.0), &sd, 0.0, 100.0)
            .is_none());
        // The crease meets the sub-ray 21 cm behind the wall.
        let behind = prims[1]
            .intersect(&p(0.0, 0.0, 0.0), &sd, 0.0, 100.0)
            .unwrap();
        assert!(behind.0 > 10.2, "{behind:?}");
        assert_eq!(
            surface(&prims, &[1], (&origin, &frame)).predict(&sd, 100.0),
            None
        );
        // The coplanar neighbour: its own test, its index.
        let on = surface(&prims, &[1, 2], (&origin, &frame))
            .predict(&sd, 100.0)
            .expect("predicted")
            .expect("a hit");
        let own = prims[2]
            .intersect(&p(0.0, 0.0, 0.0), &sd, 0.0, 100.0)
            .unwrap();
        assert_eq!(on.range.to_bits(), own.0.to_bits());
        assert_eq!(on.primitive, Some(2));
        assert_eq!(on.material, WALL);
    }
}

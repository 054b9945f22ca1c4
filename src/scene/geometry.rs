//! Primitives and the BVH that finds the first one a ray meets.
//!
//! Traversal uses obvhs' compressed wide BVH (CWBVH, 8-wide, SIMD node tests), which works in
//! f32. The primitives themselves are intersected in f64 against the caller's f64 ray: f32 would
//! still be far below the 2 mm range quantum, but f64 makes the analytic tests exact to the
//! quantum without thinking about where the scene's origin is. Boxes are triangles (planar, so
//! exact); cylinders are analytic, because a tessellated cylinder is off by up to
//! `r (1 - cos(π/n))`, which would need thousands of facets to stay below 2 mm.
//!
//! Primitives that span most of the scene (the ground's two triangles) are tested before
//! traversal instead of sitting in every ray's path: their hit bounds the traversal from the
//! start. The BVH's primitives are stored in its leaf order, so a leaf's primitives are
//! neighbours in memory and the BVH's index array is not needed on the way. (An f32 copy of
//! each triangle as a conservative prefilter, our own node test and history-based prefetching
//! were tried against a 20 s VLS-128 drive through an 800k-triangle street: none was faster
//! than obvhs' traversal with these f64 primitives; a cast there is about 8.5 nodes and 3
//! primitive tests and is bound by mispredicted branches and cache misses, not arithmetic.
//! Nor was testing the primitive the same laser hit one firing before, to bound the traversal
//! from the start: 8-11 % slower over a VLS-128 rotation. What helps is sharing the traversal
//! among neighbouring rays: [`Geometry::cast_rays`].)

use glam::UVec2;
use glam::Vec3A;
use nalgebra::{Isometry3, Point3, Vector3};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use obvhs::{Boundable, BvhBuildParams};
use std::time::Duration;

/// Index of an object in the scene: statics first, then actors; ground is [`SurfaceId::GROUND`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SurfaceId(pub u32);

impl SurfaceId {
    /// The ground plane.
    pub const GROUND: SurfaceId = SurfaceId(u32::MAX);
}

/// What a surface is made of, as far as a lidar cares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// Diffuse reflectivity at the lidar wavelength (0..1; above 1 retro-reflective).
    pub reflectivity: f64,
    /// Which object.
    pub surface: SurfaceId,
}

/// A primitive in its BVH's frame.
#[derive(Clone, Debug)]
pub enum Primitive {
    /// A two-sided triangle.
    Triangle {
        /// First vertex.
        v0: Point3<f64>,
        /// v1 - v0.
        e1: Vector3<f64>,
        /// v2 - v0.
        e2: Vector3<f64>,
        /// Unit normal.
        normal: Vector3<f64>,
        /// Material.
        material: Material,
    },
    /// A capped cylinder with its axis along the z axis of `pose` (base centre at its origin).
    Cylinder {
        /// Cylinder frame to BVH frame.
        pose: Isometry3<f64>,
        /// Radius.
        radius: f64,
        /// Height.
        height: f64,
        /// Material.
        material: Material,
    },
}

/// Where a ray met a primitive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray, metres.
    pub range: f64,
    /// Unit surface normal, facing the ray (dot with the ray direction ≤ 0).
    pub normal: Vector3<f64>,
    /// Material.
    pub material: Material,
    /// Which primitive was hit: an index into [`Geometry::primitives`] of the geometry cast
    /// (`Scene::cast` keeps it for the static geometry and clears it for an actor's, whose
    /// primitives are in the actor's frame). Intersecting that primitive again with a nearby
    /// ray gives exactly what a cast would when nothing lies in front of it: the lidar model's
    /// adaptive beam footprint relies on that.
    pub primitive: Option<u32>,
}

// Rounding margin for the f32 boxes around f64 primitives.
const PAD: f32 = 1e-3;

impl Primitive {
    /// A triangle from three vertices; `None` when degenerate.
    pub fn triangle(a: Point3<f64>, b: Point3<f64>, c: Point3<f64>, m: Material) -> Option<Self> {
        let (e1, e2) = (b - a, c - a);
        let n = e1.cross(&e2);
        let len = n.norm();
        (len > 1e-12 && len.is_finite()).then(|| Primitive::Triangle {
            v0: a,
            e1,
            e2,
            normal: n / len,
            material: m,
        })
    }

    /// Distance and normal of the first intersection in `(tmin, tmax)`.
    #[inline]
    pub fn intersect(
        &self,
        o: &Point3<f64>,
        d: &Vector3<f64>,
        tmin: f64,
        tmax: f64,
    ) -> Option<(f64, Vector3<f64>)> {
        match self {
            Primitive::Triangle {
                v0, e1, e2, normal, ..
            } => {
                // Möller–Trumbore, two-sided.
                let p = d.cross(e2);
                let det = e1.dot(&p);
                if det.abs() < 1e-14 {
                    return None;
                }
                let inv = 1.0 / det;
                let s = o - v0;
                let u = s.dot(&p) * inv;
                if !(0.0..=1.0).contains(&u) {
                    return None;
                }
                let q = s.cross(e1);
                let v = d.dot(&q) * inv;
                if v < 0.0 || u + v > 1.0 {
                    return None;
                }
                let t = e2.dot(&q) * inv;
                (t > tmin && t < tmax).then(|| {
                    let n = if normal.dot(d) > 0.0 {
                        -normal
                    } else {
                        *normal
                    };
                    (t, n)
                })
            }
            Primitive::Cylinder {
                pose,
                radius,
                height,
                ..
            } => {
                let lo = pose.inverse_transform_point(o);
                let ld = pose.inverse_transform_vector(d);
                let mut best: Option<(f64, Vector3<f64>)> = None;
                let mut consider = |t: f64, n: Vector3<f64>| {
                    if t > tmin && t < tmax && best.is_none_or(|(b, _)| t < b) {
                        best = Some((t, n));
                    }
                };
                // Side: (ox + t dx)² + (oy + t dy)² = r².
                let a = ld.x * ld.x + ld.y * ld.y;
                if a > 1e-18 {
                    let b = lo.x * ld.x + lo.y * ld.y;
                    let c = lo.x * lo.x + lo.y * lo.y - radius * radius;
                    let disc = b * b - a * c;
                    if disc >= 0.0 {
                        let sq = disc.sqrt();
                        // Numerically stable roots.
                        let q = -(b + b.signum() * sq);
                        let roots = if q != 0.0 { [q / a, c / q] } else { [0.0, 0.0] };
                        for t in roots {
                            let z = lo.z + t * ld.z;
                            if (0.0..=*height).contains(&z) {
                                let p = lo + ld * t;
                                consider(t, Vector3::new(p.x, p.y, 0.0) / *radius);
                            }
                        }
                    }
                }
                // Caps.
                if ld.z.abs() > 1e-18 {
                    for (zc, nz) in [(0.0, -1.0), (*height, 1.0)] {
                        let t = (zc - lo.z) / ld.z;
                        let p = lo + ld * t;
                        if p.x * p.x + p.y * p.y <= radius * radius {
                            consider(t, Vector3::new(0.0, 0.0, nz));
                        }
                    }
                }
                best.map(|(t, n)| {
                    let n = pose.transform_vector(&n);
                    (t, if n.dot(d) > 0.0 { -n } else { n })
                })
            }
        }
    }

    /// The material.
    pub fn material(&self) -> Material {
        match self {
            Primitive::Triangle { material, .. } | Primitive::Cylinder { material, .. } => {
                *material
            }
        }
    }
}

fn v3a(p: &Point3<f64>) -> Vec3A {
    Vec3A::new(p.x as f32, p.y as f32, p.z as f32)
}

/// The eight corners of the box around a capped cylinder (axis along z of `pose`, base centre
/// at its origin), in the frame `pose` maps to: their bounds hold the cylinder however it is
/// turned (four corners miss the rims of a tilted one).
pub fn cylinder_box(pose: &Isometry3<f64>, radius: f64, height: f64) -> [Point3<f64>; 8] {
    std::array::from_fn(|k| {
        let s = |bit: usize| if k & (1 << bit) == 0 { -radius } else { radius };
        let z = if k & 4 == 0 { 0.0 } else { height };
        pose.transform_point(&Point3::new(s(0), s(1), z))
    })
}

impl Boundable for Primitive {
    fn aabb(&self) -> Aabb {
        let mut b = Aabb::empty();
        match self {
            Primitive::Triangle { v0, e1, e2, .. } => {
                for p in [*v0, v0 + e1, v0 + e2] {
                    b.extend(v3a(&p));
                }
            }
            Primitive::Cylinder {
                pose,
                radius,
                height,
                ..
            } => {
                for p in cylinder_box(pose, *radius, *height) {
                    b.extend(v3a(&p));
                }
            }
        }
        Aabb::new(b.min - Vec3A::splat(PAD), b.max + Vec3A::splat(PAD))
    }
}

/// `prims` in the BVH's leaf order: element `k` is `prims[order[k]]`. In place (a scene's
/// primitives are a hundred megabytes at real size) when `order` is a permutation, which it is
/// for a BVH built without splitting primitives; by copying otherwise.
fn leaf_order(mut prims: Vec<Primitive>, order: &[u32]) -> Vec<Primitive> {
    let n = prims.len();
    let mut done = vec![false; n];
    let permutation = order.len() == n
        && order.iter().all(|&i| {
            let seen = done.get_mut(i as usize).map(|d| std::mem::replace(d, true));
            seen == Some(false)
        });
    if !permutation {
        return order.iter().map(|&i| prims[i as usize].clone()).collect();
    }
    done.fill(false);
    // Cycle by cycle: along i -> order[i] -> ..., each slot takes its successor's primitive.
    for i in 0..n {
        let mut j = i;
        while !done[j] {
            done[j] = true;
            let k = order[j] as usize;
            if k == i {
                break;
            }
            prims.swap(j, k);
            j = k;
        }
    }
    prims
}

/// At most this many primitives are taken out of the BVH as spanning the scene.
const MAX_SPANNING: usize = 8;

/// Primitives with their BVH.
pub struct Geometry {
    /// The BVH's primitives in leaf order (slot `i` of the BVH is `prims[i]`), then the
    /// spanning ones.
    prims: Vec<Primitive>,
    /// Where the spanning primitives, tested before traversal, start in `prims`.
    spanning: usize,
    bvh: Option<CwBvh>,
    /// Time the BVH build took.
    pub build_time: Duration,
    bounds: Aabb,
}

impl std::fmt::Debug for Geometry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Geometry")
            .field("primitives", &self.prims.len())
            .field("spanning", &(self.prims.len() - self.spanning))
            .field("build_time", &self.build_time)
            .finish()
    }
}

impl Geometry {
    /// Builds the BVH over `prims`; primitives whose box covers a quarter of the whole
    /// geometry's (by half surface area; the ground) stay out of it, at most
    /// [`MAX_SPANNING`] of them.
    pub fn build(prims: Vec<Primitive>) -> Geometry {
        let start = std::time::Instant::now();
        let mut bounds = Aabb::empty();
        let mut areas = Vec::with_capacity(prims.len());
        for p in &prims {
            let b = p.aabb();
            bounds = bounds.union(&b);
            areas.push(b.half_area());
        }
        let mut by_area: Vec<usize> = (0..prims.len())
            .filter(|&i| areas[i] >= 0.25 * bounds.half_area())
            .collect();
        by_area.sort_by(|&a, &b| areas[b].total_cmp(&areas[a]));
        by_area.truncate(MAX_SPANNING);
        drop(areas);
        let mut is_spanning = vec![false; prims.len()];
        for &i in &by_area {
            is_spanning[i] = true;
        }
        // Spanning primitives in input order (the order ties were decided in before).
        let (mut rest, mut span) = (Vec::with_capacity(prims.len() - by_area.len()), Vec::new());
        for (p, spanning) in prims.into_iter().zip(is_spanning) {
            if spanning {
                span.push(p);
            } else {
                rest.push(p);
            }
        }
        let mut bvh = (!rest.is_empty()).then(|| {
            let mut core = Duration::ZERO;
            obvhs::cwbvh::builder::build_cwbvh(&rest, BvhBuildParams::medium_build(), &mut core)
        });
        if let Some(bvh) = bvh.as_mut() {
            rest = leaf_order(rest, &bvh.primitive_indices);
            // Slot `i` is `prims[i]` now: the index array is no longer needed.
            bvh.primitive_indices = Vec::new();
        }
        let spanning = rest.len();
        rest.extend(span);
        Geometry {
            prims: rest,
            spanning,
            bvh,
            build_time: start.elapsed(),
            bounds,
        }
    }

    /// Number of primitives.
    pub fn len(&self) -> usize {
        self.prims.len()
    }

    /// True without primitives.
    pub fn is_empty(&self) -> bool {
        self.prims.is_empty()
    }

    /// The primitives: the BVH's in leaf order (what keeps a leaf's primitives in one place in
    /// memory), then the spanning ones.
    pub fn primitives(&self) -> &[Primitive] {
        &self.prims
    }

    /// The BVH (for benchmarks that traverse it bare); its primitive slot `i` is
    /// `primitives()[i]`.
    pub fn bvh(&self) -> Option<&CwBvh> {
        self.bvh.as_ref()
    }

    /// Radius of a sphere around the frame origin that holds everything.
    pub fn bounding_radius(&self) -> f64 {
        if self.prims.is_empty() {
            return 0.0;
        }
        let m = self.bounds.min.abs().max(self.bounds.max.abs());
        f64::from(m.length())
    }

    /// The first hit along the unit ray `o + t d`, `t` in `(tmin, tmax)`.
    #[inline]
    pub fn cast(&self, o: &Point3<f64>, d: &Vector3<f64>, tmin: f64, tmax: f64) -> Option<Hit> {
        let mut best: Option<(f64, Vector3<f64>, usize)> = None;
        for (k, p) in self.prims[self.spanning..].iter().enumerate() {
            let limit = best.map_or(tmax, |b| b.0);
            if let Some((t, n)) = p.intersect(o, d, tmin, limit) {
                best = Some((t, n, self.spanning + k));
            }
        }
        if let Some(bvh) = &self.bvh {
            let limit = best.map_or(tmax, |b| b.0);
            // `+ 0.0` turns -0.0 into +0.0: obvhs 0.4 picks the traversal octant from the sign
            // bit but inverts -0.0 to +1/ε, and then misses everything (test
            // `negative_zero_directions`).
            let ray = Ray::new(
                v3a(o),
                Vec3A::new(d.x as f32 + 0.0, d.y as f32 + 0.0, d.z as f32 + 0.0),
                (tmin as f32 - 2.0 * PAD).max(0.0),
                limit as f32 + 2.0 * PAD,
            );
            let mut hit = obvhs::ray::RayHit::none();
            bvh.ray_traverse(ray, &mut hit, |_, slot| {
                let limit = best.map_or(tmax, |b| b.0);
                match self.prims[slot].intersect(o, d, tmin, limit) {
                    Some((t, n)) => {
                        best = Some((t, n, slot));
                        // Keep the f32 bound conservative so nearer boxes are still visited.
                        t as f32 + 2.0 * PAD
                    }
                    None => f32::INFINITY,
                }
            });
        }
        best.map(|(range, normal, i)| self.hit_of(i, (range, normal)))
    }

    /// The [`Hit`] primitive `i` gives at `(range, normal)`: how every cast reports one.
    fn hit_of(&self, i: usize, (range, normal): (f64, Vector3<f64>)) -> Hit {
        Hit {
            range,
            normal,
            material: self.prims[i].material(),
            primitive: u32::try_from(i).ok(),
        }
    }
}

impl Geometry {
    /// The hit of primitive `i` (an index a [`Hit`] of this geometry names) along `o + t d`,
    /// exactly as [`Geometry::cast`] reports it when `i` is the nearest: the same intersection
    /// test of the same ray, so that a ray known to meet `i` first is not traversed again.
    pub fn hit_on(
        &self,
        i: u32,
        o: &Point3<f64>,
        d: &Vector3<f64>,
        tmin: f64,
        tmax: f64,
    ) -> Option<Hit> {
        let at = self.prims.get(i as usize)?.intersect(o, d, tmin, tmax)?;
        Some(self.hit_of(i as usize, at))
    }
}

/// Rays of one [`Geometry::cast_bundle`] traversal at most (more are cast in several).
pub const BUNDLE: usize = 16;

/// One ray of a [`Geometry::cast_rays`] bundle: origin and unit direction.
pub type RaySpec = (Point3<f64>, Vector3<f64>);

impl Geometry {
    /// [`Geometry::cast`] of the unit rays `o + t d` for every `d` in `dirs`, into `out` (same
    /// length): exactly what `cast` finds for each, bit for bit, but in one traversal for rays
    /// that leave `o` into the same octant (a diverging beam's sub-rays, milliradians apart).
    /// See [`Geometry::cast_rays`].
    pub fn cast_bundle(
        &self,
        o: &Point3<f64>,
        dirs: &[Vector3<f64>],
        tmin: f64,
        tmax: f64,
        out: &mut [Option<Hit>],
    ) {
        let mut rays = [(*o, Vector3::zeros()); BUNDLE];
        for (dirs, out) in dirs.chunks(BUNDLE).zip(out.chunks_mut(BUNDLE)) {
            for (r, d) in rays.iter_mut().zip(dirs) {
                r.1 = *d;
            }
            self.cast_few(&rays[..dirs.len()], tmin, tmax, out);
        }
    }

    /// [`Geometry::cast`] of each ray of `rays` (its own origin and unit direction) into `out`
    /// (same length), bit for bit what `cast` finds for each: `rays` are taken [`BUNDLE`] at
    /// a time, and those of a bundle that go into one octant are traversed together. Made for neighbouring firings of a lidar
    /// (adjacent lasers, adjacent azimuths: a degree or less apart, origins millimetres apart),
    /// whose traversals share most of their nodes.
    ///
    /// The bundle enters every node any of its rays enters (the union of their child hit
    /// masks, whose layout depends only on the octant) and each primitive met is tested
    /// exactly for every ray, each keeping its own nearest hit and its own box bound. A ray's
    /// nearest primitive is behind boxes that ray enters itself, so it is found; and the
    /// primitives a ray meets are met in the same depth-first octant order as alone, so even a
    /// tie (two triangles at the same distance: a ray through their shared edge) goes the same
    /// way. The nodes and their memory are shared: one traversal's loads and branches instead
    /// of one per ray.
    pub fn cast_rays(&self, rays: &[RaySpec], tmin: f64, tmax: f64, out: &mut [Option<Hit>]) {
        for (rays, out) in rays.chunks(BUNDLE).zip(out.chunks_mut(BUNDLE)) {
            self.cast_few(rays, tmin, tmax, out);
        }
    }

    /// At most [`BUNDLE`] rays, one traversal per octant among them.
    fn cast_few(&self, rays: &[RaySpec], tmin: f64, tmax: f64, out: &mut [Option<Hit>]) {
        let n = rays.len().min(out.len()).min(BUNDLE);
        let f32_dir = |d: &Vector3<f64>| {
            // `+ 0.0`: see `cast`.
            Vec3A::new(d.x as f32 + 0.0, d.y as f32 + 0.0, d.z as f32 + 0.0)
        };
        let octant = |d: Vec3A| (d.x < 0.0, d.y < 0.0, d.z < 0.0);
        let Some(bvh) = &self.bvh else {
            for ((o, d), h) in rays.iter().zip(out.iter_mut()) {
                *h = self.cast(o, d, tmin, tmax);
            }
            return;
        };
        let mut best: [Option<(f64, Vector3<f64>, usize)>; BUNDLE] = [None; BUNDLE];
        // The spanning primitives first, for every ray: their hits bound the traversal.
        let mut octants = [(false, false, false); BUNDLE];
        for (k, (o, d)) in rays[..n].iter().enumerate() {
            octants[k] = octant(f32_dir(d));
            for (j, p) in self.prims[self.spanning..].iter().enumerate() {
                let limit = best[k].map_or(tmax, |b| b.0);
                if let Some((t, nrm)) = p.intersect(o, d, tmin, limit) {
                    best[k] = Some((t, nrm, self.spanning + j));
                }
            }
        }
        let mut done = [false; BUNDLE];
        let mut group = [Ray::new_inf(Vec3A::ZERO, Vec3A::X); BUNDLE];
        // Which rays traverse together: those into the first remaining ray's octant.
        let mut members = [0usize; BUNDLE];
        for first in 0..n {
            if done[first] {
                continue;
            }
            let mut m = 0;
            for k in first..n {
                if done[k] || octants[k] != octants[first] {
                    continue;
                }
                done[k] = true;
                let limit = best[k].map_or(tmax, |b| b.0);
                group[m] = Ray::new(
                    v3a(&rays[k].0),
                    f32_dir(&rays[k].1),
                    (tmin as f32 - 2.0 * PAD).max(0.0),
                    limit as f32 + 2.0 * PAD,
                );
                members[m] = k;
                m += 1;
            }
            let mut state = bvh.new_traversal(group[0].direction);
            let mut node;
            obvhs::traverse!(
                bvh,
                node,
                state,
                {
                    let mut mask = 0;
                    for ray in &group[..m] {
                        mask |= node.intersect_ray(ray, state.oct_inv4);
                    }
                    mask
                },
                {
                    let slot = state.primitive_id as usize;
                    let prim = &self.prims[slot];
                    for (ray, &k) in group[..m].iter_mut().zip(&members[..m]) {
                        let limit = best[k].map_or(tmax, |b| b.0);
                        let (o, d) = &rays[k];
                        if let Some((t, nrm)) = prim.intersect(o, d, tmin, limit) {
                            best[k] = Some((t, nrm, slot));
                            // Keep the f32 bound conservative (see `cast`).
                            ray.tmax = ray.tmax.min(t as f32 + 2.0 * PAD);
                        }
                    }
                }
            );
        }
        for k in 0..n {
            out[k] = best[k].map(|(range, normal, i)| self.hit_of(i, (range, normal)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const M: Material = Material {
        reflectivity: 0.5,
        surface: SurfaceId(0),
    };

    #[test]
    fn cylinder_side_and_caps() {
        let c = Primitive::Cylinder {
            pose: Isometry3::translation(10.0, 0.0, 0.0),
            radius: 1.0,
            height: 2.0,
            material: M,
        };
        let o = Point3::new(0.0, 0.0, 1.0);
        let (t, n) = c.intersect(&o, &Vector3::x(), 0.0, f64::INFINITY).unwrap();
        assert!((t - 9.0).abs() < 1e-12);
        assert!((n - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-12);
        // From above onto the top cap.
        let (t, n) = c
            .intersect(
                &Point3::new(10.2, 0.1, 5.0),
                &-Vector3::z(),
                0.0,
                f64::INFINITY,
            )
            .unwrap();
        assert!((t - 3.0).abs() < 1e-12);
        assert!((n - Vector3::z()).norm() < 1e-12);
        // Above the top, passing over.
        assert!(c
            .intersect(&Point3::new(0.0, 0.0, 2.5), &Vector3::x(), 0.0, 100.0)
            .is_none());
    }

    /// Triangles facing x at x = 1..49, surface id = x.
    fn stack() -> Vec<Primitive> {
        (1..50u32)
            .filter_map(|k| {
                let x = f64::from(k);
                Primitive::triangle(
                    Point3::new(x, -1.0, -1.0),
                    Point3::new(x, 1.0, -1.0),
                    Point3::new(x, 0.0, 1.0),
                    Material {
                        reflectivity: 0.1,
                        surface: SurfaceId(k),
                    },
                )
            })
            .collect()
    }

    #[test]
    fn bvh_finds_the_nearest_of_many() {
        let g = Geometry::build(stack());
        let h = g
            .cast(&Point3::new(7.5, 0.0, 0.0), &Vector3::x(), 0.0, 1e9)
            .unwrap();
        assert_eq!(h.material.surface, SurfaceId(8));
        assert!((h.range - 0.5).abs() < 1e-12);
        let h = g
            .cast(&Point3::new(7.5, 0.0, 0.0), &-Vector3::x(), 0.0, 1e9)
            .unwrap();
        assert_eq!(h.material.surface, SurfaceId(7));
        assert!(g
            .cast(&Point3::new(7.5, 0.0, 0.0), &Vector3::y(), 0.0, 1e9)
            .is_none());
    }

    #[test]
    fn negative_zero_directions() {
        let g = Geometry::build(stack());
        for d in [
            Vector3::new(-1.0, -0.0, -0.0),
            Vector3::new(1.0, -0.0, -0.0),
        ] {
            let h = g.cast(&Point3::new(7.5, 0.0, 0.0), &d, 0.0, 1e9);
            assert!((h.unwrap().range - 0.5).abs() < 1e-12, "{d:?}");
        }
    }

    /// Large, thin and far primitives (a 2 km wall 0.1 m thick, found by fuzzing): the BVH finds
    /// exactly what brute force over all primitives finds.
    #[test]
    fn bvh_agrees_with_brute_force_on_large_thin_geometry() {
        use rand::{Rng, SeedableRng};
        let mut prims = Vec::new();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let quad = |prims: &mut Vec<Primitive>, c: [f64; 3], a: [f64; 3], b: [f64; 3], k: u32| {
            let p = |u: f64, v: f64| {
                Point3::new(
                    c[0] + u * a[0] + v * b[0],
                    c[1] + u * a[1] + v * b[1],
                    c[2] + u * a[2] + v * b[2],
                )
            };
            let m = Material {
                reflectivity: 0.5,
                surface: SurfaceId(k),
            };
            prims.extend(Primitive::triangle(
                p(0.0, 0.0),
                p(1.0, 0.0),
                p(1.0, 1.0),
                m,
            ));
            prims.extend(Primitive::triangle(
                p(0.0, 0.0),
                p(1.0, 1.0),
                p(0.0, 1.0),
                m,
            ));
        };
        quad(
            &mut prims,
            [20.0, -1001.0, 1.2],
            [0.0, 2002.0, 0.0],
            [0.0, 0.0, 0.1],
            1,
        );
        quad(
            &mut prims,
            [-3000.0, -3000.0, 0.0],
            [6000.0, 0.0, 0.0],
            [0.0, 6000.0, 0.0],
            2,
        );
        for k in 0..200 {
            let c = [
                rng.random_range(-900.0..900.0),
                rng.random_range(-900.0..900.0),
                rng.random_range(0.0..5.0),
            ];
            quad(&mut prims, c, [0.5, 0.0, 0.0], [0.0, 0.0, 1.5], 10 + k);
        }
        let g = Geometry::build(prims.clone());
        for _ in 0..20_000 {
            let o = Point3::new(
                rng.random_range(-500.0..500.0),
                rng.random_range(-500.0..500.0),
                rng.random_range(0.5..3.0),
            );
            let d = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-0.2..0.2),
            )
            .normalize();
            let brute = prims
                .iter()
                .filter_map(|p| p.intersect(&o, &d, 0.0, 5000.0).map(|(t, _)| t))
                .fold(f64::INFINITY, f64::min);
            let got = g
                .cast(&o, &d, 0.0, 5000.0)
                .map_or(f64::INFINITY, |h| h.range);
            assert!(
                got == brute || (got - brute).abs() < 1e-9,
                "{o} {d}: bvh {got} brute {brute}"
            );
        }
    }

    #[test]
    fn leaf_order_permutes_in_place_and_copies_otherwise() {
        let prims = stack();
        let n = prims.len() as u32;
        let id = |p: &Primitive| p.material().surface.0;
        // A permutation of several cycles and fixed points.
        let order: Vec<u32> = (0..n).map(|k| (k * 7 + 3) % n).collect();
        let got: Vec<u32> = leaf_order(prims.clone(), &order).iter().map(id).collect();
        let want: Vec<u32> = order.iter().map(|&k| id(&prims[k as usize])).collect();
        assert_eq!(got, want);
        // Not a permutation (a primitive in two leaves): copied.
        let order = [0, 0, 5, 5, 1];
        let got: Vec<u32> = leaf_order(prims.clone(), &order).iter().map(id).collect();
        assert_eq!(got, vec![1, 1, 6, 6, 2]);
    }

    /// A street at real scale, 500 m from the frame origin: a ground of two large triangles
    /// (kept out of the BVH) and facades either side (y = ±9 m, 60 m long, 6 m high)
    /// tessellated into 20 cm squares, every third one a window recessed 10 cm.
    fn street() -> (Vec<Primitive>, impl Fn(f64, f64, f64) -> Point3<f64>) {
        let (x0, y0) = (500.0, -300.0);
        let p = move |x: f64, y: f64, z: f64| Point3::new(x0 + x, y0 + y, z);
        let m = |k: u32| Material {
            reflectivity: 0.3,
            surface: SurfaceId(k),
        };
        let mut prims = Vec::new();
        let ground = Material {
            reflectivity: 0.1,
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
        let cell = 0.2;
        for (k, side) in [(1u32, 9.0f64), (2, -9.0)] {
            for i in 0..300 {
                for j in 0..30 {
                    let (xa, za) = (-30.0 + f64::from(i) * cell, f64::from(j) * cell);
                    let y = if (i / 3 + j / 3) % 3 == 0 {
                        side + side.signum() * 0.1
                    } else {
                        side
                    };
                    let (a, b) = (p(xa, y, za), p(xa + cell, y, za));
                    let (c, d) = (p(xa + cell, y, za + cell), p(xa, y, za + cell));
                    prims.extend(Primitive::triangle(a, b, c, m(k)));
                    prims.extend(Primitive::triangle(a, c, d, m(k)));
                }
            }
        }
        (prims, p)
    }

    /// The street cast at from a sensor 2 m up in every direction, grazing the ground and the
    /// facades too: the BVH finds exactly the primitive and range brute force finds, bit for
    /// bit.
    #[test]
    fn bvh_agrees_with_brute_force_at_scene_scale() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (prims, p) = street();
        let g = Geometry::build(prims.clone());
        assert_eq!(g.len(), prims.len());
        assert_eq!(
            g.prims.len() - g.spanning,
            2,
            "the ground is tested outside the BVH"
        );
        let mut hits = 0;
        for k in 0..20_000 {
            let o = p(
                rng.random_range(-25.0..25.0),
                rng.random_range(-2.0..2.0),
                2.0,
            );
            let el: f64 = if k % 4 == 0 {
                // Grazing the ground far away.
                rng.random_range(-0.02..0.0)
            } else {
                rng.random_range(-0.5..0.3)
            };
            let az: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let d = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            let brute = prims
                .iter()
                .filter_map(|q| q.intersect(&o, &d, 0.0, 300.0).map(|(t, _)| (t, q)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let got = g.cast(&o, &d, 0.0, 300.0);
            match (got, brute) {
                (None, None) => {}
                (Some(h), Some((t, q))) => {
                    hits += 1;
                    assert_eq!(h.range.to_bits(), t.to_bits(), "{o} {d}");
                    assert_eq!(h.material, q.material(), "{o} {d}");
                }
                (a, b) => panic!("{o} {d}: bvh {a:?}, brute force {:?}", b.map(|b| b.0)),
            }
        }
        assert!(hits > 15_000, "{hits} hits");
    }

    /// Bundles of rays from one origin (a diverging beam's sub-rays, a whole fan, bundles
    /// longer than [`BUNDLE`], rays into several octants, rays along a window's edge), and the
    /// same with an origin of its own for each ray: every ray gets exactly what it gets cast
    /// alone, bit for bit.
    #[test]
    fn bundles_find_what_single_rays_find() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (prims, p) = street();
        let g = Geometry::build(prims);
        let (mut bundled, mut hits) = (0, 0);
        for k in 0..3000 {
            let o = p(
                rng.random_range(-25.0..25.0),
                rng.random_range(-2.0..2.0),
                2.0,
            );
            let el: f64 = rng.random_range(-0.5..0.3);
            let az: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let d = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            let spread = match k % 3 {
                0 => 2e-3,
                1 => 0.2,
                _ => 2.0,
            };
            let n = 1 + k % (2 * BUNDLE + 3);
            let mut dirs: Vec<Vector3<f64>> = (0..n)
                .map(|_| {
                    let j = Vector3::new(
                        rng.random_range(-spread..spread),
                        rng.random_range(-spread..spread),
                        rng.random_range(-spread..spread),
                    );
                    (d + j).normalize()
                })
                .collect();
            if k % 7 == 0 {
                // Straight at a corner of a 20 cm cell: the ray meets two or more triangles'
                // shared edge at one distance.
                let corner = p((k % 50) as f64 * 0.2 - 5.0, 9.0, 1.0);
                dirs.push((corner - o).normalize());
            }
            let mut out = vec![None; dirs.len()];
            g.cast_bundle(&o, &dirs, 0.0, 300.0, &mut out);
            // The same directions from origins apart (a moving sensor's firings, millimetres;
            // a spread of metres too), cast as one set of rays.
            let reach = if k % 2 == 0 { 0.005 } else { 2.0 };
            let rays: Vec<RaySpec> = dirs
                .iter()
                .map(|d| {
                    let j = Vector3::new(
                        rng.random_range(-reach..reach),
                        rng.random_range(-reach..reach),
                        rng.random_range(-reach..reach) * 0.2,
                    );
                    (o + j, *d)
                })
                .collect();
            let mut out_rays = vec![None; rays.len()];
            g.cast_rays(&rays, 0.0, 300.0, &mut out_rays);
            let key = |h: &Option<Hit>| h.map(|h| (h.range.to_bits(), h.normal, h.material));
            for (d, got) in dirs.iter().zip(&out) {
                let alone = g.cast(&o, d, 0.0, 300.0);
                assert_eq!(key(got), key(&alone), "{o} {d}");
                bundled += 1;
                hits += usize::from(alone.is_some());
            }
            for ((o, d), got) in rays.iter().zip(&out_rays) {
                assert_eq!(key(got), key(&g.cast(o, d, 0.0, 300.0)), "{o} {d}");
                bundled += 1;
            }
        }
        assert!(
            bundled > 60_000 && hits > bundled / 4,
            "{bundled} rays, {hits} hits"
        );
    }
}

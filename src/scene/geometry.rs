//! Primitives and the BVH that finds the first one a ray meets.
//!
//! Traversal uses obvhs' compressed wide BVH (CWBVH, 8-wide, SIMD node tests), which works in
//! f32. The primitives themselves are intersected in f64 against the caller's f64 ray: f32 would
//! still be far below the 2 mm range quantum, but f64 makes the analytic tests exact to the
//! quantum without thinking about where the scene's origin is. Boxes are triangles (planar, so
//! exact); cylinders are analytic, because a tessellated cylinder is off by up to
//! `r (1 - cos(π/n))`, which would need thousands of facets to stay below 2 mm.

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
                for &(x, y) in &[(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
                    for z in [0.0, *height] {
                        b.extend(v3a(&pose.transform_point(&Point3::new(
                            x * radius,
                            y * radius,
                            z,
                        ))));
                    }
                }
            }
        }
        Aabb::new(b.min - Vec3A::splat(PAD), b.max + Vec3A::splat(PAD))
    }
}

/// Primitives with their BVH.
pub struct Geometry {
    prims: Vec<Primitive>,
    bvh: Option<CwBvh>,
    /// Time the BVH build took.
    pub build_time: Duration,
    bounds: Aabb,
}

impl std::fmt::Debug for Geometry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Geometry")
            .field("primitives", &self.prims.len())
            .field("build_time", &self.build_time)
            .finish()
    }
}

impl Geometry {
    /// Builds the BVH over `prims`.
    pub fn build(prims: Vec<Primitive>) -> Geometry {
        let start = std::time::Instant::now();
        let mut bounds = Aabb::empty();
        for p in &prims {
            bounds = bounds.union(&p.aabb());
        }
        let bvh = (!prims.is_empty()).then(|| {
            let mut core = Duration::ZERO;
            obvhs::cwbvh::builder::build_cwbvh(&prims, BvhBuildParams::medium_build(), &mut core)
        });
        Geometry {
            prims,
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

    /// The primitives, in input order.
    pub fn primitives(&self) -> &[Primitive] {
        &self.prims
    }

    /// The BVH (for benchmarks that traverse it bare).
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
        let bvh = self.bvh.as_ref()?;
        // `+ 0.0` turns -0.0 into +0.0: obvhs 0.4 picks the traversal octant from the sign bit
        // but inverts -0.0 to +1/ε, and then misses everything (test `negative_zero_directions`).
        let ray = Ray::new(
            v3a(o),
            Vec3A::new(d.x as f32 + 0.0, d.y as f32 + 0.0, d.z as f32 + 0.0),
            (tmin as f32 - 2.0 * PAD).max(0.0),
            tmax as f32 + 2.0 * PAD,
        );
        let mut best: Option<(f64, Vector3<f64>, usize)> = None;
        let mut hit = obvhs::ray::RayHit::none();
        bvh.ray_traverse(ray, &mut hit, |_, id| {
            let index = bvh.primitive_indices[id] as usize;
            let limit = best.map_or(tmax, |b| b.0);
            match self.prims[index].intersect(o, d, tmin, limit) {
                Some((t, n)) => {
                    best = Some((t, n, index));
                    // Keep the f32 bound conservative so nearer boxes are still visited.
                    t as f32 + 2.0 * PAD
                }
                None => f32::INFINITY,
            }
        });
        best.map(|(range, normal, i)| Hit {
            range,
            normal,
            material: self.prims[i].material(),
            primitive: u32::try_from(i).ok(),
        })
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
}

//! Regions of interest: which points a metric looks at. The whole measurement range, one of the
//! scene's objects, or all of them; with or without the ground.

use crate::scene::geometry::Primitive;
use crate::scene::Scene;
use nalgebra::{Point3, Vector3};

/// An axis-aligned box in the scene frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Lowest corner.
    pub min: Point3<f64>,
    /// Highest corner.
    pub max: Point3<f64>,
}

impl Bounds {
    fn empty() -> Bounds {
        Bounds {
            min: Point3::from(Vector3::repeat(f64::INFINITY)),
            max: Point3::from(Vector3::repeat(f64::NEG_INFINITY)),
        }
    }

    fn grow(&mut self, p: &Point3<f64>) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }

    /// Whether `p` lies within the box widened by `margin` on every side.
    pub fn contains(&self, p: &Point3<f64>, margin: f64) -> bool {
        (0..3).all(|i| p[i] >= self.min[i] - margin && p[i] <= self.max[i] + margin)
    }

    /// The box's centre.
    pub fn centre(&self) -> Point3<f64> {
        nalgebra::center(&self.min, &self.max)
    }
}

/// The bounds of every static object of the scene, by name, in the scene's order.
pub fn object_bounds(scene: &Scene) -> Vec<(String, Bounds)> {
    let n = scene.file.objects.len();
    let mut b = vec![Bounds::empty(); n];
    for prim in scene.statics.primitives() {
        let i = prim.material().surface.0 as usize;
        let Some(bounds) = b.get_mut(i) else {
            continue;
        };
        match prim {
            Primitive::Triangle { v0, e1, e2, .. } => {
                for p in [*v0, v0 + e1, v0 + e2] {
                    bounds.grow(&p);
                }
            }
            Primitive::Cylinder {
                pose,
                radius,
                height,
                ..
            } => {
                for (x, y, z) in [
                    (-1.0, -1.0, 0.0),
                    (1.0, 1.0, 1.0),
                    (-1.0, 1.0, 0.0),
                    (1.0, -1.0, 1.0),
                ] {
                    bounds.grow(&(pose * Point3::new(x * radius, y * radius, z * height)));
                }
            }
        }
    }
    scene
        .file
        .objects
        .iter()
        .zip(b)
        .filter(|(_, b)| b.min.x.is_finite())
        .map(|(o, b)| (o.name.clone(), b))
        .collect()
}

/// Which points count.
#[derive(Clone, Debug, PartialEq)]
pub enum Region {
    /// Everything the sensor returned.
    All,
    /// The points on one object (within its bounds widened by the margin).
    Object(String),
    /// The points on any object.
    Objects,
}

/// A region, the object bounds it needs and the ground to leave out.
#[derive(Clone, Debug)]
pub struct Roi {
    region: Region,
    boxes: Vec<(String, Bounds)>,
    /// Points below this height (scene frame) are ground; `None` keeps them.
    ground_below: Option<f64>,
    margin: f64,
}

/// Points closer than this above the ground plane count as ground, m: a VLP-16's range noise
/// (3 cm) and the ground's survey, with room to spare.
pub const GROUND_MARGIN_M: f64 = 0.15;

impl Roi {
    /// A region of `scene` (without a scene only [`Region::All`] is possible). `exclude_ground`
    /// drops the points within [`GROUND_MARGIN_M`] of the scene's ground plane; `margin` widens
    /// the objects' bounds (their survey error and the range noise).
    pub fn new(
        region: Region,
        scene: Option<&Scene>,
        exclude_ground: bool,
        margin: f64,
    ) -> Result<Roi, String> {
        let boxes = scene.map(object_bounds).unwrap_or_default();
        match &region {
            Region::All => {}
            Region::Objects if scene.is_none() => {
                return Err("--roi objects needs the scene (--scene)".into())
            }
            Region::Object(name) if !boxes.iter().any(|(n, _)| n == name) => {
                return Err(format!(
                    "--roi object:{name}: the scene has no object of that name (it has {})",
                    boxes
                        .iter()
                        .map(|(n, _)| n.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            }
            _ => {}
        }
        let ground_below = match (exclude_ground, scene.and_then(|s| s.file.ground)) {
            (false, _) => None,
            (true, Some(g)) => Some(g.z + GROUND_MARGIN_M),
            (true, None) => return Err("ground exclusion needs a scene with a ground".into()),
        };
        Ok(Roi {
            region,
            boxes,
            ground_below,
            margin,
        })
    }

    /// The objects' bounds.
    pub fn boxes(&self) -> &[(String, Bounds)] {
        &self.boxes
    }

    /// Whether a point (scene frame) counts.
    pub fn keeps(&self, p: &Point3<f64>) -> bool {
        if self.ground_below.is_some_and(|z| p.z < z) {
            return false;
        }
        match &self.region {
            Region::All => true,
            Region::Objects => self.boxes.iter().any(|(_, b)| b.contains(p, self.margin)),
            Region::Object(name) => self
                .boxes
                .iter()
                .any(|(n, b)| n == name && b.contains(p, self.margin)),
        }
    }
}

/// As `--roi` takes it (and the reports write it): `all`, `objects`, `object:NAME`.
impl std::fmt::Display for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Region::All => f.write_str("all"),
            Region::Objects => f.write_str("objects"),
            Region::Object(n) => write!(f, "object:{n}"),
        }
    }
}

impl std::str::FromStr for Region {
    type Err = String;
    fn from_str(s: &str) -> Result<Region, String> {
        match s {
            "all" | "range" => Ok(Region::All),
            "objects" => Ok(Region::Objects),
            _ => s
                .strip_prefix("object:")
                .filter(|n| !n.is_empty())
                .map(|n| Region::Object(n.to_owned()))
                .ok_or_else(|| format!("region '{s}': one of all, objects, object:NAME")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Region;

    /// A region reads back from what it writes; `range` is read as `all`; a bare `object:` and
    /// an unknown word are refused.
    #[test]
    fn regions_round_trip_through_their_text() {
        for r in [Region::All, Region::Objects, Region::Object("car 3".into())] {
            assert_eq!(r.to_string().parse::<Region>(), Ok(r));
        }
        assert_eq!("range".parse::<Region>(), Ok(Region::All));
        assert!("object:".parse::<Region>().is_err());
        assert!("cars".parse::<Region>().is_err());
    }
}

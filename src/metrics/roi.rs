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
                // The box the BVH bounds it by (four of its corners, as here once, miss the
                // rims of a tilted cylinder).
                for p in crate::scene::geometry::cylinder_box(pose, *radius, *height) {
                    bounds.grow(&p);
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
    index: BoxIndex,
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
    ) -> Result<Roi, RoiError> {
        let boxes = scene.map(object_bounds).unwrap_or_default();
        match &region {
            Region::All => {}
            Region::Objects if scene.is_none() => return Err(RoiError::ObjectsNeedScene),
            Region::Object(name) if !boxes.iter().any(|(n, _)| n == name) => {
                return Err(RoiError::NoSuchObject {
                    name: name.clone(),
                    known: boxes
                        .iter()
                        .map(|(n, _)| n.as_str())
                        .collect::<Vec<_>>()
                        .join(", "),
                })
            }
            _ => {}
        }
        let ground_below = match (exclude_ground, scene.and_then(|s| s.file.ground)) {
            (false, _) => None,
            (true, Some(g)) => Some(g.z + GROUND_MARGIN_M),
            (true, None) => return Err(RoiError::GroundNeedsScene),
        };
        Ok(Roi {
            region,
            index: BoxIndex::new(&boxes, margin),
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
            Region::Objects => self.boxes_at(p).next().is_some(),
            Region::Object(name) => self.boxes_at(p).any(|i| self.boxes[i].0 == *name),
        }
    }

    /// The indices (into [`Roi::boxes`]) of the boxes that hold `p` within the margin.
    pub fn boxes_at<'a>(&'a self, p: &'a Point3<f64>) -> impl Iterator<Item = usize> + 'a {
        self.index
            .near(p)
            .iter()
            .map(|&i| i as usize)
            .filter(move |&i| self.boxes[i].1.contains(p, self.margin))
    }
}

/// As `--roi` takes it (and the reports write it): `all`, `objects`, `object:NAME`.
/// The boxes near each cell of a grid in the ground plane: a point is tested against the few
/// boxes of its cell, not against every object of the scene (a street has a hundred, and a
/// scan a hundred thousand points).
#[derive(Clone, Debug)]
struct BoxIndex {
    /// Lowest corner of the grid (x, y), m.
    origin: [f64; 2],
    /// Cell edge, m.
    cell: f64,
    /// Cells along x and y.
    size: [usize; 2],
    /// Per cell (row-major in y), where its boxes start in `items`; one more at the end.
    starts: Vec<u32>,
    /// Box indices, cell after cell.
    items: Vec<u32>,
}

/// Cells of the box index at most: 16 MB of starts.
const MAX_INDEX_CELLS: f64 = 4.0e6;

impl BoxIndex {
    fn new(boxes: &[(String, Bounds)], margin: f64) -> BoxIndex {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (_, b) in boxes {
            for k in 0..2 {
                lo[k] = lo[k].min(b.min[k] - margin);
                hi[k] = hi[k].max(b.max[k] + margin);
            }
        }
        if boxes.is_empty() || !(lo[0].is_finite() && hi[0].is_finite()) {
            return BoxIndex {
                origin: [0.0; 2],
                cell: 1.0,
                size: [0, 0],
                starts: vec![0],
                items: Vec::new(),
            };
        }
        let area = ((hi[0] - lo[0]) * (hi[1] - lo[1])).max(1e-6);
        let cell = (area / MAX_INDEX_CELLS).sqrt().max(1.0);
        let size = [
            ((hi[0] - lo[0]) / cell).ceil().max(1.0) as usize,
            ((hi[1] - lo[1]) / cell).ceil().max(1.0) as usize,
        ];
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); size[0] * size[1]];
        for (i, (_, b)) in boxes.iter().enumerate() {
            let a = |v: f64, k: usize| {
                (((v - lo[k]) / cell).floor().max(0.0) as usize).min(size[k] - 1)
            };
            let (x0, x1) = (a(b.min.x - margin, 0), a(b.max.x + margin, 0));
            let (y0, y1) = (a(b.min.y - margin, 1), a(b.max.y + margin, 1));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    lists[y * size[0] + x].push(i as u32);
                }
            }
        }
        let mut starts = Vec::with_capacity(lists.len() + 1);
        let mut items = Vec::new();
        for l in lists {
            starts.push(items.len() as u32);
            items.extend(l);
        }
        starts.push(items.len() as u32);
        BoxIndex {
            origin: lo,
            cell,
            size,
            starts,
            items,
        }
    }

    /// The boxes whose cells hold `p`'s column (a superset of those that hold `p`).
    fn near(&self, p: &Point3<f64>) -> &[u32] {
        let (x, y) = (
            ((p.x - self.origin[0]) / self.cell).floor(),
            ((p.y - self.origin[1]) / self.cell).floor(),
        );
        if !(x >= 0.0 && y >= 0.0 && (x as usize) < self.size[0] && (y as usize) < self.size[1]) {
            return &[];
        }
        let c = y as usize * self.size[0] + x as usize;
        &self.items[self.starts[c] as usize..self.starts[c + 1] as usize]
    }
}

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
    type Err = RoiError;
    fn from_str(s: &str) -> Result<Region, RoiError> {
        match s {
            "all" | "range" => Ok(Region::All),
            "objects" => Ok(Region::Objects),
            _ => s
                .strip_prefix("object:")
                .filter(|n| !n.is_empty())
                .map(|n| Region::Object(n.to_owned()))
                .ok_or_else(|| RoiError::NotARegion(s.to_owned())),
        }
    }
}

/// Why a region cannot be compared in.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RoiError {
    /// Not one of the regions.
    #[error("region '{0}': one of all, objects, object:NAME")]
    NotARegion(String),
    /// The objects' region without a scene.
    #[error("--roi objects needs the scene (--scene)")]
    ObjectsNeedScene,
    /// An object the scene does not have.
    #[error("--roi object:{name}: the scene has no object of that name (it has {known})")]
    NoSuchObject {
        /// The name asked for.
        name: String,
        /// The scene's objects, joined.
        known: String,
    },
    /// Ground exclusion without a ground.
    #[error("ground exclusion needs a scene with a ground")]
    GroundNeedsScene,
}

#[cfg(test)]
mod tests {
    use super::{object_bounds, Bounds, BoxIndex, Region, Roi};
    use crate::scene::file::SceneFile;
    use crate::scene::Scene;
    use nalgebra::Point3;
    use std::path::Path;

    fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
        Point3::new(x, y, z)
    }

    /// An object's bounds hold every point of its surface: a cylinder yawed and tilted, a box
    /// yawed; and they are tight (the extreme surface points lie on them).
    #[test]
    fn object_bounds_hold_every_point_of_a_tilted_cylinder() {
        let text = r#"
            name = "bounds"
            origin = { latitude_deg = 48.0, longitude_deg = 11.0, height_m = 400.0 }
            [[object]]
            name = "pole"
            pose = { x = 10.0, y = -4.0, z = 1.0, yaw_deg = 45.0, pitch_deg = 30.0 }
            reflectivity = 0.5
            parts = [ { shape = "cylinder", radius = 0.5, height = 4.0 } ]
            [[object]]
            name = "box"
            pose = { x = -3.0, y = 2.0, yaw_deg = 30.0 }
            reflectivity = 0.5
            parts = [ { shape = "box", size = [2.0, 1.0, 1.5] } ]
        "#;
        let file: SceneFile = toml::from_str(text).unwrap();
        let scene = Scene::from_file(file, Path::new("."), Path::new("bounds.toml")).unwrap();
        let bounds = object_bounds(&scene);
        assert_eq!(bounds.len(), 2);
        let (name, pole) = &bounds[0];
        assert_eq!(name, "pole");
        // Points on the cylinder's rims and its axis, placed as the scene places it.
        let pose = scene
            .statics
            .primitives()
            .iter()
            .find_map(|q| match q {
                crate::scene::geometry::Primitive::Cylinder { pose, .. } => Some(*pose),
                _ => None,
            })
            .unwrap();
        let (mut lo, mut hi) = (
            p(f64::MAX, f64::MAX, f64::MAX),
            p(f64::MIN, f64::MIN, f64::MIN),
        );
        for i in 0..3600 {
            let a = f64::from(i).to_radians() / 10.0;
            for z in [0.0, 4.0] {
                let q = pose * p(0.5 * a.cos(), 0.5 * a.sin(), z);
                assert!(pole.contains(&q, 1e-9), "{q:?} lies outside {pole:?}");
                lo = lo.inf(&q);
                hi = hi.sup(&q);
            }
        }
        // The box around the cylinder's frame is at most r(√2 - 1) wider than the rims.
        for k in 0..3 {
            assert!(
                lo[k] - pole.min[k] < 0.5 * (2f64.sqrt() - 1.0) + 1e-9
                    && pole.max[k] - hi[k] < 0.5 * (2f64.sqrt() - 1.0) + 1e-9,
                "axis {k}: bounds {pole:?}, surface {lo:?}..{hi:?}"
            );
        }
        // The yawed box: its corners are exactly the bounds' extremes.
        let (_, b) = &bounds[1];
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let half_x = 1.0 * c + 0.5 * s;
        assert!(
            (b.max.x - (-3.0 + half_x)).abs() < 1e-9 && (b.min.x - (-3.0 - half_x)).abs() < 1e-9,
            "box bounds {b:?}"
        );
        assert!(
            (b.max.z - 1.5).abs() < 1e-9 && b.min.z.abs() < 1e-9,
            "{b:?}"
        );
        assert_eq!(b.centre(), p(-3.0, 2.0, 0.75));
    }

    /// The box index finds a point's boxes from any corner of the scene, and nothing for a
    /// point just beyond its last row and column.
    #[test]
    fn the_box_index_finds_boxes_away_from_the_origin_and_nothing_beyond() {
        let boxes = vec![
            (
                "a".to_owned(),
                Bounds {
                    min: p(10.0, 20.0, 0.0),
                    max: p(12.5, 21.5, 1.0),
                },
            ),
            (
                "b".to_owned(),
                Bounds {
                    min: p(12.2, 20.2, 0.0),
                    max: p(12.4, 20.4, 3.0),
                },
            ),
        ];
        let index = BoxIndex::new(&boxes, 0.0);
        assert_eq!(index.near(&p(10.5, 20.5, 0.0)), &[0]);
        assert_eq!(index.near(&p(12.3, 20.3, 0.0)), &[0, 1]);
        // 1 m cells from (10, 20): three columns, two rows; (13.2, 21.2) is in the fourth
        // column of the last row, which does not exist.
        assert!(index.near(&p(13.2, 21.2, 0.0)).is_empty());
        assert!(index.near(&p(9.9, 20.5, 0.0)).is_empty());
        let roi = Roi {
            region: Region::Object("b".into()),
            index,
            boxes,
            ground_below: Some(0.15),
            margin: 0.05,
        };
        assert!(roi.keeps(&p(12.3, 20.3, 2.0)));
        assert!(roi.keeps(&p(12.43, 20.3, 2.0)), "within the margin");
        assert!(!roi.keeps(&p(12.3, 20.3, 0.1)), "ground");
        assert!(!roi.keeps(&p(10.5, 20.5, 0.5)), "on the other object");
        assert_eq!(
            roi.boxes_at(&p(12.3, 20.3, 0.5)).collect::<Vec<_>>(),
            [0, 1]
        );
    }

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

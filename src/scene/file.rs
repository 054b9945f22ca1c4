//! The scene file (TOML): the digital twin of the test site that re-simulation casts rays into.
//!
//! ```toml
//! name = "parking"
//! origin = { latitude_deg = 48.78, longitude_deg = 11.47, height_m = 370.0 }  # WGS84, ENU origin
//!
//! [ground]                  # a horizontal plane; omit for none
//! z = 0.0                   # height in the local frame, metres
//! half_size_m = 150.0       # square extent around the origin
//! reflectivity = 0.15       # diffuse reflectivity at 905 nm, 0..1 (above 1: retro-reflector)
//! accuracy_m = 0.02         # surveyed accuracy, 1 sigma
//!
//! [[object]]                # a static object: one or more parts in the object's frame
//! name = "car 1"
//! pose = { x = 10.0, y = 4.0, yaw_deg = 90.0 }       # object frame in the local frame
//! reflectivity = 0.55
//! accuracy_m = 0.10         # how well the object was surveyed, 1 sigma
//! parts = [
//!   { shape = "box", size = [4.6, 1.8, 0.9], at = { z = 0.3 } },   # centred in x, y; z from its base
//!   { shape = "cylinder", radius = 0.3, height = 1.0 },
//!   { shape = "mesh", file = "car.obj", scale = 1.0, reflectivity = 0.1 },
//! ]
//!
//! [[actor]]                 # a dynamic object: parts as above, moving along a trajectory
//! name = "pedestrian"
//! trajectory = "pedestrian.csv"   # t (s since the Unix epoch, UTC), x, y, z, yaw_deg
//! accuracy_m = 0.15
//! reflectivity = 0.3
//! parts = [ { shape = "cylinder", radius = 0.25, height = 1.75 } ]
//! ```
//!
//! Paths are relative to the scene file. Reflectivity is per object with an optional override per
//! part. Unknown keys are errors, so that a misspelt key never silently changes a simulation.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A WGS84 position: the origin of the scene's local ENU frame.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Wgs84 {
    /// Latitude, degrees north.
    pub latitude_deg: f64,
    /// Longitude, degrees east.
    pub longitude_deg: f64,
    /// Ellipsoidal height, metres.
    pub height_m: f64,
}

/// A placement in a parent frame: translation (metres) and yaw, pitch, roll (degrees, applied
/// as yaw about z, then pitch about y, then roll about x).
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    /// East (or forward in a part's parent), metres.
    #[serde(default)]
    pub x: f64,
    /// North (or left), metres.
    #[serde(default)]
    pub y: f64,
    /// Up, metres.
    #[serde(default)]
    pub z: f64,
    /// Yaw, degrees counter-clockwise about z.
    #[serde(default)]
    pub yaw_deg: f64,
    /// Pitch, degrees about y.
    #[serde(default)]
    pub pitch_deg: f64,
    /// Roll, degrees about x.
    #[serde(default)]
    pub roll_deg: f64,
}

/// The ground plane.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Ground {
    /// Height in the local frame, metres.
    #[serde(default)]
    pub z: f64,
    /// Half the side of the square it covers, metres.
    #[serde(default = "default_half_size")]
    pub half_size_m: f64,
    /// Diffuse reflectivity at the lidar wavelength.
    pub reflectivity: f64,
    /// Surveyed accuracy (1 sigma), metres.
    #[serde(default)]
    pub accuracy_m: f64,
}

fn default_half_size() -> f64 {
    200.0
}

/// The shape of one part.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(tag = "shape", rename_all = "lowercase", deny_unknown_fields)]
pub enum Shape {
    /// A box: `size` = [length along x, width along y, height along z]; the placement is the
    /// centre of its base.
    Box {
        /// Edge lengths, metres.
        size: [f64; 3],
        /// Placement in the object's frame.
        #[serde(default)]
        at: Placement,
        /// Overrides the object's reflectivity.
        #[serde(default)]
        reflectivity: Option<f64>,
    },
    /// A cylinder standing on its base (axis along z), capped at both ends.
    Cylinder {
        /// Radius, metres.
        radius: f64,
        /// Height, metres.
        height: f64,
        /// Placement of the centre of its base.
        #[serde(default)]
        at: Placement,
        /// Overrides the object's reflectivity.
        #[serde(default)]
        reflectivity: Option<f64>,
    },
    /// A triangle mesh from an OBJ or PLY file (by extension), in metres times `scale`.
    Mesh {
        /// The file, relative to the scene file.
        file: PathBuf,
        /// Scale applied to the vertices.
        #[serde(default = "one")]
        scale: f64,
        /// Placement in the object's frame.
        #[serde(default)]
        at: Placement,
        /// Overrides the object's reflectivity.
        #[serde(default)]
        reflectivity: Option<f64>,
    },
}

fn one() -> f64 {
    1.0
}

/// A static object.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectFile {
    /// Name (reports, metrics per object).
    pub name: String,
    /// The object's frame in the local frame.
    #[serde(default)]
    pub pose: Placement,
    /// Diffuse reflectivity at the lidar wavelength (parts may override).
    pub reflectivity: f64,
    /// Surveyed accuracy of the pose, 1 sigma, metres.
    #[serde(default)]
    pub accuracy_m: f64,
    /// Its parts.
    pub parts: Vec<Shape>,
}

/// A moving object.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ActorFile {
    /// Name.
    pub name: String,
    /// CSV trajectory (t, x, y, z, yaw_deg), relative to the scene file.
    pub trajectory: PathBuf,
    /// Accuracy of the trajectory, 1 sigma, metres.
    #[serde(default)]
    pub accuracy_m: f64,
    /// Diffuse reflectivity.
    pub reflectivity: f64,
    /// Parts in the actor's frame (x forward along its heading).
    pub parts: Vec<Shape>,
}

/// The whole file.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Name of the site.
    pub name: String,
    /// WGS84 origin of the local ENU frame.
    pub origin: Wgs84,
    /// Ground plane.
    #[serde(default)]
    pub ground: Option<Ground>,
    /// Static objects.
    #[serde(default, rename = "object")]
    pub objects: Vec<ObjectFile>,
    /// Moving objects.
    #[serde(default, rename = "actor")]
    pub actors: Vec<ActorFile>,
}

//! Per-laser geometry: built in from the manuals, or read from a ros-drivers calibration YAML.
//!
//! The YAML format is the one `velodyne_pointcloud` ships (`lasers: [{laser_id, rot_correction,
//! vert_correction, vert_offset_correction, horiz_offset_correction, dist_correction, ...}]`,
//! angles in radians, lengths in metres), which is also what VeloView's XML converts to. It is the
//! format engineers already have for their individual sensors.

use crate::error::CalibrationError;
use crate::model::Model;
use serde::Deserialize;

/// Geometry of one laser, ready for point computation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaserCalibration {
    /// Elevation in radians.
    pub vertical_rad: f64,
    /// Azimuth correction in radians, ros-drivers sign: the beam points at `azimuth - rot`.
    pub rot_correction_rad: f64,
    /// Vertical offset of the beam origin in metres, ros-drivers semantics (perpendicular to the
    /// beam: shifts z by `vo cos ω` and the horizontal distance by `-vo sin ω`).
    pub vertical_offset_m: f64,
    /// Vertical correction in metres as the Velodyne manuals define it: added to z only. The
    /// built-in VLP-16 and Puck Hi-Res tables carry these (manual table 9-1); calibration files
    /// use `vertical_offset_m` instead.
    pub z_offset_m: f64,
    /// Horizontal offset of the beam origin in metres.
    pub horizontal_offset_m: f64,
    /// Distance added to every measurement in metres.
    pub distance_correction_m: f64,
    /// Ring: index of the laser when sorted by elevation, lowest 0.
    pub ring: u8,
    pub(crate) sin_vert: f64,
    pub(crate) cos_vert: f64,
}

/// A laser beam in the sensor frame (x forward, y left, z up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beam {
    /// Where ranges are measured from, metres.
    pub origin: [f64; 3],
    /// Unit direction.
    pub direction: [f64; 3],
}

/// Sine and cosine of a firing's horizontal angle (azimuth minus the laser's rotation
/// correction), computed in f32 as the decoder always has: the angle is below 2π, so f32 keeps it
/// to ~4e-7 rad (0.04 mm at 100 m), far below the 2 mm range quantum, at about half the cost.
#[inline]
pub fn azimuth_sin_cos(azimuth_hundredths: f64, rot_correction_rad: f64) -> (f64, f64) {
    let a = ((azimuth_hundredths * 0.01).to_radians() - rot_correction_rad) as f32;
    let (s, c) = a.sin_cos();
    (f64::from(s), f64::from(c))
}

/// Geometry of all lasers of one sensor.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// Per laser id.
    pub lasers: Vec<LaserCalibration>,
    /// Metres per distance count.
    pub distance_resolution_m: f64,
}

#[derive(Deserialize)]
struct YamlFile {
    lasers: Vec<YamlLaser>,
    num_lasers: Option<usize>,
    distance_resolution: Option<f64>,
}

// Unknown keys are tolerated here on purpose: ros-drivers files carry intensity fields
// (focal_distance, min_intensity, ...) that do not change geometry.
#[derive(Deserialize)]
struct YamlLaser {
    laser_id: usize,
    #[serde(default)]
    rot_correction: f64,
    vert_correction: f64,
    #[serde(default)]
    vert_offset_correction: f64,
    #[serde(default)]
    horiz_offset_correction: f64,
    #[serde(default)]
    dist_correction: f64,
    #[serde(default)]
    dist_correction_x: Option<f64>,
    #[serde(default)]
    dist_correction_y: Option<f64>,
}

fn laser(vertical_rad: f64, rot: f64, vo: f64, ho: f64, dc: f64) -> LaserCalibration {
    LaserCalibration {
        vertical_rad,
        rot_correction_rad: rot,
        vertical_offset_m: vo,
        z_offset_m: 0.0,
        horizontal_offset_m: ho,
        distance_correction_m: dc,
        ring: 0,
        sin_vert: vertical_rad.sin(),
        cos_vert: vertical_rad.cos(),
    }
}

impl Calibration {
    /// The manual's geometry for a model.
    pub fn builtin(model: Model) -> Calibration {
        let lasers = model
            .laser_specs()
            .iter()
            .map(|s| LaserCalibration {
                z_offset_m: s.vertical_offset_m,
                ..laser(
                    s.vertical_deg.to_radians(),
                    -s.azimuth_offset_deg.to_radians(),
                    0.0,
                    0.0,
                    0.0,
                )
            })
            .collect();
        Calibration::with_rings(lasers, model.distance_resolution_m())
    }

    /// The beam of laser `laser` at `azimuth_hundredths` (hundredths of a degree, the decoder's
    /// interpolated firing azimuth): its origin in the sensor frame and its unit direction. A
    /// return at range `r` along it is the point the decoder computes for the raw distance whose
    /// metres ([`Calibration::metres`]) are `r`. The simulator casts exactly this ray, so that
    /// decoding simulated packets puts every point back on the ray it came from.
    #[inline]
    pub fn beam(&self, laser: usize, azimuth_hundredths: f64) -> Beam {
        let cal = &self.lasers[laser];
        let (sin_a, cos_a) = azimuth_sin_cos(azimuth_hundredths, cal.rot_correction_rad);
        self.beam_at(laser, sin_a, cos_a)
    }

    /// [`Calibration::beam`] from the sine and cosine of the beam's horizontal angle (azimuth
    /// minus the laser's rotation correction), for callers that get them by angle addition.
    #[inline]
    pub fn beam_at(&self, laser: usize, sin_a: f64, cos_a: f64) -> Beam {
        let cal = &self.lasers[laser];
        let (vo, ho) = (cal.vertical_offset_m, cal.horizontal_offset_m);
        Beam {
            origin: [
                -vo * cal.sin_vert * cos_a + ho * sin_a,
                vo * cal.sin_vert * sin_a + ho * cos_a,
                vo * cal.cos_vert + cal.z_offset_m,
            ],
            direction: [cal.cos_vert * cos_a, -cal.cos_vert * sin_a, cal.sin_vert],
        }
    }

    /// Metres a raw distance count stands for on `laser` (resolution and distance correction).
    #[inline]
    pub fn metres(&self, laser: usize, raw: u16) -> f64 {
        f64::from(raw) * self.distance_resolution_m + self.lasers[laser].distance_correction_m
    }

    /// The raw count whose [`Calibration::metres`] is nearest `range_m`; `None` when it does not
    /// fit a count (1..=65535; 0 means no return).
    #[inline]
    pub fn raw_distance(&self, laser: usize, range_m: f64) -> Option<u16> {
        let raw = ((range_m - self.lasers[laser].distance_correction_m)
            / self.distance_resolution_m)
            .round();
        (raw >= 1.0 && raw <= f64::from(u16::MAX)).then_some(raw as u16)
    }

    /// Parses a ros-drivers calibration YAML for a model.
    pub fn from_yaml(text: &str, model: Model) -> Result<Calibration, CalibrationError> {
        let file: YamlFile =
            serde_yaml::from_str(text).map_err(|e| CalibrationError::Yaml(e.to_string()))?;
        let n = file.lasers.len();
        if let Some(declared) = file.num_lasers {
            if declared != n {
                return Err(CalibrationError::Inconsistent(format!(
                    "num_lasers is {declared} but {n} lasers are listed"
                )));
            }
        }
        if n != model.lasers() {
            return Err(CalibrationError::Inconsistent(format!(
                "{n} lasers listed, but a {model} has {}",
                model.lasers()
            )));
        }
        let mut slots: Vec<Option<LaserCalibration>> = vec![None; n];
        for l in &file.lasers {
            if l.laser_id >= n {
                return Err(CalibrationError::Inconsistent(format!(
                    "laser_id {} is out of range 0..{n}",
                    l.laser_id
                )));
            }
            if slots[l.laser_id].is_some() {
                return Err(CalibrationError::Inconsistent(format!(
                    "laser_id {} appears twice",
                    l.laser_id
                )));
            }
            let two_point = [l.dist_correction_x, l.dist_correction_y]
                .iter()
                .any(|v| v.is_some_and(|v| (v - l.dist_correction).abs() > 1e-9 && v != 0.0));
            if two_point {
                return Err(CalibrationError::Unsupported(format!(
                    "two-point distance corrections (dist_correction_x/y) on laser {}",
                    l.laser_id
                )));
            }
            let values = [
                l.rot_correction,
                l.vert_correction,
                l.vert_offset_correction,
                l.horiz_offset_correction,
                l.dist_correction,
            ];
            if values.iter().any(|v| !v.is_finite()) {
                return Err(CalibrationError::Inconsistent(format!(
                    "laser {} has a non-finite value",
                    l.laser_id
                )));
            }
            slots[l.laser_id] = Some(laser(
                l.vert_correction,
                l.rot_correction,
                l.vert_offset_correction,
                l.horiz_offset_correction,
                l.dist_correction,
            ));
        }
        let lasers = slots.into_iter().flatten().collect();
        let res = file
            .distance_resolution
            .unwrap_or(model.distance_resolution_m());
        if !(res > 0.0 && res < 0.1) {
            return Err(CalibrationError::Inconsistent(format!(
                "distance_resolution {res} m is not plausible"
            )));
        }
        Ok(Calibration::with_rings(lasers, res))
    }

    /// Reads a calibration file.
    pub fn from_file(
        path: &std::path::Path,
        model: Model,
    ) -> Result<Calibration, CalibrationError> {
        let text = std::fs::read_to_string(path).map_err(|e| CalibrationError::Io {
            path: path.display().to_string(),
            source: e,
        })?;
        Calibration::from_yaml(&text, model)
    }

    fn with_rings(mut lasers: Vec<LaserCalibration>, distance_resolution_m: f64) -> Calibration {
        let mut order: Vec<usize> = (0..lasers.len()).collect();
        order.sort_by(|&a, &b| lasers[a].vertical_rad.total_cmp(&lasers[b].vertical_rad));
        for (ring, &id) in order.iter().enumerate() {
            lasers[id].ring = ring as u8;
        }
        Calibration {
            lasers,
            distance_resolution_m,
        }
    }

    /// Writes the calibration in the ros-drivers YAML format (angles in radians). Manual-style z
    /// corrections are converted to the format's vertical offsets (see the comment inside).
    pub fn to_yaml(&self) -> String {
        let mut s = format!(
            "distance_resolution: {}\nnum_lasers: {}\nlasers:\n",
            self.distance_resolution_m,
            self.lasers.len()
        );
        for (id, l) in self.lasers.iter().enumerate() {
            s.push_str(&format!(
                "- {{laser_id: {id}, rot_correction: {}, vert_correction: {}, vert_offset_correction: {}, horiz_offset_correction: {}, dist_correction: {}}}\n",
                l.rot_correction_rad,
                l.vertical_rad,
                // A pure z shift has no exact ros-drivers equivalent; vo cos ω = dz keeps z exact
                // and moves the horizontal distance by dz tan ω (up to 3 mm for the VLP-16).
                l.vertical_offset_m + l.z_offset_m / l.cos_vert,
                l.horizontal_offset_m,
                l.distance_correction_m
            ));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_rings_sort_by_elevation() {
        let c = Calibration::builtin(Model::Hdl32e);
        assert_eq!(c.lasers[0].ring, 0); // -30.67°
        assert_eq!(c.lasers[1].ring, 16); // -9.33°
        assert_eq!(c.lasers[31].ring, 31); // +10.67°
        let v = Calibration::builtin(Model::Vlp16);
        assert_eq!(v.lasers[1].ring, 8); // +1°
    }

    #[test]
    fn yaml_round_trips() {
        let c = Calibration::builtin(Model::Vlp32c);
        let back = Calibration::from_yaml(&c.to_yaml(), Model::Vlp32c).unwrap();
        assert_eq!(back.lasers.len(), 32);
        for (a, b) in c.lasers.iter().zip(&back.lasers) {
            assert!((a.vertical_rad - b.vertical_rad).abs() < 1e-12);
            assert!((a.rot_correction_rad - b.rot_correction_rad).abs() < 1e-12);
            assert_eq!(a.ring, b.ring);
        }
    }

    #[test]
    fn wrong_laser_count_is_explained() {
        let c = Calibration::builtin(Model::Vlp16);
        let e = Calibration::from_yaml(&c.to_yaml(), Model::Hdl32e).unwrap_err();
        assert!(
            e.to_string()
                .contains("16 lasers listed, but a hdl32e has 32"),
            "{e}"
        );
    }

    #[test]
    fn duplicate_ids_are_rejected() {
        let mut y = String::from("lasers:\n");
        for id in [0, 0, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15] {
            y.push_str(&format!("- {{laser_id: {id}, vert_correction: 0.{id}}}\n"));
        }
        let e = Calibration::from_yaml(&y, Model::Vlp16).unwrap_err();
        assert!(e.to_string().contains("laser_id 0 appears twice"), "{e}");
    }
}

//! Per-laser geometry: built in from the manuals, or read from the unit's calibration file.
//!
//! Two file formats are read, the two engineers have for their sensors:
//! - ros-drivers YAML, the one `velodyne_pointcloud` ships (`lasers: [{laser_id, rot_correction,
//!   vert_correction, vert_offset_correction, horiz_offset_correction, dist_correction, ...}]`,
//!   angles in radians, lengths in metres);
//! - VeloView XML (`db.xml`, the file Velodyne delivers with each HDL-64E and VeloView ships for
//!   every model: boost-serialized `<DB>` with `<distLSB_>` and `<points_>` of `<px>` lasers,
//!   angles in degrees, lengths in centimetres). ros-drivers' `gen_calibration.py` converts it
//!   to the YAML by exactly those unit changes, and so does this reader.
//!
//! Points follow the ros-drivers and VeloView formulas (the HDL-64E manuals'): the vertical
//! offset moves the beam's origin perpendicular to the beam, the horizontal offset sideways.
//!
//! **Two-point distance correction** (HDL-64E): the far-point correction `dist_correction`
//! holds beyond 25.04 m; nearer, x and y each take a correction interpolated linearly towards
//! the near-point corrections `dist_correction_x` (at |x| = 2.4 m) and `dist_correction_y` (at
//! |y| = 1.93 m), and z takes y's, as ros-drivers' `rawdata.cc` does. A YAML file applies it when
//! it says `two_pt_correction_available: true` (ros-drivers' switch: without it ros-drivers
//! ignores the near-point values, and so does hilrig); an XML file when its near-point values
//! are set and differ from the far one (VeloView's rule). velodyne-decoder applies it only below
//! 25.04 m and gives z the mean of the two; the interop tests measure that difference.

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
    /// Distance added to every measurement in metres (the far-point correction).
    pub distance_correction_m: f64,
    /// Ring: index of the laser when sorted by elevation, lowest 0.
    pub ring: u8,
    pub(crate) sin_vert: f64,
    pub(crate) cos_vert: f64,
}

/// The near-point distance corrections of a two-point calibration (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoPointCorrection {
    /// Correction in metres at |x| = 2.4 m (Velodyne's x: sideways).
    pub x_m: f64,
    /// Correction in metres at |y| = 1.93 m (Velodyne's y: forward).
    pub y_m: f64,
}

/// Where the near-point corrections are given, and where the far one holds (metres): the
/// HDL-64E manual's calibration distances, as ros-drivers and VeloView use them.
const NEAR_X_M: f64 = 2.4;
const NEAR_Y_M: f64 = 1.93;
const FAR_M: f64 = 25.04;

impl TwoPointCorrection {
    /// The corrections to add to a distance that already carries the far-point correction
    /// `far_m`, for a point whose Velodyne-frame |x| and |y| (sideways and forward) are `xx`
    /// and `yy`: (for x, for y and z). Linear in |x| and |y| between the near and far points,
    /// and beyond them, as ros-drivers computes it.
    #[inline]
    pub fn corrections(&self, far_m: f64, xx: f64, yy: f64) -> (f64, f64) {
        let cx = (far_m - self.x_m) * (xx - NEAR_X_M) / (FAR_M - NEAR_X_M) + self.x_m - far_m;
        let cy = (far_m - self.y_m) * (yy - NEAR_Y_M) / (FAR_M - NEAR_Y_M) + self.y_m - far_m;
        (cx, cy)
    }
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
    /// The HDL-64E's near-point corrections per laser id, where the file has them and asks for
    /// them; empty when no laser has one. Kept apart from [`LaserCalibration`] so that the
    /// common decoding path stays as small as it was (the decoder applies them in a second pass
    /// over the points of the lasers that have them).
    pub two_point: Vec<Option<TwoPointCorrection>>,
}

#[derive(Deserialize)]
struct YamlFile {
    lasers: Vec<YamlLaser>,
    num_lasers: Option<usize>,
    distance_resolution: Option<f64>,
}

/// One laser as a file gives it, in metres and radians (both formats end up here).
struct FileLaser {
    laser_id: usize,
    rot_correction: f64,
    vert_correction: f64,
    vert_offset_correction: f64,
    horiz_offset_correction: f64,
    dist_correction: f64,
    two_point: Option<TwoPointCorrection>,
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
    #[serde(default)]
    two_pt_correction_available: bool,
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
        Calibration::with_rings(lasers, model.distance_resolution_m(), Vec::new())
    }

    /// The beam of laser `laser` at `azimuth_hundredths` (hundredths of a degree, the decoder's
    /// interpolated firing azimuth): its origin in the sensor frame and its unit direction. A
    /// return at range `r` along it is the point the decoder computes for the raw distance whose
    /// metres ([`Calibration::metres`]) are `r`. The simulator casts exactly this ray, so that
    /// decoding simulated packets puts every point back on the ray it came from. (Except for a
    /// two-point calibration's near-range terms, which one raw count cannot undo for x and y at
    /// once: within 25 m such a laser's points sit up to the difference of its near and far
    /// corrections off the ray.)
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
        let mut lasers = Vec::with_capacity(file.lasers.len());
        for l in &file.lasers {
            let two_point = if l.two_pt_correction_available {
                match (l.dist_correction_x, l.dist_correction_y) {
                    (Some(x_m), Some(y_m)) => Some(TwoPointCorrection { x_m, y_m }),
                    _ => {
                        return Err(CalibrationError::Inconsistent(format!(
                            "laser {} asks for the two-point correction but lacks dist_correction_x or dist_correction_y",
                            l.laser_id
                        )))
                    }
                }
            } else {
                None
            };
            lasers.push(FileLaser {
                laser_id: l.laser_id,
                rot_correction: l.rot_correction,
                vert_correction: l.vert_correction,
                vert_offset_correction: l.vert_offset_correction,
                horiz_offset_correction: l.horiz_offset_correction,
                dist_correction: l.dist_correction,
                two_point,
            });
        }
        Calibration::from_file_lasers(&lasers, file.num_lasers, file.distance_resolution, model)
    }

    /// Parses a VeloView XML calibration (`db.xml`) for a model: degrees and centimetres,
    /// converted as ros-drivers' `gen_calibration.py` converts them.
    pub fn from_veloview_xml(text: &str, model: Model) -> Result<Calibration, CalibrationError> {
        // VeloView's files start with `<!DOCTYPE boost_serialization>`; roxmltree never
        // fetches external entities, so allowing the declaration is safe.
        let options = roxmltree::ParsingOptions {
            allow_dtd: true,
            ..roxmltree::ParsingOptions::default()
        };
        let doc = roxmltree::Document::parse_with_options(text, options)
            .map_err(|e| CalibrationError::Xml(e.to_string()))?;
        let bad = |m: String| CalibrationError::Xml(m);
        let number = |node: roxmltree::Node, what: &str| -> Result<f64, CalibrationError> {
            let t = node.text().unwrap_or("").trim();
            t.parse::<f64>().map_err(|_| {
                bad(format!(
                    "<{what}> holds {t:?}, not a number (line {})",
                    doc.text_pos_at(node.range().start).row
                ))
            })
        };
        let resolution = match doc.descendants().find(|n| n.has_tag_name("distLSB_")) {
            Some(n) => Some(number(n, "distLSB_")? * 0.01),
            None => None,
        };
        let mut lasers = Vec::new();
        for px in doc.descendants().filter(|n| n.has_tag_name("px")) {
            let field = |tag: &str| -> Result<Option<f64>, CalibrationError> {
                match px.children().find(|c| c.has_tag_name(tag)) {
                    Some(n) => number(n, tag).map(Some),
                    None => Ok(None),
                }
            };
            let line = doc.text_pos_at(px.range().start).row;
            let id =
                field("id_")?.ok_or_else(|| bad(format!("a <px> without <id_> (line {line})")))?;
            if !(id >= 0.0 && id.fract() == 0.0 && id < 1024.0) {
                return Err(bad(format!(
                    "<id_> {id} is not a laser number (line {line})"
                )));
            }
            let vert = field("vertCorrection_")?
                .ok_or_else(|| bad(format!("laser {id} has no <vertCorrection_> (line {line})")))?;
            let cm = |tag: &str| -> Result<f64, CalibrationError> {
                Ok(field(tag)?.unwrap_or(0.0) * 0.01)
            };
            let dc = cm("distCorrection_")?;
            let (dcx, dcy) = (cm("distCorrectionX_")?, cm("distCorrectionY_")?);
            let two_point = ((dcx != 0.0 || dcy != 0.0) && (dcx != dc || dcy != dc))
                .then_some(TwoPointCorrection { x_m: dcx, y_m: dcy });
            lasers.push(FileLaser {
                laser_id: id as usize,
                rot_correction: field("rotCorrection_")?.unwrap_or(0.0).to_radians(),
                vert_correction: vert.to_radians(),
                vert_offset_correction: cm("vertOffsetCorrection_")?,
                horiz_offset_correction: cm("horizOffsetCorrection_")?,
                dist_correction: dc,
                two_point,
            });
        }
        if lasers.is_empty() {
            return Err(bad(
                "no <px> lasers found (expected <DB><points_><item><px>...)".into(),
            ));
        }
        Calibration::from_file_lasers(&lasers, None, resolution, model)
    }

    /// Checks a file's lasers against the model and builds the calibration.
    fn from_file_lasers(
        file: &[FileLaser],
        declared: Option<usize>,
        resolution: Option<f64>,
        model: Model,
    ) -> Result<Calibration, CalibrationError> {
        let n = file.len();
        if let Some(declared) = declared {
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
        let mut two_point: Vec<Option<TwoPointCorrection>> = vec![None; n];
        for l in file {
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
            let tp = l.two_point.map_or([0.0; 2], |t| [t.x_m, t.y_m]);
            let values = [
                l.rot_correction,
                l.vert_correction,
                l.vert_offset_correction,
                l.horiz_offset_correction,
                l.dist_correction,
                tp[0],
                tp[1],
            ];
            if values.iter().any(|v| !v.is_finite() || v.abs() > 1e3) {
                return Err(CalibrationError::Inconsistent(format!(
                    "laser {} has a value that is not finite or not plausible",
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
            two_point[l.laser_id] = l.two_point;
        }
        let lasers = slots.into_iter().flatten().collect();
        let res = resolution.unwrap_or(model.distance_resolution_m());
        if !(res > 0.0 && res < 0.1) {
            return Err(CalibrationError::Inconsistent(format!(
                "distance_resolution {res} m is not plausible"
            )));
        }
        if two_point.iter().all(Option::is_none) {
            two_point.clear();
        }
        Ok(Calibration::with_rings(lasers, res, two_point))
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
        Calibration::from_text(&text, model)
    }

    /// Parses a calibration file's text, VeloView XML or ros-drivers YAML, told apart by their
    /// first character (`<` starts every XML document; YAML cannot start with it).
    pub fn from_text(text: &str, model: Model) -> Result<Calibration, CalibrationError> {
        if text
            .trim_start_matches('\u{feff}')
            .trim_start()
            .starts_with('<')
        {
            Calibration::from_veloview_xml(text, model)
        } else {
            Calibration::from_yaml(text, model)
        }
    }

    fn with_rings(
        mut lasers: Vec<LaserCalibration>,
        distance_resolution_m: f64,
        two_point: Vec<Option<TwoPointCorrection>>,
    ) -> Calibration {
        let mut order: Vec<usize> = (0..lasers.len()).collect();
        order.sort_by(|&a, &b| lasers[a].vertical_rad.total_cmp(&lasers[b].vertical_rad));
        for (ring, &id) in order.iter().enumerate() {
            lasers[id].ring = ring as u8;
        }
        Calibration {
            lasers,
            distance_resolution_m,
            two_point,
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
            let two_point = self.two_point.get(id).copied().flatten().map_or(String::new(), |t| {
                format!(
                    ", dist_correction_x: {}, dist_correction_y: {}, two_pt_correction_available: true",
                    t.x_m, t.y_m
                )
            });
            s.push_str(&format!(
                "- {{laser_id: {id}, rot_correction: {}, vert_correction: {}, vert_offset_correction: {}, horiz_offset_correction: {}, dist_correction: {}{two_point}}}\n",
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

    /// A calibration written as VeloView writes `db.xml` (degrees, centimetres).
    fn veloview_xml(c: &Calibration) -> String {
        let mut s = format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\" standalone=\"yes\" ?>\n<!DOCTYPE boost_serialization>\n<boost_serialization signature=\"serialization::archive\" version=\"4\">\n<DB class_id=\"0\" tracking_level=\"0\" version=\"0\">\n\t<distLSB_>{}</distLSB_>\n\t<points_ class_id=\"5\" tracking_level=\"0\" version=\"0\">\n\t\t<count>{}</count>\n",
            c.distance_resolution_m * 100.0,
            c.lasers.len()
        );
        for (id, l) in c.lasers.iter().enumerate() {
            let (x, y) = c
                .two_point
                .get(id)
                .copied()
                .flatten()
                .map_or((0.0, 0.0), |t| (t.x_m, t.y_m));
            s.push_str(&format!(
                "\t\t<item><px><id_>{id}</id_><rotCorrection_>{}</rotCorrection_><vertCorrection_>{}</vertCorrection_><distCorrection_>{}</distCorrection_><distCorrectionX_>{}</distCorrectionX_><distCorrectionY_>{}</distCorrectionY_><vertOffsetCorrection_>{}</vertOffsetCorrection_><horizOffsetCorrection_>{}</horizOffsetCorrection_><focalDistance_>0</focalDistance_><focalSlope_>0</focalSlope_></px></item>\n",
                l.rot_correction_rad.to_degrees(),
                l.vertical_rad.to_degrees(),
                l.distance_correction_m * 100.0,
                x * 100.0,
                y * 100.0,
                l.vertical_offset_m * 100.0,
                l.horizontal_offset_m * 100.0,
            ));
        }
        s + "\t</points_>\n</DB>\n</boost_serialization>\n"
    }

    /// An HDL-64E calibration as real units have them: offsets of centimetres, far corrections
    /// over a metre, near-point corrections a few centimetres off the far one.
    fn real_looking_64e() -> Calibration {
        let mut c = Calibration::builtin(Model::Hdl64eS3);
        let mut two_point = Vec::new();
        for (i, l) in c.lasers.iter_mut().enumerate() {
            let k = i as f64;
            l.rot_correction_rad = 0.08 * (0.7 * k).sin();
            l.vertical_offset_m = 0.2 + 0.01 * (0.3 * k).cos();
            l.horizontal_offset_m = if i % 2 == 0 { 0.026 } else { -0.026 };
            l.distance_correction_m = 1.3 + 0.1 * (0.9 * k).sin();
            two_point.push(Some(TwoPointCorrection {
                x_m: l.distance_correction_m + 0.04 * (1.1 * k).cos(),
                y_m: l.distance_correction_m - 0.03 * (0.5 * k).sin(),
            }));
        }
        c.two_point = two_point;
        c
    }

    #[test]
    fn veloview_xml_reads_as_its_yaml_conversion() {
        let c = real_looking_64e();
        let xml = Calibration::from_text(&veloview_xml(&c), Model::Hdl64eS3).unwrap();
        let yaml = Calibration::from_text(&c.to_yaml(), Model::Hdl64eS3).unwrap();
        assert_eq!(xml.lasers.len(), 64);
        assert!((xml.distance_resolution_m - 0.002).abs() < 1e-12);
        for (i, ((a, b), o)) in xml
            .lasers
            .iter()
            .zip(&yaml.lasers)
            .zip(&c.lasers)
            .enumerate()
        {
            let tp = |c: &Calibration| c.two_point[i].unwrap();
            for (u, v) in [
                (a.vertical_rad, o.vertical_rad),
                (a.rot_correction_rad, o.rot_correction_rad),
                (a.vertical_offset_m, o.vertical_offset_m),
                (a.horizontal_offset_m, o.horizontal_offset_m),
                (a.distance_correction_m, o.distance_correction_m),
                (tp(&xml).x_m, tp(&c).x_m),
                (tp(&xml).y_m, tp(&yaml).y_m),
                (b.vertical_offset_m, o.vertical_offset_m),
            ] {
                assert!((u - v).abs() < 1e-9, "{u} vs {v}");
            }
            assert_eq!(a.ring, b.ring);
        }
    }

    #[test]
    fn two_point_is_applied_only_where_the_file_asks() {
        let c = real_looking_64e();
        // ros-drivers' switch: near-point values without `two_pt_correction_available` are
        // ignored.
        let no_switch = c
            .to_yaml()
            .replace(", two_pt_correction_available: true", "");
        let y = Calibration::from_yaml(&no_switch, Model::Hdl64eS3).unwrap();
        assert!(y.two_point.is_empty());
        // VeloView's rule: near-point values equal to the far one (or zero) are no correction.
        let mut flat = c.clone();
        flat.two_point = flat
            .lasers
            .iter()
            .map(|l| {
                Some(TwoPointCorrection {
                    x_m: l.distance_correction_m,
                    y_m: l.distance_correction_m,
                })
            })
            .collect();
        let x = Calibration::from_veloview_xml(&veloview_xml(&flat), Model::Hdl64eS3).unwrap();
        assert!(x.two_point.is_empty());
        let half = no_switch.replacen(
            "dist_correction_x",
            "two_pt_correction_available: true, unused",
            1,
        );
        let e = Calibration::from_yaml(&half, Model::Hdl64eS3).unwrap_err();
        assert!(e.to_string().contains("lacks dist_correction_x"), "{e}");
    }

    #[test]
    fn two_point_corrections_hold_at_the_near_and_far_points() {
        let t = TwoPointCorrection {
            x_m: 1.25,
            y_m: 1.31,
        };
        let far = 1.28;
        let (cx, cy) = t.corrections(far, NEAR_X_M, NEAR_Y_M);
        assert!((far + cx - 1.25).abs() < 1e-12 && (far + cy - 1.31).abs() < 1e-12);
        let (cx, cy) = t.corrections(far, FAR_M, FAR_M);
        assert!(cx.abs() < 1e-12 && cy.abs() < 1e-12);
        // Linear beyond the far point, as ros-drivers extrapolates.
        let (cx, _) = t.corrections(far, 2.0 * FAR_M - NEAR_X_M, 0.0);
        assert!((cx - (far - 1.25)).abs() < 1e-12);
    }

    #[test]
    fn bad_xml_says_what_and_where() {
        let c = real_looking_64e();
        let xml = veloview_xml(&c);
        let e = Calibration::from_text(
            &xml.replacen("<vertCorrection_>", "<vertCorrection_>x", 1),
            Model::Hdl64eS3,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("<vertCorrection_> holds") && e.to_string().contains("line 8"),
            "{e}"
        );
        let e = Calibration::from_text("<DB><distLSB_>0.2</distLSB_></DB>", Model::Hdl64eS3)
            .unwrap_err();
        assert!(e.to_string().contains("no <px> lasers"), "{e}");
        let e = Calibration::from_text("<DB><points_>", Model::Hdl64eS3).unwrap_err();
        assert!(e.to_string().contains("not a VeloView XML file"), "{e}");
        let e = Calibration::from_text(
            &xml.replace("<id_>63</id_>", "<id_>3</id_>"),
            Model::Hdl64eS3,
        )
        .unwrap_err();
        assert!(e.to_string().contains("laser_id 3 appears twice"), "{e}");
        let e = Calibration::from_text(&xml, Model::Vlp32a).unwrap_err();
        assert!(
            e.to_string()
                .contains("64 lasers listed, but a vlp32a has 32"),
            "{e}"
        );
    }

    use proptest::prelude::*;

    proptest! {
        /// Any text built from calibration-file pieces (XML tags and YAML keys with any
        /// numbers, cut anywhere) reads as a calibration or an error, never a panic; a
        /// calibration read has one laser per id and finite values.
        #[test]
        fn any_calibration_text_reads_or_errors(
            pieces in proptest::collection::vec(
                prop_oneof![
                    Just("<DB>".to_string()),
                    Just("<points_><item><px>".to_string()),
                    Just("</px></item>".to_string()),
                    Just("lasers:\n".to_string()),
                    (0usize..70).prop_map(|i| format!("<id_>{i}</id_>")),
                    (0usize..70).prop_map(|i| format!("- {{laser_id: {i}, vert_correction: 0.1}}\n")),
                    proptest::num::f64::ANY.prop_map(|v| format!("<vertCorrection_>{v}</vertCorrection_>")),
                    proptest::num::f64::ANY.prop_map(|v| format!("<distCorrectionX_>{v}</distCorrectionX_>")),
                    proptest::num::f64::ANY.prop_map(|v| format!("<distLSB_>{v}</distLSB_>")),
                    "[ -~]{0,12}",
                ],
                0..80,
            ),
            cut in 0usize..4000,
        ) {
            let text: String = pieces.concat();
            let text = &text[..text.floor_char_boundary(cut.min(text.len()))];
            for model in [Model::Vlp16, Model::Hdl64eS3] {
                if let Ok(c) = Calibration::from_text(text, model) {
                    prop_assert_eq!(c.lasers.len(), model.lasers());
                    prop_assert!(c.lasers.iter().all(|l| l.vertical_rad.is_finite()));
                }
            }
        }
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

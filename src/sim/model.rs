//! The lidar model file (`model.toml`): the idealized model of Rosenberger et al. 2019, Table 1 plus a list of named
//! effects, each with its parameters. The gap workflow adds effects to this list one at a time.
//!
//! ```toml
//! name = "vlp16-truth"
//! description = "what this model is for"
//!
//! [limits]                 # optional; defaults from the sensor's specification sheet
//! min_range_m = 0.5
//! max_range_m = 100.0
//!
//! [[effect]]
//! name = "range_noise"
//! sigma_m = 0.012
//!
//! [[effect]]
//! name = "detection_threshold"
//! reference_range_m = 100.0
//! reference_reflectivity = 0.10
//! ```
//!
//! Each effect may appear once. Unknown names and keys are errors.

pub use crate::sim::pattern::{
    footprint_grid, footprint_stratified, FootprintPattern, STRATIFIED_MAX_PER_AXIS,
};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Range limits of the idealized model.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Returns nearer than this are not reported (the sensor's blind zone), metres.
    pub min_range_m: Option<f64>,
    /// Returns beyond this are not reported, metres (default: the model's specification).
    pub max_range_m: Option<f64>,
}

/// One effect of the catalogue. Documentation says what it does, its parameters, and where the
/// phenomenon and its typical values come from.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(tag = "name", rename_all = "snake_case", deny_unknown_fields)]
pub enum Effect {
    /// Zero-mean Gaussian noise on every range. Source: the range accuracy of the Velodyne
    /// specification sheets ("±3 cm typical" for VLP-16/VLP-32C, taken as about 2σ);
    /// Rosenberger et al. 2019, Table 1 lists noise as the first phenomenological effect.
    RangeNoise {
        /// Standard deviation, metres.
        sigma_m: f64,
    },
    /// A constant added to every range (an uncalibrated distance offset). Source: per-laser
    /// `dist_correction` of Velodyne calibration files, which exists because such biases occur.
    RangeBias {
        /// Bias, metres (positive: farther).
        bias_m: f64,
    },
    /// Each firing is lost with a fixed probability, independent of the target (random
    /// detection failures). Source: Rosenberger et al. 2019, Table 1 (detection probability).
    RandomDropout {
        /// Probability that a firing reports nothing.
        probability: f64,
    },
    /// Received power against a detection threshold. For an extended Lambertian target the lidar
    /// equation gives P ∝ ρ cos θ / R² (ρ reflectivity, θ incidence angle, R range; beam
    /// entirely on the target), times the two-way atmospheric transmission. A target of
    /// `reference_reflectivity` at normal incidence is detected up to `reference_range_m`, so a
    /// target ρ, θ reaches `reference_range_m · sqrt(ρ cos θ / reference_reflectivity)`: dark
    /// objects vanish at long range. Source: the lidar range equation (Jelalian, "Laser Radar
    /// Systems", 1992) and the specification sheets' "range at 10 % reflectivity".
    DetectionThreshold {
        /// Range at which the reference target is still detected, metres.
        reference_range_m: f64,
        /// Reflectivity of that reference target.
        reference_reflectivity: f64,
    },
    /// The beam is a cone, not a line: sub-rays across the elliptical footprint share its
    /// power, the points of a `sub_rays_per_axis`² grid that lie inside the ellipse
    /// ([`footprint_grid`]: 5 for 3 per axis, 13 for 5). Sub-ray hits within `range_separation_m` merge into one echo at
    /// their power-weighted mean range (mixed returns between a foreground edge and what lies
    /// behind); farther apart they are separate echoes (strongest and last). A surface at
    /// grazing incidence is one echo however much range its part spans (its sub-rays merge
    /// across gaps up to the range a sub-ray's share spans on it, `R δ tan θ`): its pulse is
    /// continuous, only a gap in depth separates echoes. A partial footprint
    /// gives an edge return with less power. Source: specification sheets (VLP-16: 3.0 mrad
    /// horizontal, 1.5 mrad vertical divergence); mixed pixels in Hebert & Krotkov 1992.
    ///
    /// **How it is cast, and its tolerance.** Most footprints lie on one surface, and casting
    /// each sub-ray there (five rays a firing for 3 per axis) is wasted. The simulator casts
    /// every firing's centre ray first; a sub-ray's hit is then the primitive the centre ray
    /// met, intersected again (the cast's own arithmetic, so the same to 1e-9 m), where the
    /// neighbouring firings' centre rays (the same laser one firing sequence before and after,
    /// the lasers above and below) met that primitive, or the same material within one range
    /// quantum of its plane, beyond the sub-ray on both sides of it, and none near it met
    /// anything else; elsewhere (edges, sky on one side, a packet's boundary) the sub-ray is
    /// cast (src/sim/lidar/footprint.rs). Dual-return VLS-128 packets, one firing sequence
    /// without neighbours, are cast in full. The result equals casting every sub-ray
    /// ([`crate::sim::lidar::FootprintCast::Full`]) to 1e-9 m, except where an object
    /// narrower than the firings' spacing (across: 3.5 mrad at 600 rpm, 3.5 cm at 10 m; along
    /// elevation the lasers' spacing, 35 mrad on the VLP-16, about 15 on the VLS-128) lies
    /// between the centre rays and inside a footprint, or an object's corner reaches within a
    /// half-axis of a sub-ray unseen: there the full cast reports its partial echo, the
    /// adaptive cast what lies behind it. Measured in tests/sim_model.rs on one rotation of a
    /// scene of boxes, cylinders and a mesh: byte-identical packets (VLP-16, VLS-128,
    /// HDL-64E, single and dual return), range noise and every random draw included; with four
    /// such objects added (poles 1 and 2 cm thick at 12 and 20 m, a 12 mm wire, a 2 cm bar on
    /// the ground), 0.19 % of the VLP-16's, 0.10 % of the VLS-128's and 0.02 % of the
    /// HDL-64E's returns differ by more than one range quantum (the test's bound: 0.5 %): the
    /// VLP-16's by appearing or vanishing only, the others' by 0.35 and 0.38 mm on average
    /// over the returns both report, at most by the distance from a pole to the wall behind
    /// it. `hilrig synth`, which stands in for the real sensor, casts in full.
    BeamDivergence {
        /// Full divergence across, milliradians.
        horizontal_mrad: f64,
        /// Full divergence along elevation, milliradians.
        vertical_mrad: f64,
        /// Sub-rays per axis (odd keeps one on the beam axis; 2 is refused: its grid points are
        /// the bounding box's corners, none inside the ellipse).
        #[serde(default = "default_sub_rays")]
        sub_rays_per_axis: u32,
        /// Echoes closer than this merge (the pulse's range resolution), metres.
        #[serde(default = "default_separation")]
        range_separation_m: f64,
        /// A receiver that detects an echo only when it holds at least this share of the
        /// footprint (its sub-rays), and reports the first (nearest) one detected in place of
        /// the strongest. Unset: every echo is detected and the strongest reported, as a
        /// Velodyne does in strongest-return mode. Where an edge crosses the footprint the two
        /// differ: the first echo of a sizeable share stands out beyond the silhouette by a
        /// share-dependent part of the half-angle, the strongest only where the near part
        /// outshines what lies behind. The gap workflow fits it beside the divergence, since a
        /// beam's width seen at edges depends on it.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        first_echo_share: Option<f64>,
        /// How the sub-rays are laid over the footprint: the grid (the default) or as many
        /// stratified by area ([`FootprintPattern`]).
        #[serde(default, skip_serializing_if = "FootprintPattern::is_grid")]
        pattern: FootprintPattern,
    },
    /// Whether each laser fires at its own time and pose (`enabled = true`, the default of every
    /// model: a rotating sensor on a moving vehicle always sees this) or the whole rotation is
    /// placed at the pose of its first firing (`false`: what a frame-based simulator does, kept so
    /// the gap workflow can show what the distortion costs). Source: Rosenberger et al. 2019, §3 on time
    /// synchronisation; the VLP-16 manual's firing timing.
    MotionDistortion {
        /// Fire each laser at its own pose.
        enabled: bool,
    },
    /// The lidar's timestamps are late against reference time by `offset_ms`: a firing stamped
    /// `t` happened at `t - offset` (a negative offset: stamps early). The same convention as
    /// `check`'s GNSS time offset and every time offset in hilrig. Source: an unsynchronised or
    /// misconfigured clock; Rosenberger et al. 2019, §6 (temporal accuracy of the reference
    /// data).
    TimeOffset {
        /// Offset, milliseconds.
        offset_ms: f64,
    },
    /// The sensor is mounted rotated from the rig file's extrinsics by these angles (applied as
    /// yaw, pitch, roll in the sensor frame; positive yaw turns the sensor counter-clockwise
    /// seen from above, towards the vehicle's left). Source: extrinsic calibration error;
    /// Rosenberger et al. 2019, §6.
    MountMisalignment {
        /// Roll error, degrees.
        #[serde(default)]
        roll_deg: f64,
        /// Pitch error, degrees.
        #[serde(default)]
        pitch_deg: f64,
        /// Yaw error, degrees.
        #[serde(default)]
        yaw_deg: f64,
    },
    /// Intensity depends on the incidence angle (`100 ρ cos^k θ`, Lambertian k = 1) with Gaussian
    /// noise, instead of the idealized model's calibrated reflectivity `100 ρ`. Source: Velodyne
    /// manual on calibrated reflectivity (0-100 diffuse, 101-255 retro-reflective); Kashani et
    /// al. 2015, "A review of lidar radiometric processing".
    Intensity {
        /// Exponent k of cos θ.
        #[serde(default = "one")]
        incidence_exponent: f64,
        /// Standard deviation of the intensity, counts.
        #[serde(default)]
        noise_sigma: f64,
    },
    /// Rain or fog: two-way extinction `exp(-2 α R)` of the received power (acts through
    /// `detection_threshold`, which it requires) and near clutter: with `clutter_probability` a
    /// firing also sees a droplet echo at a uniform range up to `clutter_max_range_m` with the
    /// power of a `clutter_reflectivity` target, unless the beam meets a surface before it.
    /// Source: Rasshofer, Spies & Spies 2011, "Influences of weather phenomena on automotive
    /// laser radar systems"; Goodin et al. 2019, "Predicting the influence of rain on LIDAR in
    /// ADAS" (α ≈ 0.01 R_rain^0.6 per metre for rain rate in mm/h); fog α = 3.912 / visibility
    /// (Koschmieder).
    Weather {
        /// Extinction coefficient α, per metre.
        extinction_per_m: f64,
        /// Probability of a clutter echo per firing.
        #[serde(default)]
        clutter_probability: f64,
        /// Clutter appears up to this range, metres.
        #[serde(default = "default_clutter_range")]
        clutter_max_range_m: f64,
        /// Apparent reflectivity of a clutter echo.
        #[serde(default = "default_clutter_reflectivity")]
        clutter_reflectivity: f64,
    },
}

fn default_sub_rays() -> u32 {
    5
}
fn default_separation() -> f64 {
    0.5
}
fn one() -> f64 {
    1.0
}
fn default_clutter_range() -> f64 {
    3.0
}
fn default_clutter_reflectivity() -> f64 {
    0.05
}

impl Effect {
    /// Which effect it is.
    pub fn kind(&self) -> EffectKind {
        match self {
            Effect::RangeNoise { .. } => EffectKind::RangeNoise,
            Effect::RangeBias { .. } => EffectKind::RangeBias,
            Effect::RandomDropout { .. } => EffectKind::RandomDropout,
            Effect::DetectionThreshold { .. } => EffectKind::DetectionThreshold,
            Effect::BeamDivergence { .. } => EffectKind::BeamDivergence,
            Effect::MotionDistortion { .. } => EffectKind::MotionDistortion,
            Effect::TimeOffset { .. } => EffectKind::TimeOffset,
            Effect::MountMisalignment { .. } => EffectKind::MountMisalignment,
            Effect::Intensity { .. } => EffectKind::Intensity,
            Effect::Weather { .. } => EffectKind::Weather,
        }
    }

    /// The effect's name as written in `model.toml`.
    pub fn name(&self) -> &'static str {
        self.kind().name()
    }
}

/// Which effect of the catalogue, without its parameters: what the gap workflow names, fits and
/// reports (in JSON as in `model.toml`: `range_noise`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    /// `range_noise`.
    RangeNoise,
    /// `range_bias`.
    RangeBias,
    /// `random_dropout`.
    RandomDropout,
    /// `detection_threshold`.
    DetectionThreshold,
    /// `beam_divergence`.
    BeamDivergence,
    /// `motion_distortion`.
    MotionDistortion,
    /// `time_offset`.
    TimeOffset,
    /// `mount_misalignment`.
    MountMisalignment,
    /// `intensity`.
    Intensity,
    /// `weather`.
    Weather,
}

impl EffectKind {
    /// Its name as written in `model.toml`.
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::RangeNoise => "range_noise",
            EffectKind::RangeBias => "range_bias",
            EffectKind::RandomDropout => "random_dropout",
            EffectKind::DetectionThreshold => "detection_threshold",
            EffectKind::BeamDivergence => "beam_divergence",
            EffectKind::MotionDistortion => "motion_distortion",
            EffectKind::TimeOffset => "time_offset",
            EffectKind::MountMisalignment => "mount_misalignment",
            EffectKind::Intensity => "intensity",
            EffectKind::Weather => "weather",
        }
    }
}

impl std::fmt::Display for EffectKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A model: limits and effects.
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// Name (written into simulated recordings).
    pub name: String,
    /// What the model is for.
    #[serde(default)]
    pub description: String,
    /// Range limits.
    #[serde(default)]
    pub limits: Option<Limits>,
    /// The effects, in any order (each at most once).
    #[serde(default, rename = "effect")]
    pub effects: Vec<Effect>,
}

/// Why a model cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// Cannot read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// Path.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// Malformed TOML, unknown effect or key.
    #[error("{path}: {message}")]
    Toml {
        /// Path.
        path: String,
        /// Message with line and column.
        message: String,
    },
    /// A parameter out of range or a conflict.
    #[error("model '{model}', effect {effect}: {what}")]
    Invalid {
        /// Model name.
        model: String,
        /// Effect name.
        effect: String,
        /// What is wrong.
        what: String,
    },
}

impl ModelFile {
    /// The idealized model (no effects).
    pub fn idealized() -> ModelFile {
        ModelFile {
            name: "idealized".into(),
            description: "Rosenberger et al. 2019, Table 1: ray casting with a perfect beam".into(),
            ..ModelFile::default()
        }
    }

    /// Reads and checks a model file.
    pub fn load(path: &Path) -> Result<ModelFile, ModelError> {
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            path: path.display().to_string(),
            source,
        })?;
        crate::config::check_finite(&text).map_err(|e| ModelError::Toml {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let m: ModelFile = toml::from_str(&text).map_err(|e| ModelError::Toml {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        m.validate()?;
        Ok(m)
    }

    /// The TOML text of this model (what simulated recordings store in their metadata).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// Checks parameter ranges and that each effect appears once. Every number must be finite
    /// (TOML reads `nan` and `inf`): a NaN compares false with everything and would pass a
    /// range check written as "not below zero", and an infinite range turns a limit off
    /// without a word. The error names the key, its value and the range it must lie in.
    pub fn validate(&self) -> Result<(), ModelError> {
        let bad = |effect: &str, what: String| ModelError::Invalid {
            model: self.name.clone(),
            effect: effect.into(),
            what,
        };
        if let Some(l) = &self.limits {
            let keys = [
                ("min_range_m", l.min_range_m),
                ("max_range_m", l.max_range_m),
            ];
            for (key, v) in keys {
                if let Some(v) = v {
                    Rule::NonNegative
                        .check(key, v)
                        .map_err(|w| bad("[limits]", w.to_string()))?;
                }
            }
            if let (Some(a), Some(b)) = (l.min_range_m, l.max_range_m) {
                if a >= b {
                    return Err(bad(
                        "[limits]",
                        format!("min_range_m = {a} is not below max_range_m = {b}"),
                    ));
                }
            }
        }
        let mut seen = std::collections::HashSet::new();
        for e in &self.effects {
            if !seen.insert(e.name()) {
                return Err(bad(e.name(), "appears more than once".into()));
            }
            for (key, v, rule) in e.parameters() {
                rule.check(key, v)
                    .map_err(|w| bad(e.name(), w.to_string()))?;
            }
            if let Effect::BeamDivergence {
                sub_rays_per_axis,
                pattern,
                ..
            } = e
            {
                if !(1..=15).contains(sub_rays_per_axis) {
                    return Err(bad(
                        e.name(),
                        format!("sub_rays_per_axis = {sub_rays_per_axis}: must lie in 1..=15"),
                    ));
                }
                if *pattern == FootprintPattern::Stratified
                    && *sub_rays_per_axis > STRATIFIED_MAX_PER_AXIS
                {
                    return Err(bad(
                        e.name(),
                        format!("sub_rays_per_axis = {sub_rays_per_axis}: a stratified footprint takes at most {STRATIFIED_MAX_PER_AXIS} (its strips would be too narrow to spread the sub-rays over the footprint)"),
                    ));
                }
                // Two per axis are the bounding box's corners, all outside the ellipse: a
                // beam of no sub-ray would return nothing.
                if footprint_grid(*sub_rays_per_axis).is_empty() {
                    return Err(bad(
                        e.name(),
                        format!("sub_rays_per_axis = {sub_rays_per_axis}: no sub-ray of its grid lies inside the footprint's ellipse (use 1, or 3 and more)"),
                    ));
                }
            }
            if matches!(e, Effect::Weather { .. })
                && !self
                    .effects
                    .iter()
                    .any(|x| matches!(x, Effect::DetectionThreshold { .. }))
            {
                return Err(bad(
                    e.name(),
                    "needs detection_threshold: extinction removes returns only through it".into(),
                ));
            }
        }
        Ok(())
    }
}

/// The range a model parameter must lie in (always finite).
#[derive(Clone, Copy, Debug)]
enum Rule {
    /// Any finite number.
    Finite,
    /// Finite, at least zero.
    NonNegative,
    /// Finite, above zero.
    Positive,
    /// A probability: 0 to 1.
    Probability,
    /// Finite, at most this far from zero.
    AtMost(f64),
}

/// A parameter outside the range its rule allows.
#[derive(Debug, thiserror::Error)]
#[error("{key} = {value}: must be {range}")]
struct OutOfRange {
    key: String,
    value: f64,
    range: String,
}

impl Rule {
    /// `Ok` when `v` obeys the rule, else what is wrong, naming `key`.
    fn check(self, key: &str, v: f64) -> Result<(), OutOfRange> {
        let (ok, range) = match self {
            Rule::Finite => (true, "a finite number".to_string()),
            Rule::NonNegative => (v >= 0.0, "a finite number, at least 0".into()),
            Rule::Positive => (v > 0.0, "a finite number above 0".into()),
            Rule::Probability => ((0.0..=1.0).contains(&v), "a probability, 0 to 1".into()),
            Rule::AtMost(m) => (
                v.abs() <= m,
                format!("a finite number between -{m} and {m}"),
            ),
        };
        if ok && v.is_finite() {
            Ok(())
        } else {
            Err(OutOfRange {
                key: key.to_owned(),
                value: v,
                range,
            })
        }
    }
}

impl Effect {
    /// Every numeric parameter with its key and the range it must lie in.
    fn parameters(&self) -> Vec<(&'static str, f64, Rule)> {
        use Rule::*;
        match *self {
            Effect::RangeNoise { sigma_m } => vec![("sigma_m", sigma_m, NonNegative)],
            Effect::RangeBias { bias_m } => vec![("bias_m", bias_m, Finite)],
            Effect::RandomDropout { probability } => {
                vec![("probability", probability, Probability)]
            }
            Effect::DetectionThreshold {
                reference_range_m,
                reference_reflectivity,
            } => vec![
                ("reference_range_m", reference_range_m, Positive),
                ("reference_reflectivity", reference_reflectivity, Positive),
            ],
            Effect::BeamDivergence {
                horizontal_mrad,
                vertical_mrad,
                range_separation_m,
                first_echo_share,
                ..
            } => {
                let mut p = vec![
                    ("horizontal_mrad", horizontal_mrad, NonNegative),
                    ("vertical_mrad", vertical_mrad, NonNegative),
                    ("range_separation_m", range_separation_m, NonNegative),
                ];
                if let Some(s) = first_echo_share {
                    p.push(("first_echo_share", s, Probability));
                }
                p
            }
            Effect::MotionDistortion { .. } => vec![],
            Effect::TimeOffset { offset_ms } => vec![("offset_ms", offset_ms, Finite)],
            Effect::MountMisalignment {
                roll_deg,
                pitch_deg,
                yaw_deg,
            } => vec![
                ("roll_deg", roll_deg, AtMost(45.0)),
                ("pitch_deg", pitch_deg, AtMost(45.0)),
                ("yaw_deg", yaw_deg, AtMost(45.0)),
            ],
            Effect::Intensity {
                incidence_exponent,
                noise_sigma,
            } => vec![
                ("incidence_exponent", incidence_exponent, NonNegative),
                ("noise_sigma", noise_sigma, NonNegative),
            ],
            Effect::Weather {
                extinction_per_m,
                clutter_probability,
                clutter_max_range_m,
                clutter_reflectivity,
            } => vec![
                ("extinction_per_m", extinction_per_m, NonNegative),
                ("clutter_probability", clutter_probability, Probability),
                ("clutter_max_range_m", clutter_max_range_m, Positive),
                ("clutter_reflectivity", clutter_reflectivity, NonNegative),
            ],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_catalogue_and_rejects_mistakes() {
        let text = r#"
name = "t"
[[effect]]
name = "range_noise"
sigma_m = 0.02
[[effect]]
name = "detection_threshold"
reference_range_m = 100.0
reference_reflectivity = 0.1
[[effect]]
name = "weather"
extinction_per_m = 0.004
"#;
        let m: ModelFile = toml::from_str(text).unwrap();
        m.validate().unwrap();
        assert_eq!(m.effects.len(), 3);
        let back: ModelFile = toml::from_str(&m.to_toml()).unwrap();
        assert_eq!(back, m);
        assert!(
            toml::from_str::<ModelFile>("name = \"t\"\n[[effect]]\nname = \"sparkle\"\n").is_err()
        );
        assert!(toml::from_str::<ModelFile>(
            "name = \"t\"\n[[effect]]\nname = \"range_noise\"\nsigma = 1.0\n"
        )
        .is_err());
        let dup: ModelFile = toml::from_str(
            "name = \"t\"\n[[effect]]\nname = \"range_bias\"\nbias_m = 1.0\n[[effect]]\nname = \"range_bias\"\nbias_m = 2.0\n",
        )
        .unwrap();
        assert!(dup
            .validate()
            .unwrap_err()
            .to_string()
            .contains("more than once"));
        let weather: ModelFile = toml::from_str(
            "name = \"t\"\n[[effect]]\nname = \"weather\"\nextinction_per_m = 0.01\n",
        )
        .unwrap();
        assert!(weather
            .validate()
            .unwrap_err()
            .to_string()
            .contains("detection_threshold"));
    }

    /// The receiver's echo logic: a share of the footprint, refused outside 0 to 1, kept through
    /// the model file's round trip; the footprint's sub-rays it counts are the grid's points
    /// inside the ellipse.
    #[test]
    fn a_first_echo_share_is_a_share_of_the_footprint() {
        let beam = |share: &str| {
            format!("name = \"t\"\n[[effect]]\nname = \"beam_divergence\"\nhorizontal_mrad = 3.0\nvertical_mrad = 1.5\nfirst_echo_share = {share}\n")
        };
        for bad in ["1.5", "-0.1"] {
            let m: ModelFile = toml::from_str(&beam(bad)).unwrap();
            let e = m.validate().map(|_| ()).unwrap_err().to_string();
            assert!(
                e.contains(&format!("first_echo_share = {bad}: must be a probability")),
                "{e}"
            );
        }
        let m: ModelFile = toml::from_str(&beam("0.25")).unwrap();
        m.validate().unwrap();
        let back: ModelFile = toml::from_str(&m.to_toml()).unwrap();
        assert_eq!(back, m);
        assert!(m.to_toml().contains("first_echo_share = 0.25"));
        assert_eq!(footprint_grid(1), vec![(0.0, 0.0)]);
        assert_eq!(footprint_grid(3).len(), 5);
        assert_eq!(footprint_grid(5).len(), 13);
        // Two per axis would be the bounding box's corners alone: refused.
        let two = beam("0.25").replace(
            "first_echo_share",
            "sub_rays_per_axis = 2\nfirst_echo_share",
        );
        let m: ModelFile = toml::from_str(&two).unwrap();
        let e = m.validate().map(|_| ()).unwrap_err().to_string();
        assert!(e.contains("sub_rays_per_axis = 2: no sub-ray"), "{e}");
        for n in (1..=15).filter(|&n| n != 2) {
            let g = footprint_grid(n);
            assert!(!g.is_empty(), "{n}");
            assert!(g.iter().all(|&(u, v)| u * u + v * v <= 1.0 + 1e-9));
            // Odd counts keep one sub-ray on the beam's axis.
            assert_eq!(g.contains(&(0.0, 0.0)), n % 2 == 1, "{n}");
        }
    }

    /// NaN and infinity, which TOML reads, in every kind of key: refused, naming the key.
    #[test]
    fn nan_and_infinity_are_refused_naming_the_key() {
        let threshold = "[[effect]]\nname = \"detection_threshold\"\nreference_range_m = 100.0\nreference_reflectivity = 0.1\n";
        let cases = [
            ("[limits]\nmax_range_m = nan\n".to_string(), "max_range_m = NaN"),
            ("[limits]\nmin_range_m = -inf\n".into(), "min_range_m = -inf"),
            ("[limits]\nmin_range_m = 5.0\nmax_range_m = 2.0\n".into(), "not below"),
            (
                "[[effect]]\nname = \"detection_threshold\"\nreference_range_m = inf\nreference_reflectivity = 0.1\n".into(),
                "reference_range_m = inf",
            ),
            (
                format!("{threshold}[[effect]]\nname = \"weather\"\nextinction_per_m = 0.01\nclutter_max_range_m = nan\n"),
                "clutter_max_range_m = NaN",
            ),
            ("[[effect]]\nname = \"range_noise\"\nsigma_m = nan\n".into(), "sigma_m = NaN"),
            ("[[effect]]\nname = \"random_dropout\"\nprobability = nan\n".into(), "probability = NaN"),
            ("[[effect]]\nname = \"time_offset\"\noffset_ms = inf\n".into(), "offset_ms = inf"),
            ("[[effect]]\nname = \"mount_misalignment\"\nyaw_deg = nan\n".into(), "yaw_deg = NaN"),
        ];
        for (body, says) in cases {
            let m: ModelFile = toml::from_str(&format!("name = \"t\"\n{body}")).unwrap();
            let e = m.validate().map(|_| ()).unwrap_err().to_string();
            assert!(e.contains(says), "{body}: {e}");
        }
    }
}

//! The effects of a model file compiled for the ray loop: distributions built, angles turned
//! into rotations, the beam footprint into sub-ray offsets, once per simulator.

use super::footprint::Pattern;
use crate::sim::model::{Effect, FootprintPattern, ModelError, ModelFile};
use nalgebra::UnitQuaternion;
use rand_distr::Normal;

/// The beam divergence effect, ready to cast.
#[derive(Clone, Debug)]
pub(super) struct Divergence {
    /// The sub-rays.
    pub(super) pattern: Pattern,
    /// Sub-ray hits closer than this merge into one echo, metres.
    pub(super) separation: f64,
    /// The angle between neighbouring sub-rays (the larger axis), radians: the part of the
    /// footprint each one stands for.
    pub(super) spacing: f64,
    /// The share of the sub-rays an echo must hold to be detected, when the receiver reports
    /// the first echo (`first_echo_share`); `None`: every echo, the strongest reported.
    pub(super) first_share: Option<f64>,
}

/// The effects of a model, ready to apply.
#[derive(Clone, Debug)]
pub(super) struct Compiled {
    pub(super) noise: Option<Normal<f64>>,
    pub(super) bias_m: f64,
    pub(super) dropout: f64,
    pub(super) min_power: Option<f64>,
    pub(super) divergence: Option<Divergence>,
    pub(super) per_firing_pose: bool,
    pub(super) time_offset_ns: i64,
    pub(super) intensity: Option<(f64, f64)>,
    pub(super) weather: Option<(f64, f64, f64, f64)>,
    pub(super) misalignment: UnitQuaternion<f64>,
}

impl Compiled {
    pub(super) fn new(model: &ModelFile) -> Result<Compiled, ModelError> {
        model.validate()?;
        let mut c = Compiled {
            noise: None,
            bias_m: 0.0,
            dropout: 0.0,
            min_power: None,
            divergence: None,
            per_firing_pose: true,
            time_offset_ns: 0,
            intensity: None,
            weather: None,
            misalignment: UnitQuaternion::identity(),
        };
        for e in &model.effects {
            match *e {
                Effect::RangeNoise { sigma_m } => {
                    c.noise = Normal::new(0.0, sigma_m).ok();
                }
                Effect::RangeBias { bias_m } => c.bias_m = bias_m,
                Effect::RandomDropout { probability } => c.dropout = probability,
                Effect::DetectionThreshold {
                    reference_range_m,
                    reference_reflectivity,
                } => c.min_power = Some(reference_reflectivity / reference_range_m.powi(2)),
                Effect::BeamDivergence {
                    horizontal_mrad,
                    vertical_mrad,
                    sub_rays_per_axis,
                    range_separation_m,
                    first_echo_share,
                    pattern,
                } => {
                    let n = sub_rays_per_axis as usize;
                    let offs: Vec<(f64, f64)> = pattern
                        .offsets(sub_rays_per_axis)
                        .into_iter()
                        .map(|(u, v)| (u * horizontal_mrad * 0.5e-3, v * vertical_mrad * 0.5e-3))
                        .collect();
                    let width = horizontal_mrad.max(vertical_mrad) * 1e-3;
                    let spacing = match pattern {
                        _ if n <= 1 => 0.0,
                        FootprintPattern::Grid => width / (n - 1) as f64,
                        // The side of the square each sub-ray stands for.
                        FootprintPattern::Stratified => {
                            0.5 * width * (std::f64::consts::PI / offs.len() as f64).sqrt()
                        }
                    };
                    c.divergence = Some(Divergence {
                        pattern: Pattern::new(
                            offs,
                            (horizontal_mrad * 0.5e-3, vertical_mrad * 0.5e-3),
                        ),
                        separation: range_separation_m,
                        spacing,
                        first_share: first_echo_share,
                    });
                }
                Effect::MotionDistortion { enabled } => c.per_firing_pose = enabled,
                Effect::TimeOffset { offset_ms } => {
                    c.time_offset_ns = (offset_ms * 1e6).round() as i64;
                }
                Effect::MountMisalignment {
                    roll_deg,
                    pitch_deg,
                    yaw_deg,
                } => {
                    c.misalignment = UnitQuaternion::from_euler_angles(
                        roll_deg.to_radians(),
                        pitch_deg.to_radians(),
                        yaw_deg.to_radians(),
                    )
                }
                Effect::Intensity {
                    incidence_exponent,
                    noise_sigma,
                } => c.intensity = Some((incidence_exponent, noise_sigma)),
                Effect::Weather {
                    extinction_per_m,
                    clutter_probability,
                    clutter_max_range_m,
                    clutter_reflectivity,
                } => {
                    c.weather = Some((
                        extinction_per_m,
                        clutter_probability,
                        clutter_max_range_m,
                        clutter_reflectivity,
                    ))
                }
            }
        }
        Ok(c)
    }
}

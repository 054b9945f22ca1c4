//! The resolution floors of the catalogue's effects: the smallest value of each that the
//! workflow adds, as numbers the candidates test against and as the words the report quotes.

use crate::sim::model::EffectKind;

/// Resolution floors: the smallest value of each effect the workflow adds; the fitted value's
/// bootstrap interval must clear it (see `clears`). Below them, the effect is
/// indistinguishable from RTK noise (1-2 cm), survey error and quantisation (2 mm), or too
/// small to change any metric; the floors are a fifth to a half of the smallest values the
/// catalogue's typical ranges hold. Each number is said once, here: the candidates test
/// against these constants and [`FLOORS`] words them for the report.
pub mod floor {
    /// `range_bias`: |bias|, m.
    pub const RANGE_BIAS_M: f64 = 0.005;
    /// `range_noise`: sigma, m.
    pub const RANGE_NOISE_M: f64 = 0.003;
    /// `random_dropout`: probability.
    pub const DROPOUT: f64 = 0.002;
    /// `detection_threshold`: the share of the predicted returns it removes.
    pub const THRESHOLD_REMOVES: f64 = 0.002;
    /// `beam_divergence`: horizontal full angle, mrad.
    pub const DIVERGENCE_MRAD: f64 = 0.5;
    /// `time_offset`: |offset|, ms; its interval holds the GNSS time offset's uncertainty.
    pub const TIME_OFFSET_MS: f64 = 1.0;
    /// `mount_misalignment`: the largest angle, degrees; the yaw's interval holds the smoothed
    /// heading's uncertainty.
    pub const MOUNT_DEG: f64 = 0.1;
    /// `intensity`: the incidence exponent.
    pub const INTENSITY_EXPONENT: f64 = 0.2;
    /// `intensity`: the noise, counts.
    pub const INTENSITY_NOISE: f64 = 1.0;
    /// `weather`: extinction, 1/m.
    pub const EXTINCTION_PER_M: f64 = 0.002;
    /// `weather`: the near-clutter probability.
    pub const CLUTTER: f64 = 0.002;
}

/// A floor's number as the report writes it: its shortest exact decimal.
fn floor_number(x: f64) -> String {
    format!("{}", (x * 1e9).round() / 1e9)
}

/// A floor as percent.
fn floor_percent(x: f64) -> String {
    floor_number(x * 100.0)
}

/// The resolution floor of each effect of the catalogue, in words (the report's and
/// `gap.json`'s), made from the constants of [`floor`].
pub static FLOORS: std::sync::LazyLock<[(EffectKind, String); 10]> = std::sync::LazyLock::new(
    || {
        use floor::*;
        [
            (
                EffectKind::RangeBias,
                format!("|bias| ≥ {} mm", floor_number(RANGE_BIAS_M * 1e3)),
            ),
            (
                EffectKind::RangeNoise,
                format!("σ ≥ {} mm", floor_number(RANGE_NOISE_M * 1e3)),
            ),
            (
                EffectKind::RandomDropout,
                format!("probability ≥ {} %", floor_percent(DROPOUT)),
            ),
            (
                EffectKind::DetectionThreshold,
                format!(
                    "removes ≥ {} % of the predicted returns",
                    floor_percent(THRESHOLD_REMOVES)
                ),
            ),
            (
                EffectKind::BeamDivergence,
                format!("horizontal ≥ {} mrad", floor_number(DIVERGENCE_MRAD)),
            ),
            (EffectKind::MotionDistortion, "none (a switch)".to_owned()),
            (
                EffectKind::TimeOffset,
                format!(
                    "|offset| ≥ {} ms, with 95 % confidence once the uncertainty of the GNSS time offset `check` found is added to its interval",
                    floor_number(TIME_OFFSET_MS)
                ),
            ),
            (
                EffectKind::MountMisalignment,
                format!(
                    "largest angle ≥ {}°, with 95 % confidence once the smoothed heading's uncertainty is added to the yaw's interval",
                    floor_number(MOUNT_DEG)
                ),
            ),
            (
                EffectKind::Intensity,
                format!(
                    "exponent ≥ {} or noise ≥ {} count",
                    floor_number(INTENSITY_EXPONENT),
                    floor_number(INTENSITY_NOISE)
                ),
            ),
            (
                EffectKind::Weather,
                format!(
                    "extinction ≥ {} /m or clutter probability ≥ {} %",
                    floor_number(EXTINCTION_PER_M),
                    floor_percent(CLUTTER)
                ),
            ),
        ]
    },
);

#[cfg(test)]
mod tests {
    use super::*;

    /// The words of the floors are the constants' (the report and gap.json quote them).
    #[test]
    fn the_floors_words_carry_the_constants() {
        let text = |k: EffectKind| {
            FLOORS
                .iter()
                .find(|(e, _)| *e == k)
                .map(|(_, t)| t.clone())
                .unwrap()
        };
        assert_eq!(text(EffectKind::RangeBias), "|bias| ≥ 5 mm");
        assert_eq!(text(EffectKind::RangeNoise), "σ ≥ 3 mm");
        assert_eq!(text(EffectKind::RandomDropout), "probability ≥ 0.2 %");
        assert_eq!(text(EffectKind::BeamDivergence), "horizontal ≥ 0.5 mrad");
        assert_eq!(
            text(EffectKind::Weather),
            "extinction ≥ 0.002 /m or clutter probability ≥ 0.2 %"
        );
        assert_eq!(
            text(EffectKind::Intensity),
            "exponent ≥ 0.2 or noise ≥ 1 count"
        );
        assert_eq!(
            text(EffectKind::DetectionThreshold),
            "removes ≥ 0.2 % of the predicted returns"
        );
        assert_eq!(text(EffectKind::MotionDistortion), "none (a switch)");
        assert_eq!(
            text(EffectKind::TimeOffset),
            "|offset| ≥ 1 ms, with 95 % confidence once the uncertainty of the GNSS time offset `check` found is added to its interval"
        );
        assert_eq!(
            text(EffectKind::MountMisalignment),
            "largest angle ≥ 0.1°, with 95 % confidence once the smoothed heading's uncertainty is added to the yaw's interval"
        );
        assert_eq!(FLOORS.len(), 10);
    }
}

//! Statistical validation (Rosenberger et al. 2019, §8 and Fig. 6 stage 5, Fig. 7): for each
//! scenario sample (a whole repetition, or a named phase of it) and each metric, the interval of
//! the metric over the real repetitions against its interval over the simulated ones, as a
//! traffic light, with the area validation metric between the two samples. In three blocks, in
//! the paper's order: measurement validation (are the real and simulated data comparable at all:
//! every simulated scan has its measured twin, and how far the simulated ranges sit from the
//! measured ones on average), scenario validation (does every repetition cover every phase, and
//! are there enough repetitions for an interval), model validation (the lights). One verdict.

use super::avm::{area_validation_metric, interval, light, Light};

/// A named time window, seconds after each run's first scan.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Phase {
    /// Name ("approach", "yield", "park").
    pub name: String,
    /// Start, s.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
}

/// One metric in one scenario sample.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Cell {
    /// Scenario sample (phase name, or "whole run").
    pub sample: String,
    /// Metric.
    pub metric: String,
    /// Its value per real repetition.
    pub real: Vec<f64>,
    /// Per simulated repetition.
    pub sim: Vec<f64>,
    /// Interval over the real repetitions.
    pub real_interval: Option<(f64, f64)>,
    /// Over the simulated ones.
    pub sim_interval: Option<(f64, f64)>,
    /// The light.
    pub light: Light,
    /// Why black, when it is.
    pub why_black: Option<String>,
    /// Area validation metric, in the metric's unit.
    pub avm: Option<f64>,
}

/// The cells of one scenario sample and metric from the per-repetition values (`None` where a
/// repetition has no value for it).
pub fn cell(sample: &str, metric: &str, real: &[Option<f64>], sim: &[Option<f64>]) -> Cell {
    let r: Vec<f64> = real.iter().flatten().copied().collect();
    let s: Vec<f64> = sim.iter().flatten().copied().collect();
    let why_black = if r.len() < 2 {
        Some(format!(
            "{} real repetitions with a value (2 needed for an interval)",
            r.len()
        ))
    } else if s.is_empty() {
        Some("no simulated repetition with a value".to_owned())
    } else {
        None
    };
    Cell {
        sample: sample.to_owned(),
        metric: metric.to_owned(),
        real_interval: interval(&r),
        sim_interval: interval(&s),
        light: if why_black.is_some() {
            Light::Black
        } else {
            light(&r, &s)
        },
        avm: area_validation_metric(&r, &s),
        why_black,
        real: r,
        sim: s,
    }
}

/// The overall verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Every cell green.
    Valid,
    /// No red, some yellow.
    PartlyValid,
    /// Some red.
    Invalid,
    /// Nothing evaluable, or the measurement or scenario block failed.
    NotEvaluable,
}

impl Verdict {
    /// Its name, as in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Valid => "valid",
            Verdict::PartlyValid => "partly_valid",
            Verdict::Invalid => "invalid",
            Verdict::NotEvaluable => "not_evaluable",
        }
    }
}

/// The verdict of the lights, given that the measurement and scenario blocks passed.
pub fn verdict(cells: &[Cell], blocks_pass: bool) -> Verdict {
    let evaluable: Vec<Light> = cells
        .iter()
        .map(|c| c.light)
        .filter(|l| *l != Light::Black)
        .collect();
    if !blocks_pass || evaluable.is_empty() {
        Verdict::NotEvaluable
    } else if evaluable.contains(&Light::Red) {
        Verdict::Invalid
    } else if evaluable.contains(&Light::Yellow) {
        Verdict::PartlyValid
    } else {
        Verdict::Valid
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_light_and_verdicts() {
        let c = cell("p", "m", &[Some(1.0), Some(2.0), None], &[Some(1.5)]);
        assert_eq!((c.light, c.real.len()), (Light::Green, 2));
        let red = cell("p", "m", &[Some(1.0), Some(2.0)], &[Some(3.0), Some(4.0)]);
        assert_eq!(red.light, Light::Red);
        assert_eq!(red.avm, Some(2.0));
        let black = cell("p", "m", &[Some(1.0)], &[Some(1.0)]);
        assert_eq!(black.light, Light::Black);
        assert!(black.why_black.as_ref().unwrap().contains("2 needed"));
        let yellow = cell("p", "m", &[Some(1.0), Some(2.0)], &[Some(1.5), Some(2.5)]);
        assert_eq!(yellow.light, Light::Yellow);
        assert_eq!(verdict(std::slice::from_ref(&c), true), Verdict::Valid);
        assert_eq!(
            verdict(&[c.clone(), yellow.clone()], true),
            Verdict::PartlyValid
        );
        assert_eq!(verdict(&[c.clone(), yellow, red], true), Verdict::Invalid);
        assert_eq!(
            verdict(std::slice::from_ref(&black), true),
            Verdict::NotEvaluable
        );
        assert_eq!(verdict(&[c], false), Verdict::NotEvaluable);
    }
}

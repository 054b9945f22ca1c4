//! What `hilrig gap` reports: `gap.json` (every round: the bins that disagreed, the candidates
//! ranked with their scores and intervals, the trials on the validation runs, the metrics before
//! and after) and the one-line findings, written atomically so an interrupted study leaves the
//! last completed round.

use super::bins::Table;
use super::candidates::{Candidate, Param};
use super::likelihood::{self, Scored};
use super::observe::{Feature, Obs};
use super::study::Role;
use super::GapError;
use crate::sim::model::EffectKind;
use crate::sim::model::ModelFile;
use std::path::Path;

/// Per-firing statistics of a set of runs under one model.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FiringStats {
    /// Median residual (measured − predicted) away from edges, m.
    pub residual_median_m: Option<f64>,
    /// Its robust σ, m.
    pub residual_sigma_m: Option<f64>,
    /// Share of cast firings the sensor returned.
    pub measured_share: f64,
    /// Share the model returned (before random dropout).
    pub predicted_share: f64,
    /// Log-likelihood per 1000 firings, nats.
    pub log_likelihood_per_1000: f64,
}

/// Full-run metrics on the validation runs.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct RunMetrics {
    /// Mean OCR^K over the validation runs at each run's admissible cell (K = 1, 3D): the
    /// share of the measured cells the simulation occupies too.
    pub ocr: Option<f64>,
    /// Mean precision (the share of the simulated cells the measurement occupies too): what
    /// improves when an effect removes returns (OCR cannot).
    pub precision: Option<f64>,
    /// Mean IoU of the occupied cells.
    pub iou: Option<f64>,
    /// Area validation metric per per-scan feature (real validation runs against their
    /// re-simulations), in the feature's unit.
    pub avm: Vec<FeatureAvm>,
    /// Traffic lights per feature.
    pub lights: Vec<FeatureLight>,
    /// The validation verdict.
    pub verdict: crate::stats::validate::Verdict,
}

/// One feature's area validation metric.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FeatureAvm {
    /// The per-scan feature (as `validate` names it).
    pub metric: String,
    /// Its AVM, in the feature's unit (none where not evaluable).
    pub avm: Option<f64>,
}

/// One feature's traffic light.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FeatureLight {
    /// The per-scan feature.
    pub metric: String,
    /// Its light.
    pub light: crate::stats::avm::Light,
}

/// An effect of the model re-fitted when another joined it: two effects that explain the same
/// disagreement (a detection threshold and random dropout both remove returns) share it out
/// only when they are fitted together.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Refit {
    /// The effect re-fitted.
    pub effect: EffectKind,
    /// Its parameters before.
    pub before: Vec<Param>,
    /// And after, fitted with the new effect in the model.
    pub after: Vec<Param>,
    /// The re-fitted value no longer clears the effect's resolution floor: the new effect
    /// explains what it did.
    pub below_floor: bool,
}

/// An added effect tested on the validation runs.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Trial {
    /// The effect.
    pub effect: EffectKind,
    /// Log-likelihood gain on the validation runs, nats.
    pub gain: f64,
    /// Its 95 % block-bootstrap interval.
    pub gain_interval: Option<(f64, f64)>,
    /// Per-firing statistics before and after.
    pub before: FiringStats,
    /// After.
    pub after: FiringStats,
    /// Kept: the interval lies above zero, and no validation metric got worse beyond its
    /// noise ([`Trial::metrics`]).
    pub kept: bool,
    /// The effects the workflow had added before, re-fitted together with this one (the
    /// model tried is the jointly fitted one).
    #[serde(default)]
    pub refits: Vec<Refit>,
    /// The keep rule's metric half: the validation runs re-simulated in full with the trial
    /// and its metrics judged against the current model's (none where the likelihood already
    /// refused it, or where full metrics were off: then it was judged on the likelihood
    /// alone).
    #[serde(default)]
    pub metrics: Option<MetricCheck>,
}

impl Trial {
    /// The metrics it made worse beyond their noise.
    pub fn worse(&self) -> &[super::keep::Worse] {
        self.metrics.as_ref().map_or(&[], |m| m.worse.as_slice())
    }

    /// Whether the metrics refused it (confounded).
    pub fn confounded(&self) -> bool {
        self.metrics
            .as_ref()
            .is_some_and(|m| m.decision == super::keep::Decision::Confounded)
    }
}

/// The metric half of the keep rule for one trial.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct MetricCheck {
    /// The trial's full-run metrics on the validation runs (as a round reports them).
    pub after: RunMetrics,
    /// What the grid metrics were judged on.
    pub grid: super::keep::GridBasis,
    /// Metrics judged (the Bonferroni family).
    pub judged: usize,
    /// The one-sided level of each: [`super::keep::FAMILY_LEVEL`] / `judged`.
    pub level: f64,
    /// The metrics made worse beyond their noise.
    pub worse: Vec<super::keep::Worse>,
    /// The grid metrics made better beyond their noise.
    #[serde(default)]
    pub improved: Vec<super::keep::Watched>,
    /// What they decide: none worse, a trade-off (kept), or confounded (not kept).
    pub decision: super::keep::Decision,
}

/// One round.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Round {
    /// 1-based.
    pub round: usize,
    /// The bins that disagree on the parameterization runs under the current model,
    /// `feature [from, to): measured x % vs model y %, median residual z m`.
    pub disagreeing_bins: Vec<String>,
    /// All bins.
    pub bins: Vec<Table>,
    /// Candidates, best first.
    pub candidates: Vec<Candidate>,
    /// The candidates tried on the validation runs, in order.
    pub trials: Vec<Trial>,
    /// The effect added in this round.
    pub chosen: Option<EffectKind>,
    /// Its fitted parameters (after the joint re-fit).
    pub parameters: Vec<Param>,
    /// The effects added before, re-fitted together with it: their parameters before and
    /// after.
    #[serde(default)]
    pub refits: Vec<Refit>,
    /// Full-run metrics on the validation runs before and after (when computed).
    pub metrics_before: Option<RunMetrics>,
    /// After.
    pub metrics_after: Option<RunMetrics>,
}

/// A run as listed in the report.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct RunInfo {
    /// Name.
    pub name: String,
    /// Role.
    pub role: Role,
    /// The check's verdict.
    pub check: crate::reference::check::Verdict,
    /// Firings sampled.
    pub sampled_firings: usize,
    /// Stretches left out where `check` marked the reference not usable (its marks).
    pub left_out: Vec<crate::reference::check::Fault>,
    /// What could not be read (damage, undecodable packets): the run was used as far as it
    /// could be read.
    pub damage: Vec<String>,
}

/// An effect's resolution floor: below it the workflow does not add the effect.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Floor {
    /// The effect.
    pub effect: EffectKind,
    /// The floor, in words.
    pub floor: String,
}

/// Everything `gap.json` holds.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct GapReport {
    /// The start model's file.
    pub start_model: String,
    /// The runs.
    pub runs: Vec<RunInfo>,
    /// Set when a single run was split in time.
    pub split: Option<String>,
    /// The resolution floors of the catalogue.
    pub floors: Vec<Floor>,
    /// The completed rounds.
    pub rounds: Vec<Round>,
    /// Whether the workflow finished (false while running or when interrupted).
    pub finished: bool,
    /// Where the reference was not usable (a line per stretch left out), then one line per
    /// effect found, or the evidence that none was.
    pub summary: Vec<String>,
    /// Why the rounds ended, when they have: the evidence that no effect is missing, or the
    /// round limit (also the summary's line of it).
    #[serde(default)]
    pub ended: Option<String>,
    /// The fitted model against a model known to have made the data (`--reference-model`).
    #[serde(default)]
    pub reference: Option<ReferenceCheck>,
    /// For each effect not added when no further one was found: the smallest size of it these
    /// runs would have shown.
    #[serde(default)]
    pub limits: Vec<super::limits::DetectionLimit>,
}

/// The fitted model's validation metrics beside those of a model known to have made the data
/// (a synthesized drive's truth), judged as the keep rule judges a trial ([`super::keep`]):
/// is the fitted model worse than the generating one beyond that one's noise?
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ReferenceCheck {
    /// The reference model's file.
    pub path: String,
    /// Its name.
    pub name: String,
    /// Its full-run metrics on the validation runs.
    pub metrics: RunMetrics,
    /// The fitted model's.
    pub fitted: RunMetrics,
    /// What the grid metrics were judged on.
    pub grid: super::keep::GridBasis,
    /// Metrics judged.
    pub judged: usize,
    /// The one-sided level of each.
    pub level: f64,
    /// Where the fitted model is worse than the reference beyond the reference's noise.
    pub worse: Vec<super::keep::Worse>,
    /// The grid metrics where it is better beyond it.
    pub improved: Vec<super::keep::Watched>,
}

impl ReferenceCheck {
    /// The summary's line.
    pub fn line(&self) -> String {
        if self.worse.is_empty() {
            format!(
                "against the generating model '{}' ({}): the fitted model is within its noise on all {} validation metrics judged",
                self.name, self.path, self.judged
            )
        } else {
            let worse: Vec<String> = self.worse.iter().map(ToString::to_string).collect();
            format!(
                "against the generating model '{}' ({}): the fitted model is worse beyond its noise in {} of {} validation metrics: {} (the generating model's value first)",
                self.name,
                self.path,
                self.worse.len(),
                self.judged,
                worse.join(", ")
            )
        }
    }
}

fn write_atomic(path: &Path, text: &str) -> Result<(), GapError> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|source| GapError::Output {
            path: path.to_owned(),
            source,
        })
}

/// Writes the fitted model and `gap.json` into `out`.
pub(super) fn save(out: &Path, model: &ModelFile, report: &GapReport) -> Result<(), GapError> {
    write_atomic(&out.join("model.fitted.toml"), &model.to_toml())?;
    Ok(crate::output::write(&out.join("gap.json"), report)?)
}

/// The per-firing statistics of observations under a model.
pub(super) fn firing_stats(
    obs: &[Vec<Obs>],
    feats: &[Vec<Feature>],
    scored: &[Scored],
) -> FiringStats {
    let mut res = Vec::new();
    let (mut cast, mut meas, mut pred) = (0usize, 0usize, 0usize);
    for (o, f) in obs.iter().zip(feats) {
        res.extend(likelihood::residuals(o, f).into_iter().map(|x| x.1));
        for o in o.iter().filter(|o| o.cast) {
            cast += 1;
            meas += usize::from(o.measured.is_finite());
            pred += usize::from(o.predicted.is_finite());
        }
    }
    let ll: f64 = scored.iter().flat_map(|s| &s.per_scan).sum();
    FiringStats {
        residual_sigma_m: likelihood::robust_sigma(&res),
        residual_median_m: likelihood::median(&mut res),
        measured_share: meas as f64 / cast.max(1) as f64,
        predicted_share: pred as f64 / cast.max(1) as f64,
        log_likelihood_per_1000: ll / cast.max(1) as f64 * 1000.0,
    }
}

/// The disagreeing bins, one line each.
pub(super) fn describe(tables: &[Table]) -> Vec<String> {
    let mut out = Vec::new();
    for t in tables {
        for b in t.bins.iter().filter(|b| b.disagrees) {
            out.push(format!(
                "{} [{}, {}): {} firings, sensor returns {:.1} % vs model {:.1} %, median residual {}",
                t.feature,
                b.from,
                b.to,
                b.firings,
                b.measured_share * 100.0,
                b.predicted_share * 100.0,
                b.median_m
                    .map_or_else(|| "n/a".to_owned(), |m| format!("{m:+.3} m")),
            ));
        }
    }
    out
}

/// The fitted parameters with their intervals, as the summary prints them.
pub(super) fn params_text(c: &Candidate) -> String {
    values_text(&c.params)
}

/// Fitted values as `name = value [low, high]`, comma-separated (a fixed reference
/// reflectivity and a switch's `enabled` left out).
fn values_text(params: &[Param]) -> String {
    params
        .iter()
        .filter(|p| p.name != "reference_reflectivity" && p.name != "enabled")
        .map(|p| {
            // Three significant digits of the value; the interval to the same decimals.
            let unit_digits = if p.value == 0.0 || !p.value.is_finite() {
                2
            } else {
                (2 - p.value.abs().log10().floor() as i32).clamp(0, 6) as usize
            };
            match p.interval {
                Some((a, b)) => format!(
                    "{} = {:.d$} [{:.d$}, {:.d$}]",
                    p.name,
                    p.value,
                    a,
                    b,
                    d = unit_digits
                ),
                None => format!("{} = {:.d$}", p.name, p.value, d = unit_digits),
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// A bootstrap interval as "low, high" (one decimal), or "n/a".
fn interval_text(i: Option<(f64, f64)>) -> String {
    i.map_or("n/a".into(), |(a, z)| format!("{a:.1}, {z:.1}"))
}

/// The summary of a round that added nothing. Eligible candidates that were tried on the
/// validation runs and not kept come first, each with both gains: an effect that fits the
/// parameterization runs but does not carry over is a finding the engineer should see (a
/// weak effect, or too few validation scans to show it), not something hidden behind the
/// candidate with the largest gain. Without such trials, the best candidate and why it is not
/// eligible.
pub(super) fn no_effect_line(round: usize, candidates: &[Candidate], trials: &[Trial]) -> String {
    let tried: Vec<String> = trials
        .iter()
        .filter(|t| !t.kept)
        .filter_map(|t| {
            let c = candidates.iter().find(|c| c.effect == t.effect)?;
            Some(if !t.confounded() {
                format!(
                    "{} ({}) fits the parameterization runs (gain {:.1} nats [{}]) but did not improve the validation runs beyond their noise (gain {:.1} nats [{}])",
                    c.effect,
                    params_text(c),
                    c.gain,
                    interval_text(c.gain_interval),
                    t.gain,
                    interval_text(t.gain_interval)
                )
            } else {
                worse_text(c, t)
            })
        })
        .collect();
    if !tried.is_empty() {
        return format!(
            "no missing effect found in round {round}: {}",
            tried.join("; ")
        );
    }
    match candidates.first() {
        Some(b) => format!(
            "no missing effect found in round {round}: best candidate {} ({}) gain {:.1} nats [{}], {}",
            b.effect,
            params_text(b),
            b.gain,
            interval_text(b.gain_interval),
            b.note.clone().unwrap_or_else(|| "not significant".into())
        ),
        None => format!("no missing effect found in round {round}: no candidate left"),
    }
}

/// A trial the metric half of the keep rule refused: confounded, with the metrics it made
/// worse and by how much.
pub(super) fn worse_text(c: &Candidate, t: &Trial) -> String {
    let worse: Vec<String> = t.worse().iter().map(ToString::to_string).collect();
    format!(
        "{} ({}) is confounded: it improves the validation runs' likelihood (gain {:.1} nats [{}]) but makes a validation metric worse beyond its noise: {}; not kept",
        c.effect,
        params_text(c),
        t.gain,
        interval_text(t.gain_interval),
        worse.join(", ")
    )
}

/// The one-line finding of a round.
pub(super) fn summary_line(
    c: &Candidate,
    trial: Option<&Trial>,
    round: &Round,
    runs: usize,
) -> String {
    // The parameters as the joint re-fit left them (the candidate's own fit where there was
    // nothing to re-fit with).
    let params = if round.parameters.is_empty() {
        &c.params
    } else {
        &round.parameters
    };
    let mut parts = vec![format!("found: {} {}", c.effect, values_text(params))];
    // The footprint's sampling is no number among the parameters: named where it is not the
    // default grid.
    if let Some(crate::sim::model::Effect::BeamDivergence { pattern, .. }) = &c.fitted {
        if !pattern.is_grid() {
            parts[0].push_str(&format!(", pattern = {}", pattern.name()));
        }
    }
    // Re-fits that changed nothing to the printed digits are in gap.json, not in the line.
    for r in round
        .refits
        .iter()
        .filter(|r| values_text(&r.before) != values_text(&r.after) || r.below_floor)
    {
        parts.push(format!(
            "{} re-fitted with it: {} -> {}{}",
            r.effect,
            values_text(&r.before),
            values_text(&r.after),
            if r.below_floor {
                " (now below its resolution floor)"
            } else {
                ""
            }
        ));
    }
    if let (Some(b), Some(a)) = (&round.metrics_before, &round.metrics_after) {
        for (label, x, y) in [
            ("OCR", b.ocr, a.ocr),
            ("precision", b.precision, a.precision),
        ] {
            if let (Some(x), Some(y)) = (x, y) {
                parts.push(format!("{label} {x:.3} -> {y:.3}"));
            }
        }
        let avm = |m: &RunMetrics, name: &str| {
            m.avm.iter().find(|a| a.metric == name).and_then(|a| a.avm)
        };
        for (name, label) in [
            ("returns_per_scan", "AVM returns/scan"),
            ("mean_range_m", "AVM mean range"),
        ] {
            if let (Some(x), Some(y)) = (avm(b, name), avm(a, name)) {
                parts.push(format!("{label} {x:.3} -> {y:.3}"));
            }
        }
    }
    if let Some(t) = trial {
        parts.push(format!(
            "log-likelihood {:+.3} -> {:+.3} per 1000 firings",
            t.before.log_likelihood_per_1000, t.after.log_likelihood_per_1000
        ));
        if let Some(m) = t
            .metrics
            .as_ref()
            .filter(|m| m.decision == super::keep::Decision::TradeOff)
        {
            let worse: Vec<String> = m.worse.iter().map(ToString::to_string).collect();
            let better: Vec<String> = m.improved.iter().map(ToString::to_string).collect();
            parts.push(format!(
                "a trade-off: {} worse beyond noise while {} improved beyond noise",
                worse.join(", "),
                better.join(", ")
            ));
        }
    }
    format!("{} on {runs} validation runs", parts.join("; "))
}

/// Whether two eligible candidates explain the parameterization runs alike: each one's gain
/// lies inside the other's bootstrap interval. Effects that act alike on a drive are
/// confounded there (a time offset and motion distortion both shift a scan along the motion;
/// at low speed the per-firing residuals away from edges barely tell them apart), and their
/// ranking by gain is then an order, not evidence.
pub(super) fn alike(a: &Candidate, b: &Candidate) -> bool {
    let inside = |g: f64, i: Option<(f64, f64)>| i.is_some_and(|(lo, hi)| lo <= g && g <= hi);
    a.eligible
        && b.eligible
        && a.effect != b.effect
        && inside(a.gain, b.gain_interval)
        && inside(b.gain, a.gain_interval)
}

/// A warning when other candidates explain the parameterization runs as well as the chosen
/// one ([`alike`]), with their gains there and, where they were tried, on the validation
/// runs: the engineer should know that the data hardly decided, and that a drive with other
/// speeds or turns would separate the effects.
pub(super) fn confounded_line(
    chosen: &Candidate,
    candidates: &[Candidate],
    trials: &[Trial],
) -> Option<String> {
    let describe = |c: &Candidate| {
        let validation = trials.iter().rfind(|t| t.effect == c.effect).map_or_else(
            || "not tried on the validation runs".to_owned(),
            |t| {
                format!(
                    "validation {:.1} [{}]",
                    t.gain,
                    interval_text(t.gain_interval)
                )
            },
        );
        format!(
            "{} (gain {:.1} nats [{}], {validation})",
            c.effect,
            c.gain,
            interval_text(c.gain_interval)
        )
    };
    let rivals: Vec<String> = candidates
        .iter()
        .filter(|c| alike(chosen, c))
        .map(describe)
        .collect();
    (!rivals.is_empty()).then(|| {
        format!(
            "confounded: {} and {} explain the parameterization runs alike; {} was added as the one that improved the validation runs most, but these drives hardly tell the effects apart: treat the choice as open (drives with other speeds, speed changes or turns would separate them)",
            describe(chosen),
            rivals.join(", "),
            chosen.effect
        )
    })
}

impl crate::output::Output for GapReport {
    const KIND: crate::output::OutputKind = crate::output::OutputKind::Gap;
    const SCHEMA: u32 = 1;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::candidates::Param;

    fn candidate(effect: EffectKind, value: f64, gain: f64, eligible: bool) -> Candidate {
        Candidate {
            effect,
            fitted: None,
            refitted: Vec::new(),
            params: vec![Param {
                name: "x".into(),
                value,
                interval: None,
            }],
            gain,
            gain_interval: Some((gain * 0.5, gain * 1.5)),
            gain_per_1000_firings: 0.0,
            above_floor: eligible,
            eligible,
            note: (!eligible).then(|| "fitted value below the resolution floor".to_owned()),
        }
    }

    fn trial(effect: EffectKind, kept: bool) -> Trial {
        let stats = FiringStats {
            residual_median_m: None,
            residual_sigma_m: None,
            measured_share: 0.0,
            predicted_share: 0.0,
            log_likelihood_per_1000: 0.0,
        };
        Trial {
            effect,
            gain: 340.0,
            gain_interval: Some((-85.8, 796.7)),
            before: stats.clone(),
            after: stats,
            kept,
            refits: Vec::new(),
            metrics: None,
        }
    }

    /// Three significant digits of a fitted value, the interval to the same decimals; the
    /// threshold's reference reflectivity (fixed, not fitted) left out.
    #[test]
    fn fitted_values_are_printed_to_three_significant_digits() {
        let mut c = candidate(EffectKind::RangeNoise, 0.0, 1.0, true);
        c.params = vec![
            Param {
                name: "sigma_m".into(),
                value: 0.012_345,
                interval: Some((0.011_94, 0.012_71)),
            },
            Param {
                name: "reference_range_m".into(),
                value: 57.91,
                interval: None,
            },
            Param {
                name: "reference_reflectivity".into(),
                value: 0.3,
                interval: None,
            },
            Param {
                name: "probability".into(),
                value: 0.0,
                interval: None,
            },
            Param {
                name: "bias_m".into(),
                value: -1234.5,
                interval: None,
            },
        ];
        assert_eq!(
            params_text(&c),
            "sigma_m = 0.0123 [0.0119, 0.0127], reference_range_m = 57.9, probability = 0.00, bias_m = -1234"
        );
    }

    /// Per-firing statistics over the runs: shares of the cast firings, the log-likelihood
    /// per 1000 cast firings; a firing the model did not cast counts nowhere.
    #[test]
    fn firing_stats_count_only_cast_firings() {
        let o = |measured: f32, predicted: f32, cast: bool| Obs {
            measured,
            intensity: 255,
            predicted,
            power: 1.0,
            reflectivity: f32::NAN,
            lambertian: f32::NAN,
            cast,
        };
        let obs = vec![
            vec![
                o(8.02, 8.0, true),
                o(f32::NAN, 8.0, true),
                o(9.0, f32::NAN, true),
                o(5.0, f32::NAN, false),
            ],
            vec![o(7.99, 8.0, true), o(6.0, f32::NAN, true)],
        ];
        let feats: Vec<Vec<Feature>> = obs
            .iter()
            .map(|r| vec![Feature::default(); r.len()])
            .collect();
        let scored = [
            Scored {
                per_scan: vec![-3.0, -2.0],
                ..Scored::default()
            },
            Scored {
                per_scan: vec![-5.0],
                ..Scored::default()
            },
        ];
        let s = firing_stats(&obs, &feats, &scored);
        // 5 cast firings: 4 measured a return, 3 were predicted one.
        assert_eq!((s.measured_share, s.predicted_share), (0.8, 0.6), "{s:?}");
        assert!((s.log_likelihood_per_1000 + 2000.0).abs() < 1e-9, "{s:?}");
        let median = s.residual_median_m.unwrap();
        assert!(
            [0.02f64, -0.01].iter().any(|r| (median - r).abs() < 1e-6),
            "{s:?}"
        );
    }

    #[test]
    fn an_effect_as_good_as_the_chosen_one_is_named_as_confounded() {
        // Gains 45 000 [9 000, 90 000] and 44 800 [20 000, 70 000]: each inside the other's.
        let chosen = candidate(EffectKind::TimeOffset, -29.7, 45_000.0, true);
        let mut rival = candidate(EffectKind::MotionDistortion, 1.0, 44_800.0, true);
        rival.gain_interval = Some((20_000.0, 70_000.0));
        let weaker = candidate(EffectKind::MountMisalignment, 0.2, 10_000.0, true);
        let tried = [trial(EffectKind::TimeOffset, true)];
        let line =
            confounded_line(&chosen, &[chosen.clone(), rival.clone(), weaker], &tried).unwrap();
        assert!(line.starts_with("confounded: time_offset (gain 45000.0 nats [22500.0, 67500.0], validation 340.0 [-85.8, 796.7]) and motion_distortion (gain 44800.0 nats [20000.0, 70000.0], not tried on the validation runs)"), "{line}");
        assert!(!line.contains("mount_misalignment"), "{line}");
        // An ineligible rival, or one clearly weaker, is no confound.
        rival.eligible = false;
        assert!(confounded_line(&chosen, &[rival], &tried).is_none());
        let far = candidate(EffectKind::RangeBias, 0.01, 15_000.0, true);
        assert!(!alike(&chosen, &far));
        assert!(confounded_line(&chosen, &[far], &tried).is_none());
    }

    /// The line names the candidate that was tried and failed validation, with both gains,
    /// not the ineligible candidate ranked first by its parameterization gain.
    #[test]
    fn a_round_without_an_effect_names_what_failed_validation() {
        let cands = [
            candidate(EffectKind::MountMisalignment, 0.17, 5707.0, false),
            candidate(EffectKind::BeamDivergence, 1.3, 700.0, true),
        ];
        let line = no_effect_line(5, &cands, &[trial(EffectKind::BeamDivergence, false)]);
        assert!(
            line.starts_with("no missing effect found in round 5: beam_divergence (x = 1.30)"),
            "{line}"
        );
        assert!(line.contains("gain 700.0 nats [350.0, 1050.0]"), "{line}");
        assert!(line.contains("did not improve the validation runs beyond their noise (gain 340.0 nats [-85.8, 796.7])"), "{line}");
        assert!(!line.contains("mount_misalignment"), "{line}");

        // Nothing tried: the best candidate and why it is not eligible.
        let line = no_effect_line(2, &cands[..1], &[]);
        assert!(line.contains("best candidate mount_misalignment"), "{line}");
        assert!(line.contains("below the resolution floor"), "{line}");
        assert_eq!(
            no_effect_line(3, &[], &[]),
            "no missing effect found in round 3: no candidate left"
        );
    }
}

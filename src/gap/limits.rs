//! Detection limits: for each effect of the catalogue the workflow did not add, the smallest
//! size of it that these runs would have shown. "None found" means little without it: a
//! 10 cm survey error hides a beam divergence that a 1 cm one shows.
//!
//! The limit is measured, not computed from a formula: the effect is injected into the runs'
//! own measured ranges at growing sizes, and the workflow's test is run on each injection as it
//! runs on the data: the candidate fitted on the parameterization runs must be eligible (its
//! value clears the resolution floor with 95 % confidence, its gain's interval is above zero),
//! and the model with it must improve the validation runs' likelihood beyond their noise. The
//! smallest size where the test fires is the limit. What the injection keeps is everything
//! that hides an effect in practice: the runs' reference errors, their noise, their scene and
//! their sampling; what it adds is the effect as the simulator makes it, firing by firing:
//!
//! - an effect that moves or removes returns (a range bias, a time offset, a mount yaw, a beam
//!   divergence, a detection threshold) adds to each measured range the change the effect makes
//!   to the current model's prediction of it; a return the effect removes is removed, a return
//!   it adds (a footprint beyond an edge) is the new prediction plus a residual of the run's
//!   own;
//! - range noise adds σ times a standard normal draw to each return, dropout removes each
//!   return with its probability. The draws are the same at every size (fixed per firing), so
//!   a larger size is the smaller one and more: the search sees one realisation growing.
//!
//! The runs may hold some of the effect already, too little for the workflow to add (its
//! candidate was fitted at a size and not kept): the injection then starts from there, moving
//! the data from the size fitted to the size tried, so that a limit is a size of the effect in
//! the data and not one on top of what they hold. A limit below an effect a drive was made
//! with would say the workflow should have seen it. An effect whose trial the keep rule
//! refused (a validation metric worse) was seen: its line says it was refused, not missed.
//!
//! The search doubles the size from the effect's resolution floor (a time offset's and a
//! mount yaw's plus 1.96 sigmas of the reference's timing or heading, the least that can clear
//! it; or the size fitted, if larger) until the test fires, then halves the last step once
//! (so the limit is known to a factor of √2), and stops at the catalogue's largest sizes. Two parts of the workflow's
//! decision are left out, on purpose: the joint re-fit of the effects added before (it moves
//! them, not the injected one) and the keep rule's metric half (it can only refuse an effect
//! the likelihood found, so the limit is where an effect is *seen*; a refusal is said in the
//! rounds).
//!
//! Long file: one search (what each effect's size means, how it is injected into the data,
//! the workflow's test on the injection, the search over sizes and what it writes), of which
//! about a sixth is its tests.

use super::candidates::{floor, least_clearing, with_effect, Fitting};
use super::observe::Obs;
use super::runset::{Measured, RunSet};
use super::GapError;
use crate::sim::model::{Effect, EffectKind, FootprintPattern, ModelFile};
use rand::{Rng, SeedableRng};
use std::borrow::Cow;

/// How an effect of a given size changes the measured ranges.
#[derive(Clone, Debug)]
enum Injection {
    /// Through the simulator: the change the effect makes to the current model's prediction.
    Predicted(Effect),
    /// Range noise of this σ, m.
    Noise(f64),
    /// Returns removed with this probability.
    Dropout(f64),
}

/// What a detection limit was searched for, and what the search found.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct DetectionLimit {
    /// The effect.
    pub effect: EffectKind,
    /// The size injected, named as in `model.toml` (or as described in `unit`).
    pub parameter: Cow<'static, str>,
    /// What the size means, in words.
    pub unit: Cow<'static, str>,
    /// The smallest size injected at which the workflow would have added the effect.
    pub seen_at: Option<f64>,
    /// The largest size injected below it that it missed.
    pub missed_at: Option<f64>,
    /// Each size injected, in the order tried.
    pub tries: Vec<Try>,
    /// Why no limit was searched, when none was (a switch has no size).
    pub note: Option<String>,
    /// The effect grows as the parameter falls (a detection threshold's reference range): the
    /// limit is a largest value, not a smallest.
    #[serde(default)]
    pub at_most: bool,
    /// The last round tried it on the validation runs and the keep rule refused it (a
    /// validation metric worse beyond its noise): it was seen, and not added.
    #[serde(default)]
    pub refused: bool,
}

/// One injection of a detection limit's search.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Try {
    /// The size injected.
    pub size: f64,
    /// Whether the workflow would have added the effect.
    pub seen: bool,
}

impl DetectionLimit {
    /// In a few words: the effect and the smallest size seen ("beam_divergence
    /// horizontal_mrad ≥ 2.83"), or why there is none.
    pub fn short(&self) -> String {
        let name = self.effect.name();
        let sign = if self.at_most { "≤" } else { "≥" };
        let refused = if self.refused { " (seen, refused)" } else { "" };
        match (&self.note, self.seen_at) {
            (Some(_), _) => format!("{name} (no limit)"),
            (None, Some(s)) => format!("{name} {} {sign} {}{refused}", self.parameter, number(s)),
            (None, None) => format!("{name} (not seen at any size tried)"),
        }
    }

    /// The summary's line: what was not found, and what would have been.
    pub fn line(&self) -> String {
        let name = self.effect.name();
        if let Some(n) = &self.note {
            return format!("{name}: none found; no detection limit ({n})");
        }
        let none = if self.refused {
            "refused, not missed (a validation metric got worse: see the last round)"
        } else {
            "none found"
        };
        let (sign, up_to) = if self.at_most {
            ("≤", "down to")
        } else {
            ("≥", "up to")
        };
        // The largest effect tried: the last size of the search.
        let largest = self.tries.last().map_or(f64::NAN, |t| t.size);
        match (self.seen_at, self.missed_at) {
            (Some(s), Some(m)) => format!(
                "{name}: {none}; would have seen {} {sign} {} ({}; {} missed)",
                self.parameter,
                number(s),
                self.unit,
                number(m)
            ),
            (Some(s), None) => format!(
                "{name}: {none}; would have seen {} {sign} {} ({}; the smallest size tried)",
                self.parameter,
                number(s),
                self.unit
            ),
            (None, _) => format!(
                "{name}: {none}; would not have seen {} {up_to} {} ({}), the largest effect tried",
                self.parameter,
                number(largest),
                self.unit
            ),
        }
    }
}

/// A size as the lines write it: three significant digits.
fn number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = (2 - x.abs().log10().floor() as i32).max(0) as usize;
    format!("{x:.digits$}")
}

/// How the limit of one effect is searched: over a strength that grows with the effect (the
/// parameter itself, or for a detection threshold its power), from `start` to `largest`.
struct Searched {
    parameter: &'static str,
    unit: &'static str,
    /// The first strength tried.
    start: f64,
    /// The largest strength tried.
    largest: f64,
    /// The parameter at a strength.
    parameter_of: fn(f64) -> f64,
    /// The effect grows as the parameter falls.
    at_most: bool,
}

/// The reference range at 10 % reflectivity of a threshold at `power`.
fn range_at(power: f64) -> f64 {
    (super::candidates::REFERENCE_REFLECTIVITY / power).sqrt()
}

/// The search of `kind` on these runs under `model`, or why there is none.
fn searched(
    kind: EffectKind,
    fit: &RunSet,
    model: &ModelFile,
) -> Result<Result<Searched, &'static str>, GapError> {
    let plain = |parameter, unit, start, largest| Searched {
        parameter,
        unit,
        start,
        largest,
        parameter_of: |x| x,
        at_most: false,
    };
    Ok(Ok(match kind {
        EffectKind::RangeBias => plain(
            "bias_m",
            "m, a constant added to every range",
            floor::RANGE_BIAS_M,
            0.64,
        ),
        EffectKind::RangeNoise => plain(
            "sigma_m",
            "m, a normal range noise",
            floor::RANGE_NOISE_M,
            0.4,
        ),
        EffectKind::RandomDropout => plain(
            "probability",
            "of each return, lost at random",
            floor::DROPOUT,
            0.5,
        ),
        EffectKind::DetectionThreshold => {
            // From the weakest power that removes the floor's share of the predicted returns
            // away from edges to the one that removes half of them. Powers come in clumps (a
            // surface seen at one range and angle by many firings), so the start is the
            // first power above the floor's share, not its quantile.
            let obs = fit.cast_recorded(model)?;
            let powers = predicted_powers(fit, &obs);
            let Some(&median) = powers.get(powers.len() / 2) else {
                return Ok(Err("no predicted return to threshold"));
            };
            let k = (floor::THRESHOLD_REMOVES * powers.len() as f64).ceil() as usize;
            let start = powers[k.min(powers.len() - 1)..]
                .iter()
                .copied()
                .find(|&p| p > powers[k.min(powers.len() - 1)])
                .unwrap_or(median);
            Searched {
                parameter: "reference_range_m",
                unit: "m at 10 % reflectivity, a detection threshold",
                start: start.min(median),
                largest: median,
                parameter_of: range_at,
                at_most: true,
            }
        }
        EffectKind::TimeOffset => plain(
            "offset_ms",
            "ms, the lidar's clock late",
            // The smallest offset whose interval, the timing's sigma in it, can clear the floor.
            least_clearing(
                floor::TIME_OFFSET_MS,
                fit.largest_over_runs(|r| r.time_sigma_ms),
            ),
            256.0,
        ),
        EffectKind::MountMisalignment => plain(
            "yaw_deg",
            "°, the sensor turned about its vertical axis",
            // Likewise, the heading's sigma.
            least_clearing(
                floor::MOUNT_DEG,
                fit.largest_over_runs(|r| r.heading_sigma_deg),
            ),
            6.4,
        ),
        EffectKind::BeamDivergence => plain(
            "horizontal_mrad",
            "mrad full angle, the vertical half of it",
            floor::DIVERGENCE_MRAD,
            16.0,
        ),
        EffectKind::MotionDistortion => return Ok(Err("a switch, it has no size")),
        EffectKind::Intensity => {
            return Ok(Err(
                "the intensity is not injected: its limit is not searched",
            ))
        }
        EffectKind::Weather => {
            return Ok(Err(
                "the weather is not injected: its limit is not searched",
            ))
        }
    }))
}

/// The predicted powers of the set's predicted returns away from edges, ascending.
fn predicted_powers(set: &RunSet, obs: &[Vec<Obs>]) -> Vec<f64> {
    let mut powers: Vec<f64> = obs
        .iter()
        .zip(&set.feats)
        .flat_map(|(o, f)| o.iter().zip(f))
        .filter(|(o, f)| o.cast && !f.is_edge() && o.predicted.is_finite())
        .map(|(o, _)| f64::from(o.power))
        .filter(|p| p.is_finite() && *p > 0.0)
        .collect();
    powers.sort_by(f64::total_cmp);
    powers
}

/// The injection of `kind` at strength `size`.
fn injection(kind: EffectKind, size: f64) -> Option<Injection> {
    Some(match kind {
        EffectKind::RangeBias => Injection::Predicted(Effect::RangeBias { bias_m: size }),
        EffectKind::RangeNoise => Injection::Noise(size),
        EffectKind::RandomDropout => Injection::Dropout(size),
        EffectKind::DetectionThreshold => Injection::Predicted(Effect::DetectionThreshold {
            reference_range_m: range_at(size),
            reference_reflectivity: super::candidates::REFERENCE_REFLECTIVITY,
        }),
        EffectKind::TimeOffset => Injection::Predicted(Effect::TimeOffset { offset_ms: size }),
        EffectKind::MountMisalignment => Injection::Predicted(Effect::MountMisalignment {
            roll_deg: 0.0,
            pitch_deg: 0.0,
            yaw_deg: size,
        }),
        EffectKind::BeamDivergence => Injection::Predicted(Effect::BeamDivergence {
            horizontal_mrad: size,
            vertical_mrad: size / 2.0,
            sub_rays_per_axis: 5,
            range_separation_m: 0.5,
            first_echo_share: None,
            pattern: FootprintPattern::Grid,
        }),
        _ => return None,
    })
}

/// A measured return this close to the model's prediction is of the surface the model
/// predicts, and an effect that moves the prediction moves it alike: far beyond the runs'
/// noise and survey error (centimetres), far below the depth step of an edge (10 cm plus 5 %
/// of the range, see `Feature::is_edge`). A return farther off is of another surface (the
/// reference's error put the beam across an edge): the injection leaves it, where adding the
/// prediction's change would make up a range no surface has.
const SAME_SURFACE_M: f32 = 0.3;

/// A measured range (NaN: none) after a geometric effect moved the model's prediction of it
/// from `predicted` to `after` (NaN: none); `residual` is the run's own, for a return the
/// effect adds.
fn moved(measured: f32, predicted: f32, after: f32, residual: f32) -> f32 {
    match (
        measured.is_finite(),
        predicted.is_finite(),
        after.is_finite(),
    ) {
        // The return is the surface the model predicts: it moves with it.
        (true, true, true) if (measured - predicted).abs() < SAME_SURFACE_M => {
            measured + (after - predicted)
        }
        // The effect takes the return away (the beam left the object, a threshold).
        (true, true, false) => f32::NAN,
        // The effect makes a return where the model had none (a footprint beyond an edge).
        (false, false, true) => after + residual,
        // A return of another surface, or one the model does not predict (something the
        // scene lacks), stays; a predicted return the sensor missed stays missed.
        _ => measured,
    }
}

/// The set's measured ranges with `injection` applied (see the module doc); `salt` fixes the
/// draws, so that every size of one search draws alike.
fn inject(
    set: &RunSet,
    model: &ModelFile,
    injection: &Injection,
    present: Option<&Effect>,
    salt: u64,
) -> Result<Measured, GapError> {
    // A geometric effect is injected with the model's detection threshold left out of both
    // casts: which returns a threshold takes stays the data's own. The threshold the
    // workflow fitted on these runs already absorbed whatever power the effect (a divergent
    // beam's spread) moves across it; injecting the effect through the fitted threshold again
    // would remove returns a second time, a loss no sensor with the effect shows.
    let base = match injection {
        Injection::Predicted(e) if e.kind() != EffectKind::DetectionThreshold => {
            let mut m = model.clone();
            m.effects
                .retain(|e| e.kind() != EffectKind::DetectionThreshold);
            m
        }
        _ => model.clone(),
    };
    // The data as they are hold the effect at about the size its candidate was fitted at
    // (`present`): the injection takes them from there to `injection`'s size, so that the
    // limit is a size of the effect in the data, not one on top of it. (On the parking demo
    // the truth's 3 mrad divergence is in the data, fitted at 1.4 mrad and not added; an
    // injection on top said 1.4 mrad more would have been seen.)
    let now = match (injection, present) {
        (Injection::Predicted(_), Some(p)) => set.cast_recorded(&with_effect(&base, p.clone()))?,
        _ => set.cast_recorded(&base)?,
    };
    let with = match injection {
        Injection::Predicted(e) => Some(set.cast_recorded(&with_effect(&base, e.clone()))?),
        _ => None,
    };
    let injection = &match (injection, present) {
        (Injection::Noise(s), Some(Effect::RangeNoise { sigma_m })) => {
            Injection::Noise((s * s - sigma_m * sigma_m).max(0.0).sqrt())
        }
        (Injection::Dropout(p), Some(Effect::RandomDropout { probability })) => {
            Injection::Dropout(((p - probability) / (1.0 - probability)).max(0.0))
        }
        (i, _) => i.clone(),
    };
    let mut out = Vec::with_capacity(now.len());
    for (r, o) in now.iter().enumerate() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(
            salt ^ (r as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15),
        );
        // The run's own residuals on surfaces, for returns the effect adds.
        let residuals: Vec<f32> = o
            .iter()
            .filter(|x| x.measured.is_finite() && x.predicted.is_finite())
            .map(|x| x.measured - x.predicted)
            .filter(|e| e.abs() < 0.5)
            .collect();
        let mut m = Vec::with_capacity(o.len());
        for (i, x) in o.iter().enumerate() {
            // Drawn for every slot, used or not: slot i draws the same at every size.
            let (u, z, pick): (f64, f64, usize) = (
                rng.random(),
                rng.sample(rand_distr::StandardNormal),
                rng.random_range(0..residuals.len().max(1)),
            );
            let v = match injection {
                _ if !x.cast => x.measured,
                Injection::Noise(s) if x.measured.is_finite() => x.measured + (s * z) as f32,
                Injection::Dropout(p) if x.measured.is_finite() && u < *p => f32::NAN,
                Injection::Noise(_) | Injection::Dropout(_) => x.measured,
                Injection::Predicted(_) => moved(
                    x.measured,
                    x.predicted,
                    with.as_ref().map_or(f32::NAN, |w| w[r][i].predicted),
                    residuals.get(pick).copied().unwrap_or(0.0),
                ),
            };
            m.push(v);
        }
        out.push(m);
    }
    Ok(out)
}

/// Whether the workflow would have added `kind` to `model` had the runs held `injection`: the
/// candidate fitted on the parameterization runs is eligible, and the model with it improves
/// the validation runs' likelihood beyond their noise.
fn seen(
    (fit, val): (&RunSet, &RunSet),
    model: &ModelFile,
    kind: EffectKind,
    (injection, present): (&Injection, Option<&Effect>),
    salt: u64,
) -> Result<bool, GapError> {
    let (mf, mv) = (
        inject(fit, model, injection, present, salt)?,
        inject(val, model, injection, present, salt ^ 0x7661)?,
    );
    fit.with_measured(mf, |fit| {
        val.with_measured(mv, |val| {
            let now = fit.evaluate(model, None)?;
            let fitting = Fitting::of(fit, model, &now);
            let Some(c) = fitting.fit(kind)? else {
                return Ok(false);
            };
            let Some(effect) = c.fitted.clone().filter(|_| c.eligible) else {
                tracing::debug!(
                    "detection limit of {kind}: {injection:?}: not eligible: {:?} gain {:.1} {:?} ({})",
                    c.params,
                    c.gain,
                    c.gain_interval,
                    c.note.as_deref().unwrap_or("")
                );
                return Ok(false);
            };
            let next = c
                .refitted
                .iter()
                .fold(with_effect(model, effect), |m, e| with_effect(&m, e.clone()));
            let before = val.evaluate(model, None)?;
            let trial = val.evaluate(&next, Some(&before.scales))?;
            let gain = val.gain(&trial.scored, &before.scored);
            tracing::debug!(
                "detection limit of {kind}: {injection:?}: fitted {:?}, validation gain {:.1} {:?}",
                c.params,
                gain.total,
                gain.interval
            );
            Ok(gain.interval.is_some_and(|(lo, _)| lo > 0.0))
        })
    })
}

/// What a search found: the smallest strength seen, the largest missed below it, every try.
#[derive(Debug)]
struct Outcome {
    seen_at: Option<f64>,
    missed_at: Option<f64>,
    tries: Vec<Try>,
}

/// The search over sizes (see the module doc): `test` says whether a size is seen.
fn search(
    start: f64,
    largest: f64,
    test: &mut dyn FnMut(f64) -> Result<bool, GapError>,
) -> Result<Outcome, GapError> {
    let mut tries = Vec::new();
    let mut missed = None;
    let mut size = start;
    loop {
        let s = test(size)?;
        tries.push(Try { size, seen: s });
        if s {
            break;
        }
        missed = Some(size);
        if size >= largest {
            return Ok(Outcome {
                seen_at: None,
                missed_at: missed,
                tries,
            });
        }
        size = (size * 2.0).min(largest);
    }
    let mut seen_at = size;
    if let Some(m) = missed {
        let mid = (m * seen_at).sqrt();
        let s = test(mid)?;
        tries.push(Try { size: mid, seen: s });
        if s {
            seen_at = mid;
        } else {
            missed = Some(mid);
        }
    }
    Ok(Outcome {
        seen_at: Some(seen_at),
        missed_at: missed,
        tries,
    })
}

/// The strength of `effect` as its search measures it (see [`Searched`]).
fn strength_of(effect: &Effect) -> Option<f64> {
    Some(match *effect {
        Effect::RangeBias { bias_m } => bias_m,
        Effect::RangeNoise { sigma_m } => sigma_m,
        Effect::RandomDropout { probability } => probability,
        Effect::DetectionThreshold {
            reference_range_m,
            reference_reflectivity,
        } => reference_reflectivity / (reference_range_m * reference_range_m),
        Effect::TimeOffset { offset_ms } => offset_ms,
        Effect::MountMisalignment { yaw_deg, .. } => yaw_deg,
        Effect::BeamDivergence {
            horizontal_mrad, ..
        } => horizontal_mrad,
        _ => return None,
    })
}

/// The detection limit of every effect of the catalogue `model` lacks, on these runs;
/// `fitted` are the last round's candidates, fitted to the runs under `model` (what the data
/// hold of each effect, added or not).
pub fn limits(
    (fit, val): (&RunSet, &RunSet),
    model: &ModelFile,
    fitted: &[super::candidates::Candidate],
    progress: &dyn Fn(EffectKind),
) -> Result<Vec<DetectionLimit>, GapError> {
    let has = |kind: EffectKind| model.effects.iter().any(|e| e.kind() == kind);
    let mut out = Vec::new();
    for kind in super::candidates::CATALOGUE {
        // Motion distortion is on unless the model switches it off: only then is it lacking.
        let lacking = match kind {
            EffectKind::MotionDistortion => model
                .effects
                .iter()
                .any(|e| matches!(e, Effect::MotionDistortion { enabled: false })),
            // The weather acts through a detection threshold; without one it is no candidate.
            EffectKind::Weather => !has(kind) && has(EffectKind::DetectionThreshold),
            _ => !has(kind),
        };
        if !lacking {
            continue;
        }
        let mut limit = DetectionLimit {
            effect: kind,
            parameter: Cow::Borrowed(""),
            unit: Cow::Borrowed(""),
            seen_at: None,
            missed_at: None,
            tries: Vec::new(),
            note: None,
            at_most: false,
            refused: false,
        };
        match searched(kind, fit, model)? {
            Err(why) => limit.note = Some(why.to_owned()),
            Ok(s) => {
                progress(kind);
                limit.parameter = Cow::Borrowed(s.parameter);
                limit.unit = Cow::Borrowed(s.unit);
                limit.at_most = s.at_most;
                let salt = 0x6c69_6d69_7400 ^ kind as u64;
                let present = fitted
                    .iter()
                    .find(|c| c.effect == kind)
                    .and_then(|c| c.fitted.as_ref());
                // Sizes up to what the data hold already are the data as they are: the
                // search starts there.
                let start = present
                    .and_then(strength_of)
                    .filter(|x| x.is_finite())
                    .map_or(s.start, |x| s.start.max(x).min(s.largest));
                let Outcome {
                    seen_at,
                    missed_at,
                    tries,
                } = search(start, s.largest, &mut |size| match injection(kind, size) {
                    Some(inj) => seen((fit, val), model, kind, (&inj, present), salt),
                    None => Ok(false),
                })?;
                let p = s.parameter_of;
                limit.seen_at = seen_at.map(p);
                limit.missed_at = missed_at.map(p);
                limit.tries = tries
                    .into_iter()
                    .map(|t| Try {
                        size: p(t.size),
                        seen: t.seen,
                    })
                    .collect();
            }
        }
        out.push(limit);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_search_doubles_to_the_first_size_seen_then_halves_the_step() {
        // Seen from 0.03 on, starting at 0.005: 0.005, 0.01, 0.02 missed, 0.04 seen, then
        // √(0.02 · 0.04) = 0.028 missed.
        let mut asked = Vec::new();
        let Outcome {
            seen_at: seen,
            missed_at: missed,
            tries,
        } = search(0.005, 1.0, &mut |s| {
            asked.push(s);
            Ok(s >= 0.03)
        })
        .unwrap();
        assert_eq!(seen, Some(0.04));
        assert!((missed.unwrap() - (0.02f64 * 0.04).sqrt()).abs() < 1e-12);
        assert_eq!(tries.len(), 5);
        assert_eq!(asked.len(), 5);
        assert!(tries[..3].iter().all(|t| !t.seen) && tries[3].seen && !tries[4].seen);
        // Seen at the start: the floor is the limit, nothing missed.
        let o = search(0.005, 1.0, &mut |_| Ok(true)).unwrap();
        assert_eq!(
            (o.seen_at, o.missed_at, o.tries.len()),
            (Some(0.005), None, 1)
        );
        // Never seen: stops at the largest size, which is tried.
        let o = search(0.005, 0.03, &mut |_| Ok(false)).unwrap();
        assert_eq!(o.seen_at, None);
        assert_eq!(o.missed_at, Some(0.03));
        assert_eq!(o.tries.last().unwrap().size, 0.03);
        // The halved step seen: it is the limit.
        let o = search(1.0, 100.0, &mut |s| Ok(s >= 5.0)).unwrap();
        assert!((o.seen_at.unwrap() - 32f64.sqrt()).abs() < 1e-12);
        assert_eq!(o.missed_at, Some(4.0));
    }

    #[test]
    fn a_geometric_effect_moves_the_returns_of_the_predicted_surface_only() {
        let nan = f32::NAN;
        // On the predicted surface (2 cm off): moved by the prediction's change.
        assert!((moved(10.02, 10.0, 10.5, 0.01) - 10.52).abs() < 1e-5);
        // Another surface (the reference put the beam across an edge): left.
        assert_eq!(moved(14.0, 10.0, 10.5, 0.01), 14.0);
        // Taken away, added (with the run's residual), never there.
        assert!(moved(10.02, 10.0, nan, 0.01).is_nan());
        assert!((moved(nan, nan, 7.0, 0.01) - 7.01).abs() < 1e-6);
        assert!(moved(nan, nan, nan, 0.01).is_nan());
        // A predicted return the sensor missed stays missed; an unpredicted return stays.
        assert!(moved(nan, 10.0, 10.5, 0.01).is_nan());
        assert_eq!(moved(3.0, nan, nan, 0.01), 3.0);
    }

    #[test]
    fn a_limit_s_line_says_what_would_have_been_seen_and_what_was_missed() {
        let mut l = DetectionLimit {
            effect: EffectKind::RangeBias,
            parameter: "bias_m".into(),
            unit: "m, a constant added to every range".into(),
            seen_at: Some(0.0141),
            missed_at: Some(0.01),
            tries: vec![],
            note: None,
            at_most: false,
            refused: false,
        };
        assert_eq!(
            l.line(),
            "range_bias: none found; would have seen bias_m ≥ 0.0141 (m, a constant added to every range; 0.0100 missed)"
        );
        l.seen_at = None;
        l.tries = vec![Try {
            size: 0.64,
            seen: false,
        }];
        assert!(
            l.line().contains("would not have seen bias_m up to 0.640"),
            "{}",
            l.line()
        );
        assert_eq!(l.short(), "range_bias (not seen at any size tried)");
        l.seen_at = Some(0.0141);
        assert_eq!(l.short(), "range_bias bias_m ≥ 0.0141");
        l.note = Some("a switch, it has no size".into());
        assert!(l
            .line()
            .ends_with("no detection limit (a switch, it has no size)"));
    }
}

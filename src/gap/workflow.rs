//! The rounds of the gap workflow: re-simulate, bin the disagreement, fit and score every
//! candidate on the parameterization runs, add the best, and keep it only if it improves the
//! validation runs by more than their noise; until no candidate helps.
//!
//! After every completed round the fitted model (`model.fitted.toml`) and `gap.json` are
//! rewritten (to a temporary file, then renamed), so an interrupted study leaves the last
//! completed round's results in the output directory.

use super::bins::tables;
use super::bootstrap::{self, Blocks};
use super::candidates::{random_of, with_effect, Candidate, Fitting};
use super::casts::Casts;
use super::full_metrics::run_metrics;
use super::likelihood::{self, Scales, Scored};
use super::observe::{count_scans, evaluate, features, load_run, Feature, Obs, RunData};
use super::report::{
    alike, confounded_line, describe, firing_stats, no_effect_line, save, summary_line, GapReport,
    Round, RunInfo, Trial,
};
use super::study::{Role, Study};
use super::GapError;
use crate::sim::model::ModelFile;
use rayon::prelude::*;
use std::path::PathBuf;

/// How the workflow runs.
#[derive(Clone, Debug)]
pub struct Options {
    /// Output directory.
    pub out: PathBuf,
    /// Firings sampled over all runs (shared equally).
    pub firings: usize,
    /// Use runs that fail `check`.
    pub force: bool,
    /// At most this many effects are added.
    pub max_rounds: usize,
    /// Also re-simulate the validation runs in full for OCR^K and the traffic light.
    pub full_metrics: bool,
}

/// What the workflow reports as it goes.
pub trait Progress: Sync {
    /// A phase starts (loading, a round's casting, a candidate, validation).
    fn phase(&self, round: usize, what: &str);
}

/// A model's observations, scores and the residual scales used, per run.
struct Evaluation {
    obs: Vec<Vec<Obs>>,
    scored: Vec<Scored>,
    scales: Vec<Scales>,
}

struct Set {
    runs: Vec<RunData>,
    feats: Vec<Vec<Feature>>,
    blocks: Blocks,
    resamples: Vec<Vec<u32>>,
    /// Casts kept from round to round.
    casts: Casts,
}

impl Set {
    fn new(runs: Vec<RunData>, feats: Vec<Vec<Feature>>, seed: u64) -> Set {
        let blocks = Blocks::new(&runs.iter().map(|r| r.scans).collect::<Vec<_>>());
        let resamples = blocks.resamples(seed);
        Set {
            runs,
            feats,
            blocks,
            resamples,
            casts: Casts::default(),
        }
    }

    /// Observations and scores of `model`, with the residual scales `scales` (per run), or
    /// the ones of these observations when `None`; the scales are returned too.
    fn evaluate(
        &self,
        model: &ModelFile,
        scales: Option<&[Scales]>,
    ) -> Result<Evaluation, GapError> {
        let random = random_of(model);
        let obs = self.casts.of(&self.runs, model)?;
        let scales: Vec<Scales> = match scales {
            Some(s) => s.to_vec(),
            None => obs
                .iter()
                .zip(&self.feats)
                .map(|(o, f)| likelihood::scales(o, f))
                .collect(),
        };
        let scored = obs
            .iter()
            .zip(&self.runs)
            .zip(&self.feats)
            .zip(&scales)
            .map(|(((o, r), f), s)| likelihood::score(o, f, random, s, r.range_quantum_m, r.scans))
            .collect();
        Ok(Evaluation {
            obs,
            scored,
            scales,
        })
    }

    fn gain(&self, new: &[Scored], old: &[Scored]) -> (f64, Option<(f64, f64)>) {
        let mut per_block = vec![0.0; self.blocks.len()];
        for (r, (a, b)) in new.iter().zip(old).enumerate() {
            for (s, (x, y)) in a.per_scan.iter().zip(&b.per_scan).enumerate() {
                per_block[self.blocks.of(r, s as u32)] += x - y;
            }
        }
        (
            per_block.iter().sum(),
            bootstrap::sum_interval(&per_block, &self.resamples),
        )
    }
}

/// A measured return this close to the start model's agrees with the scene: far more than the
/// reference's errors (centimetres) and any effect of the catalogue at its documented size
/// moves most returns, far less than a different site or a moved object.
const BELONG_M: f64 = 0.5;
/// The share of returns on the scene's objects that must agree: most of them. Measured on the
/// gap drive (tests/gap.rs) with the catalogue's largest documented geometric effects left out
/// of the start model (a 2° mount yaw or pitch, a 50 ms time offset, a frame-based
/// simulation, heavy rain): at least 81 % agree; with the scene 30 m off, none; with its
/// objects mirrored across the drive, 35 % in the first half of the run.
const BELONG_SHARE_OBJECTS: f64 = 0.5;
/// Object returns needed before their share is judged (its sampling error is then at most
/// 5 %); a run with fewer is judged on all its returns, of which at least this share must
/// agree (a 2° mount pitch leaves a third of them: the ground at grazing incidence).
const BELONG_MIN_OBJECTS: usize = 100;
/// See [`BELONG_MIN_OBJECTS`].
const BELONG_SHARE_ALL: f64 = 0.3;

/// How many of a run's measured returns lie within [`BELONG_M`] of the start model's: of all,
/// and of those whose ideal beam meets one of the scene's objects. A flat ground agrees with
/// any trajectory over it and holds half the returns of a car's lidar, so a run of another
/// site, or a scene whose objects were moved, passed on all returns: the objects decide
/// where there are enough of them. Returns where the scene has nothing (a partial twin of
/// the site) say nothing either way.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Agreement {
    /// (agreeing, measured) over all cast firings.
    all: (usize, usize),
    /// The same over firings whose ideal beam meets an object.
    objects: (usize, usize),
}

impl Agreement {
    fn of(obs: &[Obs], feats: &[Feature]) -> Agreement {
        let mut a = Agreement::default();
        for (o, f) in obs.iter().zip(feats) {
            if !(o.cast && o.measured.is_finite()) {
                continue;
            }
            let near =
                o.predicted.is_finite() && f64::from((o.measured - o.predicted).abs()) < BELONG_M;
            let object = f.range > 0.0 && !f.ground;
            for (count, yes) in [(&mut a.all, true), (&mut a.objects, object)] {
                if yes {
                    count.0 += usize::from(near);
                    count.1 += 1;
                }
            }
        }
        a
    }

    /// Why the run does not belong to the scene, if it does not.
    fn mismatch(&self) -> Option<String> {
        let low = |(near, n): (usize, usize), share: f64| (near as f64) < share * n as f64;
        if self.objects.1 >= BELONG_MIN_OBJECTS {
            low(self.objects, BELONG_SHARE_OBJECTS).then(|| format!(
                "only {} of {} measured returns lie within {BELONG_M} m of the object the start model's beam meets",
                self.objects.0, self.objects.1
            ))
        } else {
            (self.all.1 == 0 || low(self.all, BELONG_SHARE_ALL)).then(|| {
                format!(
                    "only {} of {} measured returns lie within {BELONG_M} m of the start model's",
                    self.all.0, self.all.1
                )
            })
        }
    }
}

/// Why the parameterization or the validation runs (each given as (name, usable scans)) are
/// too short to judge an effect by, if they are: each set needs [`bootstrap::MIN_SCANS`].
fn too_few_scans(fit: &[(String, usize)], val: &[(String, usize)]) -> Option<String> {
    let short: Vec<String> = [("parameterization", fit), ("validation", val)]
        .iter()
        .filter_map(|(what, runs)| {
            let n: usize = runs.iter().map(|r| r.1).sum();
            (n < bootstrap::MIN_SCANS).then(|| {
                let each: Vec<String> = runs
                    .iter()
                    .map(|(name, k)| format!("{name}: {k}"))
                    .collect();
                format!(
                    "the {what} runs hold {n} usable scans ({})",
                    each.join(", ")
                )
            })
        })
        .collect();
    (!short.is_empty()).then(|| {
        format!(
            "too few scans to judge an effect by: {}; each needs at least {} (two bootstrap blocks of {} scans: with one, an effect's gain has no interval); record longer runs or add runs (scans `check` left out do not count)",
            short.join(" and "),
            bootstrap::MIN_SCANS,
            bootstrap::BLOCK_SCANS
        )
    })
}

/// Runs the workflow on `study`; returns the report (also written to `opts.out`).
///
/// The output folder is made first, so that an unwritable one fails before minutes of work;
/// if the study then fails before anything is written into it, the folder made here is
/// removed again: bad input leaves nothing behind.
pub fn run(study: &Study, opts: &Options, progress: &dyn Progress) -> Result<GapReport, GapError> {
    let made = !opts.out.exists();
    std::fs::create_dir_all(&opts.out)
        .map_err(|e| GapError::Output(format!("{}: {e}", opts.out.display())))?;
    let result = run_in(study, opts, progress);
    if result.is_err() && made {
        // Only an empty folder goes: rounds already saved stay.
        let _ = std::fs::remove_dir(&opts.out);
    }
    result
}

#[allow(
    clippy::too_many_lines,
    reason = "the rounds in order: load, evaluate, candidates, trials, metrics, save; each step is a call"
)]
fn run_in(study: &Study, opts: &Options, progress: &dyn Progress) -> Result<GapReport, GapError> {
    let rig = match &study.rig {
        Some(p) => Some(crate::rig::Rig::load(p).map_err(|e| GapError::Input(e.to_string()))?),
        None => None,
    };
    let mut scenes: Vec<Option<crate::scene::Scene>> =
        study.scenes()?.into_iter().map(Some).collect();
    progress.phase(0, "loading and checking the runs");
    // One run: first half fits, second half validates.
    // (study run, role, scans) of each part.
    type Part = (usize, Role, Option<(usize, usize)>);
    let mut parts: Vec<Part> = Vec::new();
    let mut split = None;
    if study.runs.len() == 1 {
        let n = count_scans(&study.runs[0].recording)?;
        parts.push((0, Role::Fit, Some((0, n / 2))));
        parts.push((0, Role::Validate, Some((n / 2, n))));
        split = Some(format!(
            "a single run: scans 0..{} fit the model, scans {}..{n} validate it (Rosenberger et al. 2019, §4: parameterization and validation data must differ)",
            n / 2,
            n / 2
        ));
    } else {
        parts.extend(
            study
                .runs
                .iter()
                .enumerate()
                .map(|(i, r)| (i, r.role, None)),
        );
    }
    // Each part with its scene (a split run needs its scene twice).
    let mut with_scenes = Vec::with_capacity(parts.len());
    for &(i, role, part) in &parts {
        let r = &study.runs[i];
        let scene = match scenes[i].take() {
            Some(s) => s,
            None => crate::scene::Scene::load(&r.scene_path)
                .map_err(|e| GapError::Input(e.to_string()))?,
        };
        with_scenes.push((r, role, part, scene));
    }
    // The runs are checked and sampled side by side (a check is one thread's work); the first
    // run that cannot be used, in the study's order, is the one reported.
    let per_run = opts.firings / parts.len().max(1);
    let loaded: Vec<Result<RunData, GapError>> = with_scenes
        .into_par_iter()
        .map(|(r, role, part, scene)| {
            load_run(
                &r.recording,
                scene,
                &r.scene_path,
                rig.as_ref(),
                role,
                part,
                per_run,
                opts.force,
            )
        })
        .collect();
    let loaded: Vec<RunData> = loaded.into_iter().collect::<Result<_, _>>()?;
    let (fit_runs, val_runs): (Vec<RunData>, Vec<RunData>) =
        loaded.into_iter().partition(|r| r.role == Role::Fit);
    let usable = |runs: &[RunData]| -> Vec<(String, usize)> {
        runs.iter()
            .map(|r| (r.name.clone(), r.usable_scans))
            .collect()
    };
    if let Some(why) = too_few_scans(&usable(&fit_runs), &usable(&val_runs)) {
        return Err(GapError::Input(why));
    }
    let feats = |runs: &[RunData]| -> Result<Vec<Vec<Feature>>, GapError> {
        runs.iter().map(|r| features(r, &study.model)).collect()
    };
    let (fit_feats, val_feats) = (feats(&fit_runs)?, feats(&val_runs)?);
    let infos: Vec<RunInfo> = fit_runs
        .iter()
        .chain(&val_runs)
        .map(|r| RunInfo {
            name: r.name.clone(),
            role: r.role,
            check: r.verdict,
            sampled_firings: r.packets.len() * super::observe::SLOTS,
            left_out: r.left_out.clone(),
            damage: r.damage.clone(),
        })
        .collect();
    let fit = Set::new(fit_runs, fit_feats, 0x6a70);
    let val = Set::new(val_runs, val_feats, 0x7661);
    // A run that does not match its scene is not a lidar effect.
    for (r, f) in fit
        .runs
        .iter()
        .zip(&fit.feats)
        .chain(val.runs.iter().zip(&val.feats))
    {
        let obs = evaluate(r, &study.model)?;
        let agreement = Agreement::of(&obs, f);
        tracing::debug!("{}: returns near the start model's: {agreement:?}", r.name);
        if agreement.all.1 == 0 {
            return Err(GapError::Input(format!(
                "{}: no measured point on any firing the start model casts in scene {}: a lidar that measured nothing (covered, or a threshold no target reaches) shows no effect to fit",
                r.name,
                r.scene_path.display()
            )));
        }
        if let Some(why) = agreement.mismatch() {
            return Err(GapError::Input(format!(
                "{}: {why} in scene {}: the run and the scene do not belong together (a different site, objects moved, or a trajectory far off)",
                r.name,
                r.scene_path.display()
            )));
        }
    }

    let mut model = study.model.clone();
    model.name = format!("{} (gap-fitted)", study.model.name);
    let mut report = GapReport {
        start_model: study.model_path.display().to_string(),
        runs: infos,
        split,
        floors: super::candidates::FLOORS
            .iter()
            .map(|&(effect, floor)| super::report::Floor {
                effect,
                floor: floor.to_owned(),
            })
            .collect(),
        rounds: Vec::new(),
        finished: false,
        summary: Vec::new(),
        ended: None,
    };
    // What the workflow did not look at, first: a stretch whose reference is not usable would
    // have shown its trajectory error as a lidar effect.
    for r in &report.runs {
        for m in &r.left_out {
            report.summary.push(format!(
                "{}: {:.1} .. {:.1} s left out ({}: `check` marks the reference not usable there)",
                r.name, m.from_s, m.to_s, m.name
            ));
        }
    }
    save(&opts.out, &model, &report)?;
    let metrics_dir = opts.out.join("sim");
    let mut measured = Vec::new();
    let mut metrics_now = if opts.full_metrics && report.split.is_none() {
        progress.phase(0, "re-simulating the validation runs with the start model");
        Some(run_metrics(
            &val.runs,
            &model,
            &metrics_dir,
            "round-0",
            &mut measured,
        )?)
    } else {
        None
    };
    for round in 1..=opts.max_rounds {
        fit.casts.next_round();
        val.casts.next_round();
        tracing::debug!(
            "round {round}: {} casts of the parameterization runs and {} of the validation runs kept from the round before",
            fit.casts.len(),
            val.casts.len()
        );
        progress.phase(round, "re-simulating the parameterization runs");
        let Evaluation {
            obs,
            scored,
            scales,
        } = fit.evaluate(&model, None)?;
        let pairs: Vec<(&[Obs], &[Feature])> = obs
            .iter()
            .zip(&fit.feats)
            .map(|(o, f)| (o.as_slice(), f.as_slice()))
            .collect();
        let bins = tables(&pairs);
        let fitting = Fitting {
            runs: &fit.runs,
            feats: &fit.feats,
            current: &model,
            obs: &obs,
            scored: &scored,
            scales: &scales,
            blocks: &fit.blocks,
            resamples: &fit.resamples,
            casts: &fit.casts,
        };
        let candidates =
            fitting.all(&|name| progress.phase(round, &format!("candidate {name}")))?;
        let mut this = Round {
            round,
            disagreeing_bins: describe(&bins),
            bins,
            candidates: candidates.clone(),
            trials: Vec::new(),
            chosen: None,
            parameters: Vec::new(),
            metrics_before: metrics_now.clone(),
            metrics_after: None,
        };
        progress.phase(round, "validating");
        let Evaluation {
            obs: val_obs,
            scored: val_scored,
            scales: val_scales,
        } = val.evaluate(&model, None)?;
        let before = firing_stats(&val_obs, &val.feats, &val_scored);
        // The first eligible candidate that improves the validation runs is added; but when
        // others explain the parameterization runs as well as it does (confounded, see
        // `alike`), their ranking is no evidence, and of those the one that improves the
        // validation runs most is added.
        let mut accepted: Option<(Candidate, ModelFile, f64)> = None;
        for c in candidates.iter().filter(|c| c.eligible) {
            if accepted.as_ref().is_some_and(|(a, _, _)| !alike(a, c)) {
                continue;
            }
            let Some(effect) = c.fitted.clone() else {
                continue;
            };
            let next = c.refitted.iter().fold(with_effect(&model, effect), |m, e| {
                with_effect(&m, e.clone())
            });
            let Evaluation {
                obs: o2,
                scored: s2,
                ..
            } = val.evaluate(&next, Some(&val_scales))?;
            let (gain, interval) = val.gain(&s2, &val_scored);
            let kept = interval.is_some_and(|(lo, _)| lo > 0.0);
            this.trials.push(Trial {
                effect: c.effect,
                gain,
                gain_interval: interval,
                before: before.clone(),
                after: firing_stats(&o2, &val.feats, &s2),
                kept,
            });
            if kept && accepted.as_ref().is_none_or(|(_, _, g)| gain > *g) {
                accepted = Some((c.clone(), next, gain));
            }
        }
        let Some((c, next, _)) = accepted else {
            let line = no_effect_line(round, &candidates, &this.trials);
            report.ended = Some(line.clone());
            report.summary.push(line);
            report.rounds.push(this);
            break;
        };
        model = next;
        this.chosen = Some(c.effect);
        this.parameters = c.params.clone();
        if opts.full_metrics && report.split.is_none() {
            progress.phase(
                round,
                "re-simulating the validation runs with the new model",
            );
            let after = run_metrics(
                &val.runs,
                &model,
                &metrics_dir,
                &format!("round-{round}"),
                &mut measured,
            )?;
            this.metrics_after = Some(after.clone());
            metrics_now = Some(after);
        }
        let trial = this
            .trials
            .iter()
            .rfind(|t| t.kept && t.effect == c.effect)
            .cloned();
        report
            .summary
            .push(summary_line(&c, trial.as_ref(), &this, val.runs.len()));
        report
            .summary
            .extend(confounded_line(&c, &candidates, &this.trials));
        report.rounds.push(this);
        save(&opts.out, &model, &report)?;
        if round == opts.max_rounds {
            let line = format!(
                "stopped after {round} rounds (--max-rounds): candidates may be left; run again from model.fitted.toml"
            );
            report.ended = Some(line.clone());
            report.summary.push(line);
        }
    }
    report.finished = true;
    save(&opts.out, &model, &report)?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` firings measured at `measured` m where the start model predicts `predicted` m, its
    /// ideal beam meeting the ground or an object.
    fn firings(n: usize, measured: f32, predicted: f32, ground: bool) -> (Vec<Obs>, Vec<Feature>) {
        let o = Obs {
            measured,
            predicted,
            cast: true,
            ..Obs::default()
        };
        let f = Feature {
            range: predicted,
            ground,
            ..Feature::default()
        };
        (vec![o; n], vec![f; n])
    }

    fn agreement(parts: &[(usize, f32, f32, bool)]) -> Agreement {
        let (mut obs, mut feats) = (Vec::new(), Vec::new());
        for &(n, m, p, g) in parts {
            let (o, f) = firings(n, m, p, g);
            obs.extend(o);
            feats.extend(f);
        }
        Agreement::of(&obs, &feats)
    }

    #[test]
    fn a_run_belongs_to_its_scene_when_most_returns_on_its_objects_agree() {
        // The ground agrees (any trajectory over a plane does), the objects do not: refused,
        // although 80 % of all returns agree.
        let moved = agreement(&[(800, 10.0, 10.2, true), (200, 5.0, 9.0, false)]);
        assert_eq!(moved.all, (800, 1000));
        assert_eq!(moved.objects, (0, 200));
        let why = moved.mismatch().expect("refused");
        assert!(why.starts_with("only 0 of 200 measured returns"), "{why}");
        // Most object returns agree (60 %, the rest moved by an effect): it belongs.
        let ok = agreement(&[
            (800, 10.0, 10.2, true),
            (120, 5.0, 5.3, false),
            (80, 5.0, 6.0, false),
        ]);
        assert_eq!(ok.objects, (120, 200));
        assert_eq!(ok.mismatch(), None);
        // 40 % of the object returns: refused.
        let few = agreement(&[(120, 5.0, 6.0, false), (80, 5.0, 5.3, false)]);
        assert!(few.mismatch().is_some());
        // Returns where the model has nothing (sky, a partial twin) count in neither share
        // of objects; measured-less firings count nowhere.
        let partial = agreement(&[
            (150, 5.0, f32::NAN, false),
            (100, 5.0, 5.1, false),
            (500, f32::NAN, 5.0, false),
        ]);
        assert_eq!((partial.all, partial.objects), ((100, 250), (100, 100)));
        assert_eq!(partial.mismatch(), None);
    }

    #[test]
    fn too_few_scans_names_the_short_sets_their_runs_and_the_minimum() {
        let runs = |v: &[(&str, usize)]| -> Vec<(String, usize)> {
            v.iter().map(|(n, k)| ((*n).to_owned(), *k)).collect()
        };
        let why = too_few_scans(
            &runs(&[("a.mcap", 3), ("b.mcap", 2)]),
            &runs(&[("c.mcap", 1)]),
        )
        .expect("refused");
        assert!(
            why.contains("the parameterization runs hold 5 usable scans (a.mcap: 3, b.mcap: 2) and the validation runs hold 1 usable scans (c.mcap: 1); each needs at least 40"),
            "{why}"
        );
        // Enough together: 20 + 20 fit, 40 validate.
        assert_eq!(
            too_few_scans(&runs(&[("a", 20), ("b", 20)]), &runs(&[("c", 40)])),
            None
        );
        let why = too_few_scans(&runs(&[("a", 20), ("b", 20)]), &runs(&[("c", 39)])).unwrap();
        assert!(
            why.contains("the validation runs hold 39") && !why.contains("parameterization"),
            "{why}"
        );
    }

    #[test]
    fn with_few_object_returns_all_returns_are_judged() {
        // 99 object returns, none agreeing: too few to judge; the ground's 80 % agreement holds.
        let a = agreement(&[(800, 10.0, 10.1, true), (99, 5.0, 9.0, false)]);
        assert_eq!(a.mismatch(), None);
        // All returns: fewer than 30 % agree.
        let b = agreement(&[(29, 10.0, 10.1, true), (71, 10.0, 12.0, true)]);
        assert!(b
            .mismatch()
            .unwrap()
            .starts_with("only 29 of 100 measured returns lie within 0.5 m of the start model's"));
        // No measured return at all.
        assert!(agreement(&[(10, f32::NAN, 5.0, true)]).mismatch().is_some());
    }
}

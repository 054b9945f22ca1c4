//! The rounds of the gap workflow: re-simulate, bin the disagreement, fit and score every
//! candidate on the parameterization runs, add the best, and keep it only if it improves the
//! validation runs by more than their noise; until no candidate helps.
//!
//! After every completed round the fitted model (`model.fitted.toml`) and `gap.json` are
//! rewritten (to a temporary file, then renamed), so an interrupted study leaves the last
//! completed round's results in the output directory.

use super::bins::{tables, Table};
use super::bootstrap;
use super::candidates::{with_effect, Candidate, Fitting, Param};
use super::casts::evaluate;
use super::engine::Engine;
use super::full_metrics::{Judged, Watch};
use super::observe::{count_scans, features, load_run, Feature, Obs, RunData};
use super::refit::{joint_refit, Added};
use super::report::{
    alike, confounded_line, describe, firing_stats, no_effect_line, save, summary_line, GapReport,
    Refit, Round, RunInfo, Trial,
};
use super::runset::RunSet;
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
    /// A model known to have made the data, to set the fitted model's metrics beside.
    pub reference_model: Option<PathBuf>,
    /// When no further effect is found: search the detection limit of each one not added
    /// ([`super::limits`]).
    pub detection_limits: bool,
    /// What runs the full re-simulations as trials, a round at a time; `None`: this process,
    /// one run after the other ([`super::engine`]).
    pub engine: Option<std::sync::Arc<dyn super::engine::RoundEngine>>,
}

impl Options {
    /// Where `study`'s full re-simulations run.
    fn engine_for(&self, study: &Study) -> Engine {
        match &self.engine {
            None => Engine::InProcess,
            Some(engine) => Engine::Planned {
                engine: engine.clone(),
                rig: study.rig.clone(),
                force: self.force,
            },
        }
    }
}

/// What the workflow reports as it goes.
pub trait Progress: Sync {
    /// A phase starts (loading, a round's casting, a candidate, validation).
    fn phase(&self, round: usize, what: &str);
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
fn too_few_scans(fit: &[(String, usize)], val: &[(String, usize)]) -> Option<GapError> {
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
    (!short.is_empty()).then_some(GapError::TooFewScans { short })
}

/// Runs the workflow on `study`; returns the report (also written to `opts.out`).
///
/// The output folder is made first, so that an unwritable one fails before minutes of work;
/// if the study then fails before anything is written into it, the folder made here is
/// removed again: bad input leaves nothing behind.
pub fn run(study: &Study, opts: &Options, progress: &dyn Progress) -> Result<GapReport, GapError> {
    let made = !opts.out.exists();
    std::fs::create_dir_all(&opts.out).map_err(|source| GapError::Output {
        path: opts.out.clone(),
        source,
    })?;
    let result = run_in(study, opts, progress);
    if result.is_err() && made {
        // Only an empty folder goes: rounds already saved stay.
        let _ = std::fs::remove_dir(&opts.out);
    }
    result
}

/// The study's runs loaded, checked, sampled and split by role.
struct Loaded {
    fit: RunSet,
    val: RunSet,
    infos: Vec<RunInfo>,
    /// How a single run was split in time, if it was.
    split: Option<String>,
}

/// Loads the study's runs (checked and sampled side by side: a check is one thread's work);
/// the first run that cannot be used, in the study's order, is the one reported. A single run
/// is split in time: its first half fits, its second half validates.
fn load(study: &Study, opts: &Options) -> Result<Loaded, GapError> {
    let rig = match &study.rig {
        Some(p) => Some(crate::rig::Rig::load(p)?),
        None => None,
    };
    let mut scenes: Vec<Option<crate::scene::Scene>> =
        study.scenes()?.into_iter().map(Some).collect();
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
            None => crate::scene::Scene::load(&r.scene_path).map_err(|source| GapError::Scene {
                recording: r.recording.clone(),
                source,
            })?,
        };
        with_scenes.push((r, role, part, scene));
    }
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
    if let Some(e) = too_few_scans(&usable(&fit_runs), &usable(&val_runs)) {
        return Err(e);
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
    Ok(Loaded {
        fit: RunSet::new(fit_runs, fit_feats, 0x6a70),
        val: RunSet::new(val_runs, val_feats, 0x7661),
        infos,
        split,
    })
}

/// Refuses a run that does not match its scene: that is not a lidar effect.
fn refuse_strangers(sets: [&RunSet; 2], start: &ModelFile) -> Result<(), GapError> {
    for set in sets {
        for (r, f) in set.runs.iter().zip(&set.feats) {
            let obs = evaluate(r, start)?;
            let agreement = Agreement::of(&obs, f);
            tracing::debug!("{}: returns near the start model's: {agreement:?}", r.name);
            if agreement.all.1 == 0 {
                return Err(GapError::NothingMeasured {
                    run: r.name.clone(),
                    scene: r.scene_path.clone(),
                });
            }
            if let Some(why) = agreement.mismatch() {
                return Err(GapError::NotItsScene {
                    run: r.name.clone(),
                    scene: r.scene_path.clone(),
                    why,
                });
            }
        }
    }
    Ok(())
}

/// The report before the first round: the runs, the resolution floors, and what the workflow
/// did not look at (a stretch whose reference is not usable would have shown its trajectory
/// error as a lidar effect).
fn first_report(study: &Study, infos: Vec<RunInfo>, split: Option<String>) -> GapReport {
    let mut report = GapReport {
        start_model: study.model_path.display().to_string(),
        runs: infos,
        split,
        floors: super::candidates::FLOORS
            .iter()
            .map(|(effect, floor)| super::report::Floor {
                effect: *effect,
                floor: floor.clone(),
            })
            .collect(),
        rounds: Vec::new(),
        finished: false,
        summary: Vec::new(),
        ended: None,
        reference: None,
        limits: Vec::new(),
    };
    for r in &report.runs {
        for m in &r.left_out {
            report.summary.push(format!(
                "{}: {:.1} .. {:.1} s left out ({}: `check` marks the reference not usable there)",
                r.name, m.from_s, m.to_s, m.name
            ));
        }
    }
    report
}

/// An effect a round added: the candidate, the model with it (the effects added before
/// re-fitted together with it), and its gain on the validation runs.
struct Accepted {
    candidate: Candidate,
    model: ModelFile,
    gain: f64,
    /// The candidate's parameters after the joint re-fit.
    params: Vec<Param>,
    refits: Vec<Refit>,
    /// Its full re-simulation of the validation runs, judged (with full metrics on).
    judged: Option<Judged>,
}

/// The candidates of a round tried on the validation runs (`this.trials` gets each trial):
/// the first eligible candidate that improves the validation runs is added; but when others
/// explain the parameterization runs as well as it does (confounded, see `alike`), their
/// ranking is no evidence, and of those the one that improves the validation runs most is
/// added. "Improves" is the keep rule: the likelihood's gain above zero, and (with `watch`)
/// no validation metric worse beyond its noise ([`super::keep`]).
fn try_candidates(
    (fit, val): (&RunSet, &RunSet),
    model: &ModelFile,
    added: &[Added],
    candidates: &[Candidate],
    mut watch: Option<&mut Watch<'_>>,
    this: &mut Round,
) -> Result<Option<Accepted>, GapError> {
    let now = val.evaluate(model, None)?;
    let before = firing_stats(&now.obs, &val.feats, &now.scored);
    let mut accepted: Option<Accepted> = None;
    for c in candidates.iter().filter(|c| c.eligible) {
        if accepted.as_ref().is_some_and(|a| !alike(&a.candidate, c)) {
            continue;
        }
        let Some(effect) = c.fitted.clone() else {
            continue;
        };
        let next = c.refitted.iter().fold(with_effect(model, effect), |m, e| {
            with_effect(&m, e.clone())
        });
        let (next, params, refits) = joint_refit(fit, next, c, added)?;
        let trial = val.evaluate(&next, Some(&now.scales))?;
        let gain = val.gain(&trial.scored, &now.scored);
        let likelier = gain.interval.is_some_and(|(lo, _)| lo > 0.0);
        let judged = match watch.as_deref_mut() {
            Some(w) if likelier => {
                Some(w.judge(&next, &format!("round-{}-{}", this.round, c.effect))?)
            }
            _ => None,
        };
        let check = judged.as_ref().map(|j| j.check.clone());
        let kept = likelier
            && check
                .as_ref()
                .is_none_or(|m| m.decision != super::keep::Decision::Confounded);
        this.trials.push(Trial {
            effect: c.effect,
            gain: gain.total,
            gain_interval: gain.interval,
            before: before.clone(),
            after: firing_stats(&trial.obs, &val.feats, &trial.scored),
            kept,
            refits: refits.clone(),
            metrics: check,
        });
        if kept && accepted.as_ref().is_none_or(|a| gain.total > a.gain) {
            accepted = Some(Accepted {
                candidate: c.clone(),
                model: next,
                gain: gain.total,
                params,
                refits,
                judged,
            });
        }
    }
    Ok(accepted)
}

/// One round's parameterization side: the current model re-simulated on the fitting runs,
/// the disagreement binned, and every candidate fitted and scored.
fn fit_candidates(
    fit: &RunSet,
    model: &ModelFile,
    round: usize,
    progress: &dyn Progress,
) -> Result<(Vec<Table>, Vec<Candidate>), GapError> {
    progress.phase(round, "re-simulating the parameterization runs");
    let now = fit.evaluate(model, None)?;
    let pairs: Vec<(&[Obs], &[Feature])> = now
        .obs
        .iter()
        .zip(&fit.feats)
        .map(|(o, f)| (o.as_slice(), f.as_slice()))
        .collect();
    let bins = tables(&pairs);
    let fitting = Fitting::of(fit, model, &now);
    let candidates = fitting.all(&|name| progress.phase(round, &format!("candidate {name}")))?;
    Ok((bins, candidates))
}

fn run_in(study: &Study, opts: &Options, progress: &dyn Progress) -> Result<GapReport, GapError> {
    progress.phase(0, "loading and checking the runs");
    let Loaded {
        fit,
        val,
        infos,
        split,
    } = load(study, opts)?;
    refuse_strangers([&fit, &val], &study.model)?;
    let mut model = study.model.clone();
    model.name = format!("{} (gap-fitted)", study.model.name);
    let mut report = first_report(study, infos, split);
    save(&opts.out, &model, &report)?;
    let full_metrics = opts.full_metrics && report.split.is_none();
    let mut added: Vec<Added> = Vec::new();
    let mut watch = if full_metrics {
        progress.phase(0, "re-simulating the validation runs with the start model");
        Some(Watch::start(
            &val.runs,
            &model,
            opts.out.join("sim"),
            opts.engine_for(study),
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
        let (bins, candidates) = fit_candidates(&fit, &model, round, progress)?;
        let mut this = Round {
            round,
            disagreeing_bins: describe(&bins),
            bins,
            candidates: candidates.clone(),
            trials: Vec::new(),
            chosen: None,
            parameters: Vec::new(),
            refits: Vec::new(),
            metrics_before: watch.as_ref().map(|w| w.metrics_now().clone()),
            metrics_after: None,
        };
        progress.phase(round, "validating");
        let Some(Accepted {
            candidate: c,
            model: next,
            params,
            refits,
            judged,
            ..
        }) = try_candidates(
            (&fit, &val),
            &model,
            &added,
            &candidates,
            watch.as_mut(),
            &mut this,
        )?
        else {
            let line = no_effect_line(round, &candidates, &this.trials);
            report.ended = Some(line.clone());
            report.summary.push(line);
            let refused: Vec<_> = this
                .trials
                .iter()
                .filter(|t| t.confounded())
                .map(|t| t.effect)
                .collect();
            report.rounds.push(this);
            if opts.detection_limits {
                // The final round is saved before the search, so that a search that fails
                // loses none of it.
                save(&opts.out, &model, &report)?;
                let mut limits =
                    super::limits::limits((&fit, &val), &model, &candidates, &|kind| {
                        progress.phase(round, &format!("detection limit of {kind}"));
                    })?;
                for l in &mut limits {
                    l.refused = refused.contains(&l.effect);
                }
                report.summary.extend(limits.iter().map(|l| l.line()));
                report.limits = limits;
            }
            break;
        };
        model = next;
        this.chosen = Some(c.effect);
        for r in &refits {
            if let Some(a) = added.iter_mut().find(|a| a.kind == r.effect) {
                a.params.clone_from(&r.after);
            }
        }
        added.push(Added {
            kind: c.effect,
            params: params.clone(),
        });
        this.parameters = params;
        this.refits = refits;
        if let (Some(w), Some(j)) = (watch.as_mut(), judged) {
            this.metrics_after = Some(j.check.after.clone());
            w.accept(j);
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
    if let Some(path) = &opts.reference_model {
        let reference = ModelFile::load(path).map_err(GapError::ReferenceModel)?;
        match watch.as_mut() {
            Some(w) => {
                progress.phase(
                    0,
                    "re-simulating the validation runs with the reference model",
                );
                let r = w.against(&reference, path)?;
                report.summary.push(r.line());
                report.reference = Some(r);
            }
            None => report.summary.push(format!(
                "the reference model {} was not compared: full metrics are off",
                path.display()
            )),
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
        .expect("refused")
        .to_string();
        assert!(
            why.contains("the parameterization runs hold 5 usable scans (a.mcap: 3, b.mcap: 2) and the validation runs hold 1 usable scans (c.mcap: 1); each needs at least 40"),
            "{why}"
        );
        // Enough together: 20 + 20 fit, 40 validate.
        assert!(too_few_scans(&runs(&[("a", 20), ("b", 20)]), &runs(&[("c", 40)])).is_none());
        let why = too_few_scans(&runs(&[("a", 20), ("b", 20)]), &runs(&[("c", 39)]))
            .unwrap()
            .to_string();
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

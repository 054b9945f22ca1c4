//! The rounds of the gap workflow: re-simulate, bin the disagreement, fit and score every
//! candidate on the parameterization runs, add the best, and keep it only if it improves the
//! validation runs by more than their noise; until no candidate helps.
//!
//! After every completed round the fitted model (`model.fitted.toml`) and `gap.json` are
//! rewritten (to a temporary file, then renamed), so an interrupted study leaves the last
//! completed round's results in the output directory.

use super::bins::{tables, Table};
use super::bootstrap::{self, Blocks};
use super::candidates::{random_of, with_effect, Candidate, Fitting, Param};
use super::likelihood::{self, Scored};
use super::observe::{count_scans, evaluate, features, load_run, Feature, Obs, RunData};
use super::study::{Role, Study};
use super::GapError;
use crate::metrics::compare::{compare, Options as CompareOptions};
use crate::metrics::grid::Dims;
use crate::metrics::roi::Region;
use crate::sim::model::ModelFile;
use crate::sim::resim::{resim, PoseSource};
use std::path::{Path, PathBuf};

/// How the workflow runs.
#[derive(Clone, Debug)]
pub struct Options {
    /// Output directory.
    pub out: PathBuf,
    /// Firings sampled per run.
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

/// Per-firing statistics of a set of runs under one model.
#[derive(Clone, Debug, serde::Serialize)]
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
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunMetrics {
    /// Mean OCR^K over the validation runs at each run's admissible cell (K = 1, 3D).
    pub ocr: Option<f64>,
    /// Area validation metric per per-scan feature (real validation runs against their
    /// re-simulations), in the feature's unit.
    pub avm: Vec<(String, Option<f64>)>,
    /// Traffic lights per feature.
    pub lights: Vec<(String, String)>,
    /// The validation verdict.
    pub verdict: String,
}

/// An added effect tested on the validation runs.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Trial {
    /// The effect.
    pub effect: &'static str,
    /// Log-likelihood gain on the validation runs, nats.
    pub gain: f64,
    /// Its 95 % block-bootstrap interval.
    pub gain_interval: Option<(f64, f64)>,
    /// Per-firing statistics before and after.
    pub before: FiringStats,
    /// After.
    pub after: FiringStats,
    /// Kept: the interval lies above zero.
    pub kept: bool,
}

/// One round.
#[derive(Clone, Debug, serde::Serialize)]
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
    pub chosen: Option<String>,
    /// Its fitted parameters.
    pub parameters: Vec<Param>,
    /// Full-run metrics on the validation runs before and after (when computed).
    pub metrics_before: Option<RunMetrics>,
    /// After.
    pub metrics_after: Option<RunMetrics>,
}

/// A run as listed in the report.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunInfo {
    /// Name.
    pub name: String,
    /// Role.
    pub role: Role,
    /// The check's verdict.
    pub check: String,
    /// Firings sampled.
    pub sampled_firings: usize,
}

/// Everything `gap.json` holds.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GapReport {
    /// The start model's file.
    pub start_model: String,
    /// The runs.
    pub runs: Vec<RunInfo>,
    /// Set when a single run was split in time.
    pub split: Option<String>,
    /// The resolution floors of the catalogue.
    pub floors: Vec<(String, String)>,
    /// The completed rounds.
    pub rounds: Vec<Round>,
    /// Whether the workflow finished (false while running or when interrupted).
    pub finished: bool,
    /// One line per effect found, or the evidence that none was.
    pub summary: Vec<String>,
}

fn write_atomic(path: &Path, text: &str) -> Result<(), GapError> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| GapError::Output(format!("{}: {e}", path.display())))
}

fn save(out: &Path, model: &ModelFile, report: &GapReport) -> Result<(), GapError> {
    write_atomic(&out.join("model.fitted.toml"), &model.to_toml())?;
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| GapError::Output(format!("gap.json: {e}")))?;
    write_atomic(&out.join("gap.json"), &json)
}

fn firing_stats(obs: &[Vec<Obs>], feats: &[Vec<Feature>], scored: &[Scored]) -> FiringStats {
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

struct Set {
    runs: Vec<RunData>,
    feats: Vec<Vec<Feature>>,
    blocks: Blocks,
    resamples: Vec<Vec<u32>>,
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
        }
    }

    fn evaluate(&self, model: &ModelFile) -> Result<(Vec<Vec<Obs>>, Vec<Scored>), GapError> {
        let random = random_of(model);
        let obs: Vec<Vec<Obs>> = self
            .runs
            .iter()
            .map(|r| evaluate(r, model))
            .collect::<Result<_, _>>()?;
        let scored = obs
            .iter()
            .zip(&self.runs)
            .zip(&self.feats)
            .map(|((o, r), f)| likelihood::score(o, f, random, r.range_quantum_m, r.scans))
            .collect();
        Ok((obs, scored))
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

/// Re-simulates the validation runs in full with `model` into `dir` and measures them.
fn run_metrics(
    val: &[RunData],
    model: &ModelFile,
    dir: &Path,
    tag: &str,
) -> Result<RunMetrics, GapError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| GapError::Output(format!("{}: {e}", dir.display())))?;
    let quiet = |_: u64, _: u64| {};
    let mut sims = Vec::new();
    let mut ocr = Vec::new();
    for (i, r) in val.iter().enumerate() {
        let sim = dir.join(format!("{tag}-validation-{:02}.mcap", i + 1));
        resim(
            &r.path,
            Some(&r.rig),
            &r.scene,
            &r.scene_path,
            model,
            PoseSource::Run,
            true,
            i as u64 + 1,
            &sim,
            &quiet,
        )
        .map_err(|e| GapError::Input(format!("re-simulating {}: {e}", r.name)))?;
        let c = compare(
            &r.path,
            &sim,
            Some(&r.rig),
            Some(&r.scene),
            CompareOptions {
                cell_m: None,
                k: 1,
                dims: Dims::Voxel,
                region: Region::All,
                exclude_ground: true,
                allow_small_cell: false,
                trajectory: None,
                sensor_frame: false,
            },
            &quiet,
        )
        .map_err(|e| GapError::Input(format!("comparing {}: {e}", r.name)))?;
        if let Some(o) = c.summary.ocr_mean {
            ocr.push(o);
        }
        sims.push(sim);
    }
    let reals: Vec<PathBuf> = val.iter().map(|r| r.path.clone()).collect();
    let v = crate::stats::repetitions::validate(&reals, &sims, Some(&val[0].rig), &[])
        .map_err(GapError::Input)?;
    Ok(RunMetrics {
        ocr: (!ocr.is_empty()).then(|| ocr.iter().sum::<f64>() / ocr.len() as f64),
        avm: v.cells.iter().map(|c| (c.metric.clone(), c.avm)).collect(),
        lights: v
            .cells
            .iter()
            .map(|c| (c.metric.clone(), format!("{:?}", c.light).to_lowercase()))
            .collect(),
        verdict: format!("{:?}", v.verdict).to_lowercase(),
    })
}

fn describe(tables: &[Table]) -> Vec<String> {
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

fn params_text(c: &Candidate) -> String {
    c.params
        .iter()
        .filter(|p| p.name != "reference_reflectivity" && p.name != "enabled")
        .map(|p| {
            let unit_digits = if p.name.ends_with("_m") { 3 } else { 2 };
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

/// Runs the workflow on `study`; returns the report (also written to `opts.out`).
#[allow(
    clippy::too_many_lines,
    reason = "the rounds in order: load, evaluate, candidates, trials, metrics, save; each step is a call"
)]
pub fn run(study: &Study, opts: &Options, progress: &dyn Progress) -> Result<GapReport, GapError> {
    std::fs::create_dir_all(&opts.out)
        .map_err(|e| GapError::Output(format!("{}: {e}", opts.out.display())))?;
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
    let loaded: Vec<RunData> = parts
        .iter()
        .map(|&(i, role, part)| {
            let r = &study.runs[i];
            // A split run needs its scene twice.
            let scene = match scenes[i].take() {
                Some(s) => s,
                None => crate::scene::Scene::load(&r.scene_path)
                    .map_err(|e| GapError::Input(e.to_string()))?,
            };
            load_run(
                &r.recording,
                scene,
                &r.scene_path,
                rig.as_ref(),
                role,
                part,
                opts.firings,
                opts.force,
            )
        })
        .collect::<Result<_, _>>()?;
    let (fit_runs, val_runs): (Vec<RunData>, Vec<RunData>) =
        loaded.into_iter().partition(|r| r.role == Role::Fit);
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
            check: format!("{:?}", r.verdict).to_lowercase(),
            sampled_firings: r.packets.len() * super::observe::SLOTS,
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
        let (mut cast, mut both) = (0usize, 0usize);
        let obs = evaluate(r, &study.model)?;
        for (o, _) in obs.iter().zip(f) {
            if o.cast && o.measured.is_finite() {
                cast += 1;
                if o.predicted.is_finite() && (o.measured - o.predicted).abs() < 0.5 {
                    both += 1;
                }
            }
        }
        if cast == 0 || (both as f64) < 0.3 * cast as f64 {
            return Err(GapError::Input(format!(
                "{}: only {both} of {cast} measured returns lie within 0.5 m of the start model's in scene {}: the run and the scene do not belong together (a different site, or a trajectory far off)",
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
            .map(|(a, b)| ((*a).to_owned(), (*b).to_owned()))
            .collect(),
        rounds: Vec::new(),
        finished: false,
        summary: Vec::new(),
    };
    save(&opts.out, &model, &report)?;
    let metrics_dir = opts.out.join("sim");
    let mut metrics_now = if opts.full_metrics && report.split.is_none() {
        progress.phase(0, "re-simulating the validation runs with the start model");
        Some(run_metrics(&val.runs, &model, &metrics_dir, "round-0")?)
    } else {
        None
    };
    for round in 1..=opts.max_rounds {
        progress.phase(round, "re-simulating the parameterization runs");
        let (obs, scored) = fit.evaluate(&model)?;
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
            blocks: &fit.blocks,
            resamples: &fit.resamples,
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
        let (val_obs, val_scored) = val.evaluate(&model)?;
        let before = firing_stats(&val_obs, &val.feats, &val_scored);
        let mut accepted = None;
        for c in candidates.iter().filter(|c| c.eligible) {
            let Some(effect) = c.fitted.clone() else {
                continue;
            };
            let next = with_effect(&model, effect);
            let (o2, s2) = val.evaluate(&next)?;
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
            if kept {
                accepted = Some((c.clone(), next));
                break;
            }
        }
        let Some((c, next)) = accepted else {
            let best = candidates.first();
            report.summary.push(match best {
                Some(b) => format!(
                    "no missing effect found in round {round}: best candidate {} ({}) {}",
                    b.effect,
                    params_text(b),
                    if b.eligible {
                        "did not improve the validation runs beyond their noise".to_owned()
                    } else {
                        format!(
                            "gain {:.1} nats [{}], {}",
                            b.gain,
                            b.gain_interval
                                .map_or("n/a".into(), |(a, z)| format!("{a:.1}, {z:.1}")),
                            b.note.clone().unwrap_or_else(|| "not significant".into())
                        )
                    }
                ),
                None => format!("no missing effect found in round {round}: no candidate left"),
            });
            report.rounds.push(this);
            break;
        };
        model = next;
        this.chosen = Some(c.effect.to_owned());
        this.parameters = c.params.clone();
        if opts.full_metrics && report.split.is_none() {
            progress.phase(
                round,
                "re-simulating the validation runs with the new model",
            );
            let after = run_metrics(&val.runs, &model, &metrics_dir, &format!("round-{round}"))?;
            this.metrics_after = Some(after.clone());
            metrics_now = Some(after);
        }
        let trial = this.trials.last().cloned();
        report
            .summary
            .push(summary_line(&c, trial.as_ref(), &this, val.runs.len()));
        report.rounds.push(this);
        save(&opts.out, &model, &report)?;
    }
    report.finished = true;
    save(&opts.out, &model, &report)?;
    Ok(report)
}

fn summary_line(c: &Candidate, trial: Option<&Trial>, round: &Round, runs: usize) -> String {
    let mut parts = vec![format!("found: {} {}", c.effect, params_text(c))];
    if let (Some(b), Some(a)) = (&round.metrics_before, &round.metrics_after) {
        if let (Some(x), Some(y)) = (b.ocr, a.ocr) {
            parts.push(format!("OCR {x:.3} -> {y:.3}"));
        }
        let avm = |m: &RunMetrics, name: &str| {
            m.avm.iter().find(|(n, _)| n == name).and_then(|(_, v)| *v)
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
    }
    format!("{} on {runs} validation runs", parts.join("; "))
}

//! `hilrig efast`: eFAST sensitivity analysis (Saltelli et al. 1999; Rosenberger et al. 2019,
//! §4) with SALib's semantics: `sample` writes the parameter sets, the user's model (or a
//! re-simulation per row) computes one output per row, `analyze` ranks the parameters.
//! Exit 2 on a bad parameter file or outputs that do not fit.

use anyhow::{Context, Result};
use hilrig::campaign::efast::{Design, Layout};
use hilrig::stats::efast::{analyze, parse_params, sample, EfastError, Parameter};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct EfastArgs {
    #[command(subcommand)]
    command: EfastCommand,
}

#[derive(clap::Subcommand)]
enum EfastCommand {
    /// Write N·D parameter sets as CSV (header: the parameter names) to standard output.
    Sample {
        /// The parameters (`[[parameter]]` with name, distribution and its bounds).
        #[arg(long)]
        params: PathBuf,
        /// Samples per parameter (more than 4 M²).
        #[arg(short = 'N', default_value_t = 1000)]
        n: usize,
        /// Harmonics (interference parameter).
        #[arg(short = 'M', default_value_t = 4)]
        m: usize,
        /// Seed of the search curves' random phases.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// S1 and ST per parameter from the sample file and one output per row.
    Analyze {
        /// The parameters, as sampled.
        #[arg(long)]
        params: PathBuf,
        /// The samples (`efast sample`'s CSV).
        samples: PathBuf,
        /// The outputs: one number per line, in the samples' order (a header line is skipped);
        /// several files are read one after the other, as the parts of one column.
        #[arg(required = true, num_args = 1..)]
        outputs: Vec<PathBuf>,
        /// Harmonics, as sampled.
        #[arg(short = 'M', default_value_t = 4)]
        m: usize,
        /// Bootstrap windows for the confidence half-widths.
        #[arg(long, default_value_t = 100)]
        resamples: usize,
        /// Seed of the bootstrap.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Also write the indices as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Also write the outputs, joined into one file with the first one's header, here.
        #[arg(long)]
        joined: Option<PathBuf>,
    },
    /// The metric of some parameter sets of a sample file: one short drive each through the
    /// scenario (as `run` makes them), one number per line with the metric's name as header.
    /// The task of `plan`'s graph; a row's drive is seeded by the seed and its row, so its
    /// metric does not depend on which task makes it.
    Evaluate {
        /// The parameters, as sampled.
        #[arg(long)]
        params: PathBuf,
        /// The scenario.
        #[arg(long)]
        scenario: PathBuf,
        /// The samples (`efast sample`'s CSV).
        #[arg(long)]
        samples: PathBuf,
        /// The rows to evaluate, `FROM-TO`, counted from 1 (the first row after the header).
        #[arg(long)]
        rows: String,
        /// The design's seed (`run`'s).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Where the metrics go.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// The task graph of `run` for another engine (the Ray executor, `python/`): the samples
    /// as the plan's own file, an `evaluate` task per few sets, `analyze` over their parts.
    Plan {
        #[command(flatten)]
        design: DesignArgs,
        /// The plan as JSON (what an executor reads) instead of one line per task.
        #[arg(long)]
        json: bool,
    },
    /// Sample, make one short drive per parameter set through a scenario (synth with the
    /// reality model, record, resim with the model under test, compare) and rank the
    /// parameters by their effect on the scenario's metric. Writes samples.csv, outputs.csv
    /// and indices.json into the output directory. The drives are the tasks of `plan`, run by
    /// the campaigns' local executor: `--jobs` at a time, and a stopped run resumes where it
    /// stopped (`--force` makes every drive again).
    Run {
        #[command(flatten)]
        design: DesignArgs,
        /// Tasks at a time (default: the cores).
        #[arg(long)]
        jobs: Option<usize>,
        /// Run every task, also those whose outputs are up to date.
        #[arg(long)]
        force: bool,
    },
}

/// An eFAST design over a scenario: `run` and `plan`.
#[derive(clap::Args)]
struct DesignArgs {
    /// The parameters (`[[parameter]]` with name, distribution and its bounds).
    #[arg(long)]
    params: PathBuf,
    /// The scenario: scene, drive, reality and model files, the metric, and a knob per
    /// parameter (see `src/stats/scenario/mod.rs`).
    #[arg(long)]
    scenario: PathBuf,
    /// Samples per parameter (more than 4 M²).
    #[arg(short = 'N', default_value_t = 65)]
    n: usize,
    /// Harmonics (interference parameter).
    #[arg(short = 'M', default_value_t = 4)]
    m: usize,
    /// Seed of the search curves' phases, the drives and the bootstrap.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Bootstrap windows for the confidence half-widths.
    #[arg(long, default_value_t = 100)]
    resamples: usize,
    /// Parameter sets per task.
    #[arg(long, default_value_t = hilrig::campaign::efast::DEFAULT_CHUNK)]
    chunk: usize,
    /// Output directory.
    #[arg(short, long)]
    output: PathBuf,
}

impl DesignArgs {
    fn design(&self) -> Design<'_> {
        Design {
            params: &self.params,
            scenario: &self.scenario,
            n: self.n,
            m: self.m,
            seed: self.seed,
            resamples: self.resamples,
            chunk: self.chunk,
        }
    }
}

/// Prints the indices ranked by ST.
fn print_ranking(s: &[hilrig::stats::efast::Indices]) {
    println!(
        "{:<24} {:>8} {:>8} {:>8} {:>8}",
        "parameter", "S1", "±", "ST", "±"
    );
    let mut ranked = s.to_vec();
    ranked.sort_by(|a, b| b.st.total_cmp(&a.st));
    for i in &ranked {
        println!(
            "{:<24} {:>8.4} {:>8.4} {:>8.4} {:>8.4}",
            i.name, i.s1, i.s1_conf, i.st, i.st_conf
        );
    }
}

pub(crate) fn params(path: &Path) -> Result<Result<Vec<Parameter>, EfastError>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(parse_params(&text, &path.display().to_string()))
}

/// A CSV row that is not what the command expects.
#[derive(Debug, thiserror::Error)]
pub(crate) enum CsvError {
    /// Another number of values than the columns.
    #[error("{path} line {line}: {got} values, expected {want}")]
    Columns {
        path: String,
        line: usize,
        got: usize,
        want: usize,
    },
    /// A value that is not a number.
    #[error("{path} line {line}: {source}")]
    Number {
        path: String,
        line: usize,
        #[source]
        source: std::num::ParseFloatError,
    },
}

/// Numbers of a CSV (`columns` per row; a first line that does not parse is a header).
pub(crate) fn numbers(path: &Path, columns: usize) -> Result<Result<Vec<Vec<f64>>, CsvError>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let parsed: Result<Vec<f64>, _> =
            line.split(',').map(|v| v.trim().parse::<f64>()).collect();
        match parsed {
            Ok(v) if v.len() == columns => rows.push(v),
            Ok(v) => {
                return Ok(Err(CsvError::Columns {
                    path: path.display().to_string(),
                    line: i + 1,
                    got: v.len(),
                    want: columns,
                }))
            }
            Err(_) if i == 0 => {}
            Err(source) => {
                return Ok(Err(CsvError::Number {
                    path: path.display().to_string(),
                    line: i + 1,
                    source,
                }))
            }
        }
    }
    Ok(Ok(rows))
}

pub fn run(args: EfastArgs) -> Result<ExitCode> {
    let fail = |e: &dyn std::fmt::Display| {
        eprintln!("error: {e}");
        Ok(ExitCode::from(2))
    };
    match args.command {
        EfastCommand::Sample {
            params: p,
            n,
            m,
            seed,
        } => {
            let ps = match params(&p)? {
                Ok(ps) => ps,
                Err(e) => return fail(&e),
            };
            let rows = match sample(&ps, n, m, seed) {
                Ok(r) => r,
                Err(e) => return fail(&e),
            };
            let out = hilrig::stats::efast::samples_csv(&ps, &rows);
            let mut stdout = super::open_output(None)?;
            stdout.write_all(out.as_bytes())?;
            Ok(ExitCode::SUCCESS)
        }
        EfastCommand::Analyze {
            params: p,
            samples,
            outputs,
            m,
            resamples,
            seed,
            json,
            joined,
        } => {
            let ps = match params(&p)? {
                Ok(ps) => ps,
                Err(e) => return fail(&e),
            };
            let x = match numbers(&samples, ps.len())? {
                Ok(x) => x,
                Err(e) => return fail(&e),
            };
            let mut y: Vec<f64> = Vec::new();
            for o in &outputs {
                match numbers(o, 1)? {
                    Ok(part) => y.extend(part.into_iter().map(|r| r[0])),
                    Err(e) => return fail(&e),
                }
            }
            let named = outputs
                .iter()
                .map(|o| o.display().to_string())
                .collect::<Vec<_>>()
                .join(", ");
            if x.len() != y.len() {
                return fail(&format!(
                    "{} has {} sample rows, {named} {} {} outputs",
                    samples.display(),
                    x.len(),
                    if outputs.len() == 1 { "has" } else { "have" },
                    y.len()
                ));
            }
            let s = match analyze(&ps, &y, m, resamples, 0.95, seed) {
                Ok(s) => s,
                Err(e) => return fail(&e),
            };
            print_ranking(&s);
            if let Some(j) = json {
                std::fs::write(&j, serde_json::to_string_pretty(&s)?)
                    .with_context(|| format!("cannot write {}", j.display()))?;
            }
            if let Some(path) = joined {
                let first = std::fs::read_to_string(&outputs[0])
                    .with_context(|| format!("cannot read {}", outputs[0].display()))?;
                let header = first
                    .lines()
                    .next()
                    .filter(|l| l.trim().parse::<f64>().is_err())
                    .unwrap_or("output");
                let mut text = format!("{header}\n");
                for v in &y {
                    let _ = writeln!(text, "{v:?}");
                }
                std::fs::write(&path, text)
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
            Ok(ExitCode::SUCCESS)
        }
        EfastCommand::Evaluate {
            params: p,
            scenario,
            samples,
            rows,
            seed,
            output,
        } => evaluate(&p, &scenario, &samples, &rows, seed, &output),
        EfastCommand::Plan { design, json } => {
            let plan = match design.design().plan(&design.output) {
                Ok(p) => p,
                Err(e) => return fail(&e),
            };
            let mut out = std::io::stdout().lock();
            if json {
                writeln!(out, "{}", hilrig::output::to_json(&plan)?)?;
            } else {
                for t in &plan.tasks {
                    writeln!(out, "{}\n    hilrig {}", t.id, t.args.join(" "))?;
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        EfastCommand::Run {
            design,
            jobs,
            force,
        } => run_design(&design, jobs, force),
    }
}

/// `efast evaluate`: the rows `rows` (`FROM-TO`) of `samples`, each made into a drive with the
/// seed `seed` plus its row less one; the metrics written only when every row has one.
fn evaluate(
    p: &Path,
    scenario: &Path,
    samples: &Path,
    rows: &str,
    seed: u64,
    output: &Path,
) -> Result<ExitCode> {
    use hilrig::stats::scenario::Scenario;
    let fail = |e: &dyn std::fmt::Display| {
        eprintln!("error: {e}");
        Ok(ExitCode::from(2))
    };
    let ps = match params(p)? {
        Ok(ps) => ps,
        Err(e) => return fail(&e),
    };
    let x = match numbers(samples, ps.len())? {
        Ok(x) => x,
        Err(e) => return fail(&e),
    };
    let range = rows
        .split_once('-')
        .and_then(|(a, b)| {
            Some((
                a.trim().parse::<usize>().ok()?,
                b.trim().parse::<usize>().ok()?,
            ))
        })
        .filter(|&(a, b)| a >= 1 && a <= b && b <= x.len());
    let Some((from, to)) = range else {
        return fail(&format!(
            "--rows {rows}: not FROM-TO with 1 <= FROM <= TO <= {} (the rows of {})",
            x.len(),
            samples.display()
        ));
    };
    let sc = match Scenario::load(scenario, &ps) {
        Ok(s) => s,
        Err(e) => return fail(&e),
    };
    let work = PathBuf::from(format!("{}.work", output.display()));
    let mut text = format!("{}\n", sc.metric());
    for row in from..=to {
        let v = sc.evaluate(
            row,
            &x[row - 1],
            seed.wrapping_add(row as u64 - 1),
            &work.join(format!("set-{row:05}")),
        );
        match v {
            Ok(v) => {
                let _ = writeln!(text, "{v:?}");
            }
            Err(e) => {
                let _ = std::fs::remove_dir_all(&work);
                return fail(&e);
            }
        }
    }
    let _ = std::fs::remove_dir_all(&work);
    if let Some(parent) = output.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("cannot create {}", parent.display()))?;
    }
    std::fs::write(output, text).with_context(|| format!("cannot write {}", output.display()))?;
    Ok(ExitCode::SUCCESS)
}

/// `efast run`: the design planned (everything checked before the first drive, exit 2
/// otherwise, nothing written), then run by the local executor; the ranking printed when every
/// task finished.
fn run_design(a: &DesignArgs, jobs: Option<usize>, force: bool) -> Result<ExitCode> {
    use hilrig::campaign::local;
    let plan = match a.design().plan(&a.output) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    let jobs = jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from));
    let options = local::Options {
        exe: std::env::current_exe().context("cannot find the hilrig executable")?,
        jobs,
        force,
    };
    let plan_path = plan.out.join("efast").join("plan.json");
    std::fs::create_dir_all(plan_path.parent().expect("has a parent"))
        .with_context(|| format!("cannot create the folder of {}", plan_path.display()))?;
    hilrig::output::write(&plan_path, &plan)?;
    let drives = plan.files[0].text.lines().count().saturating_sub(1);
    eprintln!(
        "efast run: {drives} drives in {} tasks, {jobs} at a time (plan: {})",
        plan.tasks.len(),
        plan_path.display()
    );
    let bars = super::campaign::Bars::new(plan.tasks.len());
    let summary = local::run(&plan, &options, &bars)?;
    bars.bar.finish_and_clear();
    let [ran, current, failed, not_run] = summary.counts();
    eprintln!(
        "efast run: {ran} tasks ran, {current} up to date, {failed} failed, {not_run} not run"
    );
    if failed + not_run > 0 {
        for (id, o) in &summary.outcomes {
            match o {
                local::Outcome::Failed { why } => eprintln!("  FAILED  {id}: {why}"),
                local::Outcome::NotRun { because } => {
                    eprintln!("  not run {id}: waits for {because}");
                }
                _ => {}
            }
        }
        return Ok(ExitCode::from(1));
    }
    let layout = Layout::new(&plan.out);
    let text = std::fs::read_to_string(layout.indices())
        .with_context(|| format!("cannot read {}", layout.indices().display()))?;
    let s: Vec<hilrig::stats::efast::Indices> = serde_json::from_str(&text)
        .with_context(|| format!("cannot read {}", layout.indices().display()))?;
    let metric = std::fs::read_to_string(layout.outputs())
        .ok()
        .and_then(|t| t.lines().next().map(str::to_owned))
        .unwrap_or_default();
    eprintln!(
        "{drives} drives through {}; {metric} by parameter (eFAST, M = {}):",
        a.scenario.display(),
        a.m
    );
    print_ranking(&s);
    Ok(ExitCode::SUCCESS)
}

use std::io::Write as _;

//! `hilrig efast`: eFAST sensitivity analysis (Saltelli et al. 1999; Rosenberger et al. 2019,
//! §4) with SALib's semantics: `sample` writes the parameter sets, the user's model (or a
//! re-simulation per row) computes one output per row, `analyze` ranks the parameters.
//! Exit 2 on a bad parameter file or outputs that do not fit.

use anyhow::{Context, Result};
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
        /// The outputs: one number per line, in the samples' order (a header line is skipped).
        outputs: PathBuf,
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
    },
    /// Sample, make one short drive per parameter set through a scenario (synth with the
    /// reality model, record, resim with the model under test, compare) and rank the
    /// parameters by their effect on the scenario's metric. Writes samples.csv, outputs.csv
    /// and indices.json into the output directory.
    Run {
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
        /// Output directory.
        #[arg(short, long)]
        output: PathBuf,
    },
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

/// The sample rows as CSV with the parameter names as header.
fn samples_csv(ps: &[Parameter], rows: &[Vec<f64>]) -> String {
    let mut out = ps
        .iter()
        .map(|q| q.name.as_str())
        .collect::<Vec<_>>()
        .join(",");
    out.push('\n');
    for r in rows {
        let line: Vec<String> = r.iter().map(|v| format!("{v:?}")).collect();
        let _ = writeln!(out, "{}", line.join(","));
    }
    out
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
            let out = samples_csv(&ps, &rows);
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
        } => {
            let ps = match params(&p)? {
                Ok(ps) => ps,
                Err(e) => return fail(&e),
            };
            let x = match numbers(&samples, ps.len())? {
                Ok(x) => x,
                Err(e) => return fail(&e),
            };
            let y: Vec<f64> = match numbers(&outputs, 1)? {
                Ok(y) => y.into_iter().map(|r| r[0]).collect(),
                Err(e) => return fail(&e),
            };
            if x.len() != y.len() {
                return fail(&format!(
                    "{} has {} sample rows, {} has {} outputs",
                    samples.display(),
                    x.len(),
                    outputs.display(),
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
            Ok(ExitCode::SUCCESS)
        }
        EfastCommand::Run {
            params: p,
            scenario,
            n,
            m,
            seed,
            resamples,
            output,
        } => run_scenario(&p, &scenario, n, m, seed, resamples, &output),
    }
}

/// `efast run`: everything is checked (parameters, scenario, the knobs on the first set)
/// before the first drive, and the outputs are written only when every set has its metric.
fn run_scenario(
    p: &Path,
    scenario: &Path,
    n: usize,
    m: usize,
    seed: u64,
    resamples: usize,
    output: &Path,
) -> Result<ExitCode> {
    use hilrig::stats::scenario::Scenario;
    use rayon::prelude::*;
    let fail = |e: &dyn std::fmt::Display| {
        eprintln!("error: {e}");
        Ok(ExitCode::from(2))
    };
    let ps = match params(p)? {
        Ok(ps) => ps,
        Err(e) => return fail(&e),
    };
    let rows = match sample(&ps, n, m, seed) {
        Ok(r) => r,
        Err(e) => return fail(&e),
    };
    let sc = match Scenario::load(scenario, &ps) {
        Ok(s) => s,
        Err(e) => return fail(&e),
    };
    if let Err(e) = sc.check(&rows[0]) {
        return fail(&e);
    }
    std::fs::create_dir_all(output)
        .with_context(|| format!("cannot create {}", output.display()))?;
    let bar = indicatif::ProgressBar::new(rows.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "efast run [{bar:30}] {pos}/{len} drives, {elapsed} (eta {eta})",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let work = output.join("work");
    let y: Result<Vec<f64>, _> = rows
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            let v = sc.evaluate(
                i + 1,
                r,
                seed.wrapping_add(i as u64),
                &work.join(format!("set-{:05}", i + 1)),
            );
            bar.inc(1);
            v
        })
        .collect();
    bar.finish_and_clear();
    let _ = std::fs::remove_dir_all(&work);
    let y = match y {
        Ok(y) => y,
        Err(e) => return fail(&e),
    };
    let s = match analyze(&ps, &y, m, resamples, 0.95, seed) {
        Ok(s) => s,
        Err(e) => return fail(&e),
    };
    let write = |name: &str, text: String| -> Result<()> {
        let path = output.join(name);
        std::fs::write(&path, text).with_context(|| format!("cannot write {}", path.display()))
    };
    write("samples.csv", samples_csv(&ps, &rows))?;
    let mut out = format!("{}\n", sc.metric());
    for v in &y {
        let _ = writeln!(out, "{v:?}");
    }
    write("outputs.csv", out)?;
    write("indices.json", serde_json::to_string_pretty(&s)?)?;
    eprintln!(
        "{} drives through {}; {} by parameter (eFAST, M = {m}):",
        rows.len(),
        scenario.display(),
        sc.metric()
    );
    print_ranking(&s);
    Ok(ExitCode::SUCCESS)
}

use std::io::Write as _;

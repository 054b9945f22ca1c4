//! `hilrig coverage`: do validation scenarios share a cell of the parameter space with the
//! parameterization scenarios (Rosenberger et al. 2019, §4)? Lists those that do, and how far
//! the two sets are apart. Exit 0 when none shares a cell, 1 when some do, 2 on bad input.

use super::efast::{numbers, params};
use anyhow::{Context, Result};
use hilrig::stats::coverage::coverage;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct CoverageArgs {
    /// The parameters (as for `efast`): their ranges are cut into cells.
    #[arg(long)]
    params: PathBuf,
    /// Parts per parameter range.
    #[arg(long, default_value_t = 10)]
    parts: usize,
    /// The parameterization samples (CSV, one column per parameter, a header line allowed).
    parameterization: PathBuf,
    /// The validation samples.
    validation: PathBuf,
    /// Also write the result as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

pub fn run(args: CoverageArgs) -> Result<ExitCode> {
    let fail = |e: &dyn std::fmt::Display| {
        eprintln!("error: {e}");
        Ok(ExitCode::from(2))
    };
    let ps = match params(&args.params)? {
        Ok(p) => p,
        Err(e) => return fail(&e),
    };
    if args.parts == 0 {
        return fail(&"--parts 0: a range needs at least one part");
    }
    let read = |p: &PathBuf| numbers(p, ps.len());
    let (par, val) = match (read(&args.parameterization)?, read(&args.validation)?) {
        (Ok(a), Ok(b)) => (a, b),
        (Err(e), _) | (_, Err(e)) => return fail(&e),
    };
    if par.is_empty() || val.is_empty() {
        return fail(&"both sample files need at least one row");
    }
    let c = coverage(&ps, args.parts, &par, &val);
    println!(
        "{} validation samples against {} parameterization samples, {} parts per parameter: {} share a cell; nearest distance min {:.3}, mean {:.3} (in units of the parameter ranges)",
        val.len(),
        par.len(),
        c.parts,
        c.shared.len(),
        c.min_distance,
        c.mean_distance
    );
    for s in &c.shared {
        println!(
            "  validation row {} shares cell {:?} with parameterization rows {:?}",
            s.validation_row, s.cell, s.parameterization_rows
        );
    }
    if let Some(j) = &args.json {
        std::fs::write(j, serde_json::to_string_pretty(&c)?)
            .with_context(|| format!("cannot write {}", j.display()))?;
    }
    Ok(if c.shared.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

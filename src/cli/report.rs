//! `hilrig report`: the HTML report from the JSON the other commands wrote (a directory is
//! searched for them), and `report.json` beside it.

use anyhow::{Context, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct ReportArgs {
    /// Directories to search for JSON (of info, check, compare, validate, gap), or the files.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// The report (HTML); report.json is written beside it.
    #[arg(short, long, default_value = "report.html")]
    output: PathBuf,
    /// A file named that does not exist is listed on the report as not produced, and the exit
    /// status is 1, instead of refusing the report (exit 2): a campaign's report over steps of
    /// which some did not run.
    #[arg(long)]
    allow_absent: bool,
}

pub fn run(args: ReportArgs) -> Result<ExitCode> {
    let gathered = if args.allow_absent {
        hilrig::report::gather_allowing_absent(&args.inputs)
    } else {
        hilrig::report::gather(&args.inputs).map(|i| (i, Vec::new()))
    };
    let (inputs, absent) = match gathered {
        Ok(i) => i,
        Err(e) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    for p in &absent {
        eprintln!("not produced: {}", p.display());
    }
    let rendered = hilrig::report::render(&inputs, &absent);
    let json = hilrig::report::write(&args.output, &rendered)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    println!(
        "report: {} ({} inputs; numbers in {})",
        args.output.display(),
        inputs.len(),
        json.display()
    );
    if !absent.is_empty() {
        println!(
            "{} input file(s) not produced, listed in the report",
            absent.len()
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

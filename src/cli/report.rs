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
}

pub fn run(args: ReportArgs) -> Result<ExitCode> {
    let inputs = match hilrig::report::gather(&args.inputs) {
        Ok(i) => i,
        Err(e) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    let rendered = hilrig::report::render(&inputs);
    let json = hilrig::report::write(&args.output, &rendered)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    println!(
        "report: {} ({} inputs; numbers in {})",
        args.output.display(),
        inputs.len(),
        json.display()
    );
    Ok(ExitCode::SUCCESS)
}

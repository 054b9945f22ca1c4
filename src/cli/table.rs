//! `hilrig table`: a command's JSON output as Parquet tables (a row per scan, epoch, cell or
//! gap trial), labelled with its drive, scenario and model, for DuckDB, Polars or Spark.

use anyhow::{bail, Context, Result};
use hilrig::campaign::tables::{table, Labels, TableKind};
use hilrig::report::Document;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct TableArgs {
    /// A JSON output of check, compare, validate or gap.
    input: PathBuf,
    /// Where the tables go: DIR/TABLE/NAME.parquet (TABLE: compare_scans, check_epochs,
    /// check_runs, validate_cells, gap_trials).
    #[arg(long)]
    dir: PathBuf,
    /// The file name in each table's folder (default: the input's stem).
    #[arg(long)]
    name: Option<String>,
    /// The drive the rows are of (a column of every table).
    #[arg(long)]
    drive: Option<String>,
    /// The scenario (a column of every table).
    #[arg(long)]
    scenario: Option<String>,
    /// The model (a column of every table).
    #[arg(long)]
    model: Option<String>,
}

pub fn run(args: TableArgs) -> Result<ExitCode> {
    let bytes = std::fs::read(&args.input)
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    let doc = Document::from_slice(&args.input, &bytes)?;
    let kinds = TableKind::of(doc.kind());
    if kinds.is_empty() {
        bail!(
            "{}: a {} file has no table (check, compare, validate and gap outputs do)",
            args.input.display(),
            doc.kind().name()
        );
    }
    let name = match args.name {
        Some(n) => n,
        None => args
            .input
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .context("the input has no file name")?,
    };
    let labels = Labels {
        drive: args.drive,
        scenario: args.scenario,
        model: args.model,
    };
    for &kind in kinds {
        let t = table(&doc, kind, &labels).expect("a table of the kinds the output gives");
        let dir = args.dir.join(kind.name());
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        let path = dir.join(format!("{name}.parquet"));
        t.write(&path)?;
        println!("{}: {} rows", path.display(), t.rows());
    }
    Ok(ExitCode::SUCCESS)
}

//! The steps of the method a plan's tasks are of: what a campaign file lists, and the eFAST
//! design's own.

use serde::{Deserialize, Serialize};

/// A step of the method, as a campaign names it; each is one command per drive, per model or
/// per scenario.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Step {
    /// `record --from` of each capture (drives given as recordings skip it).
    Record,
    /// `check` of each drive's reference data.
    Check,
    /// `resim` of each drive with each model.
    Resim,
    /// `compare` of each drive with each of its re-simulations.
    Compare,
    /// `validate` per scenario and model, over the scenario's repetitions.
    Validate,
    /// `gap` per scenario, from its start model.
    Gap,
    /// `table` of every JSON the campaign wrote: Parquet for DuckDB, Polars or Spark.
    Tables,
    /// `report` over every JSON the campaign wrote.
    Report,
    /// A task of an eFAST design (`hilrig efast plan`: its drives, then the analysis); not a
    /// step of a campaign file.
    Efast,
}

impl Step {
    /// Its name in the campaign file and in task ids.
    pub fn name(self) -> &'static str {
        match self {
            Step::Record => "record",
            Step::Check => "check",
            Step::Resim => "resim",
            Step::Compare => "compare",
            Step::Validate => "validate",
            Step::Gap => "gap",
            Step::Tables => "tables",
            Step::Report => "report",
            Step::Efast => "efast",
        }
    }

    /// The command its tasks run.
    pub fn command(self) -> &'static str {
        match self {
            Step::Tables => "table",
            other => other.name(),
        }
    }
}

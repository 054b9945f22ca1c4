//! Why a scenario cannot be run: the scenario's files, a knob that does not reach a number, or
//! a step of one parameter set's pipeline.

use std::path::PathBuf;

/// Why a scenario cannot be run.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The scenario file or a document it names cannot be read (or a number of it is not
    /// finite, or it is not TOML of the right type).
    #[error(transparent)]
    File(#[from] crate::config::TomlFileError),
    /// The metric is not one of `compare`'s summary fields.
    #[error("{}: metric '{metric}' is not one of compare's: {}", .path.display(), .known.join(", "))]
    Metric {
        /// The scenario file.
        path: PathBuf,
        /// The metric named.
        metric: String,
        /// The ones there are.
        known: Vec<String>,
    },
    /// A knob for a parameter the parameter file does not have.
    #[error("{}: knob for '{parameter}', which the parameter file does not have", .path.display())]
    UnknownParameter {
        /// The scenario file.
        path: PathBuf,
        /// The knob's parameter.
        parameter: String,
    },
    /// A parameter without exactly one knob.
    #[error("{}: {} for parameter '{parameter}'", .path.display(), if *.knobs == 0 { "no knob".to_owned() } else { format!("{} knobs", .knobs) })]
    Knobs {
        /// The scenario file.
        path: PathBuf,
        /// The parameter.
        parameter: String,
        /// How many knobs it has.
        knobs: usize,
    },
    /// The documents do not load with the first parameter set.
    #[error(transparent)]
    Documents(Box<StepError>),
    /// A knob that does not reach a number.
    #[error("knob '{knob}': {source}")]
    Knob {
        /// The knob, as the scenario file writes it (with the file where it is read).
        knob: String,
        /// Where it stops.
        #[source]
        source: KnobError,
    },
    /// One parameter set failed.
    #[error("parameter set {row} ({values}): {source}")]
    Sample {
        /// Row of the sample file, 1-based.
        row: usize,
        /// The set's values, `name=value`.
        values: String,
        /// The step that failed and why.
        #[source]
        source: Box<StepError>,
    },
}

/// Where a knob's path (`model.effect[range_noise].sigma_m`) stops short of a number.
#[derive(Debug, thiserror::Error)]
pub enum KnobError {
    /// A `[` without its `]`.
    #[error("'[' without ']'")]
    Unclosed,
    /// The path does not start with one of the four files.
    #[error("a knob starts with scene, drive, reality or model")]
    NoFile,
    /// Only the file.
    #[error("no key after the file")]
    NoKey,
    /// A key where there is no table.
    #[error("'{0}' is not inside a table")]
    NotInTable(String),
    /// A key the table lacks.
    #[error("no key '{0}'")]
    Missing(String),
    /// An index where there is no array.
    #[error("[{0}]: not an array")]
    NotAnArray(usize),
    /// An index beyond the array.
    #[error("index {index} of an array of {len}")]
    OutOfRange {
        /// The index.
        index: usize,
        /// The array's length.
        len: usize,
    },
    /// A name where there is no array of tables.
    #[error("[{0}]: not an array of tables")]
    NotTables(String),
    /// A name no table of the array has.
    #[error("no table named '{0}'")]
    NoTableNamed(String),
    /// The path ends at something else than a number.
    #[error("holds {0}, not a number")]
    NotANumber(&'static str),
}

/// The step of evaluating one parameter set that failed.
#[derive(Debug, thiserror::Error)]
pub enum StepError {
    /// A file after the knobs set their numbers: no longer of its type.
    #[error("{path} (after the knobs): {what}")]
    Document {
        /// The file the knobs changed.
        path: PathBuf,
        /// What its parser or check says.
        what: String,
    },
    /// A step of the pipeline (synth, record, resim, compare) or a file it reads.
    #[error("{step}: {source}")]
    Step {
        /// The step, or the file.
        step: String,
        /// Its error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The drive did not give the metric.
    #[error("the drive gives no {0} (compare could not compute it: too few points?)")]
    NoMetric(String),
}

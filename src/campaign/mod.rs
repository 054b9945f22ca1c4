//! Campaigns: many drives, one study (Rosenberger et al. 2019, §4 and §8: repetitions of every
//! scenario, parameterization and validation sets). A campaign file ([`file`]) names the drives,
//! their scenarios and the models; [`plan`] turns it into a graph of tasks, each one invocation
//! of an existing command on files; [`local`] runs the graph on this machine, skipping what a
//! stopped run already finished ([`stamp`]); [`store`] runs it on files in object storage.
//!
//! The tasks are the commands a user would type, so a campaign computes nothing the commands do
//! not: its outputs are the commands' outputs, byte for byte. Any engine that can run a command
//! on files can run a plan (`hilrig campaign plan --json`).

pub mod efast;
pub mod file;
pub mod gap_rounds;
mod gap_trials;
mod graph;
pub mod local;
pub mod mirror;
pub mod parquet;
pub mod plan;
mod resolve;
pub mod staged;
pub mod stamp;
mod step;
pub mod store;
pub mod tables;
mod task;

use std::path::PathBuf;

/// Why a campaign cannot be planned or run: said before any task runs.
#[derive(Debug, thiserror::Error)]
pub enum CampaignError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The campaign file says something that cannot be run.
    #[error("{path}: {what}")]
    Invalid {
        /// The campaign file.
        path: PathBuf,
        /// What and where.
        what: String,
    },
    /// A drive pattern matched nothing.
    #[error("drive {entry} of the campaign: no file matches {pattern}")]
    NoDrive {
        /// Which `[[drive]]` (1-based).
        entry: usize,
        /// The pattern, resolved.
        pattern: String,
    },
    /// A file the campaign names does not exist.
    #[error("{what}: {path} does not exist")]
    Missing {
        /// Whose file.
        what: String,
        /// The path.
        path: PathBuf,
    },
    /// Two tasks would write the same file.
    #[error("{first} and {second} would both write {path}")]
    TwoWriters {
        /// The file.
        path: PathBuf,
        /// One task.
        first: String,
        /// The other.
        second: String,
    },
    /// A task would wait for itself.
    #[error("the tasks wait for each other in a circle: {tasks} (through {file}; are the campaign's drives among its own outputs?)")]
    Cycle {
        /// The tasks of the circle.
        tasks: String,
        /// A file that closes it.
        file: PathBuf,
    },
    /// Object storage: no credentials, a bucket that does not answer, a failed transfer.
    #[error(transparent)]
    Store(#[from] store::StoreError),
}

impl From<mirror::UrlError> for CampaignError {
    fn from(e: mirror::UrlError) -> CampaignError {
        CampaignError::Store(e.into())
    }
}

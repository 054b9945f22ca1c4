//! One task of a plan: a command line with the files it reads and writes.

use super::file::Step;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// One invocation of `hilrig`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Task {
    /// Unique name: the step, then the model and drive or scenario it is for
    /// (`resim/truth/rep-01`).
    pub id: String,
    /// The step it is of.
    pub step: Step,
    /// The command line after `hilrig`.
    pub args: Vec<String>,
    /// The files it reads (each one that a task writes makes it wait for that task).
    pub inputs: Vec<PathBuf>,
    /// The files it writes.
    pub outputs: Vec<PathBuf>,
    /// The tasks it waits for (ids; every one is earlier in [`Plan::tasks`]).
    pub after: Vec<String>,
    /// Exit codes that are results, not failures (`check` exits 1 for a run that fails). A
    /// task that ended with one lets the tasks that read its outputs run.
    pub results: Vec<i32>,
    /// Of `after`, the tasks that must have exited 0, not only with a result: a drive is
    /// re-simulated and studied only after it passed `check`, while the tables and the report
    /// of a failed check are still made.
    pub gates: Vec<String>,
    /// A summary (the report): it runs after its predecessors whatever their outcome, also
    /// when one failed or did not run, over the inputs that exist, and names those that do not
    /// (the command is told so). Without it a fleet's report would wait for every drive to
    /// pass, and the drive that failed is the one its readers need to see.
    pub partial: bool,
    /// Where its standard output and error go.
    pub log: PathBuf,
}

impl Task {
    /// A task that waits for nothing, passes only with exit 0 and is no summary: what a task
    /// is until the plan says more (what it waits for, which exits are results).
    pub fn new(
        id: String,
        step: Step,
        args: Vec<String>,
        (inputs, outputs): (Vec<PathBuf>, Vec<PathBuf>),
        log: PathBuf,
    ) -> Task {
        Task {
            id,
            step,
            args,
            inputs,
            outputs,
            after: Vec::new(),
            results: vec![0],
            gates: Vec::new(),
            partial: false,
            log,
        }
    }
}

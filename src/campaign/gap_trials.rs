//! A campaign's `[gap]` table: where its gap steps run their full re-simulations, said as
//! `hilrig gap` takes it (`--jobs N`, `--engine COMMAND`).

use serde::Deserialize;

/// Where the gap step's full re-simulations run, as `hilrig gap` takes it: a campaign whose
/// tasks run on a cluster hands each study's trials to the cluster too, instead of running
/// every validation run's re-simulations one after the other in the gap task's process.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GapEntry {
    /// `gap --jobs`: trials as local tasks of the node the gap task runs on, this many at a
    /// time.
    #[serde(default)]
    pub jobs: Option<u16>,
    /// `gap --engine`: a command that runs a plan file (split as a POSIX shell splits it).
    #[serde(default)]
    pub engine: Option<String>,
}

/// The words of an engine command (`gap --engine`, `[gap] engine`), split as a POSIX shell
/// splits them (quotes and backslashes; no `~` or `$VAR` expansion); `Err` says why it is not
/// a command.
pub fn engine_argv(command: &str) -> Result<Vec<String>, &'static str> {
    match shlex::split(command) {
        Some(argv) if !argv.is_empty() => Ok(argv),
        Some(_) => Err("not a command"),
        None => Err("unbalanced quotes or a trailing backslash"),
    }
}

/// Where the gap step's full re-simulations run, checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GapTrials {
    /// `gap --jobs N`.
    Jobs(u16),
    /// `gap --engine COMMAND` (a command line that splits into at least one word).
    Engine(String),
}

impl GapTrials {
    /// The `[gap]` table checked: one of `jobs` (at least 1) and `engine` (a command line).
    pub fn of(g: &GapEntry) -> Result<GapTrials, String> {
        match (g.jobs, &g.engine) {
            (Some(_), Some(_)) => Err(
                "[gap] names both `jobs` and `engine`: the trials run on one or the other".into(),
            ),
            (Some(0), None) => Err("[gap] jobs = 0: at least 1".into()),
            (Some(n), None) => Ok(GapTrials::Jobs(n)),
            (None, Some(c)) => match engine_argv(c) {
                Ok(_) => Ok(GapTrials::Engine(c.clone())),
                Err(why) => Err(format!("[gap] engine = {c:?}: {why}")),
            },
            (None, None) => Err("[gap] names neither `jobs` nor `engine`".into()),
        }
    }

    /// The arguments of `hilrig gap` that say it.
    pub fn args(&self) -> [String; 2] {
        match self {
            GapTrials::Jobs(n) => ["--jobs".into(), n.to_string()],
            GapTrials::Engine(c) => ["--engine".into(), c.clone()],
        }
    }
}

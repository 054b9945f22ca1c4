//! What a finished task leaves behind so that the next run can skip it: the command line, the
//! exit code, and the SHA-256 of every file it read and wrote.
//!
//! A task is up to date when its stamp exists, this build of hilrig made it, its command line is
//! the plan's (but for where a gap task's trials run: `--jobs`, `--engine`), and every input
//! and output still has the hash the stamp gives (an output that is missing, cut short or
//! edited makes it run again; so does an input that a task before it wrote anew; so does a
//! fixed hilrig). A stamp is written only after the task ended with a result, and removed
//! before it starts: a task killed half-way has none. Content hashes, not modification times, so that a drive copied to another
//! disk, or an output rewritten with the same bytes, does not redo the work after it.

use super::plan::Task;
use super::CampaignError;
use crate::output::{Output, OutputKind};
use serde::{Deserialize, Serialize};
use sha2::Digest;
use std::collections::HashMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// A file and its content hash.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileHash {
    /// The file.
    pub path: PathBuf,
    /// SHA-256 of its bytes, lowercase hex; empty for an input of a summary task that was
    /// absent ([`Task::partial`]).
    pub sha256: String,
}

/// A finished task (`OUT/campaign/done/<task id>.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stamp {
    /// The task's id.
    pub task: String,
    /// Its command line after `hilrig`.
    pub args: Vec<String>,
    /// Its exit code (one of the task's results).
    pub exit: i32,
    /// Its inputs as they were when it started.
    pub inputs: Vec<FileHash>,
    /// Its outputs as it left them.
    pub outputs: Vec<FileHash>,
    /// The hilrig that ran it ([`TOOL`]): a task another build made is made again, so that a
    /// fixed resim, compare or check does not leave the results of the build before it.
    pub tool: String,
}

impl Output for Stamp {
    const KIND: OutputKind = OutputKind::CampaignTask;
    const SCHEMA: u32 = 2;
}

/// This build of hilrig ([`crate::output::BUILD`]).
pub const TOOL: &str = crate::output::BUILD;

/// Where the stamp of task `id` lives under the output directory `out`.
pub fn path(out: &Path, id: &str) -> PathBuf {
    out.join("campaign").join("done").join(format!("{id}.json"))
}

/// Hashes files, each once while its size and modification time stay the same (a recording of
/// a fleet's drive is gigabytes, and every task of the drive reads it).
#[derive(Default)]
pub struct Hashes {
    known: HashMap<PathBuf, (u64, Option<SystemTime>, String)>,
}

impl Hashes {
    /// The file's hash, or `None` when it does not exist.
    pub fn of(&mut self, path: &Path) -> Result<Option<String>, CampaignError> {
        let io = |source| CampaignError::Io {
            path: path.to_owned(),
            source,
        };
        let meta = match std::fs::metadata(path) {
            Ok(m) if m.is_file() => m,
            Ok(_) => return Ok(None),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(io(e)),
        };
        let key = (meta.len(), meta.modified().ok());
        if let Some((len, modified, hash)) = self.known.get(path) {
            if (*len, *modified) == key {
                return Ok(Some(hash.clone()));
            }
        }
        let mut f = std::fs::File::open(path).map_err(io)?;
        let mut h = sha2::Sha256::new();
        let mut buf = vec![0u8; 1 << 20];
        loop {
            let n = f.read(&mut buf).map_err(io)?;
            if n == 0 {
                break;
            }
            h.update(&buf[..n]);
        }
        let hash = crate::report::hex(&h.finalize());
        self.known
            .insert(path.to_owned(), (key.0, key.1, hash.clone()));
        Ok(Some(hash))
    }

    /// The inputs of `task` with their hashes; `None` when one is missing, except for a
    /// summary's ([`Task::partial`]), whose absent inputs are listed with an empty hash (so
    /// that its stamp is out of date once a task before it writes one).
    pub fn inputs(&mut self, task: &Task) -> Result<Option<Vec<FileHash>>, CampaignError> {
        if !task.partial {
            return self.all(&task.inputs);
        }
        let mut out = Vec::with_capacity(task.inputs.len());
        for p in &task.inputs {
            out.push(FileHash {
                path: p.clone(),
                sha256: self.of(p)?.unwrap_or_default(),
            });
        }
        Ok(Some(out))
    }

    /// Every file of `paths` with its hash; `None` when one is missing.
    pub fn all(&mut self, paths: &[PathBuf]) -> Result<Option<Vec<FileHash>>, CampaignError> {
        let mut out = Vec::with_capacity(paths.len());
        for p in paths {
            let Some(sha256) = self.of(p)? else {
                return Ok(None);
            };
            out.push(FileHash {
                path: p.clone(),
                sha256,
            });
        }
        Ok(Some(out))
    }
}

/// A gap task's options that say where its trials run, not what it makes: its results are
/// the same with either or neither (tests/gap_engine.rs), so a campaign resumed with another
/// `[gap]`, or with its engine at a new address, keeps the studies it finished.
const WHERE_TRIALS_RUN: [&str; 2] = ["--jobs", "--engine"];

/// `args` of `task` without the options that do not change its outputs.
fn what_it_makes<'a>(task: &Task, args: &'a [String]) -> Vec<&'a String> {
    let mut out = Vec::with_capacity(args.len());
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if task.step == super::file::Step::Gap && WHERE_TRIALS_RUN.contains(&a.as_str()) {
            it.next();
        } else {
            out.push(a);
        }
    }
    out
}

/// The exit code `task` ended with last time, when its stamp shows it up to date.
pub fn up_to_date(
    out: &Path,
    task: &Task,
    hashes: &mut Hashes,
) -> Result<Option<i32>, CampaignError> {
    let p = path(out, &task.id);
    let Ok(bytes) = std::fs::read(&p) else {
        return Ok(None);
    };
    // A stamp this build cannot read (another schema, damaged) only means the task runs again.
    let Ok(stamp) = crate::output::from_slice::<Stamp>(&p, &bytes) else {
        return Ok(None);
    };
    if stamp.tool != TOOL
        || what_it_makes(task, &stamp.args) != what_it_makes(task, &task.args)
        || !task.results.contains(&stamp.exit)
    {
        return Ok(None);
    }
    let same = |now: Option<Vec<FileHash>>, then: &[FileHash]| now.is_some_and(|n| n == then);
    if !same(hashes.inputs(task)?, &stamp.inputs)
        || !same(hashes.all(&task.outputs)?, &stamp.outputs)
    {
        return Ok(None);
    }
    Ok(Some(stamp.exit))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::file::Step;

    /// The stamp `task` would leave with `exit`, made by `tool`, its files as they are now.
    fn stamp_of(task: &Task, exit: i32, tool: &str, hashes: &mut Hashes) -> Stamp {
        Stamp {
            task: task.id.clone(),
            args: task.args.clone(),
            exit,
            inputs: hashes.inputs(task).unwrap().unwrap(),
            outputs: hashes.all(&task.outputs).unwrap().unwrap(),
            tool: tool.into(),
        }
    }

    /// A stamp whose files all match is up to date only when this build made it: after an
    /// upgrade (another source, another version) the task is made again.
    #[test]
    fn a_stamp_of_another_build_is_out_of_date() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("in.mcap"), b"recording").unwrap();
        std::fs::write(d.join("out.json"), b"{}").unwrap();
        let task = Task {
            id: "check/r".into(),
            step: Step::Check,
            args: vec!["check".into()],
            inputs: vec![d.join("in.mcap")],
            outputs: vec![d.join("out.json")],
            after: Vec::new(),
            results: vec![0, 1],
            gates: Vec::new(),
            partial: false,
            log: d.join("check.log"),
        };
        let mut hashes = Hashes::default();
        let stamp = |tool: &str, hashes: &mut Hashes| stamp_of(&task, 1, tool, hashes);
        let at = path(d, &task.id);
        std::fs::create_dir_all(at.parent().unwrap()).unwrap();
        crate::output::write(&at, &stamp(TOOL, &mut hashes)).unwrap();
        assert_eq!(up_to_date(d, &task, &mut hashes).unwrap(), Some(1));
        let other = TOOL.replace("sha256:", "sha256:0");
        crate::output::write(&at, &stamp(&other, &mut hashes)).unwrap();
        assert_eq!(up_to_date(d, &task, &mut hashes).unwrap(), None);
        assert!(TOOL.starts_with("hilrig ") && TOOL.len() > 64, "{TOOL}");
    }

    /// A gap task stamped with its trials run in process is up to date when they would now run
    /// as local jobs or on an engine, and the other way round; another study, or such options
    /// on a task of another step, make it run again.
    #[test]
    fn where_a_gap_task_s_trials_run_does_not_make_it_run_again() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("study.toml"), b"study").unwrap();
        std::fs::write(d.join("gap.json"), b"{}").unwrap();
        let args = |extra: &[&str]| -> Vec<String> {
            ["gap", "study.toml", "-o", "g"]
                .iter()
                .chain(extra)
                .map(|a| a.to_string())
                .collect()
        };
        let task = |step: Step, args: Vec<String>| Task {
            id: "gap/s".into(),
            step,
            args,
            inputs: vec![d.join("study.toml")],
            outputs: vec![d.join("gap.json")],
            after: Vec::new(),
            results: vec![0],
            gates: Vec::new(),
            partial: false,
            log: d.join("gap.log"),
        };
        let mut hashes = Hashes::default();
        let at = path(d, "gap/s");
        std::fs::create_dir_all(at.parent().unwrap()).unwrap();
        for (stamped, now, step, fresh) in [
            (args(&[]), args(&["--jobs", "2"]), Step::Gap, true),
            (
                args(&["--jobs", "2"]),
                args(&["--engine", "ray --address a:1"]),
                Step::Gap,
                true,
            ),
            (
                args(&["--engine", "ray --address a:1"]),
                args(&[]),
                Step::Gap,
                true,
            ),
            (
                args(&["--jobs", "2"]),
                args(&["--jobs", "2", "--force"]),
                Step::Gap,
                false,
            ),
            (args(&[]), args(&["--jobs", "2"]), Step::Check, false),
        ] {
            let then = task(step, stamped.clone());
            crate::output::write(&at, &stamp_of(&then, 0, TOOL, &mut hashes)).unwrap();
            let got = up_to_date(d, &task(step, now.clone()), &mut hashes).unwrap();
            assert_eq!(
                got.is_some(),
                fresh,
                "{step:?}: {stamped:?} then, {now:?} now"
            );
        }
    }
}

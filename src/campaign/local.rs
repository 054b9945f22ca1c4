//! The local executor: a plan's tasks as subprocesses of this machine, up to `jobs` at a time,
//! each as soon as the tasks it waits for have passed.
//!
//! A task that fails is named with its log and the rest of the graph still runs where it does
//! not wait for it; the tasks that do are reported as not run, with the reason. Finished tasks
//! leave a stamp (stamp.rs), so a campaign that was stopped (killed, a machine rebooted) skips
//! on its next run every task whose files are as it left them. Each task's process is killed
//! with the executor (`PR_SET_PDEATHSIG`): a killed campaign leaves no command writing on.

use super::plan::{Plan, Task};
use super::staged::Staged;
use super::stamp::{self, FileHash, Hashes, Stamp};
use super::CampaignError;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How to run a plan.
#[derive(Clone, Debug)]
pub struct Options {
    /// The `hilrig` executable the tasks run.
    pub exe: PathBuf,
    /// Tasks at a time.
    pub jobs: usize,
    /// Run every task, up to date or not.
    pub force: bool,
}

/// How a task ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// It ran and ended with one of its results.
    Ran {
        /// Its exit code.
        exit: i32,
        /// Its wall time.
        time: Duration,
    },
    /// Its stamp showed it up to date; it did not run.
    UpToDate {
        /// The exit code it ended with then.
        exit: i32,
    },
    /// It ran and failed.
    Failed {
        /// What went wrong.
        why: String,
    },
    /// It did not run because a task it waits for did not pass.
    NotRun {
        /// That task's id and what it ended with.
        because: String,
    },
}

impl Outcome {
    /// Its exit code, when it has a result.
    pub fn exit(&self) -> Option<i32> {
        match self {
            Outcome::Ran { exit, .. } | Outcome::UpToDate { exit } => Some(*exit),
            _ => None,
        }
    }
}

/// Told of every task as it starts and ends (the command line's progress bar).
pub trait Progress: Sync {
    /// A task started.
    fn started(&self, task: &Task);
    /// A task ended (or was found up to date, or will not run).
    fn finished(&self, task: &Task, outcome: &Outcome);
}

/// Every task's outcome, in the plan's order.
#[derive(Clone, Debug)]
pub struct Summary {
    /// (task id, outcome).
    pub outcomes: Vec<(String, Outcome)>,
}

impl Summary {
    /// Tasks that ran, were up to date, failed, did not run.
    pub fn counts(&self) -> [usize; 4] {
        let mut c = [0; 4];
        for (_, o) in &self.outcomes {
            c[match o {
                Outcome::Ran { .. } => 0,
                Outcome::UpToDate { .. } => 1,
                Outcome::Failed { .. } => 2,
                Outcome::NotRun { .. } => 3,
            }] += 1;
        }
        c
    }
}

/// What the executor knows of a task while the plan runs.
enum State {
    Waiting,
    Running {
        inputs: Vec<FileHash>,
        started: Instant,
    },
    Done(Outcome),
}

/// Writes the plan's own files, creates every output's directory, then runs the tasks.
pub fn run(
    plan: &Plan,
    options: &Options,
    progress: &dyn Progress,
) -> Result<Summary, CampaignError> {
    // A plan on object storage runs on this machine's mirror of it (store.rs).
    let staged = Staged::new(plan)?;
    let plan = staged.as_ref().map_or(plan, |s| &s.plan);
    let mut pulled = vec![staged.is_none(); plan.tasks.len()];
    let mut pull = |i: usize| -> Result<(), String> {
        match &staged {
            Some(s) if !pulled[i] => {
                s.pull(&plan.tasks[i]).map_err(|e| e.to_string())?;
                pulled[i] = true;
                Ok(())
            }
            _ => Ok(()),
        }
    };
    prepare(plan)?;
    let mut hashes = Hashes::default();
    let mut states: Vec<State> = plan.tasks.iter().map(|_| State::Waiting).collect();
    let index: std::collections::HashMap<&str, usize> = plan
        .tasks
        .iter()
        .enumerate()
        .map(|(i, t)| (t.id.as_str(), i))
        .collect();
    let (tx, rx) = mpsc::channel::<(usize, std::io::Result<std::process::ExitStatus>)>();
    let mut running = 0usize;
    // The order tasks start in when several are ready: the gap workflow first (it is the
    // longest task by far and nothing waits for it but the report), then the plan's order.
    let mut starts: Vec<usize> = (0..plan.tasks.len()).collect();
    starts.sort_by_key(|&i| plan.tasks[i].step != super::file::Step::Gap);
    loop {
        // Settle what can be settled without running anything: tasks whose predecessor did
        // not pass, and tasks that are up to date.
        let mut changed = true;
        while changed {
            changed = false;
            for (i, task) in plan.tasks.iter().enumerate() {
                if !matches!(states[i], State::Waiting) {
                    continue;
                }
                let mut blocked = None;
                let mut ready = true;
                for dep in &task.after {
                    let j = index[dep.as_str()];
                    match &states[j] {
                        State::Done(o) => {
                            if !passed(task, dep, o.exit()) {
                                blocked.get_or_insert_with(|| format!("{dep}: {}", short(o)));
                            }
                        }
                        _ => ready = false,
                    }
                }
                if let Some(because) = blocked.filter(|_| ready) {
                    let o = not_run(plan, &staged, task, because);
                    progress.finished(task, &o);
                    states[i] = State::Done(o);
                    changed = true;
                } else if ready && !options.force {
                    if let Err(why) = pull(i) {
                        let o = named(&staged, Outcome::Failed { why });
                        progress.finished(task, &o);
                        states[i] = State::Done(o);
                        changed = true;
                        continue;
                    }
                    if let Some(exit) = stamp::up_to_date(&plan.out, task, &mut hashes)? {
                        let o = Outcome::UpToDate { exit };
                        progress.finished(task, &o);
                        states[i] = State::Done(o);
                        changed = true;
                    }
                }
            }
        }
        // Start what is ready.
        for &i in &starts {
            let task = &plan.tasks[i];
            if running >= options.jobs.max(1) {
                break;
            }
            // Every task before it done and passed: one that failed to start a moment ago in
            // this loop is done but did not pass, and what waits for it is settled above.
            let ready = matches!(states[i], State::Waiting)
                && task.after.iter().all(|d| match &states[index[d.as_str()]] {
                    State::Done(o) => passed(task, d, o.exit()),
                    _ => false,
                });
            if !ready {
                continue;
            }
            let started = pull(i)
                .and_then(|()| clear(plan, &staged, task))
                .and_then(|()| start(task, i, options, &mut hashes, &tx));
            match started {
                Ok(inputs) => {
                    progress.started(task);
                    states[i] = State::Running {
                        inputs,
                        started: Instant::now(),
                    };
                    running += 1;
                }
                Err(why) => {
                    let o = named(&staged, Outcome::Failed { why });
                    progress.finished(task, &o);
                    states[i] = State::Done(o);
                }
            }
        }
        if running == 0 {
            if states.iter().all(|s| matches!(s, State::Done(_))) {
                break;
            }
            // Something became decidable by a failure to start: settle again.
            continue;
        }
        let (i, status) = rx.recv().expect("a waiter per running task");
        running -= 1;
        let task = &plan.tasks[i];
        let State::Running { inputs, started } = std::mem::replace(&mut states[i], State::Waiting)
        else {
            unreachable!("only running tasks are waited for");
        };
        let o = finish(plan, task, status, inputs, started.elapsed(), &mut hashes)?;
        let o = named(
            &staged,
            no_result_left(plan, &staged, task, pushed(&staged, task, o)),
        );
        progress.finished(task, &o);
        states[i] = State::Done(o);
    }
    Ok(Summary {
        outcomes: plan
            .tasks
            .iter()
            .zip(states)
            .map(|(t, s)| match s {
                State::Done(o) => (t.id.clone(), o),
                _ => unreachable!("the loop ends when every task is done"),
            })
            .collect(),
    })
}

/// `o` after what the task left was put into object storage: a task whose outputs did not
/// reach the bucket failed (its stamp is not put, so the next run does it again); a failed
/// task whose log did not reach it says so beside why it failed.
fn pushed(staged: &Option<Staged>, task: &Task, o: Outcome) -> Outcome {
    let Some(s) = staged else {
        return o;
    };
    match (s.push(task, matches!(o, Outcome::Ran { .. })), o) {
        (Ok(()), o) => o,
        (Err(e), Outcome::Ran { .. }) => Outcome::Failed {
            why: format!("its files were not stored: {e}"),
        },
        (Err(e), Outcome::Failed { why }) => Outcome::Failed {
            why: format!("{why} (its log was not stored: {e})"),
        },
        (Err(_), o) => o,
    }
}

/// Removes what `task` left before, its outputs and its stamp, here and (on object storage)
/// in the bucket: a task about to run, one that failed and one that does not run this time
/// leave nothing that a task after them, the report or a user would take for their result. (A
/// report runs after any outcome and says which files were not produced; a stale file would be
/// shown as this run's.) The log stays: it says what happened.
fn clear(plan: &Plan, staged: &Option<Staged>, task: &Task) -> Result<(), String> {
    if let Some(s) = staged {
        s.remove(task).map_err(|e| e.to_string())?;
    }
    let stamp = stamp::path(&plan.out, &task.id);
    for p in task.outputs.iter().chain([&stamp]) {
        match std::fs::remove_file(p) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(format!("cannot remove {}: {e}", p.display())),
        }
    }
    Ok(())
}

/// `task` does not run `because` a task before it did not pass: what it left before is
/// removed ([`clear`]).
fn not_run(plan: &Plan, staged: &Option<Staged>, task: &Task, because: String) -> Outcome {
    match clear(plan, staged, task) {
        Ok(()) => Outcome::NotRun { because },
        Err(e) => Outcome::Failed {
            why: format!("not run ({because}), and what it left before stays: {e}"),
        },
    }
}

/// `o`, with what a task that failed wrote removed ([`clear`]): a failed command's files are
/// no result.
fn no_result_left(plan: &Plan, staged: &Option<Staged>, task: &Task, o: Outcome) -> Outcome {
    match o {
        Outcome::Failed { why } => match clear(plan, staged, task) {
            Ok(()) => Outcome::Failed { why },
            Err(e) => Outcome::Failed {
                why: format!("{why}; {e}"),
            },
        },
        o => o,
    }
}

/// `o` with mirror paths named as the user named them (their URLs).
fn named(staged: &Option<Staged>, o: Outcome) -> Outcome {
    match (staged, o) {
        (Some(s), Outcome::Failed { why }) => Outcome::Failed { why: s.named(&why) },
        (Some(s), Outcome::NotRun { because }) => Outcome::NotRun {
            because: s.named(&because),
        },
        (_, o) => o,
    }
}

/// Whether `task` may run after its predecessor `dep` ended with `exit` (`None`: it failed or
/// did not run): any result does, except for a gate, which must have passed (exit 0); a
/// summary runs after any outcome.
fn passed(task: &Task, dep: &str, exit: Option<i32>) -> bool {
    if task.partial {
        return true;
    }
    match exit {
        None => false,
        Some(e) => e == 0 || !task.gates.iter().any(|g| g == dep),
    }
}

/// One line for an outcome that stops the tasks after it.
fn short(o: &Outcome) -> String {
    match o {
        Outcome::Ran { exit, .. } | Outcome::UpToDate { exit } => format!("exit {exit}"),
        Outcome::Failed { why } => format!("failed ({why})"),
        Outcome::NotRun { because } => format!("not run ({because})"),
    }
}

fn prepare(plan: &Plan) -> Result<(), CampaignError> {
    let io = |path: &Path| {
        let path = path.to_owned();
        move |source| CampaignError::Io { path, source }
    };
    let mut dirs: Vec<PathBuf> = plan
        .tasks
        .iter()
        .flat_map(|t| {
            t.outputs
                .iter()
                .chain([&t.log])
                .map(|p| p.parent().unwrap_or(Path::new("/")).to_owned())
        })
        .chain(
            plan.files
                .iter()
                .map(|f| f.path.parent().unwrap_or(Path::new("/")).to_owned()),
        )
        .chain(plan.tasks.iter().map(|t| {
            stamp::path(&plan.out, &t.id)
                .parent()
                .unwrap_or(Path::new("/"))
                .to_owned()
        }))
        .collect();
    dirs.sort();
    dirs.dedup();
    for d in dirs {
        std::fs::create_dir_all(&d).map_err(io(&d))?;
    }
    for f in &plan.files {
        // Rewritten only when it differs, so that an unchanged study keeps its hash and time;
        // through a file renamed into place, because engines that run single tasks on several
        // workers prepare the plan on each of them.
        if std::fs::read_to_string(&f.path).ok().as_deref() != Some(f.text.as_str()) {
            let tmp = f.path.with_extension(format!("tmp{}", std::process::id()));
            std::fs::write(&tmp, &f.text).map_err(io(&tmp))?;
            std::fs::rename(&tmp, &f.path).map_err(io(&f.path))?;
        }
    }
    Ok(())
}

/// Starts `task` with its inputs hashed (its stamp and outputs [`clear`]ed before); the reason
/// when it cannot start.
fn start(
    task: &super::plan::Task,
    i: usize,
    options: &Options,
    hashes: &mut Hashes,
    tx: &mpsc::Sender<(usize, std::io::Result<std::process::ExitStatus>)>,
) -> Result<Vec<FileHash>, String> {
    let inputs = match hashes.inputs(task) {
        Ok(Some(h)) => h,
        Ok(None) => {
            let missing = task
                .inputs
                .iter()
                .find(|p| !p.is_file())
                .map(|p| p.display().to_string())
                .unwrap_or_default();
            return Err(format!("input {missing} does not exist"));
        }
        Err(e) => return Err(e.to_string()),
    };
    let log = std::fs::File::create(&task.log)
        .map_err(|e| format!("cannot create {}: {e}", task.log.display()))?;
    let err = log
        .try_clone()
        .map_err(|e| format!("{}: {e}", task.log.display()))?;
    let mut cmd = Command::new(&options.exe);
    cmd.args(&task.args)
        .stdin(Stdio::null())
        .stdout(log)
        .stderr(err);
    // SAFETY: the closure runs in the child between fork and exec and only calls prctl(2),
    // which is async-signal-safe; it touches no memory of the parent.
    unsafe {
        use std::os::unix::process::CommandExt;
        cmd.pre_exec(|| {
            nix::sys::prctl::set_pdeathsig(nix::sys::signal::Signal::SIGKILL)
                .map_err(std::io::Error::from)
        });
    }
    let mut child = cmd
        .spawn()
        .map_err(|e| format!("cannot start {}: {e}", options.exe.display()))?;
    let tx = tx.clone();
    std::thread::spawn(move || {
        let status = child.wait();
        let _ = tx.send((i, status));
    });
    Ok(inputs)
}

/// The outcome of a task that ended, its stamp written when it has a result.
fn finish(
    plan: &Plan,
    task: &Task,
    status: std::io::Result<std::process::ExitStatus>,
    inputs: Vec<FileHash>,
    time: Duration,
    hashes: &mut Hashes,
) -> Result<Outcome, CampaignError> {
    let log = task.log.display();
    let code = match status {
        Ok(s) => match s.code() {
            Some(c) => c,
            None => {
                return Ok(Outcome::Failed {
                    why: format!("killed by a signal ({s}); see {log}"),
                })
            }
        },
        Err(e) => {
            return Ok(Outcome::Failed {
                why: format!("cannot wait for it: {e}"),
            })
        }
    };
    if !task.results.contains(&code) {
        return Ok(Outcome::Failed {
            why: format!("exit {code}; see {log}"),
        });
    }
    let Some(outputs) = hashes.all(&task.outputs)? else {
        let missing = task
            .outputs
            .iter()
            .find(|p| !p.is_file())
            .map(|p| p.display().to_string())
            .unwrap_or_default();
        return Ok(Outcome::Failed {
            why: format!("exit {code} but {missing} was not written; see {log}"),
        });
    };
    let stamp = Stamp {
        task: task.id.clone(),
        args: task.args.clone(),
        exit: code,
        inputs,
        outputs,
        tool: stamp::TOOL.to_owned(),
    };
    crate::output::write(&stamp::path(&plan.out, &task.id), &stamp).map_err(|e| {
        CampaignError::Invalid {
            path: stamp::path(&plan.out, &task.id),
            what: e.to_string(),
        }
    })?;
    Ok(Outcome::Ran { exit: code, time })
}

/// Runs the single task `id` of `plan`, as an engine that schedules tasks itself does it (one
/// `hilrig campaign task` per task, on any worker): the plan's files made, the tasks it waits
/// for checked by their stamps (each must have passed), skipped when up to date, else run and
/// stamped like the local executor's tasks.
pub fn run_task(plan: &Plan, id: &str, options: &Options) -> Result<Outcome, CampaignError> {
    let staged = Staged::new(plan)?;
    let plan = staged.as_ref().map_or(plan, |s| &s.plan);
    let Some(task) = plan.task(id) else {
        return Err(CampaignError::Invalid {
            path: plan.campaign_file.clone(),
            what: format!("the plan has no task '{id}'"),
        });
    };
    prepare(plan)?;
    if let Some(s) = &staged {
        let fetched = s.pull_stamps(&task.after).and_then(|()| s.pull(task));
        if let Err(e) = fetched {
            return Ok(named(&staged, Outcome::Failed { why: e.to_string() }));
        }
    }
    for dep in &task.after {
        let p = stamp::path(&plan.out, dep);
        let exit = std::fs::read(&p)
            .ok()
            .and_then(|b| crate::output::from_slice::<Stamp>(&p, &b).ok())
            .map(|s| s.exit);
        let because = match exit {
            e if passed(task, dep, e) => continue,
            Some(e) => format!("{dep}: exit {e}"),
            None => format!("{dep}: not finished"),
        };
        return Ok(named(&staged, not_run(plan, &staged, task, because)));
    }
    let mut hashes = Hashes::default();
    if !options.force {
        if let Some(exit) = stamp::up_to_date(&plan.out, task, &mut hashes)? {
            return Ok(Outcome::UpToDate { exit });
        }
    }
    let i = plan
        .tasks
        .iter()
        .position(|t| t.id == id)
        .expect("found above");
    let (tx, rx) = mpsc::channel();
    let started = Instant::now();
    let inputs =
        match clear(plan, &staged, task).and_then(|()| start(task, i, options, &mut hashes, &tx)) {
            Ok(inputs) => inputs,
            Err(why) => return Ok(named(&staged, Outcome::Failed { why })),
        };
    let (_, status) = rx.recv().expect("the waiter sends once");
    let o = finish(plan, task, status, inputs, started.elapsed(), &mut hashes)?;
    let o = pushed(&staged, task, o);
    Ok(named(&staged, no_result_left(plan, &staged, task, o)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::campaign::file::Step;

    struct Quiet;

    impl Progress for Quiet {
        fn started(&self, _: &Task) {}
        fn finished(&self, _: &Task, _: &Outcome) {}
    }

    fn task(dir: &Path, id: &str, inputs: &[PathBuf], after: &[&str]) -> Task {
        Task {
            id: id.into(),
            step: Step::Check,
            args: vec!["check".into()],
            inputs: inputs.to_vec(),
            outputs: vec![dir.join(format!("{id}.json"))],
            after: after.iter().map(|a| (*a).to_owned()).collect(),
            results: vec![0],
            gates: Vec::new(),
            partial: false,
            log: dir.join(format!("{id}.log")),
        }
    }

    /// A task that cannot even start (here: no executable) fails, and a task after it does
    /// not run: it must not be started on whatever the failed task left from an earlier run.
    /// What both left from that run is removed, so that nothing shows it as this run's.
    #[test]
    fn a_task_after_one_that_failed_to_start_does_not_run_and_neither_leaves_old_outputs() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let input = d.join("run.mcap");
        std::fs::write(&input, b"recording").unwrap();
        let a = task(d, "a", std::slice::from_ref(&input), &[]);
        let b = task(d, "b", &[d.join("a.json")], &["a"]);
        for t in [&a, &b] {
            std::fs::write(&t.outputs[0], b"an earlier run's").unwrap();
        }
        let plan = Plan {
            campaign: "x".into(),
            campaign_file: d.join("c.toml"),
            out: d.to_owned(),
            files: Vec::new(),
            tasks: vec![a, b],
        };
        let options = Options {
            exe: d.join("no-such-hilrig"),
            jobs: 1,
            force: false,
        };
        let summary = run(&plan, &options, &Quiet).unwrap();
        let outcome = |id: &str| &summary.outcomes.iter().find(|o| o.0 == id).unwrap().1;
        assert!(
            matches!(outcome("a"), Outcome::Failed { why } if why.contains("cannot start")),
            "{:?}",
            outcome("a")
        );
        assert!(
            matches!(outcome("b"), Outcome::NotRun { because } if because.starts_with("a: ")),
            "{:?}",
            outcome("b")
        );
        assert!(!d.join("a.json").exists() && !d.join("b.json").exists());
        assert!(input.is_file(), "an input is never removed");
    }
}

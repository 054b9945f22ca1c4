//! `hilrig campaign`: a campaign file planned into tasks and run here (`--jobs` at a time,
//! resumable), or the plan printed for another engine (`campaign plan`). Exit 0 when every task
//! ran with a passing result, 1 when a task failed or did not run (or a check failed), 2 when
//! the campaign cannot be planned (nothing runs then).

use anyhow::{Context, Result};
use hilrig::campaign::file::Campaign;
use hilrig::campaign::local::{self, Outcome, Progress};
use hilrig::campaign::plan::{Plan, Task};
use hilrig::campaign::{mirror, store};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct CampaignArgs {
    #[command(subcommand)]
    sub: Option<Sub>,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(clap::Subcommand)]
enum Sub {
    /// Print the task graph (inputs, outputs, command line, what each waits for).
    Plan(PlanArgs),
    /// Run one task of a plan (for engines that schedule the tasks themselves): its
    /// predecessors must have passed (their stamps say so); skipped when up to date. Prints
    /// one JSON line with the outcome; exit 0 when the task has a result, 1 when not.
    Task(TaskArgs),
}

#[derive(clap::Args)]
struct TaskArgs {
    /// The plan (`campaign plan --json`, or DIR/campaign/plan.json): a file, an object
    /// (`s3://...`), or `-` for standard input.
    #[arg(long)]
    plan: PathBuf,
    /// The task's id.
    id: String,
    /// Run it even when it is up to date.
    #[arg(long)]
    force: bool,
}

/// What `campaign task` prints: one task's outcome, for the engine that ran it.
#[derive(serde::Serialize)]
struct TaskOutcome<'a> {
    task: &'a str,
    /// ran, up_to_date, failed, not_run.
    outcome: &'static str,
    /// Its exit code, when it has a result.
    exit: Option<i32>,
    /// Whether the tasks that wait for it may run.
    passes: bool,
    /// Why it failed or did not run.
    why: Option<String>,
}

/// The plan from a file, an object (`s3://...`) or standard input (`-`: an engine passes it to a
/// worker that shares no disk with it).
fn read_plan(path: &std::path::Path) -> Result<Plan> {
    if path == std::path::Path::new("-") {
        let mut bytes = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin(), &mut bytes)?;
        return Ok(hilrig::output::from_slice(path, &bytes)?);
    }
    if mirror::is_url(path) {
        let url = path.to_string_lossy();
        let bytes = store::shared()?
            .get_bytes(&url)?
            .with_context(|| format!("{url} does not exist"))?;
        return Ok(hilrig::output::from_slice(path, &bytes)?);
    }
    Ok(hilrig::output::read(path)?)
}

fn run_task(t: TaskArgs) -> Result<ExitCode> {
    // An engine's worker that dies (a lost node) takes this task with it, and the command it
    // runs after it (that one dies with this process): a retry elsewhere must not race a task
    // still writing the same files.
    nix::sys::prctl::set_pdeathsig(nix::sys::signal::Signal::SIGKILL)?;
    if nix::unistd::getppid() == nix::unistd::Pid::from_raw(1) {
        anyhow::bail!("the engine that started this task has gone");
    }
    let plan: Plan = match read_plan(&t.plan) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e:#}");
            return Ok(ExitCode::from(2));
        }
    };
    let options = local::Options {
        exe: std::env::current_exe().context("cannot find the hilrig executable")?,
        jobs: 1,
        force: t.force,
    };
    let outcome = match local::run_task(&plan, &t.id, &options) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    // Whether the tasks that read its outputs may run (a gate's own check is theirs).
    let passes = outcome.exit().is_some();
    let (name, why) = match &outcome {
        Outcome::Ran { .. } => ("ran", None),
        Outcome::UpToDate { .. } => ("up_to_date", None),
        Outcome::Failed { why } => ("failed", Some(why.clone())),
        Outcome::NotRun { because } => ("not_run", Some(because.clone())),
    };
    let report = TaskOutcome {
        task: &t.id,
        outcome: name,
        exit: outcome.exit(),
        passes,
        why,
    };
    writeln!(
        std::io::stdout().lock(),
        "{}",
        serde_json::to_string(&report)?
    )?;
    Ok(if outcome.exit().is_some() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

#[derive(clap::Args)]
struct RunArgs {
    /// The campaign file (TOML: steps, [[drive]], [[scenario]], [[model]]).
    #[arg(required = true)]
    campaign: Option<PathBuf>,
    /// Output directory.
    #[arg(long, default_value = "campaign-out")]
    out: PathBuf,
    /// Tasks at a time (each command also uses every core for its own work).
    #[arg(long, short)]
    jobs: Option<usize>,
    /// Run every task again, including those a previous run finished.
    #[arg(long)]
    force: bool,
}

#[derive(clap::Args)]
struct PlanArgs {
    /// The campaign file.
    campaign: PathBuf,
    /// The output directory the plan writes into.
    #[arg(long, default_value = "campaign-out")]
    out: PathBuf,
    /// The plan as JSON (schema in hilrig::campaign::plan) instead of one line per task.
    #[arg(long)]
    json: bool,
}

/// The plan, or exit 2 with the reason.
fn plan(campaign: &std::path::Path, out: &std::path::Path) -> Result<Plan, ExitCode> {
    let planned = Campaign::load(campaign).and_then(|c| {
        let plan = Plan::build(&c, out)?;
        // Outputs in a bucket: that it answers with these credentials, before any task runs.
        if mirror::is_url(&plan.out) {
            store::shared()?.reachable(&plan.out.to_string_lossy())?;
        }
        Ok(plan)
    });
    planned.map_err(|e| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    })
}

pub fn run(args: CampaignArgs) -> Result<ExitCode> {
    if let Some(Sub::Task(t)) = args.sub {
        return run_task(t);
    }
    if let Some(Sub::Plan(p)) = args.sub {
        let plan = match plan(&p.campaign, &p.out) {
            Ok(p) => p,
            Err(code) => return Ok(code),
        };
        let mut out = std::io::stdout().lock();
        if p.json {
            writeln!(out, "{}", hilrig::output::to_json(&plan)?)?;
        } else {
            for t in &plan.tasks {
                let after = if t.after.is_empty() {
                    "-".into()
                } else {
                    t.after.join(", ")
                };
                writeln!(
                    out,
                    "{}  (after: {after})\n    hilrig {}",
                    t.id,
                    t.args.join(" ")
                )?;
            }
        }
        return Ok(ExitCode::SUCCESS);
    }
    let a = args.run;
    let campaign = a.campaign.expect("required unless a subcommand is given");
    let plan = match plan(&campaign, &a.out) {
        Ok(p) => p,
        Err(code) => return Ok(code),
    };
    let jobs = a
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from));
    let options = local::Options {
        exe: std::env::current_exe().context("cannot find the hilrig executable")?,
        jobs,
        force: a.force,
    };
    let plan_path = plan.out.join("campaign").join("plan.json");
    // Beside its outputs, also in a bucket: through this machine's mirror of it.
    let url = mirror::is_url(&plan_path).then(|| plan_path.to_string_lossy().into_owned());
    let store = match &url {
        Some(_) => Some(store::shared()?),
        None => None,
    };
    let local_plan = match (&url, store) {
        (Some(u), Some(s)) => s.mirror.local(u),
        _ => plan_path.clone(),
    };
    std::fs::create_dir_all(local_plan.parent().expect("has a parent"))
        .with_context(|| format!("cannot create the folder of {}", local_plan.display()))?;
    hilrig::output::write(&local_plan, &plan)?;
    if let (Some(u), Some(s)) = (&url, store) {
        s.put(u)?;
    }
    println!(
        "campaign '{}': {} tasks, {jobs} at a time (plan: {})",
        plan.campaign,
        plan.tasks.len(),
        plan_path.display()
    );
    let bars = Bars::new(plan.tasks.len());
    let summary = local::run(&plan, &options, &bars)?;
    bars.bar.finish_and_clear();
    let [ran, current, failed, not_run] = summary.counts();
    let checks_failed = summary
        .outcomes
        .iter()
        .filter(|(id, o)| id.starts_with("check/") && o.exit() == Some(1))
        .count();
    println!(
        "campaign '{}': {ran} ran, {current} up to date, {failed} failed, {not_run} not run; {checks_failed} drive(s) failed check; outputs in {}",
        plan.campaign,
        plan.out.display()
    );
    for (id, o) in &summary.outcomes {
        match o {
            Outcome::Failed { why } => println!("  FAILED  {id}: {why}"),
            Outcome::NotRun { because } => println!("  not run {id}: waits for {because}"),
            _ => {}
        }
    }
    Ok(if failed + not_run + checks_failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// One bar over the tasks, a line per task that ends.
pub(super) struct Bars {
    pub(super) bar: indicatif::ProgressBar,
    running: Mutex<Vec<String>>,
}

impl Bars {
    pub(super) fn new(n: usize) -> Bars {
        let bar = indicatif::ProgressBar::new(n as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:30} {pos}/{len} tasks {elapsed} {wide_msg}",
            )
            .expect("a valid template"),
        );
        Bars {
            bar,
            running: Mutex::new(Vec::new()),
        }
    }

    fn show(&self) {
        if let Ok(r) = self.running.lock() {
            self.bar.set_message(r.join(", "));
        }
    }
}

impl Progress for Bars {
    fn started(&self, task: &Task) {
        if let Ok(mut r) = self.running.lock() {
            r.push(task.id.clone());
        }
        self.show();
    }

    fn finished(&self, task: &Task, outcome: &Outcome) {
        if let Ok(mut r) = self.running.lock() {
            r.retain(|id| id != &task.id);
        }
        let line = match outcome {
            Outcome::Ran { exit, time } => format!(
                "{:<8} {} ({:.1} s, exit {exit})",
                "ran",
                task.id,
                time.as_secs_f64()
            ),
            Outcome::UpToDate { exit } => {
                format!("{:<8} {} (exit {exit} before)", "current", task.id)
            }
            Outcome::Failed { why } => format!("{:<8} {}: {why}", "FAILED", task.id),
            Outcome::NotRun { because } => {
                format!("{:<8} {}: waits for {because}", "not run", task.id)
            }
        };
        // A hidden bar (output not a terminal: a log, a test) prints nothing of its own.
        if self.bar.is_hidden() {
            println!("{line}");
        } else {
            self.bar.println(line);
        }
        self.bar.inc(1);
        self.show();
    }
}

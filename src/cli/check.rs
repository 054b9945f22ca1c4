//! `hilrig check`: the reference-data report on a recording; the exit code is the verdict.

use anyhow::{Context, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct CheckArgs {
    /// The recording (.mcap).
    run: PathBuf,
    /// The scene (origin of the local frame, survey accuracy of static objects).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// The rig file (lever arm, thresholds); default: the one attached to the recording.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Also write the report as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Also write the smoothed ego trajectory as CSV here (every 10 ms: time, rear-axle east and
    /// north, heading, and their 1-sigma errors). Its times are GNSS time where the run's logger
    /// clock was put on it (the report says so), else the run's.
    #[arg(long)]
    trajectory: Option<PathBuf>,
}

pub fn run(args: CheckArgs) -> Result<ExitCode> {
    use hilrig::reference::{check, run::Run};
    let run = match Run::read(&args.run) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("verdict: UNUSABLE\n  {e}");
            return Ok(ExitCode::from(2));
        }
    };
    let rig = match (&args.rig, &run.rig_toml) {
        (Some(p), _) => hilrig::rig::Rig::load(p)?,
        (None, Some(text)) => {
            hilrig::rig::Rig::from_toml(text, "rig.toml attached to the recording")?
        }
        (None, None) => {
            eprintln!("verdict: UNUSABLE\n  the recording has no rig.toml attached: give --rig");
            return Ok(ExitCode::from(2));
        }
    };
    let scene = args
        .scene
        .as_ref()
        .map(|p| hilrig::scene::Scene::load(p))
        .transpose()?;
    let (report, trajectory) = check::check_with_trajectory(&run, &rig, scene.as_ref());
    print!("{}", report.text());
    if let Some(p) = &args.json {
        hilrig::output::write(p, &report)?;
    }
    if let Some(p) = &args.trajectory {
        let Some(t) = &trajectory else {
            anyhow::bail!(
                "no trajectory to write to {}: {}",
                p.display(),
                report.text()
            );
        };
        std::fs::write(p, t.to_csv(10_000_000))
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(ExitCode::from(report.verdict.exit_code()))
}

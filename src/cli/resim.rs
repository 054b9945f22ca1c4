//! `hilrig resim`: a recording re-simulated with a lidar model, with a progress bar.

use anyhow::{Context, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct ResimArgs {
    /// The recording (.mcap).
    run: PathBuf,
    /// The scene.
    #[arg(long)]
    scene: PathBuf,
    /// The lidar model (model.toml).
    #[arg(long)]
    model: PathBuf,
    /// The output MCAP.
    #[arg(short, long)]
    output: PathBuf,
    /// The rig file; default: the one attached to the recording.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Take the ego poses from this trajectory file (t, x, y, z, yaw_deg in the scene frame)
    /// instead of the run's RTK+CAN trajectory.
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Re-simulate even when the run fails `check`.
    #[arg(long)]
    force: bool,
    /// Seed of the model's random effects.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Leave out /sim/points, the simulated clouds for viewing: most of the file (a minute of
    /// a VLS-128: 1.7 of 1.9 GB) and a sixth of the time. compare, validate and replay read
    /// only the simulated VelodyneScans.
    #[arg(long)]
    no_clouds: bool,
}

pub fn run(args: ResimArgs) -> Result<ExitCode> {
    use hilrig::sim::resim::{resim_recording, PoseSource, Recording, ResimError, ViewingClouds};
    // Without --rig, resim takes the rig file attached to the recording (reading it once).
    let rig = args
        .rig
        .as_ref()
        .map(|p| hilrig::rig::Rig::load(p))
        .transpose()?;
    let model = hilrig::sim::ModelFile::load(&args.model)?;
    // The scene (a BVH over every triangle) is built while the recording is read (a pass over
    // the whole file for `check`): a second or more each at real size.
    let (scene, recording) = std::thread::scope(|s| {
        let scene = s.spawn(|| hilrig::scene::Scene::load(&args.scene));
        let recording = Recording::read(&args.run, rig.as_ref());
        (scene.join(), recording)
    });
    let scene = scene.map_err(|_| anyhow::anyhow!("loading {} failed", args.scene.display()))??;
    let recording = recording?;
    let poses = match &args.trajectory {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            let t = hilrig::scene::pose::Trajectory::from_csv(&text)
                .map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?;
            PoseSource::File(t, p.display().to_string())
        }
        None => PoseSource::Run,
    };
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("resim [{bar:30}] {pos}/{len} scans, {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    match resim_recording(
        recording,
        &scene,
        &args.scene,
        &model,
        poses,
        args.force,
        args.seed,
        if args.no_clouds {
            ViewingClouds::LeaveOut
        } else {
            ViewingClouds::Write
        },
        &args.output,
        &progress,
    ) {
        Ok(s) => {
            bar.finish_and_clear();
            eprintln!(
                "{}: {} scans, {} packets re-simulated with model '{}' ({} of {} firings returned; check: {:?})",
                args.output.display(),
                s.scans,
                s.packets,
                model.name,
                s.stats.returns,
                s.stats.firings,
                s.verdict.unwrap_or(hilrig::reference::check::Verdict::Unusable)
            );
            if s.stats.outside_trajectory > 0 {
                eprintln!(
                    "{}: {} firings lie outside the trajectory and have no returns",
                    args.output.display(),
                    s.stats.outside_trajectory
                );
            }
            tracing::debug!(
                rays = s.stats.rays,
                footprints_cast = s.stats.footprints_cast,
                "rays cast"
            );
            Ok(ExitCode::SUCCESS)
        }
        Err(ResimError::Refused(report)) => {
            bar.finish_and_clear();
            eprint!("{}", report.text());
            eprintln!(
                "error: {}: {}",
                args.run.display(),
                ResimError::Refused(report.clone())
            );
            Ok(ExitCode::from(1))
        }
        Err(e) => Err(e.into()),
    }
}

//! `hilrig synth`: measured drives synthesized through a scene, with a progress bar per
//! repetition.

use anyhow::{Context, Result};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct SynthArgs {
    /// The true scene (TOML).
    #[arg(long)]
    scene: PathBuf,
    /// The drive (TOML: path, walkers, stream errors, rig).
    #[arg(long)]
    drive: PathBuf,
    /// The truth lidar model (model.toml).
    #[arg(long)]
    truth: PathBuf,
    /// Number of repetitions.
    #[arg(long, default_value_t = 5)]
    reps: u32,
    /// Base seed (each repetition derives its own).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory (rep-01, rep-02, ... are created in it).
    #[arg(short, long)]
    output: PathBuf,
    /// Write zstd-compressed captures (drive.pcapng.zst; hilrig reads them directly).
    #[arg(long)]
    compress: bool,
    /// The planned drive exactly, without human variation, reference errors or packet loss.
    #[arg(long)]
    no_errors: bool,
}

pub fn run(args: SynthArgs) -> Result<ExitCode> {
    use hilrig::sim::synth::{synth_rep, SynthJob};
    let scene_text = std::fs::read_to_string(&args.scene)
        .with_context(|| format!("cannot read {}", args.scene.display()))?;
    let scene_file: hilrig::scene::SceneFile =
        toml::from_str(&scene_text).with_context(|| format!("{}", args.scene.display()))?;
    // Load once to check the whole scene (meshes, trajectories) before any work.
    hilrig::scene::Scene::load(&args.scene)?;
    let drive = hilrig::sim::drive::DriveFile::load(&args.drive)?;
    let truth = hilrig::sim::ModelFile::load(&args.truth)?;
    let base = |p: &std::path::Path| p.parent().unwrap_or(std::path::Path::new(".")).to_owned();
    let (scene_base, drive_base) = (base(&args.scene), base(&args.drive));
    let job = SynthJob {
        scene_file: &scene_file,
        scene_base: &scene_base,
        drive: &drive,
        drive_base: &drive_base,
        truth: &truth,
        seed: args.seed,
        compress: args.compress,
        errors: !args.no_errors,
    };
    // A drive no car can drive is refused before anything is written.
    drive
        .drivable()
        .with_context(|| args.drive.display().to_string())?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("cannot create {}", args.output.display()))?;
    std::fs::write(args.output.join("truth-model.toml"), truth.to_toml())?;
    let bar = indicatif::ProgressBar::new(u64::from(args.reps));
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg} [{bar:30}] {pos}/{len} repetitions, {elapsed}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message("synth");
    for rep in 1..=args.reps {
        let dir = args.output.join(format!("rep-{rep:02}"));
        let s = synth_rep(&job, rep, &dir)?;
        bar.suspend(|| eprintln!(
            "{}: {:.1} s, {} lidar packets ({} lost), {} position, {} NMEA, {} CAN, {}, waited {:.1} s for the walker",
            dir.join(&s.capture).display(),
            s.duration_s,
            s.lidar_packets,
            s.lidar_packets_lost,
            s.position_packets,
            s.sentences,
            s.can_frames,
            s.return_share.map_or("returns not cast ([lidar] returns = false)".to_owned(), |r| {
                format!("returns {:.0} %", r * 100.0)
            }),
            s.yield_stop_s
        ));
        for w in &s.beyond_car {
            bar.suspend(|| {
                eprintln!(
                    "{}: warning: as driven (the driver model's steering, the human variation drawn for it), this repetition goes beyond what a car can do: {w}",
                    dir.display()
                );
            });
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(ExitCode::SUCCESS)
}

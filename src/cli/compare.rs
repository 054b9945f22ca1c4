//! `hilrig compare`: a run against its re-simulation, scan by scan (Rosenberger et al. 2019,
//! §5): grid and point metrics, the calibration curve over cell sizes and the Fig. 5 trend.
//! Exit 0 when compared, 2 when the inputs cannot be compared (nothing written then).

use anyhow::{Context, Result};
use hilrig::metrics::compare::{compare, Comparison, Options};
use hilrig::metrics::grid::Dims;
use hilrig::metrics::roi::Region;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
pub struct CompareArgs {
    /// The measured recording (.mcap).
    run: PathBuf,
    /// Its re-simulation (`hilrig resim`).
    sim: PathBuf,
    /// The scene (objects for the region and the objects in view, the ground).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// The rig file; default: the one attached to the recording.
    #[arg(long)]
    rig: Option<PathBuf>,
    /// Grid cell, m; default: the admissible cell `check` derives from the reference accuracy.
    #[arg(long)]
    cell: Option<f64>,
    /// Scans per occupancy grid (a cell is occupied when hit in more than half of them).
    #[arg(short = 'K', default_value_t = 1)]
    k: usize,
    /// Bird's-eye 2D cells instead of 3D voxels.
    #[arg(long)]
    bev: bool,
    /// Which points count: all, objects, or object:NAME.
    #[arg(long, default_value = "all")]
    roi: Region,
    /// Keep the ground's points (left out by default when the scene has a ground).
    #[arg(long)]
    keep_ground: bool,
    /// Compute with a cell smaller than the admissible one.
    #[arg(long)]
    allow_small_cell: bool,
    /// Poses from this trajectory file (t, x, y, z, yaw_deg) instead of the run's.
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Compare each scan in the sensor frame instead of the scene frame (no region, no ground
    /// exclusion: give --keep-ground).
    #[arg(long)]
    sensor_frame: bool,
    /// Average each scan's cell metrics over this many grids spread over a cell, placed anew
    /// from scan to scan (a wall on a cell boundary would otherwise halve OCR whatever the
    /// model)
    #[arg(long, default_value_t = hilrig::metrics::compare::DEFAULT_GRID_PHASES)]
    grid_phases: usize,
    /// The calibration curve (OCR over cell sizes) from every n-th scan's window (1: every
    /// window; 0: no curve); the chosen cell's OCR always comes from every window
    #[arg(long, default_value_t = hilrig::metrics::compare::DEFAULT_CURVE_EVERY)]
    curve_every: usize,
    /// Leave out the point metrics (Chamfer, Hausdorff: a nearest-neighbour search for every
    /// point, about as much work as the rest of the comparison)
    #[arg(long)]
    no_point_metrics: bool,
    /// Write everything as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the per-scan series as CSV here.
    #[arg(long)]
    csv: Option<PathBuf>,
}

fn fmt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "n/a".to_owned(), |x| format!("{x:.digits$}"))
}

/// The per-scan series (Fig. 5's columns first).
fn csv(c: &Comparison) -> String {
    let mut s = String::from(
        "t_s,stamp_ns,ego_speed_mps,objects_in_view,mean_distance_m,ocr,precision,iou,cosine,chamfer_m,hausdorff_m,range_diff_mean_m,range_diff_rms_m,only_real,only_sim,real_points,sim_points\n",
    );
    for r in &c.scans {
        let g = r.grid;
        let _ = writeln!(
            s,
            "{:.3},{},{:.3},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.t_s,
            r.stamp_ns,
            r.ego_speed_mps,
            r.objects_in_view,
            fmt(r.mean_distance_m, 3),
            fmt(g.and_then(|g| g.ocr), 4),
            fmt(g.and_then(|g| g.precision), 4),
            fmt(g.and_then(|g| g.iou), 4),
            fmt(g.and_then(|g| g.cosine), 4),
            fmt(r.points.map(|p| p.chamfer_m), 4),
            fmt(r.points.map(|p| p.hausdorff_m), 4),
            fmt(r.range_diff_mean_m, 4),
            fmt(r.range_diff_rms_m, 4),
            r.only_real,
            r.only_sim,
            r.real_points,
            r.sim_points
        );
    }
    s
}

fn text(c: &Comparison) -> String {
    let s = &c.summary;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "compared {} scans ({} of the run without a twin) in the {} frame; cell {:.3} m ({}, admissible {:.3} m), K = {}, region {}{}",
        s.scans,
        s.unpaired_run_scans,
        c.frame.name(),
        c.cell_m,
        if c.dims == Dims::Bev { "2D" } else { "3D" },
        c.admissible_cell_m,
        c.k,
        c.region,
        if c.ground_excluded { ", ground left out" } else { "" }
    );
    for l in &c.left_out {
        let _ = writeln!(
            out,
            "left out {} scans at {:.1} .. {:.1} s: check marks the reference not usable there ({}: {})",
            l.scans, l.mark.from_s, l.mark.to_s, l.mark.name, l.mark.detail
        );
    }
    let _ = writeln!(
        out,
        "OCR^K mean {} (median {}), precision {}, IoU {}, cosine {}",
        fmt(s.ocr_mean, 3),
        fmt(s.ocr_median, 3),
        fmt(s.precision_mean, 3),
        fmt(s.iou_mean, 3),
        fmt(s.cosine_mean, 3)
    );
    let _ = writeln!(
        out,
        "Chamfer {} m, Hausdorff {} m; per firing: range sim - real {} m (rms {} m), returns only measured {} %, only simulated {} %",
        fmt(s.chamfer_mean_m, 3),
        fmt(s.hausdorff_mean_m, 3),
        fmt(s.range_diff_mean_m, 4),
        fmt(s.range_diff_rms_m, 4),
        fmt(s.only_real_share.map(|x| x * 100.0), 1),
        fmt(s.only_sim_share.map(|x| x * 100.0), 1)
    );
    match &s.ocr_vs_distance {
        Some(r) => {
            let _ = writeln!(
                out,
                "OCR against the mean distance to the objects (Rosenberger et al. 2019, Fig. 5): Spearman {:.2} (95 % bootstrap interval {:.2} .. {:.2}, {} scans)",
                r.rho, r.low, r.high, r.n
            );
        }
        None => {
            let _ = writeln!(
                out,
                "OCR against distance: not evaluable (too few scans with objects in view)"
            );
        }
    }
    let _ = writeln!(out, "calibration (mean OCR^K by cell size; * admissible):");
    for p in &c.calibration {
        let _ = writeln!(
            out,
            "  {:>5.2} m {} {}",
            p.cell_m,
            fmt(p.ocr_mean, 3),
            if p.admissible { "*" } else { "" }
        );
    }
    out
}

pub fn run(args: CompareArgs) -> Result<ExitCode> {
    let rig = args
        .rig
        .as_ref()
        .map(|p| hilrig::rig::Rig::load(p))
        .transpose()?;
    let scene = args
        .scene
        .as_ref()
        .map(|p| hilrig::scene::Scene::load(p))
        .transpose()?;
    let trajectory = match &args.trajectory {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            Some(
                hilrig::scene::pose::Trajectory::from_csv(&text)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?,
            )
        }
        None => None,
    };
    let opts = Options {
        cell_m: args.cell,
        k: args.k,
        dims: if args.bev { Dims::Bev } else { Dims::Voxel },
        region: args.roi.clone(),
        exclude_ground: !args.keep_ground
            && scene.as_ref().is_some_and(|s| s.file.ground.is_some()),
        allow_small_cell: args.allow_small_cell,
        trajectory,
        sensor_frame: args.sensor_frame,
        grid_phases: args.grid_phases,
        curve_every: args.curve_every,
        point_metrics: !args.no_point_metrics,
    };
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("compare [{bar:30}] {pos}/{len} scans, {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let c = match compare(
        &args.run,
        &args.sim,
        rig.as_ref(),
        scene.as_ref(),
        opts,
        &progress,
    ) {
        Ok(c) => c,
        Err(e) => {
            bar.finish_and_clear();
            eprintln!("error: {e}");
            return Ok(ExitCode::from(2));
        }
    };
    bar.finish_and_clear();
    for d in &c.damage {
        eprintln!("warning: {d}");
    }
    print!("{}", text(&c));
    if let Some(p) = &args.json {
        hilrig::output::write(p, &c)?;
    }
    if let Some(p) = &args.csv {
        std::fs::write(p, csv(&c)).with_context(|| format!("cannot write {}", p.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

//! `hilrig compare`: a measured run against its re-simulation, scan by scan.
//!
//! Scans are paired by their stamp (re-simulation keeps every measured scan's stamp, packet
//! stamps and azimuths, so each simulated firing has a measured twin). Both are decoded with the
//! rig's calibration and put into the scene frame at each firing's pose: the trajectory `check`
//! smooths from the run (or a trajectory file), the lidar's mounting from the rig. Then per scan:
//! the grid metrics over the last K scans ([`super::grid`]), the point metrics
//! ([`super::points`]), the per-firing range residuals (same packet, firing time and laser), what the
//! sensor sees of the scene's objects, and the ego's speed; over the drive: the calibration
//! curve of OCR over cell sizes (Rosenberger et al. 2019, §5: a grid metric's cell size "has to
//! be evaluated in any case") and the Fig. 5 trend of OCR against the mean distance to the
//! objects (Spearman's ρ with a bootstrap interval).
//!
//! The cell must not be smaller than the admissible cell `check` derives from the reference
//! accuracy (§6): below it the metric measures the reference's errors, not the model's.

use super::cloud::{Cloud, Frame};
use super::grid::{compare as grid_compare, Dims, GridScores, GridSpec, Occupancy};
use super::pairing::usable_pairs;
use super::points::distances;
pub use super::report::{Comparison, CurvePoint, LeftOut, ObjectSeen, ScanRow, Snapshot, Summary};
use super::roi::{Region, Roi};
use crate::bag::scans::{read_scans, Scan};
use crate::reference::check::{check_with_trajectory, Verdict};
use crate::reference::run::Run;
use crate::rig::Rig;
use crate::scene::pose::{mounting_isometry, Trajectory};
use crate::scene::Scene;
use crate::stats::rank::spearman_with_interval;

use hilrig_velodyne::Decoder;
use nalgebra::Point3;
use rayon::prelude::*;
use std::path::Path;

/// Why two files cannot be compared.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// An input is unusable, or the two do not belong together.
    #[error("{0}")]
    Input(String),
    /// The cell is smaller than the reference data support.
    #[error("a {cell:.3} m cell is smaller than the {admissible:.3} m the reference accuracy admits (Rosenberger et al. 2019, §6: the cell must be at least ten times the reference accuracy); the metric would measure the reference's errors: use --cell {admissible:.3} or more, or --allow-small-cell to compute it anyway")]
    CellTooSmall {
        /// Asked for, m.
        cell: f64,
        /// What `check` admits, m.
        admissible: f64,
    },
}

/// What to compute.
#[derive(Clone, Debug)]
pub struct Options {
    /// Cell size, m (default: the admissible one from `check`).
    pub cell_m: Option<f64>,
    /// Scans per occupancy grid.
    pub k: usize,
    /// 2D or 3D cells.
    pub dims: Dims,
    /// Which points count.
    pub region: Region,
    /// Leave the ground out.
    pub exclude_ground: bool,
    /// Compute below the admissible cell.
    pub allow_small_cell: bool,
    /// Poses from this trajectory instead of the run's smoothed one.
    pub trajectory: Option<Trajectory>,
    /// Compare in the sensor frame (each scan as the sensor saw it, no ego motion) instead of
    /// the scene frame. The region and the ground then cannot be applied: all points count.
    pub sensor_frame: bool,
    /// The grid metrics are averaged over this many grids per window, spread over a cell and
    /// moving on from window to window ([`grid_phase`], [`GridSpec::shifted`]).
    pub grid_phases: usize,
}

/// Grids per window the cell metrics are averaged over unless told otherwise: of four
/// placements a quarter of a cell apart, at most one has a given wall within a few
/// centimetres of a boundary (a scan's own OCR then errs by at most a quarter of what that
/// wall's cells weigh), at four times the binning.
pub const DEFAULT_GRID_PHASES: usize = 4;

/// An object counts as seen with this many measured points in a scan.
pub const MIN_POINTS_SEEN: usize = 10;

/// Cell sizes of the calibration curve, m.
pub const CURVE_CELLS_M: [f64; 9] = [0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0];

fn mean(v: impl Iterator<Item = f64>) -> Option<f64> {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| s / n as f64)
}

fn extent(points: &[Point3<f64>]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let (mut lo, mut hi) = (points[0], points[0]);
    for p in points {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (hi - lo).norm()
}

/// What the sensor saw of the objects in one scan pair.
fn objects_seen(roi: &Roi, real: &Cloud, sim: &Cloud) -> Vec<ObjectSeen> {
    let margin = 0.2;
    roi.boxes()
        .iter()
        .filter_map(|(name, b)| {
            let r: Vec<&(Point3<f64>, f32)> = real
                .all
                .iter()
                .filter(|(p, _)| b.contains(p, margin))
                .collect();
            if r.len() < MIN_POINTS_SEEN {
                return None;
            }
            let s: Vec<Point3<f64>> = sim
                .all
                .iter()
                .filter(|(p, _)| b.contains(p, margin))
                .map(|(p, _)| *p)
                .collect();
            let rp: Vec<Point3<f64>> = r.iter().map(|(p, _)| *p).collect();
            Some(ObjectSeen {
                name: name.clone(),
                real_points: r.len(),
                sim_points: s.len(),
                range_m: r.iter().map(|(_, d)| f64::from(*d)).sum::<f64>() / r.len() as f64,
                real_extent_m: extent(&rp),
                sim_extent_m: extent(&s),
            })
        })
        .collect()
}

/// The range residuals of one scan pair: their sum and sum of squares over the firings both
/// have, and the returns only one has.
#[derive(Clone, Copy, Default)]
struct Residuals {
    sum: f64,
    sum2: f64,
    both: usize,
    only_real: usize,
    only_sim: usize,
}

/// Simulated minus measured range of the firings both have, and the returns only one has.
fn residuals(real: &Cloud, sim: &Cloud) -> Residuals {
    let mut r = Residuals::default();
    let (a, b) = (&real.firings, &sim.firings);
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].0.cmp(&b[j].0) {
            std::cmp::Ordering::Less => {
                r.only_real += 1;
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                r.only_sim += 1;
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                let diff = f64::from(b[j].1) - f64::from(a[i].1);
                r.sum += diff;
                r.sum2 += diff * diff;
                r.both += 1;
                i += 1;
                j += 1;
            }
        }
    }
    r.only_real += a.len() - i;
    r.only_sim += b.len() - j;
    r
}

/// Where the j-th of the `phases` grids of the window ending at scan `i` lies, as a fraction
/// of a cell from the scene origin along every axis: (j + u_i) / N, with u_i = frac(½ + i/φ)
/// (the golden-ratio sequence). A window's N grids are spread evenly over a cell, and from
/// window to window the spread moves on, so that a drive's mean is taken over N times its
/// scans' placements, as if the grid had been put down at random; no placement is favoured,
/// in particular not the origin, where man-made scenes put their walls on round coordinates
/// and round cell sizes would put the boundaries.
fn grid_phase(i: usize, j: usize, phases: usize) -> f64 {
    const INV_GOLDEN: f64 = 0.618_033_988_749_894_9;
    let u = (0.5 + i as f64 * INV_GOLDEN).fract();
    (j as f64 + u) / phases.max(1) as f64
}

/// The occupancy grids' scores of every window of K scans ending at each scan, averaged over
/// `phases` shifted grids ([`grid_phase`]).
fn windows(
    spec: &GridSpec,
    phases: usize,
    k: usize,
    real: &[Cloud],
    sim: &[Cloud],
) -> Vec<Option<GridScores>> {
    (0..real.len())
        .into_par_iter()
        .map(|i| {
            if i + 1 < k {
                return None;
            }
            let r: Vec<&[Point3<f64>]> = real[i + 1 - k..=i]
                .iter()
                .map(|c| c.points.as_slice())
                .collect();
            let s: Vec<&[Point3<f64>]> = sim[i + 1 - k..=i]
                .iter()
                .map(|c| c.points.as_slice())
                .collect();
            let scores = (0..phases.max(1))
                .map(|j| {
                    let g = spec.shifted(grid_phase(i, j, phases));
                    Some(grid_compare(
                        &Occupancy::of(&g, &r).ok()?,
                        &Occupancy::of(&g, &s).ok()?,
                    ))
                })
                .collect::<Option<Vec<GridScores>>>()?;
            GridScores::mean(&scores)
        })
        .collect()
}

/// The run's measured scans (and the damage they were read up to).
type Measured = (Vec<Scan>, Option<String>);

/// What `compare` takes from the run besides its scans.
struct Reference {
    run: Run,
    rig: Rig,
    trajectory: Trajectory,
    /// The admissible cell, m.
    admissible: f64,
    /// Stretches `check` marked not usable on this trajectory (none on a trajectory file).
    not_usable: Vec<LeftOut>,
}

/// The run's measured scans and what else `compare` needs of it.
fn reference(
    run_path: &Path,
    rig: Option<&Rig>,
    scene: Option<&Scene>,
    trajectory: Option<Trajectory>,
) -> Result<(Measured, Reference), CompareError> {
    let input = CompareError::Input;
    let (bytes, run, rig) = crate::reference::run::load_with_rig(run_path, rig).map_err(input)?;
    // The measured scans are read while the reference data are checked.
    let ((report, smoothed), measured) = rayon::join(
        || check_with_trajectory(&run, &rig, scene),
        || read_scans(&bytes),
    );
    if report.verdict == Verdict::Unusable {
        return Err(input(format!(
            "{}: the reference data cannot be judged ({}): see `hilrig check`",
            run_path.display(),
            report.unusable.unwrap_or_default()
        )));
    }
    let admissible = report.accuracy.grid_cell_m;
    // The marks judge the smoothed trajectory: on a trajectory file they do not apply.
    let marks = if trajectory.is_some() {
        Vec::new()
    } else {
        report.marks
    };
    let trajectory = match trajectory {
        Some(t) => t,
        None => smoothed
            .and_then(|t| t.sampled(10_000_000))
            .ok_or_else(|| input(format!("{}: no RTK+CAN trajectory", run_path.display())))?,
    };
    Ok((
        measured,
        Reference {
            run,
            rig,
            trajectory,
            admissible,
            not_usable: marks
                .into_iter()
                .map(|mark| LeftOut { mark, scans: 0 })
                .collect(),
        },
    ))
}

/// The grid of the options (the cell defaults to the admissible one), once the options are
/// known to be sound and the cell not below the admissible one (unless allowed).
fn grid_spec(opts: &Options, admissible: f64) -> Result<GridSpec, CompareError> {
    let input = CompareError::Input;
    let cell = opts.cell_m.unwrap_or(admissible);
    let spec = GridSpec::new(cell, opts.dims).map_err(|e| input(e.to_string()))?;
    if opts.k == 0 {
        return Err(input("-K 0: a grid needs at least one scan".into()));
    }
    if opts.grid_phases == 0 {
        return Err(input(
            "--grid-phases 0: the metrics need at least one grid".into(),
        ));
    }
    if cell < admissible - 1e-9 && !opts.allow_small_cell {
        return Err(CompareError::CellTooSmall { cell, admissible });
    }
    Ok(spec)
}

/// The simulation's scans, and the damage they were read up to.
fn read_simulation(sim_path: &Path) -> Result<(Vec<Scan>, Option<String>), CompareError> {
    let input = CompareError::Input;
    let sim_bytes = std::fs::read(sim_path)
        .map_err(|e| input(format!("cannot read {}: {e}", sim_path.display())))?;
    if !sim_bytes.starts_with(mcap::MAGIC) {
        return Err(input(format!("{}: not an MCAP file", sim_path.display())));
    }
    Ok(read_scans(&sim_bytes))
}

/// Compares the run at `run_path` with its re-simulation at `sim_path`. `progress(done, total)`
/// is called as scans are decoded.
pub fn compare(
    run_path: &Path,
    sim_path: &Path,
    rig: Option<&Rig>,
    scene: Option<&Scene>,
    opts: Options,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Comparison, CompareError> {
    let input = CompareError::Input;
    let started = std::time::Instant::now();
    let phase = |what: &str| {
        tracing::debug!(
            "compare: {what} after {:.3} s",
            started.elapsed().as_secs_f64()
        )
    };
    // The simulation is read while the run's reference data are checked.
    let (reference, simulated) = rayon::join(
        || reference(run_path, rig, scene, opts.trajectory.clone()),
        || read_simulation(sim_path),
    );
    let ((real_scans, real_damage), mut reference) = reference?;
    let admissible = reference.admissible;
    phase("reference checked, simulation read");
    let spec = grid_spec(&opts, admissible)?;
    let cell = spec.cell_m();
    let (sim_scans, sim_damage) = simulated?;
    // A damaged file is compared as far as it can be read, and says so.
    let damage: Vec<String> = [(run_path, real_damage), (sim_path, sim_damage)]
        .into_iter()
        .filter_map(|(p, d)| {
            let d = d?;
            Some(format!(
                "{}: read up to damage ({d}); compared what could be read",
                p.display()
            ))
        })
        .collect();
    if real_scans.is_empty() || sim_scans.is_empty() {
        return Err(input(format!(
            "no lidar scans (/velodyne_packets) in {}",
            if real_scans.is_empty() {
                run_path
            } else {
                sim_path
            }
            .display()
        )));
    }
    phase("scans read");
    let (pairs, n_paired) = usable_pairs(
        (&real_scans, run_path),
        (&sim_scans, sim_path),
        &mut reference.not_usable,
    )
    .map_err(input)?;
    let (lidar, model, calibration) = reference.rig.lidar_sensor().map_err(input)?;
    let decoder = Decoder::with_calibration(model, calibration);
    if opts.sensor_frame && (opts.region != Region::All || opts.exclude_ground) {
        return Err(input(
            "the sensor frame has no scene: --roi and ground exclusion need the scene frame (use --roi all --keep-ground)".into(),
        ));
    }
    let roi = Roi::new(opts.region.clone(), scene, opts.exclude_ground, 0.2).map_err(input)?;
    let frame = Frame {
        decoder: &decoder,
        mount: mounting_isometry(&lidar.mounting),
        trajectory: &reference.trajectory,
        pps_locked: reference
            .run
            .metadata
            .get("clock_sync/lidar")
            .and_then(|m| m.get("pps"))
            .is_some_and(|p| p == "Locked"),
        roi: &roi,
        sensor_frame: opts.sensor_frame,
    };
    let total = pairs.len() as u64;
    let done = std::sync::atomic::AtomicU64::new(0);
    let clouds: Vec<(Cloud, Cloud)> = pairs
        .par_iter()
        .map(|(r, s)| {
            let c = (frame.cloud(r), frame.cloud(s));
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(n, total);
            c
        })
        .collect();
    let (real, sim): (Vec<Cloud>, Vec<Cloud>) = clouds.into_iter().unzip();
    if real.iter().all(|c| c.points.is_empty()) {
        return Err(input(format!(
            "{}: no measured point lies in the region {:?} on the trajectory",
            run_path.display(),
            opts.region
        )));
    }
    phase("scans decoded");
    let grids = windows(&spec, opts.grid_phases, opts.k, &real, &sim);
    phase("grids");
    let t0 = real[0].middle;
    let (rows, res): (Vec<ScanRow>, Vec<Residuals>) = (0..real.len())
        .into_par_iter()
        .map(|i| {
            let (r, s) = (&real[i], &sim[i]);
            let objects = objects_seen(&roi, r, s);
            let res = residuals(r, s);
            let per = |x: f64| (res.both > 0).then(|| x / res.both as f64);
            let mut hint = 0;
            let speed = reference
                .trajectory
                .velocity_at(r.middle, &mut hint)
                .map_or(0.0, |v| v.xy().norm());
            let row = ScanRow {
                t_s: (r.middle.0 - t0.0) as f64 * 1e-9,
                stamp_ns: pairs[i].0.stamp.0,
                ego_speed_mps: speed,
                objects_in_view: objects.len(),
                mean_distance_m: mean(objects.iter().map(|o| o.range_m)),
                real_points: r.points.len(),
                sim_points: s.points.len(),
                grid: grids[i],
                points: distances(&r.points, &s.points),
                range_diff_mean_m: per(res.sum),
                range_diff_rms_m: per(res.sum2).map(f64::sqrt),
                only_real: res.only_real,
                only_sim: res.only_sim,
                objects,
            };
            (row, res)
        })
        .unzip();
    phase("rows");
    let calibration = curve(&real, &sim, &opts, (cell, &grids), admissible);
    phase("calibration curve");
    let summary = summarise(&rows, &res, &real, &sim, real_scans.len() - n_paired);
    let grid_of = |i: usize| spec.shifted(grid_phase(i, 0, opts.grid_phases));
    let snapshot = super::snapshot::snapshot(&rows, &real, &sim, &roi, &grid_of);
    Ok(Comparison {
        cell_m: cell,
        admissible_cell_m: admissible,
        k: opts.k,
        grid_phases: opts.grid_phases,
        dims: opts.dims,
        region: opts.region.to_string(),
        ground_excluded: opts.exclude_ground,
        damage,
        left_out: reference
            .not_usable
            .into_iter()
            .filter(|l| l.scans > 0)
            .collect(),
        frame: if opts.sensor_frame { "sensor" } else { "scene" },
        scans: rows,
        calibration,
        snapshot,
        summary,
    })
}

/// Mean OCR^K over the scans at each cell size of [`CURVE_CELLS_M`], the admissible and the
/// chosen cell. The curve holds drive means only, and those need one grid per window (the
/// placements move on from window to window, [`grid_phase`]); the chosen cell's point is the
/// mean of `chosen`, the per-scan scores already computed, so that it equals the summary's.
fn curve(
    real: &[Cloud],
    sim: &[Cloud],
    opts: &Options,
    (cell, chosen): (f64, &[Option<GridScores>]),
    admissible: f64,
) -> Vec<CurvePoint> {
    let mut cells: Vec<f64> = CURVE_CELLS_M.to_vec();
    cells.extend([cell, admissible]);
    cells.sort_by(f64::total_cmp);
    cells.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    cells
        .into_iter()
        .filter_map(|c| {
            let w = if (c - cell).abs() < 1e-9 {
                chosen.to_vec()
            } else {
                windows(&GridSpec::new(c, opts.dims).ok()?, 1, opts.k, real, sim)
            };
            Some(CurvePoint {
                cell_m: c,
                ocr_mean: mean(w.iter().flatten().filter_map(|g| g.ocr)),
                admissible: c >= admissible - 1e-9,
            })
        })
        .collect()
}

fn summarise(
    rows: &[ScanRow],
    res: &[Residuals],
    real: &[Cloud],
    sim: &[Cloud],
    unpaired: usize,
) -> Summary {
    let grid = |f: fn(&GridScores) -> Option<f64>| {
        mean(rows.iter().filter_map(|r| r.grid.as_ref().and_then(f)))
    };
    let mut ocr: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.grid.and_then(|g| g.ocr))
        .collect();
    ocr.sort_by(f64::total_cmp);
    let (sum, sum2, n) = res.iter().fold((0.0, 0.0, 0usize), |a, r| {
        (a.0 + r.sum, a.1 + r.sum2, a.2 + r.both)
    });
    let only_r: usize = res.iter().map(|r| r.only_real).sum();
    let only_s: usize = res.iter().map(|r| r.only_sim).sum();
    let (real_returns, sim_returns): (usize, usize) = real
        .iter()
        .zip(sim)
        .map(|(r, s)| (r.firings.len(), s.firings.len()))
        .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let trend: (Vec<f64>, Vec<f64>) = rows
        .iter()
        .filter_map(|r| Some((r.grid?.ocr?, r.mean_distance_m?)))
        .unzip();
    Summary {
        scans: rows.len(),
        unpaired_run_scans: unpaired,
        ocr_mean: grid(|g| g.ocr),
        ocr_median: (!ocr.is_empty()).then(|| ocr[ocr.len() / 2]),
        precision_mean: grid(|g| g.precision),
        iou_mean: grid(|g| g.iou),
        cosine_mean: grid(|g| g.cosine),
        chamfer_mean_m: mean(rows.iter().filter_map(|r| r.points.map(|p| p.chamfer_m))),
        hausdorff_mean_m: mean(rows.iter().filter_map(|r| r.points.map(|p| p.hausdorff_m))),
        range_diff_mean_m: (n > 0).then(|| sum / n as f64),
        range_diff_rms_m: (n > 0).then(|| (sum2 / n as f64).sqrt()),
        only_real_share: (real_returns > 0).then(|| only_r as f64 / real_returns as f64),
        only_sim_share: (sim_returns > 0).then(|| only_s as f64 / sim_returns as f64),
        ocr_vs_distance: spearman_with_interval(&trend.1, &trend.0, 2000, 2019),
    }
}

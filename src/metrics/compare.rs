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

pub use super::checked::Checked;
use super::cloud::Frame;
pub use super::error::{CompareError, SimulateError};
use super::grid::{Dims, GridScores, GridSpec};
use super::measure::{measure, Measured, Residuals};
use super::pairing::{Pair, Pairs};
pub use super::report::{
    Comparison, ComparisonFrame, CurvePoint, LeftOut, ObjectSeen, ScanRow, Snapshot, Summary,
};
use super::roi::{Region, Roi};
use super::tally::{mean, Tally};
use super::windows::{grid_phase, refuse_clamping_cell, windows, CurveSums, PointPair};
use crate::bag::scans::{Scan, ScanStream};
use crate::estimate::rank::spearman_with_interval;
use crate::rig::Rig;
use crate::scene::pose::{mounting_isometry, Trajectory};
use crate::scene::Scene;

use hilrig_velodyne::Decoder;
use rayon::prelude::*;
use std::path::Path;

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
    /// The calibration curve's other cells from every n-th window only (0: no curve; the
    /// chosen cell's point is always the mean over every window).
    pub curve_every: usize,
    /// Chamfer and Hausdorff distances per scan (nearest neighbours of every point: as much
    /// work as everything else together).
    pub point_metrics: bool,
}

/// Windows the calibration curve's other cells take by default: one in four. The curve holds
/// drive means, and consecutive windows of a 10 Hz sensor are nearly the same scene, so a
/// quarter of them gives the mean to well within what it is read for (Rosenberger et al.
/// 2019, §5: which cell sizes the metric can be used at); its ten grids per window were the
/// larger part of the binning.
pub const DEFAULT_CURVE_EVERY: usize = 4;

/// Grids per window the cell metrics are averaged over unless told otherwise: of four
/// placements a quarter of a cell apart, at most one has a given wall within a few
/// centimetres of a boundary (a scan's own OCR then errs by at most a quarter of what that
/// wall's cells weigh), at four times the binning.
pub const DEFAULT_GRID_PHASES: usize = 4;

pub use super::measure::MIN_POINTS_SEEN;
pub use super::windows::CURVE_CELLS_M;

/// The grid of the options (the cell defaults to the admissible one), once the options are
/// known to be sound and the cell not below the admissible one (unless allowed).
fn grid_spec(opts: &Options, admissible: f64) -> Result<GridSpec, CompareError> {
    let cell = opts.cell_m.unwrap_or(admissible);
    let spec = GridSpec::new(cell, opts.dims)?;
    if opts.k == 0 {
        return Err(CompareError::Option {
            option: "-K 0".into(),
            why: "a grid needs at least one scan",
        });
    }
    if opts.grid_phases == 0 {
        return Err(CompareError::Option {
            option: "--grid-phases 0".into(),
            why: "the metrics need at least one grid",
        });
    }
    if cell < admissible - 1e-9 && !opts.allow_small_cell {
        return Err(CompareError::CellTooSmall { cell, admissible });
    }
    Ok(spec)
}

/// Scan pairs decoded and measured together: enough to keep every core busy, few enough that
/// a 128-beam sensor's clouds stay a few hundred megabytes.
const BATCH_PAIRS: usize = 8;

/// What a comparison hands the simulation it makes as it goes ([`compare_simulated`]): the
/// poses to cast at, whether the lidar's stamps are GNSS time, and a batch of measured scans.
pub struct ToSimulate<'a> {
    /// The trajectory `check` smoothed from the run (or the one given).
    pub trajectory: &'a Trajectory,
    /// The lidar is PPS-locked (its packet stamps are GNSS time).
    pub pps_locked: bool,
    /// Measured scans, in file order.
    pub scans: &'a [Scan],
}

/// A simulation made as the comparison goes: the simulated twin of every scan it is handed,
/// in order, or why it cannot make them.
pub type Simulate<'a> = dyn FnMut(ToSimulate<'_>) -> Result<Vec<Scan>, SimulateError> + 'a;

/// Where the simulated twins come from.
enum Twins<'s, 'f> {
    /// A re-simulation's file, opened.
    File(&'f Path, ScanStream),
    /// Made as the run is read.
    Simulated(&'s mut Simulate<'f>),
}

/// Compares the run at `run_path` with its re-simulation at `sim_path`. `progress(done, total)`
/// is called as scans are decoded.
///
/// Both files are streamed: a first pass reads the run's reference data (and indexes its
/// scans), a second walks both files' scans together, so that memory holds the last K scan
/// pairs and a batch, never the drive.
pub fn compare(
    run_path: &Path,
    sim_path: &Path,
    rig: Option<&Rig>,
    scene: Option<&Scene>,
    opts: Options,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Comparison, CompareError> {
    // The simulation is opened first: a missing one fails before the run is checked.
    let sim = ScanStream::open(sim_path)?;
    let started = std::time::Instant::now();
    let checked = Checked::new(run_path, rig, scene, opts.trajectory.clone())?;
    tracing::debug!(
        "compare: run read and checked in {:.3} s",
        started.elapsed().as_secs_f64()
    );
    compare_twins(
        run_path,
        checked,
        Twins::File(sim_path, sim),
        scene,
        opts,
        progress,
    )
}

/// [`compare`] with a simulation made as the run is read: `simulate` is handed the measured
/// scans batch by batch and gives their twins (what the gap workflow does: no simulation file
/// to write in full and read back, one pass over the run instead of five).
///
/// `checked` is the run as [`Checked::new`] (or the caller's own check, through
/// [`Checked::from_check`]) made it: a run compared again and again is checked once.
pub fn compare_simulated(
    run_path: &Path,
    checked: Checked,
    simulate: &mut Simulate<'_>,
    scene: Option<&Scene>,
    opts: Options,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Comparison, CompareError> {
    compare_twins(
        run_path,
        checked,
        Twins::Simulated(simulate),
        scene,
        opts,
        progress,
    )
}

/// The scans of a run with the twins a simulation makes of them, batch by batch, less the
/// scans that touch a mark of `left_out` (counted there); a simulation that fails stops it,
/// with its reason kept.
struct Simulating<'a, 's, 'f> {
    real: &'a mut ScanStream,
    simulate: &'s mut Simulate<'f>,
    trajectory: &'a Trajectory,
    pps_locked: bool,
    left_out: &'a mut [LeftOut],
    /// The run's times of the scans' logger times (the marks are on them).
    clock: &'a crate::reference::run::LoggerClock,
    ready: std::collections::VecDeque<Pair>,
    paired: usize,
    error: Option<SimulateError>,
}

impl Iterator for Simulating<'_, '_, '_> {
    type Item = Pair;

    fn next(&mut self) -> Option<Pair> {
        while self.ready.is_empty() {
            if self.error.is_some() {
                return None;
            }
            let batch: Vec<Scan> = self.real.by_ref().take(BATCH_PAIRS).collect();
            if batch.is_empty() {
                return None;
            }
            let sims = match (self.simulate)(ToSimulate {
                trajectory: self.trajectory,
                pps_locked: self.pps_locked,
                scans: &batch,
            }) {
                Ok(s) if s.len() == batch.len() => s,
                Ok(s) => {
                    self.error = Some(
                        format!("the simulation gave {} scans for {}", s.len(), batch.len()).into(),
                    );
                    return None;
                }
                Err(e) => {
                    self.error = Some(e);
                    return None;
                }
            };
            for (r, s) in batch.into_iter().zip(sims) {
                self.paired += 1;
                if !super::pairing::marked(self.left_out, &r, self.clock) {
                    self.ready.push_back((r, s));
                }
            }
        }
        self.ready.pop_front()
    }
}

/// [`compare`] and [`compare_simulated`].
#[allow(
    clippy::too_many_lines,
    reason = "setup, the streamed pass over either kind of twin, and the summary, in order; the pass itself is measure_all"
)]
fn compare_twins(
    run_path: &Path,
    mut reference: Checked,
    twins: Twins<'_, '_>,
    scene: Option<&Scene>,
    opts: Options,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Comparison, CompareError> {
    let started = std::time::Instant::now();
    let phase = |what: &str| {
        tracing::debug!(
            "compare: {what} after {:.3} s",
            started.elapsed().as_secs_f64()
        )
    };
    let admissible = reference.admissible;
    let spec = grid_spec(&opts, admissible)?;
    let cell = spec.cell_m();
    let (Some(first_scan), Some(last_scan)) =
        (reference.run.scans.first(), reference.run.scans.last())
    else {
        return Err(CompareError::NoScans {
            run: run_path.to_owned(),
        });
    };
    let real_span = Some((first_scan.stamp, last_scan.stamp));
    refuse_clamping_cell(cell, &reference.trajectory, opts.sensor_frame)?;
    let (lidar, model, calibration) = reference.rig.lidar_sensor()?;
    let decoder = Decoder::with_calibration(model, calibration);
    if opts.sensor_frame && (opts.region != Region::All || opts.exclude_ground) {
        return Err(CompareError::SensorFrameHasNoScene);
    }
    let roi = Roi::new(opts.region.clone(), scene, opts.exclude_ground, 0.2)?;
    let frame = Frame {
        decoder: &decoder,
        mount: mounting_isometry(&lidar.mounting),
        trajectory: &reference.trajectory,
        pps_locked: reference.run.lidar_pps_locked(),
        roi: &roi,
        sensor_frame: opts.sensor_frame,
    };
    let total = reference.run.scans.len() as u64;
    let mut real_stream = ScanStream::open(run_path)?;
    let mut curve = CurveSums::new(cell, admissible, opts.dims);
    let (tally, paired, sim_path, sim_damage) = match twins {
        Twins::File(sim_path, mut sim_stream) => {
            let mut pairs = Pairs::new(
                real_stream.by_ref(),
                &reference.run.scans,
                sim_stream.by_ref(),
                &mut reference.not_usable,
                &reference.run.logger_clock,
            );
            let tally = measure_all(
                &mut pairs,
                (&frame, &roi),
                (&spec, &opts),
                &mut curve,
                &|n| progress(n, total),
            );
            if let Some(e) = pairs.finish_error(tally.rows.len(), (run_path, real_span), sim_path) {
                return Err(e);
            }
            let paired = pairs.paired;
            (tally, paired, Some(sim_path), sim_stream.finish())
        }
        Twins::Simulated(simulate) => {
            let mut pairs = Simulating {
                real: &mut real_stream,
                simulate,
                trajectory: &reference.trajectory,
                pps_locked: frame.pps_locked,
                left_out: &mut reference.not_usable,
                clock: &reference.run.logger_clock,
                ready: std::collections::VecDeque::new(),
                paired: 0,
                error: None,
            };
            let tally = measure_all(
                &mut pairs,
                (&frame, &roi),
                (&spec, &opts),
                &mut curve,
                &|n| progress(n, total),
            );
            if let Some(source) = pairs.error {
                return Err(CompareError::Simulation {
                    run: run_path.display().to_string(),
                    source,
                });
            }
            if tally.rows.is_empty() {
                return Err(CompareError::NothingUsable {
                    run: run_path.to_owned(),
                    marks: String::new(),
                });
            }
            (tally, pairs.paired, None, None)
        }
    };
    // A damaged file is compared as far as it can be read, and says so.
    let damage: Vec<String> = [
        (run_path, real_stream.finish()),
        (sim_path.unwrap_or(run_path), sim_damage),
    ]
    .into_iter()
    .filter_map(|(p, d)| {
        let d = d?;
        Some(format!(
            "{}: read up to damage ({d}); compared what could be read",
            p.display()
        ))
    })
    .collect();
    if !tally.any_real_point {
        return Err(CompareError::NoPointInRegion {
            run: run_path.to_owned(),
            region: opts.region.to_string(),
        });
    }
    phase("scans measured");
    let rows = tally.rows;
    let calibration = curve.points(&rows, cell, admissible);
    let summary = summarise(
        &rows,
        &tally.res,
        tally.returns,
        reference.run.scans.len() - paired,
    );
    let snapshot = tally.pick.map(|p| {
        super::snapshot::snapshot(
            (p.index, &rows[p.index]),
            (&p.real, &p.sim),
            p.origin,
            &roi,
            &spec.shifted(grid_phase(p.index, 0, opts.grid_phases)),
        )
    });
    Ok(Comparison {
        cell_m: cell,
        admissible_cell_m: admissible,
        k: opts.k,
        grid_phases: opts.grid_phases,
        curve_every: opts.curve_every,
        point_metrics: opts.point_metrics,
        dims: opts.dims,
        region: opts.region.to_string(),
        ground_excluded: opts.exclude_ground,
        damage,
        left_out: reference
            .not_usable
            .into_iter()
            .filter(|l| l.scans > 0)
            .collect(),
        frame: if opts.sensor_frame {
            ComparisonFrame::Sensor
        } else {
            ComparisonFrame::Scene
        },
        scans: rows,
        calibration,
        snapshot,
        summary,
    })
}

/// Measures every pair of `pairs` in batches: decoded and measured in parallel, then the
/// windows ending at the batch's scans (over the K - 1 pairs before it and the batch) at the
/// chosen cell and at the calibration curve's cells, then the rows.
fn measure_all(
    pairs: &mut dyn Iterator<Item = Pair>,
    (frame, roi): (&Frame<'_>, &Roi),
    (spec, opts): (&GridSpec, &Options),
    curve: &mut CurveSums,
    progress: &(dyn Fn(u64) + Sync),
) -> Tally {
    let mut tally = Tally::default();
    // The last K - 1 pairs' points before the batch.
    let mut history: std::collections::VecDeque<PointPair> = std::collections::VecDeque::new();
    let done = std::sync::atomic::AtomicU64::new(0);
    loop {
        let batch: Vec<Pair> = pairs.take(BATCH_PAIRS).collect();
        if batch.is_empty() {
            break;
        }
        let measured: Vec<Measured> = batch
            .par_iter()
            .map(|p| {
                let m = measure(frame, roi, p, opts.point_metrics);
                progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
                m
            })
            .collect();
        drop(batch);
        let first = tally.rows.len() - history.len();
        let (real, sim): (Vec<_>, Vec<_>) = history
            .iter()
            .map(|(r, s)| (r.as_slice(), s.as_slice()))
            .chain(
                measured
                    .iter()
                    .map(|m| (m.real.as_slice(), m.sim.as_slice())),
            )
            .unzip();
        let ends = history.len()..real.len();
        let grids = windows(
            spec,
            opts.grid_phases,
            opts.k,
            (&real, &sim),
            first,
            ends.clone(),
        );
        curve.add((opts.k, opts.curve_every), (&real, &sim), first, &ends);
        drop((real, sim));
        for c in tally.add(measured, grids, frame.trajectory) {
            history.push_back(c);
            if history.len() >= opts.k {
                history.pop_front();
            }
        }
    }
    tally
}

fn summarise(
    rows: &[ScanRow],
    res: &[Residuals],
    (real_returns, sim_returns): (usize, usize),
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

#[cfg(test)]
mod tests {
    use super::{summarise, GridScores, Residuals, ScanRow};
    use crate::metrics::points::PointScores;

    fn row(ocr: f64, precision: f64, distance_m: f64, chamfer_m: f64) -> ScanRow {
        ScanRow {
            objects_in_view: 1,
            mean_distance_m: Some(distance_m),
            grid: Some(GridScores {
                ocr: Some(ocr),
                precision: Some(precision),
                iou: Some(ocr * precision),
                cosine: None,
                real_cells: 1,
                sim_cells: 1,
                both_cells: 1,
            }),
            points: Some(PointScores {
                chamfer_m,
                hausdorff_m: 10.0 * chamfer_m,
            }),
            ..ScanRow::default()
        }
    }

    /// The drive's summary from rows and residuals whose numbers are known: means and the
    /// median over the scans, residuals pooled over the firings (not averaged per scan), the
    /// shares of returns only one side has, and OCR falling with distance.
    #[test]
    fn the_summary_of_known_rows() {
        let rows = [
            row(0.9, 0.8, 5.0, 0.02),
            row(0.5, 0.6, 20.0, 0.04),
            row(0.7, 1.0, 10.0, 0.09),
            row(0.6, 0.4, 15.0, 0.01),
        ];
        let res = [
            Residuals {
                sum: 0.3,
                sum2: 0.05,
                both: 3,
                only_real: 4,
                only_sim: 3,
            },
            Residuals {
                sum: -0.1,
                sum2: 0.03,
                both: 2,
                only_real: 6,
                only_sim: 2,
            },
        ];
        let s = summarise(&rows, &res, (100, 40), 2);
        let near = |a: Option<f64>, b: f64, what: &str| {
            assert!(
                a.is_some_and(|a| (a - b).abs() < 1e-12),
                "{what}: {a:?}, want {b}"
            );
        };
        assert_eq!((s.scans, s.unpaired_run_scans), (4, 2));
        near(s.ocr_mean, 0.675, "OCR mean");
        near(
            s.ocr_median,
            0.7,
            "OCR median (the upper of the middle two)",
        );
        near(s.precision_mean, 0.7, "precision");
        near(s.chamfer_mean_m, 0.04, "Chamfer");
        near(s.hausdorff_mean_m, 0.4, "Hausdorff");
        near(
            s.range_diff_mean_m,
            0.04,
            "mean residual: 0.2 m over 5 firings",
        );
        near(s.range_diff_rms_m, (0.08f64 / 5.0).sqrt(), "rms residual");
        near(s.only_real_share, 0.1, "only measured: 10 of 100 returns");
        near(s.only_sim_share, 0.125, "only simulated: 5 of 40 returns");
        let trend = s.ocr_vs_distance.expect("a trend over 4 scans");
        assert!((trend.rho + 1.0).abs() < 1e-12, "{trend:?}");
        // Nothing measured: no shares, no residuals.
        let empty = summarise(&[], &[], (0, 0), 0);
        assert_eq!(
            (
                empty.only_real_share,
                empty.only_sim_share,
                empty.range_diff_mean_m
            ),
            (None, None, None)
        );
    }
}

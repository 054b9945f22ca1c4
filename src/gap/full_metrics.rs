//! The validation runs re-simulated in full after each round, for the metrics a user reads
//! beside the per-firing likelihood the workflow decides by: OCR^K, precision, IoU and the
//! validation's traffic lights (Rosenberger et al. 2019, Fig. 7), so that the report shows the
//! gap shrink on data the fit did not see.

use super::observe::RunData;
use super::report::{FeatureAvm, FeatureLight, RunMetrics};
use super::GapError;
use crate::metrics::compare::{compare_simulated, Options as CompareOptions, ToSimulate};
use crate::metrics::features::scan_features;
use crate::metrics::grid::Dims;
use crate::metrics::roi::Region;
use crate::sim::model::ModelFile;
use crate::sim::resim::Resimulator;
use crate::stats::repetitions::RunFeatures;
use std::path::Path;

/// Re-simulates the validation runs in full with `model` into `dir` and measures them: each run
/// is read once, its scans cast batch by batch and compared as they come (OCR^K, precision,
/// IoU at the admissible cell), and their features kept for the validation (Rosenberger et al.
/// 2019, Fig. 7) of the simulated runs against the measured ones. The simulations are written
/// to `dir` (their VelodyneScans) for the user to open.
///
/// `measured` holds the measured runs' features once a first call has found them (the same
/// scans are compared in every round; only the simulation changes).
pub(super) fn run_metrics(
    val: &[RunData],
    model: &ModelFile,
    dir: &Path,
    tag: &str,
    measured: &mut Vec<RunFeatures>,
) -> Result<RunMetrics, GapError> {
    std::fs::create_dir_all(dir).map_err(|source| GapError::Output {
        path: dir.to_owned(),
        source,
    })?;
    let quiet = |_: u64, _: u64| {};
    let known = measured.len() == val.len();
    if !known {
        measured.clear();
    }
    let mut sim_features = Vec::new();
    let (mut ocr, mut precision, mut iou) = (Vec::new(), Vec::new(), Vec::new());
    for (i, r) in val.iter().enumerate() {
        let sim_path = dir.join(format!("{tag}-validation-{:02}.mcap", i + 1));
        let (_, sensor, calibration) = r.rig.lidar_sensor().map_err(|source| GapError::Lidar {
            run: r.name.clone(),
            source,
        })?;
        let decoder = hilrig_velodyne::Decoder::with_calibration(sensor, calibration);
        let mut resim = Resimulator::new(
            &r.path,
            &r.rig,
            &r.scene,
            &r.scene_path,
            model,
            i as u64 + 1,
            &sim_path,
            r.trajectory.span().0,
        )
        .map_err(|source| GapError::Resim {
            run: r.name.clone(),
            source,
        })?;
        let (mut real_scans, mut sim_scans) = (Vec::new(), Vec::new());
        let checked = r.checked.clone().map_err(|source| GapError::Compare {
            run: r.name.clone(),
            source,
        })?;
        let c = compare_simulated(
            &r.path,
            checked,
            &mut |t: ToSimulate<'_>| {
                let sims = resim.cast(t.trajectory, t.pps_locked, t.scans)?;
                if !known {
                    real_scans.extend(scan_features(t.scans, &decoder));
                }
                sim_scans.extend(scan_features(&sims, &decoder));
                Ok(sims)
            },
            Some(&r.scene),
            CompareOptions {
                cell_m: None,
                k: 1,
                dims: Dims::Voxel,
                region: Region::All,
                exclude_ground: true,
                allow_small_cell: false,
                trajectory: None,
                sensor_frame: false,
                grid_phases: crate::metrics::compare::DEFAULT_GRID_PHASES,
                // The rounds report OCR, precision and IoU: no curve, no point metrics.
                curve_every: 0,
                point_metrics: false,
            },
            &quiet,
        )
        .map_err(|source| GapError::Compare {
            run: r.name.clone(),
            source: std::sync::Arc::new(source),
        })?;
        resim.finish().map_err(|source| GapError::Resim {
            run: r.name.clone(),
            source,
        })?;
        ocr.extend(c.summary.ocr_mean);
        precision.extend(c.summary.precision_mean);
        iou.extend(c.summary.iou_mean);
        if !known {
            measured.push(RunFeatures {
                name: r.path.display().to_string(),
                damage: None,
                scans: real_scans,
            });
        }
        sim_features.push(RunFeatures {
            name: sim_path.display().to_string(),
            damage: None,
            scans: sim_scans,
        });
    }
    let v = crate::stats::repetitions::validate_features(measured, &sim_features, &[])?;
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    Ok(RunMetrics {
        ocr: mean(&ocr),
        precision: mean(&precision),
        iou: mean(&iou),
        avm: v
            .cells
            .iter()
            .map(|c| FeatureAvm {
                metric: c.metric.clone(),
                avm: c.avm,
            })
            .collect(),
        lights: v
            .cells
            .iter()
            .map(|c| FeatureLight {
                metric: c.metric.clone(),
                light: c.light,
            })
            .collect(),
        verdict: v.verdict,
    })
}

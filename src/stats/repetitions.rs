//! `hilrig validate` over files: the real repetitions and their re-simulations read, paired and
//! reduced to one value per run, scenario sample and feature; then [`super::validate`].

use super::validate::{cell, verdict, Cell, Phase, Verdict};
use crate::bag::scans::{Scan, ScanStream};
use crate::metrics::features::{scan_features, ScanFeatures, FEATURES};
use crate::rig::Rig;
use hilrig_velodyne::Decoder;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A simulated run and the real run it re-simulates.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Pairing {
    /// The simulation.
    pub sim: String,
    /// The real run sharing its scan stamps, if any.
    pub real: Option<String>,
    /// Scans they share.
    pub shared_scans: usize,
    /// Mean over the shared scans of (simulated − measured) mean range, m: a systematic
    /// difference of the data.
    pub mean_range_difference_m: Option<f64>,
}

/// Everything `validate` found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Validation {
    /// Block 1: measurement validation: each simulation's real twin.
    pub measurement: Vec<Pairing>,
    /// Whether every simulation has a twin.
    pub measurement_pass: bool,
    /// Inputs read only up to damage.
    pub damage: Vec<String>,
    /// Block 2: scenario validation: what is missing (repetitions too few, phases not covered).
    pub scenario_problems: Vec<String>,
    /// Block 3: model validation, per scenario sample and feature.
    pub cells: Vec<Cell>,
    /// The verdict.
    pub verdict: Verdict,
}

/// One run's per-scan features, as validation sets them against the other repetitions.
#[derive(Clone, Debug)]
pub struct RunFeatures {
    /// The run's name (its file).
    pub name: String,
    /// Where the file is damaged (it is used as far as it could be read).
    pub damage: Option<String>,
    /// Every scan's features, in order.
    pub scans: Vec<ScanFeatures>,
}

type Loaded = RunFeatures;

/// Scans whose features are computed together (both cores busy, a few scans in memory).
const BATCH_SCANS: usize = 16;

fn load(path: &Path, decoder: &Decoder) -> Result<Loaded, String> {
    let mut stream = ScanStream::open(path).map_err(|e| e.to_string())?;
    let mut scans = Vec::new();
    loop {
        let batch: Vec<Scan> = stream.by_ref().take(BATCH_SCANS).collect();
        if batch.is_empty() {
            break;
        }
        scans.extend(scan_features(&batch, decoder));
    }
    let damage = stream.finish();
    if scans.is_empty() {
        return Err(format!(
            "{}: no lidar scans (/velodyne_packets){}",
            path.display(),
            damage.map_or(String::new(), |d| format!(" ({d})"))
        ));
    }
    Ok(Loaded {
        damage: damage.map(|d| format!("{}: read up to damage ({d})", path.display())),
        name: path.display().to_string(),
        scans,
    })
}

/// Mean of each feature over the scans of `run` within `phase` (seconds after its first scan).
fn phase_values(run: &Loaded, phase: Option<&Phase>) -> [Option<f64>; 4] {
    let t0 = run.scans[0].stamp.0;
    let inside: Vec<&ScanFeatures> = run
        .scans
        .iter()
        .filter(|s| {
            let t = (s.stamp.0 - t0) as f64 * 1e-9;
            phase.is_none_or(|p| t >= p.from_s && t < p.to_s)
        })
        .collect();
    let mut out = [None; 4];
    for (k, o) in out.iter_mut().enumerate() {
        let v: Vec<f64> = inside.iter().filter_map(|s| s.values()[k]).collect();
        if !v.is_empty() {
            *o = Some(v.iter().sum::<f64>() / v.len() as f64);
        }
    }
    out
}

/// Validates `sims` against `reals` per phase (the whole run when `phases` is empty). The
/// decoder comes from `rig` or the first real run's attached rig.
pub fn validate(
    reals: &[PathBuf],
    sims: &[PathBuf],
    rig: Option<&Rig>,
    phases: &[Phase],
) -> Result<Validation, String> {
    if reals.is_empty() || sims.is_empty() {
        return Err("give at least one --real and one --sim".into());
    }
    let rig = match rig {
        Some(r) => r.clone(),
        None => crate::reference::run::load_with_rig(&reals[0], None)?.1,
    };
    let (_, model, calibration) = rig.lidar_sensor()?;
    let decoder = Decoder::with_calibration(model, calibration);
    let real: Vec<Loaded> = reals
        .iter()
        .map(|p| load(p, &decoder))
        .collect::<Result<_, _>>()?;
    let sim: Vec<Loaded> = sims
        .iter()
        .map(|p| load(p, &decoder))
        .collect::<Result<_, _>>()?;
    validate_features(&real, &sim, phases)
}

/// [`validate`] of runs whose features are known already (a re-simulation measured as it was
/// made, say). Every run must have at least one scan.
pub fn validate_features(
    real: &[RunFeatures],
    sim: &[RunFeatures],
    phases: &[Phase],
) -> Result<Validation, String> {
    if let Some(r) = real.iter().chain(sim).find(|r| r.scans.is_empty()) {
        return Err(format!("{}: no lidar scans (/velodyne_packets)", r.name));
    }
    for p in phases {
        if !(p.from_s.is_finite() && p.to_s.is_finite() && p.from_s < p.to_s) {
            return Err(format!(
                "phase '{}': from_s {} is not before to_s {}",
                p.name, p.from_s, p.to_s
            ));
        }
    }

    // Block 1: each simulation's twin.
    let measurement: Vec<Pairing> = sim
        .iter()
        .map(|s| {
            let by_stamp: HashMap<i64, &ScanFeatures> =
                s.scans.iter().map(|x| (x.stamp.0, x)).collect();
            let best = real
                .iter()
                .map(|r| {
                    (
                        r,
                        r.scans
                            .iter()
                            .filter(|x| by_stamp.contains_key(&x.stamp.0))
                            .count(),
                    )
                })
                .max_by_key(|(_, n)| *n);
            let (twin, shared) = match best {
                Some((r, n)) if n > 0 => (Some(r), n),
                _ => (None, 0),
            };
            let diff = twin.and_then(|r| {
                let d: Vec<f64> = r
                    .scans
                    .iter()
                    .filter_map(|a| {
                        let b = by_stamp.get(&a.stamp.0)?;
                        (a.returns > 0 && b.returns > 0).then_some(b.mean_range_m - a.mean_range_m)
                    })
                    .collect();
                (!d.is_empty()).then(|| d.iter().sum::<f64>() / d.len() as f64)
            });
            Pairing {
                sim: s.name.clone(),
                real: twin.map(|r| r.name.clone()),
                shared_scans: shared,
                mean_range_difference_m: diff,
            }
        })
        .collect();
    let measurement_pass = measurement.iter().all(|p| p.real.is_some());

    // Block 2: enough repetitions, every phase in every run.
    let mut scenario_problems = Vec::new();
    if real.len() < 2 {
        scenario_problems.push(format!(
            "{} real repetition: an interval needs at least 2",
            real.len()
        ));
    }
    for p in phases {
        for r in real.iter().chain(sim) {
            if phase_values(r, Some(p))[0].is_none() {
                scenario_problems.push(format!(
                    "{}: no scan in phase '{}' ({} .. {} s)",
                    r.name, p.name, p.from_s, p.to_s
                ));
            }
        }
    }

    // Block 3: the lights.
    let samples: Vec<Option<&Phase>> = if phases.is_empty() {
        vec![None]
    } else {
        phases.iter().map(Some).collect()
    };
    let mut cells = Vec::new();
    for ph in samples {
        let rv: Vec<[Option<f64>; 4]> = real.iter().map(|r| phase_values(r, ph)).collect();
        let sv: Vec<[Option<f64>; 4]> = sim.iter().map(|s| phase_values(s, ph)).collect();
        for (k, name) in FEATURES.iter().enumerate() {
            let r: Vec<Option<f64>> = rv.iter().map(|v| v[k]).collect();
            let s: Vec<Option<f64>> = sv.iter().map(|v| v[k]).collect();
            cells.push(cell(
                ph.map_or("whole run", |p| p.name.as_str()),
                name,
                &r,
                &s,
            ));
        }
    }
    let v = verdict(&cells, measurement_pass && scenario_problems.is_empty());
    Ok(Validation {
        damage: real
            .iter()
            .chain(sim)
            .filter_map(|l| l.damage.clone())
            .collect(),
        measurement,
        measurement_pass,
        scenario_problems,
        cells,
        verdict: v,
    })
}

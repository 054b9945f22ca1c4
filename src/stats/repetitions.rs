//! `hilrig validate` over files: the real repetitions and their re-simulations read, paired and
//! reduced to one value per run, scenario sample and feature; then [`super::validate`].

use super::validate::{cell, verdict, Cell, Phase, Verdict};
use crate::bag::scans::{Scan, ScanStream};
use crate::metrics::features::{scan_features, ScanFeatures, FEATURES};
use crate::rig::Rig;
use hilrig_velodyne::Decoder;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Why repetitions cannot be validated.
#[derive(Debug, thiserror::Error)]
pub enum ValidateError {
    /// No real or no simulated run.
    #[error("give at least one --real and one --sim")]
    NoRuns,
    /// The first real run (whose rig decodes them all) cannot be read, or has no rig.
    #[error(transparent)]
    Run(#[from] crate::reference::run::RunError),
    /// The rig's lidar cannot be decoded.
    #[error(transparent)]
    Lidar(#[from] crate::rig::LidarSensorError),
    /// A run cannot be opened.
    #[error(transparent)]
    Open(#[from] crate::bag::scans::ScanStreamError),
    /// A run without a scan.
    #[error("{run}: no lidar scans (/velodyne_packets){damage}")]
    NoScans {
        /// The run.
        run: String,
        /// What stopped its reading, if anything (in parentheses).
        damage: String,
    },
    /// A phase that ends before it starts.
    #[error("phase '{name}': from_s {from_s} is not before to_s {to_s}")]
    Phase {
        /// Its name.
        name: String,
        /// Its start, s.
        from_s: f64,
        /// Its end, s.
        to_s: f64,
    },
}

/// A simulated run and the real run it re-simulates.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
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

fn load(path: &Path, decoder: &Decoder) -> Result<Loaded, ValidateError> {
    let mut stream = ScanStream::open(path)?;
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
        return Err(ValidateError::NoScans {
            run: path.display().to_string(),
            damage: damage.map_or(String::new(), |d| format!(" ({d})")),
        });
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
) -> Result<Validation, ValidateError> {
    if reals.is_empty() || sims.is_empty() {
        return Err(ValidateError::NoRuns);
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
) -> Result<Validation, ValidateError> {
    if let Some(r) = real.iter().chain(sim).find(|r| r.scans.is_empty()) {
        return Err(ValidateError::NoScans {
            run: r.name.clone(),
            damage: String::new(),
        });
    }
    for p in phases {
        if !(p.from_s.is_finite() && p.to_s.is_finite() && p.from_s < p.to_s) {
            return Err(ValidateError::Phase {
                name: p.name.clone(),
                from_s: p.from_s,
                to_s: p.to_s,
            });
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

impl crate::output::Output for Validation {
    const KIND: crate::output::OutputKind = crate::output::OutputKind::Validate;
    const SCHEMA: u32 = 1;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::avm::Light;
    use hilrig_stamp::UtcNanos;

    const T0: i64 = 1_800_000_000_000_000_000;

    /// A scan `tenths` tenths of a second after `T0` (exact stamps), with `returns` returns at
    /// a mean range `range` (p95 one metre further, intensity 20); a scan without returns has
    /// zeros, as [`scan_features`] gives it.
    fn scan(tenths: i64, returns: usize, range: f64) -> ScanFeatures {
        let some = if returns > 0 { 1.0 } else { 0.0 };
        ScanFeatures {
            stamp: UtcNanos(T0 + tenths * 100_000_000),
            returns,
            mean_range_m: some * range,
            range_p95_m: some * (range + 1.0),
            mean_intensity: some * 20.0,
        }
    }

    fn run(name: &str, scans: Vec<ScanFeatures>) -> RunFeatures {
        RunFeatures {
            name: name.into(),
            damage: None,
            scans,
        }
    }

    /// Scans every 0.1 s from `from` (tenths) for `n` scans, mean range 10 m.
    fn steady(name: &str, from: i64, n: i64) -> RunFeatures {
        run(
            name,
            (from..from + n).map(|k| scan(k, 1000, 10.0)).collect(),
        )
    }

    #[test]
    fn a_simulation_is_paired_with_the_real_run_sharing_most_stamps_and_its_range_difference_is_signed(
    ) {
        // Real A: 10 scans from 0 s; real B: 30 scans from 5 s. The simulation re-simulates B's
        // first 20 scans (stamps 5.0..6.9 s, of which A holds none), 4 cm further than B
        // measured, except one scan the simulation has no return in and one B has none in.
        let a = steady("a", 0, 10);
        let mut b = steady("b", 50, 30);
        b.scans[3].returns = 0;
        let sim = run(
            "sim",
            (50..70)
                .map(|k| scan(k, if k == 57 { 0 } else { 900 }, 10.04))
                .collect(),
        );
        let v = validate_features(&[a, b], &[sim], &[]).unwrap();
        let p = &v.measurement[0];
        assert_eq!(p.real.as_deref(), Some("b"), "the twin");
        assert_eq!(p.shared_scans, 20);
        // Simulated minus measured, over the 18 scans both have returns in.
        let d = p.mean_range_difference_m.unwrap();
        assert!(
            (d - 0.04).abs() < 1e-9,
            "mean range difference {d} m, simulated 4 cm further than measured"
        );
        assert!(v.measurement_pass);
    }

    #[test]
    fn a_simulation_without_a_twin_fails_the_measurement_block() {
        let sim = steady("sim", 1000, 5);
        let v = validate_features(&[steady("a", 0, 20), steady("b", 0, 20)], &[sim], &[]).unwrap();
        assert_eq!(v.measurement[0].real, None);
        assert_eq!(v.measurement[0].shared_scans, 0);
        assert_eq!(v.measurement[0].mean_range_difference_m, None);
        assert!(!v.measurement_pass);
        assert_eq!(v.verdict, Verdict::NotEvaluable);
    }

    #[test]
    fn a_phase_averages_each_feature_over_its_half_open_window_from_the_first_scan() {
        // Scans at 3.0, 3.1, ... 4.9 s: mean range 10 + (time since the first scan); the scan
        // at 0.8 s after the first has no returns.
        let r = run(
            "r",
            (30..50)
                .map(|k| {
                    let t = (k - 30) as f64 * 0.1;
                    scan(k, if k == 38 { 0 } else { 100 + k as usize }, 10.0 + t)
                })
                .collect(),
        );
        let phase = Phase {
            name: "p".into(),
            from_s: 0.5,
            to_s: 1.0,
        };
        // In [0.5, 1.0): the scans at 0.5, 0.6, 0.7, 0.9 s with returns (0.8 s has none, 1.0 s
        // is outside): mean range 10.675; the returns counted over all five scans in it.
        let v = phase_values(&r, Some(&phase));
        assert!(
            (v[1].unwrap() - 10.675).abs() < 1e-9,
            "features in [0.5, 1.0) s: {v:?}, mean range 10.675 m"
        );
        assert!((v[2].unwrap() - 11.675).abs() < 1e-9, "{v:?}");
        let returns = (135 + 136 + 137 + 139) as f64 / 5.0;
        assert!((v[0].unwrap() - returns).abs() < 1e-9, "{v:?}");
        // The whole run: every scan.
        let all = phase_values(&r, None);
        let n_ret = (30..50).filter(|&k| k != 38).count() as f64;
        let mean: f64 = (30..50)
            .filter(|&k| k != 38)
            .map(|k| 10.0 + (k - 30) as f64 * 0.1)
            .sum::<f64>()
            / n_ret;
        assert!((all[1].unwrap() - mean).abs() < 1e-9);
        // A phase with no scan has no value.
        let late = Phase {
            name: "late".into(),
            from_s: 5.0,
            to_s: 6.0,
        };
        assert_eq!(phase_values(&r, Some(&late)), [None; 4]);
    }

    #[test]
    fn each_feature_gets_its_light_from_the_real_and_simulated_intervals() {
        // Two real repetitions (mean range 10.0 and 10.2 m), one simulation inside that interval
        // in mean range, beyond it in the 95th percentile, and overlapping it in intensity.
        let real = |name: &str, from: i64, range: f64, intensity: f64| {
            run(
                name,
                (from..from + 10)
                    .map(|k| ScanFeatures {
                        mean_intensity: intensity,
                        ..scan(k, 1000, range)
                    })
                    .collect(),
            )
        };
        let sim = run(
            "sim",
            (0..10)
                .map(|k| ScanFeatures {
                    range_p95_m: 14.0,
                    mean_intensity: 25.0,
                    ..scan(k, 1000, 10.1)
                })
                .collect(),
        );
        let sim2 = run(
            "sim2",
            (0..10)
                .map(|k| ScanFeatures {
                    range_p95_m: 14.0,
                    mean_intensity: 21.0,
                    ..scan(k, 1000, 10.1)
                })
                .collect(),
        );
        let v = validate_features(
            &[real("a", 0, 10.0, 20.0), real("b", 100, 10.2, 22.0)],
            &[sim, sim2],
            &[],
        )
        .unwrap();
        let light = |m: &str| v.cells.iter().find(|c| c.metric == m).unwrap().light;
        assert_eq!(light("returns_per_scan"), Light::Green);
        assert_eq!(light("mean_range_m"), Light::Green);
        assert_eq!(light("range_p95_m"), Light::Red);
        assert_eq!(light("mean_intensity"), Light::Yellow);
        let p95 = v.cells.iter().find(|c| c.metric == "range_p95_m").unwrap();
        assert!((p95.real[0] - 11.0).abs() < 1e-9 && (p95.real[1] - 11.2).abs() < 1e-9);
        assert_eq!(p95.sim, vec![14.0, 14.0]);
        assert_eq!(v.verdict, Verdict::Invalid);
    }

    #[test]
    fn too_few_repetitions_and_uncovered_phases_are_scenario_problems() {
        let phases = [Phase {
            name: "park".into(),
            from_s: 1.5,
            to_s: 2.5,
        }];
        // One real run of 2 s (scans in the phase from 1.5 to 1.9 s), re-simulated: too few
        // repetitions for an interval.
        let v = validate_features(&[steady("a", 0, 20)], &[steady("sim", 0, 20)], &phases).unwrap();
        assert_eq!(v.scenario_problems.len(), 1, "{:?}", v.scenario_problems);
        assert!(v.scenario_problems[0].starts_with("1 real repetition"));
        let short = validate_features(
            &[steady("a", 0, 30), steady("b", 0, 12)],
            &[steady("sim", 0, 30)],
            &phases,
        )
        .unwrap();
        assert_eq!(
            short.scenario_problems,
            ["b: no scan in phase 'park' (1.5 .. 2.5 s)"]
        );
        assert_eq!(short.verdict, Verdict::NotEvaluable);
    }

    #[test]
    fn bad_phases_and_runs_without_scans_are_refused() {
        let (r, s) = (steady("a", 0, 5), steady("sim", 0, 5));
        for (from_s, to_s) in [
            (2.0, 1.0),
            (1.0, 1.0),
            (f64::NAN, 1.0),
            (0.0, f64::INFINITY),
        ] {
            let p = Phase {
                name: "x".into(),
                from_s,
                to_s,
            };
            let e = validate_features(std::slice::from_ref(&r), std::slice::from_ref(&s), &[p])
                .unwrap_err()
                .to_string();
            assert!(e.contains("phase 'x'"), "{e}");
        }
        let e = validate_features(&[run("empty", vec![])], &[s], &[])
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("empty: no lidar scans"), "{e}");
    }
}

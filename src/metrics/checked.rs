//! A run checked for comparison: what `compare` takes from a run besides its scans.

use super::error::CompareError;
use super::report::LeftOut;
use crate::reference::check::report::Report;
use crate::reference::check::{check_with_trajectory, Verdict};
use crate::reference::run::Run;
use crate::reference::trajectory::EgoTrajectory;
use crate::rig::Rig;
use crate::scene::pose::Trajectory;
use crate::scene::Scene;
use std::path::Path;

/// What `compare` takes from a run besides its scans: the run read as a stream (its scans only
/// indexed), its rig, the trajectory to place the clouds with, the admissible cell and the
/// stretches `check` marked not usable. Made once per run ([`Checked::new`]); the gap workflow
/// keeps it from loading the run and hands it to every comparison of that run
/// ([`compare_simulated`]), so that a run compared six times is checked once.
#[derive(Clone)]
pub struct Checked {
    pub(super) run: Run,
    pub(super) rig: Rig,
    pub(super) trajectory: Trajectory,
    /// The admissible cell, m.
    pub(super) admissible: f64,
    /// Stretches `check` marked not usable on this trajectory (none on a trajectory file).
    pub(super) not_usable: Vec<LeftOut>,
}

impl Checked {
    /// Reads the run at `run_path` (with `rig`, else the one it carries), checks it and takes
    /// its smoothed trajectory (or `trajectory` when given: the marks then do not apply).
    pub fn new(
        run_path: &Path,
        rig: Option<&Rig>,
        scene: Option<&Scene>,
        trajectory: Option<Trajectory>,
    ) -> Result<Checked, CompareError> {
        let (run, rig) = crate::reference::run::load_with_rig(run_path, rig)?;
        let (report, smoothed) = check_with_trajectory(&run, &rig, scene);
        Checked::from_check(run_path, run, rig, report, smoothed, trajectory)
    }

    /// What [`Checked::new`] makes, from a check already made of `run` (its report and smoothed
    /// trajectory): one function for both, so that a comparison sees the same whichever made it.
    pub fn from_check(
        run_path: &Path,
        run: Run,
        rig: Rig,
        report: Report,
        smoothed: Option<EgoTrajectory>,
        trajectory: Option<Trajectory>,
    ) -> Result<Checked, CompareError> {
        if report.verdict == Verdict::Unusable {
            return Err(CompareError::Unusable {
                run: run_path.to_owned(),
                why: report.unusable.unwrap_or_default(),
            });
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
                .ok_or_else(|| CompareError::NoTrajectory {
                    run: run_path.to_owned(),
                })?,
        };
        Ok(Checked {
            run,
            rig,
            trajectory,
            admissible,
            not_usable: marks
                .into_iter()
                .map(|mark| LeftOut { mark, scans: 0 })
                .collect(),
        })
    }

    /// The trajectory the clouds are placed with.
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }
}

//! The gap workflow (`hilrig gap`): where simulation and measurement disagree, which effect of
//! the catalogue explains it, with what parameters, and proof on data it did not fit that the
//! gap shrank.
//!
//! Every re-simulated firing has a measured twin (same packet stamp, block and channel), so the
//! workflow works firing by firing: [`observe`] casts a sample of each run's firings with a
//! model and pairs them with the measured returns; [`bins`] shows where they disagree;
//! [`likelihood`] scores how well a model explains them; [`candidates`] fits every effect the
//! model lacks and scores it on the parameterization runs' [`runset`], on casts [`casts`]
//! keeps from round to round; [`workflow`] tries the best one with the effects added before
//! re-fitted together with it ([`refit`]), and keeps it only when it improves the validation
//! runs' likelihood beyond their noise ([`bootstrap`]) and makes none of the metrics a user
//! reads worse beyond theirs ([`keep`]: the validation runs re-simulated in full,
//! [`full_metrics`], here or as tasks on an [`engine`]); then it repeats. [`report`] is what
//! it writes. The runs and their roles come from a [`study`] file. Parameterization and
//! validation data never mix (Rosenberger et al. 2019, §4).

pub mod bins;
pub mod bootstrap;
pub mod candidates;
pub mod casts;
pub mod engine;
mod full_metrics;
pub mod keep;
pub mod likelihood;
pub mod limits;
pub mod observe;
mod refit;
pub mod report;
pub mod runset;
pub mod study;
pub mod trial;
pub mod workflow;

use std::path::PathBuf;

/// Why the workflow cannot run.
#[derive(Debug, thiserror::Error)]
pub enum GapError {
    /// The study file cannot be read (or a number of it is not finite, or it is no study).
    #[error(transparent)]
    StudyFile(#[from] crate::config::TomlFileError),
    /// The study's runs cannot make a study.
    #[error(transparent)]
    Study(Box<study::StudyProblem>),
    /// The start model cannot be read.
    #[error("start model: {0}")]
    StartModel(#[source] crate::sim::model::ModelError),
    /// The reference model (`--reference-model`) cannot be read.
    #[error("reference model: {0}")]
    ReferenceModel(#[source] crate::sim::model::ModelError),
    /// A run's scene cannot be read.
    #[error("scene of {}: {source}", .recording.display())]
    Scene {
        /// The run.
        recording: PathBuf,
        /// Why.
        #[source]
        source: crate::scene::SceneError,
    },
    /// The study's rig file cannot be read.
    #[error(transparent)]
    Rig(#[from] crate::rig::RigError),
    /// A run cannot be read, or has no rig.
    #[error(transparent)]
    Run(#[from] crate::reference::run::RunError),
    /// A run's scans cannot be read.
    #[error(transparent)]
    Scans(#[from] crate::bag::scans::ScanStreamError),
    /// A run failed `check`.
    #[error("{run}: the reference data fail the check ({faults}): a trajectory error must not pass for a lidar effect; see `hilrig check`, or give --force to use the run anyway")]
    Refused {
        /// The run.
        run: String,
        /// The check's faults.
        faults: String,
    },
    /// A run's check gives no trajectory.
    #[error("{}: no RTK+CAN trajectory", .run.display())]
    NoTrajectory {
        /// The run.
        run: PathBuf,
    },
    /// A run (or its part) holds no lidar scan.
    #[error("{}: no /velodyne_packets to re-simulate", .run.display())]
    NoScans {
        /// The run.
        run: PathBuf,
    },
    /// The parameterization or the validation runs are too short to judge an effect by.
    #[error("too few scans to judge an effect by: {}; each needs at least {} (two bootstrap blocks of {} scans: with one, an effect's gain has no interval); record longer runs or add runs (scans `check` left out do not count)", .short.join(" and "), bootstrap::MIN_SCANS, bootstrap::BLOCK_SCANS)]
    TooFewScans {
        /// Each short set: "the validation runs hold N usable scans (run: n, ...)".
        short: Vec<String>,
    },
    /// A run whose lidar measured nothing the start model casts.
    #[error("{run}: no measured point on any firing the start model casts in scene {}: a lidar that measured nothing (covered, or a threshold no target reaches) shows no effect to fit", .scene.display())]
    NothingMeasured {
        /// The run.
        run: String,
        /// Its scene.
        scene: PathBuf,
    },
    /// A run and its scene do not belong together.
    #[error("{run}: {why} in scene {}: the run and the scene do not belong together (a different site, objects moved, or a trajectory far off)", .scene.display())]
    NotItsScene {
        /// The run.
        run: String,
        /// Its scene.
        scene: PathBuf,
        /// How few of its returns agree with the start model's.
        why: String,
    },
    /// A trial run as a task failed, or its result cannot be used.
    #[error("{task}: {why}{}", .log.as_ref().map_or(String::new(), |l| format!(" (see {})", l.display())))]
    Engine {
        /// The trial (or the engine that runs a model's trials).
        task: String,
        /// What went wrong.
        why: String,
        /// Its log, when the message does not name it already.
        log: Option<PathBuf>,
    },
    /// A model cannot simulate a run's lidar.
    #[error("{run}: {source}")]
    Model {
        /// The run.
        run: String,
        /// Why.
        #[source]
        source: crate::sim::model::ModelError,
    },
    /// A geometric effect's fit has too few firings on smooth surfaces.
    #[error("too few firings on smooth surfaces to fit a geometric effect ({firings}, at least {needed})")]
    TooFewSmoothFirings {
        /// How many there were.
        firings: usize,
        /// How many a fit needs.
        needed: usize,
    },
    /// A validation run's full re-simulation failed.
    #[error("re-simulating {run}: {source}")]
    Resim {
        /// The run.
        run: String,
        /// Why.
        #[source]
        source: crate::sim::resim::ResimError,
    },
    /// The validation runs' traffic lights cannot be made.
    #[error(transparent)]
    Validate(#[from] crate::stats::repetitions::ValidateError),
    /// Writing the results failed.
    #[error("writing the results: {path}: {source}", path = .path.display())]
    Output {
        /// The file or folder.
        path: PathBuf,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// Writing `gap.json` failed.
    #[error("writing the results: {0}")]
    Json(#[from] crate::output::OutputError),
    /// A run cannot be compared with its re-simulation.
    #[error("comparing {run}: {source}")]
    Compare {
        /// The run.
        run: String,
        /// Why.
        #[source]
        source: std::sync::Arc<crate::metrics::compare::CompareError>,
    },
    /// A run's rig names a lidar that cannot be decoded or simulated.
    #[error("{run}: {source}")]
    Lidar {
        /// The run.
        run: String,
        /// Why.
        #[source]
        source: crate::rig::LidarSensorError,
    },
}

impl From<study::StudyProblem> for GapError {
    fn from(p: study::StudyProblem) -> GapError {
        GapError::Study(Box::new(p))
    }
}

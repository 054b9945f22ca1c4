//! The gap workflow (`hilrig gap`): where simulation and measurement disagree, which effect of
//! the catalogue explains it, with what parameters, and proof on data it did not fit that the
//! gap shrank.
//!
//! Every re-simulated firing has a measured twin (same packet stamp, block and channel), so the
//! workflow works firing by firing: [`observe`] casts a sample of each run's firings with a
//! model and pairs them with the measured returns; [`bins`] shows where they disagree;
//! [`likelihood`] scores how well a model explains them; [`candidates`] fits every effect the
//! model lacks and scores it, on casts [`casts`] keeps from round to round; [`workflow`] adds the best one, keeps it only when it improves
//! the validation runs beyond their noise ([`bootstrap`]), re-simulates them in full for the
//! metrics a user reads ([`full_metrics`]), and repeats; [`report`] is what it
//! writes. The runs and their
//! roles come from a [`study`] file. Parameterization and validation data never mix
//! (Rosenberger et al. 2019, §4).

pub mod bins;
pub mod bootstrap;
pub mod candidates;
pub mod casts;
mod full_metrics;
pub mod likelihood;
pub mod observe;
pub mod report;
pub mod study;
pub mod workflow;

/// Why the workflow cannot run.
#[derive(Debug, thiserror::Error)]
pub enum GapError {
    /// Bad input: a study, model, scene or run that cannot be used.
    #[error("{0}")]
    Input(String),
    /// A run failed `check`.
    #[error("{run}: the reference data fail the check ({faults}): a trajectory error must not pass for a lidar effect; see `hilrig check`, or give --force to use the run anyway")]
    Refused {
        /// The run.
        run: String,
        /// The check's faults.
        faults: String,
    },
    /// Writing the results failed.
    #[error("writing the results: {0}")]
    Output(String),
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

//! Why `compare` cannot compare (its own module: the run's check and the comparison both
//! return it).

use std::path::PathBuf;

/// Why the simulation made as a comparison goes failed: the simulator's own error (the
/// comparison does not know which simulator it is handed).
pub type SimulateError = Box<dyn std::error::Error + Send + Sync>;

/// Why two files cannot be compared.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// A file's scans cannot be read.
    #[error(transparent)]
    Scans(#[from] crate::bag::scans::ScanStreamError),
    /// The cell or the grid's dimensions are not a grid.
    #[error(transparent)]
    Grid(#[from] super::grid::GridError),
    /// An option that cannot be measured with.
    #[error("{option}: {why}")]
    Option {
        /// The option as given (`-K 0`).
        option: String,
        /// Why not.
        why: &'static str,
    },
    /// A region or ground exclusion asked for in the sensor frame.
    #[error("the sensor frame has no scene: --roi and ground exclusion need the scene frame (use --roi all --keep-ground)")]
    SensorFrameHasNoScene,
    /// The run holds no lidar scan.
    #[error("no lidar scans (/velodyne_packets) in {}", .run.display())]
    NoScans {
        /// The run.
        run: PathBuf,
    },
    /// `check` cannot judge the run's reference data.
    #[error("{}: the reference data cannot be judged ({why}): see `hilrig check`", .run.display())]
    Unusable {
        /// The run.
        run: PathBuf,
        /// The check's reason.
        why: String,
    },
    /// The run's check gives no trajectory.
    #[error("{}: no RTK+CAN trajectory", .run.display())]
    NoTrajectory {
        /// The run.
        run: PathBuf,
    },
    /// The two files share no scan stamp.
    #[error("{} and {} share no scan (scan stamps {run_span} and {sim_span}): the simulation is not a re-simulation of this run", .run.display(), .sim.display())]
    NotTwins {
        /// The run.
        run: PathBuf,
        /// The simulation.
        sim: PathBuf,
        /// The run's first and last scan stamps (ISO 8601), or "none".
        run_span: String,
        /// The simulation's.
        sim_span: String,
    },
    /// Every scan lies where `check` marks the reference not usable.
    #[error("{}: every {}scan lies where `check` marks the reference not usable{}: nothing is left to compare; see `hilrig check`", .run.display(), if .marks.is_empty() { "" } else { "paired " }, if .marks.is_empty() { String::new() } else { format!(" ({})", .marks) })]
    NothingUsable {
        /// The run.
        run: PathBuf,
        /// The marks that left the scans out (`name from-to s`, comma-separated), when known.
        marks: String,
    },
    /// No measured point lies in the region.
    #[error("{}: no measured point lies in the region {region} on the trajectory (out of the sensor's view, or hidden: choose a region the drive sees)", .run.display())]
    NoPointInRegion {
        /// The run.
        run: PathBuf,
        /// The region, as `--roi` names it.
        region: String,
    },
    /// The run cannot be read, or has no rig.
    #[error(transparent)]
    Run(#[from] crate::reference::run::RunError),
    /// The rig's lidar cannot be decoded.
    #[error(transparent)]
    Lidar(#[from] crate::rig::LidarSensorError),
    /// The region cannot be compared in.
    #[error(transparent)]
    Region(#[from] super::roi::RoiError),
    /// A cell so small that the grid's indices would clamp where the drive's points lie.
    #[error("--cell {cell:e}: the grid's cell indices would be clamped (at most 2^20 cells either side of the origin; points here reach {reach:.0} m from it): the smallest cell for this drive is {smallest:.2e} m")]
    CellClamped {
        /// Asked for, m.
        cell: f64,
        /// How far from the origin the points can lie, m.
        reach: f64,
        /// The smallest cell that does not clamp, m.
        smallest: f64,
    },
    /// The simulation made as the comparison went failed.
    #[error("simulating {run}: {source}")]
    Simulation {
        /// The run.
        run: String,
        /// The simulator's error.
        #[source]
        source: SimulateError,
    },
    /// The cell is smaller than the reference data support.
    #[error("a {cell:.3} m cell is smaller than the {admissible:.3} m the reference accuracy admits (Rosenberger et al. 2019, §6: the cell must be at least ten times the reference accuracy); the metric would measure the reference's errors: use --cell {admissible:.3} or more, or --allow-small-cell to compute it anyway")]
    CellTooSmall {
        /// Asked for, m.
        cell: f64,
        /// What `check` admits, m.
        admissible: f64,
    },
}

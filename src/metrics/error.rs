//! Why `compare` cannot compare (its own module: the run's check and the comparison both
//! return it).

/// Why the simulation made as a comparison goes failed: the simulator's own error (the
/// comparison does not know which simulator it is handed).
pub type SimulateError = Box<dyn std::error::Error + Send + Sync>;

/// Why two files cannot be compared.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// An input is unusable, or the two do not belong together.
    #[error("{0}")]
    Input(String),
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

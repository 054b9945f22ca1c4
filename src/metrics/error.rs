//! Why `compare` cannot compare (its own module: the run's check and the comparison both
//! return it).

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
    /// The cell is smaller than the reference data support.
    #[error("a {cell:.3} m cell is smaller than the {admissible:.3} m the reference accuracy admits (Rosenberger et al. 2019, §6: the cell must be at least ten times the reference accuracy); the metric would measure the reference's errors: use --cell {admissible:.3} or more, or --allow-small-cell to compute it anyway")]
    CellTooSmall {
        /// Asked for, m.
        cell: f64,
        /// What `check` admits, m.
        admissible: f64,
    },
}

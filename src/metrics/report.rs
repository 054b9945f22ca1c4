//! What `hilrig compare` reports: per scan, the calibration curve and the summary (the JSON of
//! `compare --json`; the CSV columns are the per-scan fields).

use super::grid::{Dims, GridScores};
use super::points::PointScores;
use crate::estimate::rank::Correlation;
use crate::reference::check::Fault;

/// An object's points in one scan.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ObjectSeen {
    /// Name.
    pub name: String,
    /// Measured points on it.
    pub real_points: usize,
    /// Simulated points on it.
    pub sim_points: usize,
    /// Mean range of its measured points, m.
    pub range_m: f64,
    /// Diagonal of the box its measured (simulated) points span, m.
    pub real_extent_m: f64,
    /// Diagonal of the box its simulated points span, m.
    pub sim_extent_m: f64,
}

/// A bird's-eye view of one scan pair for the report: measured and simulated points over the
/// scene's objects, and the cells (at the comparison's cell size) occupied in only one of them.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Snapshot {
    /// Index of the scan in `scans`.
    pub scan: usize,
    /// Seconds after the first paired scan.
    pub t_s: f64,
    /// Sensor position (east, north), m.
    pub sensor: Option<[f64; 2]>,
    /// Measured points in the region (east, north), every n-th so that at most
    /// [`SNAPSHOT_POINTS`] are kept.
    pub real: Vec<[f32; 2]>,
    /// Simulated points, thinned alike.
    pub sim: Vec<[f32; 2]>,
    /// The scene's objects' footprints.
    pub objects: Vec<Footprint>,
    /// Cell size, m.
    pub cell_m: f64,
    /// Cells (south-west corner) occupied by the measurement only.
    pub only_real_cells: Vec<[f64; 2]>,
    /// Cells occupied by the simulation only.
    pub only_sim_cells: Vec<[f64; 2]>,
    /// Cells both occupy.
    pub both_cells: usize,
}

/// An object's footprint from above.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Footprint {
    /// The object's name in the scene.
    pub name: String,
    /// Its south-west corner (east, north), m.
    pub min: [f64; 2],
    /// Its north-east corner (east, north), m.
    pub max: [f64; 2],
}

/// Points kept per cloud in a [`Snapshot`].
pub const SNAPSHOT_POINTS: usize = 5000;

/// One scan pair.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct ScanRow {
    /// Seconds after the first paired scan.
    pub t_s: f64,
    /// The scan's stamp, ns since the Unix epoch.
    pub stamp_ns: i64,
    /// Ego speed, m/s.
    pub ego_speed_mps: f64,
    /// Objects with at least [`super::compare::MIN_POINTS_SEEN`] measured points (the paper's "objects in FoV").
    pub objects_in_view: usize,
    /// Mean over those objects of their measured points' mean range, m.
    pub mean_distance_m: Option<f64>,
    /// Points in the region: measured, simulated.
    pub real_points: usize,
    /// Simulated points in the region.
    pub sim_points: usize,
    /// Grid metrics over the K scans ending here (`None` for the first K - 1).
    pub grid: Option<GridScores>,
    /// Chamfer and Hausdorff distances.
    pub points: Option<PointScores>,
    /// Firings with a return in both: mean and rms of simulated minus measured range, m.
    pub range_diff_mean_m: Option<f64>,
    /// Their rms, m.
    pub range_diff_rms_m: Option<f64>,
    /// Returns only the measurement has.
    pub only_real: usize,
    /// Returns only the simulation has.
    pub only_sim: usize,
    /// The objects in view.
    pub objects: Vec<ObjectSeen>,
}

/// One point of the calibration curve.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CurvePoint {
    /// Cell size, m.
    pub cell_m: f64,
    /// Mean OCR^K over the scans.
    pub ocr_mean: Option<f64>,
    /// At least the admissible cell.
    pub admissible: bool,
}

/// The summary over all scans.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Summary {
    /// Paired scans.
    pub scans: usize,
    /// Scans of the run without a twin in the simulation.
    pub unpaired_run_scans: usize,
    /// Mean and median OCR^K.
    pub ocr_mean: Option<f64>,
    /// Median OCR^K.
    pub ocr_median: Option<f64>,
    /// Mean precision.
    pub precision_mean: Option<f64>,
    /// Mean IoU.
    pub iou_mean: Option<f64>,
    /// Mean cosine similarity.
    pub cosine_mean: Option<f64>,
    /// Mean Chamfer distance, m.
    pub chamfer_mean_m: Option<f64>,
    /// Mean Hausdorff distance, m.
    pub hausdorff_mean_m: Option<f64>,
    /// Range residuals over all firings: mean, rms, m.
    pub range_diff_mean_m: Option<f64>,
    /// Their rms, m.
    pub range_diff_rms_m: Option<f64>,
    /// Returns only in the measurement, as a share of its returns.
    pub only_real_share: Option<f64>,
    /// Returns only in the simulation, as a share of its returns.
    pub only_sim_share: Option<f64>,
    /// Spearman's ρ of OCR against the mean distance to the objects (Fig. 5).
    pub ocr_vs_distance: Option<Correlation>,
}

/// Scans `compare` left out because `check` marked the reference not usable where they lie.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LeftOut {
    /// The mark, as `check` reports it (name, stretch, the numbers behind it).
    #[serde(flatten)]
    pub mark: Fault,
    /// Paired scans within it.
    pub scans: usize,
}

/// The frame in which `compare` sets the clouds against each other.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ComparisonFrame {
    /// The scene's: a cell is a place in the world, as the method of Rosenberger et al. 2019, §5 grids it.
    Scene,
    /// The sensor's: the reference's pose error drops out (`compare --sensor-frame`).
    Sensor,
}

impl ComparisonFrame {
    /// Its name, as in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            ComparisonFrame::Scene => "scene",
            ComparisonFrame::Sensor => "sensor",
        }
    }
}

/// Everything `compare` found.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Comparison {
    /// Cell used, m.
    pub cell_m: f64,
    /// The admissible cell from `check`, m.
    pub admissible_cell_m: f64,
    /// Scans per grid.
    pub k: usize,
    /// Shifted grids the cell metrics are the mean over (1: the grid at the scene origin).
    pub grid_phases: usize,
    /// The calibration curve's other cells were taken from every n-th window (0: no curve).
    pub curve_every: usize,
    /// Whether the point metrics (Chamfer, Hausdorff) were computed.
    pub point_metrics: bool,
    /// 2D or 3D.
    pub dims: Dims,
    /// The region, as given.
    pub region: String,
    /// Inputs read only up to damage, and where.
    pub damage: Vec<String>,
    /// Stretches whose scans were left out: the reference is not usable there.
    pub left_out: Vec<LeftOut>,
    /// Ground left out.
    pub ground_excluded: bool,
    /// The frame the points were compared in.
    pub frame: ComparisonFrame,
    /// Per scan.
    pub scans: Vec<ScanRow>,
    /// OCR over cell sizes.
    pub calibration: Vec<CurvePoint>,
    /// One scan pair from above (the one with the most objects in view).
    pub snapshot: Option<Snapshot>,
    /// Over the drive.
    pub summary: Summary,
}

impl crate::output::Output for Comparison {
    const KIND: crate::output::OutputKind = crate::output::OutputKind::Compare;
    const SCHEMA: u32 = 1;
}

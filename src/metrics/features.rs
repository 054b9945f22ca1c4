//! Per-scan features of one run, measured or simulated alike: what a lidar's output looks like
//! without a twin to compare it with, so that repetitions can be set against each other
//! (statistical validation, Rosenberger et al. 2019, §8). Computed in the sensor frame from the
//! decoded returns: how many, how far, how bright.

use crate::bag::scans::Scan;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::{DataPacket, Decoder, Point};

/// The features, by name, in the order of [`ScanFeatures::values`].
pub const FEATURES: [&str; 4] = [
    "returns_per_scan",
    "mean_range_m",
    "range_p95_m",
    "mean_intensity",
];

/// One scan's features.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScanFeatures {
    /// The scan's stamp.
    pub stamp: UtcNanos,
    /// Returns.
    pub returns: usize,
    /// Mean range of the returns, m.
    pub mean_range_m: f64,
    /// 95th percentile of the ranges, m.
    pub range_p95_m: f64,
    /// Mean calibrated reflectivity.
    pub mean_intensity: f64,
}

impl ScanFeatures {
    /// The values in the order of [`FEATURES`] (`None` for a scan without returns, except the
    /// count).
    pub fn values(&self) -> [Option<f64>; 4] {
        let some = self.returns > 0;
        [
            Some(self.returns as f64),
            some.then_some(self.mean_range_m),
            some.then_some(self.range_p95_m),
            some.then_some(self.mean_intensity),
        ]
    }
}

/// The features of every scan.
pub fn scan_features(scans: &[Scan], decoder: &Decoder) -> Vec<ScanFeatures> {
    use rayon::prelude::*;
    scans
        .par_iter()
        .map(|scan| {
            let mut points: Vec<Point> = Vec::new();
            let mut previous: Option<DataPacket> = None;
            for (_, bytes) in &scan.packets {
                if let Ok(p) = DataPacket::decode(&bytes[..]) {
                    let _ = decoder.decode_into_after(&p, previous.as_ref(), &mut points);
                    previous = Some(p);
                }
            }
            let mut ranges: Vec<f64> = points.iter().map(|p| f64::from(p.distance_m)).collect();
            ranges.sort_by(f64::total_cmp);
            let n = ranges.len();
            ScanFeatures {
                stamp: scan.stamp,
                returns: n,
                mean_range_m: ranges.iter().sum::<f64>() / n.max(1) as f64,
                range_p95_m: if n > 0 {
                    ranges[(n * 95 / 100).min(n - 1)]
                } else {
                    0.0
                },
                mean_intensity: points.iter().map(|p| f64::from(p.intensity)).sum::<f64>()
                    / n.max(1) as f64,
            }
        })
        .collect()
}

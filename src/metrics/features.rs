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

/// A per-scan feature, as a value (the JSON and the validation cells spell it as in
/// [`FEATURES`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScanFeature {
    /// Returns in the scan.
    ReturnsPerScan,
    /// Mean range of the returns, m.
    MeanRangeM,
    /// 95th percentile of the ranges, m.
    RangeP95M,
    /// Mean calibrated reflectivity.
    MeanIntensity,
}

impl ScanFeature {
    /// Every feature, in the order of [`ScanFeatures::values`].
    pub const ALL: [ScanFeature; 4] = [
        ScanFeature::ReturnsPerScan,
        ScanFeature::MeanRangeM,
        ScanFeature::RangeP95M,
        ScanFeature::MeanIntensity,
    ];

    /// Its name, as in [`FEATURES`].
    pub fn name(self) -> &'static str {
        FEATURES[self as usize]
    }
}

/// One scan's features.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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

#[cfg(test)]
mod tests {
    use super::*;
    use hilrig_velodyne::{Channel, Model, PacketEncoder, ReturnMode, Sequence};

    #[test]
    fn a_feature_is_spelled_alike_as_a_value_and_by_name() {
        for f in ScanFeature::ALL {
            let json = serde_json::to_string(&f).unwrap();
            assert_eq!(json, format!("\"{}\"", f.name()));
        }
    }

    /// A scan of known returns (every fourth laser empty, distances and reflectivities by
    /// formula), encoded as VLP-16 packets: the features against the same numbers computed
    /// here from the list, not from decoded points.
    #[test]
    fn features_of_a_scan_of_known_returns() {
        let model = Model::Vlp16;
        let mut enc = PacketEncoder::new(model, ReturnMode::Strongest);
        let (mut ranges, mut intensities) = (Vec::new(), Vec::new());
        let mut packets = Vec::new();
        for k in 0..enc.sequences_per_packet() * 4 {
            let strongest: Vec<Channel> = (0..16)
                .map(|l| {
                    let distance = if l % 4 == 3 { 0 } else { 500 + 37 * k + 11 * l };
                    let reflectivity = (l * 5 + k % 7) as u8;
                    if distance > 0 {
                        ranges.push(distance as f64 * 0.002);
                        intensities.push(f64::from(reflectivity));
                    }
                    Channel {
                        distance: distance as u16,
                        reflectivity,
                    }
                })
                .collect();
            let seq = Sequence {
                azimuth: ((k * 20) % 36_000) as u16,
                strongest,
                last: None,
            };
            if let Some(p) = enc.push(&seq, (k * 55) as u32).unwrap() {
                packets.push((UtcNanos(k as i64), p.encode()));
            }
        }
        let scan = Scan {
            log_time: 0,
            publish_time: 0,
            stamp: UtcNanos(7),
            packets,
        };
        let f = scan_features(&[scan], &Decoder::new(model))[0];
        let n = ranges.len();
        assert_eq!(f.returns, n, "every non-empty channel, no empty one");
        let mean = ranges.iter().sum::<f64>() / n as f64;
        assert!(
            (f.mean_range_m - mean).abs() < 1e-5,
            "{} {mean}",
            f.mean_range_m
        );
        ranges.sort_by(f64::total_cmp);
        // The 95th percentile: the value below which 95 % of the returns lie.
        let p95 = ranges[n * 95 / 100];
        assert!(
            (f.range_p95_m - p95).abs() < 1e-5,
            "{} {p95}",
            f.range_p95_m
        );
        let mean_i = intensities.iter().sum::<f64>() / n as f64;
        assert!(
            (f.mean_intensity - mean_i).abs() < 1e-9,
            "{} {mean_i}",
            f.mean_intensity
        );
        assert_eq!(f.stamp, UtcNanos(7));
        // An empty scan: a count of zero and no other value.
        let empty = Scan {
            log_time: 0,
            publish_time: 0,
            stamp: UtcNanos(8),
            packets: vec![],
        };
        let e = scan_features(&[empty], &Decoder::new(model))[0];
        assert_eq!(e.values(), [Some(0.0), None, None, None]);
    }
}

//! Over all drives: OCR^K against the distance to the objects in view, pooled over every
//! comparison of a model. One drive's Fig. 5 (Rosenberger et al. 2019) shows OCR^K falling with
//! distance along that drive; over a campaign's drives the question is whether the model's
//! agreement holds at every distance the fleet saw, which no single drive covers.

use super::markup::{esc, figure, table};
use super::plots::{fixed, ocr_lines, Named};
use crate::metrics::report::Comparison;
use plotters::prelude::SeriesLabelPosition;
use std::collections::BTreeMap;
use std::fmt::Write;

/// Width of a distance bin, m: the scans of a drive move through tens of metres of distance,
/// so a bin holds scans of several drives without blurring the trend.
const BIN_M: f64 = 5.0;

/// The scans of one group of comparisons (those in one folder: a campaign's `compare/MODEL/`)
/// in one distance bin, as `report.json` lists them.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FleetBin {
    /// The folder of the comparisons' names; "all" for names without one.
    pub group: String,
    /// The bin's distances, m: from (inclusive) ...
    pub from_m: f64,
    /// ... to (exclusive).
    pub to_m: f64,
    /// Scans with both an OCR^K and a distance in it.
    pub scans: usize,
    /// Comparisons (drives) they come from.
    pub drives: usize,
    /// Their mean OCR^K.
    pub ocr_mean: f64,
    /// The standard deviation of their OCR^K (n - 1); `None` for a single scan.
    pub ocr_sd: Option<f64>,
}

/// A comparison's group: the folder of its name (`compare/idealized/rep-01.json` is of
/// `compare/idealized`); a name without a folder is of the group "all".
fn group_of(name: &str) -> &str {
    name.rsplit_once('/').map_or("all", |(dir, _)| dir)
}

/// Every comparison's scans pooled per group and distance bin, in the order of the groups'
/// names and the distances.
pub fn bins(cmps: &[Named<Comparison>]) -> Vec<FleetBin> {
    // (group, bin) -> (scans, drives, sum, sum of squares)
    let mut acc: BTreeMap<(&str, u32), (usize, usize, f64, f64)> = BTreeMap::new();
    for (name, c) in cmps {
        let group = group_of(name);
        let mut seen = std::collections::BTreeSet::new();
        for s in &c.scans {
            let (Some(d), Some(ocr)) = (s.mean_distance_m, s.grid.as_ref().and_then(|g| g.ocr))
            else {
                continue;
            };
            if !(d.is_finite() && ocr.is_finite() && d >= 0.0) {
                continue;
            }
            let k = (d / BIN_M) as u32;
            let a = acc.entry((group, k)).or_default();
            a.0 += 1;
            a.2 += ocr;
            a.3 += ocr * ocr;
            if seen.insert(k) {
                a.1 += 1;
            }
        }
    }
    acc.into_iter()
        .map(|((group, k), (n, drives, sum, sum_sq))| {
            let nf = n as f64;
            FleetBin {
                group: group.to_owned(),
                from_m: f64::from(k) * BIN_M,
                to_m: f64::from(k + 1) * BIN_M,
                scans: n,
                drives,
                ocr_mean: sum / nf,
                ocr_sd: (n > 1).then(|| ((sum_sq - sum * sum / nf) / (nf - 1.0)).max(0.0).sqrt()),
            }
        })
        .collect()
}

/// The section, when there are comparisons of at least two drives: the plot of the pooled
/// bins' mean OCR^K, one line per group, and the table of its numbers.
pub(super) fn section(out: &mut String, comparisons: usize, bins: &[FleetBin]) {
    if comparisons < 2 || bins.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "<h2 id=\"section-fleet\">Over all drives</h2>\n<p class=\"note\">OCR^K against the mean distance to the objects in view, every scan of {comparisons} comparisons pooled in {BIN_M} m bins, one line per folder of comparisons (a campaign's model). Each comparison at its own cell. The numbers are in report.json (<code>fleet</code>).</p>"
    );
    figure(
        out,
        "fleet-ocr-distance",
        plot(bins),
        "Mean OCR^K of the scans in each distance bin, over all drives.",
    );
    let rows: Vec<Vec<String>> = bins
        .iter()
        .map(|b| {
            vec![
                esc(&b.group),
                format!("{}–{}", b.from_m, b.to_m),
                b.scans.to_string(),
                b.drives.to_string(),
                fixed(Some(b.ocr_mean), 3),
                fixed(b.ocr_sd, 3),
            ]
        })
        .collect();
    table(
        out,
        "fleet-ocr-distance-table",
        &[
            "comparisons",
            "distance, m",
            "scans",
            "drives",
            "OCR^K mean",
            "OCR^K sd over scans",
        ],
        &rows,
    );
}

fn plot(bins: &[FleetBin]) -> Option<String> {
    let x1 = bins.iter().map(|b| b.to_m).fold(BIN_M, f64::max);
    let mut groups: BTreeMap<&str, Vec<(f64, f64)>> = BTreeMap::new();
    for b in bins {
        groups
            .entry(&b.group)
            .or_default()
            .push((0.5 * (b.from_m + b.to_m), b.ocr_mean));
    }
    let series: Vec<(&str, Vec<(f64, f64)>)> = groups.into_iter().collect();
    ocr_lines(
        None,
        "mean distance to the objects in view, m",
        &series,
        x1,
        SeriesLabelPosition::LowerLeft,
        |_| Ok(()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_comparison_is_of_the_folder_it_was_named_in() {
        assert_eq!(
            group_of("compare/idealized/rep-01.json"),
            "compare/idealized"
        );
        assert_eq!(group_of("rep-01.json"), "all");
    }

    fn comparison(scans: &[(Option<f64>, Option<f64>)]) -> Comparison {
        let scans = scans
            .iter()
            .map(|&(d, ocr)| crate::metrics::report::ScanRow {
                mean_distance_m: d,
                grid: ocr.map(|o| crate::metrics::grid::GridScores {
                    ocr: Some(o),
                    precision: None,
                    iou: None,
                    cosine: None,
                    real_cells: 0,
                    sim_cells: 0,
                    both_cells: 0,
                }),
                ..Default::default()
            })
            .collect();
        crate::report::glance::tests::comparison(scans, Default::default())
    }

    #[test]
    fn scans_are_pooled_per_folder_and_distance_bin_over_drives() {
        let a = comparison(&[
            (Some(3.0), Some(0.5)),
            (Some(4.0), Some(0.7)),
            (Some(7.0), Some(0.9)),
        ]);
        let b = comparison(&[(Some(1.0), Some(0.9)), (None, Some(0.1)), (Some(2.0), None)]);
        let c = comparison(&[(Some(6.0), Some(0.2))]);
        let bins = bins(&[("m/a.json", &a), ("m/b.json", &b), ("n/c.json", &c)]);
        let got: Vec<(&str, f64, usize, usize)> = bins
            .iter()
            .map(|b| (b.group.as_str(), b.from_m, b.scans, b.drives))
            .collect();
        // A scan without a distance or without an OCR^K is in no bin.
        assert_eq!(got, [("m", 0.0, 3, 2), ("m", 5.0, 1, 1), ("n", 5.0, 1, 1)]);
        assert!((bins[0].ocr_mean - 0.7).abs() < 1e-12);
        assert!((bins[0].ocr_sd.unwrap() - 0.2).abs() < 1e-12);
        assert_eq!(bins[1].ocr_sd, None);
    }
}

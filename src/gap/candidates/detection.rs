//! The detection threshold's sweep: predicted returns sorted by power, and the split below
//! which predicting them missing explains the detections best.

use super::DetectionRow;
use crate::gap::likelihood;

pub(super) fn sort_rows(rows: &mut Vec<DetectionRow>) {
    rows.retain(|r| r.1.is_finite() && r.1 > 0.0);
    rows.sort_by(|a, b| a.1.total_cmp(&b.1));
}

/// The index k into `rows` (sorted by power) below which predicting every return missing
/// explains the detections best, by the likelihood's detection term: returned rows below pay
/// ln ε, missing ones ln(1 − ε); rows above pay the model's. `weight(i)` weights row i (the
/// bootstrap's block counts).
pub(super) fn sweep(rows: &[DetectionRow], keep: f64, weight: &dyn Fn(usize) -> f64) -> usize {
    sweep_ll(rows, keep, weight).0
}

/// [`sweep`] with the detection log-likelihood at the best split.
pub(super) fn sweep_ll(
    rows: &[DetectionRow],
    keep: f64,
    weight: &dyn Fn(usize) -> f64,
) -> (usize, f64) {
    let (eps, p_in) = (likelihood::EPS, keep * (1.0 - likelihood::EPS));
    let (lh_in, lm_in) = (p_in.ln(), (1.0 - p_in).max(1e-12).ln());
    let (lh_out, lm_out) = (eps.ln(), (1.0 - eps).ln());
    let mut above: f64 = rows
        .iter()
        .enumerate()
        .map(|(i, r)| weight(i) * if r.2 { lh_in } else { lm_in })
        .sum();
    let mut below = 0.0;
    let (mut best, mut best_ll) = (0usize, above);
    for (i, r) in rows.iter().enumerate() {
        let w = weight(i);
        above -= w * if r.2 { lh_in } else { lm_in };
        below += w * if r.2 { lh_out } else { lm_out };
        if below + above > best_ll {
            best_ll = below + above;
            best = i + 1;
        }
    }
    (best, best_ll)
}

/// The power between row k − 1 and row k (geometric mean); `None` for k = 0.
pub(super) fn power_at(rows: &[DetectionRow], k: usize) -> Option<f64> {
    if k == 0 || rows.is_empty() {
        return None;
    }
    let lo = rows[k - 1].1;
    let hi = rows.get(k).map_or(lo, |r| r.1);
    Some((lo * hi).sqrt())
}

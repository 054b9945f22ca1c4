//! Location and spread of a sample that outliers do not move.

/// Median of a slice (reordered); `None` when empty.
pub fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

/// 1.4826 × the median absolute deviation from the median: the standard deviation of a
/// Gaussian, robust to outliers.
pub fn robust_sigma(v: &[f64]) -> Option<f64> {
    let mut c = v.to_vec();
    let m = median(&mut c)?;
    let mut d: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    median(&mut d).map(|x| 1.4826 * x)
}

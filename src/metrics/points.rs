//! Point metrics: how far each cloud's points are from the other cloud.
//!
//! - Chamfer distance: the mean nearest-neighbour distance from A to B and from B to A,
//!   averaged: ½ (1/|A| Σ_a min_b ‖a − b‖ + 1/|B| Σ_b min_a ‖b − a‖), in metres (distances, not
//!   their squares, so it reads as a length).
//! - Hausdorff distance: the largest of those nearest-neighbour distances either way,
//!   max(max_a min_b ‖a − b‖, max_b min_a ‖b − a‖): the worst point.
//!
//! Nearest neighbours come from `kiddo`'s immutable k-d tree (a well-kept crate, exact queries,
//! built once per scan and queried for every point of the other scan). Querying in a spatial
//! order instead of the scan's own was tried and gained nothing measurable.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::Point3;

/// Chamfer and Hausdorff distances of two clouds, m.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PointScores {
    /// Chamfer distance, m.
    pub chamfer_m: f64,
    /// Hausdorff distance, m.
    pub hausdorff_m: f64,
}

/// Nearest-neighbour distances from every point of `from` to `to` (which must not be empty).
fn nearest(from: &[Point3<f64>], to: &[Point3<f64>]) -> Option<Vec<f64>> {
    // The tree in f32 (half the memory traffic; a lidar point is good to millimetres, f32 to
    // micrometres at 100 m), the nearest point's distance then recomputed in f64.
    let entries: Vec<[f32; 3]> = to
        .iter()
        .map(|p| [p.x as f32, p.y as f32, p.z as f32])
        .collect();
    let tree: ImmutableKdTree<f32, 3> = ImmutableKdTree::new_from_slice(&entries).ok()?;
    Some(
        from.iter()
            .map(|p| {
                let nn = tree
                    .query(&[p.x as f32, p.y as f32, p.z as f32])
                    .nearest_one::<SquaredEuclidean<f32>>()
                    .execute();
                (to[nn.item as usize] - p).norm()
            })
            .collect(),
    )
}

/// The Chamfer and Hausdorff distances of `a` and `b`; `None` when either is empty.
pub fn distances(a: &[Point3<f64>], b: &[Point3<f64>]) -> Option<PointScores> {
    if a.is_empty() || b.is_empty() {
        return None;
    }
    // The two directions are independent: each on its own core where one is free (in
    // `compare`, scans are already spread over the cores and this adds nothing).
    let (ab, ba) = rayon::join(|| nearest(a, b), || nearest(b, a));
    let (ab, ba) = (ab?, ba?);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    Some(PointScores {
        chamfer_m: 0.5 * (mean(&ab) + mean(&ba)),
        hausdorff_m: max(&ab).max(max(&ba)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn brute(a: &[Point3<f64>], b: &[Point3<f64>]) -> PointScores {
        let nn = |p: &Point3<f64>, s: &[Point3<f64>]| {
            s.iter()
                .map(|q| (p - q).norm())
                .fold(f64::INFINITY, f64::min)
        };
        let ab: Vec<f64> = a.iter().map(|p| nn(p, b)).collect();
        let ba: Vec<f64> = b.iter().map(|p| nn(p, a)).collect();
        PointScores {
            chamfer_m: 0.5
                * (ab.iter().sum::<f64>() / ab.len() as f64
                    + ba.iter().sum::<f64>() / ba.len() as f64),
            hausdorff_m: ab.iter().chain(&ba).copied().fold(0.0, f64::max),
        }
    }

    /// Against a brute-force search on random clouds of different sizes (duplicates included).
    #[test]
    fn chamfer_and_hausdorff_equal_a_brute_force_search() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for (na, nb) in [(1, 1), (7, 300), (500, 211), (1000, 1000)] {
            let mut cloud = |n: usize| -> Vec<Point3<f64>> {
                (0..n)
                    .map(|_| {
                        Point3::new(
                            rng.random_range(-20.0..20.0),
                            rng.random_range(-20.0..20.0),
                            rng.random_range(-2.0..3.0),
                        )
                    })
                    .collect()
            };
            let (a, mut b) = (cloud(na), cloud(nb));
            b.extend(a.iter().take(3).copied());
            let got = distances(&a, &b).unwrap();
            let want = brute(&a, &b);
            assert!(
                (got.chamfer_m - want.chamfer_m).abs() < 1e-9,
                "{na}x{nb}: {got:?} {want:?}"
            );
            assert!(
                (got.hausdorff_m - want.hausdorff_m).abs() < 1e-9,
                "{na}x{nb}"
            );
        }
        assert_eq!(distances(&[], &[Point3::origin()]), None);
    }
}

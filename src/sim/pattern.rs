//! How a divergent beam's footprint is sampled: where its sub-rays lie, in units of the
//! footprint's half-axes. The grid is the catalogue's default; the stratified pattern keeps its
//! sub-ray count and gives each an equal share of the beam's area along both axes, which a
//! receiver that detects an echo by its share of the footprint needs.

use serde::{Deserialize, Serialize};

/// How a divergent beam's footprint is sampled by its sub-rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FootprintPattern {
    /// The points of a `sub_rays_per_axis`² grid over the footprint's bounding box that lie
    /// inside its ellipse ([`footprint_grid`]). Its points stand in rows and columns, so a
    /// straight edge crossing the footprint changes the share it cuts off a whole column at a
    /// time (with 5 per axis: by 1, 3, 5, 3 and 1 of the 13 sub-rays).
    #[default]
    Grid,
    /// As many sub-rays as the grid, stratified by area ([`footprint_stratified`]): cut the
    /// footprint across into as many strips of equal area as there are sub-rays, and again
    /// along elevation; each strip of either cut holds one sub-ray. So each sub-ray stands
    /// for an equal share of a top-hat beam, and as an edge along either axis (a facade's
    /// side, a kerb, a car's roof) moves across the footprint the share it cuts off grows one
    /// sub-ray at a time, within half a sub-ray of the area's share. For a receiver that
    /// detects an echo by its share of the footprint (`first_echo_share`) the grid places
    /// the echo's edge only at its columns: a quarter of its 13 sub-rays (four) is reached
    /// half a half-axis beyond the silhouette, where a quarter of the beam's area lies 0.40
    /// half-axes beyond it (a 4 mrad beam of a first echo at a quarter share was fitted as
    /// 2.75 mrad with the grid). Up to 6 per axis (16 sub-rays): for some larger counts no
    /// pairing of the strips keeps every sub-ray inside the footprint (9, 11, 13 and 15 per
    /// axis), and for the others the sub-rays crowd along a diagonal.
    Stratified,
}

impl FootprintPattern {
    pub(crate) fn is_grid(&self) -> bool {
        *self == FootprintPattern::Grid
    }

    /// Its name in a model file (`pattern = "..."`).
    pub fn name(self) -> &'static str {
        match self {
            FootprintPattern::Grid => "grid",
            FootprintPattern::Stratified => "stratified",
        }
    }

    /// The sub-rays of a footprint sampled with `n` per axis in this pattern, as offsets in
    /// units of its half-axes (across, along elevation), in the order they are cast and merged.
    pub fn offsets(self, n: u32) -> Vec<(f64, f64)> {
        match self {
            FootprintPattern::Grid => footprint_grid(n),
            // Counts no pairing fits are refused by the model's validation; were one asked
            // for, the grid is the pattern of that many sub-rays.
            FootprintPattern::Stratified => {
                footprint_stratified(footprint_grid(n).len()).unwrap_or_else(|| footprint_grid(n))
            }
        }
    }
}

/// The most sub-rays per axis of a [`FootprintPattern::Stratified`] footprint.
pub const STRATIFIED_MAX_PER_AXIS: u32 = 6;

/// Where the unit disc's area left of `u` is the share `p`: the inverse of
/// `(π - acos u + u √(1 - u²)) / π`, by bisection.
fn area_quantile(p: f64) -> f64 {
    let (mut lo, mut hi) = (-1.0f64, 1.0f64);
    for _ in 0..64 {
        let m = 0.5 * (lo + hi);
        let left =
            (std::f64::consts::PI - m.acos() + m * (1.0 - m * m).sqrt()) / std::f64::consts::PI;
        if left < p {
            lo = m;
        } else {
            hi = m;
        }
    }
    0.5 * (lo + hi)
}

/// `count` sub-rays over the unit disc, stratified by area along both axes: the `i`-th lies
/// across at the middle (by area) of the `i`-th of `count` equal-area strips, and along
/// elevation in the strip `(a i + b) mod count`. Of the pairings `(a, b)` that keep every
/// sub-ray inside the disc and the pattern point-symmetric (its centroid on the beam axis,
/// where the echo's range on a surface at grazing incidence wants it; with an odd count the
/// centre is one of them), the one whose closest two sub-rays lie farthest apart. The centre
/// alone for one; `None` when no pairing keeps every sub-ray inside.
pub fn footprint_stratified(count: usize) -> Option<Vec<(f64, f64)>> {
    if count <= 1 {
        return Some(vec![(0.0, 0.0); count]);
    }
    let mut q = vec![0.0; count];
    for i in 0..count / 2 {
        let x = area_quantile((i as f64 + 0.5) / count as f64);
        q[i] = x;
        q[count - 1 - i] = -x;
    }
    let gcd = |mut a: usize, mut b: usize| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let mut best: Option<(f64, Vec<(f64, f64)>)> = None;
    for a in (1..count).filter(|&a| gcd(a, count) == 1) {
        for b in 0..count {
            // Point symmetry: strip i pairs with strip σ(i) = (a i + b) mod count exactly
            // when strip count - 1 - i pairs with count - 1 - σ(i).
            if !(2 * b + count - (a - 1)).is_multiple_of(count) {
                continue;
            }
            let pts: Vec<(f64, f64)> = (0..count).map(|i| (q[i], q[(a * i + b) % count])).collect();
            if pts.iter().any(|(u, v)| u * u + v * v >= 1.0) {
                continue;
            }
            let mut closest = f64::INFINITY;
            for (i, p) in pts.iter().enumerate() {
                for r in &pts[..i] {
                    closest = closest.min((p.0 - r.0).hypot(p.1 - r.1));
                }
            }
            // Mirror images tie: the first found is kept, whatever the last bits say.
            if best.as_ref().is_none_or(|(c, _)| closest > c + 1e-9) {
                best = Some((closest, pts));
            }
        }
    }
    best.map(|(_, p)| p)
}

/// The sub-rays of a footprint sampled with `n` per axis, as offsets in units of its half-axes
/// (across, along elevation): the points of an `n` × `n` grid over the footprint's bounding box
/// that lie inside its ellipse (the centre alone for `n` = 1), in the order they are cast and
/// merged.
pub fn footprint_grid(n: u32) -> Vec<(f64, f64)> {
    let n = n.max(1);
    let at = |i: u32| {
        if n == 1 {
            0.0
        } else {
            -1.0 + 2.0 * f64::from(i) / f64::from(n - 1)
        }
    };
    let mut grid = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (u, v) = (at(i), at(j));
            if u * u + v * v <= 1.0 + 1e-9 {
                grid.push((u, v));
            }
        }
    }
    grid
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The name a report prints is the one a model file reads.
    #[test]
    fn a_patterns_name_is_its_model_file_spelling() {
        for p in [FootprintPattern::Grid, FootprintPattern::Stratified] {
            let json = serde_json::to_string(&p).unwrap();
            assert_eq!(json, format!("\"{}\"", p.name()));
        }
    }

    /// The share of a top-hat beam's area beyond a straight edge at `d` half-axes from the
    /// centre: the circular segment's area over the disc's.
    fn segment(d: f64) -> f64 {
        let d = d.clamp(-1.0, 1.0);
        (d.acos() - d * (1.0 - d * d).sqrt()) / std::f64::consts::PI
    }

    /// The stratified pattern samples the share of the footprint an edge along either axis
    /// cuts off to within half a sub-ray, and one of any orientation to within three; the
    /// grid does not (which is why a first-echo receiver is fitted with the stratified one).
    /// Both have the grid's sub-ray count, inside the footprint, centred on the beam axis.
    #[test]
    fn the_stratified_pattern_samples_the_share_an_edge_cuts_off() {
        for n in [1, 3, 4, 5, 6] {
            let strat = FootprintPattern::Stratified.offsets(n);
            let grid = FootprintPattern::Grid.offsets(n);
            assert_eq!(footprint_stratified(grid.len()), Some(strat.clone()));
            assert_eq!(strat.len(), grid.len());
            assert!(
                strat.iter().all(|(u, v)| u * u + v * v < 1.0),
                "{n}: {strat:?}"
            );
            let sum = strat.iter().fold((0.0, 0.0), |s, p| (s.0 + p.0, s.1 + p.1));
            assert!(sum.0.abs() < 1e-12 && sum.1.abs() < 1e-12, "{n}: {sum:?}");
            if n == 1 {
                assert_eq!(strat, vec![(0.0, 0.0)]);
                continue;
            }
            let count = strat.len() as f64;
            let (mut axes, mut any, mut grid_axes) = (0.0f64, 0.0f64, 0.0f64);
            for turn in 0..24 {
                let a = f64::from(turn) * std::f64::consts::PI / 12.0;
                let (c, s) = (a.cos(), a.sin());
                for i in -99..=99 {
                    let d = f64::from(i) * 0.01;
                    let share = |p: &[(f64, f64)]| {
                        p.iter().filter(|(u, v)| u * c + v * s > d).count() as f64 / count
                    };
                    let off = (share(&strat) - segment(d)).abs();
                    any = any.max(off);
                    if turn % 6 == 0 {
                        axes = axes.max(off);
                        grid_axes = grid_axes.max((share(&grid) - segment(d)).abs());
                    }
                }
            }
            assert!(
                axes <= 0.5 / count + 1e-6,
                "{n} per axis: {axes} on the axes"
            );
            assert!(any <= 3.0 / count, "{n} per axis: {any}");
            assert!(grid_axes > axes, "{n} per axis: grid {grid_axes}");
        }
        // A quarter of the beam's area lies beyond 0.40 half-axes: the stratified 13 put four
        // sub-rays beyond 0.37, three beyond 0.41; the grid's four stand beyond 0.5.
        let beyond = |p: &[(f64, f64)], d: f64| p.iter().filter(|x| x.0 > d).count();
        let strat = FootprintPattern::Stratified.offsets(5);
        assert_eq!((beyond(&strat, 0.36), beyond(&strat, 0.41)), (4, 3));
        let grid = FootprintPattern::Grid.offsets(5);
        assert_eq!((beyond(&grid, 0.49), beyond(&grid, 0.51)), (4, 1));
        // More per axis than the strips allow is refused.
        let text = |n: u32| {
            format!("name = \"t\"\n[[effect]]\nname = \"beam_divergence\"\nhorizontal_mrad = 3.0\nvertical_mrad = 1.5\nsub_rays_per_axis = {n}\npattern = \"stratified\"\n")
        };
        let six: crate::sim::ModelFile = toml::from_str(&text(6)).unwrap();
        six.validate().unwrap();
        let back: crate::sim::ModelFile = toml::from_str(&six.to_toml()).unwrap();
        assert_eq!(back, six);
        assert!(six.to_toml().contains("pattern = \"stratified\""));
        let seven: crate::sim::ModelFile = toml::from_str(&text(7)).unwrap();
        let e = seven.validate().map(|_| ()).unwrap_err().to_string();
        assert!(e.contains("at most 6"), "{e}");
    }
}

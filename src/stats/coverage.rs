//! Scenario coverage (Rosenberger et al. 2019, §4): the samples a model is parameterized with
//! and the samples it is validated on must not be the same scenarios. The parameter space is cut
//! into cells (each parameter's range in equal parts: a uniform one's bounds, a normal one's
//! mean ± 3 sd); a validation sample that shares a cell with a parameterization sample is listed.
//! And how far apart the two sets are: each validation sample's distance to the nearest
//! parameterization sample, in units of the parameters' ranges.

use super::efast::{Distribution, Parameter};

/// The range a parameter's cells divide.
fn range(p: &Parameter) -> (f64, f64) {
    match p.distribution {
        Distribution::Uniform { low, high } => (low, high),
        Distribution::Normal { mean, sd } => (mean - 3.0 * sd, mean + 3.0 * sd),
    }
}

/// A sample's cell: per parameter the index of its part (values outside the range fall into
/// the first or last part).
pub fn cell(params: &[Parameter], parts: usize, x: &[f64]) -> Vec<usize> {
    params
        .iter()
        .zip(x)
        .map(|(p, &v)| {
            let (a, b) = range(p);
            let f = ((v - a) / (b - a)).clamp(0.0, 1.0);
            ((f * parts as f64) as usize).min(parts - 1)
        })
        .collect()
}

/// A validation sample that shares a cell with parameterization samples.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Shared {
    /// Row of the validation sample, counted from 1 (the first data row after the header), as
    /// the text output and a spreadsheet count them.
    pub validation_row: usize,
    /// Rows of the parameterization samples in the same cell, counted from 1.
    pub parameterization_rows: Vec<usize>,
    /// The cell.
    pub cell: Vec<usize>,
}

/// What the coverage check found.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Coverage {
    /// Parts per parameter.
    pub parts: usize,
    /// Validation samples sharing a cell.
    pub shared: Vec<Shared>,
    /// Per validation sample: distance to the nearest parameterization sample, in range units.
    pub nearest: Vec<f64>,
    /// The smallest of those distances.
    pub min_distance: f64,
    /// Their mean.
    pub mean_distance: f64,
}

/// Checks `validation` against `parameterization` (rows of parameter values).
pub fn coverage(
    params: &[Parameter],
    parts: usize,
    parameterization: &[Vec<f64>],
    validation: &[Vec<f64>],
) -> Coverage {
    let parts = parts.max(1);
    let cells: Vec<Vec<usize>> = parameterization
        .iter()
        .map(|x| cell(params, parts, x))
        .collect();
    let shared = validation
        .iter()
        .enumerate()
        .filter_map(|(i, x)| {
            let c = cell(params, parts, x);
            let rows: Vec<usize> = cells
                .iter()
                .enumerate()
                .filter(|(_, pc)| **pc == c)
                .map(|(j, _)| j + 1)
                .collect();
            (!rows.is_empty()).then_some(Shared {
                validation_row: i + 1,
                parameterization_rows: rows,
                cell: c,
            })
        })
        .collect();
    let scaled = |x: &[f64]| -> Vec<f64> {
        params
            .iter()
            .zip(x)
            .map(|(p, v)| {
                let (a, b) = range(p);
                (v - a) / (b - a)
            })
            .collect()
    };
    let ps: Vec<Vec<f64>> = parameterization.iter().map(|x| scaled(x)).collect();
    let nearest: Vec<f64> = validation
        .iter()
        .map(|x| {
            let v = scaled(x);
            ps.iter()
                .map(|p| {
                    p.iter()
                        .zip(&v)
                        .map(|(a, b)| (a - b).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    Coverage {
        parts,
        shared,
        min_distance: nearest.iter().copied().fold(f64::INFINITY, f64::min),
        mean_distance: nearest.iter().sum::<f64>() / nearest.len().max(1) as f64,
        nearest,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::efast::parse_params;

    /// Speed 0..10 m/s and distance 0..50 m in 5 parts (2 m/s, 10 m): the validation sample
    /// (5.5, 23) shares cell (2, 2) with the parameterization sample (4.2, 27); the others lie
    /// elsewhere, one of them on the upper edge of the range.
    #[test]
    fn the_one_validation_sample_in_a_parameterization_cell_is_found() {
        let params = parse_params(
            "[[parameter]]\nname = \"speed\"\ndistribution = \"uniform\"\nlow = 0.0\nhigh = 10.0\n\
             [[parameter]]\nname = \"distance\"\ndistribution = \"uniform\"\nlow = 0.0\nhigh = 50.0\n",
            "p",
        )
        .unwrap();
        let par = vec![vec![1.0, 5.0], vec![4.2, 27.0], vec![9.0, 35.0]];
        let val = vec![
            vec![3.9, 5.0],
            vec![5.5, 23.0],
            vec![10.0, 50.0],
            vec![7.0, 31.0],
        ];
        let c = coverage(&params, 5, &par, &val);
        assert_eq!(
            c.shared,
            vec![Shared {
                validation_row: 2,
                parameterization_rows: vec![2],
                cell: vec![2, 2],
            }]
        );
        // (5.5, 23) against (4.2, 27): (0.13, 0.08) in range units.
        assert!((c.nearest[1] - (0.13f64.powi(2) + 0.08f64.powi(2)).sqrt()).abs() < 1e-12);
        assert!((c.min_distance - c.nearest[1]).abs() < 1e-12);
        // (7, 31) against (9, 35): (0.2, 0.08); the mean over the four samples.
        assert!((c.nearest[3] - (0.2f64.powi(2) + 0.08f64.powi(2)).sqrt()).abs() < 1e-12);
        let mean = c.nearest.iter().sum::<f64>() / 4.0;
        assert!(
            (c.mean_distance - mean).abs() < 1e-12,
            "{}",
            c.mean_distance
        );
    }

    /// A range that does not start at 0 and a normal parameter (cut over mean ± 3 sd): the
    /// cells follow from the bounds in closed form.
    #[test]
    fn cells_of_an_offset_range_and_of_a_normal_parameter() {
        let params = parse_params(
            "[[parameter]]\nname = \"temperature\"\ndistribution = \"uniform\"\nlow = 10.0\nhigh = 30.0\n\
             [[parameter]]\nname = \"reflectivity\"\ndistribution = \"normal\"\nmean = 0.5\nsd = 0.1\n",
            "p",
        )
        .unwrap();
        // 10..30 in 4 parts of 5; 0.2..0.8 in 4 parts of 0.15.
        assert_eq!(cell(&params, 4, &[10.0, 0.2]), vec![0, 0]);
        assert_eq!(cell(&params, 4, &[14.9, 0.34]), vec![0, 0]);
        assert_eq!(cell(&params, 4, &[16.0, 0.36]), vec![1, 1]);
        assert_eq!(cell(&params, 4, &[24.0, 0.51]), vec![2, 2]);
        assert_eq!(cell(&params, 4, &[29.0, 0.79]), vec![3, 3]);
        // Outside the range: the first or last part.
        assert_eq!(cell(&params, 4, &[5.0, 0.9]), vec![0, 3]);
    }
}

//! The extended Fourier amplitude sensitivity test (eFAST; Saltelli, Tarantola and Chan 1999,
//! "A quantitative model-independent method for global sensitivity analysis of model output",
//! Technometrics 41(1)): which scenario parameters move a metric, and how much of its variance
//! each explains alone (first order, S1) and with all its interactions (total, ST). Rosenberger
//! et al. 2019, §4, uses it to decide which parameters a validation has to cover.
//!
//! The semantics are those of SALib's `fast_sampler.sample` and `fast.analyze` (version 1.6),
//! so that samples and results can be exchanged with it:
//! - sampling: for each parameter i in turn, N points along a search curve on which parameter i
//!   oscillates at the high frequency ω₀ = ⌊(N − 1) / 2M⌋ and the others at low frequencies
//!   (1 .. ⌊ω₀ / 2M⌋), each curve with a random phase: x_j(s) = ½ + arcsin(sin(ω_j s + φ)) / π,
//!   s = 2πk/N, scaled to each parameter's distribution. N·D rows.
//! - analysis: the power spectrum of each block's outputs; S1 = the power at the first M
//!   harmonics of ω₀ over the total, ST = 1 − (the power below ω₀/2) / total. Confidence: the
//!   same from 100 contiguous half-length windows (wrapping around) of the block, z · sd.
//!
//! `tests/efast_interop.rs` holds the analysis against SALib on the same samples.

use rand::{Rng, SeedableRng};
use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use serde::Deserialize;
use statrs::distribution::{ContinuousCDF, Normal};

/// Why eFAST cannot run.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EfastError {
    /// The parameter file is wrong.
    #[error("parameter file {path}: {message}")]
    Params {
        /// Where.
        path: String,
        /// What.
        message: String,
    },
    /// N is too small for M.
    #[error("N = {n} with M = {m}: eFAST needs N > 4 M² = {}", 4 * m * m)]
    TooFewSamples {
        /// Samples per parameter.
        n: usize,
        /// Harmonics.
        m: usize,
    },
    /// The outputs do not fit the parameters.
    #[error("{0}")]
    Outputs(String),
}

/// One parameter as the file gives it.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
struct ParamEntry {
    name: String,
    distribution: String,
    #[serde(default)]
    low: Option<f64>,
    #[serde(default)]
    high: Option<f64>,
    #[serde(default)]
    mean: Option<f64>,
    #[serde(default)]
    sd: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ParamFile {
    #[serde(rename = "parameter")]
    parameters: Vec<ParamEntry>,
}

/// How a parameter is distributed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distribution {
    /// Uniform on [low, high].
    Uniform {
        /// Lower bound.
        low: f64,
        /// Upper bound.
        high: f64,
    },
    /// Normal with this mean and standard deviation.
    Normal {
        /// Mean.
        mean: f64,
        /// Standard deviation.
        sd: f64,
    },
}

impl Distribution {
    /// The value at quantile `u` in [0, 1] (SALib's `scale_samples`: uniform scaled, normal by
    /// its inverse CDF).
    pub fn at(&self, u: f64) -> f64 {
        match *self {
            Distribution::Uniform { low, high } => low + u * (high - low),
            Distribution::Normal { mean, sd } => Normal::new(mean, sd)
                .map_or(f64::NAN, |n| n.inverse_cdf(u.clamp(1e-12, 1.0 - 1e-12))),
        }
    }
}

/// One parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct Parameter {
    /// Name.
    pub name: String,
    /// Distribution.
    pub distribution: Distribution,
}

/// Reads a parameter file: `[[parameter]]` tables with `name`, `distribution` ("uniform" with
/// `low` and `high`, or "normal" with `mean` and `sd`).
pub fn parse_params(text: &str, path: &str) -> Result<Vec<Parameter>, EfastError> {
    let err = |message: String| EfastError::Params {
        path: path.to_owned(),
        message,
    };
    crate::config::check_finite(text).map_err(|e| err(e.to_string()))?;
    let file: ParamFile = toml::from_str(text).map_err(|e| err(e.to_string()))?;
    if file.parameters.is_empty() {
        return Err(err("no [[parameter]]".into()));
    }
    let mut out = Vec::new();
    for p in file.parameters {
        let need = |v: Option<f64>, what: &str| {
            v.filter(|x| x.is_finite()).ok_or_else(|| {
                err(format!(
                    "parameter '{}': a {} distribution needs a finite `{what}`",
                    p.name, p.distribution
                ))
            })
        };
        let distribution = match p.distribution.as_str() {
            "uniform" => {
                let (low, high) = (need(p.low, "low")?, need(p.high, "high")?);
                if low >= high {
                    return Err(err(format!(
                        "parameter '{}': low {low} is not below high {high}",
                        p.name
                    )));
                }
                Distribution::Uniform { low, high }
            }
            "normal" => {
                let (mean, sd) = (need(p.mean, "mean")?, need(p.sd, "sd")?);
                if sd <= 0.0 {
                    return Err(err(format!(
                        "parameter '{}': sd {sd} must be positive",
                        p.name
                    )));
                }
                Distribution::Normal { mean, sd }
            }
            other => {
                return Err(err(format!(
                    "parameter '{}': unknown distribution '{other}' (uniform or normal)",
                    p.name
                )))
            }
        };
        if out.iter().any(|q: &Parameter| q.name == p.name) {
            return Err(err(format!("parameter '{}' appears twice", p.name)));
        }
        out.push(Parameter {
            name: p.name,
            distribution,
        });
    }
    Ok(out)
}

/// The search-curve frequencies: ω₀ for the parameter under study, then the others'.
fn frequencies(n: usize, m: usize, d: usize) -> (usize, Vec<usize>) {
    let omega0 = (n - 1) / (2 * m);
    let mm = omega0 / (2 * m);
    let others: Vec<usize> = if d < 2 {
        Vec::new()
    } else if mm >= d - 1 {
        // numpy's floor(linspace(1, m, d - 1)).
        (0..d - 1)
            .map(|k| {
                if d == 2 {
                    1
                } else {
                    (1.0 + (mm as f64 - 1.0) * k as f64 / (d - 2) as f64).floor() as usize
                }
            })
            .collect()
    } else {
        (0..d - 1).map(|k| k % mm + 1).collect()
    };
    (omega0, others)
}

/// Sample rows as CSV: a header of the parameters' names, then one row per line, each value
/// written so that it reads back to the same `f64`.
pub fn samples_csv(params: &[Parameter], rows: &[Vec<f64>]) -> String {
    use std::fmt::Write as _;
    let mut out = params
        .iter()
        .map(|q| q.name.as_str())
        .collect::<Vec<_>>()
        .join(",");
    out.push('\n');
    for r in rows {
        let line: Vec<String> = r.iter().map(|v| format!("{v:?}")).collect();
        let _ = writeln!(out, "{}", line.join(","));
    }
    out
}

/// N·D sample rows (D values each), block i studying parameter i.
pub fn sample(
    params: &[Parameter],
    n: usize,
    m: usize,
    seed: u64,
) -> Result<Vec<Vec<f64>>, EfastError> {
    if n <= 4 * m * m || m == 0 {
        return Err(EfastError::TooFewSamples { n, m });
    }
    let d = params.len();
    let (omega0, others) = frequencies(n, m, d);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut rows = Vec::with_capacity(n * d);
    for i in 0..d {
        let mut omega = vec![0usize; d];
        omega[i] = omega0;
        let mut rest = others.iter();
        for (j, w) in omega.iter_mut().enumerate() {
            if j != i {
                *w = *rest.next().unwrap_or(&1);
            }
        }
        let phi = std::f64::consts::TAU * rng.random::<f64>();
        for k in 0..n {
            let s = std::f64::consts::TAU / n as f64 * k as f64;
            rows.push(
                params
                    .iter()
                    .zip(&omega)
                    .map(|(p, &w)| {
                        let g = 0.5 + ((w as f64 * s + phi).sin()).asin() / std::f64::consts::PI;
                        p.distribution.at(g)
                    })
                    .collect(),
            );
        }
    }
    Ok(rows)
}

/// First and total order of one block of outputs (SALib's `compute_orders`).
fn orders(y: &[f64], m: usize, omega: usize) -> (f64, f64) {
    let n = y.len();
    let mut buf: Vec<Complex<f64>> = y.iter().map(|&v| Complex::new(v, 0.0)).collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    // Power at frequencies 1 .. ceil(n/2) - 1.
    let sp: Vec<f64> = (1..n.div_ceil(2))
        .map(|k| (buf[k].norm() / n as f64).powi(2))
        .collect();
    let v = 2.0 * sp.iter().sum::<f64>();
    let d1 = 2.0
        * (1..=m)
            .filter_map(|h| (h * omega).checked_sub(1).and_then(|k| sp.get(k)))
            .sum::<f64>();
    let dt = 2.0 * sp.iter().take(omega / 2).sum::<f64>();
    (d1 / v, 1.0 - dt / v)
}

/// One parameter's indices.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Indices {
    /// Parameter.
    pub name: String,
    /// First order.
    pub s1: f64,
    /// Its confidence half-width.
    pub s1_conf: f64,
    /// Total order.
    pub st: f64,
    /// Its confidence half-width.
    pub st_conf: f64,
}

/// S1 and ST of every parameter from the outputs `y` of [`sample`]'s rows (in order), with
/// bootstrap confidence half-widths at `conf_level` from `resamples` windows.
pub fn analyze(
    params: &[Parameter],
    y: &[f64],
    m: usize,
    resamples: usize,
    conf_level: f64,
    seed: u64,
) -> Result<Vec<Indices>, EfastError> {
    let d = params.len();
    if y.is_empty() || !y.len().is_multiple_of(d) {
        return Err(EfastError::Outputs(format!(
            "{} outputs for {d} parameters: eFAST needs N outputs per parameter",
            y.len()
        )));
    }
    if let Some(i) = y.iter().position(|v| !v.is_finite()) {
        return Err(EfastError::Outputs(format!(
            "output {} is not a number",
            i + 1
        )));
    }
    let n = y.len() / d;
    if n <= 4 * m * m || m == 0 {
        return Err(EfastError::TooFewSamples { n, m });
    }
    let omega0 = (n - 1) / (2 * m);
    let z = Normal::new(0.0, 1.0).map_or(1.96, |nd| nd.inverse_cdf(0.5 + conf_level / 2.0));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(d);
    for (i, p) in params.iter().enumerate() {
        let block = &y[i * n..(i + 1) * n];
        let (s1, st) = orders(block, m, omega0);
        // Contiguous half-length windows, wrapping around.
        let half = n.div_ceil(2);
        let w = (half - 1) / (2 * m);
        let (mut r1, mut rt) = (Vec::new(), Vec::new());
        for _ in 0..resamples {
            let start = rng.random_range(0..n);
            let window: Vec<f64> = (0..half).map(|k| block[(start + k) % n]).collect();
            let (a, b) = orders(&window, m, w);
            r1.push(a);
            rt.push(b);
        }
        let sd = |v: &[f64]| {
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len().max(2) - 1) as f64).sqrt()
        };
        out.push(Indices {
            name: p.name.clone(),
            s1,
            s1_conf: if resamples > 1 { z * sd(&r1) } else { f64::NAN },
            st,
            st_conf: if resamples > 1 { z * sd(&rt) } else { f64::NAN },
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ISHIGAMI: &str = r#"
[[parameter]]
name = "x1"
distribution = "uniform"
low = -3.141592653589793
high = 3.141592653589793
[[parameter]]
name = "x2"
distribution = "uniform"
low = -3.141592653589793
high = 3.141592653589793
[[parameter]]
name = "x3"
distribution = "uniform"
low = -3.141592653589793
high = 3.141592653589793
"#;

    fn ishigami(x: &[f64]) -> f64 {
        x[0].sin() + 7.0 * x[1].sin().powi(2) + 0.1 * x[2].powi(4) * x[0].sin()
    }

    /// Ishigami (a = 7, b = 0.1): S1 = 0.3139, 0.4424, 0; ST = 0.5576, 0.4424, 0.2437.
    #[test]
    fn ishigami_indices_are_the_analytic_ones() {
        let p = parse_params(ISHIGAMI, "ishigami.toml").unwrap();
        let x = sample(&p, 1000, 4, 7).unwrap();
        assert_eq!(x.len(), 3000);
        let y: Vec<f64> = x.iter().map(|r| ishigami(r)).collect();
        let s = analyze(&p, &y, 4, 100, 0.95, 1).unwrap();
        for (got, want) in s.iter().zip([0.3139, 0.4424, 0.0]) {
            assert!((got.s1 - want).abs() < 0.03, "{got:?} vs {want}");
        }
        for (got, want) in s.iter().zip([0.5576, 0.4424, 0.2437]) {
            assert!((got.st - want).abs() < 0.05, "{got:?} vs {want}");
        }
        assert!(s.iter().all(|i| i.s1_conf > 0.0 && i.s1_conf < 0.2));
        // One bootstrap window has no spread: no half-width rather than a zero one.
        for i in analyze(&p, &y, 4, 1, 0.95, 1).unwrap() {
            assert!(i.s1_conf.is_nan() && i.st_conf.is_nan(), "{i:?}");
            assert!(i.s1.is_finite(), "{i:?}");
        }
    }

    /// numpy's frequencies for a few (N, M, D): ω₀ = ⌊(N−1)/2M⌋, the rest spread or cycled.
    #[test]
    fn frequencies_as_salib_makes_them() {
        assert_eq!(frequencies(1000, 4, 3), (124, vec![1, 15]));
        assert_eq!(frequencies(1000, 4, 2), (124, vec![1]));
        assert_eq!(frequencies(65, 4, 5), (8, vec![1, 1, 1, 1]));
        assert_eq!(frequencies(200, 4, 6), (24, vec![1, 2, 3, 1, 2]));
    }

    #[test]
    fn bad_parameter_files_and_sizes_are_refused() {
        let bad = ISHIGAMI.replacen("\"uniform\"", "\"weibull\"", 1);
        let e = parse_params(&bad, "p.toml").unwrap_err();
        assert!(
            e.to_string().contains("unknown distribution 'weibull'"),
            "{e}"
        );
        assert!(parse_params(
            "[[parameter]]\nname = \"a\"\ndistribution = \"uniform\"\nlow = 1.0\n",
            "p"
        )
        .is_err());
        assert!(parse_params(
            "[[parameter]]\nname = \"a\"\ndistribution = \"normal\"\nmean = 1.0\nsd = 0.0\n",
            "p"
        )
        .is_err());
        assert!(parse_params("[[parameter]]\nname = \"a\"\ndistribution = \"uniform\"\nlow = 0.0\nhigh = 1.0\nshape = 2\n", "p").is_err());
        let p = parse_params(ISHIGAMI, "p").unwrap();
        assert_eq!(
            sample(&p, 64, 4, 1),
            Err(EfastError::TooFewSamples { n: 64, m: 4 })
        );
        assert!(analyze(&p, &[1.0; 100], 4, 10, 0.95, 1).is_err());
    }
}

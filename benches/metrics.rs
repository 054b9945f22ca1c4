//! Metric speed (issue 13, must-hold 8):
//! - OCR^K of two 100 k-point scans (binning both, comparing the grids) in scan pairs per
//!   second on one core, against the bare baseline of hashing the same 200 k cell keys into a
//!   set;
//! - the Chamfer and Hausdorff distances of 100 k against 100 k points in pairs per second (the
//!   two directions run in parallel; `RAYON_NUM_THREADS=1` for one core).
//!
//! `cargo bench --bench metrics`; the ratios are printed from interleaved rounds so both sides
//! see the same machine load.

use criterion::{criterion_group, Criterion, Throughput};
use hilrig::metrics::grid::{compare, Dims, GridSpec, Occupancy};
use hilrig::metrics::points::distances;
use nalgebra::Point3;
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use std::time::Instant;

/// A VLP-like scan of `n` points on walls and ground within 30 m.
fn scan(n: usize, seed: u64) -> Vec<Point3<f64>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let r: f64 = rng.random_range(2.0..30.0);
            Point3::new(r * a.cos(), r * a.sin(), rng.random_range(-1.5..2.0))
        })
        .collect()
}

fn ocr(spec: &GridSpec, a: &[Point3<f64>], b: &[Point3<f64>]) -> Option<f64> {
    let ra = Occupancy::of(spec, &[a]).ok()?;
    let rb = Occupancy::of(spec, &[b]).ok()?;
    compare(&ra, &rb).ocr
}

fn baseline(spec: &GridSpec, a: &[Point3<f64>], b: &[Point3<f64>]) -> usize {
    let mut set = std::collections::HashSet::with_capacity(a.len() + b.len());
    for p in a.iter().chain(b) {
        set.insert(spec.cell(p));
    }
    set.len()
}

fn benches(c: &mut Criterion) {
    let (a, b) = (scan(100_000, 1), scan(100_000, 2));
    let spec = GridSpec::new(0.1, Dims::Voxel).unwrap();
    let mut g = c.benchmark_group("metrics");
    g.throughput(Throughput::Elements(1));
    g.bench_function("ocr_100k_pair", |x| {
        x.iter(|| black_box(ocr(&spec, &a, &b)))
    });
    g.bench_function("cell_keys_hashset_baseline", |x| {
        x.iter(|| black_box(baseline(&spec, &a, &b)))
    });
    g.sample_size(10);
    g.bench_function("chamfer_100k_pair", |x| {
        x.iter(|| black_box(distances(&a, &b)))
    });
    g.finish();
}

criterion_group!(group, benches);

fn main() {
    group();
    Criterion::default().configure_from_args().final_summary();
    let (a, b) = (scan(100_000, 1), scan(100_000, 2));
    let spec = GridSpec::new(0.1, Dims::Voxel).unwrap();
    // Rounds of 50 OCR pairs, 50 baselines and 3 Chamfers in turn: each metric is timed over a
    // run of calls, as `compare` calls it scan after scan (one call after a Chamfer would time
    // the caches and pages the Chamfer left behind).
    let (mut t_ocr, mut t_base, mut t_ch) = (0.0, 0.0, 0.0);
    let (rounds, per_round, chamfers) = (10, 50, 3);
    for _ in 0..rounds {
        let s = Instant::now();
        for _ in 0..per_round {
            black_box(ocr(&spec, &a, &b));
        }
        t_ocr += s.elapsed().as_secs_f64();
        let s = Instant::now();
        for _ in 0..per_round {
            black_box(baseline(&spec, &a, &b));
        }
        t_base += s.elapsed().as_secs_f64();
        let s = Instant::now();
        for _ in 0..chamfers {
            black_box(distances(&a, &b));
        }
        t_ch += s.elapsed().as_secs_f64();
    }
    let n = f64::from(rounds * per_round);
    let n_ch = f64::from(rounds * chamfers);
    println!(
        "OCR of 100 k-point scans: {:.0} pairs/s (bare cell hashing {:.0}/s, ratio {:.2}); Chamfer+Hausdorff 100 k x 100 k: {:.1} pairs/s",
        n / t_ocr,
        n / t_base,
        t_base / t_ocr,
        n_ch / t_ch
    );
}

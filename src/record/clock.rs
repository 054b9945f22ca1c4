//! Per-source clock models: a sensor's own clock mapped onto the logger's (host) time base.
//!
//! Every item a driver delivers has a host receive stamp and, for sensors with a clock, the
//! sensor's stamp. `host - sensor` is the clock offset plus the transport delay, and transport
//! delay is never negative. So the offset (and drift) is the *lower envelope* of the
//! `(sensor, host - sensor)` points: the line below all points that is closest to them
//! (the classic skew estimator of Moon, Skelly and Towsley, an LP whose optimum is the edge of the
//! lower convex hull that spans the mean sensor time). Residuals above the line are the
//! transport-delay jitter: the temporal accuracy of that source. A constant transport latency is
//! indistinguishable from a clock offset and ends up in the offset, which is what replay and
//! synchronisation want (it is when the logger *could* have known).
//!
//! Sans-IO in the quinn manner: [`ClockEstimator::handle`] takes one pair, [`ClockEstimator::model`]
//! answers at any time. The hull is built incrementally (sensor times arrive in order; an
//! out-of-order pair is counted and ignored) and stays small; residual statistics use a
//! decimated copy of the pairs, so memory is bounded for recordings of any length.

use hilrig_stamp::UtcNanos;

/// Pairs kept for residual statistics (decimated by doubling the stride when full).
const MAX_KEPT: usize = 65_536;

/// The fitted mapping from sensor time to host time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockModel {
    /// Sensor time the line is anchored at (the first pair's).
    pub reference: UtcNanos,
    /// `host - sensor` at the reference, nanoseconds (offset plus minimum transport delay).
    pub offset_ns: f64,
    /// Drift: change of `host - sensor` per unit of sensor time (1e-6 = 1 ppm).
    pub drift: f64,
}

impl ClockModel {
    /// Host time of a sensor time.
    pub fn to_host(&self, sensor: UtcNanos) -> UtcNanos {
        let dx = (sensor.0 - self.reference.0) as f64;
        UtcNanos(
            sensor
                .0
                .saturating_add((self.offset_ns + self.drift * dx).round() as i64),
        )
    }

    /// `host - sensor` predicted at a sensor time, nanoseconds.
    pub fn offset_at(&self, sensor: UtcNanos) -> f64 {
        self.offset_ns + self.drift * (sensor.0 - self.reference.0) as f64
    }
}

/// Distribution of residuals above the envelope (transport-delay jitter), nanoseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Residuals {
    /// Pairs the statistics are over (after decimation).
    pub count: usize,
    /// Median.
    pub p50_ns: f64,
    /// 95th percentile.
    pub p95_ns: f64,
    /// 99th percentile.
    pub p99_ns: f64,
    /// Largest.
    pub max_ns: f64,
}

/// Estimates a [`ClockModel`] from (sensor, host) pairs.
#[derive(Clone, Debug, Default)]
pub struct ClockEstimator {
    reference: Option<i64>,
    last_x: Option<f64>,
    /// Lower convex hull of (x, y): x = sensor - reference, y = host - sensor, both ns.
    hull: Vec<(f64, f64)>,
    n: u64,
    sum_x: f64,
    kept: Vec<(f64, f64)>,
    stride: u64,
    /// Pairs whose sensor time went backwards (ignored).
    pub out_of_order: u64,
}

fn cross(o: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
}

impl ClockEstimator {
    /// An empty estimator.
    pub fn new() -> Self {
        ClockEstimator {
            stride: 1,
            ..Default::default()
        }
    }

    /// Pairs accepted.
    pub fn pairs(&self) -> u64 {
        self.n
    }

    /// Takes one pair.
    pub fn handle(&mut self, sensor: UtcNanos, host: UtcNanos) {
        let r = *self.reference.get_or_insert(sensor.0);
        let x = (sensor.0 - r) as f64;
        if self.last_x.is_some_and(|l| x < l) {
            self.out_of_order += 1;
            return;
        }
        self.last_x = Some(x);
        let y = (host.0 - sensor.0) as f64;
        // Equal x: only the lower point matters for the envelope.
        if let Some(&(lx, ly)) = self.hull.last() {
            if lx == x {
                if y < ly {
                    self.hull.pop();
                } else {
                    self.note(x, y);
                    return;
                }
            }
        }
        while self.hull.len() >= 2
            && cross(
                self.hull[self.hull.len() - 2],
                self.hull[self.hull.len() - 1],
                (x, y),
            ) <= 0.0
        {
            self.hull.pop();
        }
        self.hull.push((x, y));
        self.note(x, y);
    }

    fn note(&mut self, x: f64, y: f64) {
        self.n += 1;
        self.sum_x += x;
        if self.stride == 0 {
            self.stride = 1;
        }
        if self.n.is_multiple_of(self.stride) {
            self.kept.push((x, y));
            if self.kept.len() >= MAX_KEPT {
                // Keep every other pair and sample half as often from now on.
                let mut i = 0;
                self.kept.retain(|_| {
                    i += 1;
                    i % 2 == 0
                });
                self.stride *= 2;
            }
        }
    }

    /// The current model; `None` before the first pair.
    pub fn model(&self) -> Option<ClockModel> {
        let reference = UtcNanos(self.reference?);
        let first = *self.hull.first()?;
        if self.hull.len() == 1 {
            return Some(ClockModel {
                reference,
                offset_ns: first.1,
                drift: 0.0,
            });
        }
        let mean = self.sum_x / self.n as f64;
        // The hull edge whose x-range holds the mean is the LP optimum.
        let edge = self
            .hull
            .windows(2)
            .find(|w| mean >= w[0].0 && mean <= w[1].0)
            .unwrap_or(&self.hull[self.hull.len() - 2..]);
        let (a, b) = (edge[0], edge[1]);
        let drift = (b.1 - a.1) / (b.0 - a.0);
        Some(ClockModel {
            reference,
            offset_ns: a.1 - drift * a.0,
            drift,
        })
    }

    /// Residuals above the current model.
    pub fn residuals(&self) -> Residuals {
        let Some(m) = self.model() else {
            return Residuals::default();
        };
        let mut r: Vec<f64> = self
            .kept
            .iter()
            .map(|&(x, y)| (y - (m.offset_ns + m.drift * x)).max(0.0))
            .collect();
        if r.is_empty() {
            return Residuals::default();
        }
        r.sort_by(f64::total_cmp);
        let q = |p: f64| r[((r.len() - 1) as f64 * p).round() as usize];
        Residuals {
            count: r.len(),
            p50_ns: q(0.5),
            p95_ns: q(0.95),
            p99_ns: q(0.99),
            max_ns: r[r.len() - 1],
        }
    }
}

/// The `clock_sync/<source>` metadata record of a model (what `check` reads).
pub fn metadata(m: &ClockModel, r: &Residuals, pairs: u64) -> crate::bag::clock_sync::ClockSync {
    crate::bag::clock_sync::ClockSync::of_model(
        m.reference.0,
        m.offset_ns,
        m.drift,
        [r.p50_ns, r.p95_ns, r.max_ns],
        pairs,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A virtual clock: the sensor's clock runs `drift` fast and is `offset` behind the host;
    /// every message takes a latency of `floor` plus exponential jitter of mean `jitter` (a
    /// deterministic generator, so the test is exact and reproducible).
    fn simulate(
        offset_ns: f64,
        drift: f64,
        floor_ns: f64,
        jitter_ns: f64,
        n: usize,
        period_ns: i64,
    ) -> ClockEstimator {
        let mut e = ClockEstimator::new();
        let mut state = 0x1234_5678_9abc_def0u64;
        let t0 = 1_700_000_000_000_000_000i64;
        for i in 0..n {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            let latency = floor_ns - jitter_ns * (1.0 - u).ln();
            let host_true = t0 + i as i64 * period_ns;
            // Sensor clock reading at that instant.
            let sensor = host_true as f64 - offset_ns - drift * (host_true - t0) as f64;
            e.handle(
                UtcNanos(sensor as i64),
                UtcNanos(host_true + latency as i64),
            );
        }
        e
    }

    #[test]
    fn offset_and_drift_are_recovered_within_100_microseconds() {
        // 37.2 ms offset, 50 ppm drift, 20 µs latency floor, 300 µs mean jitter, 10 min at 100 Hz.
        let e = simulate(37.2e6, 50e-6, 20e3, 300e3, 60_000, 10_000_000);
        let m = e.model().unwrap();
        // Truth: host - sensor = offset + drift-induced term + latency floor.
        let true_at_ref = 37.2e6 + 20e3;
        assert!(
            (m.offset_ns - true_at_ref).abs() < 100e3,
            "offset {} vs {}",
            m.offset_ns,
            true_at_ref
        );
        assert!((m.drift - 50e-6).abs() < 1e-6, "drift {}", m.drift);
        let r = e.residuals();
        // Exponential jitter of mean 300 µs: median ~208 µs, 95th ~899 µs.
        assert!((r.p50_ns - 208e3).abs() < 30e3, "{r:?}");
        assert!((r.p95_ns - 899e3).abs() < 90e3, "{r:?}");
        // Mapping a sensor time gives the host time minus jitter: never later than received.
        assert_eq!(e.out_of_order, 0);
    }

    #[test]
    fn a_single_pair_gives_a_pure_offset_and_backward_times_are_ignored() {
        let mut e = ClockEstimator::new();
        e.handle(UtcNanos(1_000), UtcNanos(5_000));
        let m = e.model().unwrap();
        assert_eq!(m.offset_ns, 4_000.0);
        assert_eq!(m.to_host(UtcNanos(2_000)), UtcNanos(6_000));
        e.handle(UtcNanos(500), UtcNanos(9_000));
        assert_eq!(e.out_of_order, 1);
        assert_eq!(e.pairs(), 1);
    }

    #[test]
    fn memory_stays_bounded_on_long_recordings() {
        let e = simulate(0.0, 0.0, 0.0, 100e3, 500_000, 1_000_000);
        assert!(e.kept.len() < MAX_KEPT);
        assert!(e.hull.len() < 200, "hull has {} points", e.hull.len());
        assert!(e.model().unwrap().offset_ns.abs() < 5e3);
    }
}

//! Faults and segments. Every problem the measurements find is a [`Fault`] with a name, a time
//! window and the numbers behind it; one-second segments take the verdict of the faults that
//! overlap them, so the engineer sees which parts of the drive are usable and why the others
//! are not.

use super::names::FaultName;
use super::report::{Fault, Segment, Verdict};
use hilrig_stamp::UtcNanos;

/// ISO 8601 with milliseconds, as gpsd writes it.
pub(super) fn iso(t: UtcNanos) -> String {
    hilrig_stamp::civil::iso8601_millis(t)
}

/// Seconds from `a` to `b`.
pub(super) fn secs(a: UtcNanos, b: UtcNanos) -> f64 {
    (b.0 - a.0) as f64 * 1e-9
}

/// Seconds from `a` to `b` to the millisecond, for the report (a time in a fault or segment
/// means nothing finer, and 19.900000000000002 helps nobody reading the JSON).
pub(super) fn secs_ms(a: UtcNanos, b: UtcNanos) -> f64 {
    ((b.0 - a.0) as f64 * 1e-6).round() / 1e3
}

/// The faults found so far, located relative to the run's start, and the stretches marked not
/// usable although nothing is wrong with the data (the reference is too uncertain there: a
/// heading not yet determined, say). A fault fails the run; a mark only takes its stretch out.
pub(super) struct FaultLog {
    start: UtcNanos,
    pub(super) faults: Vec<Fault>,
    pub(super) marks: Vec<Fault>,
}

impl FaultLog {
    /// An empty log for a run that starts at `start`.
    pub(super) fn new(start: UtcNanos) -> FaultLog {
        FaultLog {
            start,
            faults: Vec::new(),
            marks: Vec::new(),
        }
    }

    /// Whether a fault of this name was raised.
    pub(super) fn has(&self, name: FaultName) -> bool {
        self.faults.iter().any(|f| f.name == name)
    }

    /// A located finding (fault or mark).
    fn located(&self, name: FaultName, from: UtcNanos, to: UtcNanos, detail: String) -> Fault {
        Fault {
            name,
            topics: name.topics().iter().map(|t| (*t).to_owned()).collect(),
            from: iso(from),
            to: iso(to),
            from_s: secs_ms(self.start, from),
            to_s: secs_ms(self.start, to),
            detail,
            from_ns: from,
            to_ns: to,
        }
    }

    /// Records one fault.
    pub(super) fn fault(&mut self, name: FaultName, from: UtcNanos, to: UtcNanos, detail: String) {
        let f = self.located(name, from, to, detail);
        self.faults.push(f);
    }

    /// Marks one stretch not usable (not a fault: the run's verdict stays).
    pub(super) fn mark(&mut self, name: FaultName, from: UtcNanos, to: UtcNanos, detail: String) {
        let m = self.located(name, from, to, detail);
        self.marks.push(m);
    }

    /// Faults for runs of consecutive flagged samples (a run ends after `gap` without a flag).
    pub(super) fn runs(
        &mut self,
        name: FaultName,
        flagged: &[(UtcNanos, f64)],
        period: i64,
        describe: impl Fn(usize, f64) -> String,
    ) {
        for (a, b, n, worst) in spans(flagged, period) {
            self.fault(name, a, b, describe(n, worst));
        }
    }

    /// Marks for runs of consecutive flagged samples, as [`FaultLog::runs`] makes faults.
    pub(super) fn mark_runs(
        &mut self,
        name: FaultName,
        flagged: &[(UtcNanos, f64)],
        period: i64,
        describe: impl Fn(usize, f64) -> String,
    ) {
        for (a, b, n, worst) in spans(flagged, period) {
            self.mark(name, a, b, describe(n, worst));
        }
    }
}

/// Runs of flagged samples (time, value) at most one and a half periods apart: start, end (one
/// period after the last), samples and the largest value of each.
fn spans(flagged: &[(UtcNanos, f64)], period: i64) -> Vec<(UtcNanos, UtcNanos, usize, f64)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < flagged.len() {
        let mut j = i + 1;
        while j < flagged.len() && flagged[j].0 .0 - flagged[j - 1].0 .0 <= period * 3 / 2 {
            j += 1;
        }
        let worst = flagged[i..j].iter().map(|f| f.1).fold(f64::NAN, f64::max);
        out.push((
            flagged[i].0,
            UtcNanos(flagged[j - 1].0 .0 + period),
            j - i,
            worst,
        ));
        i = j;
    }
    out
}

/// A fault (`true`) or mark (`false`) of some name entering (+1) or leaving (-1) the cells.
type Edge = ((bool, FaultName), i32);

/// One-second segments from `start` to `end` (a last piece under 50 ms joins the one before
/// it), each failing with the faults that overlap it (or not usable with the marks that overlap
/// it, when no fault does), merged while verdict and reasons stay the same. Computed by sweeping over the faults' edges rather than second by second, so that a
/// damaged recording whose stamps span years is judged as quickly as a sound one.
pub(super) fn segments(
    faults: &[Fault],
    marks: &[Fault],
    start: UtcNanos,
    end: UtcNanos,
) -> Vec<Segment> {
    const S: i64 = 1_000_000_000;
    let total = end.0 - start.0;
    if total <= 0 {
        return Vec::new();
    }
    // Cells of one second; the last one runs to the end (it absorbs a remainder under 50 ms).
    let full = total / S;
    let rem = total - full * S;
    let n = if rem == 0 || (rem < 50_000_000 && full >= 1) {
        full
    } else {
        full + 1
    };
    let cell_start = |k: i64| UtcNanos(start.0 + k * S);
    let cell_end = |k: i64| {
        if k == n - 1 {
            end
        } else {
            UtcNanos(start.0 + (k + 1) * S)
        }
    };
    // A fault covers the cells from the one its start falls in to the one its end falls in.
    let mut edges: std::collections::BTreeMap<i64, Vec<Edge>> = std::collections::BTreeMap::new();
    let tagged = faults
        .iter()
        .map(|f| (true, f))
        .chain(marks.iter().map(|m| (false, m)));
    for (is_fault, f) in tagged {
        let (a, b) = f.window();
        if a >= end || b < start {
            continue;
        }
        let first = (a.0 - start.0).div_euclid(S).clamp(0, n - 1);
        let last = (b.0 - start.0).div_euclid(S).clamp(0, n - 1);
        if first > last {
            continue;
        }
        edges
            .entry(first)
            .or_default()
            .push(((is_fault, f.name), 1));
        edges
            .entry(last + 1)
            .or_default()
            .push(((is_fault, f.name), -1));
    }
    edges.entry(0).or_default();
    edges.entry(n).or_default();
    let mut active: std::collections::BTreeMap<(bool, FaultName), i32> = Default::default();
    let mut segments: Vec<Segment> = Vec::new();
    let points: Vec<(i64, Vec<Edge>)> = edges.into_iter().collect();
    for w in points.windows(2) {
        let ((k, changes), (next, _)) = (&w[0], &w[1]);
        for &(name, d) in changes {
            *active.entry(name).or_default() += d;
        }
        active.retain(|_, c| *c > 0);
        let (k, next) = (*k, (*next).min(n));
        if k >= next {
            continue;
        }
        let faulty = active.keys().any(|k| k.0);
        let mut reasons: Vec<FaultName> = active.keys().map(|k| k.1).collect();
        reasons.sort_unstable();
        reasons.dedup();
        let verdict = if reasons.is_empty() {
            Verdict::Pass
        } else if faulty {
            Verdict::Fail
        } else {
            Verdict::Unusable
        };
        let (from, to) = (cell_start(k), cell_end(next - 1));
        match segments.last_mut() {
            Some(s) if s.verdict == verdict && s.reasons == reasons => s.to_s = secs_ms(start, to),
            _ => segments.push(Segment {
                from_s: secs_ms(start, from),
                to_s: secs_ms(start, to),
                verdict,
                reasons,
            }),
        }
    }
    segments
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fault(name: FaultName, a: i64, b: i64) -> Fault {
        Fault {
            name,
            topics: Vec::new(),
            from: String::new(),
            to: String::new(),
            from_s: 0.0,
            to_s: 0.0,
            detail: String::new(),
            from_ns: UtcNanos(a),
            to_ns: UtcNanos(b),
        }
    }

    /// The second-by-second rule, spelled out as the reference for the sweep.
    fn by_the_second(
        faults: &[Fault],
        start: UtcNanos,
        end: UtcNanos,
    ) -> Vec<(f64, f64, Vec<FaultName>)> {
        let mut out: Vec<(f64, f64, Vec<FaultName>)> = Vec::new();
        let mut t = start;
        while t < end {
            let mut e = UtcNanos((t.0 + 1_000_000_000).min(end.0));
            if end.0 - e.0 < 50_000_000 {
                e = end;
            }
            let mut r: Vec<FaultName> = faults
                .iter()
                .filter(|f| f.from_ns < e && f.to_ns >= t)
                .map(|f| f.name)
                .collect();
            r.sort_unstable();
            r.dedup();
            match out.last_mut() {
                Some(s) if s.2 == r => s.1 = secs_ms(start, e),
                _ => out.push((secs_ms(start, t), secs_ms(start, e), r)),
            }
            t = e;
        }
        out
    }

    #[test]
    fn the_sweep_gives_the_second_by_second_segments() {
        let s = 1_000_000_000i64;
        let cases: Vec<(i64, Vec<Fault>)> = vec![
            (20 * s + 30_000_000, vec![]),
            (
                20 * s + 300_000_000,
                vec![fault(FaultName::RtkFloat, 3 * s + 400_000_000, 5 * s)],
            ),
            (
                12 * s,
                vec![
                    fault(FaultName::RtkFloat, 2 * s, 4 * s),
                    fault(FaultName::Jump, 3 * s + 1, 9 * s + 999_999_999),
                    fault(FaultName::RtkFloat, 6 * s, 6 * s),
                    fault(FaultName::LidarGap, -5 * s, 0),
                    fault(FaultName::CanGap, 11 * s + 999_000_000, 30 * s),
                ],
            ),
            (40_000_000, vec![fault(FaultName::GnssGap, 0, 1)]),
        ];
        for (len, faults) in cases {
            let (a, b) = (UtcNanos(0), UtcNanos(len));
            let got: Vec<(f64, f64, Vec<FaultName>)> = segments(&faults, &[], a, b)
                .into_iter()
                .map(|g| (g.from_s, g.to_s, g.reasons))
                .collect();
            assert_eq!(got, by_the_second(&faults, a, b), "{len} ns");
        }
    }

    /// A recording whose stamps span fifty years (a flipped bit in a log time) is segmented at
    /// once.
    #[test]
    fn fifty_years_are_segmented_at_once() {
        let s = 1_000_000_000i64;
        let end = UtcNanos(50 * 365 * 86_400 * s);
        let segs = segments(
            &[fault(FaultName::RtkFloat, 10 * s, 20 * s)],
            &[],
            UtcNanos(0),
            end,
        );
        assert_eq!(segs.len(), 3);
        assert_eq!(segs[1].reasons, vec![FaultName::RtkFloat]);
    }
}

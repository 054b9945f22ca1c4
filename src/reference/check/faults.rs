//! Faults and segments. Every problem the measurements find is a [`Fault`] with a name, a time
//! window and the numbers behind it; one-second segments take the verdict of the faults that
//! overlap them, so the engineer sees which parts of the drive are usable and why the others
//! are not.

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

/// The faults found so far, located relative to the run's start.
pub(super) struct FaultLog {
    start: UtcNanos,
    pub(super) faults: Vec<Fault>,
}

impl FaultLog {
    /// An empty log for a run that starts at `start`.
    pub(super) fn new(start: UtcNanos) -> FaultLog {
        FaultLog {
            start,
            faults: Vec::new(),
        }
    }

    /// Whether a fault of this name was raised.
    pub(super) fn has(&self, name: &str) -> bool {
        self.faults.iter().any(|f| f.name == name)
    }

    /// Records one fault.
    pub(super) fn fault(
        &mut self,
        name: &'static str,
        from: UtcNanos,
        to: UtcNanos,
        detail: String,
    ) {
        self.faults.push(Fault {
            name,
            from: iso(from),
            to: iso(to),
            from_s: secs(self.start, from),
            to_s: secs(self.start, to),
            detail,
            window: (from, to),
        });
    }

    /// Faults for runs of consecutive flagged samples (a run ends after `gap` without a flag).
    pub(super) fn runs(
        &mut self,
        name: &'static str,
        flagged: &[(UtcNanos, f64)],
        period: i64,
        describe: impl Fn(usize, f64) -> String,
    ) {
        let mut i = 0;
        while i < flagged.len() {
            let mut j = i + 1;
            while j < flagged.len() && flagged[j].0 .0 - flagged[j - 1].0 .0 <= period * 3 / 2 {
                j += 1;
            }
            let worst = flagged[i..j].iter().map(|f| f.1).fold(f64::NAN, f64::max);
            let (a, b) = (flagged[i].0, UtcNanos(flagged[j - 1].0 .0 + period));
            self.fault(name, a, b, describe(j - i, worst));
            i = j;
        }
    }
}

/// One-second segments from `start` to `end`, merged while verdict and reasons stay the same.
pub(super) fn segments(faults: &[Fault], start: UtcNanos, end: UtcNanos) -> Vec<Segment> {
    let mut segments: Vec<Segment> = Vec::new();
    let mut t = start;
    while t < end {
        let e = UtcNanos((t.0 + 1_000_000_000).min(end.0));
        let mut reasons: Vec<&'static str> = faults
            .iter()
            .filter(|f| f.window.0 < e && f.window.1 >= t)
            .map(|f| f.name)
            .collect();
        reasons.sort_unstable();
        reasons.dedup();
        let verdict = if reasons.is_empty() {
            Verdict::Pass
        } else {
            Verdict::Fail
        };
        match segments.last_mut() {
            Some(s) if s.verdict == verdict && s.reasons == reasons => s.to_s = secs(start, e),
            _ => segments.push(Segment {
                from_s: secs(start, t),
                to_s: secs(start, e),
                verdict,
                reasons,
            }),
        }
        t = e;
    }
    segments
}

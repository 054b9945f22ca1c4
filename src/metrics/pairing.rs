//! Scan pairing: each measured scan with its simulated twin (a re-simulation keeps every
//! measured scan's stamp), less the scans that lie where `check` marked the reference not
//! usable.
//!
//! Both files are streams, so the twins are found by merging: a re-simulation writes its scans
//! in the run's order, possibly without some of them, so its scans are a subsequence of the
//! run's. Where the run's scan and the simulation's next scan differ, the run's index (the
//! position of every measured stamp, from the first pass over the run) says which one has no
//! twin: a simulated stamp still ahead in the run means the measured scan has none; any other
//! (behind, or not in the run at all) means the simulated one has none.
//!
//! The files carry the logger's clock; `check`'s marks are on the trajectory's time, GNSS
//! time, and so is the run's index where the run put its logger times on it ([`LoggerClock`]):
//! the files' times go through that mapping before they are looked up. Where it did not, the
//! logger is within 100 ms of GNSS time, or `check`'s report says why it could not tell.

use super::error::CompareError;
use super::report::LeftOut;
use crate::bag::scans::Scan;
use crate::reference::run::{LoggerClock, ScanIndex};
use hilrig_stamp::UtcNanos;
use std::collections::HashMap;
use std::iter::Peekable;
use std::path::Path;

/// A measured scan and its simulated twin.
pub(super) type Pair = (Scan, Scan);

/// The measured scans of a stream with their simulated twins from another, less those that
/// touch a mark of `left_out` (which counts them per mark).
pub(super) struct Pairs<'a, R: Iterator<Item = Scan>, S: Iterator<Item = Scan>> {
    real: R,
    sim: Peekable<S>,
    /// Position of each measured stamp in the run (the first, for a stamp seen twice).
    position: HashMap<i64, usize>,
    /// Measured scans taken so far.
    at: usize,
    left_out: &'a mut [LeftOut],
    /// The run's times of the files' logger times.
    clock: &'a LoggerClock,
    /// Pairs found (kept or left out).
    pub(super) paired: usize,
    /// The simulation's first and last stamp seen.
    sim_span: Option<(UtcNanos, UtcNanos)>,
}

impl<'a, R: Iterator<Item = Scan>, S: Iterator<Item = Scan>> Pairs<'a, R, S> {
    /// Pairs the scans of `real` (whose stamps `index` lists in file order, on the run's times
    /// that `clock` gives) with those of `sim`.
    pub(super) fn new(
        real: R,
        index: &[ScanIndex],
        sim: S,
        left_out: &'a mut [LeftOut],
        clock: &'a LoggerClock,
    ) -> Self {
        let mut position = HashMap::with_capacity(index.len());
        for (i, s) in index.iter().enumerate() {
            position.entry(s.stamp.0).or_insert(i);
        }
        Pairs {
            real,
            sim: sim.peekable(),
            position,
            at: 0,
            left_out,
            clock,
            paired: 0,
            sim_span: None,
        }
    }

    /// The next simulated scan, noting its stamp (on the run's times).
    fn next_sim(&mut self) -> Option<Scan> {
        let s = self.sim.next()?;
        let t = self.clock.gnss_time_of(s.stamp);
        self.sim_span = Some(match self.sim_span {
            None => (t, t),
            Some((a, _)) => (a, t),
        });
        Some(s)
    }

    /// The error to give when the streams are through: none paired at all, or every pair in a
    /// marked stretch. `real_span` is the run's first and last scan stamp (on its times).
    pub(super) fn finish_error(
        &mut self,
        kept: usize,
        (run_path, real_span): (&Path, Option<(UtcNanos, UtcNanos)>),
        sim_path: &Path,
    ) -> Option<CompareError> {
        if self.paired == 0 {
            // The rest of the simulation, for its span.
            while self.next_sim().is_some() {}
            let span = |s: Option<(UtcNanos, UtcNanos)>| {
                s.map_or("none".to_owned(), |(a, b)| {
                    format!(
                        "{} .. {}",
                        hilrig_stamp::civil::iso8601_millis(a),
                        hilrig_stamp::civil::iso8601_millis(b)
                    )
                })
            };
            return Some(CompareError::NotTwins {
                run: run_path.to_owned(),
                sim: sim_path.to_owned(),
                run_span: span(real_span),
                sim_span: span(self.sim_span),
            });
        }
        if kept == 0 {
            return Some(CompareError::NothingUsable {
                run: run_path.to_owned(),
                marks: self
                    .left_out
                    .iter()
                    .map(|l| format!("{} {:.1}-{:.1} s", l.mark.name, l.mark.from_s, l.mark.to_s))
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
        None
    }
}

/// Whether the measured scan touches a mark of `left_out` (each mark it touches counts it);
/// `clock` puts its times on the marks' (the run's).
pub(super) fn marked(left_out: &mut [LeftOut], r: &Scan, clock: &LoggerClock) -> bool {
    let (a, b) = r.span();
    let (a, b) = (clock.gnss_time_of(a), clock.gnss_time_of(b));
    let mut marked = false;
    for l in left_out.iter_mut() {
        let w = l.mark.window();
        if a <= w.1 && w.0 <= b {
            l.scans += 1;
            marked = true;
        }
    }
    marked
}

impl<R: Iterator<Item = Scan>, S: Iterator<Item = Scan>> Iterator for Pairs<'_, R, S> {
    type Item = Pair;

    fn next(&mut self) -> Option<Pair> {
        loop {
            let r = self.real.next()?;
            let here = self.at;
            self.at += 1;
            // Simulated scans without a twin at or after this measured scan are passed over.
            let twin = loop {
                let Some(s) = self.sim.peek() else {
                    break None;
                };
                if s.stamp == r.stamp {
                    break self.next_sim();
                }
                match self.position.get(&self.clock.gnss_time_of(s.stamp).0) {
                    // Its twin is still ahead: this measured scan has none.
                    Some(&p) if p > here => break None,
                    _ => {
                        self.next_sim();
                    }
                }
            };
            let Some(s) = twin else { continue };
            self.paired += 1;
            if marked(self.left_out, &r, self.clock) {
                continue;
            }
            return Some((r, s));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(t: i64) -> Scan {
        Scan {
            log_time: t as u64,
            publish_time: t as u64,
            stamp: UtcNanos(t),
            packets: Vec::new(),
        }
    }

    fn index(stamps: &[i64]) -> Vec<ScanIndex> {
        stamps
            .iter()
            .map(|&t| ScanIndex {
                stamp: UtcNanos(t),
                packets: 0,
                span: (UtcNanos(t), UtcNanos(t)),
            })
            .collect()
    }

    fn pair(real: &[i64], sim: &[i64]) -> (Vec<i64>, usize) {
        pair_on(real, sim, &LoggerClock::default(), 0)
    }

    /// Pairs files whose times are the logger's, `ahead` ns ahead of the run's (whose index
    /// `clock` puts on GNSS time).
    fn pair_on(real: &[i64], sim: &[i64], clock: &LoggerClock, ahead: i64) -> (Vec<i64>, usize) {
        let mut left_out: Vec<LeftOut> = Vec::new();
        let on_run: Vec<i64> = real.iter().map(|&t| t - ahead).collect();
        let mut p = Pairs::new(
            real.iter().map(|&t| scan(t)),
            &index(&on_run),
            sim.iter().map(|&t| scan(t)),
            &mut left_out,
            clock,
        );
        let got: Vec<i64> = p
            .by_ref()
            .map(|(r, s)| {
                assert_eq!(r.stamp, s.stamp);
                r.stamp.0
            })
            .collect();
        (got, p.paired)
    }

    /// A simulation that lacks scans, or holds scans the run does not, pairs every twin; the
    /// run's order need not be sorted by stamp (a clock step back), only shared.
    #[test]
    fn twins_are_found_in_a_subsequence_in_the_runs_order() {
        assert_eq!(pair(&[1, 2, 3, 4], &[1, 2, 3, 4]), (vec![1, 2, 3, 4], 4));
        assert_eq!(pair(&[1, 2, 3, 4], &[2, 4]), (vec![2, 4], 2));
        assert_eq!(pair(&[1, 2, 3, 4], &[0, 2, 9, 3, 5]), (vec![2, 3], 2));
        // Stamps that step back in the run (a re-synchronised clock).
        assert_eq!(pair(&[5, 6, 2, 3], &[5, 2, 3]), (vec![5, 2, 3], 3));
        assert_eq!(pair(&[1, 2], &[7, 8]), (vec![], 0));
        assert_eq!(pair(&[], &[1]), (vec![], 0));
    }

    /// Where the run's times were put on GNSS time (its logger 2.5 s ahead), the files' stamps,
    /// on the logger's clock, are looked up on the run's: a simulation without the first
    /// scans still pairs every twin (looked up unmapped, none would be found and every
    /// simulated scan passed over).
    #[test]
    fn twins_are_found_where_the_runs_times_were_put_on_gnss_time() {
        let ahead = 2_500_000_000;
        let clock = LoggerClock::put_on_gnss_time_with(
            crate::bag::clock_sync::ClockSync::of_model(0, ahead as f64, 0.0, [0.0; 3], 100),
        );
        let at = |k: &[i64]| -> Vec<i64> { k.iter().map(|k| ahead + k * 100_000_000).collect() };
        assert_eq!(
            pair_on(&at(&[1, 2, 3, 4]), &at(&[3, 4]), &clock, ahead),
            (at(&[3, 4]), 2)
        );
        assert_eq!(
            pair_on(&at(&[1, 2, 3, 4]), &at(&[1, 3]), &clock, ahead),
            (at(&[1, 3]), 2)
        );
    }
}

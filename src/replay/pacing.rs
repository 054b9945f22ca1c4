//! The player: items sent at their deadlines, with the lag of every send measured.
//!
//! Item `i` is due at `wall_start + (t_i - t_first) / speed`: an absolute deadline, so a late
//! send never delays the ones after it and nothing drifts over an hour-long file. A serial line
//! cannot carry bytes faster than its baud rate, so a piece of the GNSS stream is due no earlier
//! than the line is free again.

use super::load::{Payload, ReplayItem};
use super::now;
use super::sink::{Destinations, SinkError};
use hilrig_stamp::UtcNanos;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How to play.
#[derive(Clone, Copy, Debug)]
pub struct PlayOptions {
    /// Speed factor (2 = twice as fast); positive and finite.
    pub speed: f64,
    /// Start again at the end, until stopped.
    pub repeat: bool,
    /// Rewrite Velodyne timestamps and position packets to the present ([`now`]).
    pub now: bool,
    /// Baud rate of the serial line, which paces the GNSS bytes.
    pub baud: u32,
}

/// What a replay did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Played {
    /// Lag statistics of the items sent.
    pub pacing: Pacing,
    /// Items that had no destination.
    pub without_destination: u64,
    /// How far the serial line's baud rate held the GNSS stream back behind its recorded
    /// pace, at most (zero when the line kept up). The send lags are measured against the
    /// time the line was free, so this is where a baud rate too low for the recording shows.
    pub serial_behind: Duration,
}

/// Plays `items` (in time order) to `dest` until done, or forever with `repeat`, until `stop`.
pub fn play(
    items: &[ReplayItem],
    dest: &mut Destinations,
    options: &PlayOptions,
    stop: &AtomicBool,
) -> Result<Played, SinkError> {
    play_stream(|| items.iter().cloned(), dest, options, stop)
}

/// Plays the items `pass()` yields (in time order; a new pass for each `repeat`), so a file
/// can be streamed rather than held: item `i` is due at `wall_start + (t_i - t_first) / speed`.
/// Lags are kept in a histogram, so memory does not grow with the number of items either.
pub fn play_stream<I: Iterator<Item = ReplayItem>>(
    mut pass: impl FnMut() -> I,
    dest: &mut Destinations,
    options: &PlayOptions,
    stop: &AtomicBool,
) -> Result<Played, SinkError> {
    let mut lags = LagHistogram::default();
    let byte_time = Duration::from_secs_f64(10.0 / f64::from(options.baud));
    let mut skipped = 0u64;
    let mut serial_behind = Duration::ZERO;
    'outer: loop {
        let mut items = pass().peekable();
        let Some(first) = items.peek().map(|i| i.time) else {
            break;
        };
        let wall0 = Instant::now();
        let utc0 = UtcNanos::now();
        let mut serial_free = wall0;
        for item in items {
            if stop.load(Ordering::Relaxed) {
                break 'outer;
            }
            let offset = Duration::from_nanos(
                ((item.time.0 - first.0).max(0) as f64 / options.speed) as u64,
            );
            let mut deadline = wall0 + offset;
            if let Payload::Serial(b) = &item.payload {
                serial_behind = serial_behind.max(serial_free.saturating_duration_since(deadline));
                deadline = deadline.max(serial_free);
                serial_free = deadline + byte_time * b.len() as u32;
            }
            wait_until(deadline);
            let lag = Instant::now().saturating_duration_since(deadline);
            let Some(sink) = dest.for_payload(&item.payload) else {
                skipped += 1;
                continue;
            };
            if options.now {
                let at = UtcNanos(utc0.0 + offset.as_nanos() as i64);
                sink.send(&now::rewrite(&item.payload, at))?;
            } else {
                sink.send(&item.payload)?;
            }
            lags.push(lag.as_nanos() as i64);
        }
        if !options.repeat {
            break;
        }
    }
    dest.finish();
    Ok(Played {
        pacing: lags.pacing(),
        without_destination: skipped,
        serial_behind,
    })
}

/// Send lags in whole microseconds up to 100 ms, each larger one kept exactly (there are few:
/// a replay that late is broken anyway).
struct LagHistogram {
    counts: Vec<u64>,
    over: Vec<i64>,
    n: u64,
    max_ns: i64,
}

impl Default for LagHistogram {
    fn default() -> Self {
        LagHistogram {
            counts: vec![0; LAG_BUCKETS],
            over: Vec::new(),
            n: 0,
            max_ns: 0,
        }
    }
}

const LAG_BUCKETS: usize = 100_000;

impl LagHistogram {
    fn push(&mut self, ns: i64) {
        let us = (ns.max(0) / 1000) as usize;
        match self.counts.get_mut(us) {
            Some(c) => *c += 1,
            None => self.over.push(ns),
        }
        self.n += 1;
        self.max_ns = self.max_ns.max(ns);
    }

    /// The lag of rank `k` (0-based) in µs, to the microsecond below.
    fn rank_us(&self, k: u64) -> f64 {
        let mut seen = 0u64;
        for (us, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen > k {
                return us as f64;
            }
        }
        let mut over = self.over.clone();
        over.sort_unstable();
        over.get((k - seen) as usize)
            .map_or(0.0, |ns| *ns as f64 * 1e-3)
    }

    fn pacing(&self) -> Pacing {
        if self.n == 0 {
            return Pacing::default();
        }
        let q = |p: f64| self.rank_us(((self.n - 1) as f64 * p).round() as u64);
        Pacing {
            sent: self.n,
            p50_us: q(0.5),
            p99_us: q(0.99),
            max_us: self.max_ns as f64 * 1e-3,
        }
    }
}

/// A flag that Ctrl-C (SIGINT) or SIGTERM sets, for [`play`]'s `stop`.
pub fn stop_on_signals() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    std::thread::spawn(move || {
        if let Ok(rt) = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
        {
            rt.block_on(async {
                use tokio::signal::unix::{signal, SignalKind};
                let mut term = signal(SignalKind::terminate()).ok();
                let terminated = async {
                    match term.as_mut() {
                        Some(t) => {
                            t.recv().await;
                        }
                        None => std::future::pending::<()>().await,
                    }
                };
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = terminated => {}
                }
            });
        }
        flag.store(true, Ordering::SeqCst);
    });
    stop
}

/// Lag statistics of a replay (send time minus deadline).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Pacing {
    /// Items sent.
    pub sent: u64,
    /// Median lag, µs.
    pub p50_us: f64,
    /// 99th percentile lag, µs.
    pub p99_us: f64,
    /// Largest lag, µs.
    pub max_us: f64,
}

impl Pacing {
    /// From the lags of every send, nanoseconds.
    pub fn from_lags(mut lags: Vec<i64>) -> Pacing {
        if lags.is_empty() {
            return Pacing::default();
        }
        lags.sort_unstable();
        let q = |p: f64| lags[((lags.len() - 1) as f64 * p).round() as usize] as f64 * 1e-3;
        Pacing {
            sent: lags.len() as u64,
            p50_us: q(0.5),
            p99_us: q(0.99),
            max_us: lags[lags.len() - 1] as f64 * 1e-3,
        }
    }
}

/// Waits until `deadline`: sleeps until shortly before it, then spins (sub-millisecond accuracy
/// without burning a core between items).
pub fn wait_until(deadline: Instant) {
    const SPIN: Duration = Duration::from_micros(300);
    let now = Instant::now();
    if deadline > now + SPIN {
        std::thread::sleep(deadline - now - SPIN);
    }
    while Instant::now() < deadline {
        std::hint::spin_loop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::replay::sink::Sink;
    use std::sync::Mutex;

    /// A sink that keeps what it gets and when.
    struct Recorder(Arc<Mutex<Vec<(Instant, Payload)>>>);

    impl Sink for Recorder {
        fn send(&mut self, payload: &Payload) -> Result<(), SinkError> {
            self.0
                .lock()
                .unwrap()
                .push((Instant::now(), payload.clone()));
            Ok(())
        }
    }

    #[test]
    fn pacing_quantiles() {
        let p = Pacing::from_lags((1..=100).map(|x| x * 1000).collect());
        assert_eq!(p.sent, 100);
        assert_eq!(p.max_us, 100.0);
        assert!((p.p50_us - 51.0).abs() < 1.01 && (p.p99_us - 99.0).abs() < 1.01);
    }

    fn items() -> Vec<ReplayItem> {
        (0..20)
            .map(|i| ReplayItem {
                time: UtcNanos(1_000_000_000_000 + i * 5_000_000),
                payload: if i % 2 == 0 {
                    Payload::LidarData(vec![i as u8; 1206])
                } else {
                    Payload::Serial(vec![i as u8; 10])
                },
            })
            .collect()
    }

    /// Play options at 1x without `--now`.
    fn at_1x(repeat: bool, baud: u32) -> PlayOptions {
        PlayOptions {
            speed: 1.0,
            repeat,
            now: false,
            baud,
        }
    }

    /// Every item reaches its sink in order, none before its deadline; items of a kind without
    /// a destination are counted.
    #[test]
    fn items_reach_their_sink_in_order_and_not_early() {
        let got = Arc::new(Mutex::new(Vec::new()));
        let mut dest = Destinations {
            lidar_data: Some(Box::new(Recorder(got.clone()))),
            ..Destinations::default()
        };
        let options = at_1x(false, 115_200);
        let items = items();
        let start = Instant::now();
        let played = play(&items, &mut dest, &options, &AtomicBool::new(false)).unwrap();
        assert_eq!(played.pacing.sent, 10);
        assert_eq!(played.without_destination, 10);
        let got = got.lock().unwrap();
        let sent: Vec<&Payload> = got.iter().map(|g| &g.1).collect();
        let expected: Vec<&Payload> = items.iter().step_by(2).map(|i| &i.payload).collect();
        assert_eq!(sent, expected);
        for (k, (at, _)) in got.iter().enumerate() {
            let due = Duration::from_millis(10 * k as u64);
            assert!(at.duration_since(start) >= due, "item {k} sent early");
        }
    }

    /// A serial line at 1200 baud carries 120 bytes a second: ten 10-byte pieces due 10 ms
    /// apart cannot leave faster than one per 83 ms, so piece `k` leaves no earlier than
    /// 5 ms + k × 83.3 ms after the start (a lower bound: a slow machine only sends later).
    #[test]
    fn the_serial_stream_is_paced_at_the_baud_rate() {
        let got = Arc::new(Mutex::new(Vec::new()));
        let mut dest = Destinations {
            serial: Some(Box::new(Recorder(got.clone()))),
            ..Destinations::default()
        };
        let options = at_1x(false, 1200);
        let start = Instant::now();
        let played = play(&items(), &mut dest, &options, &AtomicBool::new(false)).unwrap();
        let piece = Duration::from_secs_f64(10.0 * 10.0 / 1200.0);
        // The last piece was due 90 ms after the first and waited for the line until 9 pieces
        // had left: 750 ms - 90 ms behind its recorded pace (whatever the machine's own lag).
        let behind = piece * 9 - Duration::from_millis(90);
        assert!(
            played.serial_behind.abs_diff(behind) < Duration::from_micros(10),
            "{:?} for {behind:?}",
            played.serial_behind
        );
        let got = got.lock().unwrap();
        assert_eq!(got.len(), 10);
        for (k, (at, _)) in got.iter().enumerate() {
            let due = Duration::from_millis(5) + piece * k as u32;
            assert!(
                at.duration_since(start) >= due,
                "piece {k} left before the line was free"
            );
        }
    }

    /// A stop flag that is already set sends nothing, even with `repeat`.
    #[test]
    fn a_stop_flag_ends_a_looping_replay() {
        let got = Arc::new(Mutex::new(Vec::new()));
        let mut dest = Destinations {
            lidar_data: Some(Box::new(Recorder(got.clone()))),
            ..Destinations::default()
        };
        let options = at_1x(true, 115_200);
        let played = play(&items(), &mut dest, &options, &AtomicBool::new(true)).unwrap();
        assert_eq!(played.pacing.sent, 0);
        assert!(got.lock().unwrap().is_empty());
    }
}

//! A run's centre hits kept on disk from one re-simulation to the next
//! ([`crate::sim::lidar::CentreHits`], why in `lidar/reuse.rs`): the gap workflow re-simulates
//! its validation runs in every round, and a round whose model casts the rays of a round
//! before traverses none of them again.
//!
//! On disk, not in memory, so that the workflow's memory does not grow with the runs' length:
//! four bytes a firing (a VLP-32C minute, 36 M firings: 144 MB) in a file of its own beside
//! the simulations, which the system removes however the process ends (unlinked once open).
//! The first re-simulation of the run writes a file, packet by packet in the run's order; the
//! later ones read it in the same order. Each packet's hits are used only where its rays hash
//! alike, so a file read by a model that moves the beams costs the reading, never a wrong
//! hit. A re-simulation whose first packets share the rays of no kept file in more than half
//! of them writes its own (the two most recently written or read are kept, [`KEPT_LOGS`]),
//! so that models casting two sets of rays each find theirs, and a third set (a candidate
//! that moves the beams) drops the set least recently used. A re-simulation that stops
//! half-way leaves no file (the next one writes it anew); a file that cannot be read is cast
//! around. Each reading reads at its own offset ([`KeptFile`]), so re-simulations of one run
//! may read its files side by side.

use super::lidar::{CentreHits, HitSlot};
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, PoisonError};

/// Logs kept per run: one for each set of rays its models cast. A study's rounds re-simulate
/// a run with the model so far and with that model and one effect more, and an effect can
/// change the rays: with an adaptive beam footprint a banked packet (VLS-128, HDL-64E) casts
/// the firing sequences around it as witnesses. With one log, every re-simulation after the
/// round that added beam divergence missed it; with one log a set, each finds its own.
const KEPT_LOGS: usize = 2;

/// The centre hits of one run, kept for its re-simulations.
#[derive(Debug, Default)]
pub struct HitLog {
    /// Where the files go (the system's temporary folder when `None`, which may be held in
    /// memory: a tmpfs).
    dir: Option<PathBuf>,
    /// The files of re-simulations that wrote every packet's hits, each with its number, the
    /// most recently written or read first.
    written: Mutex<Vec<(u64, File)>>,
    /// The number of the last file written.
    last: AtomicU64,
}

impl HitLog {
    /// A log whose files go to `dir` (the simulations' own folder: on the disk they go to).
    pub fn in_dir(dir: PathBuf) -> HitLog {
        HitLog {
            dir: Some(dir),
            ..HitLog::default()
        }
    }

    /// What a re-simulation of the run does with the log: reads the kept files where there
    /// are some (all of them for its first packets, then the one that fits more than half of
    /// those, or, where none does, writes a file of its own), else writes one. `None` when no
    /// file can be made (the re-simulation then casts every ray, as without a log).
    pub fn open(&self) -> Option<HitRun<'_>> {
        let kept: Vec<(u64, BufReader<KeptFile>)> = self
            .written
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .iter()
            .filter_map(|(id, f)| {
                let file = f.try_clone().ok()?;
                Some((*id, BufReader::new(KeptFile { file, at: 0 })))
            })
            .collect();
        let mode = if kept.is_empty() {
            Mode::Write(self.new_file()?)
        } else {
            Mode::Read {
                logs: kept,
                chosen: false,
            }
        };
        Some(HitRun {
            log: self,
            mode,
            hits: 0,
        })
    }

    fn new_file(&self) -> Option<BufWriter<File>> {
        let file = match &self.dir {
            Some(d) => tempfile::tempfile_in(d),
            None => tempfile::tempfile(),
        };
        match file {
            Ok(f) => Some(BufWriter::new(f)),
            Err(e) => {
                tracing::warn!("no file for the centre hits ({e}): every ray is cast");
                None
            }
        }
    }

    /// Puts the file `id` first (read or just written: the last to be dropped).
    fn to_front(&self, id: u64) {
        let mut written = self.written.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(i) = written.iter().position(|(k, _)| *k == id) {
            let f = written.remove(i);
            written.insert(0, f);
        }
    }
}

enum Mode {
    /// Reading kept files (each with its number): each one's hits offered for the first
    /// batch of packets; from the second on, only the one `chosen` (the others are dropped).
    Read {
        logs: Vec<(u64, BufReader<KeptFile>)>,
        chosen: bool,
    },
    Write(BufWriter<File>),
    /// Reading failed, or no file fitted and none could be made: cast the rest.
    Off,
}

/// One re-simulation's use of a [`HitLog`]: reading what a re-simulation before kept, or
/// writing it.
pub struct HitRun<'l> {
    log: &'l HitLog,
    mode: Mode,
    /// Packets whose hits this run wrote (a run that cast no centre ray, a dual-return
    /// VLS-128's whose footprints are cast whole, keeps no file).
    hits: u64,
}

impl HitRun<'_> {
    /// The slots of the run's next `n` packets: each with its kept hits (reading) or asking
    /// for them (writing; in the first batch of a reading also, in case no file fits).
    pub fn slots(&mut self, n: usize) -> Vec<HitSlot> {
        let mut slots: Vec<HitSlot> = (0..n).map(|_| HitSlot::default()).collect();
        match &mut self.mode {
            Mode::Read { logs, chosen } => {
                let read = slots.iter_mut().try_for_each(|s| {
                    s.keep = !*chosen;
                    for (_, r) in logs.iter_mut() {
                        s.given.push(read_one(r)?);
                    }
                    Ok::<(), std::io::Error>(())
                });
                if let Err(e) = read {
                    tracing::warn!("the kept centre hits end early ({e}): cast anew");
                    self.mode = Mode::Off;
                    slots.fill_with(HitSlot::default);
                }
            }
            Mode::Write(_) => {
                for s in &mut slots {
                    s.keep = true;
                }
            }
            Mode::Off => {}
        }
        slots
    }

    /// The slots of [`HitRun::slots`] after their packets were simulated: written, in order,
    /// when this re-simulation writes a file. After the first batch of a reading whose
    /// packets cast centre rays, the file whose rays more than half of those packets share is
    /// read on; where none is, this re-simulation writes its own (that batch's hits, cast or
    /// taken, and every packet's after).
    pub fn done(&mut self, slots: Vec<HitSlot>) {
        if let Mode::Read {
            logs,
            chosen: chosen @ false,
        } = &mut self.mode
        {
            // The packets that cast (or took) their centre rays, and per file how many of
            // those share its rays (every file that does, not only the one taken).
            let cast: Vec<&HitSlot> = slots.iter().filter(|s| s.rays.is_some()).collect();
            if cast.is_empty() {
                return;
            }
            let fits = |j: usize| {
                cast.iter()
                    .filter(|s| s.given.get(j).is_some_and(|g| Some(g.rays) == s.rays))
                    .count()
            };
            let took: Vec<usize> = (0..logs.len()).map(fits).collect();
            let best = (0..took.len()).max_by_key(|&j| (took[j], std::cmp::Reverse(j)));
            match best.filter(|&j| 2 * took[j] > cast.len()) {
                Some(j) => {
                    let log = logs.swap_remove(j);
                    self.log.to_front(log.0);
                    *logs = vec![log];
                    *chosen = true;
                    return;
                }
                None => {
                    tracing::info!(
                        "the kept centre hits fit at most {} of {} packets: kept anew",
                        took.iter().max().copied().unwrap_or(0),
                        cast.len()
                    );
                    self.mode = self.log.new_file().map_or(Mode::Off, Mode::Write);
                }
            }
        }
        let Mode::Write(w) = &mut self.mode else {
            return;
        };
        let empty = CentreHits::default();
        for s in &slots {
            let h = s
                .kept
                .as_ref()
                .or_else(|| s.used.and_then(|u| s.given.get(u)));
            self.hits += u64::from(h.is_some());
            if let Err(e) = write_one(w, h.unwrap_or(&empty)) {
                tracing::warn!("the centre hits cannot be kept ({e}): the next rounds cast");
                self.mode = Mode::Off;
                return;
            }
        }
    }

    /// The re-simulation wrote every packet, and some hits: its file is kept for the next
    /// ones, first, beside the most recently used other ([`KEPT_LOGS`]).
    pub fn finish(self) {
        if let Mode::Write(w) = self.mode {
            if self.hits == 0 {
                return;
            }
            if let Ok(f) = w.into_inner() {
                let id = self.log.last.fetch_add(1, Ordering::Relaxed) + 1;
                let mut written = self
                    .log
                    .written
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner);
                written.insert(0, (id, f));
                written.truncate(KEPT_LOGS);
            }
        }
    }
}

/// A kept file read from its start at an offset of its own. A cloned handle shares the
/// kernel's offset with every other clone of the file, so two re-simulations reading one
/// file through `read` would each skip what the other read (and a writer's last position
/// would be the readers' start); reading at an explicit offset leaves the handle's alone.
struct KeptFile {
    file: File,
    /// The next byte to read.
    at: u64,
}

impl Read for KeptFile {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        // (Unix only, like the campaigns' process groups: hilrig runs on Linux.)
        let n = std::os::unix::fs::FileExt::read_at(&self.file, buf, self.at)?;
        self.at += n as u64;
        Ok(n)
    }
}

/// One packet's hits: the rays' hash, the count, the primitives (little-endian).
fn write_one(w: &mut impl Write, h: &CentreHits) -> std::io::Result<()> {
    w.write_all(&h.rays.to_le_bytes())?;
    let n = u32::try_from(h.prims.len()).map_err(std::io::Error::other)?;
    w.write_all(&n.to_le_bytes())?;
    for p in &h.prims {
        w.write_all(&p.to_le_bytes())?;
    }
    Ok(())
}

/// The most primitives one packet's record can name (a packet plans at most a few hundred
/// firings; anything more is not a record this module wrote).
const MAX_PER_PACKET: u32 = 1 << 16;

fn read_one(r: &mut impl Read) -> std::io::Result<CentreHits> {
    let mut b8 = [0u8; 8];
    r.read_exact(&mut b8)?;
    let mut b4 = [0u8; 4];
    r.read_exact(&mut b4)?;
    let n = u32::from_le_bytes(b4);
    if n > MAX_PER_PACKET {
        return Err(std::io::Error::other(format!("{n} hits in one packet")));
    }
    let mut bytes = vec![0u8; 4 * n as usize];
    r.read_exact(&mut bytes)?;
    Ok(CentreHits {
        rays: u64::from_le_bytes(b8),
        prims: bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hits(k: u32) -> CentreHits {
        CentreHits {
            rays: u64::from(k) * 0x1234_5678_9abc,
            prims: (0..k).map(|i| i * 7 + k).collect(),
        }
    }

    /// The hits of packet `k` under the rays of set `set` (another set: other hashes).
    fn of(set: u32, k: u32) -> CentreHits {
        CentreHits {
            rays: hits(k + 2).rays ^ u64::from(set) << 48,
            ..hits(k + 2)
        }
    }

    /// One re-simulation of five packets (batches of three and two) whose rays are those of
    /// `set`: what the cast does with each slot (hashes the rays, takes the first given file's
    /// hits of the same hash, or casts and keeps where asked). Returns, per packet, the file
    /// position it took (`None`: cast).
    fn resim(log: &HitLog, set: u32) -> Vec<Option<usize>> {
        let mut run = log.open().unwrap();
        let mut took = Vec::new();
        for (from, n) in [(0u32, 3usize), (3, 2)] {
            let mut slots = run.slots(n);
            for (k, s) in slots.iter_mut().enumerate() {
                let mine = of(set, from + k as u32);
                s.rays = Some(mine.rays);
                s.used = s.given.iter().position(|g| *g == mine);
                if s.used.is_none() && s.keep {
                    s.kept = Some(mine);
                }
                took.push(s.used);
            }
            run.done(slots);
        }
        run.finish();
        took
    }

    /// Every record of the most recent file, in order.
    fn records(log: &HitLog, n: usize) -> Vec<CentreHits> {
        let mut run = log.open().unwrap();
        run.slots(n)
            .into_iter()
            .map(|s| s.given[0].clone())
            .collect()
    }

    /// A log written packet by packet reads back the same in every later run; a run that
    /// stopped before `finish` leaves none (the next one writes).
    #[test]
    fn a_written_log_reads_back_in_order_in_every_later_run() {
        let log = HitLog::default();
        let mut first = log.open().unwrap();
        let mut slots = first.slots(3);
        assert!(slots.iter().all(|s| s.keep && s.given.is_empty()));
        for (k, s) in slots.iter_mut().enumerate() {
            s.kept = (k != 1).then(|| hits(k as u32 + 2));
        }
        first.done(slots);
        let mut slots = first.slots(2);
        slots[0].kept = Some(hits(40));
        first.done(slots);
        // Not finished: nothing kept, the next run writes.
        drop(first);
        let mut w = log.open().unwrap();
        let mut s = w.slots(5);
        assert!(s.iter().all(|s| s.keep && s.given.is_empty()));
        for (k, slot) in s.iter_mut().enumerate() {
            slot.kept = (k != 1).then(|| hits(k as u32 + 2));
        }
        w.done(s);
        w.finish();
        for _ in 0..2 {
            let mut r = log.open().unwrap();
            let mut got = r.slots(5);
            for (k, s) in got.iter_mut().enumerate() {
                let want = if k == 1 {
                    CentreHits::default()
                } else {
                    hits(k as u32 + 2)
                };
                assert_eq!(s.given, vec![want], "packet {k}");
                // The first batch is also kept, in case no file fits it.
                assert!(s.keep);
                s.rays = Some(s.given[0].rays);
                s.used = Some(0);
            }
            r.done(got);
            // Past the end: nothing given, and no error.
            assert!(r.slots(2).iter().all(|s| s.given.is_empty() && !s.keep));
        }
    }

    /// Two re-simulations reading one kept file side by side, batch by batch in turn, each
    /// read every record in order: each reads at its own offset (cloned handles share the
    /// kernel's, and then each skipped what the other read). The records are larger than a
    /// read's buffer, so that each batch goes to the file.
    #[test]
    fn re_simulations_read_one_file_side_by_side() {
        let big = |k: u32| CentreHits {
            rays: u64::from(k),
            prims: (0..5000).map(|i| i * 3 + k).collect(),
        };
        let log = HitLog::default();
        let mut w = log.open().unwrap();
        let mut s = w.slots(6);
        for (k, slot) in s.iter_mut().enumerate() {
            slot.kept = Some(big(k as u32 + 1));
        }
        w.done(s);
        w.finish();
        let (mut a, mut b) = (log.open().unwrap(), log.open().unwrap());
        let mut seen = (Vec::new(), Vec::new());
        for _ in 0..3 {
            seen.0.extend(a.slots(2).into_iter().map(|s| s.given));
            seen.1.extend(b.slots(2).into_iter().map(|s| s.given));
        }
        let want: Vec<Vec<CentreHits>> = (1..=6).map(|k| vec![big(k)]).collect();
        assert_eq!(seen.0, want);
        assert_eq!(seen.1, want);
    }

    /// A model that casts other rays (an effect that adds witness sequences) writes a file of
    /// its own when no kept one fits more than half of its first packets, and from then on
    /// each set of rays finds its own file, whichever ran last; a third set (a candidate that
    /// moves the beams) replaces the file least recently used.
    #[test]
    fn each_set_of_rays_finds_its_own_file() {
        let log = HitLog::default();
        let (mine, first) = (
            vec![Some(0); 5],
            [vec![Some(1); 3], vec![Some(0); 2]].concat(),
        );
        assert_eq!(resim(&log, 0), vec![None; 5], "the first run casts");
        assert_eq!(resim(&log, 0), mine, "the same rays take every hit");
        // Other rays: nothing fits; the run writes its own file (its first batch included).
        assert_eq!(resim(&log, 1), vec![None; 5]);
        assert_eq!(
            records(&log, 5),
            (0..5).map(|k| of(1, k)).collect::<Vec<_>>()
        );
        // Each set takes its own: the other set's file is first (the most recently used).
        for set in [0, 1, 0] {
            assert_eq!(resim(&log, set), first, "set {set}");
        }
        // A third set is written; the file of set 1, least recently used, is dropped.
        assert_eq!(resim(&log, 2), vec![None; 5]);
        assert_eq!(
            resim(&log, 0),
            first,
            "set 0's file was used last before set 2's"
        );
        assert_eq!(resim(&log, 1), vec![None; 5], "set 1's file was dropped");
    }

    /// The file that fits more than half of the first batch's packets is read on; at half or
    /// less, the run writes its own file: the first batch's hits, those taken and those cast,
    /// then every packet's, in order. Packets that cast no centre ray count for neither.
    #[test]
    fn a_file_is_read_on_when_it_fits_more_than_half_of_the_first_packets() {
        for (fitting, of_first, not_cast, read_on) in [
            (3usize, 3usize, 0usize, true),
            (2, 3, 0, true),
            (2, 4, 0, false),
            (1, 3, 0, false),
            (2, 3, 1, true),
        ] {
            let what = format!("{fitting} of {of_first} fit, {not_cast} not cast");
            let log = HitLog::default();
            for set in [0, 0] {
                // Five packets kept: enough for the first batch here.
                resim(&log, set);
            }
            let mut run = log.open().unwrap();
            let mut slots = run.slots(of_first + not_cast);
            for (k, s) in slots.iter_mut().enumerate().take(of_first) {
                if k < fitting {
                    s.rays = Some(s.given[0].rays);
                    s.used = Some(0);
                } else {
                    let h = of(1, k as u32);
                    s.rays = Some(h.rays);
                    s.kept = Some(h);
                }
            }
            run.done(slots);
            let mut next = run.slots(1);
            assert_eq!(
                next.iter().all(|s| s.given.len() == 1 && !s.keep),
                read_on,
                "{what}"
            );
            assert_eq!(
                next.iter().all(|s| s.given.is_empty() && s.keep),
                !read_on,
                "{what}"
            );
            if !read_on {
                next[0].kept = Some(of(1, 99));
                run.done(next);
                run.finish();
                let mut want: Vec<CentreHits> = (0..of_first as u32)
                    .map(|k| {
                        if (k as usize) < fitting {
                            of(0, k)
                        } else {
                            of(1, k)
                        }
                    })
                    .collect();
                want.extend((0..not_cast).map(|_| CentreHits::default()));
                want.push(of(1, 99));
                assert_eq!(records(&log, want.len()), want, "{what}");
            }
        }
    }

    /// A re-simulation that casts no centre ray (a dual-return VLS-128's footprints are cast
    /// whole) decides nothing, writes no file and drops none.
    #[test]
    fn a_run_that_casts_no_centre_ray_keeps_no_file_and_drops_none() {
        let log = HitLog::default();
        let mut run = log.open().unwrap();
        let slots = run.slots(3);
        run.done(slots);
        run.finish();
        assert_eq!(resim(&log, 0), vec![None; 5], "nothing was kept");
        for _ in 0..3 {
            let mut run = log.open().unwrap();
            let slots = run.slots(3);
            run.done(slots);
            assert!(run.slots(2).iter().all(|s| s.given.len() == 1 && s.keep));
            run.finish();
        }
        assert_eq!(
            resim(&log, 0),
            vec![Some(0); 5],
            "set 0's file is still there"
        );
    }
}

//! A run's centre hits kept on disk from one re-simulation to the next
//! ([`crate::sim::lidar::CentreHits`], why in `lidar/reuse.rs`): the gap workflow re-simulates
//! its validation runs in every round, and a round whose model casts the rays of the round
//! before traverses none of them again.
//!
//! On disk, not in memory, so that the workflow's memory does not grow with the runs' length:
//! four bytes a firing (a VLP-32C minute, 36 M firings: 144 MB) in a file of its own beside
//! the simulations, which the system removes however the process ends (unlinked once open). The first re-simulation of the run writes it,
//! packet by packet in the run's order; the later ones read it in the same order. Each packet's
//! hits are used only where its rays hash alike, so a log read by a model that moves the beams
//! costs the reading, never a wrong hit. A re-simulation that stops half-way leaves no log
//! (the next one writes it anew); a log that cannot be read is cast around.

use super::lidar::{CentreHits, HitSlot};
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, Write};
use std::path::PathBuf;
use std::sync::{Mutex, PoisonError};

/// The centre hits of one run, kept for its re-simulations (one at a time).
#[derive(Debug, Default)]
pub struct HitLog {
    /// Where the file goes (the system's temporary folder when `None`, which may be held in
    /// memory: a tmpfs).
    dir: Option<PathBuf>,
    /// The file of a re-simulation that wrote every packet's hits.
    written: Mutex<Option<File>>,
}

impl HitLog {
    /// A log whose file goes to `dir` (the simulations' own folder: on the disk they go to).
    pub fn in_dir(dir: PathBuf) -> HitLog {
        HitLog {
            dir: Some(dir),
            written: Mutex::default(),
        }
    }

    /// What a re-simulation of the run does with the log: reads it where one was written,
    /// else writes it. `None` when the file cannot be made (the re-simulation then casts
    /// every ray, as without a log).
    pub fn open(&self) -> Option<HitRun<'_>> {
        let written = self
            .written
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .as_ref()
            .and_then(|f| f.try_clone().ok());
        let mode = match written {
            Some(mut f) => {
                f.rewind().ok()?;
                Mode::Read(BufReader::new(f))
            }
            None => {
                let file = match &self.dir {
                    Some(d) => tempfile::tempfile_in(d),
                    None => tempfile::tempfile(),
                };
                match file {
                    Ok(f) => Mode::Write(BufWriter::new(f)),
                    Err(e) => {
                        tracing::warn!("no file for the centre hits ({e}): every ray is cast");
                        return None;
                    }
                }
            }
        };
        Some(HitRun { log: self, mode })
    }
}

enum Mode {
    Read(BufReader<File>),
    Write(BufWriter<File>),
    /// Reading failed: cast the rest.
    Off,
}

/// One re-simulation's use of a [`HitLog`]: reading what a re-simulation before kept, or
/// writing it.
pub struct HitRun<'l> {
    log: &'l HitLog,
    mode: Mode,
}

impl HitRun<'_> {
    /// The slots of the run's next `n` packets: each with its kept hits (reading) or asking
    /// for them (writing).
    pub fn slots(&mut self, n: usize) -> Vec<HitSlot> {
        let mut slots: Vec<HitSlot> = (0..n).map(|_| HitSlot::default()).collect();
        match &mut self.mode {
            Mode::Read(r) => {
                for s in &mut slots {
                    match read_one(r) {
                        Ok(h) => s.given = Some(h),
                        Err(e) => {
                            tracing::warn!("the kept centre hits end early ({e}): cast anew");
                            self.mode = Mode::Off;
                            break;
                        }
                    }
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
    /// when this re-simulation writes the log.
    pub fn done(&mut self, slots: Vec<HitSlot>) {
        let Mode::Write(w) = &mut self.mode else {
            return;
        };
        let empty = CentreHits::default();
        for s in &slots {
            if let Err(e) = write_one(w, s.kept.as_ref().unwrap_or(&empty)) {
                tracing::warn!("the centre hits cannot be kept ({e}): the next rounds cast");
                self.mode = Mode::Off;
                return;
            }
        }
    }

    /// The re-simulation wrote every packet: the log is kept for the next ones.
    pub fn finish(self) {
        if let Mode::Write(w) = self.mode {
            if let Ok(f) = w.into_inner() {
                *self
                    .log
                    .written
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner) = Some(f);
            }
        }
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

    /// A log written packet by packet reads back the same in every later run; a run that
    /// stopped before `finish` leaves none (the next one writes).
    #[test]
    fn a_written_log_reads_back_in_order_in_every_later_run() {
        let log = HitLog::default();
        let mut first = log.open().unwrap();
        let mut slots = first.slots(3);
        assert!(slots.iter().all(|s| s.keep && s.given.is_none()));
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
        assert!(s.iter().all(|s| s.keep && s.given.is_none()));
        for (k, slot) in s.iter_mut().enumerate() {
            slot.kept = (k != 1).then(|| hits(k as u32 + 2));
        }
        w.done(s);
        w.finish();
        for _ in 0..2 {
            let mut r = log.open().unwrap();
            let got = r.slots(5);
            assert!(got.iter().all(|s| !s.keep));
            for (k, s) in got.iter().enumerate() {
                let want = if k == 1 {
                    CentreHits::default()
                } else {
                    hits(k as u32 + 2)
                };
                assert_eq!(s.given.as_ref(), Some(&want), "packet {k}");
            }
            // Past the end: nothing given, and no error.
            assert!(r.slots(2).iter().all(|s| s.given.is_none()));
        }
    }
}

//! The recorded lidar scans (`/velodyne_packets`) as re-simulation and comparison read them:
//! each scan's stamps and its packets' bytes, and the sensor time of a packet.
//!
//! A recording is read scan by scan ([`ScanStream`]): a minute of a 128-beam sensor is
//! gigabytes once its chunks are uncompressed, so every step that walks the scans holds a few
//! of them at a time, never the file.

use super::cdr::CdrReader;
use super::read::{read, read_stream, Event, Message, ReadError};
use super::topics;
use hilrig_stamp::UtcNanos;
use hilrig_velodyne::DATA_PACKET_SIZE;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver};

/// One `/velodyne_packets` message.
#[derive(Clone, Debug)]
pub struct Scan {
    /// The message's log time, ns.
    pub log_time: u64,
    /// The message's publish time, ns.
    pub publish_time: u64,
    /// The scan header's stamp.
    pub stamp: UtcNanos,
    /// Every packet with its receive stamp.
    pub packets: Vec<(UtcNanos, [u8; DATA_PACKET_SIZE])>,
}

impl Scan {
    /// Its first and last packet's receive stamps (the scan's stamp for a scan without
    /// packets).
    pub fn span(&self) -> (UtcNanos, UtcNanos) {
        let last = self.packets.last().map_or(self.stamp, |p| p.0);
        (self.stamp.min(last), self.stamp.max(last))
    }
}

/// A `/velodyne_packets` message as a [`Scan`]; `None` for other topics, an error naming the
/// topic for a scan that does not decode.
fn scan_of(m: &Message<'_>) -> Result<Option<Scan>, ReadError> {
    if m.channel.topic != topics::VELODYNE_PACKETS {
        return Ok(None);
    }
    let bad = || ReadError::Undecodable {
        topic: m.channel.topic.clone(),
    };
    let mut c = CdrReader::new(m.data).ok_or_else(bad)?;
    let stamp = c.header().ok_or_else(bad)?;
    let n = c.u32().ok_or_else(bad)?;
    let mut packets = Vec::with_capacity((n as usize).min(m.data.len() / DATA_PACKET_SIZE));
    for _ in 0..n {
        let t = c.time().ok_or_else(bad)?;
        let b = c.bytes(DATA_PACKET_SIZE).ok_or_else(bad)?;
        let mut a = [0u8; DATA_PACKET_SIZE];
        a.copy_from_slice(b);
        packets.push((t, a));
    }
    Ok(Some(Scan {
        log_time: m.log_time,
        publish_time: m.publish_time,
        stamp,
        packets,
    }))
}

/// The scans of an MCAP's bytes, in file order, and what stopped the reading early (damage), if
/// anything. A scan that does not decode is an error naming the topic. Holds every scan: for
/// files of any size, [`ScanStream`].
pub fn read_scans(bytes: &[u8]) -> (Vec<Scan>, Option<String>) {
    let mut scans = Vec::new();
    let damage = read(bytes, &mut |e| {
        if let Event::Message(m) = e {
            scans.extend(scan_of(&m)?);
        }
        Ok(())
    })
    .err()
    .map(|e| e.to_string());
    (scans, damage)
}

/// Why a recording's scans cannot be read at all.
#[derive(Debug, thiserror::Error)]
pub enum ScanStreamError {
    /// The file cannot be opened.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// It is no MCAP.
    #[error("{}: not an MCAP file", .0.display())]
    NotMcap(PathBuf),
}

/// Scans read ahead of the consumer: enough to keep a batch of scans on every core busy while
/// the reader decompresses the next chunk, few enough to stay a few megabytes.
const READ_AHEAD_SCANS: usize = 8;

/// The scans of a recording file in file order, read on a thread of their own (decompressing
/// the next chunk while the caller works on the last scans) and handed over one at a time, a
/// few ahead at most: memory does not grow with the file. After the last scan, [`finish`]
/// says what stopped the reading early (damage), if anything.
///
/// [`finish`]: ScanStream::finish
pub struct ScanStream {
    rx: Option<Receiver<Scan>>,
    reader: Option<std::thread::JoinHandle<Option<String>>>,
}

impl ScanStream {
    /// Starts reading the scans of the MCAP file at `path`.
    pub fn open(path: &Path) -> Result<ScanStream, ScanStreamError> {
        let io = |source| ScanStreamError::Io {
            path: path.to_owned(),
            source,
        };
        let mut file = std::fs::File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        let mut magic = [0u8; 8];
        use std::io::{Read, Seek};
        if file.read_exact(&mut magic).is_err() || magic[..] != mcap::MAGIC[..] {
            return Err(ScanStreamError::NotMcap(path.to_owned()));
        }
        file.rewind().map_err(io)?;
        let (tx, rx) = sync_channel(READ_AHEAD_SCANS);
        let reader = std::thread::Builder::new()
            .name("scan reader".into())
            .spawn(move || {
                let src = std::io::BufReader::with_capacity(1 << 20, file);
                let result = read_stream(src, len, &mut |e| {
                    if let Event::Message(m) = e {
                        if let Some(scan) = scan_of(&m)? {
                            tx.send(scan).map_err(|_| ReadError::Stopped)?;
                        }
                    }
                    Ok(())
                });
                match result {
                    Ok(()) | Err(ReadError::Stopped) => None,
                    Err(e) => Some(e.to_string()),
                }
            })
            .map_err(io)?;
        Ok(ScanStream {
            rx: Some(rx),
            reader: Some(reader),
        })
    }

    /// What stopped the reading early (damage), if anything; scans not taken yet are dropped.
    pub fn finish(mut self) -> Option<String> {
        self.stop()
    }

    fn stop(&mut self) -> Option<String> {
        // The receiver goes first, so that a reader waiting to hand over a scan stops.
        self.rx = None;
        self.reader.take().and_then(|r| {
            r.join()
                .unwrap_or_else(|_| Some("the scan reader failed".into()))
        })
    }
}

impl Iterator for ScanStream {
    type Item = Scan;
    fn next(&mut self) -> Option<Scan> {
        self.rx.as_ref()?.recv().ok()
    }
}

impl Drop for ScanStream {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The sensor time of a packet stamp (µs past the hour) near `near` (the recorder's time of it).
pub fn sensor_time(timestamp_us: u32, near: UtcNanos) -> UtcNanos {
    let hour = 3_600_000_000_000i64;
    let t = near.hour_floor().0 + i64::from(timestamp_us) * 1000;
    if t - near.0 > hour / 2 {
        UtcNanos(t - hour)
    } else if near.0 - t > hour / 2 {
        UtcNanos(t + hour)
    } else {
        UtcNanos(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drive across the full hour: a packet stamped 0.1 s past the hour but recorded (scan
    /// time) 0.1 s before it belongs to the new hour, and the other way round; both directions
    /// are needed, or the packets after the hour are cast an hour away from the trajectory.
    #[test]
    fn sensor_times_follow_the_recording_across_the_full_hour() {
        let s = 1_000_000_000i64;
        let ten = UtcNanos(1_795_356_000 * s - 1_795_356_000 * s % (3600 * s) + 3600 * s);
        // 0.1 s past ten, recorded at 9:59:59.9.
        let near = UtcNanos(ten.0 - s / 10);
        assert_eq!(sensor_time(100_000, near), UtcNanos(ten.0 + s / 10));
        // 0.1 s before ten (3599.9 s past nine), recorded at 10:00:00.1.
        let near = UtcNanos(ten.0 + s / 10);
        assert_eq!(sensor_time(3_599_900_000, near), UtcNanos(ten.0 - s / 10));
        // Within the hour: as stamped.
        let near = UtcNanos(ten.0 + 1800 * s);
        assert_eq!(sensor_time(1_800_000_000, near), UtcNanos(ten.0 + 1800 * s));
    }
}

#[cfg(test)]
mod stream_tests {
    use super::*;
    use crate::bag::{msgs, BagOptions, BagWriter};

    /// A recording of `n` scans of `k` packets each (packet bytes tell scan and packet apart).
    fn recording(dir: &Path, n: usize, k: usize) -> PathBuf {
        let path = dir.join("scans.mcap");
        let mut bag = BagWriter::create(&path, &BagOptions::default()).unwrap();
        for s in 0..n {
            let t = UtcNanos(1_800_000_000_000_000_000 + s as i64 * 100_000_000);
            let packets: Vec<[u8; DATA_PACKET_SIZE]> = (0..k)
                .map(|p| {
                    let mut b = [0u8; DATA_PACKET_SIZE];
                    b[0] = s as u8;
                    b[1] = p as u8;
                    b
                })
                .collect();
            let list: Vec<(UtcNanos, &[u8; DATA_PACKET_SIZE])> = packets
                .iter()
                .enumerate()
                .map(|(p, b)| (UtcNanos(t.0 + p as i64 * 1000), b))
                .collect();
            let cdr = msgs::velodyne_scan(t, "velodyne", &list);
            bag.write(
                topics::VELODYNE_PACKETS,
                &msgs::velodyne_scan_type(),
                t,
                t,
                &cdr,
            )
            .unwrap();
            // Another topic between the scans.
            bag.write("/x", &msgs::can_frame_type(), t, t, &[0u8; 16])
                .unwrap();
        }
        bag.finish().unwrap();
        path
    }

    /// The stream hands over exactly what reading the whole file gives, in order, however many
    /// scans the file holds beyond the read-ahead.
    #[test]
    fn the_stream_gives_every_scan_of_the_file_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = recording(dir.path(), 3 * READ_AHEAD_SCANS + 5, 7);
        let (whole, damage) = read_scans(&std::fs::read(&path).unwrap());
        assert!(damage.is_none());
        let mut stream = ScanStream::open(&path).unwrap();
        let streamed: Vec<Scan> = stream.by_ref().collect();
        assert_eq!(stream.finish(), None);
        assert_eq!(streamed.len(), whole.len());
        for (a, b) in streamed.iter().zip(&whole) {
            assert_eq!(
                (a.stamp, a.log_time, a.publish_time),
                (b.stamp, b.log_time, b.publish_time)
            );
            assert_eq!(a.packets, b.packets);
        }
    }

    /// A consumer that stops early does not leave the reader waiting (the test would hang), and
    /// that is not damage; a cut file's scans come up to the cut, then the damage.
    #[test]
    fn stopping_early_is_not_damage_and_a_cut_file_says_where_it_ends() {
        let dir = tempfile::tempdir().unwrap();
        let path = recording(dir.path(), 4 * READ_AHEAD_SCANS, 3);
        let mut stream = ScanStream::open(&path).unwrap();
        assert_eq!(stream.by_ref().take(2).count(), 2);
        assert_eq!(stream.finish(), None);
        drop(ScanStream::open(&path).unwrap());

        let bytes = std::fs::read(&path).unwrap();
        let cut = dir.path().join("cut.mcap");
        std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
        let (whole, damage) = read_scans(&bytes[..bytes.len() / 2]);
        let mut stream = ScanStream::open(&cut).unwrap();
        assert_eq!(stream.by_ref().count(), whole.len());
        let d = stream.finish().expect("damage");
        assert_eq!(Some(&d), damage.as_ref());

        std::fs::write(&cut, b"not an mcap at all").unwrap();
        assert!(matches!(
            ScanStream::open(&cut),
            Err(ScanStreamError::NotMcap(_))
        ));
        assert!(matches!(
            ScanStream::open(&dir.path().join("missing.mcap")),
            Err(ScanStreamError::Io { .. })
        ));
    }
}

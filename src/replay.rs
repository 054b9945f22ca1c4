//! `hilrig replay`: a recording, capture or re-simulation played back to a device under test at
//! the original pace.
//!
//! The schedule is pure: every item has a time in the file; item `i` is due at
//! `wall_start + (t_i - t_first) / speed`, an absolute deadline, so errors never accumulate over
//! long runs. The sender sleeps until shortly before a deadline and spins the rest, which keeps
//! the lag (send time minus deadline) in the microseconds; the lag of every send is kept and its
//! p50, p99 and maximum are reported at the end.

use hilrig_capture::demux::{Demux, Packet};
use hilrig_capture::{CanFrame, CaptureReader};
use hilrig_stamp::UtcNanos;
use std::path::Path;
use std::time::{Duration, Instant};

/// What to send.
#[derive(Clone, Debug, PartialEq)]
pub enum Payload {
    /// A Velodyne data packet (UDP).
    LidarData(Vec<u8>),
    /// A Velodyne position packet (UDP).
    LidarPosition(Vec<u8>),
    /// Bytes of the GNSS serial stream.
    Serial(Vec<u8>),
    /// A CAN frame.
    Can(CanFrame),
}

/// One scheduled item.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplayItem {
    /// Time in the file (capture time or MCAP log time).
    pub time: UtcNanos,
    /// What to send.
    pub payload: Payload,
}

/// Why a file cannot be replayed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// Reading failed.
    #[error("{path}: {what}")]
    Input {
        /// The file.
        path: String,
        /// What went wrong.
        what: String,
    },
}

/// Reads a capture (pcap/pcapng) or an MCAP recording into a time-ordered schedule.
///
/// Captures stream in file order; an MCAP's messages are collected and sorted by log time (the
/// packets of a VelodyneScan at their own stamps), so memory is proportional to the recording.
/// A capture that breaks off part way is an error here; [`load_partial`] keeps what came before.
pub fn load(
    path: &Path,
    data_port: u16,
    position_port: u16,
) -> Result<Vec<ReplayItem>, ReplayError> {
    match load_partial(path, data_port, position_port)? {
        (items, None) => Ok(items),
        (_, Some(e)) => Err(e),
    }
}

/// Like [`load`], but a capture that is cut off or damaged part way (a drive log whose disk
/// filled up) still gives every item before the damage, with the error beside it: the lab
/// can replay what was recorded and is told what was not.
pub fn load_partial(
    path: &Path,
    data_port: u16,
    position_port: u16,
) -> Result<(Vec<ReplayItem>, Option<ReplayError>), ReplayError> {
    let err = |what: String| ReplayError::Input {
        path: path.display().to_string(),
        what,
    };
    let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
    if bytes.starts_with(mcap::MAGIC) {
        return load_mcap(&bytes).map(|v| (v, None)).map_err(err);
    }
    let mut d = Demux::new(
        CaptureReader::new(std::io::Cursor::new(bytes)).map_err(|e| err(e.to_string()))?,
    );
    let mut out = Vec::new();
    while let Some(item) = d.next_item() {
        let item = match item {
            Ok(i) => i,
            Err(e) => return Ok((out, Some(err(e.to_string())))),
        };
        let payload = match item.packet {
            Packet::Udp { dst, payload, .. }
                if dst.port() == data_port
                    && payload.len() == hilrig_velodyne::DATA_PACKET_SIZE =>
            {
                Payload::LidarData(payload.to_vec())
            }
            Packet::Udp { dst, payload, .. }
                if dst.port() == position_port
                    && payload.len() == hilrig_velodyne::POSITION_PACKET_SIZE =>
            {
                Payload::LidarPosition(payload.to_vec())
            }
            Packet::Udp { .. } => continue,
            Packet::Serial(b) => Payload::Serial(b.to_vec()),
            Packet::Can(f) => Payload::Can(f),
        };
        out.push(ReplayItem {
            time: item.time,
            payload,
        });
    }
    Ok((out, None))
}

/// A minimal CDR reader for the recorder's own message layouts.
struct Cdr<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Cdr<'a> {
    fn new(b: &'a [u8]) -> Option<Self> {
        (b.len() >= 4).then_some(Cdr { b, pos: 4 })
    }
    fn align(&mut self, n: usize) {
        let rel = self.pos - 4;
        self.pos += (n - rel % n) % n;
    }
    fn u32(&mut self) -> Option<u32> {
        self.align(4);
        let v = self.b.get(self.pos..self.pos + 4)?;
        self.pos += 4;
        Some(u32::from_le_bytes([v[0], v[1], v[2], v[3]]))
    }
    fn time(&mut self) -> Option<UtcNanos> {
        let s = self.u32()? as i32;
        let n = self.u32()?;
        Some(UtcNanos::from_secs_nanos(i64::from(s), n))
    }
    fn bytes(&mut self, n: usize) -> Option<&'a [u8]> {
        let v = self.b.get(self.pos..self.pos.checked_add(n)?)?;
        self.pos += n;
        Some(v)
    }
    fn string(&mut self) -> Option<&'a str> {
        let n = self.u32()? as usize;
        let s = self.bytes(n)?;
        std::str::from_utf8(s.strip_suffix(&[0]).unwrap_or(s)).ok()
    }
    fn header(&mut self) -> Option<UtcNanos> {
        let t = self.time()?;
        self.string()?;
        Some(t)
    }
}

fn load_mcap(bytes: &[u8]) -> Result<Vec<ReplayItem>, String> {
    let stream =
        mcap::MessageStream::new_with_options(bytes, mcap::read::Options::IgnoreEndMagic.into())
            .map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    for m in stream {
        let m = m.map_err(|e| e.to_string())?;
        let t = UtcNanos(m.log_time as i64);
        let bad = || format!("{}: a message does not decode as its type", m.channel.topic);
        match m.channel.topic.as_str() {
            crate::record::topics::VELODYNE_PACKETS => {
                let mut c = Cdr::new(&m.data).ok_or_else(bad)?;
                c.header().ok_or_else(bad)?;
                let n = c.u32().ok_or_else(bad)?;
                for _ in 0..n {
                    let stamp = c.time().ok_or_else(bad)?;
                    let data = c.bytes(hilrig_velodyne::DATA_PACKET_SIZE).ok_or_else(bad)?;
                    out.push(ReplayItem {
                        time: stamp,
                        payload: Payload::LidarData(data.to_vec()),
                    });
                }
            }
            crate::record::topics::VELODYNE_POSITION | crate::record::topics::GNSS_UBX => {
                let mut c = Cdr::new(&m.data).ok_or_else(bad)?;
                c.header().ok_or_else(bad)?;
                let n = c.u32().ok_or_else(bad)? as usize;
                let data = c.bytes(n).ok_or_else(bad)?.to_vec();
                let payload = if m.channel.topic == crate::record::topics::VELODYNE_POSITION {
                    Payload::LidarPosition(data)
                } else {
                    Payload::Serial(data)
                };
                out.push(ReplayItem { time: t, payload });
            }
            crate::record::topics::GNSS_NMEA => {
                let mut c = Cdr::new(&m.data).ok_or_else(bad)?;
                c.header().ok_or_else(bad)?;
                let s = c.string().ok_or_else(bad)?;
                out.push(ReplayItem {
                    time: t,
                    payload: Payload::Serial(format!("{s}\r\n").into_bytes()),
                });
            }
            crate::record::topics::CAN_FRAMES
                if m.channel
                    .schema
                    .as_ref()
                    .is_some_and(|s| s.name == "can_msgs/msg/Frame") =>
            {
                let mut c = Cdr::new(&m.data).ok_or_else(bad)?;
                c.header().ok_or_else(bad)?;
                let id = c.u32().ok_or_else(bad)?;
                let flags = c.bytes(3).ok_or_else(bad)?;
                let dlc = c.bytes(1).ok_or_else(bad)?[0];
                let data = c.bytes(8).ok_or_else(bad)?;
                let (rtr, ext, error) = (flags[0] != 0, flags[1] != 0, flags[2] != 0);
                let f = if rtr {
                    CanFrame::new_remote(id, ext, dlc)
                } else {
                    CanFrame::new(id, ext, &data[..usize::from(dlc.min(8))])
                };
                if let Some(mut f) = f {
                    f.error = error;
                    out.push(ReplayItem {
                        time: t,
                        payload: Payload::Can(f),
                    });
                }
            }
            _ => {}
        }
    }
    out.sort_by_key(|i| i.time);
    Ok(out)
}

/// Keeps items between `start` and `end` seconds after the first item.
pub fn window(items: Vec<ReplayItem>, start_s: Option<f64>, end_s: Option<f64>) -> Vec<ReplayItem> {
    let Some(first) = items.first().map(|i| i.time) else {
        return items;
    };
    let from = start_s.map_or(i64::MIN, |s| first.0 + (s * 1e9) as i64);
    let to = end_s.map_or(i64::MAX, |s| first.0 + (s * 1e9) as i64);
    items
        .into_iter()
        .filter(|i| i.time.0 >= from && i.time.0 <= to)
        .collect()
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

    #[test]
    fn window_keeps_the_requested_seconds() {
        let items: Vec<ReplayItem> = (0..10)
            .map(|i| ReplayItem {
                time: UtcNanos(1_000_000_000 * i),
                payload: Payload::Serial(vec![i as u8]),
            })
            .collect();
        let w = window(items, Some(2.0), Some(4.5));
        assert_eq!(
            w.iter()
                .map(|i| i.time.0 / 1_000_000_000)
                .collect::<Vec<_>>(),
            vec![2, 3, 4]
        );
    }

    #[test]
    fn pacing_quantiles() {
        let p = Pacing::from_lags((1..=100).map(|x| x * 1000).collect());
        assert_eq!(p.sent, 100);
        assert_eq!(p.max_us, 100.0);
        assert!((p.p50_us - 51.0).abs() < 1.01 && (p.p99_us - 99.0).abs() < 1.01);
    }
}

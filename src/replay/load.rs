//! Loading what replay sends: a capture (pcap/pcapng, streamed in file order) or an MCAP
//! recording (messages sorted by log time, the packets of a VelodyneScan at their own stamps) as
//! one time-ordered schedule of [`ReplayItem`]s, several files merged by time
//! ([`MergeByTime`]), and the `--start`/`--end` window on it.

use crate::bag::cdr::CdrReader;
use crate::bag::read::ReadError;
use hilrig_capture::demux::{Demux, Packet};
use hilrig_capture::{CanFrame, CaptureReader};
use hilrig_stamp::UtcNanos;
use std::path::Path;

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

/// Why a file cannot be replayed, or could be only part way.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// Neither a capture nor a recording.
    #[error("{path}: {source}")]
    NotCapture {
        /// The file.
        path: String,
        /// What the capture reader found.
        #[source]
        source: hilrig_capture::CaptureError,
    },
    /// Damage that ended the reading early: everything before it was read.
    #[error("{path}: {source}")]
    Damaged {
        /// The file.
        path: String,
        /// Where and what.
        #[source]
        source: Damage,
    },
}

/// What ended a schedule early (everything before it is in the schedule).
#[derive(Debug, thiserror::Error)]
pub enum Damage {
    /// A recording damaged part way.
    #[error("the recording is damaged after {items} items: {source}")]
    Recording {
        /// Items read before the damage.
        items: usize,
        /// The damage.
        #[source]
        source: ReadError,
    },
    /// A capture damaged part way.
    #[error("{0}")]
    Capture(#[source] hilrig_capture::CaptureError),
}

/// Reads a capture (pcap/pcapng) or an MCAP recording into a time-ordered schedule.
///
/// Captures stream in file order; an MCAP's messages are collected and sorted by log time (the
/// packets of a VelodyneScan at their own stamps), so memory is proportional to the recording.
/// A capture or recording that is cut off or damaged part way (a drive log whose disk filled up)
/// still gives every item before the damage, with the error beside it: the lab can replay what
/// was recorded and is told what was not.
pub fn load(
    path: &Path,
    data_port: u16,
    position_port: u16,
) -> Result<(Vec<ReplayItem>, Option<ReplayError>), ReplayError> {
    let p = || path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| ReplayError::Io { path: p(), source })?;
    let (items, damage) = schedule(bytes, data_port, position_port)
        .map_err(|source| ReplayError::NotCapture { path: p(), source })?;
    Ok((
        items,
        damage.map(|source| ReplayError::Damaged { path: p(), source }),
    ))
}

/// How far (in file time) an MCAP item may come after items later than it: a VelodyneScan's
/// packets are stamped around the message's log time and channels interleave by a few
/// milliseconds, so items are held back this long and sent in time order. An item that still
/// comes too late is sent at once, out of order, and counted.
pub const REORDER_HORIZON_NS: i64 = 3_000_000_000;

/// What [`stream`] read.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Streamed {
    /// Items handed over.
    pub items: u64,
    /// MCAP items that came later than [`REORDER_HORIZON_NS`] behind a later one, and so were
    /// handed over out of time order.
    pub out_of_order: u64,
    /// Damage that ended the reading early (everything before it was handed over).
    pub damage: Option<String>,
    /// Recorded CAN frames replay cannot send: CAN FD frames (on /can/fd_frames; files of
    /// earlier builds have them on /can/frames under another type) and frames that do not make
    /// a classic CAN frame. Counted, never silently passed over.
    pub not_replayed: u64,
    /// Capture records the reader skipped, by reason: damaged ones (cut by the snap length, a
    /// truncated header, a malformed CAN frame, an unfinished IPv4 datagram) may have held the
    /// rig's data and were not replayed; other traffic is not the rig's.
    pub capture_records: crate::record::CaptureSkips,
    /// Datagrams to the lidar's data or position port whose size is not a data or position
    /// packet's: not replayed.
    pub lidar_wrong_size: u64,
}

/// Streams a capture (in file order) or an MCAP recording (in time order, through a reorder
/// buffer of [`REORDER_HORIZON_NS`]) to `each`, which returns false to stop. Memory is bounded
/// by one chunk and the reorder buffer, not by the file: an hour-long VLS-128 drive (26 GB)
/// streams like a minute of it. Damage part way ends the stream with everything before it
/// handed over, as [`load`] does.
pub fn stream(
    path: &Path,
    data_port: u16,
    position_port: u16,
    each: &mut dyn FnMut(ReplayItem) -> bool,
) -> Result<Streamed, ReplayError> {
    let io = |source| ReplayError::Io {
        path: path.display().to_string(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    let mut reader = std::io::BufReader::with_capacity(1 << 20, file);
    let magic = {
        use std::io::BufRead;
        let head = reader.fill_buf().map_err(io)?;
        head.starts_with(mcap::MAGIC)
    };
    let mut out = Streamed::default();
    if magic {
        stream_mcap(reader, len, &mut out, each);
        return Ok(out);
    }
    let mut d =
        Demux::new(
            CaptureReader::new(reader).map_err(|source| ReplayError::NotCapture {
                path: path.display().to_string(),
                source,
            })?,
        );
    while let Some(item) = d.next_item() {
        let item = match item {
            Ok(i) => i,
            Err(e) => {
                out.damage = Some(e.to_string());
                break;
            }
        };
        let to_lidar = matches!(item.packet, Packet::Udp { dst, .. }
            if dst.port() == data_port || dst.port() == position_port);
        let Some(payload) = capture_payload(item.packet, data_port, position_port) else {
            out.lidar_wrong_size += u64::from(to_lidar);
            continue;
        };
        out.items += 1;
        if !each(ReplayItem {
            time: item.time,
            payload,
        }) {
            break;
        }
    }
    out.capture_records.add(d.stats());
    Ok(out)
}

/// What replay sends for one demultiplexed capture packet, if anything.
fn capture_payload(packet: Packet<'_>, data_port: u16, position_port: u16) -> Option<Payload> {
    Some(match packet {
        Packet::Udp { dst, payload, .. }
            if dst.port() == data_port && payload.len() == hilrig_velodyne::DATA_PACKET_SIZE =>
        {
            Payload::LidarData(payload.to_vec())
        }
        Packet::Udp { dst, payload, .. }
            if dst.port() == position_port
                && payload.len() == hilrig_velodyne::POSITION_PACKET_SIZE =>
        {
            Payload::LidarPosition(payload.to_vec())
        }
        Packet::Udp { .. } => return None,
        Packet::Serial(b) => Payload::Serial(b.to_vec()),
        Packet::Can(f) => Payload::Can(f),
    })
}

/// An item in the reorder buffer: earliest time first, then file order.
struct Held(ReplayItem, u64);

impl PartialEq for Held {
    fn eq(&self, other: &Self) -> bool {
        (self.0.time, self.1) == (other.0.time, other.1)
    }
}
impl Eq for Held {}
impl PartialOrd for Held {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Held {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        // Reversed: `BinaryHeap` is a max-heap.
        (other.0.time, other.1).cmp(&(self.0.time, self.1))
    }
}

fn stream_mcap(
    reader: impl std::io::Read,
    len: u64,
    out: &mut Streamed,
    each: &mut dyn FnMut(ReplayItem) -> bool,
) {
    let mut held = std::collections::BinaryHeap::new();
    let (mut seq, mut latest, mut sent_up_to) = (0u64, i64::MIN, i64::MIN);
    let mut stopped = false;
    let mut batch = Vec::new();
    let result = crate::bag::read::read_stream(reader, len, &mut |event| {
        let crate::bag::read::Event::Message(m) = event else {
            return Ok(());
        };
        batch.clear();
        if !message_into(&m, &mut batch)? {
            out.not_replayed += 1;
        }
        latest = latest.max(m.log_time as i64);
        for item in batch.drain(..) {
            if item.time.0 < sent_up_to {
                out.out_of_order += 1;
                out.items += 1;
                if !each(item) {
                    stopped = true;
                    return Err(ReadError::Stopped);
                }
                continue;
            }
            held.push(Held(item, seq));
            seq += 1;
        }
        while held
            .peek()
            .is_some_and(|h| h.0.time.0 <= latest.saturating_sub(REORDER_HORIZON_NS))
        {
            let Some(Held(item, _)) = held.pop() else {
                break;
            };
            sent_up_to = item.time.0;
            out.items += 1;
            if !each(item) {
                stopped = true;
                return Err(ReadError::Stopped);
            }
        }
        Ok(())
    });
    if stopped {
        return;
    }
    if let Err(e) = result {
        out.damage = Some(format!(
            "the recording is damaged after {} items: {e}",
            out.items + held.len() as u64
        ));
    }
    while let Some(Held(item, _)) = held.pop() {
        out.items += 1;
        if !each(item) {
            return;
        }
    }
}

/// The sans-IO core of [`load`]: the schedule of a capture or MCAP recording held in
/// memory. `Err` when the bytes are no capture or recording at all; otherwise the items read and
/// what stopped the reading early, if anything.
pub fn schedule(
    bytes: Vec<u8>,
    data_port: u16,
    position_port: u16,
) -> Result<(Vec<ReplayItem>, Option<Damage>), hilrig_capture::CaptureError> {
    if bytes.starts_with(mcap::MAGIC) {
        return Ok(load_mcap(&bytes));
    }
    let mut d = Demux::new(CaptureReader::new(std::io::Cursor::new(bytes))?);
    let mut out = Vec::new();
    while let Some(item) = d.next_item() {
        let item = match item {
            Ok(i) => i,
            Err(e) => return Ok((out, Some(Damage::Capture(e)))),
        };
        let Some(payload) = capture_payload(item.packet, data_port, position_port) else {
            continue;
        };
        out.push(ReplayItem {
            time: item.time,
            payload,
        });
    }
    Ok((out, None))
}

/// The schedule of an MCAP recording; a recording cut off or damaged part way (`.active` after a
/// crash) gives the messages before the damage and says where it stopped.
fn load_mcap(bytes: &[u8]) -> (Vec<ReplayItem>, Option<Damage>) {
    let mut out = Vec::new();
    let damage = crate::bag::read::read(bytes, &mut |event| match event {
        crate::bag::read::Event::Message(m) => message_into(&m, &mut out).map(|_| ()),
        _ => Ok(()),
    })
    .err()
    .map(|source| Damage::Recording {
        items: out.len(),
        source,
    });
    out.sort_by_key(|i| i.time);
    (out, damage)
}

/// Schedules one message of the recorder's topics; others (derived ones: clouds, fixes,
/// transforms) are passed over. False for a recorded CAN frame that replay cannot send (see
/// [`Streamed::not_replayed`]).
fn message_into(
    m: &crate::bag::read::Message<'_>,
    out: &mut Vec<ReplayItem>,
) -> Result<bool, ReadError> {
    let t = UtcNanos(m.log_time as i64);
    let data = m.data;
    let channel = m.channel;
    let bad = || ReadError::Undecodable {
        topic: channel.topic.clone(),
    };
    match channel.topic.as_str() {
        crate::bag::topics::VELODYNE_PACKETS => {
            let mut c = CdrReader::new(data).ok_or_else(bad)?;
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
        crate::bag::topics::VELODYNE_POSITION
        | crate::bag::topics::GNSS_UBX
        | crate::bag::topics::GNSS_RTCM
        | crate::bag::topics::GNSS_UNFRAMED => {
            let mut c = CdrReader::new(data).ok_or_else(bad)?;
            c.header().ok_or_else(bad)?;
            let n = c.u32().ok_or_else(bad)? as usize;
            let data = c.bytes(n).ok_or_else(bad)?.to_vec();
            let payload = if channel.topic == crate::bag::topics::VELODYNE_POSITION {
                Payload::LidarPosition(data)
            } else {
                Payload::Serial(data)
            };
            out.push(ReplayItem { time: t, payload });
        }
        crate::bag::topics::GNSS_NMEA => {
            let mut c = CdrReader::new(data).ok_or_else(bad)?;
            c.header().ok_or_else(bad)?;
            let s = c.string().ok_or_else(bad)?;
            out.push(ReplayItem {
                time: t,
                payload: Payload::Serial(format!("{s}\r\n").into_bytes()),
            });
        }
        crate::bag::topics::CAN_FRAMES
            if channel
                .schema
                .as_ref()
                .is_some_and(|s| s.name == "can_msgs/msg/Frame") =>
        {
            let mut c = CdrReader::new(data).ok_or_else(bad)?;
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
            let Some(mut f) = f else {
                return Ok(false);
            };
            f.error = error;
            out.push(ReplayItem {
                time: t,
                payload: Payload::Can(f),
            });
        }
        // A CAN FD frame (or a frame of another type on the classic topic, as files of
        // earlier builds have them): classic CAN sinks cannot send it.
        crate::bag::topics::CAN_FRAMES | crate::bag::topics::CAN_FD_FRAMES => return Ok(false),
        _ => {}
    }
    Ok(true)
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

/// Several streams merged by time: the next item is the earliest head among them, ties going
/// to the stream listed first. Each stream keeps its own order (a capture's file order), so
/// files recorded side by side on one clock (lidar in one capture, CAN in another, or the parts
/// of a split recording) play as one drive. Holds one item per stream.
pub struct MergeByTime<I: Iterator<Item = ReplayItem>> {
    streams: Vec<std::iter::Peekable<I>>,
}

impl<I: Iterator<Item = ReplayItem>> MergeByTime<I> {
    /// Merges `streams`.
    pub fn new(streams: impl IntoIterator<Item = I>) -> MergeByTime<I> {
        MergeByTime {
            streams: streams.into_iter().map(Iterator::peekable).collect(),
        }
    }
}

impl<I: Iterator<Item = ReplayItem>> Iterator for MergeByTime<I> {
    type Item = ReplayItem;

    fn next(&mut self) -> Option<ReplayItem> {
        let mut best: Option<(usize, UtcNanos)> = None;
        for (k, s) in self.streams.iter_mut().enumerate() {
            if let Some(head) = s.peek() {
                if best.is_none_or(|(_, t)| head.time < t) {
                    best = Some((k, head.time));
                }
            }
        }
        self.streams[best?.0].next()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_takes_the_earliest_head_and_keeps_each_stream_s_order() {
        let item = |t: i64, tag: u8| ReplayItem {
            time: UtcNanos(t),
            payload: Payload::Serial(vec![tag]),
        };
        // Stream 0 is not in time order (a capture's file order is kept: its 25 follows its 30,
        // before stream 1's 30 that ties with that 30 and so comes after it); ties go to
        // stream 0.
        let a = vec![item(10, 0), item(30, 1), item(25, 2), item(50, 3)];
        let b = vec![item(5, 10), item(30, 11), item(40, 12)];
        let c: Vec<ReplayItem> = Vec::new();
        let merged: Vec<u8> = MergeByTime::new([a.into_iter(), b.into_iter(), c.into_iter()])
            .map(|i| match i.payload {
                Payload::Serial(b) => b[0],
                _ => unreachable!(),
            })
            .collect();
        assert_eq!(merged, vec![10, 0, 1, 2, 11, 12, 3]);
    }

    /// An MCAP with a header and one zstd chunk holding `records`, claiming `size`.
    fn recording_with_chunk(records: &[u8], size: u64) -> Vec<u8> {
        let compressed = zstd::bulk::compress(records, 3).unwrap();
        let record = |op: u8, body: &[u8]| {
            let mut r = vec![op];
            r.extend_from_slice(&(body.len() as u64).to_le_bytes());
            r.extend_from_slice(body);
            r
        };
        let mut header = Vec::new();
        for s in ["ros2", "test"] {
            header.extend_from_slice(&(s.len() as u32).to_le_bytes());
            header.extend_from_slice(s.as_bytes());
        }
        let mut chunk = Vec::new();
        chunk.extend_from_slice(&0u64.to_le_bytes()); // start time
        chunk.extend_from_slice(&0u64.to_le_bytes()); // end time
        chunk.extend_from_slice(&size.to_le_bytes()); // uncompressed size
        chunk.extend_from_slice(&0u32.to_le_bytes()); // no CRC
        chunk.extend_from_slice(&4u32.to_le_bytes());
        chunk.extend_from_slice(b"zstd");
        chunk.extend_from_slice(&(compressed.len() as u64).to_le_bytes());
        chunk.extend_from_slice(&compressed);
        let mut out = mcap::MAGIC.to_vec();
        out.extend(record(0x01, &header));
        out.extend(record(0x06, &chunk));
        out
    }

    /// The inputs with which fuzzing `replay_schedule` made the mcap crate reserve exabytes or
    /// slice out of bounds (fixtures/fuzz, in the fuzz target's encoding: an odd first byte
    /// stands for the MCAP magic). They end in a schedule with the damage named.
    #[test]
    fn the_fuzzer_s_damaged_recordings_are_damage_not_a_panic() {
        for name in [
            "replay_schedule_chunk_size.bin",
            "replay_schedule_record_length.bin",
            "replay_schedule_attachment.bin",
        ] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("fixtures/fuzz")
                .join(name);
            let data = std::fs::read(path).unwrap();
            assert_eq!(data[0] % 2, 1);
            let file = [mcap::MAGIC, &data[1..]].concat();
            let (_, damage) = schedule(file, 2368, 8308).unwrap();
            let damage = damage.expect("damage reported").to_string();
            assert!(
                damage.starts_with("the recording is damaged after"),
                "{name}: {damage}"
            );
        }
    }

    /// Found by fuzzing (`replay_schedule`): sizes a damaged recording claims, for a chunk or for
    /// a record inside one, made the mcap crate reserve exabytes (a panic). They are damage,
    /// reported with what came before.
    #[test]
    fn absurd_sizes_in_a_damaged_recording_are_damage_not_a_panic() {
        // A record inside the chunk claiming 0x7221f3000004011e bytes, as the fuzzer found.
        let mut inner = vec![0x03];
        inner.extend_from_slice(&0x7221_f300_0004_011e_u64.to_le_bytes());
        inner.extend_from_slice(&[0; 16]);
        let file = recording_with_chunk(&inner, inner.len() as u64);
        let (items, damage) = schedule(file, 2368, 8308).unwrap();
        assert!(items.is_empty());
        let damage = damage.expect("damage reported").to_string();
        assert!(
            damage.starts_with("the recording is damaged after 0 items"),
            "{damage}"
        );

        // A chunk claiming far more than it can hold.
        let file = recording_with_chunk(&inner, u64::MAX / 3);
        let damage = schedule(file, 2368, 8308)
            .unwrap()
            .1
            .expect("damage reported")
            .to_string();
        assert!(
            damage.contains("claims 6148914691236517205 bytes uncompressed"),
            "{damage}"
        );

        // A chunk claiming a little more than it holds.
        let file = recording_with_chunk(&inner, inner.len() as u64 + 5);
        let damage = schedule(file, 2368, 8308)
            .unwrap()
            .1
            .expect("damage reported")
            .to_string();
        assert!(damage.contains("but holds 25"), "{damage}");
    }

    /// Only datagrams of the lidar's ports and sizes are replayed: other UDP traffic in a
    /// capture (here a 100-byte datagram to port 9999 and a 1206-byte one to the position port)
    /// is left out.
    #[test]
    fn other_udp_traffic_in_a_capture_is_not_replayed() {
        use hilrig_capture::writer::udp_ethernet_frame;
        use hilrig_capture::{LinkType, PcapngWriter};
        use std::net::{Ipv4Addr, SocketAddrV4};
        let mut w = PcapngWriter::new(Vec::new(), "test").unwrap();
        let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
        let to = |port| SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 77), port);
        let from = SocketAddrV4::new(Ipv4Addr::new(192, 168, 1, 201), 2368);
        let datagrams: [(u16, usize); 4] = [(2368, 1206), (8308, 512), (9999, 100), (8308, 1206)];
        for (k, (port, len)) in datagrams.iter().enumerate() {
            let frame = udp_ethernet_frame(from, to(*port), &vec![k as u8; *len]);
            w.write_packet(eth, UtcNanos(1_000 + k as i64), &frame)
                .unwrap();
        }
        let (items, damage) = schedule(w.finish().unwrap(), 2368, 8308).unwrap();
        assert!(damage.is_none());
        let kinds: Vec<&str> = items
            .iter()
            .map(|i| match i.payload {
                Payload::LidarData(_) => "data",
                Payload::LidarPosition(_) => "position",
                _ => "other",
            })
            .collect();
        assert_eq!(kinds, vec!["data", "position"]);
    }

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
}

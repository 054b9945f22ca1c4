//! Framing a mixed serial byte stream: NMEA 0183 sentences, UBX frames and RTCM3 frames, with
//! whatever garbage sits between them.
//!
//! Sans-IO, in the manner of tokio-util's `Decoder`: bytes go in through [`Framer::push`],
//! frames come out of [`Framer::next_frame`]. A corrupt frame is an item ([`Item::Rejected`]),
//! not an error that ends the stream, and resynchronisation advances by one byte only, so a
//! corrupted sentence never takes a valid neighbour with it, even one that starts inside it.
//!
//! Every candidate is validated by its own checksum (NMEA XOR, UBX Fletcher-8, RTCM3 CRC-24Q)
//! before it is accepted. Memory is bounded: a candidate can be at most [`MAX_FRAME`] bytes.

use std::collections::VecDeque;

/// Largest frame kept while waiting for its end (UBX frames of the F9 series stay below 8 KiB;
/// RTCM3 frames are at most 1029 bytes).
pub const MAX_FRAME: usize = 8 * 1024;
/// Longest NMEA sentence accepted (the standard says 82 characters; proprietary ones run longer).
pub const MAX_NMEA: usize = 256;

/// A complete, checksum-verified frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Frame {
    /// An NMEA sentence from `$` (or `!`) up to and including the checksum (no line end).
    Nmea(String),
    /// A UBX frame: class, id and payload.
    Ubx {
        /// Message class.
        class: u8,
        /// Message id.
        id: u8,
        /// Payload bytes.
        payload: Vec<u8>,
    },
    /// An RTCM3 frame: corrections a moving-base receiver sends its rover, or that a receiver
    /// echoes. Not decoded, but recorded and replayed as they came.
    Rtcm3 {
        /// Message number (first 12 bits of the payload), 0 when the payload is empty.
        message: u16,
        /// The whole frame: preamble, length, payload and CRC.
        bytes: Vec<u8>,
    },
}

/// Why a candidate frame was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum RejectReason {
    /// An NMEA sentence whose checksum does not match.
    NmeaChecksum,
    /// An NMEA sentence with non-printable bytes, no `*hh`, or too long.
    NmeaMalformed,
    /// A UBX frame whose checksum does not match.
    UbxChecksum,
    /// An RTCM3 frame whose CRC does not match.
    Rtcm3Crc,
}

/// What the framer yields.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Item {
    /// A valid frame, with the stream offset of its first byte.
    Frame {
        /// Stream offset of the first byte.
        offset: u64,
        /// The frame.
        frame: Frame,
    },
    /// A candidate that failed validation (its first byte is skipped and scanning goes on).
    Rejected {
        /// Stream offset of the candidate.
        offset: u64,
        /// Why.
        reason: RejectReason,
    },
}

/// Counters.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FramerStats {
    /// Bytes pushed.
    pub bytes: u64,
    /// NMEA sentences accepted.
    pub nmea: u64,
    /// UBX frames accepted.
    pub ubx: u64,
    /// RTCM3 frames accepted.
    pub rtcm3: u64,
    /// Candidates rejected.
    pub rejected: u64,
    /// Bytes that belonged to no frame (garbage, rejected candidates' first bytes, comments).
    pub skipped_bytes: u64,
    /// gpsd log comment lines skipped.
    pub comment_lines: u64,
    /// Their bytes (among `skipped_bytes`): the log's, not the receiver's.
    pub comment_bytes: u64,
}

/// A run of the stream's bytes that belonged to no frame: what a recorder keeps so that
/// nothing the receiver sent is lost (a protocol the framer does not know, a frame cut off at
/// the stream's start, a rejected candidate's bytes).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Unframed {
    /// Stream offset of the first byte.
    pub offset: u64,
    /// The bytes, as they came.
    pub bytes: Vec<u8>,
}

/// The framer.
#[derive(Debug)]
pub struct Framer {
    buf: VecDeque<u8>,
    /// Stream offset of `buf[0]`.
    offset: u64,
    at_line_start: bool,
    gpsd_comments: bool,
    finished: bool,
    /// With [`Framer::keeping_unframed`]: the runs of bytes skipped, oldest first; the last
    /// one grows while no frame follows it.
    unframed: Option<VecDeque<Unframed>>,
    /// A frame (or nothing yet) came after the last run: the next skipped byte starts a new one.
    run_closed: bool,
    /// Counters.
    pub stats: FramerStats,
}

impl Default for Framer {
    fn default() -> Self {
        Framer::new()
    }
}

enum Scan {
    Item(Item, usize),
    Skip(usize),
    NeedMore,
}

impl Framer {
    /// A framer for a raw serial stream.
    pub fn new() -> Framer {
        Framer {
            buf: VecDeque::with_capacity(4096),
            offset: 0,
            at_line_start: true,
            gpsd_comments: false,
            finished: false,
            unframed: None,
            run_closed: true,
            stats: FramerStats::default(),
        }
    }

    /// This framer keeping the bytes it skips (outside any frame; a gpsd log's comment lines
    /// are the log's, not the stream's, and not kept), for [`Framer::take_unframed`]. A caller
    /// that takes them after each item keeps the stream's order: frames and the runs between
    /// them, every byte once.
    #[must_use]
    pub fn keeping_unframed(mut self) -> Framer {
        self.unframed = Some(VecDeque::new());
        self
    }

    /// The next run of skipped bytes, oldest first, when the framer keeps them: all runs that
    /// came before the item [`Framer::next_frame`] returned last (a run still growing at the
    /// end of what was pushed too).
    pub fn take_unframed(&mut self) -> Option<Unframed> {
        let run = self.unframed.as_mut()?.pop_front();
        if self.unframed.as_ref().is_some_and(VecDeque::is_empty) {
            self.run_closed = true;
        }
        run
    }

    /// Skips `n` bytes that belong to no frame (kept when the framer keeps them, unless they
    /// are a gpsd log's comment).
    fn skip(&mut self, n: usize, comment: bool) {
        let n = n.min(self.buf.len());
        if comment {
            // The log's line, not the stream's: the runs on either side are two.
            self.run_closed = true;
        } else if let Some(runs) = self.unframed.as_mut() {
            let bytes = self.buf.range(..n).copied();
            match runs.back_mut() {
                Some(run) if !self.run_closed => run.bytes.extend(bytes),
                _ => {
                    runs.push_back(Unframed {
                        offset: self.offset,
                        bytes: bytes.collect(),
                    });
                    self.run_closed = false;
                }
            }
        }
        self.consume(n);
    }

    /// A framer that also skips gpsd log comment lines (`#` at the start of a line, outside any
    /// frame), for reading gpsd regression logs.
    pub fn for_gpsd_log() -> Framer {
        Framer {
            gpsd_comments: true,
            ..Framer::new()
        }
    }

    /// Adds bytes from the stream.
    pub fn push(&mut self, bytes: &[u8]) {
        self.stats.bytes += bytes.len() as u64;
        self.buf.extend(bytes);
    }

    /// Marks the end of the stream: an incomplete tail is then dropped (counted as skipped).
    pub fn finish(&mut self) {
        self.finished = true;
    }

    /// Bytes pushed that are not yet part of a frame or skipped: at the end of a stream, a
    /// frame cut off there.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Stream offset of the next unread byte.
    pub fn position(&self) -> u64 {
        self.offset
    }

    /// The next item, or `None` when more bytes are needed (or the stream is finished).
    pub fn next_frame(&mut self) -> Option<Item> {
        loop {
            if self.buf.is_empty() {
                return None;
            }
            self.buf.make_contiguous();
            let scan = {
                let (data, _) = self.buf.as_slices();
                scan(
                    data,
                    self.offset,
                    self.at_line_start && self.gpsd_comments,
                    self.finished,
                )
            };
            match scan {
                Scan::Item(item, len) => {
                    match &item {
                        Item::Frame {
                            frame: Frame::Nmea(_),
                            ..
                        } => self.stats.nmea += 1,
                        Item::Frame {
                            frame: Frame::Ubx { .. },
                            ..
                        } => self.stats.ubx += 1,
                        Item::Frame {
                            frame: Frame::Rtcm3 { .. },
                            ..
                        } => self.stats.rtcm3 += 1,
                        Item::Rejected { .. } => {
                            self.stats.rejected += 1;
                            self.stats.skipped_bytes += len as u64;
                        }
                    }
                    if matches!(item, Item::Rejected { .. }) {
                        self.skip(len, false);
                    } else {
                        self.consume(len);
                        self.run_closed = true;
                    }
                    return Some(item);
                }
                Scan::Skip(n) => {
                    let comment =
                        self.at_line_start && self.gpsd_comments && self.buf.front() == Some(&b'#');
                    if comment {
                        self.stats.comment_lines += 1;
                        self.stats.comment_bytes += n as u64;
                    }
                    self.stats.skipped_bytes += n as u64;
                    self.skip(n, comment);
                }
                Scan::NeedMore => {
                    if !self.finished {
                        return None;
                    }
                    // At the end a candidate can no longer complete: drop its first byte only,
                    // since a corrupted length may have made it swallow valid frames behind it.
                    self.stats.skipped_bytes += 1;
                    self.skip(1, false);
                }
            }
        }
    }

    fn consume(&mut self, n: usize) {
        let n = n.min(self.buf.len());
        let last = if n > 0 {
            self.buf.get(n - 1).copied()
        } else {
            None
        };
        self.buf.drain(..n);
        self.offset += n as u64;
        if let Some(b) = last {
            self.at_line_start = b == b'\n';
        }
    }
}

fn scan(data: &[u8], offset: u64, comment_possible: bool, finished: bool) -> Scan {
    if comment_possible && data[0] == b'#' {
        return match data.iter().position(|&b| b == b'\n') {
            Some(i) => Scan::Skip(i + 1),
            None if data.len() > MAX_NMEA => Scan::Skip(data.len()),
            None => Scan::NeedMore,
        };
    }
    match data[0] {
        b'$' | b'!' => scan_nmea(data, offset, finished),
        0xB5 => scan_ubx(data, offset),
        0xD3 => scan_rtcm3(data, offset),
        _ => {
            // Skip to the next possible start byte, or through a line end (so that gpsd comment
            // lines are recognised at the start of the next line).
            let stop = data[1..]
                .iter()
                .position(|&b| matches!(b, b'$' | b'!' | 0xB5 | 0xD3 | b'\n'));
            match stop {
                Some(i) if data[i + 1] == b'\n' => Scan::Skip(i + 2),
                Some(i) => Scan::Skip(i + 1),
                None => Scan::Skip(data.len()),
            }
        }
    }
}

fn reject(offset: u64, reason: RejectReason) -> Scan {
    Scan::Item(Item::Rejected { offset, reason }, 1)
}

fn scan_nmea(data: &[u8], offset: u64, finished: bool) -> Scan {
    // The sentence ends at the first CR or LF; any byte that cannot be in a sentence ends the
    // candidate early (so that a frame starting inside it is not swallowed).
    let limit = data.len().min(MAX_NMEA);
    let mut end = None;
    for (i, &b) in data.iter().enumerate().take(limit).skip(1) {
        if b == b'\r' || b == b'\n' {
            end = Some(i);
            break;
        }
        if !(0x20..0x7f).contains(&b) || b == b'$' {
            return reject(offset, RejectReason::NmeaMalformed);
        }
    }
    let Some(end) = end else {
        if data.len() >= MAX_NMEA {
            return reject(offset, RejectReason::NmeaMalformed);
        }
        return Scan::NeedMore;
    };
    let s = &data[..end];
    let Some(star) = s.iter().rposition(|&b| b == b'*') else {
        return reject(offset, RejectReason::NmeaMalformed);
    };
    if star + 3 != s.len() {
        return reject(offset, RejectReason::NmeaMalformed);
    }
    let hex = |b: u8| (b as char).to_digit(16);
    let (Some(h), Some(l)) = (hex(s[star + 1]), hex(s[star + 2])) else {
        return reject(offset, RejectReason::NmeaMalformed);
    };
    let expected = (h * 16 + l) as u8;
    let computed = s[1..star].iter().fold(0u8, |a, b| a ^ b);
    if expected != computed {
        return reject(offset, RejectReason::NmeaChecksum);
    }
    // Consume the line end too (CR, LF or CRLF). A CR that ends what came may be followed by
    // its LF in the next read: wait for it (kept apart, the LF would be a byte in no frame).
    if data[end] == b'\r' && end + 1 == data.len() && !finished {
        return Scan::NeedMore;
    }
    let mut len = end + 1;
    if data[end] == b'\r' && data.get(end + 1) == Some(&b'\n') {
        len += 1;
    }
    // Safe: every byte was checked to be printable ASCII.
    let text = String::from_utf8_lossy(s).into_owned();
    Scan::Item(
        Item::Frame {
            offset,
            frame: Frame::Nmea(text),
        },
        len,
    )
}

/// UBX checksum (8-bit Fletcher over class, id, length and payload).
pub fn ubx_checksum(bytes: &[u8]) -> (u8, u8) {
    let (mut a, mut b) = (0u8, 0u8);
    for &x in bytes {
        a = a.wrapping_add(x);
        b = b.wrapping_add(a);
    }
    (a, b)
}

fn scan_ubx(data: &[u8], offset: u64) -> Scan {
    if data.len() < 2 {
        return Scan::NeedMore;
    }
    if data[1] != 0x62 {
        return Scan::Skip(1);
    }
    if data.len() < 6 {
        return Scan::NeedMore;
    }
    let len = usize::from(u16::from_le_bytes([data[4], data[5]]));
    let total = 8 + len;
    if total > MAX_FRAME {
        return reject(offset, RejectReason::UbxChecksum);
    }
    if data.len() < total {
        return Scan::NeedMore;
    }
    let (a, b) = ubx_checksum(&data[2..6 + len]);
    if data[6 + len] != a || data[7 + len] != b {
        return reject(offset, RejectReason::UbxChecksum);
    }
    Scan::Item(
        Item::Frame {
            offset,
            frame: Frame::Ubx {
                class: data[2],
                id: data[3],
                payload: data[6..6 + len].to_vec(),
            },
        },
        total,
    )
}

/// CRC-24Q (RTCM 10403), as used by RTCM3 frames.
pub fn crc24q(bytes: &[u8]) -> u32 {
    let mut crc: u32 = 0;
    for &b in bytes {
        crc ^= u32::from(b) << 16;
        for _ in 0..8 {
            crc <<= 1;
            if crc & 0x100_0000 != 0 {
                crc ^= 0x186_4CFB;
            }
        }
    }
    crc & 0xFF_FFFF
}

fn scan_rtcm3(data: &[u8], offset: u64) -> Scan {
    if data.len() < 3 {
        return Scan::NeedMore;
    }
    if data[1] & 0xFC != 0 {
        return Scan::Skip(1);
    }
    let len = (usize::from(data[1] & 0x03) << 8) | usize::from(data[2]);
    let total = 3 + len + 3;
    if data.len() < total {
        return Scan::NeedMore;
    }
    let crc = crc24q(&data[..3 + len]);
    let got = (u32::from(data[3 + len]) << 16)
        | (u32::from(data[4 + len]) << 8)
        | u32::from(data[5 + len]);
    if crc != got {
        return reject(offset, RejectReason::Rtcm3Crc);
    }
    let message = if len >= 2 {
        (u16::from(data[3]) << 4) | (u16::from(data[4]) >> 4)
    } else {
        0
    };
    Scan::Item(
        Item::Frame {
            offset,
            frame: Frame::Rtcm3 {
                message,
                bytes: data[..total].to_vec(),
            },
        },
        total,
    )
}

/// Builds a UBX frame (for tests, synthesis and replay).
pub fn ubx_frame(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
    let mut f = vec![0xB5, 0x62, class, id];
    f.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    f.extend_from_slice(payload);
    let (a, b) = ubx_checksum(&f[2..]);
    f.push(a);
    f.push(b);
    f
}

/// Builds an RTCM3 frame around a payload.
pub fn rtcm3_frame(payload: &[u8]) -> Vec<u8> {
    let mut f = vec![
        0xD3,
        ((payload.len() >> 8) & 0x03) as u8,
        payload.len() as u8,
    ];
    f.extend_from_slice(payload);
    let crc = crc24q(&f);
    f.extend_from_slice(&[(crc >> 16) as u8, (crc >> 8) as u8, crc as u8]);
    f
}

/// Builds an NMEA sentence with checksum and CRLF from its body (without `$` and `*hh`).
pub fn nmea_sentence(body: &str) -> String {
    let cs = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{cs:02X}\r\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn frames(bytes: &[u8]) -> (Vec<Frame>, Vec<RejectReason>) {
        let mut f = Framer::new();
        f.push(bytes);
        f.finish();
        let (mut ok, mut bad) = (Vec::new(), Vec::new());
        while let Some(item) = f.next_frame() {
            match item {
                Item::Frame { frame, .. } => ok.push(frame),
                Item::Rejected { reason, .. } => bad.push(reason),
            }
        }
        (ok, bad)
    }

    #[test]
    fn crc24q_known_value() {
        // The standard check value of CRC-24Q (poly 0x864CFB, init 0, no reflection, no xor
        // out): the CRC of the nine ASCII digits "123456789" is 0xCDE703.
        assert_eq!(crc24q(b"123456789"), 0xCD_E703);
        assert_eq!(crc24q(b""), 0);
        // A frame built here carries that CRC over its header and payload, and the framer
        // accepts it and rejects it with one bit flipped.
        let f = rtcm3_frame(&[0x3E, 0xD0, 0x00, 0x03]);
        assert_eq!(
            crc24q(&f[..f.len() - 3]),
            u32::from_be_bytes([0, f[f.len() - 3], f[f.len() - 2], f[f.len() - 1]])
        );
        let mut bad = f.clone();
        bad[4] ^= 0x01;
        let (ok, rejected) = frames(&bad);
        assert!(ok.is_empty());
        assert_eq!(rejected, vec![RejectReason::Rtcm3Crc]);
        let (ok, rejected) = frames(&f);
        assert_eq!(ok.len(), 1);
        assert!(rejected.is_empty());
    }

    /// Polls from the u-blox protocol specification, checksums as printed there: CFG-RATE
    /// (`B5 62 06 08 00 00 0E 30`) and MON-VER (`B5 62 0A 04 00 00 0E 34`). A frame with a
    /// wrong checksum is rejected, not passed on.
    #[test]
    fn ubx_checksums_are_the_specification_s() {
        assert_eq!(
            ubx_frame(0x06, 0x08, &[]),
            [0xB5, 0x62, 0x06, 0x08, 0, 0, 0x0E, 0x30]
        );
        assert_eq!(
            ubx_frame(0x0A, 0x04, &[]),
            [0xB5, 0x62, 0x0A, 0x04, 0, 0, 0x0E, 0x34]
        );
        let (ok, bad) = frames(&[0xB5, 0x62, 0x06, 0x08, 0, 0, 0x0E, 0x30]);
        assert_eq!(ok.len(), 1);
        assert!(bad.is_empty());
        let (ok, bad) = frames(&[0xB5, 0x62, 0x06, 0x08, 0, 0, 0x0E, 0x31]);
        assert!(ok.is_empty());
        assert_eq!(bad, vec![RejectReason::UbxChecksum]);
    }

    /// The counters `decode --kind gnss` prints: every accepted frame by kind, every rejected
    /// candidate, and every byte that belonged to no frame.
    #[test]
    fn counters_add_up_over_a_mixed_stream() {
        let good = nmea_sentence("GPGGA,1,2,3");
        let bad = "$GPGGA,1,2,3*00\r\n";
        let mut s = b"xx\xff".to_vec();
        s.extend(good.bytes());
        s.extend(ubx_frame(1, 7, &[1, 2, 3]));
        s.extend(rtcm3_frame(&[0x3E, 0xD0, 0x00, 0x03]));
        s.extend(bad.bytes());
        s.extend(good.bytes());
        let mut f = Framer::new();
        f.push(&s);
        f.finish();
        while f.next_frame().is_some() {}
        let st = &f.stats;
        assert_eq!(st.bytes, s.len() as u64);
        assert_eq!((st.nmea, st.ubx, st.rtcm3, st.rejected), (2, 1, 1, 1));
        assert_eq!(st.skipped_bytes, 3 + bad.len() as u64);
        assert_eq!(st.comment_lines, 0);
    }

    /// NMEA sentences end with CR LF, which belongs to the sentence: back-to-back sentences
    /// leave no byte over, and each starts where the one before ended.
    #[test]
    fn a_sentence_s_line_end_is_part_of_it() {
        let a = nmea_sentence("GPGGA,1,2,3");
        let b = nmea_sentence("GPRMC,4,5,6");
        let mut f = Framer::new();
        f.push(format!("{a}{b}").as_bytes());
        f.finish();
        let mut offsets = Vec::new();
        while let Some(Item::Frame { offset, .. }) = f.next_frame() {
            offsets.push(offset);
        }
        assert_eq!(offsets, vec![0, a.len() as u64]);
        assert_eq!(f.stats.skipped_bytes, 0);
    }

    /// A `#` line is a comment only in gpsd's logs; in a receiver's own stream it is bytes
    /// outside any frame. Either way its bytes are counted as skipped, and an empty comment
    /// line (`#` alone, as gpsd's logs have them) is skipped too.
    #[test]
    fn hash_lines_are_comments_only_in_gpsd_logs() {
        let text = format!("# a comment\n#\n{}", nmea_sentence("GPGGA,1,2,3"));
        for (mut f, comments) in [(Framer::new(), 0), (Framer::for_gpsd_log(), 2)] {
            f.push(text.as_bytes());
            f.finish();
            let mut n = 0;
            while let Some(item) = f.next_frame() {
                n += usize::from(matches!(item, Item::Frame { .. }));
            }
            assert_eq!(n, 1);
            assert_eq!(f.stats.comment_lines, comments);
            assert_eq!(f.stats.comment_bytes, if comments > 0 { 14 } else { 0 });
            assert_eq!(f.stats.skipped_bytes, "# a comment\n#\n".len() as u64);
            assert_eq!(f.stats.rejected, 0);
        }
    }

    /// A stream that ends inside a sentence: the unfinished candidate's bytes are counted as
    /// skipped (one by one, since a corrupted length could have swallowed frames behind it).
    #[test]
    fn an_unfinished_sentence_at_the_end_is_skipped_bytes() {
        let mut f = Framer::new();
        f.push(b"$GPGGA,1,2");
        f.finish();
        while f.next_frame().is_some() {}
        assert_eq!(f.stats.skipped_bytes, 10);
        assert_eq!((f.stats.nmea, f.stats.rejected), (0, 0));
    }

    /// Large UBX frames (MON and ESF messages run to kilobytes) pass: up to 8 KiB.
    #[test]
    fn a_two_kilobyte_ubx_frame_passes() {
        let payload: Vec<u8> = (0..2000u32).map(|i| i as u8).collect();
        let (ok, bad) = frames(&ubx_frame(0x0A, 0x31, &payload));
        assert!(bad.is_empty());
        assert_eq!(
            ok,
            vec![Frame::Ubx {
                class: 0x0A,
                id: 0x31,
                payload
            }]
        );
    }

    #[test]
    fn mixed_stream_with_garbage() {
        let mut s = b"xx\xff".to_vec();
        s.extend(nmea_sentence("GPGGA,1,2,3").bytes());
        s.extend(ubx_frame(1, 7, &[1, 2, 3]));
        s.extend(rtcm3_frame(&[0x3E, 0xD0, 1, 2]));
        s.extend(b"$GPRMC,bad*7F\r\n"); // true checksum is 00
        s.extend(nmea_sentence("GNZDA,4").bytes());
        let (ok, bad) = frames(&s);
        assert_eq!(ok.len(), 4, "{ok:?}");
        assert_eq!(
            ok[0],
            Frame::Nmea("$GPGGA,1,2,3*4F".replace(
                "4F",
                &format!("{:02X}", b"GPGGA,1,2,3".iter().fold(0, |a, b| a ^ b))
            ))
        );
        assert_eq!(
            ok[1],
            Frame::Ubx {
                class: 1,
                id: 7,
                payload: vec![1, 2, 3]
            }
        );
        assert_eq!(
            ok[2],
            Frame::Rtcm3 {
                message: 1005,
                bytes: rtcm3_frame(&[0x3E, 0xD0, 1, 2])
            }
        );
        assert_eq!(bad, vec![RejectReason::NmeaChecksum]);
    }

    #[test]
    fn a_sentence_cut_by_another_is_rejected_and_the_other_kept() {
        let mut s = b"$GPGGA,12345".to_vec(); // cut off mid-sentence
        s.extend(nmea_sentence("GPRMC,ok").bytes());
        let (ok, bad) = frames(&s);
        assert_eq!(ok.len(), 1);
        assert_eq!(bad, vec![RejectReason::NmeaMalformed]);
    }

    #[test]
    fn gpsd_comment_lines_are_skipped() {
        let mut f = Framer::for_gpsd_log();
        f.push(b"# Name: test $GPGGA,x*00\n# more\n");
        f.push(nmea_sentence("GPGGA,1").as_bytes());
        let mut n = 0;
        while let Some(i) = f.next_frame() {
            assert!(matches!(i, Item::Frame { .. }));
            n += 1;
        }
        assert_eq!(n, 1);
        assert_eq!(f.stats.comment_lines, 2);
    }

    fn stream_of(frames: &[Vec<u8>]) -> Vec<u8> {
        frames.concat()
    }

    fn arb_frame() -> impl Strategy<Value = Vec<u8>> {
        prop_oneof![
            "[A-Z]{5}(,[0-9A-Z.]{0,8}){0,12}".prop_map(|b| nmea_sentence(&b).into_bytes()),
            (
                any::<u8>(),
                any::<u8>(),
                proptest::collection::vec(any::<u8>(), 0..120)
            )
                .prop_map(|(c, i, p)| ubx_frame(c, i, &p)),
            proptest::collection::vec(any::<u8>(), 2..200).prop_map(|p| rtcm3_frame(&p)),
        ]
    }

    proptest! {
        /// Corruption (flips, insertions, deletions) loses only the frames it touches.
        #[test]
        fn corruption_loses_only_touched_frames(
            frames_in in proptest::collection::vec(arb_frame(), 1..30),
            edits in proptest::collection::vec((any::<proptest::sample::Index>(), 0u8..3, any::<u8>()), 0..6),
            chunk in 1usize..100,
        ) {
            let stream = stream_of(&frames_in);
            // Frame spans in the original stream.
            let mut spans = Vec::new();
            let mut at = 0;
            for f in &frames_in {
                spans.push((at, at + f.len()));
                at += f.len();
            }
            let mut touched = vec![false; frames_in.len()];
            let mut bytes = stream.clone();
            // Apply edits from the back so earlier positions stay valid.
            let mut positions: Vec<(usize, u8, u8)> = edits.iter().map(|(i, k, v)| (i.index(stream.len()), *k, *v)).collect();
            positions.sort_by_key(|p| std::cmp::Reverse(p.0));
            // One edit per place: a second one would land on the byte after a removal, which
            // belongs to the next frame, and that frame would be changed but not marked.
            positions.dedup_by_key(|p| p.0);
            for (pos, kind, v) in positions {
                // Two edits at the same place: a removal can leave the other one past the end.
                if pos > bytes.len() || (kind != 1 && pos == bytes.len()) {
                    continue;
                }
                for (k, (s, e)) in spans.iter().enumerate() {
                    // An insertion at a frame's start touches the boundary, not the frame.
                    if pos >= *s && pos < *e && !(kind == 1 && pos == *s) {
                        touched[k] = true;
                        // A removal shortens the frame, whose length field then reaches one
                        // byte into the next frame: when that byte happens to complete the
                        // checksum (the removed byte equals the next frame's first), the next
                        // frame loses its start. The stream is then ambiguous for any framer.
                        if kind == 2 && k + 1 < touched.len() {
                            touched[k + 1] = true;
                        }
                    }
                }
                match kind {
                    0 => bytes[pos] ^= v | 1,
                    1 => bytes.insert(pos, v),
                    _ => { bytes.remove(pos); }
                }
            }
            let mut f = Framer::new();
            for c in bytes.chunks(chunk) {
                f.push(c);
            }
            f.finish();
            let mut got = Vec::new();
            while let Some(item) = f.next_frame() {
                if let Item::Frame { frame, .. } = item {
                    got.push(frame);
                }
            }
            let (expected, _) = frames(&stream);
            // Every untouched frame is recovered, in order, unless the corruption forged a
            // frame: a flipped length field whose frame still passes its checksum (a 16-bit
            // Fletcher sum over a run of zeros is zero) swallows the frames it spans, and no
            // framer can tell it from a real one. Such a forged frame is one the original
            // stream does not have.
            let forged = got.iter().filter(|g| !expected.contains(g)).count();
            let mut at = 0;
            for (k, e) in expected.iter().enumerate() {
                if touched[k] {
                    continue;
                }
                match got[at..].iter().position(|g| g == e) {
                    Some(i) => at += i + 1,
                    None => prop_assert!(forged > 0, "untouched frame {k} lost without a forged frame: {e:?}"),
                }
            }
        }

        /// A framer that keeps what it skips loses no byte: the frames (their bytes as the
        /// recorder writes them, an NMEA sentence with the line end it came with) and the runs
        /// between them, taken after each item, are the stream again, in order, whatever
        /// junk lies between the frames and however the stream is cut into chunks. A gpsd
        /// log's comment lines are the only bytes not kept.
        #[test]
        fn kept_runs_and_frames_are_the_stream_again(
            parts in proptest::collection::vec(
                prop_oneof![
                    arb_frame(),
                    // Junk without `#`, which at a line's start in a gpsd log begins one of
                    // the log's comments.
                    proptest::collection::vec(any::<u8>().prop_map(|b| if b == b'#' { b'+' } else { b }), 1..40),
                ],
                1..30,
            ),
            chunk in 1usize..100,
            gpsd in any::<bool>(),
        ) {
            let mut stream = if gpsd { b"# a gpsd log's comment\n".to_vec() } else { Vec::new() };
            let comment = stream.len();
            stream.extend(parts.concat());
            let mut f = if gpsd { Framer::for_gpsd_log() } else { Framer::new() }.keeping_unframed();
            let mut again: Vec<u8> = Vec::new();
            let take = |f: &mut Framer, again: &mut Vec<u8>| -> Result<(), TestCaseError> {
                while let Some(run) = f.take_unframed() {
                    prop_assert!(!run.bytes.is_empty());
                    let at = run.offset as usize;
                    prop_assert_eq!(&stream[at..at + run.bytes.len()], run.bytes.as_slice());
                    again.extend(run.bytes);
                }
                Ok(())
            };
            let drain = |f: &mut Framer, again: &mut Vec<u8>| -> Result<(), TestCaseError> {
                loop {
                    let before = f.position() as usize;
                    let item = f.next_frame();
                    take(f, again)?;
                    match item {
                        Some(Item::Frame { offset, frame }) => {
                            let end = f.position() as usize;
                            let bytes = &stream[offset as usize..end];
                            // A CR and the LF after it are never parted (replay writes a
                            // sentence with CRLF: the LF alone would be written again).
                            prop_assert!(!(bytes.ends_with(b"\r") && stream.get(end) == Some(&b'\n')));
                            match frame {
                                Frame::Nmea(text) => prop_assert!(bytes.starts_with(text.as_bytes())),
                                Frame::Ubx { class, id, payload } => {
                                    let want = ubx_frame(class, id, &payload);
                                    prop_assert_eq!(bytes, want.as_slice());
                                }
                                Frame::Rtcm3 { bytes: b, .. } => prop_assert_eq!(bytes, b.as_slice()),
                            }
                            again.extend_from_slice(bytes);
                        }
                        Some(Item::Rejected { .. }) => {}
                        None => {
                            prop_assert!(f.position() as usize >= before);
                            return Ok(());
                        }
                    }
                }
            };
            for c in stream.chunks(chunk) {
                f.push(c);
                drain(&mut f, &mut again)?;
            }
            f.finish();
            drain(&mut f, &mut again)?;
            let kept = if gpsd { &stream[comment..] } else { &stream[..] };
            prop_assert_eq!(again.as_slice(), kept);
        }

        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2000), chunk in 1usize..64) {
            let mut f = Framer::for_gpsd_log();
            for c in bytes.chunks(chunk) {
                f.push(c);
                while f.next_frame().is_some() {}
            }
            f.finish();
            while f.next_frame().is_some() {}
            prop_assert_eq!(f.position(), bytes.len() as u64);
        }
    }
}

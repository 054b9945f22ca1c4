//! From capture records to what the sensors sent: UDP datagrams, CAN frames, serial bytes.
//!
//! Every record ends up either as a [`Packet`] or as a counted [`SkipReason`], so a summary can
//! always account for the whole file (DESIGN.md: "bad input is counted and reported, never
//! silently dropped").

use crate::can::CanFrame;
use crate::error::{CaptureError, SkipReason};
use crate::ipv4::{parse_ipv4, parse_udp, Reassembler, PROTO_UDP};
use crate::link::{ipv4_payload, LinkType};
use crate::reader::{CaptureReader, Interface};
use hilrig_stamp::UtcNanos;
use std::collections::BTreeMap;
use std::io::Read;
use std::net::SocketAddrV4;

/// What a record carried.
#[derive(Debug, PartialEq)]
pub enum Packet<'a> {
    /// A UDP datagram.
    Udp {
        /// Sender.
        src: SocketAddrV4,
        /// Receiver (its port says which sensor stream it is).
        dst: SocketAddrV4,
        /// Payload.
        payload: &'a [u8],
    },
    /// A CAN frame.
    Can(CanFrame),
    /// A chunk of a serial port's byte stream.
    Serial(&'a [u8]),
}

/// A decoded record with its place and time.
#[derive(Debug)]
pub struct Item<'a> {
    /// Byte offset of the record in the capture.
    pub offset: u64,
    /// Interface index (see [`Demux::interfaces`] for names).
    pub interface: u32,
    /// Capture time.
    pub time: UtcNanos,
    /// The packet.
    pub packet: Packet<'a>,
}

/// Counters for a whole capture.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Packet records read.
    pub records: u64,
    /// Captured bytes in those records.
    pub bytes: u64,
    /// UDP datagrams delivered.
    pub udp: u64,
    /// CAN frames delivered.
    pub can: u64,
    /// Serial chunks delivered.
    pub serial: u64,
    /// IPv4 fragments held back until their datagram completes (reassembled or dropped).
    pub fragments: u64,
    /// Fragments whose datagram never completed.
    pub fragments_dropped: u64,
    /// Records skipped, by reason.
    pub skipped: BTreeMap<SkipReason, u64>,
    /// Whole frames whose IPv4 total length runs past their end, accepted because their UDP
    /// length fits (a firmware quirk, see [`crate::ipv4::parse_ipv4`]).
    pub ipv4_length_quirks: u64,
    /// Byte offset of the first such record.
    pub first_ipv4_length_quirk: Option<u64>,
}

impl Stats {
    /// Total skipped records.
    pub fn skipped_total(&self) -> u64 {
        self.skipped.values().sum()
    }
}

/// Turns a capture into packets.
pub struct Demux<R: Read> {
    reader: CaptureReader<R>,
    reassembler: Reassembler,
    stats: Stats,
    buf: Vec<u8>,
}

enum Outcome {
    Udp {
        src: SocketAddrV4,
        dst: SocketAddrV4,
        quirk: bool,
    },
    Can(CanFrame),
    Serial,
    Pending,
    Skip(SkipReason),
}

impl<R: Read + Send + 'static> Demux<R> {
    /// Wraps a reader.
    pub fn new(reader: CaptureReader<R>) -> Self {
        Demux {
            reader,
            reassembler: Reassembler::default(),
            stats: Stats::default(),
            buf: Vec::with_capacity(2048),
        }
    }

    /// Interfaces of the current section.
    pub fn interfaces(&self) -> &[Interface] {
        self.reader.interfaces()
    }

    /// Counters so far. Fragments still pending at the end are included in `fragments_dropped`
    /// once the stream has ended.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The next packet; `None` at the end. An error ends the stream (everything before it was
    /// delivered).
    pub fn next_item(&mut self) -> Option<Result<Item<'_>, CaptureError>> {
        loop {
            let (offset, interface, time, outcome) = {
                let rec = match self.reader.next_record() {
                    None => {
                        self.stats.fragments_dropped = self.reassembler.fragments_dropped
                            + self.reassembler.pending_fragments();
                        return None;
                    }
                    Some(Err(e)) => return Some(Err(e)),
                    Some(Ok(r)) => r,
                };
                self.stats.records += 1;
                self.stats.bytes += rec.data.len() as u64;
                let outcome = if (rec.data.len() as u64) < u64::from(rec.orig_len) {
                    Outcome::Skip(SkipReason::CutBySnapLength)
                } else {
                    classify(
                        rec.link,
                        rec.data,
                        rec.time,
                        &mut self.reassembler,
                        &mut self.buf,
                    )
                };
                (rec.offset, rec.interface, rec.time, outcome)
            };
            let packet = match outcome {
                Outcome::Skip(reason) => {
                    *self.stats.skipped.entry(reason).or_insert(0) += 1;
                    continue;
                }
                Outcome::Pending => {
                    self.stats.fragments += 1;
                    continue;
                }
                Outcome::Udp { src, dst, quirk } => {
                    self.stats.udp += 1;
                    if quirk {
                        self.stats.ipv4_length_quirks += 1;
                        self.stats.first_ipv4_length_quirk.get_or_insert(offset);
                    }
                    Packet::Udp {
                        src,
                        dst,
                        payload: &self.buf,
                    }
                }
                Outcome::Can(frame) => {
                    self.stats.can += 1;
                    Packet::Can(frame)
                }
                Outcome::Serial => {
                    self.stats.serial += 1;
                    Packet::Serial(&self.buf)
                }
            };
            return Some(Ok(Item {
                offset,
                interface,
                time,
                packet,
            }));
        }
    }
}

fn classify(
    link: LinkType,
    data: &[u8],
    time: UtcNanos,
    reassembler: &mut Reassembler,
    buf: &mut Vec<u8>,
) -> Outcome {
    match link {
        LinkType::CAN_SOCKETCAN => match CanFrame::decode_socketcan(data) {
            Ok(f) => Outcome::Can(f),
            Err(r) => Outcome::Skip(r),
        },
        LinkType::USER0 => {
            buf.clear();
            buf.extend_from_slice(data);
            Outcome::Serial
        }
        _ => {
            let ip_bytes = match ipv4_payload(link, data) {
                Ok(b) => b,
                Err(r) => return Outcome::Skip(r),
            };
            // Records cut by the snap length were skipped before: this frame is whole.
            let ip = match parse_ipv4(ip_bytes, true) {
                Ok(ip) => ip,
                Err(r) => return Outcome::Skip(r),
            };
            if ip.protocol != PROTO_UDP {
                return Outcome::Skip(SkipReason::NotUdp(ip.protocol));
            }
            if ip.more_fragments || ip.fragment_offset > 0 {
                return match reassembler.push(&ip, time) {
                    None => Outcome::Pending,
                    Some(done) => match parse_udp(done.src, done.dst, &done.payload) {
                        Ok(u) => {
                            buf.clear();
                            buf.extend_from_slice(u.payload);
                            Outcome::Udp {
                                src: u.src,
                                dst: u.dst,
                                quirk: false,
                            }
                        }
                        Err(r) => Outcome::Skip(r),
                    },
                };
            }
            match parse_udp(ip.src, ip.dst, ip.payload) {
                Ok(u) => {
                    buf.clear();
                    buf.extend_from_slice(u.payload);
                    Outcome::Udp {
                        src: u.src,
                        dst: u.dst,
                        quirk: ip.length_quirk,
                    }
                }
                Err(r) => Outcome::Skip(r),
            }
        }
    }
}

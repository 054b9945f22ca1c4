//! What can go wrong reading a capture: [`CaptureError`] ends the stream, and always says
//! where in the file it happened and what to do; [`SkipReason`] is why a single record was not
//! turned into a packet (not IPv4, a bad UDP length, an unknown link type): [`crate::demux`]
//! counts those and reading goes on. Both live here, below every decoding layer, so that the
//! layers (link, IPv4, CAN) and the demultiplexer over them import in one direction only.

use std::fmt;
use std::io;

/// Why a capture file cannot be read (further).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CaptureError {
    /// The operating system failed to read the file.
    #[error("reading the capture failed at byte {offset}: {source}")]
    Io {
        /// Byte offset of the record being read.
        offset: u64,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// The file does not start like a pcap or pcapng file.
    #[error(
        "not a pcap or pcapng file: it starts with {magic:02x?}, expected a pcap magic \
         (a1b2c3d4, a1b23c4d or byte-swapped) or a pcapng section header (0a0d0d0a)"
    )]
    NotACapture {
        /// The first bytes of the file.
        magic: Vec<u8>,
    },
    /// The file ends inside a record: it was cut off (a recording that did not finish).
    #[error(
        "the capture is truncated: the record at byte {offset} is incomplete; every record \
         before it was read"
    )]
    Truncated {
        /// Byte offset of the incomplete record.
        offset: u64,
    },
    /// A record's header or block structure is invalid.
    #[error("malformed capture record at byte {offset}: {what}")]
    Malformed {
        /// Byte offset of the record.
        offset: u64,
        /// What was wrong.
        what: String,
    },
    /// A record is larger than the reader will buffer.
    #[error(
        "record at byte {offset} is larger than the {limit} byte limit: the file is corrupt or \
         not a sensor capture"
    )]
    RecordTooLarge {
        /// Byte offset of the record.
        offset: u64,
        /// The buffer limit in bytes.
        limit: usize,
    },
    /// A packet names an interface that no interface description block declared.
    #[error(
        "packet at byte {offset} refers to interface {interface}, but only {declared} are declared"
    )]
    UnknownInterface {
        /// Byte offset of the packet block.
        offset: u64,
        /// The interface id in the packet.
        interface: u32,
        /// How many interfaces the section declared.
        declared: usize,
    },
}

/// Why a record was not turned into a packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SkipReason {
    /// A link type this reader does not decode (number attached).
    UnsupportedLinkType(u16),
    /// The frame is shorter than its link-layer header.
    TruncatedLinkHeader,
    /// Not IPv4 (ARP, IPv6, LLDP, ...).
    NotIpv4,
    /// IPv4, but not UDP (protocol number attached).
    NotUdp(u8),
    /// Shorter than the IPv4 header or its total length.
    TruncatedIpv4,
    /// IPv4 header length fields are inconsistent.
    BadIpv4Header,
    /// Shorter than a UDP header.
    TruncatedUdp,
    /// UDP length field is beyond the datagram.
    BadUdpLength,
    /// The SocketCAN record is malformed.
    BadCanFrame,
    /// The capture's snap length cut the packet (caplen < original length).
    CutBySnapLength,
}

impl fmt::Display for SkipReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SkipReason::UnsupportedLinkType(l) => write!(f, "unsupported link type {l}"),
            SkipReason::TruncatedLinkHeader => f.write_str("frame shorter than its link header"),
            SkipReason::NotIpv4 => f.write_str("not IPv4"),
            SkipReason::NotUdp(p) => write!(f, "IPv4 protocol {p}, not UDP"),
            SkipReason::TruncatedIpv4 => f.write_str("truncated IPv4 packet"),
            SkipReason::BadIpv4Header => f.write_str("inconsistent IPv4 header"),
            SkipReason::TruncatedUdp => f.write_str("truncated UDP header"),
            SkipReason::BadUdpLength => f.write_str("UDP length beyond the packet"),
            SkipReason::BadCanFrame => f.write_str("malformed SocketCAN frame"),
            SkipReason::CutBySnapLength => f.write_str("packet cut by the capture's snap length"),
        }
    }
}

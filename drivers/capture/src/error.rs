//! Errors that end reading a capture file.
//!
//! Problems with a single packet (not IPv4, a bad UDP length, an unknown link type) are not
//! errors: [`crate::demux`] counts them as skips and reading goes on. What is here stops the
//! stream, and always says where in the file it happened and what to do.

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

//! Capture files that stand in for hardware.
//!
//! A drive recorded with tcpdump, Wireshark or `hilrig record --raw` is a pcap or pcapng file; this
//! crate turns it back into what the sensors sent: UDP datagrams (lidar), SocketCAN frames and
//! chunks of a serial byte stream, each with the capture's receive time. It also writes such files,
//! so that the synthesizer and the recorder produce captures that every other tool opens.
//!
//! Layers, as in the rest of hilrig:
//! - [`reader`]: a streaming record reader on top of `pcap-parser` (memory bounded by its buffer,
//!   whatever the file size), giving `(interface, link type, time, bytes)` with file offsets;
//! - [`link`], [`ipv4`], [`can`]: pure decoders for link layers, IPv4 (with fragment
//!   reassembly) and UDP, and SocketCAN frames;
//! - [`demux`]: the two put together, yielding [`demux::Packet`]s and counting everything it
//!   skips by reason;
//! - [`writer`]: pcapng and pcap writers and frame builders.
//!
//! Serial ports are stored on interfaces with link type `LINKTYPE_USER0` (147) whose `if_name` is
//! the port (hilrig's convention, so that one pcapng holds a whole drive: lidar UDP, CAN and the
//! GNSS byte stream each on its own interface).

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod can;
pub mod demux;
pub mod error;
pub mod ipv4;
pub mod link;
pub mod reader;
pub mod writer;

pub use can::CanFrame;
pub use demux::{Demux, Packet, Stats};
pub use error::{CaptureError, SkipReason};
pub use hilrig_stamp::UtcNanos;
pub use link::LinkType;
pub use reader::{CaptureReader, Interface, Record};
pub use writer::{PcapWriter, PcapngWriter};

//! RTK GNSS driver: framing a mixed serial stream (NMEA 0183, UBX, RTCM3), decoding the sentences
//! and messages a reference trajectory needs, and assembling them into fixes.
//!
//! Sans-IO throughout: [`framer::Framer`] takes bytes and yields frames, the decoders are pure
//! functions of one frame, [`epoch::GnssStream`] chains them. The serial port shell
//! (`serial`, feature `tokio`) only moves bytes and stamps them.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod attitude;
pub mod epoch;
pub mod framer;
pub mod nmea;
#[cfg(feature = "tokio")]
pub mod serial;
pub mod ubx;

pub use attitude::{Attitude, AttitudeMode, AttitudeOf, AttitudeSource};
pub use epoch::{Fix, FixSource, GnssStream, RtkState};
pub use framer::{Frame, Framer, Item, RejectReason};

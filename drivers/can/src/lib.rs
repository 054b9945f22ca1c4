//! CAN ego data: a DBC database compiled for decoding and encoding frames, and candump logs.
//!
//! DBC files are parsed by `can-dbc` (it reads the opendbc files in shared/data/can as shipped,
//! which cantools does not); `can-dbc` only parses, so the signal codec is here: Intel and
//! Motorola byte order, signed and IEEE float signals, factor and offset, simple and extended
//! multiplexing, value tables, standard and extended ids, CAN FD payloads up to 64 bytes.
//! Frames are [`hilrig_capture::CanFrame`], the type the capture layer reads from SocketCAN
//! records, so captures, candump logs and live sockets meet in one type.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod candump;
pub mod codec;
pub mod dbc;
pub mod ego;
#[cfg(feature = "tokio")]
pub mod socketcan_source;

pub use dbc::{Database, DbcError, Decoded, MessageDef, SignalDef};
pub use hilrig_capture::CanFrame;

//! Velodyne lidar driver: data and position packets, decode and encode, calibration, firing
//! timing, rotation assembly and a UDP source.
//!
//! The core is sans-IO: [`DataPacket::decode`] and [`Decoder`] are pure functions of bytes (time
//! is passed in), which is what the tests, the fuzzers, the simulator and replay use. The tokio
//! UDP source ([`source`], feature `tokio`) is a thin shell that only moves bytes and stamps them.
//!
//! Supported: VLP-16, Puck Hi-Res, VLP-32A/B/C, HDL-32E, VLS-128, HDL-64E S2/S3, in strongest,
//! last and dual return.

#![warn(missing_docs)]

pub mod calibration;
pub mod check;
pub mod clock;
pub mod decode;
pub mod encode;
pub mod error;
pub mod model;
pub mod packet;
pub mod plausibility;
pub mod position;
pub mod rotation;
#[cfg(feature = "tokio")]
pub mod source;

pub use calibration::{Beam, Calibration};
pub use decode::{Decoder, LaserId, Point, ReturnType};
pub use encode::{PacketEncoder, Sequence};
pub use error::{CalibrationError, DecodeError};
pub use model::{Model, ProductId};
pub use packet::{Block, Channel, DataPacket, ReturnMode, DATA_PACKET_SIZE};
pub use position::{PositionPacket, PpsStatus, Rmc, POSITION_PACKET_SIZE};
pub use rotation::{LossCounter, RawDataPacket, Rotation, RotationAssembler, RotationPacket};

/// Default UDP port of data packets.
pub const DATA_PORT: u16 = 2368;
/// Default UDP port of position packets.
pub const POSITION_PORT: u16 = 8308;

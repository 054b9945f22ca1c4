//! Why a packet or calibration could not be used.
//!
//! Grouped by cause as in rustls: malformed input (the bytes are not a valid packet) versus
//! unsupported-but-valid input (a real packet of a kind hilrig does not decode). Each variant
//! carries what was expected and what was found, and where in the packet.

use crate::model::{Model, ProductId};

/// Block flags as they are on the wire, for messages (`FF EE, FF DD`).
fn flag_list(flags: &[u16]) -> String {
    flags
        .iter()
        .map(|f| format!("{:02X} {:02X}", f & 0xFF, f >> 8))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A packet that cannot be decoded.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum DecodeError {
    /// The payload is not the size of this packet type.
    #[error("wrong payload size: expected {expected} bytes, got {got}")]
    WrongSize {
        /// Expected size.
        expected: usize,
        /// Actual size.
        got: usize,
    },
    /// A block does not start with a Velodyne block flag (malformed bytes).
    #[error("block {block} at byte {offset} has flag {got:#06x}, which no Velodyne sensor writes (FF EE, or a bank's FF DD, FF CC, FF BB)")]
    BadBlockFlag {
        /// Block index 0-11.
        block: usize,
        /// Byte offset of the flag in the payload.
        offset: usize,
        /// The flag read (little-endian).
        got: u16,
    },
    /// A block carries a bank flag (`FF DD`, `FF CC`, `FF BB`) that the model does not send:
    /// another model's packet (the VLS-128's banks on a 32-laser sensor's port, say).
    #[error("block {block} at byte {offset} has the bank flag {got:#06x}, which a {model} does not send (it sends {})", flag_list(model.block_flags()))]
    ForeignBankFlag {
        /// Block index 0-11.
        block: usize,
        /// Byte offset of the flag in the payload.
        offset: usize,
        /// The flag read (little-endian).
        got: u16,
        /// The model the packet was checked as.
        model: Model,
    },
    /// In a dual-return packet (VLS-128, HDL-64E), a bank's two returns come in two blocks
    /// with the same flag; these two differ.
    #[error("block {block} at byte {offset} has flag {got:#06x}, but the other return of its bank has {pair:#06x}: a dual-return packet gives a bank's two returns in two blocks with one flag")]
    BankPairMismatch {
        /// Block index 0-11.
        block: usize,
        /// Byte offset of the flag in the payload.
        offset: usize,
        /// The flag read (little-endian).
        got: u16,
        /// The flag of the block it pairs with.
        pair: u16,
    },
    /// The product byte is not one the expected model writes: another sensor's packet.
    #[error("product byte {got:#04x} at byte 1205 is {}, not the {expected}'s ({:#04x}): another sensor sends to this port, or the rig names the wrong model", Model::describe_product(ProductId(*got)), expected.product().0)]
    OtherSensor {
        /// The product byte read.
        got: u8,
        /// The model the packet was checked as (the rig's).
        expected: Model,
    },
    /// A block azimuth above 360.00° (36000 itself is an HDL-32E quirk for 0° and accepted).
    #[error("block {block} azimuth at byte {offset} is {got}, above the maximum 36000 (360°)")]
    AzimuthOutOfRange {
        /// Block index 0-11.
        block: usize,
        /// Byte offset of the azimuth in the payload.
        offset: usize,
        /// The value read.
        got: u16,
    },
    /// The product byte names a sensor hilrig does not decode (and no model was forced).
    #[error(
        "product byte {0:#04x} at byte 1205 is not a model hilrig decodes; force one with --model"
    )]
    UnsupportedProduct(u8),
    /// The return-mode byte is not 0x37, 0x38 or 0x39.
    #[error("return mode byte {0:#04x} at byte 1204 is not strongest (0x37), last (0x38) or dual (0x39)")]
    UnsupportedReturnMode(u8),
}

/// A calibration file that cannot be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// The file could not be read.
    #[error("cannot read calibration file {path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// Not valid YAML of the ros-drivers calibration format.
    #[error("calibration is not in the ros-drivers YAML format: {0}")]
    Yaml(String),
    /// Not a VeloView XML calibration (`<DB>` with `<points_>` of `<px>` lasers).
    #[error("calibration is not a VeloView XML file: {0}")]
    Xml(String),
    /// Laser ids are missing, repeated, or do not match the model.
    #[error("calibration lasers are inconsistent: {0}")]
    Inconsistent(String),
    /// A correction hilrig does not apply (it would silently give wrong points).
    #[error("calibration uses {0}, which hilrig does not apply")]
    Unsupported(String),
}

//! Why a packet or calibration could not be used.
//!
//! Grouped by cause as in rustls: malformed input (the bytes are not a valid packet) versus
//! unsupported-but-valid input (a real packet of a kind hilrig does not decode). Each variant
//! carries what was expected and what was found, and where in the packet.

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
    /// A block does not start with `FF EE`.
    #[error("block {block} at byte {offset} has flag {got:#06x}, expected 0xeeff (bytes FF EE)")]
    BadBlockFlag {
        /// Block index 0-11.
        block: usize,
        /// Byte offset of the flag in the payload.
        offset: usize,
        /// The flag read (little-endian).
        got: u16,
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

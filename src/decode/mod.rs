//! Decoding captures and logs for `hilrig decode`: the capture layer and a driver put together,
//! with summaries of what was read and what was skipped.
//!
//! - [`lidar`]: Velodyne captures to points (also what the decode benchmarks measure);
//! - [`gnss`]: serial byte logs and capture serial interfaces to GNSS fixes;
//! - [`can`]: candump logs and capture SocketCAN interfaces to DBC-decoded frames;
//! - [`sinks`]: the CSV and JSON-lines writers for points.

pub mod can;
pub mod gnss;
pub mod lidar;
pub mod sinks;

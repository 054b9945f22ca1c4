//! MCAP files in the ROS 2 profile: CDR encoding, the contract's message types, and a writer
//! that keeps a recording safe (an `.active` file renamed on a clean finish, chunks closed at
//! least every second so that a cut-off file loses at most the last second).

pub mod cdr;
pub mod clock_sync;
pub mod info;
pub mod msgs;
pub mod packet_times;
pub mod read;
pub mod recover;
pub mod scans;
mod sync;
pub mod topics;
pub mod writer;

pub use writer::{BagError, BagOptions, BagWriter, Compression};

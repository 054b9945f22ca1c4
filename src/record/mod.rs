//! Recording: sensors into one time-synchronised MCAP (DESIGN.md, "the flow").
//!
//! - [`from_capture`]: `hilrig record --from`, captures and logs (pcap/pcapng, candump, serial
//!   byte logs) in two passes, clock models first;
//! - [`live`]: `hilrig record --rig R` on the vehicle, one task per source and a writer thread;
//! - [`clock`]: the per-source clock models (lower envelope of host - sensor) both use;
//! - [`rejects`]: the lidar packets left out, counted per reason, printed and written into the
//!   recording;
//! - [`gnss_stream`]: what each GNSS serial stream held (frames, bytes outside them, fixes with
//!   and without a date), judged per stream;
//! - [`messages`]: topic names and the conversion of driver output into the contract's ROS 2
//!   messages, so that both recorders write the same bytes.
//!
//! The MCAP writer itself, the CDR encoding and the message schemas are in [`crate::bag`].

pub mod clock;
pub mod from_capture;
pub mod gnss_stream;
pub mod live;
pub mod messages;
pub mod rejects;

pub use from_capture::{record_from, CaptureSkips, RecordError, RecordSummary};

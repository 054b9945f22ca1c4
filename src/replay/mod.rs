//! `hilrig replay`: a recording, capture or re-simulation played back to a device under test at
//! the original pace.
//!
//! - [`load`]: the file as one time-ordered schedule of [`ReplayItem`]s (captures in file order,
//!   MCAP messages by log time; several files merged by time), cut to a `--start`/`--end`
//!   window;
//! - [`pacing`]: the player. Item `i` is due at `wall_start + (t_i - t_first) / speed`, an
//!   absolute deadline, so errors never accumulate over long runs; the sender sleeps until
//!   shortly before a deadline and spins the rest, which keeps the lag (send time minus deadline)
//!   in the microseconds; the lag of every send is kept and its p50, p99 and maximum reported;
//! - [`sink`]: where items go (UDP, a serial device or a new pty, SocketCAN), behind one small
//!   trait so that the player is tested without sockets;
//! - [`now`]: `--now`, Velodyne timestamps and position packets rewritten to the present.

pub mod load;
pub mod now;
pub mod pacing;
pub mod sink;

pub use load::{
    load, schedule, stream, window, MergeByTime, Payload, ReplayError, ReplayItem, Streamed,
};
pub use pacing::{play, play_stream, stop_on_signals, wait_until, Pacing, PlayOptions, Played};
pub use sink::{Destinations, Sink, SinkError};

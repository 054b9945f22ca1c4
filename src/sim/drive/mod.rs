//! A planned drive (`drive.toml`) and how a human drives it: the path, the speed profile, a
//! stop for a crossing walker, and the variation between repetitions.
//!
//! ```toml
//! name = "parking, third slot on the left"
//! start_utc = "2026-11-21T10:00:00Z"
//! rig = "../../rigs/demo.toml"        # sensors, mounting, lever arm, DBC (relative to this file)
//!
//! [path]                              # rear-axle centre in the scene's local frame
//! waypoints = [[-16.0, 0.0], [0.0, 0.0], [6.0, 2.5], [7.0, 6.0]]
//! cruise_speed_mps = 2.2
//!
//! [[walker]]                          # an actor of the scene walking a straight line
//! actor = "pedestrian"
//! from = [3.0, -6.0]
//! to = [3.0, 6.0]
//! speed_mps = 1.0
//! start_s = 2.0                       # after the drive's start
//!
//! [yield_to]                          # the ego waits for this walker
//! walker = "pedestrian"
//! stop_at_m = 8.0                     # arc length of the stop line
//! ```
//!
//! A parking manoeuvre backs up after the last waypoint (`[path.reverse]`, see
//! [`ReverseLeg`]):
//!
//! ```toml
//! [path.reverse]
//! waypoints = [[5.0, 3.5], [4.0, 6.0]]  # after backing straight from the path's end
//! speed_mps = 1.0
//! pause_s = 1.0                         # standing at the turn-around point
//! ```
//!
//! The sensor, GNSS, CAN and survey error sections are documented on their structs.
//!
//! Three files, each read for a different reason: `file.rs` is the format as a user writes it
//! (every table, its defaults, loading it and the errors naming it), `path.rs` the geometry the
//! planned path is made of (the spline through the waypoints and the steering that ramps its
//! curvature), and `driven.rs` the driver that turns a drive file into one repetition's
//! trajectory ([`Driven`]). The format's documentation then reads without the driver's loops, and the
//! geometry without either. `backing.rs` splits a drive that backs up into its two legs and
//! turns the second round.

mod backing;
mod driven;
mod file;
mod path;

pub use driven::Driven;
pub use file::{
    beyond_text, parse_utc, AgeFault, CanStream, DriveError, DriveFile, Faults, FreeClock,
    GnssStream, HeadingStream, JumpFault, LidarStream, PathSpec, ReverseLeg, RtkFault, SigmaFault,
    Survey, Variation, WalkerSpec, Window, YieldSpec, BACKING_UP,
};

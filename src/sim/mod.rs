//! Simulation: the lidar model (Rosenberger et al. 2019, Table 1: idealized ray casting plus named effects), the
//! spinning-sensor schedule, and the synthesis of whole measured drives.

pub mod drivable;
pub mod drive;
pub mod hit_log;
pub mod lidar;
pub mod model;
pub mod pattern;
pub mod resim;
mod sim_file;
pub mod spin;
mod streams;
pub mod synth;

pub use lidar::{Echo, LidarSim, PacketTime, Returns, SimStats};
pub use model::{Effect, FootprintPattern, ModelFile};

//! hilrig: a hardware-in-the-loop recorder and replay rig for validating lidar sensor models.
//!
//! The library holds the rig (DESIGN.md, `src/`): it knows the drivers only through their public
//! types. The `hilrig` binary is a thin CLI over it.

#![warn(missing_docs)]

pub mod bag;
pub mod can_log;
pub mod clock;
pub mod geodesy;
pub mod gnss_log;
pub mod lidar;
pub mod points_out;
pub mod pose;
pub mod record;
pub mod record_live;
pub mod reference;
pub mod replay;
pub mod rig;
pub mod scene;
pub mod sim;

pub use hilrig_can as can;
pub use hilrig_capture as capture;
pub use hilrig_gnss as gnss;
pub use hilrig_stamp as stamp;
pub use hilrig_velodyne as velodyne;

//! hilrig: a hardware-in-the-loop recorder and replay rig for validating lidar sensor models.
//!
//! The library holds the rig (DESIGN.md, `src/`): it knows the drivers only through their public
//! types. The `hilrig` binary is a thin command line over it (`src/cli/`, one module per
//! command). Each folder is one step of DESIGN.md's flow:
//!
//! - [`decode`]: captures and logs to points, fixes and frames (`hilrig decode`);
//! - [`record`]: captures and live sensors into one time-synchronised MCAP, with the per-source
//!   clock models (`hilrig record`);
//! - [`bag`]: MCAP in the ROS 2 profile: CDR, the contract's topics and message types, the
//!   writer, a checked reader, `info` and `recover`;
//! - [`replay`]: recordings and captures back out at the original pace (`hilrig replay`);
//! - [`reference`]: the ego trajectory from RTK GNSS and CAN, and `check`;
//! - [`scene`]: the digital twin (objects, actors, the WGS84/ENU frame, poses and trajectories);
//! - [`sim`]: the lidar model and its effects, `synth` and `resim`;
//! - [`estimate`]: estimators shared by the steps (median, robust sigma, rank correlation);
//! - [`metrics`]: a run against its re-simulation, scan by scan (`hilrig compare`);
//! - [`gap`]: the gap workflow: the missing effect found, fitted and validated (`hilrig gap`);
//! - [`stats`]: over repetitions: area validation metric, traffic lights, rank correlation;
//! - [`output`]: the JSON files the commands write, one typed struct per kind in an envelope;
//! - [`campaign`]: many drives through the steps above, planned as a graph of commands and run
//!   here, resumable (`hilrig campaign`);
//! - [`report`]: the HTML validation report from the JSON the steps write (`hilrig report`);
//! - [`rig`]: the rig file every step reads (sensors, mounting, ports, thresholds).

#![warn(missing_docs)]
#![warn(clippy::too_many_lines)]

pub mod bag;
pub mod campaign;
pub mod config;
pub mod decode;
pub mod estimate;
pub mod gap;
pub mod metrics;
pub mod output;
pub mod record;
pub mod reference;
pub mod replay;
pub mod report;
pub mod rig;
pub mod scene;
pub mod sim;
pub mod stats;

pub use hilrig_can as can;
pub use hilrig_capture as capture;
pub use hilrig_gnss as gnss;
pub use hilrig_stamp as stamp;
pub use hilrig_velodyne as velodyne;

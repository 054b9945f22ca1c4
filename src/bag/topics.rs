//! Topics of the MCAP contract (DESIGN.md): what the recorders write and what replay, check
//! and re-simulation read.

/// VelodyneScan per rotation.
pub const VELODYNE_PACKETS: &str = "/velodyne_packets";
/// Position packets.
pub const VELODYNE_POSITION: &str = "/velodyne_position";
/// NMEA sentences.
pub const GNSS_NMEA: &str = "/gnss/nmea";
/// UBX frames.
pub const GNSS_UBX: &str = "/gnss/ubx";
/// Fixes.
pub const GNSS_FIX: &str = "/gnss/fix";
/// Attitude reports of the reference system (INS, dual antenna): `hilrig_msgs/msg/Attitude`.
pub const GNSS_ATTITUDE: &str = "/gnss/attitude";
/// CAN frames.
pub const CAN_FRAMES: &str = "/can/frames";
/// Ego speed and yaw rate.
pub const EGO_TWIST: &str = "/ego/twist";
/// Rig extrinsics.
pub const TF_STATIC: &str = "/tf_static";
/// Decoded lidar points per rotation, for viewing.
pub const POINTS: &str = "/points";

/// The metadata record of the lidar's clock synchronisation.
pub const CLOCK_SYNC_LIDAR: &str = "clock_sync/lidar";

/// The key, in [`CLOCK_SYNC_LIDAR`], of the lidar's PPS state.
pub const PPS_KEY: &str = "pps";

/// How a PPS state is written into the metadata, and read back: the one spelling both sides
/// use (a reader that compared with its own literal would take every run for unlocked, and
/// place its points by the host's receive time, if the writer's spelling ever changed).
pub fn pps_text(status: hilrig_velodyne::PpsStatus) -> String {
    format!("{status:?}")
}

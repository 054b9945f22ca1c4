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
/// RTCM3 frames the receiver sent (a moving base's corrections for its rover), whole:
/// `hilrig_msgs/msg/RawPacket`.
pub const GNSS_RTCM: &str = "/gnss/rtcm";
/// Bytes of the GNSS serial stream that belonged to no NMEA, UBX or RTCM3 frame (another
/// protocol the receiver interleaves, a frame cut off at the start, a rejected frame's bytes),
/// each run as it came: `hilrig_msgs/msg/RawPacket`. With the frames, the stream again, byte
/// for byte; replay sends them too.
pub const GNSS_UNFRAMED: &str = "/gnss/unframed";
/// Fixes.
pub const GNSS_FIX: &str = "/gnss/fix";
/// Attitude reports of the reference system (INS, dual antenna): `hilrig_msgs/msg/Attitude`.
pub const GNSS_ATTITUDE: &str = "/gnss/attitude";
/// Classic CAN frames: `can_msgs/msg/Frame`.
pub const CAN_FRAMES: &str = "/can/frames";
/// CAN FD frames, which `can_msgs/msg/Frame` cannot hold: `hilrig_msgs/msg/RawPacket` with
/// the frame as a SocketCAN `canfd_frame` (its own topic: one topic has one message type).
pub const CAN_FD_FRAMES: &str = "/can/fd_frames";
/// Ego speed and yaw rate.
pub const EGO_TWIST: &str = "/ego/twist";
/// Rig extrinsics.
pub const TF_STATIC: &str = "/tf_static";
/// Decoded lidar points per rotation, for viewing.
pub const POINTS: &str = "/points";

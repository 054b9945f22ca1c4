//! The ROS 2 message types of the MCAP contract (DESIGN.md), with their `ros2msg` schema text as
//! MCAP stores it (the type's definition, then each dependency after a line of `=` and
//! `MSG: pkg/Type`), and CDR encoders.
//!
//! Definitions are the standard ones of the ROS 2 packages named, so Foxglove and `ros2 bag`
//! read the files without conversion; `hilrig_msgs/RawPacket` is hilrig's own for byte payloads
//! without a standard message (Velodyne position packets, UBX frames).

use super::cdr::CdrWriter;
use hilrig_stamp::UtcNanos;

const SEP: &str =
    "================================================================================\n";

const TIME: &str = "int32 sec\nuint32 nanosec\n";
const HEADER: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";

fn with_deps(top: &str, deps: &[(&str, &str)]) -> String {
    let mut s = top.to_owned();
    for (name, def) in deps {
        s.push_str(SEP);
        s.push_str(&format!("MSG: {name}\n"));
        s.push_str(def);
    }
    s
}

/// A message type: its name and schema text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MessageType {
    /// `pkg/msg/Type`.
    pub name: &'static str,
    /// `ros2msg` schema text with dependencies.
    pub schema: String,
}

/// `velodyne_msgs/msg/VelodyneScan`.
pub fn velodyne_scan_type() -> MessageType {
    MessageType {
        name: "velodyne_msgs/msg/VelodyneScan",
        schema: with_deps(
            "std_msgs/Header header\nvelodyne_msgs/VelodynePacket[] packets\n",
            &[
                ("std_msgs/Header", HEADER),
                ("builtin_interfaces/Time", TIME),
                (
                    "velodyne_msgs/VelodynePacket",
                    "builtin_interfaces/Time stamp\nuint8[1206] data\n",
                ),
            ],
        ),
    }
}

/// `hilrig_msgs/msg/RawPacket`.
pub fn raw_packet_type() -> MessageType {
    MessageType {
        name: "hilrig_msgs/msg/RawPacket",
        schema: with_deps(
            "# A payload with no standard message: Velodyne position packets, UBX frames.\nstd_msgs/Header header\nuint8[] data\n",
            &[("std_msgs/Header", HEADER), ("builtin_interfaces/Time", TIME)],
        ),
    }
}

/// `nmea_msgs/msg/Sentence`.
pub fn nmea_sentence_type() -> MessageType {
    MessageType {
        name: "nmea_msgs/msg/Sentence",
        schema: with_deps(
            "std_msgs/Header header\nstring sentence\n",
            &[
                ("std_msgs/Header", HEADER),
                ("builtin_interfaces/Time", TIME),
            ],
        ),
    }
}

/// `sensor_msgs/msg/NavSatFix`.
pub fn nav_sat_fix_type() -> MessageType {
    MessageType {
        name: "sensor_msgs/msg/NavSatFix",
        schema: with_deps(
            "uint8 COVARIANCE_TYPE_UNKNOWN=0\nuint8 COVARIANCE_TYPE_APPROXIMATED=1\nuint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\nstd_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\nfloat64 longitude\nfloat64 altitude\nfloat64[9] position_covariance\nuint8 position_covariance_type\n",
            &[
                ("std_msgs/Header", HEADER),
                ("builtin_interfaces/Time", TIME),
                (
                    "sensor_msgs/NavSatStatus",
                    "int8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\nint8 STATUS_GBAS_FIX=2\nint8 status\nuint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\nuint16 SERVICE_COMPASS=4\nuint16 SERVICE_GALILEO=8\nuint16 service\n",
                ),
            ],
        ),
    }
}

/// `hilrig_msgs/msg/Attitude`: one attitude report of the reference system (an INS or a
/// dual-antenna receiver), as the GNSS driver reads it. No standard message fits: a heading
/// sensor reports the heading alone (HDT, THS), and `sensor_msgs/Imu` cannot say that roll and
/// pitch are unknown while the heading is known. Angles absent from the message are NaN.
pub fn attitude_type() -> MessageType {
    MessageType {
        name: "hilrig_msgs/msg/Attitude",
        schema: with_deps(
            concat!(
                "# The message the report came from.\n",
                "uint8 SOURCE_HDT=0\nuint8 SOURCE_THS=1\nuint8 SOURCE_PASHR=2\nuint8 SOURCE_PSTI_036=3\n",
                "uint8 SOURCE_NAV_ATT=4\nuint8 SOURCE_NAV_PVAT=5\nuint8 SOURCE_NAV_RELPOSNED=6\n",
                "uint8 SOURCE_HNR_ATT=7\nuint8 SOURCE_ESF_ALG=8\n",
                "# What it is the attitude of: the vehicle, or the receiver's IMU in the vehicle.\n",
                "uint8 OF_VEHICLE=0\nuint8 OF_SENSOR_MOUNTING=1\n",
                "# How the source obtained it.\n",
                "uint8 MODE_MEASURED=0\nuint8 MODE_ESTIMATED=1\nuint8 MODE_MANUAL=2\nuint8 MODE_SIMULATOR=3\n",
                "std_msgs/Header header\n",
                "uint8 source\nuint8 of\nuint8 mode\n",
                "# Degrees; heading clockwise from true north; NaN where the message has none.\n",
                "float64 heading_deg\nfloat64 yaw_deg\nfloat64 pitch_deg\nfloat64 roll_deg\n",
                "# Accuracies (1 sigma) as the message states them, degrees; NaN where it states none.\n",
                "float64 sigma_heading_deg\nfloat64 sigma_pitch_deg\nfloat64 sigma_roll_deg\n",
            ),
            &[("std_msgs/Header", HEADER), ("builtin_interfaces/Time", TIME)],
        ),
    }
}

/// An attitude report as `hilrig_msgs/msg/Attitude` (see [`attitude_type`]).
pub fn attitude(stamp: UtcNanos, frame_id: &str, a: &hilrig_gnss::Attitude) -> Vec<u8> {
    use hilrig_gnss::{AttitudeMode, AttitudeOf, AttitudeSource as S};
    let mut w = CdrWriter::with_capacity(128);
    header(&mut w, stamp, frame_id);
    let source = match a.source {
        S::Hdt => 0,
        S::Ths => 1,
        S::Pashr => 2,
        S::Psti036 => 3,
        S::NavAtt => 4,
        S::NavPvat => 5,
        S::NavRelposned => 6,
        S::HnrAtt => 7,
        S::EsfAlg => 8,
    };
    let of = match a.of {
        AttitudeOf::Vehicle => 0,
        AttitudeOf::SensorMounting => 1,
    };
    let mode = match a.mode {
        AttitudeMode::Measured => 0,
        AttitudeMode::Estimated => 1,
        AttitudeMode::Manual => 2,
        AttitudeMode::Simulator => 3,
    };
    w.u8(source).u8(of).u8(mode);
    for v in [
        a.heading_deg,
        a.yaw_deg,
        a.pitch_deg,
        a.roll_deg,
        a.sigma_heading_deg,
        a.sigma_pitch_deg,
        a.sigma_roll_deg,
    ] {
        w.f64(v.unwrap_or(f64::NAN));
    }
    w.finish()
}

/// `can_msgs/msg/Frame`.
pub fn can_frame_type() -> MessageType {
    MessageType {
        name: "can_msgs/msg/Frame",
        schema: with_deps(
            "std_msgs/Header header\nuint32 id\nbool is_rtr\nbool is_extended\nbool is_error\nuint8 dlc\nuint8[8] data\n",
            &[("std_msgs/Header", HEADER), ("builtin_interfaces/Time", TIME)],
        ),
    }
}

/// `geometry_msgs/msg/TwistStamped`.
pub fn twist_stamped_type() -> MessageType {
    MessageType {
        name: "geometry_msgs/msg/TwistStamped",
        schema: with_deps(
            "std_msgs/Header header\ngeometry_msgs/Twist twist\n",
            &[
                ("std_msgs/Header", HEADER),
                ("builtin_interfaces/Time", TIME),
                (
                    "geometry_msgs/Twist",
                    "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n",
                ),
                ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
            ],
        ),
    }
}

fn time(w: &mut CdrWriter, t: UtcNanos) {
    let (s, n) = t.secs_nanos();
    w.i32(s.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32)
        .u32(n);
}

fn header(w: &mut CdrWriter, t: UtcNanos, frame_id: &str) {
    time(w, t);
    w.string(frame_id);
}

/// A VelodyneScan: the packets of one rotation with their host stamps.
pub fn velodyne_scan(
    stamp: UtcNanos,
    frame_id: &str,
    packets: &[(UtcNanos, &[u8; 1206])],
) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(64 + packets.len() * 1216);
    header(&mut w, stamp, frame_id);
    w.sequence_len(packets.len());
    for (t, data) in packets {
        time(&mut w, *t);
        w.fixed_bytes(&data[..]);
    }
    w.finish()
}

/// A RawPacket.
pub fn raw_packet(stamp: UtcNanos, frame_id: &str, data: &[u8]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(32 + data.len());
    header(&mut w, stamp, frame_id);
    w.bytes(data);
    w.finish()
}

/// An NMEA sentence.
pub fn nmea_sentence(stamp: UtcNanos, frame_id: &str, sentence: &str) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(32 + sentence.len());
    header(&mut w, stamp, frame_id);
    w.string(sentence);
    w.finish()
}

/// The fields of a NavSatFix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavSatFix {
    /// -1 no fix, 0 fix, 1 SBAS, 2 GBAS (RTK and DGPS).
    pub status: i8,
    /// Bit mask of constellations (1 GPS).
    pub service: u16,
    /// Degrees.
    pub latitude: f64,
    /// Degrees.
    pub longitude: f64,
    /// Metres above the WGS84 ellipsoid.
    pub altitude: f64,
    /// ENU covariance, row-major, m².
    pub covariance: [f64; 9],
    /// 0 unknown, 1 approximated, 2 diagonal known, 3 known.
    pub covariance_type: u8,
}

/// A NavSatFix.
pub fn nav_sat_fix(stamp: UtcNanos, frame_id: &str, f: &NavSatFix) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(160);
    header(&mut w, stamp, frame_id);
    w.i8(f.status)
        .u16(f.service)
        .f64(f.latitude)
        .f64(f.longitude)
        .f64(f.altitude);
    for c in f.covariance {
        w.f64(c);
    }
    w.u8(f.covariance_type);
    w.finish()
}

/// A can_msgs/Frame (classic CAN: FD payloads do not fit its 8 data bytes and are recorded as
/// RawPacket by the recorder).
pub fn can_frame(stamp: UtcNanos, frame_id: &str, f: &hilrig_capture::CanFrame) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(64);
    header(&mut w, stamp, frame_id);
    let mut data = [0u8; 8];
    let d = f.data();
    data[..d.len().min(8)].copy_from_slice(&d[..d.len().min(8)]);
    w.u32(f.id)
        .bool(f.rtr)
        .bool(f.extended)
        .bool(f.error)
        .u8(f.len().min(8) as u8)
        .fixed_bytes(&data);
    w.finish()
}

/// A TwistStamped: linear x (forward speed, m/s) and angular z (yaw rate, rad/s).
pub fn twist_stamped(
    stamp: UtcNanos,
    frame_id: &str,
    linear: [f64; 3],
    angular: [f64; 3],
) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(96);
    header(&mut w, stamp, frame_id);
    for v in linear.iter().chain(&angular) {
        w.f64(*v);
    }
    w.finish()
}

/// `tf2_msgs/msg/TFMessage`.
pub fn tf_message_type() -> MessageType {
    MessageType {
        name: "tf2_msgs/msg/TFMessage",
        schema: with_deps(
            "geometry_msgs/TransformStamped[] transforms\n",
            &[
                ("geometry_msgs/TransformStamped", "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n"),
                ("std_msgs/Header", HEADER),
                ("builtin_interfaces/Time", TIME),
                ("geometry_msgs/Transform", "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n"),
                ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n"),
                ("geometry_msgs/Quaternion", "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"),
            ],
        ),
    }
}

/// One static transform: `child` in `parent`, translation in metres, rotation as roll, pitch,
/// yaw in radians (applied yaw, then pitch, then roll: the ROS RPY convention).
#[derive(Clone, Debug, PartialEq)]
pub struct Transform {
    /// Parent frame.
    pub parent: String,
    /// Child frame.
    pub child: String,
    /// Translation x, y, z.
    pub translation: [f64; 3],
    /// Roll, pitch, yaw.
    pub rpy: [f64; 3],
}

/// Quaternion (x, y, z, w) of roll, pitch, yaw.
pub fn quaternion_from_rpy(roll: f64, pitch: f64, yaw: f64) -> [f64; 4] {
    let (sr, cr) = (roll * 0.5).sin_cos();
    let (sp, cp) = (pitch * 0.5).sin_cos();
    let (sy, cy) = (yaw * 0.5).sin_cos();
    [
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    ]
}

/// A TFMessage with static transforms.
pub fn tf_message(stamp: UtcNanos, transforms: &[Transform]) -> Vec<u8> {
    let mut w = CdrWriter::with_capacity(128 * transforms.len() + 8);
    w.sequence_len(transforms.len());
    for t in transforms {
        header(&mut w, stamp, &t.parent);
        w.string(&t.child);
        for v in t.translation {
            w.f64(v);
        }
        for v in quaternion_from_rpy(t.rpy[0], t.rpy[1], t.rpy[2]) {
            w.f64(v);
        }
    }
    w.finish()
}

/// `sensor_msgs/msg/PointCloud2`.
pub fn point_cloud2_type() -> MessageType {
    MessageType {
        name: "sensor_msgs/msg/PointCloud2",
        schema: with_deps(
            "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\nbool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
            &[
                ("std_msgs/Header", HEADER),
                ("builtin_interfaces/Time", TIME),
                (
                    "sensor_msgs/PointField",
                    "uint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\nuint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n",
                ),
            ],
        ),
    }
}

/// Bytes per point of [`point_cloud2`]: x, y, z, intensity (float32), ring (uint16, 2 bytes
/// padding), time (float32, seconds after the header stamp) — the layout of ros-drivers'
/// `velodyne_pointcloud`, so existing tools read it.
pub const POINT_STEP: usize = 24;

/// A PointCloud2 of decoded lidar points (one rotation), for viewing.
pub fn point_cloud2(
    stamp: UtcNanos,
    frame_id: &str,
    points: &[(f32, f32, f32, f32, u16, f32)],
) -> Vec<u8> {
    let mut cloud = PointCloudWriter::new(stamp, frame_id, points.len());
    for &(x, y, z, i, ring, t) in points {
        cloud.push(x, y, z, i, ring, t);
    }
    cloud.finish()
}

/// A [`point_cloud2`] written point by point straight into the message: a rotation of a 128-beam
/// sensor is 240 000 points, and re-simulation writes one every 100 ms, so the points are not
/// collected first and copied twice (as a list, then as the data field).
pub struct PointCloudWriter {
    buf: Vec<u8>,
    /// Where `width`, `row_step` and the data's length prefix are (placeholders until the end).
    width_at: usize,
    row_step_at: usize,
    data_len_at: usize,
    points: u32,
}

impl PointCloudWriter {
    /// A cloud stamped `stamp` in `frame_id`, with room for `capacity` points.
    pub fn new(stamp: UtcNanos, frame_id: &str, capacity: usize) -> PointCloudWriter {
        let mut w = CdrWriter::with_capacity(160 + capacity * POINT_STEP);
        header(&mut w, stamp, frame_id);
        w.u32(1);
        // Every placeholder follows a u32, so it is aligned already: it starts at `len()`.
        let width_at = w.len();
        w.u32(0);
        let fields: [(&str, u32, u8); 6] = [
            ("x", 0, 7),
            ("y", 4, 7),
            ("z", 8, 7),
            ("intensity", 12, 7),
            ("ring", 16, 4),
            ("time", 20, 7),
        ];
        w.sequence_len(fields.len());
        for (name, offset, datatype) in fields {
            w.string(name).u32(offset).u8(datatype).u32(1);
        }
        w.bool(false).u32(POINT_STEP as u32);
        let row_step_at = w.len();
        w.u32(0);
        let data_len_at = w.len();
        w.u32(0);
        PointCloudWriter {
            buf: w.finish(),
            width_at,
            row_step_at,
            data_len_at,
            points: 0,
        }
    }

    /// Appends one point: position, intensity, ring, seconds after the stamp.
    #[inline]
    pub fn push(&mut self, x: f32, y: f32, z: f32, intensity: f32, ring: u16, time: f32) {
        let mut p = [0u8; POINT_STEP];
        p[0..4].copy_from_slice(&x.to_le_bytes());
        p[4..8].copy_from_slice(&y.to_le_bytes());
        p[8..12].copy_from_slice(&z.to_le_bytes());
        p[12..16].copy_from_slice(&intensity.to_le_bytes());
        p[16..18].copy_from_slice(&ring.to_le_bytes());
        p[20..24].copy_from_slice(&time.to_le_bytes());
        self.buf.extend_from_slice(&p);
        self.points += 1;
    }

    /// The encoded message.
    pub fn finish(mut self) -> Vec<u8> {
        let bytes = self.points * POINT_STEP as u32;
        for (at, v) in [
            (self.width_at, self.points),
            (self.row_step_at, bytes),
            (self.data_len_at, bytes),
        ] {
            self.buf[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
        // is_dense
        self.buf.push(1);
        self.buf
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_of_a_quarter_turn_in_yaw() {
        let q = quaternion_from_rpy(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for (a, b) in q.iter().zip([0.0, 0.0, h, h]) {
            assert!((a - b).abs() < 1e-12, "{q:?}");
        }
    }

    /// The cloud written point by point reads back as a PointCloud2: width, row step and the
    /// data's length prefix are set at the end, points are 24 bytes in the velodyne_pointcloud
    /// layout, is_dense closes the message.
    #[test]
    fn point_clouds_read_back_field_by_field() {
        use crate::bag::cdr::CdrReader;
        let points = [
            (1.5f32, -2.0f32, 0.25f32, 40.0f32, 7u16, 0.01f32),
            (-3.0, 4.5, 1.0, 100.0, 31, 0.099),
            (0.0, 0.0, -1.75, 0.0, 0, 0.0),
        ];
        let stamp = UtcNanos(1_795_255_200_123_456_789);
        let bytes = point_cloud2(stamp, "velodyne", &points);
        let mut r = CdrReader::new(&bytes).unwrap();
        assert_eq!(r.header(), Some(stamp));
        assert_eq!((r.u32(), r.u32()), (Some(1), Some(3)));
        let fields = r.u32().unwrap();
        let mut names = Vec::new();
        for _ in 0..fields {
            names.push(r.string().unwrap().to_owned());
            let (offset, datatype) = (r.u32().unwrap(), r.bytes(1).unwrap()[0]);
            assert_eq!(r.u32(), Some(1));
            names.push(format!("{offset}:{datatype}"));
        }
        assert_eq!(
            names.join(" "),
            "x 0:7 y 4:7 z 8:7 intensity 12:7 ring 16:4 time 20:7"
        );
        assert_eq!(r.bytes(1), Some(&[0u8][..]), "is_bigendian");
        assert_eq!((r.u32(), r.u32()), (Some(24), Some(72)));
        assert_eq!(r.u32(), Some(72));
        let data = r.bytes(72).unwrap();
        for (p, q) in points.iter().zip(data.chunks(24)) {
            let f = |k: usize| f32::from_le_bytes(q[k..k + 4].try_into().unwrap());
            assert_eq!((f(0), f(4), f(8), f(12), f(20)), (p.0, p.1, p.2, p.3, p.5));
            assert_eq!(u16::from_le_bytes([q[16], q[17]]), p.4);
            assert_eq!(&q[18..20], &[0, 0]);
        }
        assert_eq!(r.bytes(1), Some(&[1u8][..]), "is_dense");
        assert_eq!(r.bytes(1), None, "nothing after is_dense");
        // No points: a valid empty cloud.
        let empty = point_cloud2(stamp, "velodyne", &[]);
        assert_eq!(empty.len() + 72, bytes.len());
    }
}

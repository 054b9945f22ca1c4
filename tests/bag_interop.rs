//! The MCAP contract checked by independent readers (issue 4, items 1 and 2, for the bag layer):
//! the PyPI `mcap` reader with CRC validation finds the ROS 2 profile, topics, types and counts,
//! and `rosbags` decodes every contract message type's CDR to the values written.

use crate::common;

use hilrig::bag::msgs;
use hilrig::bag::{BagOptions, BagWriter, Compression};
use hilrig::capture::CanFrame;
use hilrig::stamp::UtcNanos;
use std::collections::BTreeMap;

fn read(path: &std::path::Path, decode: &[&str]) -> serde_json::Value {
    let args: Vec<&str> = decode.iter().flat_map(|t| ["--decode", t]).collect();
    common::mcap_json(path, &args)
}

#[test]
#[cfg_attr(
    not(hilrig_python),
    ignore = "needs HILRIG_PYTHON (set by .ci/run): did not run"
)]
fn every_contract_type_reads_back_with_mcap_and_rosbags() {
    for compression in [Compression::Zstd, Compression::Lz4, Compression::None] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.mcap");
        let mut w = BagWriter::create(
            &path,
            &BagOptions {
                compression,
                ..BagOptions::default()
            },
        )
        .unwrap();
        assert!(
            dir.path().join("t.mcap.active").exists(),
            "writes to .active first"
        );
        let t0 = UtcNanos(1_700_000_000_123_456_789);
        let mut packet = [0u8; 1206];
        for (i, b) in packet.iter_mut().enumerate() {
            *b = i as u8;
        }
        // 3 s of data: chunks close every second of log time.
        for k in 0..30i64 {
            let t = UtcNanos(t0.0 + k * 100_000_000);
            w.write(
                "/velodyne_packets",
                &msgs::velodyne_scan_type(),
                t,
                t,
                &msgs::velodyne_scan(
                    t,
                    "velodyne",
                    &[(t, &packet), (UtcNanos(t.0 + 1327), &packet)],
                ),
            )
            .unwrap();
            w.write(
                "/gnss/nmea",
                &msgs::nmea_sentence_type(),
                t,
                t,
                &msgs::nmea_sentence(t, "gnss", "$GPGGA,1*00"),
            )
            .unwrap();
            let fix = msgs::NavSatFix {
                status: 2,
                service: 1,
                latitude: 48.117_3,
                longitude: 11.516_6,
                altitude: 545.4 + k as f64,
                covariance: [0.0001, 0.0, 0.0, 0.0, 0.0004, 0.0, 0.0, 0.0, 0.0009],
                covariance_type: 2,
            };
            w.write(
                "/gnss/fix",
                &msgs::nav_sat_fix_type(),
                t,
                t,
                &msgs::nav_sat_fix(t, "gnss", &fix),
            )
            .unwrap();
            let frame = CanFrame::new(0x18DA_F110, true, &[1, 2, 3]).unwrap();
            w.write(
                "/can/frames",
                &msgs::can_frame_type(),
                t,
                UtcNanos(t.0 + 5),
                &msgs::can_frame(t, "can0", &frame),
            )
            .unwrap();
            w.write(
                "/ego/twist",
                &msgs::twist_stamped_type(),
                t,
                t,
                &msgs::twist_stamped(t, "base_link", [10.0, 0.0, 0.0], [0.0, 0.0, -0.25]),
            )
            .unwrap();
            w.write(
                "/velodyne_position",
                &msgs::raw_packet_type(),
                t,
                t,
                &msgs::raw_packet(t, "velodyne", &[7; 512]),
            )
            .unwrap();
        }
        let mut meta = BTreeMap::new();
        meta.insert("rig".to_owned(), "demo".to_owned());
        w.metadata("hilrig", meta).unwrap();
        w.attach("rig.toml", "application/toml", b"name = \"demo\"\n", t0)
            .unwrap();
        w.finish().unwrap();
        assert!(
            path.exists() && !dir.path().join("t.mcap.active").exists(),
            "renamed on finish"
        );

        let v = read(
            &path,
            &[
                "/velodyne_packets",
                "/gnss/fix",
                "/can/frames",
                "/ego/twist",
                "/gnss/nmea",
                "/velodyne_position",
            ],
        );
        assert_eq!(v["profile"], "ros2");
        // No chunk spans more than a second of log time: a cut-off file loses at most that.
        let chunks = v["chunks"].as_array().unwrap();
        assert!(chunks.len() >= 3, "{chunks:?}");
        for c in chunks {
            let span = c["end"].as_u64().unwrap() - c["start"].as_u64().unwrap();
            assert!(span < 1_000_000_000, "chunk spans {span} ns");
            let expected = match compression {
                Compression::Zstd => "zstd",
                Compression::Lz4 => "lz4",
                Compression::None => "",
            };
            assert_eq!(c["compression"], expected);
        }
        for (topic, ty) in [
            ("/velodyne_packets", "velodyne_msgs/msg/VelodyneScan"),
            ("/gnss/nmea", "nmea_msgs/msg/Sentence"),
            ("/gnss/fix", "sensor_msgs/msg/NavSatFix"),
            ("/can/frames", "can_msgs/msg/Frame"),
            ("/ego/twist", "geometry_msgs/msg/TwistStamped"),
            ("/velodyne_position", "hilrig_msgs/msg/RawPacket"),
        ] {
            let c = &v["channels"][topic];
            assert_eq!(c["type"], ty, "{topic}");
            assert_eq!(c["encoding"], "cdr");
            assert_eq!(c["schema_encoding"], "ros2msg");
            assert_eq!(c["count"], 30, "{topic}");
        }
        let scan = &v["messages"]["/velodyne_packets"][0];
        assert_eq!(scan["header"]["stamp"]["sec"], 1_700_000_000);
        assert_eq!(scan["header"]["stamp"]["nanosec"], 123_456_789);
        assert_eq!(scan["header"]["frame_id"], "velodyne");
        assert_eq!(scan["packets"].as_array().unwrap().len(), 2);
        assert_eq!(scan["packets"][1]["stamp"]["nanosec"], 123_458_116);
        let data: Vec<u64> = scan["packets"][0]["data"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_u64().unwrap())
            .collect();
        assert_eq!(
            data,
            packet.iter().map(|&b| u64::from(b)).collect::<Vec<_>>()
        );
        let fix = &v["messages"]["/gnss/fix"][5];
        assert_eq!(fix["status"]["status"], 2);
        assert_eq!(fix["latitude"], 48.117_3);
        assert_eq!(fix["altitude"], 550.4);
        assert_eq!(fix["position_covariance"][8], 0.0009);
        assert_eq!(fix["position_covariance_type"], 2);
        let can = &v["messages"]["/can/frames"][0];
        assert_eq!(can["id"], 0x18DA_F110);
        assert_eq!(can["is_extended"], true);
        assert_eq!(can["dlc"], 3);
        assert_eq!(can["data"], serde_json::json!([1, 2, 3, 0, 0, 0, 0, 0]));
        assert_eq!(
            can["_publish_time"].as_u64().unwrap(),
            can["_log_time"].as_u64().unwrap() + 5
        );
        let tw = &v["messages"]["/ego/twist"][0];
        assert_eq!(tw["twist"]["linear"]["x"], 10.0);
        assert_eq!(tw["twist"]["angular"]["z"], -0.25);
        assert_eq!(v["messages"]["/gnss/nmea"][0]["sentence"], "$GPGGA,1*00");
        assert_eq!(
            v["messages"]["/velodyne_position"][0]["data"]
                .as_array()
                .unwrap()
                .len(),
            512
        );
        assert_eq!(v["metadata"]["hilrig"]["rig"], "demo");
        assert_eq!(v["attachments"][0]["name"], "rig.toml");
    }
}

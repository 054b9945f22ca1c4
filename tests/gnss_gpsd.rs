//! gpsd as the oracle for the GNSS driver (issue 3, item 1): for every receiver log in
//! ../shared/data/gnss (read in place), every gpsd TPV report with lat/lon has a hilrig fix of the
//! same time with lat/lon within 1e-8 degrees and the same RTK state (gpsd status 3 = RTK fixed,
//! 4 = RTK float). TPVs that gpsd emitted before it knew the date carry no time; those are matched
//! by position and RTK state. Also (item 2): on the mixed UBX + NMEA + RTCM3 stream of the
//! ZED-F9R, every NAV-PVT and every NMEA sentence with a valid checksum is recovered, counted
//! independently of the framer.

use crate::common;

use hilrig::gnss::{Fix, GnssStream, RtkState};
use hilrig::stamp::civil::iso8601_millis;

fn decode(bytes: &[u8], chunk: usize) -> Vec<Fix> {
    let mut s = GnssStream::for_gpsd_log();
    let mut out = Vec::new();
    for c in bytes.chunks(chunk) {
        s.push(c, &mut out);
    }
    s.finish(&mut out);
    out
}

struct Tpv {
    time: Option<String>,
    lat: f64,
    lon: f64,
    rtk: RtkState,
}

fn tpvs(chk: &str) -> Vec<Tpv> {
    chk.lines()
        .filter(|l| l.starts_with('{'))
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v["class"] == "TPV" && v["lat"].is_number() && v["lon"].is_number())
        .map(|v| Tpv {
            time: v["time"].as_str().map(str::to_owned),
            lat: v["lat"].as_f64().unwrap(),
            lon: v["lon"].as_f64().unwrap(),
            rtk: match v["status"].as_i64() {
                Some(3) => RtkState::Fixed,
                Some(4) => RtkState::Float,
                _ => RtkState::None,
            },
        })
        .collect()
}

fn check_log(name: &str) {
    let dir = common::real_data().join("gnss");
    let log = std::fs::read(dir.join(name)).unwrap();
    let chk = std::fs::read_to_string(dir.join(format!("{name}.chk"))).unwrap();
    let expected = tpvs(&chk);
    // Feed in odd-sized chunks, as a serial port delivers.
    let fixes = decode(&log, 37);
    assert_eq!(
        fixes,
        decode(&log, log.len()),
        "{name}: chunking must not change the result"
    );
    let close = |f: &Fix, t: &Tpv| {
        f.lat.is_some_and(|la| (la - t.lat).abs() <= 1e-8)
            && f.lon.is_some_and(|lo| (lo - t.lon).abs() <= 1e-8)
            && f.rtk == t.rtk
    };
    let mut matched = 0;
    let mut unmatched = Vec::new();
    for t in &expected {
        let ok = match &t.time {
            Some(time) => fixes.iter().any(|f| {
                f.time.map(iso8601_millis).as_deref() == Some(time.as_str()) && close(f, t)
            }),
            None => fixes.iter().any(|f| close(f, t)),
        };
        if ok {
            matched += 1;
        } else {
            unmatched.push(format!("{:?} {} {} {:?}", t.time, t.lat, t.lon, t.rtk));
        }
    }
    println!(
        "{name}: {matched}/{} gpsd TPVs matched ({} hilrig fixes)",
        expected.len(),
        fixes.len()
    );
    assert!(!expected.is_empty());
    assert!(
        unmatched.is_empty(),
        "{name}: unmatched TPVs:\n{}",
        unmatched.join("\n")
    );
}

macro_rules! gpsd_oracle {
    ($($test:ident => $file:literal),*) => {$(
        #[test]
        #[cfg_attr(not(hilrig_real_data), ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run")]
        fn $test() {
            check_log($file);
        }
    )*};
}

gpsd_oracle!(
    trimble_nmea_rtk => "nmea-rtk.log",
    ublox_zed_f9r_mixed => "ublox-zed-f9r.log",
    skytraq_px1172rh => "skytraq-PX1172RH_DS.log",
    ublox_zed_f9p_rtk => "ublox-zed-f9p-rtk.log",
    ublox_zed_f9p_hp => "ublox-zed-f9p-hp.log"
);

/// Counts NMEA sentences with a valid checksum and UBX NAV-PVT frames with a valid checksum by
/// brute force: every position in the file is tried as a frame start.
fn independent_counts(b: &[u8]) -> (usize, usize) {
    let mut nmea = 0;
    let mut pvt = 0;
    for i in 0..b.len() {
        if b[i] == b'$' {
            if let Some(end) = b[i..]
                .iter()
                .take(300)
                .position(|&c| c == b'\r' || c == b'\n')
            {
                let line = &b[i..i + end];
                if line.iter().all(|c| (0x20..0x7f).contains(c))
                    && line.len() > 4
                    && line[line.len() - 3] == b'*'
                {
                    let body = &line[1..line.len() - 3];
                    let cs = body.iter().fold(0u8, |a, c| a ^ c);
                    if std::str::from_utf8(&line[line.len() - 2..])
                        .ok()
                        .and_then(|h| u8::from_str_radix(h, 16).ok())
                        == Some(cs)
                        && !body.contains(&b'$')
                    {
                        nmea += 1;
                    }
                }
            }
        }
        if b[i..].starts_with(&[0xB5, 0x62, 0x01, 0x07, 92, 0]) && i + 100 <= b.len() {
            let (mut ca, mut cb) = (0u8, 0u8);
            for &x in &b[i + 2..i + 98] {
                ca = ca.wrapping_add(x);
                cb = cb.wrapping_add(ca);
            }
            if b[i + 98] == ca && b[i + 99] == cb {
                pvt += 1;
            }
        }
    }
    (nmea, pvt)
}

/// The RTCM3 frames gpsd decoded from the F9R log (its `.chk` file), per message type. gpsd
/// prints 27 of its reports twice in a row, identical to the byte (all BeiDou MSM5, type 1125,
/// each following the same frame); a CRC scan of the log finds each of those frames once, so a
/// report that repeats the one before it is counted once. What remains is the oracle: 224 frames
/// of 13 message types.
fn gpsd_rtcm3_frames() -> std::collections::BTreeMap<u16, usize> {
    let chk =
        std::fs::read_to_string(common::real_data().join("gnss/ublox-zed-f9r.log.chk")).unwrap();
    let reports: Vec<&str> = chk
        .lines()
        .filter(|l| l.contains("\"class\":\"RTCM3\""))
        .collect();
    let mut frames = std::collections::BTreeMap::new();
    for (k, r) in reports.iter().enumerate() {
        if k > 0 && reports[k - 1] == *r {
            continue;
        }
        let v: serde_json::Value = serde_json::from_str(r).unwrap();
        *frames
            .entry(v["type"].as_u64().unwrap() as u16)
            .or_default() += 1;
    }
    assert_eq!(reports.len(), 251, "gpsd's RTCM3 reports in the .chk file");
    frames
}

#[test]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
fn f9r_mixed_stream_loses_nothing() {
    use hilrig::gnss::framer::{Frame, Framer, Item};
    let log = std::fs::read(common::real_data().join("gnss/ublox-zed-f9r.log")).unwrap();
    let (nmea_expected, pvt_expected) = independent_counts(&log);
    let rtcm_expected = gpsd_rtcm3_frames();
    for chunk in [1, 7, 64, 1000, log.len()] {
        let mut f = Framer::for_gpsd_log();
        let (mut nmea, mut pvt) = (0, 0);
        let mut rtcm = std::collections::BTreeMap::<u16, usize>::new();
        for c in log.chunks(chunk) {
            f.push(c);
            while let Some(item) = f.next_frame() {
                match item {
                    Item::Frame {
                        frame: Frame::Nmea(_),
                        ..
                    } => nmea += 1,
                    Item::Frame {
                        frame:
                            Frame::Ubx {
                                class: 1, id: 7, ..
                            },
                        ..
                    } => pvt += 1,
                    Item::Frame {
                        frame: Frame::Rtcm3 { message, .. },
                        ..
                    } => *rtcm.entry(message).or_default() += 1,
                    _ => {}
                }
            }
        }
        f.finish();
        while f.next_frame().is_some() {}
        println!("chunk {chunk}: NMEA {nmea}/{nmea_expected}, NAV-PVT {pvt}/{pvt_expected}, RTCM3 {}/{}, rejected {}", rtcm.values().sum::<usize>(), rtcm_expected.values().sum::<usize>(), f.stats.rejected);
        assert_eq!(nmea, nmea_expected, "NMEA sentences with a valid checksum");
        assert_eq!(pvt, pvt_expected, "NAV-PVT frames");
        assert_eq!(
            rtcm, rtcm_expected,
            "RTCM3 frames per message type, as gpsd reports them"
        );
    }
    assert!(pvt_expected >= 30 && nmea_expected > 600);
}

/// The GNSS stream stored on a serial interface (LINKTYPE_USER0) of a pcapng capture, in odd
/// chunks next to lidar traffic, decodes to the same fixes as the raw log.
#[test]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
fn serial_interface_of_a_pcapng_capture_gives_the_same_fixes() {
    use hilrig::capture::{LinkType, PcapngWriter, UtcNanos};
    let log = std::fs::read(common::real_data().join("gnss/ublox-zed-f9r.log")).unwrap();
    let mut w = PcapngWriter::new(Vec::new(), "test").unwrap();
    let eth = w.add_interface(LinkType::ETHERNET, "eth0").unwrap();
    let ser = w.add_interface(LinkType::USER0, "/dev/ttyACM0").unwrap();
    let mut t = 1_700_000_000_000_000_000i64;
    for (i, c) in log.chunks(97).enumerate() {
        t += 1_000_000;
        w.write_packet(ser, UtcNanos(t), c).unwrap();
        if i % 10 == 0 {
            w.write_packet(
                eth,
                UtcNanos(t),
                &hilrig::capture::writer::udp_ethernet_frame(
                    std::net::SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, 1),
                    std::net::SocketAddrV4::new(std::net::Ipv4Addr::LOCALHOST, 2368),
                    &[0; 100],
                ),
            )
            .unwrap();
        }
    }
    let capture = w.finish().unwrap();
    let mut from_capture = Vec::new();
    let summary = hilrig::decode::gnss::decode_gnss(std::io::Cursor::new(capture), &mut |r| {
        if let hilrig::decode::gnss::GnssReport::Fix(f) = r {
            from_capture.push(f.clone());
        }
        Ok(())
    })
    .unwrap();
    assert_eq!(summary.interfaces, vec!["/dev/ttyACM0".to_string()]);
    assert_eq!(from_capture, decode(&log, 4096));
}

/// Every `ATT` object of gpsd's expected output appears, in order, among hilrig's attitude
/// records: heading, pitch and roll to 0.01° where gpsd reports them, and the same time where
/// gpsd gives one. (gpsd merges the messages of a cycle into one report, so hilrig, which
/// reports each message, has more.) gpsd's `yaw` is ESF-ALG's mounting yaw: hilrig reports
/// it as `yaw_deg` of `"of": "sensor_mounting"`, never as a heading.
fn check_attitude(name: &str, sources: &[&str]) {
    let dir = common::real_data().join("gnss");
    let chk = std::fs::read_to_string(dir.join(format!("{name}.chk"))).unwrap();
    let expected: Vec<serde_json::Value> = chk
        .lines()
        .filter(|l| l.starts_with('{'))
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|v| v["class"] == "ATT")
        .collect();
    assert!(!expected.is_empty(), "{name}: gpsd reports no ATT");
    let (ours, stderr) = common::decode_attitudes(&dir.join(name));
    let mut at = 0;
    for (k, e) in expected.iter().enumerate() {
        // gpsd keeps the last ESF-ALG's yaw in the reports after it; hilrig reports the
        // vehicle's attitude and the IMU's mounting apart. A gpsd report with a heading is
        // the vehicle's (its yaw, if any, must be a mounting yaw hilrig reported before);
        // one with a yaw alone is the mounting's.
        let vehicle = e["heading"].is_number();
        let agrees = |o: &serde_json::Value| {
            let fields: &[&str] = if vehicle {
                &["heading", "pitch", "roll"]
            } else {
                &["yaw", "pitch", "roll"]
            };
            o["of"]
                == if vehicle {
                    "vehicle"
                } else {
                    "sensor_mounting"
                }
                && fields.iter().all(|f| match e[*f].as_f64() {
                    Some(x) => o[format!("{f}_deg")]
                        .as_f64()
                        .is_some_and(|y| (x - y).abs() <= 0.01),
                    None => true,
                })
                && e["time"].as_str().is_none_or(|t| o["time"] == t)
        };
        if let (true, Some(yaw)) = (vehicle, e["yaw"].as_f64()) {
            assert!(
                ours[..at].iter().any(|o| o["of"] == "sensor_mounting"
                    && o["yaw_deg"].as_f64().is_some_and(|y| (y - yaw).abs() <= 0.01)),
                "{name}: gpsd's ATT {k} ({e}) carries a mounting yaw hilrig did not report before it"
            );
        }
        match ours[at..].iter().position(agrees) {
            Some(i) => at += i + 1,
            None => panic!(
                "{name}: gpsd's ATT {k} ({e}) is not among hilrig's attitude records after record {at}:\n{}",
                ours.iter().map(|o| o.to_string()).collect::<Vec<_>>().join("\n")
            ),
        }
    }
    for o in &ours {
        assert!(sources.contains(&o["source"].as_str().unwrap()), "{o}");
    }
    assert!(
        stderr.contains(&format!("attitude reports: {}", ours.len())),
        "{stderr}"
    );
    println!(
        "{name}: {} gpsd ATT objects found in order among {} attitude records",
        expected.len(),
        ours.len()
    );
}

#[test]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
fn skytraq_dual_antenna_attitude_matches_gpsd() {
    check_attitude("skytraq-PX1172RH_DS.log", &["THS", "HDT", "PSTI,036"]);
}

#[test]
#[cfg_attr(
    not(hilrig_real_data),
    ignore = "needs HILRIG_REAL_DATA (set by .ci/run): did not run"
)]
fn ublox_m8u_high_rate_attitude_matches_gpsd() {
    check_attitude("ublox-neo-m8u-hnr.log", &["HNR-ATT", "ESF-ALG"]);
}

/// Attitude messages that are malformed or flagged invalid are counted and never reported:
/// a THS in mode V, a PSTI,036 in mode N, a PASHR with a NaN roll and one with a heading of
/// 400°, a NAV-ATT with a wrong checksum, a NAV-PVAT with no valid angle; the good ones
/// around them (a PASHR, a NAV-ATT, a NAV-PVAT with its heading only) are reported.
#[test]
fn bad_attitude_messages_are_counted_and_not_used() {
    use hilrig::gnss::framer::{nmea_sentence, ubx_frame};
    let mut log: Vec<u8> = Vec::new();
    for body in [
        "GPRMC,120000.00,A,4807.038,N,01131.000,E,0.0,0.0,251126,,,R",
        "GPGGA,120000.00,4807.038,N,01131.000,E,4,12,0.9,545.4,M,46.9,M,1.0,0001",
        "GPTHS,123.40,V",
        "PSTI,036,120000.000,251126,123.40,1.00,0.50,N",
        "PASHR,120000.00,123.40,T,NaN,+0.31,+0.01,0.029,0.029,0.059,2,1",
        "PASHR,120000.00,400.00,T,-0.30,+0.31,+0.01,0.029,0.029,0.059,2,1",
        "PASHR,120000.10,123.45,T,-0.30,+0.31,+0.01,0.029,0.029,0.059,2,1",
        "GPGGA,120001.00,4807.038,N,01131.000,E,4,12,0.9,545.4,M,46.9,M,1.0,0001",
    ] {
        log.extend(nmea_sentence(body).bytes());
    }
    let att = |heading_e5: i32| {
        let mut p = [0u8; 32];
        p[0..4].copy_from_slice(&345_600_000u32.to_le_bytes());
        p[16..20].copy_from_slice(&heading_e5.to_le_bytes());
        p[28..32].copy_from_slice(&5_000u32.to_le_bytes());
        ubx_frame(0x01, 0x05, &p)
    };
    log.extend(att(12_345_000));
    let mut broken = att(12_345_000);
    let n = broken.len();
    broken[n - 1] ^= 0xFF;
    log.extend(broken);
    let pvat = |flags: u8| {
        let mut p = [0u8; 116];
        p[25] = flags;
        p[80..84].copy_from_slice(&9_000_000i32.to_le_bytes());
        p[92..94].copy_from_slice(&12u16.to_le_bytes());
        ubx_frame(0x01, 0x17, &p)
    };
    log.extend(pvat(0x01 | 0x20));
    log.extend(pvat(0x01));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("attitude.log");
    std::fs::write(&path, &log).unwrap();
    let (ours, stderr) = common::decode_attitudes(&path);
    let got: Vec<(String, Option<f64>)> = ours
        .iter()
        .map(|o| {
            (
                o["source"].as_str().unwrap().to_owned(),
                o["heading_deg"].as_f64(),
            )
        })
        .collect();
    assert_eq!(
        got,
        vec![
            ("PASHR".to_owned(), Some(123.45)),
            ("NAV-ATT".to_owned(), Some(123.45)),
            ("NAV-PVAT".to_owned(), Some(90.0)),
        ],
        "{stderr}"
    );
    assert_eq!(ours[1]["sigma_heading_deg"].as_f64(), Some(0.05));
    assert_eq!(ours[2]["sigma_heading_deg"].as_f64(), Some(0.12));
    assert!(ours[2]["roll_deg"].is_null() && ours[2]["pitch_deg"].is_null());
    // The PASHR's own time on the date the RMC gave.
    assert_eq!(ours[0]["time"], "2026-11-25T12:00:00.100Z");
    assert!(
        stderr.contains(
            "attitude reports: 3, attitude messages flagged invalid (not used): NAV-PVAT 1, PSTI,036 1, THS 1"
        ),
        "{stderr}"
    );
    // The two malformed PASHRs fail to decode; the NAV-ATT with the wrong checksum is rejected.
    assert!(
        stderr.contains("rejected frames: 1, undecodable frames: 2"),
        "{stderr}"
    );
}

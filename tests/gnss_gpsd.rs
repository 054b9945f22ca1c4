//! gpsd as the oracle for the GNSS driver (issue 3, item 1): for every receiver log in
//! ../shared/data/gnss (read in place), every gpsd TPV report with lat/lon has a hilrig fix of the
//! same time with lat/lon within 1e-8 degrees and the same RTK state (gpsd status 3 = RTK fixed,
//! 4 = RTK float). TPVs that gpsd emitted before it knew the date carry no time; those are matched
//! by position and RTK state. Also (item 2): on the mixed UBX + NMEA + RTCM3 stream of the
//! ZED-F9R, every NAV-PVT and every NMEA sentence with a valid checksum is recovered, counted
//! independently of the framer.

mod common;

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
    let summary = hilrig::decode::gnss::decode_gnss(std::io::Cursor::new(capture), &mut |f| {
        from_capture.push(f.clone());
        Ok(())
    })
    .unwrap();
    assert_eq!(summary.interfaces, vec!["/dev/ttyACM0".to_string()]);
    assert_eq!(from_capture, decode(&log, 4096));
}

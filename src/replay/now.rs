//! `--now`: a recording replayed as if it happened at this moment. A device under test that
//! checks the lidar's timestamps against its own clock (or needs a current GPS time from the
//! position packets) then accepts the data.

use super::load::Payload;
use hilrig_stamp::UtcNanos;

/// `payload` as sent at `at`: data packets get the timestamp of `at` (microseconds past the
/// hour), position packets that and PPS locked and an RMC with the time and date of `at`. Other
/// payloads are returned unchanged.
pub fn rewrite(payload: &Payload, at: UtcNanos) -> Payload {
    match payload {
        Payload::LidarData(b) => {
            let mut b = b.clone();
            if b.len() >= 1204 {
                b[1200..1204]
                    .copy_from_slice(&((at.nanos_past_hour() / 1000) as u32).to_le_bytes());
            }
            Payload::LidarData(b)
        }
        Payload::LidarPosition(b) => Payload::LidarPosition(position_now(b, at)),
        other => other.clone(),
    }
}

/// Shifts a position packet to `at`: timestamp, PPS locked, RMC time and date. A packet that
/// does not decode is sent as it is.
pub fn position_now(p: &[u8], at: UtcNanos) -> Vec<u8> {
    let Ok(mut pkt) = hilrig_velodyne::PositionPacket::decode(p) else {
        return p.to_vec();
    };
    pkt.timestamp_us = (at.nanos_past_hour() / 1000) as u32;
    pkt.pps_byte = 2;
    if let Some(s) = pkt.nmea() {
        if let Ok(body) = hilrig_gnss::nmea::body(s) {
            let mut f: Vec<String> = body.split(',').map(str::to_owned).collect();
            if f.len() > 9 && f[0].ends_with("RMC") {
                let iso = hilrig_stamp::civil::iso8601_millis(UtcNanos(
                    at.0 - at.0.rem_euclid(1_000_000_000),
                ));
                f[1] = format!("{}{}{}", &iso[11..13], &iso[14..16], &iso[17..19]);
                f[2] = "A".into();
                f[9] = format!("{}{}{}", &iso[8..10], &iso[5..7], &iso[2..4]);
                let sentence = hilrig_gnss::framer::nmea_sentence(&f.join(","));
                pkt = hilrig_velodyne::PositionPacket::new(
                    pkt.timestamp_us,
                    hilrig_velodyne::PpsStatus::Locked,
                    &sentence,
                );
            }
        }
    }
    pkt.encode().to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_packets_get_the_microseconds_past_the_hour_of_now() {
        let at = UtcNanos(3_600_000_000_000 * 5 + 1_234_567_000);
        let Payload::LidarData(b) = rewrite(&Payload::LidarData(vec![0; 1206]), at) else {
            panic!("a data packet stays a data packet");
        };
        assert_eq!(
            u32::from_le_bytes([b[1200], b[1201], b[1202], b[1203]]),
            1_234_567
        );
        assert!(b[..1200].iter().chain(&b[1204..]).all(|&x| x == 0));
    }

    #[test]
    fn position_packets_get_pps_and_an_rmc_of_now() {
        let rmc = hilrig_gnss::framer::nmea_sentence(
            "GPRMC,101010,V,4807.038,N,01131.000,E,000.0,000.0,010120,,,A",
        );
        let old = hilrig_velodyne::PositionPacket::new(7, hilrig_velodyne::PpsStatus::Absent, &rmc)
            .encode()
            .to_vec();
        // 2026-11-22T14:05:06.5Z
        let at = UtcNanos(1_795_356_306_500_000_000);
        let new = position_now(&old, at);
        let p = hilrig_velodyne::PositionPacket::decode(&new).unwrap();
        assert_eq!(p.pps_byte, 2);
        assert_eq!(
            u64::from(p.timestamp_us),
            (at.nanos_past_hour() / 1000) as u64
        );
        let s = p.nmea().unwrap();
        assert!(s.contains(",140506,A,") && s.contains(",221126,"), "{s}");
    }

    /// Only an RMC is rewritten; another sentence in a position packet (some firmware sends
    /// GGA) keeps its fields, and the packet still gets the time and PPS of now.
    #[test]
    fn a_gga_in_a_position_packet_is_left_as_it_is() {
        let gga = hilrig_gnss::framer::nmea_sentence(
            "GPGGA,101010.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
        );
        let old = hilrig_velodyne::PositionPacket::new(7, hilrig_velodyne::PpsStatus::Absent, &gga)
            .encode()
            .to_vec();
        let at = UtcNanos(1_795_356_306_500_000_000);
        let p = hilrig_velodyne::PositionPacket::decode(&position_now(&old, at)).unwrap();
        assert_eq!(p.pps_byte, 2);
        assert_eq!(p.nmea().unwrap().trim_end(), gga.trim_end());
    }
}
